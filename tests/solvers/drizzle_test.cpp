#include "aosr/solvers/drizzle.hpp"

#include <gtest/gtest.h>

#include <cstring>
#include <limits>
#include <memory>

#include "aosr/core/forward_model.hpp"
#include "aosr/solvers/shift_and_add.hpp"
#include "drizzle_fixture.hpp"
#include "support/testing.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

using aosr::test::RandomImage;

bool BitIdentical(const Image& a, const Image& b) {
  return ShapeOf(a) == ShapeOf(b) && std::memcmp(a.data(), b.data(), sizeof(double) * a.size()) == 0;
}

constexpr DrizzleKernel kAllKernels[] = {DrizzleKernel::kSquare, DrizzleKernel::kTurbo, DrizzleKernel::kPoint,
                                         DrizzleKernel::kGaussian, DrizzleKernel::kLanczos3};

TEST(DrizzleTest, KernelNamesRoundTrip) {
  for (DrizzleKernel k : kAllKernels) EXPECT_EQ(ParseDrizzleKernel(ToString(k)), k);
  EXPECT_STREQ(ToString(DrizzleKernel::kLanczos3), "lanczos3");
  std::string why;
  EXPECT_TRUE(DrizzleOptions{}.IsValid(&why)) << why;
}

// The two-frame case worked by hand with cdrizzle's square-kernel formulas (dover / jaco = overlap
// area / drop area, data scaled by iscale = 1/r², dow = dover · w, weighted mean), the check that
// stands in for running the STScI package, which cannot be installed here.
//
// r = 2, pixfrac = 0.5: every drop is a 1 x 1 HR-pixel square.
//  Frame 0, offset (0, 0), w = 1: drop (Y, X) centred at (2Y + 0.5, 2X + 0.5) covers [2Y, 2Y+1] x
//    [2X, 2X+1], a quarter of it on each of the HR pixels (2Y..2Y+1, 2X..2X+1).
//  Frame 1, offset (0.5, -0.25), w = 3: centre (2Y, 2X + 0.75): rows [2Y - .5, 2Y + .5] lie wholly in
//    row 2Y; columns [2X + .25, 2X + 1.25] put .25 in column 2X and .75 in column 2X + 1. Odd rows get
//    nothing from frame 1.
//  Values: y0 = 8 except y0(1,1) = 16 (d = 2, 4); y1 = 4 except y1(1,1) = 12 (d = 1, 3).
//  HR (2,2): f0 LR(1,1) a w = .25, d = 4; f1 LR(1,1) a w = .25·3 = .75, d = 3 -> I = 3.25, W = 1
//  HR (2,3): f0 .25 x 4; f1 LR(1,1) .75·3 = 2.25 x 3              -> I = 7.75/2.5 = 3.1, W = 2.5
//  HR (3,2), (3,3): frame 0 only, d = 4                            -> I = 4, W = .25
//  HR (2,1): f0 LR(1,0) .25 x 2; f1 LR(1,0) 2.25 x 1               -> I = 2.75/2.5 = 1.1, W = 2.5
//  HR (2,4): f0 LR(1,2) .25 x 2; f1 LR(1,2) .75 x 1                -> I = 1.25, W = 1
TEST(DrizzleTest, TwoFrameSquareKernelMatchesHandComputedOverlaps) {
  Image y0 = Image::Constant(3, 3, 8.0), y1 = Image::Constant(3, 3, 4.0);
  y0(1, 1) = 16.0;
  y1(1, 1) = 12.0;
  const ReconstructionProblem p = test::RegistrationProblem({6, 6}, 2, {y0, y1}, {{0.0, 0.0}, {0.5, -0.25}},
                                              {Image::Ones(3, 3), Image::Constant(3, 3, 3.0)});
  DrizzleOptions o;
  o.pixfrac = 0.5;
  for (DrizzleBoundary b : {DrizzleBoundary::kPeriodic, DrizzleBoundary::kClip}) {  // no drop leaves the grid
    o.boundary = b;
    const DrizzleResult d = Drizzle(p, o);
    EXPECT_NEAR(d.image(2, 2), 3.25, 1e-14);
    EXPECT_NEAR(d.weight(2, 2), 1.0, 1e-14);
    EXPECT_NEAR(d.image(2, 3), 3.1, 1e-14);
    EXPECT_NEAR(d.weight(2, 3), 2.5, 1e-14);
    EXPECT_NEAR(d.image(3, 2), 4.0, 1e-14);
    EXPECT_NEAR(d.image(3, 3), 4.0, 1e-14);
    EXPECT_NEAR(d.weight(3, 3), 0.25, 1e-14);
    EXPECT_NEAR(d.image(2, 1), 1.1, 1e-14);
    EXPECT_NEAR(d.image(2, 4), 1.25, 1e-14);
    EXPECT_NEAR(d.weight(2, 4), 1.0, 1e-14);
    ASSERT_EQ(d.context.size(), 1u);
    EXPECT_EQ(d.context[0](2, 2), 3u);  // both frames
    EXPECT_EQ(d.context[0](3, 3), 1u);  // frame 0 only
    EXPECT_TRUE(d.Contributed(1, 2, 3));
    EXPECT_FALSE(d.Contributed(1, 3, 3));
    EXPECT_EQ(d.summary.covered_pixels, 36);
    EXPECT_EQ(d.summary.missed_inputs, 0);
    EXPECT_EQ(d.summary.method, "drizzle");
    EXPECT_EQ(d.summary.termination, Termination::kConverged);
    EXPECT_TRUE(d.summary.frame_residual_rms.empty());
  }
  // For a pure translation turbo is the same rectangle and the same fractions: bit-identical.
  DrizzleOptions t = o;
  t.kernel = DrizzleKernel::kTurbo;
  o.boundary = t.boundary = DrizzleBoundary::kPeriodic;
  EXPECT_TRUE(BitIdentical(Drizzle(p, o).image, Drizzle(p, t).image));
  EXPECT_TRUE(BitIdentical(Drizzle(p, o).weight, Drizzle(p, t).weight));
}

