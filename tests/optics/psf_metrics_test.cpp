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

// An elliptical Gaussian (sigma 3 and 2 px, major axis at +30 degrees from +x toward +y, i.e. toward larger
// rows): the half-maximum region is an ellipse of semi-axes sqrt(2 ln 2) sigma, so the major and minor FWHM are
// 2 sqrt(2 ln 2) sigma (within 2 %) and the angle is +30 degrees (within 0.5). A circular one: ratio 1.
TEST(PsfMetricsTest, EllipticalCoreElongationAndAngle) {
  const double s1 = 3.0, s2 = 2.0, psi = 30.0 * M_PI / 180.0;
  Image g(64, 64);
  for (Index y = 0; y < 64; ++y)
    for (Index x = 0; x < 64; ++x) {
      const double dx = x - 31.7, dy = y - 32.2;
      const double u = dx * std::cos(psi) + dy * std::sin(psi), v = -dx * std::sin(psi) + dy * std::cos(psi);
      g(y, x) = std::exp(-0.5 * (u * u / (s1 * s1) + v * v / (s2 * s2)));
    }
  const PsfStats s = MeasurePsf(g);
  const double k = 2 * std::sqrt(2 * std::log(2.0));
  EXPECT_NEAR(s.fwhm_major_px / (k * s1), 1.0, 0.02);
  EXPECT_NEAR(s.fwhm_minor_px / (k * s2), 1.0, 0.02);
  EXPECT_NEAR(s.Elongation(), 1.5, 0.03);
  EXPECT_NEAR(s.major_axis_angle_rad * 180.0 / M_PI, 30.0, 0.5);
  Image round(64, 64);
  for (Index y = 0; y < 64; ++y)
    for (Index x = 0; x < 64; ++x) round(y, x) = std::exp(-((y - 32.0) * (y - 32.0) + (x - 32.0) * (x - 32.0)) / 8.0);
  EXPECT_NEAR(MeasurePsf(round).Elongation(), 1.0, 0.01);
}

}  // namespace
}  // namespace aosr
