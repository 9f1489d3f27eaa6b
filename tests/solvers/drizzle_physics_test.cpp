// Physics and maths oracles for drizzle (drizzle.hpp): flux conservation, centroids, interlacing.
#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <random>

#include "aosr/core/forward_model.hpp"
#include "aosr/core/operators.hpp"
#include "aosr/solvers/drizzle.hpp"
#include "drizzle_fixture.hpp"
#include "support/testing.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

using aosr::test::RandomImage;

// The complete r x r raster of whole-HR-pixel offsets k = (ky, kx), ky, kx in 0 .. r-1, rendered through
// the forward model (scene moved by +k, optional PSF, r x r box pixels).
struct Raster {
  std::shared_ptr<const MultiFrameModel> model;
  std::vector<FrameOffset> offsets;
};
Raster CompleteRaster(Shape hr, int r, const Image& centred_psf) {
  Raster out;
  std::vector<ComplexImage> otfs;
  const ComplexImage h = TransferFunction(hr, centred_psf);
  for (int ky = 0; ky < r; ++ky)
    for (int kx = 0; kx < r; ++kx) {
      otfs.push_back(ShiftTransfer(hr, ky, kx) * h);
      out.offsets.push_back({double(ky), double(kx)});
    }
  out.model = std::make_shared<const MultiFrameModel>(hr, r, otfs);
  return out;
}

constexpr DrizzleKernel kAllKernels[] = {DrizzleKernel::kSquare, DrizzleKernel::kTurbo, DrizzleKernel::kPoint,
                                         DrizzleKernel::kGaussian, DrizzleKernel::kLanczos3};

// Weighted flux Σ_o W I = Σ_{i,p} w y / r² for the kernels whose drops sum to one (square, turbo, point),
// with random frames, random inverse-variance weights (some masked), random sub-pixel offsets.
TEST(DrizzlePhysicsTest, SquareTurboAndPointConserveTheWeightedFlux) {
  const std::uint64_t seed = 2024;
  const int r = 3;
  const Shape hr{21, 24}, lr{7, 8};
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(-4.0, 4.0);
  ImageStack frames, weights;
  std::vector<FrameOffset> offsets;
  for (int i = 0; i < 5; ++i) {
    frames.push_back(RandomImage(lr, seed + i, false) * 100.0);
    Image w = RandomImage(lr, seed + 50 + i, false) + 0.25;
    w(i, i) = 0.0;  // a masked pixel per frame
    weights.push_back(w);
    offsets.push_back({u(rng), u(rng)});
  }
  double expected = 0;
  for (int i = 0; i < 5; ++i) expected += (weights[i] * frames[i]).sum() / double(r * r);
  const ReconstructionProblem p = test::RegistrationProblem(hr, r, frames, offsets, weights);
  for (DrizzleKernel k : {DrizzleKernel::kSquare, DrizzleKernel::kTurbo, DrizzleKernel::kPoint}) {
    for (double pixfrac : {1.0, 0.6, 0.25}) {
      DrizzleOptions o;
      o.kernel = k;
      o.pixfrac = pixfrac;
      const DrizzleResult d = Drizzle(p, o);
      const double out = (d.weight > 0).select(d.weight * d.image, 0.0).sum();
      EXPECT_NEAR(out / expected, 1.0, 1e-9) << ToString(k) << " pixfrac " << pixfrac << " seed " << seed;
      EXPECT_NEAR(d.summary.weighted_flux_in / expected, 1.0, 1e-12);
      EXPECT_NEAR(d.summary.weighted_flux_out / expected, 1.0, 1e-9);
      // Weight is conserved too: Σ W = Σ w (each drop's fractions sum to one).
      double wsum = 0;
      for (const Image& w : weights) wsum += w.sum();
      EXPECT_NEAR(d.weight.sum() / wsum, 1.0, 1e-12) << ToString(k);
    }
  }
}

