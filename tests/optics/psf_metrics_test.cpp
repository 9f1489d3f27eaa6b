#include "aosr/optics/psf_metrics.hpp"

#include <gtest/gtest.h>

#include <cmath>

namespace aosr {
namespace AOSR_TEST_NS {

// A well-sampled circular Gaussian: equivalent-area FWHM = 2 sqrt(2 ln 2) sigma, EE(ρ) = 1 - exp(-ρ²/2σ²).
TEST(PsfMetricsTest, GaussianFwhmAndEncircledEnergy) {
  const double sigma = 6.0;
  Image g(129, 129);
  for (Index y = 0; y < 129; ++y)
    for (Index x = 0; x < 129; ++x) g(y, x) = std::exp(-((y - 64.0) * (y - 64.0) + (x - 64.0) * (x - 64.0)) / (2 * sigma * sigma));
  const PsfStats s = MeasurePsf(g);
  EXPECT_EQ(s.peak_y, 64);
  EXPECT_NEAR(s.centroid_x, 64.0, 1e-12);
  EXPECT_NEAR(s.fwhm_px, 2 * std::sqrt(2 * std::log(2.0)) * sigma, 0.1);  // pixel counting: ±0.1 px at this size
  const auto ee = EncircledEnergy(g, {sigma, 2 * sigma});
  EXPECT_NEAR(ee[0], 1 - std::exp(-0.5), 0.01);
  EXPECT_NEAR(ee[1], 1 - std::exp(-2.0), 0.01);
}

// The core centroid finds a displaced core to ~1e-3 px and ignores a far, one-sided halo that moves the plain
// centroid by more than a pixel.
TEST(PsfMetricsTest, CoreCentroidFollowsTheCoreNotTheHalo) {
  const double sigma = 1.5, cy = 32.3, cx = 31.8;
  Image g(64, 64);
  for (Index y = 0; y < 64; ++y)
    for (Index x = 0; x < 64; ++x)
      g(y, x) = std::exp(-((y - cy) * (y - cy) + (x - cx) * (x - cx)) / (2 * sigma * sigma)) + (x > 50 ? 0.02 : 0.0);
  const auto core = CoreCentroid(g, 4 * sigma);
  EXPECT_NEAR(core.first, cy, 2e-3);
  EXPECT_NEAR(core.second, cx, 2e-3);
  EXPECT_GT(MeasurePsf(g).centroid_x, cx + 1.0);
}

}  // namespace
}  // namespace aosr
