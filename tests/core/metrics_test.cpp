#include "aosr/core/metrics.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <random>
#include <vector>

namespace aosr {
namespace AOSR_TEST_NS {

// Values k/64 with k in 0..63: dyadic, so sums and differences with dyadic offsets are exact in double.
Image DyadicImage(Shape s, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_int_distribution<int> k(0, 63);
  Image img(s.rows, s.cols);
  for (Index i = 0; i < img.size(); ++i) img.data()[i] = k(rng) / 64.0;
  return img;
}

// A smooth pattern plus uniform noise in [0, 1): structure at several scales for SSIM to see.
Image TestScene(Shape s, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  Image img(s.rows, s.cols);
  for (Index y = 0; y < s.rows; ++y)
    for (Index x = 0; x < s.cols; ++x)
      img(y, x) = 0.5 + 0.3 * std::sin(0.37 * x + 0.11 * y) * std::cos(0.21 * y) + 0.2 * u(rng);
  return img;
}

// Independent reference for SSIM: for every window position where the 11 x 11 window fits, build the 2-D
// Gaussian weights directly, compute the weighted moments in two passes (mean first, then centred
// moments), evaluate eq. (13) of Wang et al. (2004), and average. No separability, no centring trick.
double BruteForceSsim(const Image& x, const Image& y, double peak) {
  const int n = kSsimWindow, half = n / 2;
  Image w(n, n);
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j)
      w(i, j) = std::exp(-((i - half) * (i - half) + (j - half) * (j - half)) / (2.0 * 1.5 * 1.5));
  w /= w.sum();
  const double c1 = std::pow(0.01 * peak, 2), c2 = std::pow(0.03 * peak, 2);
  double total = 0.0;
  int count = 0;
  for (Index r = 0; r + n <= x.rows(); ++r) {
    for (Index c = 0; c + n <= x.cols(); ++c) {
      double mx = 0, my = 0;
      for (int i = 0; i < n; ++i)
        for (int j = 0; j < n; ++j) {
          mx += w(i, j) * x(r + i, c + j);
          my += w(i, j) * y(r + i, c + j);
        }
      double vx = 0, vy = 0, cxy = 0;
      for (int i = 0; i < n; ++i)
        for (int j = 0; j < n; ++j) {
          const double dx = x(r + i, c + j) - mx, dy = y(r + i, c + j) - my;
          vx += w(i, j) * dx * dx;
          vy += w(i, j) * dy * dy;
          cxy += w(i, j) * dx * dy;
        }
      total += (2 * mx * my + c1) * (2 * cxy + c2) / ((mx * mx + my * my + c1) * (vx + vy + c2));
      ++count;
    }
  }
  return total / count;
}

TEST(MetricsTest, RmseIsExactForAKnownDifference) {
  const Image truth = DyadicImage({20, 23}, 1);
  // Alternating ±1/4: every squared error is 1/16, so RMSE = 1/4 with no rounding at all.
  Image estimate = truth;
  for (Index i = 0; i < estimate.size(); ++i) estimate.data()[i] += (i % 2 == 0 ? 0.25 : -0.25);
  EXPECT_EQ(Rmse(truth, estimate), 0.25);
  EXPECT_EQ(Rmse(truth, truth), 0.0);
}

TEST(MetricsTest, PsnrOfAConstantOffset) {
  const Image truth = DyadicImage({16, 16}, 2);
  const double offset = 0.125;  // MSE = 1/64 exactly
  const Image estimate = truth + offset;
  MetricOptions opts;
  opts.peak = 1.0;
  EXPECT_NEAR(Psnr(truth, estimate, opts), 10.0 * std::log10(64.0), 1e-12);  // = 18.0618 dB
  // Derived peak: the truth's data range.
  const double range = truth.maxCoeff() - truth.minCoeff();
  EXPECT_NEAR(Psnr(truth, estimate), 10.0 * std::log10(range * range / (offset * offset)), 1e-12);
}

TEST(MetricsTest, IdenticalImagesGiveInfinitePsnrAndUnitSsim) {
  const Image x = TestScene({32, 40}, 3);
  EXPECT_EQ(Psnr(x, x), std::numeric_limits<double>::infinity());
  EXPECT_DOUBLE_EQ(Ssim(x, x), 1.0);
  const ImageMetrics m = CompareImages(x, x);
  EXPECT_EQ(m.psnr, std::numeric_limits<double>::infinity());
  EXPECT_DOUBLE_EQ(m.ssim, 1.0);
  EXPECT_EQ(m.rmse, 0.0);
}

TEST(MetricsTest, SsimOfTwoConstantImages) {
  // Constant images have σx = σy = σxy = 0 in every window, so eq. (13) reduces to the luminance term:
  //   SSIM = (2ab + C1) C2 / ((a² + b² + C1) C2) = (2ab + C1) / (a² + b² + C1).
  // The truth is constant, so its range is 0: the peak must be stated.
  const double a = 0.3, b = 0.7, peak = 1.0;
  const double c1 = (0.01 * peak) * (0.01 * peak);
  MetricOptions opts;
  opts.peak = peak;
  const double expected = (2 * a * b + c1) / (a * a + b * b + c1);
  EXPECT_NEAR(Ssim(Image::Constant(15, 18, a), Image::Constant(15, 18, b), opts), expected, 1e-15);
  // Non-trivial: it is well below 1 and depends on C1 only through L.
  EXPECT_LT(expected, 0.85);
  opts.peak = 10.0;
  const double c1_big = (0.01 * 10.0) * (0.01 * 10.0);
  EXPECT_NEAR(Ssim(Image::Constant(15, 18, a), Image::Constant(15, 18, b), opts),
              (2 * a * b + c1_big) / (a * a + b * b + c1_big), 1e-15);
}

TEST(MetricsTest, SsimMatchesABruteForceWindowLoop) {
  const Image x = TestScene({37, 43}, 4);
  for (const double alpha : {0.8, 1.3}) {
    const Image y = alpha * x;
    // Derived peak (truth range) and an explicit one.
    const double range = x.maxCoeff() - x.minCoeff();
    EXPECT_NEAR(Ssim(x, y), BruteForceSsim(x, y, range), 1e-12) << "alpha = " << alpha;
    MetricOptions opts;
    opts.peak = 1.0;
    EXPECT_NEAR(Ssim(x, y, opts), BruteForceSsim(x, y, 1.0), 1e-12) << "alpha = " << alpha;
  }
  // A less structured pair too: independent noise on top.
  const Image z = x + 0.1 * TestScene({37, 43}, 5);
  EXPECT_NEAR(Ssim(x, z), BruteForceSsim(x, z, x.maxCoeff() - x.minCoeff()), 1e-12);
}

TEST(MetricsTest, SsimIsRobustToALargeCommonOffset) {
  // With the same explicit L, adding 1e6 to both images changes only the luminance terms (slightly), and
  // must not destroy the σ terms by cancellation: compare against the brute-force loop.
  const Image x = TestScene({30, 30}, 6) + 1e6;
  const Image y = 0.9 * TestScene({30, 30}, 6) + 1e6;
  MetricOptions opts;
  opts.peak = 1.0;
  EXPECT_NEAR(Ssim(x, y, opts), BruteForceSsim(x, y, 1.0), 1e-8);
}

TEST(MetricsTest, SsimMapHasTheValidShapeAndAveragesToSsim) {
  const Image x = TestScene({25, 31}, 7);
  const Image y = 0.7 * x + 0.1;
  MetricOptions opts;
  opts.crop_px = 2;
  const Image map = SsimMap(x, y, opts);
  EXPECT_EQ(map.rows(), 25 - 4 - 10);
  EXPECT_EQ(map.cols(), 31 - 4 - 10);
  EXPECT_NEAR(map.mean(), Ssim(x, y, opts), 1e-15);
  EXPECT_LE(map.maxCoeff(), 1.0);
  EXPECT_GE(map.minCoeff(), -1.0);
}

TEST(MetricsTest, CropIgnoresTheBorderAndMatchesAManualCrop) {
  const Image truth = TestScene({40, 36}, 8);
  Image estimate = truth;
  const int crop = 3;
  // Damage only the border band: outside the crop nothing differs.
  estimate.topRows(crop) += 5.0;
  estimate.bottomRows(crop) -= 2.0;
  estimate.leftCols(crop) += 1.0;
  estimate.rightCols(crop) *= 3.0;
  MetricOptions opts;
  opts.crop_px = crop;
  EXPECT_EQ(Rmse(truth, estimate, opts), 0.0);
  EXPECT_EQ(Psnr(truth, estimate, opts), std::numeric_limits<double>::infinity());
  EXPECT_DOUBLE_EQ(Ssim(truth, estimate, opts), 1.0);
  EXPECT_GT(Rmse(truth, estimate), 0.5);  // without the crop the damage counts

  // With a genuine difference everywhere, the cropped metrics equal the metrics of the cropped images,
  // including the derived peak (taken from the cropped truth, not the full one).
  Image truth_spiky = truth;
  truth_spiky(0, 0) = 100.0;  // in the border: must not set L
  const Image noisy = truth_spiky + 0.05 * TestScene({40, 36}, 9);
  const Image tc = truth_spiky.block(crop, crop, 40 - 2 * crop, 36 - 2 * crop);
  const Image nc = noisy.block(crop, crop, 40 - 2 * crop, 36 - 2 * crop);
  const ImageMetrics cropped = CompareImages(truth_spiky, noisy, opts);
  const ImageMetrics manual = CompareImages(tc, nc);
  EXPECT_NEAR(cropped.rmse, manual.rmse, 1e-15);
  EXPECT_NEAR(cropped.psnr, manual.psnr, 1e-12);
  EXPECT_NEAR(cropped.ssim, manual.ssim, 1e-15);
  EXPECT_TRUE(std::isfinite(cropped.psnr));
}

TEST(MetricsTest, CompareImagesAgreesWithTheSingleMetrics) {
  const Image x = TestScene({28, 33}, 10);
  const Image y = x + 0.07 * TestScene({28, 33}, 11) - 0.03;
  MetricOptions opts;
  opts.peak = 1.0;
  const ImageMetrics m = CompareImages(x, y, opts);
  EXPECT_EQ(m.rmse, Rmse(x, y, opts));
  EXPECT_EQ(m.psnr, Psnr(x, y, opts));
  EXPECT_EQ(m.ssim, Ssim(x, y, opts));
  EXPECT_NEAR(m.psnr, -20.0 * std::log10(m.rmse), 1e-12);  // L = 1
}

TEST(MetricsTest, SsimFallsWithNoiseAndIsSymmetricForAFixedPeak) {
  const Image x = TestScene({40, 40}, 12);
  MetricOptions opts;
  opts.peak = 1.0;
  double previous = 1.0;
  for (const double level : {0.01, 0.05, 0.2, 0.5}) {
    const Image y = x + level * (TestScene({40, 40}, 13) - 0.5);
    const double s = Ssim(x, y, opts);
    EXPECT_LT(s, previous) << "noise level " << level;
    EXPECT_NEAR(s, Ssim(y, x, opts), 1e-14);
    previous = s;
  }
}

TEST(MetricsTest, OptionsValidity) {
  std::string why;
  EXPECT_TRUE(MetricOptions{}.IsValid(&why));
  MetricOptions bad;
  bad.crop_px = -1;
  EXPECT_FALSE(bad.IsValid(&why));
  EXPECT_NE(why.find("crop_px"), std::string::npos);
  bad = MetricOptions{};
  bad.peak = std::numeric_limits<double>::quiet_NaN();
  EXPECT_FALSE(bad.IsValid(nullptr));
  EXPECT_FALSE(bad.IsValid(&why));
  EXPECT_NE(why.find("peak"), std::string::npos);
}

// A band-limited periodic image: random sinusoids with periods that divide the sides and frequencies up to
// half the Nyquist limit, evaluated at (y − dy, x − dx). Its shift is exact, so it is the oracle for both the
// offset and the Fourier shift.
Image BandLimited(Shape s, double dy, double dx, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_int_distribution<int> fy(-static_cast<int>(s.rows) / 4, static_cast<int>(s.rows) / 4);
  std::uniform_int_distribution<int> fx(-static_cast<int>(s.cols) / 4, static_cast<int>(s.cols) / 4);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  struct Wave {
    int ky, kx;
    double amplitude, phase;
  };
  std::vector<Wave> waves;
  for (int i = 0; i < 40; ++i) waves.push_back({fy(rng), fx(rng), u(rng) / (1 + i), 6.283185307179586 * u(rng)});
  Image img = Image::Constant(s.rows, s.cols, 2.0);
  for (Index y = 0; y < s.rows; ++y)
    for (Index x = 0; x < s.cols; ++x)
      for (const Wave& w : waves)
        img(y, x) += w.amplitude * std::cos(6.283185307179586 * (w.ky * (y - dy) / s.rows + w.kx * (x - dx) / s.cols) +
                                            w.phase);
  return img;
}

TEST(MetricsTest, KnownSubPixelShiftIsRecoveredAndAlignedScoresAreHigh) {
  // Tolerance 0.01 px on the offset (the refinement grid is 0.001 px); after alignment the residual is the
  // offset error times the gradient: PSNR > 50 dB (measured ~70), against ~20 dB raw for a 0.37-px shift.
  const Shape s{64, 80};
  const Image truth = BandLimited(s, 0.0, 0.0, 5);
  for (const auto& d : std::vector<ImageOffset>{{0.3737, -1.2345}, {-0.5, 0.5}, {2.7104, 0.0406}, {-0.0043, 0.0081}}) {
    const Image estimate = BandLimited(s, d.dy, d.dx, 5);
    // The Fourier shift reproduces the analytic shift to rounding.
    EXPECT_LT((FourierShiftImage(truth, d.dy, d.dx) - estimate).abs().maxCoeff(), 1e-12);
    const ImageOffset m = MeasureImageOffset(truth, estimate);
    EXPECT_NEAR(m.dy, d.dy, 0.01) << "dy " << d.dy;
    EXPECT_NEAR(m.dx, d.dx, 0.01) << "dx " << d.dx;
    // The aligned scores measure the offset on the crop (apodised): the same shift to the same tolerance.
    const AlignedImageMetrics a = CompareImagesAligned(truth, estimate, MetricOptions{4, 0.0});
    EXPECT_TRUE(a.offset_applied);
    EXPECT_NEAR(a.offset.dy, d.dy, 0.01) << "dy " << d.dy;
    EXPECT_NEAR(a.offset.dx, d.dx, 0.01) << "dx " << d.dx;
    EXPECT_DOUBLE_EQ(a.raw.psnr, CompareImages(truth, estimate, MetricOptions{4, 0.0}).psnr);
    EXPECT_GT(a.aligned.psnr, 50.0) << "offset " << d.dy << ", " << d.dx;
    EXPECT_GT(a.aligned.ssim, 0.9999);
    EXPECT_GT(a.aligned.psnr, a.raw.psnr);
    std::printf("shift (%+.3f, %+.3f): measured (%+.4f, %+.4f), on the crop (%+.4f, %+.4f), PSNR raw %.2f aligned "
                "%.2f dB\n", d.dy, d.dx, m.dy, m.dx, a.offset.dy, a.offset.dx, a.raw.psnr, a.aligned.psnr);
  }
}

TEST(MetricsTest, UnshiftedImageHasZeroOffset) {
  const Image truth = BandLimited({48, 48}, 0.0, 0.0, 9);
  const ImageOffset m = MeasureImageOffset(truth, truth);
  EXPECT_EQ(m.dy, 0.0);
  EXPECT_EQ(m.dx, 0.0);
  // A noisy, rescaled copy still registers at 0 (to 0.01 px).
  std::mt19937_64 rng(3);
  std::normal_distribution<double> noise(0.0, 0.05);
  Image noisy = 1.7 * truth;
  for (Index i = 0; i < noisy.size(); ++i) noisy.data()[i] += noise(rng);
  const ImageOffset n = MeasureImageOffset(truth, noisy);
  EXPECT_NEAR(n.dy, 0.0, 0.01);
  EXPECT_NEAR(n.dx, 0.0, 0.01);
  const AlignedImageMetrics a = CompareImagesAligned(truth, truth);
  EXPECT_TRUE(std::isinf(a.raw.psnr));
  EXPECT_TRUE(std::isinf(a.aligned.psnr));
}

TEST(MetricsTest, OffsetFollowsThePixelCentreConvention) {
  // +dx moves the scene toward +x (image.hpp): a point moved from column 10 to 12 measures dx = +2.
  Image truth = Image::Zero(32, 32), estimate = Image::Zero(32, 32);
  truth(7, 10) = 1.0;
  estimate(6, 12) = 1.0;
  const ImageOffset m = MeasureImageOffset(truth, estimate);
  EXPECT_NEAR(m.dy, -1.0, 1e-9);
  EXPECT_NEAR(m.dx, 2.0, 1e-9);
}

// ---- The offset where it is scored, and the aligned >= raw guarantee (issue 31) ----------------------------

// A smooth scene that is NOT periodic: Gaussian blobs (some cut by the edges) on a tilted plane, evaluated at
// (y − dy, x − dx) and blurred by a Gaussian of σ = blur px (a blob of σ_b becomes one of σ = √(σ_b² + blur²) with
// the same flux; the plane is unchanged): an exact, symmetric blur and an exact shift, with no periodic wrap.
Image SmoothNonPeriodic(Shape s, double dy, double dx, double blur, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  struct Blob {
    double y, x, sigma, flux;
  };
  std::vector<Blob> blobs;
  for (int i = 0; i < 60; ++i)
    blobs.push_back({-4 + (s.rows + 8) * u(rng), -4 + (s.cols + 8) * u(rng), 1.2 + 3.0 * u(rng), 20 + 80 * u(rng)});
  Image img(s.rows, s.cols);
  for (Index y = 0; y < s.rows; ++y)
    for (Index x = 0; x < s.cols; ++x) {
      const double py = y - dy, px = x - dx;
      double v = 1.0 + 0.02 * py + 0.035 * px;  // the plane: a step of several units where the grid wraps
      for (const Blob& b : blobs) {
        const double var = b.sigma * b.sigma + blur * blur;
        v += b.flux / (6.283185307179586 * var) * std::exp(-((py - b.y) * (py - b.y) + (px - b.x) * (px - b.x)) / (2 * var));
      }
      img(y, x) = v;
    }
  return img;
}

// A sharp-edged scene (not band-limited): random discs of constant grey, point-sampled on the pixel grid.
Image SharpDiscs(Shape s, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  Image img = Image::Constant(s.rows, s.cols, 0.2);
  for (int i = 0; i < 40; ++i) {
    const double cy = s.rows * u(rng), cx = s.cols * u(rng), r = 2 + 10 * u(rng), g = u(rng);
    for (Index y = 0; y < s.rows; ++y)
      for (Index x = 0; x < s.cols; ++x)
        if ((y - cy) * (y - cy) + (x - cx) * (x - cx) < r * r) img(y, x) = g;
  }
  return img;
}

Image AddNoise(Image img, double sigma, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> n(0.0, sigma);
  for (Index i = 0; i < img.size(); ++i) img.data()[i] += n(rng);
  return img;
}

// What a periodic reconstructor does at the border: the outer `border` px replaced by the scene wrapped around
// from the opposite side, moved by a few pixels (asymmetric, so it pulls a whole-image correlation).
Image WithWrappedBorder(const Image& img, int border) {
  Image out = img;
  const Index rows = img.rows(), cols = img.cols();
  for (Index y = 0; y < rows; ++y)
    for (Index x = 0; x < cols; ++x)
      if (y < border || x < border || y >= rows - border || x >= cols - border)
        out(y, x) = img((y + rows / 2) % rows, (x + cols / 2 + 3) % cols);
  return out;
}

// The failure, reproduced: an estimate that is the truth blurred symmetrically (no offset at all) with
// a border a periodic reconstructor gets wrong. The whole-image correlation is pulled by the border and the
// wrap (0.3-11 px here); the offset measured on the crop is ~0, and the aligned scores are at least the raw ones.
// Tolerance 0.03 px: the least-squares shift of a BLURRED estimate against the sharp truth over a finite region
// carries a boundary term (Σ over the region of t·∇(Bt) vanishes only on an unbounded domain), largest where the
// scene is brightest at the region's edge (the tilted plane here); measured 0.001-0.021 px.
TEST(MetricsTest, OffsetMeasuredOnTheCropIsNotPulledByTheBorder) {
  const Shape s{96, 112};
  for (std::uint64_t seed : {1u, 2u, 3u}) {
    const Image truth = SmoothNonPeriodic(s, 0, 0, 0.0, seed);
    const Image estimate = AddNoise(WithWrappedBorder(SmoothNonPeriodic(s, 0, 0, 1.5, seed), 8), 0.01, seed);
    const ImageOffset whole = MeasureImageOffset(truth, estimate);
    const AlignedImageMetrics a = CompareImagesAligned(truth, estimate, MetricOptions{10, 0.0});
    std::printf("seed %d: whole-image offset (%+.4f, %+.4f), on the crop (%+.4f, %+.4f), applied %d; PSNR raw %.3f "
                "aligned %.3f dB\n", int(seed), whole.dy, whole.dx, a.measured_offset.dy, a.measured_offset.dx,
                int(a.offset_applied), a.raw.psnr, a.aligned.psnr);
    EXPECT_NEAR(a.measured_offset.dy, 0.0, 0.03) << "seed " << seed;
    EXPECT_NEAR(a.measured_offset.dx, 0.0, 0.03) << "seed " << seed;
    EXPECT_GT(std::hypot(whole.dy, whole.dx), 0.25) << "seed " << seed;  // the whole image's pull, for comparison
    EXPECT_GE(a.aligned.psnr, a.raw.psnr);
    EXPECT_GE(a.aligned.ssim, a.raw.ssim);
  }
}

// A known sub-pixel shift of a non-periodic scene (the plane makes a step where the grid wraps): recovered on the
// crop to 0.01 px with noise, and to 0.03 px when the estimate is also blurred (the boundary term above; measured
// up to 0.024 px), where alignment then recovers the part of the loss that the offset causes (the blur stays).
TEST(MetricsTest, KnownShiftOfANonPeriodicSceneIsRecoveredOnTheCrop) {
  const Shape s{80, 96};
  for (const auto& d : std::vector<ImageOffset>{{0.31, -0.47}, {-0.5, 0.12}, {1.73, 0.66}}) {
    for (double blur : {0.0, 1.2}) {
      const Image truth = SmoothNonPeriodic(s, 0, 0, 0.0, 7);
      const Image estimate = AddNoise(SmoothNonPeriodic(s, d.dy, d.dx, blur, 7), 0.005, 8);
      const AlignedImageMetrics a = CompareImagesAligned(truth, estimate, MetricOptions{6, 0.0});
      const double tolerance = blur > 0 ? 0.03 : 0.01;
      EXPECT_TRUE(a.offset_applied) << d.dy << ", " << d.dx << " blur " << blur;
      EXPECT_NEAR(a.offset.dy, d.dy, tolerance) << d.dy << ", " << d.dx << " blur " << blur;
      EXPECT_NEAR(a.offset.dx, d.dx, tolerance) << d.dy << ", " << d.dx << " blur " << blur;
      EXPECT_GT(a.aligned.psnr, a.raw.psnr + (blur > 0 ? 1.0 : 10.0)) << d.dy << ", " << d.dx << " blur " << blur;
      std::printf("shift (%+.2f, %+.2f) blur %.1f: measured (%+.4f, %+.4f), PSNR raw %.2f aligned %.2f dB\n", d.dy, d.dx,
                  blur, a.offset.dy, a.offset.dx, a.raw.psnr, a.aligned.psnr);
    }
  }
}

// The guarantee, on cases where a Fourier shift can only hurt or barely help: aligned PSNR and SSIM are never below
// the raw ones (not even by rounding: the measured offset is applied only when it does not lower them), on the
// crop and in every ring.
TEST(MetricsTest, AlignedScoresAreNeverBelowRaw) {
  const Shape s{72, 88};
  struct Case {
    const char* name;
    Image truth, estimate;
  };
  const Image smooth = SmoothNonPeriodic(s, 0, 0, 0.0, 11);
  const Image sharp = SharpDiscs(s, 12);
  std::vector<Case> cases;
  cases.push_back({"symmetric blur, wrapped border", smooth, WithWrappedBorder(SmoothNonPeriodic(s, 0, 0, 1.5, 11), 6)});
  cases.push_back({"shifted 0.3, 0.2 px, noisy", smooth, AddNoise(SmoothNonPeriodic(s, 0.3, 0.2, 0.0, 11), 0.05, 13)});
  cases.push_back({"noise only", smooth, AddNoise(smooth, 0.3, 14)});
  cases.push_back({"sharp edges, small noise", sharp, AddNoise(sharp, 0.002, 15)});
  cases.push_back({"sharp edges, blurred by a box", sharp,
                   Image(0.25 * (sharp + FourierShiftImage(sharp, 0, 1) + FourierShiftImage(sharp, 1, 0) +
                                 FourierShiftImage(sharp, 1, 1)))});
  cases.push_back({"contrast 0.8, shifted", smooth, Image(0.8 * SmoothNonPeriodic(s, -0.4, 0.25, 0.8, 11) + 0.1)});
  cases.push_back({"truth itself", smooth, smooth});
  for (const Case& c : cases) {
    for (int crop : {0, 5}) {
      const AlignedImageMetrics a = CompareImagesAligned(c.truth, c.estimate, MetricOptions{crop, 0.0});
      EXPECT_GE(a.aligned.psnr, a.raw.psnr) << c.name << " crop " << crop;
      EXPECT_GE(a.aligned.ssim, a.raw.ssim) << c.name << " crop " << crop;
      if (!a.offset_applied) {
        EXPECT_EQ(a.offset.dy, 0.0);
        EXPECT_EQ(a.offset.dx, 0.0);
        EXPECT_EQ(a.aligned.psnr, a.raw.psnr);
      }
      const RingMetrics rings = CompareImagesInRings(c.truth, c.estimate, RingOptions{3}, MetricOptions{crop, 0.0});
      for (const RingScore& r : rings.rings) {
        EXPECT_GE(r.scores.aligned.psnr, r.scores.raw.psnr) << c.name << " ring " << r.inner_px;
        EXPECT_GE(r.scores.aligned.ssim, r.scores.raw.ssim) << c.name << " ring " << r.inner_px;
      }
      std::printf("%-32s crop %d: offset (%+.3f, %+.3f) applied %d, PSNR raw %.3f aligned %.3f dB\n", c.name, crop,
                  a.measured_offset.dy, a.measured_offset.dx, int(a.offset_applied), a.raw.psnr, a.aligned.psnr);
    }
  }
}

// ---- Scores in rings ---------------------------------------------------------------------------------------

TEST(MetricsTest, RingRadiiCountsAndAreas) {
  const Shape s{96, 128};
  const Image truth = BandLimited(s, 0, 0, 21);
  const Image estimate = AddNoise(truth, 0.05, 22);
  const int crop = 4, k_rings = 4;
  const RingMetrics m = CompareImagesInRings(truth, estimate, RingOptions{k_rings}, MetricOptions{crop, 0.0});
  EXPECT_EQ(m.centre_y, 47.5);  // (R − 1)/2, (C − 1)/2
  EXPECT_EQ(m.centre_x, 63.5);
  EXPECT_EQ(m.peak, truth.block(crop, crop, 88, 120).maxCoeff() - truth.block(crop, crop, 88, 120).minCoeff());
  ASSERT_EQ(m.rings.size(), std::size_t(k_rings));
  const double rho_max = std::hypot(47.5 - crop, 63.5 - crop);  // to a corner pixel centre of the crop
  Index pixels = 0, positions = 0;
  double mse_sum = 0.0;
  for (int k = 0; k < k_rings; ++k) {
    const RingScore& r = m.rings[std::size_t(k)];
    EXPECT_NEAR(r.inner_px, k * rho_max / k_rings, 1e-12);
    EXPECT_NEAR(r.outer_px, (k + 1) * rho_max / k_rings, 1e-12);
    EXPECT_NEAR(r.area_px, kPi * (r.outer_px * r.outer_px - r.inner_px * r.inner_px), 1e-9);
    // Brute force: the crop's pixel centres in the ring, and the SSIM window centres (5 px inside the crop).
    Index n = 0, p = 0;
    double se = 0.0;
    for (Index y = crop; y < s.rows - crop; ++y)
      for (Index x = crop; x < s.cols - crop; ++x) {
        const double rho = std::hypot(y - 47.5, x - 63.5);
        if (rho >= r.inner_px && (rho < r.outer_px || k + 1 == k_rings)) {
          ++n;
          se += (estimate(y, x) - truth(y, x)) * (estimate(y, x) - truth(y, x));
          if (y >= crop + 5 && y < s.rows - crop - 5 && x >= crop + 5 && x < s.cols - crop - 5) ++p;
        }
      }
    EXPECT_EQ(r.pixels, n) << "ring " << k;
    EXPECT_EQ(r.ssim_positions, p) << "ring " << k;
    EXPECT_NEAR(r.scores.raw.rmse, std::sqrt(se / n), 1e-12);
    // Rings inside the crop hold about their area in pixels (lattice points in an annulus); the outer ring is cut.
    if (r.outer_px < 43.5) {
      EXPECT_NEAR(double(n), r.area_px, 0.03 * r.area_px + 10) << "ring " << k;
    }
    pixels += n;
    positions += p;
    mse_sum += se;
  }
  EXPECT_LT(double(m.rings.back().pixels), 0.7 * m.rings.back().area_px);
  EXPECT_EQ(pixels, Index(88) * 120);
  EXPECT_EQ(positions, Index(78) * 110);
  // The rings partition the crop: their squared errors add up to the crop's.
  const ImageMetrics whole = CompareImages(truth, estimate, MetricOptions{crop, 0.0});
  EXPECT_NEAR(mse_sum / pixels, whole.rmse * whole.rmse, 1e-12);
  // A centre in a corner: quarter discs.
  const RingMetrics corner = CompareImagesInRings(truth, estimate, RingOptions{2, 0.0, 0.0}, MetricOptions{0, 0.0});
  EXPECT_NEAR(corner.rings[1].outer_px, std::hypot(95.0, 127.0), 1e-12);
  EXPECT_NEAR(double(corner.rings[0].pixels), corner.rings[0].area_px / 4, 0.05 * corner.rings[0].area_px / 4);
  // A centre in the crop's border: the rings start at its distance from the crop's nearest pixel centre.
  const RingMetrics border = CompareImagesInRings(truth, estimate, RingOptions{2, 1.0, 60.0}, MetricOptions{crop, 0.0});
  EXPECT_NEAR(border.rings[0].inner_px, 3.0, 1e-12);
}

// Noise only outside the third ring: the loss shows there and nowhere else (PSNR infinite and SSIM 1 inside, raw and
// aligned; the outer ring's PSNR is exactly that of the noise added there, with the crop's dynamic range).
TEST(MetricsTest, NoiseInTheOuterRingShowsOnlyThere) {
  const Shape s{128, 128};
  const Image truth = BandLimited(s, 0, 0, 31);
  const double rho_max = std::hypot(63.5, 63.5), r3 = 0.75 * rho_max;
  std::mt19937_64 rng(32);
  std::normal_distribution<double> noise(0.0, 0.05);
  Image estimate = truth;
  double se = 0.0;
  Index n = 0;
  for (Index y = 0; y < s.rows; ++y)
    for (Index x = 0; x < s.cols; ++x)
      if (std::hypot(y - 63.5, x - 63.5) >= r3) {
        const double e = noise(rng);
        estimate(y, x) += e;
        se += e * e;
        ++n;
      }
  const RingMetrics m = CompareImagesInRings(truth, estimate, RingOptions{4});
  ASSERT_EQ(m.rings.size(), 4u);
  EXPECT_NEAR(m.rings[3].inner_px, r3, 1e-12);
  for (int k = 0; k < 3; ++k) {
    const RingScore& r = m.rings[std::size_t(k)];
    EXPECT_TRUE(std::isinf(r.scores.raw.psnr)) << "ring " << k;
    EXPECT_TRUE(std::isinf(r.scores.aligned.psnr)) << "ring " << k;
    EXPECT_EQ(r.scores.offset.dy, 0.0);
    EXPECT_EQ(r.scores.offset.dx, 0.0);
  }
  // SSIM windows reach 5 px (7 diagonally) beyond their centre: rings 0 and 1 never see the noise.
  EXPECT_NEAR(m.rings[0].scores.raw.ssim, 1.0, 1e-12);
  EXPECT_NEAR(m.rings[1].scores.raw.ssim, 1.0, 1e-12);
  EXPECT_LT(m.rings[3].scores.raw.ssim, 0.99);
  const double range = truth.maxCoeff() - truth.minCoeff();
  EXPECT_EQ(m.rings[3].pixels, n);
  EXPECT_NEAR(m.rings[3].scores.raw.psnr, 10 * std::log10(range * range / (se / n)), 1e-9);
  EXPECT_GE(m.rings[3].scores.aligned.psnr, m.rings[3].scores.raw.psnr);
  const ImageMetrics whole = CompareImages(truth, estimate);
  EXPECT_GT(whole.psnr, m.rings[3].scores.raw.psnr);  // diluted by the clean rings
  std::printf("outer ring PSNR %.2f dB SSIM %.4f; whole image %.2f dB; ring 2 SSIM %.6f\n", m.rings[3].scores.raw.psnr,
              m.rings[3].scores.raw.ssim, whole.psnr, m.rings[2].scores.raw.ssim);
}

// Each ring is aligned on its own: the scene moved by a sub-pixel offset only beyond the second ring is measured
// there (to 0.01 px) and not in the inner rings, which are the truth itself (offset 0, PSNR infinite).
TEST(MetricsTest, EachRingIsAlignedOnItsOwn) {
  const Shape s{128, 128};
  const Image truth = BandLimited(s, 0, 0, 41);
  const ImageOffset d{0.35, -0.25};
  const Image moved = BandLimited(s, d.dy, d.dx, 41);
  const double rho_max = std::hypot(63.5, 63.5), w = rho_max / 4;
  // Blend from the truth to the moved scene across the outer half of ring 1, so rings 2 and 3 are all moved.
  Image estimate(s.rows, s.cols);
  for (Index y = 0; y < s.rows; ++y)
    for (Index x = 0; x < s.cols; ++x) {
      const double t = std::clamp((std::hypot(y - 63.5, x - 63.5) - 1.5 * w) / (0.5 * w), 0.0, 1.0);
      estimate(y, x) = (1 - t) * truth(y, x) + t * moved(y, x);
    }
  const RingMetrics m = CompareImagesInRings(truth, estimate, RingOptions{4});
  EXPECT_TRUE(std::isinf(m.rings[0].scores.aligned.psnr));
  EXPECT_EQ(m.rings[0].scores.offset.dy, 0.0);
  EXPECT_EQ(m.rings[0].scores.offset.dx, 0.0);
  for (int k : {2, 3}) {
    const AlignedImageMetrics& a = m.rings[std::size_t(k)].scores;
    EXPECT_TRUE(a.offset_applied) << "ring " << k;
    EXPECT_NEAR(a.offset.dy, d.dy, 0.01) << "ring " << k;
    EXPECT_NEAR(a.offset.dx, d.dx, 0.01) << "ring " << k;
    EXPECT_GT(a.aligned.psnr, a.raw.psnr + 10) << "ring " << k;
    std::printf("ring %d: offset (%+.4f, %+.4f), PSNR raw %.2f aligned %.2f dB\n", k, a.offset.dy, a.offset.dx,
                a.raw.psnr, a.aligned.psnr);
  }
}

// One ring about the image centre is the whole crop: its raw scores are CompareImages'.
TEST(MetricsTest, OneRingIsTheWholeCrop) {
  const Shape s{64, 72};
  const Image truth = SmoothNonPeriodic(s, 0, 0, 0, 51);
  const Image estimate = AddNoise(SmoothNonPeriodic(s, 0.2, -0.1, 1.0, 51), 0.02, 52);
  const RingMetrics m = CompareImagesInRings(truth, estimate, RingOptions{1}, MetricOptions{3, 0.0});
  const ImageMetrics whole = CompareImages(truth, estimate, MetricOptions{3, 0.0});
  ASSERT_EQ(m.rings.size(), 1u);
  EXPECT_NEAR(m.rings[0].scores.raw.psnr, whole.psnr, 1e-9);
  EXPECT_NEAR(m.rings[0].scores.raw.ssim, whole.ssim, 1e-12);
  EXPECT_NEAR(m.rings[0].scores.raw.rmse, whole.rmse, 1e-12);
  EXPECT_EQ(m.rings[0].pixels, Index(58) * 66);
}

}  // namespace
}  // namespace aosr

