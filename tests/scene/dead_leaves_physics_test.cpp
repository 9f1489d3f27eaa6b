// The dead-leaves texture: complete coverage, determinism, and the natural-image power law.
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <vector>

#include "aosr/core/fft.hpp"
#include "aosr/scene/dead_leaves.hpp"

namespace aosr {
namespace {

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
