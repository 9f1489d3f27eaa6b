#include "aosr/core/metrics.hpp"

#include <gtest/gtest.h>

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
    const AlignedImageMetrics a = CompareImagesAligned(truth, estimate, MetricOptions{4, 0.0});
    EXPECT_EQ(a.offset.dy, m.dy);
    EXPECT_EQ(a.offset.dx, m.dx);
    EXPECT_DOUBLE_EQ(a.raw.psnr, CompareImages(truth, estimate, MetricOptions{4, 0.0}).psnr);
    EXPECT_GT(a.aligned.psnr, 50.0) << "offset " << d.dy << ", " << d.dx;
    EXPECT_GT(a.aligned.ssim, 0.9999);
    EXPECT_GT(a.aligned.psnr, a.raw.psnr);
    std::printf("shift (%+.3f, %+.3f): measured (%+.4f, %+.4f), PSNR raw %.2f aligned %.2f dB\n", d.dy, d.dx, m.dy,
                m.dx, a.raw.psnr, a.aligned.psnr);
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

}  // namespace
}  // namespace aosr

