// The dead-leaves texture: complete coverage, determinism, and the natural-image power law.
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <vector>

#include "aosr/core/fft.hpp"
#include "aosr/scene/dead_leaves.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

// Least-squares slope of log P(f) against log f of the radially averaged power spectrum (annuli of width one
// frequency bin, mean removed) over f in [f_lo, f_hi] cycles per pixel.
double SpectralSlope(const Image& img, double f_lo, double f_hi) {
  const Index n = img.rows();
  const ComplexImage spec = FftR2C(img - img.mean());
  std::vector<double> power(n, 0.0), count(n, 0.0);
  for (Index u = 0; u < n; ++u)
    for (Index v = 0; v < spec.cols(); ++v) {
      const double fy = double(SignedFrequency(u, n)), fx = double(v);
      const Index k = static_cast<Index>(std::lround(std::hypot(fy, fx)));
      if (k >= n) continue;
      const double w = (v == 0 || 2 * v == n) ? 1.0 : 2.0;  // the half spectrum holds both ±v
      power[k] += w * std::norm(spec(u, v));
      count[k] += w;
    }
  double sx = 0, sy = 0, sxx = 0, sxy = 0, m = 0;
  for (Index k = 1; k < n; ++k) {
    const double f = double(k) / n;
    if (f < f_lo || f > f_hi || count[k] == 0) continue;
    const double x = std::log(f), y = std::log(power[k] / count[k]);
    sx += x;
    sy += y;
    sxx += x * x;
    sxy += x * y;
    ++m;
  }
  return (m * sxy - sx * sy) / (m * sxx - sx * sx);
}

TEST(DeadLeavesTest, CoversTheFieldAndIsDeterministic) {
  DeadLeavesOptions options;
  DeadLeavesSummary summary, again;
  const auto t0 = std::chrono::steady_clock::now();
  const Image a = DeadLeaves({256, 192}, options, 17, &summary);
  const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  const Image b = DeadLeaves({256, 192}, options, 17, &again);
  std::printf("256x192, s = 4: %lld leaves drawn, %lld visible, %lld samples, %.0f ms\n",
              static_cast<long long>(summary.leaves_drawn), static_cast<long long>(summary.leaves_visible),
              static_cast<long long>(summary.samples), ms);
  EXPECT_TRUE(summary.complete());
  EXPECT_EQ(summary.uncovered_samples, 0);
  EXPECT_EQ(summary.samples, 256LL * 192 * 16);
  EXPECT_GT(summary.leaves_visible, 100);
  EXPECT_LE(summary.leaves_visible, summary.leaves_drawn);
  EXPECT_TRUE(AllFinite(a));
  EXPECT_GE(a.minCoeff(), options.grey_min);
  EXPECT_LT(a.maxCoeff(), options.grey_max);
  EXPECT_EQ((a - b).abs().maxCoeff(), 0.0);
  EXPECT_EQ(summary.leaves_drawn, again.leaves_drawn);
  EXPECT_GT((a - DeadLeaves({256, 192}, options, 18)).abs().maxCoeff(), 0.1);
}

TEST(DeadLeavesTest, LeafCapLeavesReportedHoles) {
  DeadLeavesOptions options;
  options.max_leaves = 10;
  DeadLeavesSummary summary;
  const Image img = DeadLeaves({64, 64}, options, 1, &summary);
  EXPECT_EQ(summary.leaves_drawn, 10);
  EXPECT_FALSE(summary.complete());
  EXPECT_GT(summary.uncovered_samples, 0);
  EXPECT_TRUE(AllFinite(img));
}

TEST(DeadLeavesTest, LeavesMuchLargerThanTheFieldCostNothingExtra) {
  // Window-meeting leaves are proposed directly, so r_max >> field wastes no draws: with r_max = 5000 on an
  // 8x8 field nearly every accepted leaf is huge and one or two of them cover the field.
  DeadLeavesOptions options;
  options.r_min_px = 1000.0;
  options.r_max_px = 5000.0;
  DeadLeavesSummary summary;
  const Image img = DeadLeaves({8, 8}, options, 9, &summary);
  EXPECT_TRUE(summary.complete());
  EXPECT_LE(summary.leaves_drawn, 2);
  EXPECT_EQ(img.maxCoeff(), img.minCoeff());
}