// Convention check against ShiftAndAdd: with pixfrac 1, whole-HR-pixel offsets and equal weights each HR
// pixel is covered by exactly one drop per frame, W = N / r², and drizzle is the mean of the frames
// block-replicated and moved back by their offsets, which is what ShiftAndAdd computes.
TEST(DrizzleTest, PixfracOneWithWholePixelOffsetsIsShiftAndAdd) {
  const int r = 3;
  const Shape hr{18, 15};
  ImageStack frames;
  for (int i = 0; i < 4; ++i) frames.push_back(RandomImage({6, 5}, 100 + i));
  const std::vector<FrameOffset> offsets = {{0, 0}, {1, 2}, {-4, 1}, {2, -1}};
  const DrizzleResult d = Drizzle(test::RegistrationProblem(hr, r, frames, offsets));
  const Image sa = ShiftAndAdd(frames, offsets, r, Combine::kMean);
  EXPECT_LT((d.image - sa).abs().maxCoeff(), 1e-12);
  EXPECT_LT((d.weight - 4.0 / 9.0).abs().maxCoeff(), 1e-14);
}

// The mapping stated in the header: LR pixel (Y, X) of a frame with offset (dy, dx) lands centred on HR
// (rY + (r-1)/2 - dy, rX + (r-1)/2 - dx). With pixfrac 1 and r = 3 the drop is 3 HR pixels wide (an
// integer), so the centroid of its overlap pattern is exactly its centre; the zero-valued neighbours give
// a uniform W, so the image is r² times that pattern.
TEST(DrizzleTest, ASingleDropLandsAtTheMappedCentre) {
  const int r = 3;
  Image y = Image::Zero(4, 4);
  y(2, 1) = 9.0;
  const ReconstructionProblem p = test::RegistrationProblem({12, 12}, r, {y}, {{0.4, -1.3}});
  const DrizzleResult d = Drizzle(p);
  const double cy = 3 * 2 + 1 - 0.4, cx = 3 * 1 + 1 + 1.3;  // (6.6, 5.3)
  double sum = 0, my = 0, mx = 0;
  for (Index v = 0; v < 12; ++v)
    for (Index u = 0; u < 12; ++u) {
      sum += d.image(v, u);
      my += double(v) * d.image(v, u);
      mx += double(u) * d.image(v, u);
    }
  EXPECT_NEAR(sum, 9.0, 1e-12);  // W uniform (1/9): the image holds the frame's flux
  EXPECT_NEAR(my / sum, cy, 1e-12);
  EXPECT_NEAR(mx / sum, cx, 1e-12);

  // The point kernel puts the whole drop on the pixel whose cell holds the centre: (7, 5).
  DrizzleOptions o;
  o.kernel = DrizzleKernel::kPoint;
  const DrizzleResult pt = Drizzle(p, o);
  EXPECT_NEAR(pt.image(7, 5), 1.0, 1e-15);  // 9 / r²
  EXPECT_NEAR(pt.image.sum(), 1.0, 1e-15);
  EXPECT_EQ(pt.summary.covered_pixels, 16);  // one HR pixel per LR pixel
}

