#include <gtest/gtest.h>

#include <cmath>

#include "aosr/scene/photometry.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

// "A magnitude-12 source in K, 10 s split over 16 frames, 8 m telescope with a 14% obstruction, 50%
// throughput", by hand:
//   Φ₀ = f_λ Δλ λ / (h c) = 3.961e-10 W m⁻² µm⁻¹ · 0.41 µm · 2.19e-6 m / (6.62607015e-34 · 299792458)
//      = 1.7904e9 photons s⁻¹ m⁻²
//   Φ  = Φ₀ · 10^(−0.4·12) = 2.8376e4 photons s⁻¹ m⁻²
//   A  = π/4 · 8² · (1 − 0.14²) = 49.280 m²
//   rate = Φ A · 0.5 = 6.9920e5 e⁻ s⁻¹;  per frame · 10/16 = 4.3700e5 e⁻.
TEST(PhotometryPhysicsTest, MagnitudeToElectronsMatchesTheHandCalculation) {
  LightCollectorOptions c;
  c.diameter_m = 8.0;
  c.obstruction = 0.14;
  c.throughput = 0.5;
  const double per_frame = ElectronsPerFrame(SourceFlux::Magnitude(12, "K"), c, ExposurePlan{10.0, 16});
  const double phi0 = 3.961e-10 * 0.41 * 2.19e-6 / (6.62607015e-34 * 299792458.0);
  const double exact = phi0 * std::pow(10.0, -4.8) * (M_PI / 4 * 64 * (1 - 0.14 * 0.14)) * 0.5 * 10.0 / 16.0;
  EXPECT_NEAR(per_frame / exact, 1.0, 1e-12);
  EXPECT_NEAR(per_frame / 4.3700e5, 1.0, 1e-4);  // the rounded figures above
  EXPECT_NEAR(VegaBand("K").zero_point_photons / 1.7904e9, 1.0, 1e-4);
}

// Sky of 13 mag/arcsec² in K on 10 mas pixels: Φ₀ 10^−5.2 · A τ · (0.01)² = 27.84 e⁻ s⁻¹ px⁻¹, and a fill
// factor F collects F² of it.
TEST(PhotometryPhysicsTest, SkyBackgroundPerPixel) {
  LightCollectorOptions c;
  c.throughput = 0.5;
  const double arcsec = M_PI / (180.0 * 3600.0);
  const double b = SkyBackgroundRate(13.0, VegaBand("K"), c, 0.01 * arcsec);
  EXPECT_NEAR(b / 27.8355, 1.0, 1e-4);
  EXPECT_NEAR(SkyBackgroundRate(13.0, VegaBand("K"), c, 0.01 * arcsec, 0.5) / b, 0.25, 1e-14);
}

}  // namespace
}  // namespace aosr