// Noise-free frames of one scene all carry its flux F (sub-pixel shifts and a unit-sum PSF keep the DC
// term), so with periodic boundaries, no hole and weights uniform within each frame the image flux is
// Σ_o I = Σ_i λ_i F_i = F for every kernel (drizzle.hpp: the weighted mean divides each kernel's total
// out), even where W is far from uniform. A single masked pixel breaks this (for every kernel) while
// the weighted-flux identity of the area kernels still holds.
TEST(DrizzlePhysicsTest, EveryKernelConservesTheSceneFluxOfNoiseFreeFrames) {
  const std::uint64_t seed = 31;
  const int r = 3;
  const Shape hr{24, 30};
  Image psf(5, 5);
  for (Index v = 0; v < 5; ++v)
    for (Index u = 0; u < 5; ++u)
      psf(v, u) = std::exp(-((v - 2.0) * (v - 2.0) + (u - 2.0) * (u - 2.0)) / 2.0);
  psf /= psf.sum();
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(-2.0, 2.0);
  std::vector<ComplexImage> otfs;
  std::vector<FrameOffset> offsets;
  const ComplexImage h = TransferFunction(hr, psf);
  for (int i = 0; i < 6; ++i) {
    offsets.push_back({u(rng), u(rng)});
    otfs.push_back(ShiftTransfer(hr, offsets.back().dy, offsets.back().dx) * h);
  }
  ReconstructionProblem p;
  p.model = std::make_shared<const MultiFrameModel>(hr, r, otfs);
  const Image x = RandomImage(hr, seed, false) * 10.0;
  p.frames = p.model->Render(x);
  p.offsets = offsets;
  for (int i = 0; i < 6; ++i) p.weights.push_back(Image::Constant(8, 10, 0.5 + i));
  const double flux = x.sum();
  for (DrizzleKernel k :
       {DrizzleKernel::kSquare, DrizzleKernel::kTurbo, DrizzleKernel::kGaussian, DrizzleKernel::kLanczos3}) {
    for (double pixfrac : {1.0, 0.8}) {
      DrizzleOptions o;
      o.kernel = k;
      o.pixfrac = pixfrac;
      const DrizzleResult d = Drizzle(p, o);
      ASSERT_EQ(d.summary.filled_pixels, 0) << ToString(k) << " seed " << seed;
      EXPECT_NEAR(d.image.sum() / flux, 1.0, 1e-9)
          << ToString(k) << " pixfrac " << pixfrac << " seed " << seed;
      if (pixfrac < 1.0) {
        const Image ripple = d.weight / d.weight.mean() - 1.0;
        EXPECT_GT(ripple.abs().maxCoeff(), 0.01) << ToString(k);  // conserved although W is not uniform
      }
    }
  }
  ReconstructionProblem masked = p;
  masked.weights[2](3, 4) = 0.0;
  DrizzleOptions o;
  o.pixfrac = 0.8;
  const DrizzleResult d = Drizzle(masked, o);
  EXPECT_GT(std::abs(d.image.sum() / flux - 1.0), 1e-6);
  EXPECT_NEAR(d.summary.weighted_flux_out / d.summary.weighted_flux_in, 1.0, 1e-12);
}