// ReconstructionProblem's rule: a pixel whose weight is 0 is never read. Its value may be NaN or 1e30 and
// the output (image, weight and context) is bit-identical to the one with a harmless value there.
TEST(DrizzleTest, AZeroWeightPixelNeverChangesTheOutput) {
  const int r = 2;
  ImageStack frames = {RandomImage({5, 6}, 7), RandomImage({5, 6}, 8), RandomImage({5, 6}, 9)};
  ImageStack weights = {RandomImage({5, 6}, 17, false) + 0.5, RandomImage({5, 6}, 18, false) + 0.5,
                        RandomImage({5, 6}, 19, false) + 0.5};
  weights[1](2, 3) = 0.0;
  const std::vector<FrameOffset> offsets = {{0.0, 0.0}, {0.7, -0.35}, {-1.2, 0.9}};
  for (DrizzleKernel k : kAllKernels) {
    DrizzleOptions o;
    o.kernel = k;
    o.pixfrac = 0.7;
    frames[1](2, 3) = 0.0;
    const DrizzleResult base = Drizzle(test::RegistrationProblem({10, 12}, r, frames, offsets, weights), o);
    for (double bad :
         {std::numeric_limits<double>::quiet_NaN(), 1e30, std::numeric_limits<double>::infinity()}) {
      frames[1](2, 3) = bad;
      const DrizzleResult d = Drizzle(test::RegistrationProblem({10, 12}, r, frames, offsets, weights), o);
      EXPECT_TRUE(BitIdentical(d.image, base.image)) << ToString(k) << " value " << bad;
      EXPECT_TRUE(BitIdentical(d.weight, base.weight)) << ToString(k) << " value " << bad;
      ASSERT_EQ(d.context.size(), 1u);
      EXPECT_TRUE((d.context[0] == base.context[0]).all()) << ToString(k);
      EXPECT_EQ(d.summary.weighted_inputs, 3 * 30 - 1);
    }
  }
}