TEST(DeadLeavesTest, SingleSamplePixelsHoldLeafGreys) {
  // supersample = 1 is point sampling: every pixel is exactly one leaf's grey level (no anti-aliasing mix).
  DeadLeavesOptions options;
  options.supersample = 1;
  options.grey_min = 2.0;
  options.grey_max = 3.0;
  DeadLeavesSummary summary;
  const Image img = DeadLeaves({64, 64}, options, 4, &summary);
  EXPECT_TRUE(summary.complete());
  EXPECT_GE(img.minCoeff(), 2.0);
  EXPECT_LT(img.maxCoeff(), 3.0);
}

// P(two points at distance d lie on the same visible leaf) for the stationary dead-leaves model with discs:
// E[lens area] / E[union area] over the radius law (Matheron 1968; Bordenave, Gousseau & Roueff 2006), with
// lens(r, d) = 2 r² acos(d / 2r) - (d / 2) sqrt(4 r² - d²) for d < 2r. Trapezoid rule in log r.
double SameLeafProbability(double d, double alpha, double r_min, double r_max) {
  const int steps = 200000;
  double lens = 0.0, unions = 0.0;
  for (int k = 0; k <= steps; ++k) {
    const double t = std::log(r_min) + (std::log(r_max) - std::log(r_min)) * k / steps;
    const double r = std::exp(t);
    const double w =
        (k == 0 || k == steps ? 0.5 : 1.0) * std::pow(r, 1.0 - alpha);  // p(r) dr = r^-alpha r dt
    const double l =
        d < 2 * r ? 2 * r * r * std::acos(d / (2 * r)) - 0.5 * d * std::sqrt(4 * r * r - d * d) : 0.0;
    lens += w * l;
    unions += w * (2 * M_PI * r * r - l);
  }
  return lens / unions;
}

TEST(DeadLeavesTest, SameLeafProbabilityMatchesTheModel) {
  // Point sampling (supersample = 1): two pixels at distance d share a grey level iff they lie on the same
  // leaf. The oracle checks the whole sampler (radius law, window-meeting proposals, occlusion order) on
  // every scale. r_max = 64 on a 96-pixel field exercises leaves centred outside it. The tolerance is 4
  // standard errors of the mean over seeds (per-seed values are independent), plus 0.002 for the model's
  // quadrature.
  DeadLeavesOptions options;
  options.supersample = 1;
  options.r_min_px = 1.0;
  options.r_max_px = 64.0;
  const Index n = 96;
  const int seeds = 64;
  for (int d : {1, 3, 8, 20}) {
    double sum = 0.0, sum2 = 0.0;
    for (int s = 0; s < seeds; ++s) {
      const Image img = DeadLeaves({n, n}, options, 500 + s);
      double same = 0.0, pairs = 0.0;
      for (Index i = 0; i < n; ++i)
        for (Index j = 0; j + d < n; ++j) {
          same += img(i, j) == img(i, j + d) ? 1.0 : 0.0;
          same += img(j, i) == img(j + d, i) ? 1.0 : 0.0;
          pairs += 2.0;
        }
      sum += same / pairs;
      sum2 += (same / pairs) * (same / pairs);
    }
    const double measured = sum / seeds;
    const double se = std::sqrt((sum2 / seeds - measured * measured) / (seeds - 1));
    const double expected =
        SameLeafProbability(d, options.radius_exponent, options.r_min_px, options.r_max_px);
    std::printf("d = %2d px: P(same leaf) measured %.4f +- %.4f, model %.4f\n", d, measured, se, expected);
    EXPECT_NEAR(measured, expected, 4.0 * se + 0.002);
  }
}

TEST(DeadLeavesTest, RadiallyAveragedPowerSpectrumFollowsANaturalImagePowerLaw) {
  // Scale-invariant leaves (alpha = 3) between 1 and 64 px: the power spectrum falls as ~ f^-2 between
  // 1/r_max and 1/r_min, steepening toward f^-3 above. Averaged over a few seeds to tame the large-leaf
  // variance.
  DeadLeavesOptions options;
  const double lo = 1.0 / 64.0, hi = 1.0 / 4.0;
  double mean = 0.0;
  const int seeds = 4;
  for (int s = 0; s < seeds; ++s) {
    const double slope = SpectralSlope(DeadLeaves({256, 256}, options, 100 + s), lo, hi);
    std::printf("seed %d: power-spectrum slope over f in [1/64, 1/4] cycles/px = %.3f\n", 100 + s, slope);
    EXPECT_GT(slope, -3.5);
    EXPECT_LT(slope, -1.5);
    mean += slope / seeds;
  }
  std::printf("mean slope %.3f\n", mean);
  EXPECT_GT(mean, -3.0);
  EXPECT_LT(mean, -1.7);
}

}  // namespace
}  // namespace aosr