// Image flux Σ_o I (flux per HR pixel x 1 HR pixel) equals the weighted mean frame flux Σ w̄_i F_i / Σ w̄_i
// wherever the weight map is uniform: equal-weight frames with pixfrac 1 (any offsets) for the area
// kernels, and the point kernel on a complete odd-r raster (one drop centre per HR pixel).
TEST(DrizzlePhysicsTest, UniformCoverageConservesTheImageFlux) {
  const std::uint64_t seed = 77;
  const int r = 3;
  const Shape hr{18, 15}, lr{6, 5};
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(-3.0, 3.0);
  ImageStack frames, weights;
  std::vector<FrameOffset> offsets;
  const double wbar[4] = {1.0, 2.5, 0.5, 4.0};  // per-frame inverse variances
  double num = 0, den = 0;
  for (int i = 0; i < 4; ++i) {
    frames.push_back(RandomImage(lr, seed + i, false) * 50.0);
    weights.push_back(Image::Constant(lr.rows, lr.cols, wbar[i]));
    offsets.push_back({u(rng), u(rng)});
    num += wbar[i] * frames[i].sum();
    den += wbar[i];
  }
  for (DrizzleKernel k : {DrizzleKernel::kSquare, DrizzleKernel::kTurbo}) {
    DrizzleOptions o;
    o.kernel = k;
    const DrizzleResult d = Drizzle(test::RegistrationProblem(hr, r, frames, offsets, weights), o);
    EXPECT_LT((d.weight - den / 9.0).abs().maxCoeff(), 1e-12);  // uniform
    EXPECT_NEAR(d.image.sum() / (num / den), 1.0, 1e-9) << ToString(k) << " seed " << seed;
  }
  // Point kernel, complete raster of whole-pixel offsets, r = 3: each HR pixel receives one centre.
  std::vector<FrameOffset> raster;
  ImageStack rframes;
  double flux = 0;
  for (int ky = 0; ky < r; ++ky)
    for (int kx = 0; kx < r; ++kx) {
      raster.push_back({double(ky), double(kx)});
      rframes.push_back(RandomImage(lr, seed + 10 * ky + kx, false));
      flux += rframes.back().sum() / 9.0;
    }
  DrizzleOptions o;
  o.kernel = DrizzleKernel::kPoint;
  const DrizzleResult d = Drizzle(test::RegistrationProblem(hr, r, rframes, raster), o);
  EXPECT_LT((d.weight - 1.0).abs().maxCoeff(), 1e-15);
  EXPECT_NEAR(d.image.sum() / flux, 1.0, 1e-9);
}

// A flat field is reproduced exactly by every kernel (a weighted mean of equal values), so with full
// coverage the image holds the frame's flux: Σ_o I = m² c = F.
TEST(DrizzlePhysicsTest, EveryKernelReproducesAFlatField) {
  const int r = 2;
  const double c = 12.0;
  ImageStack frames(3, Image::Constant(8, 6, c));
  const std::vector<FrameOffset> offsets = {{0.0, 0.0}, {0.3, -0.8}, {-1.1, 0.45}};
  for (DrizzleKernel k : kAllKernels) {
    DrizzleOptions o;
    o.kernel = k;
    const DrizzleResult d = Drizzle(test::RegistrationProblem({16, 12}, r, frames, offsets), o);
    if (k != DrizzleKernel::kPoint) {
      ASSERT_EQ(d.summary.filled_pixels, 0) << ToString(k);
      EXPECT_NEAR(d.image.sum() / (48 * c), 1.0, 1e-9) << ToString(k);
    }
    for (Index p = 0; p < d.image.size(); ++p) {
      if (d.weight.data()[p] > 0) {
        EXPECT_NEAR(d.image.data()[p], c / 4.0, 1e-12) << ToString(k);
      }
    }
  }
}