// Coverage as a function of pixfrac. r = 3, offset 0: drops are centred on HR pixels 3X + 1 and have
// side s = 3·pixfrac; an HR pixel o is touched when |o - c| < s/2 + 1/2. With pixfrac 0.3 (s = 0.9) only
// the central pixel of each 3 x 3 block is touched (coverage 1/9, a = 1 there); with pixfrac 0.5
// (s = 1.5) all three per axis are, with fractions 1/6, 2/3, 1/6. Dithers fill the holes: 2 x 2 whole-
// pixel offsets cover (2/3)², the complete 3 x 3 raster everything. The total weight Σ W = Σ w always
// (the area kernels spread each drop's weight with fractions summing to one).
TEST(DrizzleTest, PixfracAndDithersSetTheCoverage) {
  const int r = 3;
  const Shape hr{12, 12};
  auto run = [&](double pixfrac, const std::vector<FrameOffset>& offsets) {
    DrizzleOptions o;
    o.pixfrac = pixfrac;
    o.fill_value = -7.0;
    ImageStack frames(offsets.size(), Image::Constant(4, 4, 9.0));
    return Drizzle(test::RegistrationProblem(hr, r, frames, offsets), o);
  };
  const DrizzleResult a = run(0.3, {{0, 0}});
  EXPECT_EQ(a.summary.covered_pixels, 16);
  EXPECT_EQ(a.summary.filled_pixels, 144 - 16);
  EXPECT_DOUBLE_EQ(a.weight(4, 7), 1.0);
  EXPECT_DOUBLE_EQ(a.weight(4, 6), 0.0);
  EXPECT_DOUBLE_EQ(a.image(4, 6), -7.0);  // fill_value in the holes
  EXPECT_DOUBLE_EQ(a.image(4, 7), 1.0);   // 9 per LR pixel = 1 per HR pixel
  EXPECT_NEAR(a.weight.sum(), 16.0, 1e-12);

  const DrizzleResult b = run(0.5, {{0, 0}});
  EXPECT_EQ(b.summary.covered_pixels, 144);
  EXPECT_NEAR(b.weight(4, 7), 4.0 / 9.0, 1e-15);
  EXPECT_NEAR(b.weight(3, 6), 1.0 / 36.0, 1e-15);
  EXPECT_NEAR(b.weight(4, 6), 1.0 / 9.0, 1e-15);
  EXPECT_NEAR(b.weight.sum(), 16.0, 1e-12);
  EXPECT_LT((b.image - 1.0).abs().maxCoeff(), 1e-15);

  EXPECT_EQ(run(0.3, {{0, 0}, {1, 0}, {0, 1}, {1, 1}}).summary.covered_pixels, 64);
  std::vector<FrameOffset> raster;
  for (int ky = 0; ky < r; ++ky)
    for (int kx = 0; kx < r; ++kx) raster.push_back({double(ky), double(kx)});
  const DrizzleResult c = run(0.3, raster);
  EXPECT_EQ(c.summary.covered_pixels, 144);
  EXPECT_NEAR(c.weight.sum(), 9.0 * 16.0, 1e-12);
}

// Context planes: frame 32k + b is bit b of plane k; with 40 frames there are two planes.
TEST(DrizzleTest, ContextPlanesRecordEveryFrame) {
  const int r = 2, n = 40;
  ImageStack frames(n, Image::Ones(4, 4));
  std::vector<FrameOffset> offsets;
  for (int i = 0; i < n; ++i)
    offsets.push_back({0.0, double(i % 8)});  // frame i covers columns shifted by i%8
  DrizzleOptions o;
  o.kernel = DrizzleKernel::kPoint;
  const DrizzleResult d = Drizzle(test::RegistrationProblem({8, 8}, r, frames, offsets), o);
  ASSERT_EQ(d.context.size(), 2u);
  // Point drops of frame i sit at (2Y + 1, 2X + 1 - i%8) (0.5 - i%8 rounds up): odd rows only.
  for (int i = 0; i < n; ++i) {
    const Index col = ((1 - i % 8) % 8 + 8) % 8;
    EXPECT_TRUE(d.Contributed(i, 1, col)) << "frame " << i;
    EXPECT_FALSE(d.Contributed(i, 0, col)) << "frame " << i;
    EXPECT_FALSE(d.Contributed(i, 1, (col + 1) % 8)) << "frame " << i;
  }
  // HR (1, 1) is X = (i % 8) / 2's drop for every frame with i % 8 even: bits 0, 2, 4, ... of each plane.
  EXPECT_EQ(d.context[0](1, 1), 0x55555555u);  // frames 0, 2, ..., 30
  EXPECT_EQ(d.context[1](1, 1), 0x55u);        // frames 32, 34, 36, 38 are bits 0, 2, 4, 6 of plane 1
  DrizzleOptions no_ctx = o;
  no_ctx.compute_context = false;
  EXPECT_TRUE(Drizzle(test::RegistrationProblem({8, 8}, r, frames, offsets), no_ctx).context.empty());
}

// kClip is cdrizzle's boundary: the part of a drop off the grid is lost. One frame moved half an LR
// pixel (dx = 1 HR pixel, r = 2): drops centred at 2X - 0.5 cover columns [2X - 1.5, 2X + 0.5], i.e.
// HR columns 2X - 1 and 2X, half each. The first drop of each row puts its left half on column -1: clip
// loses it (and column 7 is reached by nobody), periodic wraps it onto column 7.
TEST(DrizzleTest, ClipLosesWhatPeriodicWraps) {
  const Image y = RandomImage({4, 4}, 3);
  const ReconstructionProblem p = test::RegistrationProblem({8, 8}, 2, {y}, {{0.0, 1.0}});
  DrizzleOptions o;
  const DrizzleResult wrap = Drizzle(p, o);
  o.boundary = DrizzleBoundary::kClip;
  const DrizzleResult clip = Drizzle(p, o);
  EXPECT_NEAR(wrap.weight.sum(), 16.0, 1e-12);
  EXPECT_NEAR(clip.weight.sum(), 16.0 - 4 * 0.5, 1e-12);
  EXPECT_EQ(clip.summary.covered_pixels, 64 - 8);
  EXPECT_LT((wrap.weight - 0.25).abs().maxCoeff(), 1e-15);
  EXPECT_NEAR(wrap.summary.weighted_flux_out, wrap.summary.weighted_flux_in, 1e-12);
  double lost = 0;
  for (Index Y = 0; Y < 4; ++Y) lost += 0.5 * y(Y, 0) / 4.0;
  EXPECT_NEAR(clip.summary.weighted_flux_in - clip.summary.weighted_flux_out, lost, 1e-12);
  EXPECT_EQ(clip.summary.missed_inputs, 0);
  // Away from the edge the two agree.
  EXPECT_LT((wrap.image.leftCols(7) - clip.image.leftCols(7)).abs().maxCoeff(), 1e-15);

  // A frame moved off the grid altogether: every input misses and nothing is covered.
  DrizzleOptions far = o;
  far.fill_value = -1.0;
  const DrizzleResult gone = Drizzle(test::RegistrationProblem({8, 8}, 2, {y}, {{0.0, 1e6}}), far);
  EXPECT_EQ(gone.summary.missed_inputs, 16);
  EXPECT_EQ(gone.summary.covered_pixels, 0);
  EXPECT_EQ(gone.summary.termination, Termination::kFailed);
  EXPECT_LT((gone.image + 1.0).abs().maxCoeff(), 1e-15);
  // Periodic: the same offset is a whole number of grid periods plus 0, so it lands like offset 0.
  const DrizzleResult back = Drizzle(test::RegistrationProblem({8, 8}, 2, {y}, {{0.0, 1e6}}));
  EXPECT_LT((back.image - Drizzle(test::RegistrationProblem({8, 8}, 2, {y}, {{0.0, 0.0}})).image).abs().maxCoeff(), 1e-12);
}

TEST(DrizzleTest, AllInputsMaskedReportsFailureNotAnException) {
  DrizzleOptions o;
  o.fill_value = std::numeric_limits<double>::quiet_NaN();  // explicitly asked for: INDEF
  const DrizzleResult d =
      Drizzle(test::RegistrationProblem({4, 4}, 2, {Image::Ones(2, 2)}, {{0, 0}}, {Image::Zero(2, 2)}), o);
  EXPECT_EQ(d.summary.termination, Termination::kFailed);
  EXPECT_NE(d.summary.message.find("no HR pixel"), std::string::npos);
  EXPECT_TRUE(d.image.isNaN().all());
  EXPECT_EQ(d.summary.weighted_inputs, 0);
}

}  // namespace
}  // namespace aosr