// Gaussian and Lanczos do not conserve the weighted flux: Σ W I / Σ w d equals the sum of one drop's kernel,
// which is not 1. One frame, offset 0, r = 2, pixfrac 1: drop centres sit at half-integers (2X + 0.5), so the
// per-axis pixel distances are Δ = ±0.5, ±1.5, ...
//  Gaussian: σ = 2 / 2.35482, pfo = max(2.5σ, 1.2·2) = 2.4, pixels with |Δ| <= 2.9: Δ in ±{0.5,1.5,2.5};
//            the 2-D sum is (Σ_Δ g(Δ))², g(Δ) = exp(-Δ²/2σ²)/(√(2π)σ), a little below 1.
//  Lanczos3: s = 2, support |Δ| < 6: Δ in ±{0.5 .. 5.5}; sum (Σ_Δ L3(Δ/2))², about s² = 4.
TEST(DrizzlePhysicsTest, GaussianAndLanczosDoNotConserveTheWeightedFlux) {
  const ReconstructionProblem p =
      test::RegistrationProblem({16, 16}, 2, {RandomImage({8, 8}, 5, false) + 1.0}, {{0.0, 0.0}});
  const double sigma = 2.0 / (2.0 * std::sqrt(2.0 * std::log(2.0)));
  double g = 0, l = 0;
  for (double a : {0.5, 1.5, 2.5})
    g += 2.0 * std::exp(-a * a / (2 * sigma * sigma)) / (std::sqrt(2 * M_PI) * sigma);
  auto sinc = [](double t) { return std::sin(M_PI * t) / (M_PI * t); };
  for (double a : {0.5, 1.5, 2.5, 3.5, 4.5, 5.5}) l += 2.0 * sinc(a / 2) * sinc(a / 6);
  for (auto [k, kernel_sum] :
       {std::pair{DrizzleKernel::kGaussian, g * g}, std::pair{DrizzleKernel::kLanczos3, l * l}}) {
    DrizzleOptions o;
    o.kernel = k;
    const DrizzleResult d = Drizzle(p, o);
    const double ratio = d.summary.weighted_flux_out / d.summary.weighted_flux_in;
    EXPECT_NEAR(ratio, kernel_sum, 1e-12) << ToString(k);
    EXPECT_GT(std::abs(ratio - 1.0), 1e-4) << ToString(k);
  }
  EXPECT_NEAR(g * g, 1.0, 2e-3);
  EXPECT_NEAR(l * l, 4.0, 0.2);
}

// A point source observed with a complete raster of whole-HR-pixel dithers (rendered through the forward
// model with a symmetric PSF): the drops of frame k hold the source at offsets (r-1)/2 - j, j = 0..r-1,
// from it and the zero-valued drops form mirror-image lattices, so the whole drop pattern is symmetric
// about the source and every symmetric kernel puts the centroid on it. The point kernel is tested with
// odd r only: with even r its centres fall on cell edges and the half-open cell breaks the tie to +.
TEST(DrizzlePhysicsTest, PointSourceCentroidLandsOnTheSource) {
  Image psf(7, 7);
  for (Index v = 0; v < 7; ++v)
    for (Index u = 0; u < 7; ++u)
      psf(v, u) = std::exp(-((v - 3.0) * (v - 3.0) + (u - 3.0) * (u - 3.0)) / 3.0);
  psf /= psf.sum();
  for (int r : {2, 3}) {
    const Shape hr{12 * r, 11 * r};
    const Raster raster = CompleteRaster(hr, r, psf);
    const Index y0 = 5 * r + 1, x0 = 6 * r - 1;
    Image x = Image::Zero(hr.rows, hr.cols);
    x(y0, x0) = 1000.0;
    ReconstructionProblem p;
    p.model = raster.model;
    p.frames = raster.model->Render(x);
    p.offsets = raster.offsets;
    for (DrizzleKernel k : {DrizzleKernel::kSquare, DrizzleKernel::kTurbo, DrizzleKernel::kPoint,
                            DrizzleKernel::kGaussian, DrizzleKernel::kLanczos3}) {
      if (k == DrizzleKernel::kPoint && r % 2 == 0) continue;
      for (double pixfrac : {1.0, 0.6}) {
        DrizzleOptions o;
        o.kernel = k;
        o.pixfrac = pixfrac;
        const DrizzleResult d = Drizzle(p, o);
        const Index h = 10;  // window (2h+1)² centred on the source, periodic indices
        double sum = 0, my = 0, mx = 0;
        for (Index v = -h; v <= h; ++v)
          for (Index u = -h; u <= h; ++u) {
            const double val = d.image((y0 + v + hr.rows) % hr.rows, (x0 + u + hr.cols) % hr.cols);
            sum += val;
            my += double(v) * val;
            mx += double(u) * val;
          }
        EXPECT_NEAR(my / sum, 0.0, 1e-6) << ToString(k) << " r " << r << " pixfrac " << pixfrac;
        EXPECT_NEAR(mx / sum, 0.0, 1e-6) << ToString(k) << " r " << r << " pixfrac " << pixfrac;
      }
    }
  }
}

// Interlacing (Fruchter & Hook §2): a complete raster of r² frames whose pixel centres fall on distinct
// HR pixel centres, drizzled with pixfrac 1/r and the square kernel, places each LR value (/ r²) on exactly
// one HR pixel. For odd r and whole-pixel offsets k the centre of LR pixel (Y, X) of frame k maps to
// (rY + (r-1)/2 - ky, ...), and since that pixel integrates the scene moved by k, the interlaced image is
// the centred r x r moving average of the scene: checked for r = 3 against the truth.
TEST(DrizzlePhysicsTest, CompleteRasterWithPixfracOneOverRIsTheInterlacedImage) {
  const int r = 3;
  const Shape hr{18, 21};
  const Raster raster = CompleteRaster(hr, r, Image::Ones(1, 1));
  const Image x = RandomImage(hr, 11, false);
  ReconstructionProblem p;
  p.model = raster.model;
  p.frames = raster.model->Render(x);
  p.offsets = raster.offsets;
  DrizzleOptions o;
  o.pixfrac = 1.0 / r;
  const DrizzleResult d = Drizzle(p, o);
  Image avg = Image::Zero(hr.rows, hr.cols);
  for (Index v = 0; v < hr.rows; ++v)
    for (Index u = 0; u < hr.cols; ++u)
      for (Index a = -1; a <= 1; ++a)
        for (Index b = -1; b <= 1; ++b)
          avg(v, u) += x((v + a + hr.rows) % hr.rows, (u + b + hr.cols) % hr.cols) / 9.0;
  EXPECT_LT((d.image - avg).abs().maxCoeff(), 1e-12);
  EXPECT_LT((d.weight - 1.0).abs().maxCoeff(), 1e-12);
}

// Even r: the centred raster of offsets k - (r-1)/2 (here ±0.5 HR pixel for r = 2) puts pixel centres on
// HR pixel centres rY + r - 1 - ky. With arbitrary frame data, drizzle must return exactly the interlaced
// array J(rY + r-1-ky, rX + r-1-kx) = y_k(Y, X) / r², with one frame per HR pixel in the context map.
TEST(DrizzlePhysicsTest, CentredEvenRasterInterlacesArbitraryFrames) {
  const int r = 2;
  const Shape hr{10, 12}, lr{5, 6};
  ImageStack frames;
  std::vector<FrameOffset> offsets;
  for (int ky = 0; ky < r; ++ky)
    for (int kx = 0; kx < r; ++kx) {
      frames.push_back(RandomImage(lr, 40 + 2 * ky + kx));
      offsets.push_back({ky - 0.5 * (r - 1), kx - 0.5 * (r - 1)});
    }
  DrizzleOptions o;
  o.pixfrac = 1.0 / r;
  const DrizzleResult d = Drizzle(test::RegistrationProblem(hr, r, frames, offsets), o);
  for (int ky = 0; ky < r; ++ky)
    for (int kx = 0; kx < r; ++kx)
      for (Index Y = 0; Y < lr.rows; ++Y)
        for (Index X = 0; X < lr.cols; ++X) {
          const Index v = r * Y + r - 1 - ky, u = r * X + r - 1 - kx;
          EXPECT_NEAR(d.image(v, u), frames[r * ky + kx](Y, X) / (r * r), 1e-14);
          EXPECT_EQ(d.context[0](v, u), 1u << (r * ky + kx));
        }
}

}  // namespace
}  // namespace aosr
