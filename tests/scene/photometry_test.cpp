#include "aosr/scene/photometry.hpp"

#include <gtest/gtest.h>

#include <cmath>

namespace aosr {
namespace AOSR_TEST_NS {

constexpr double kH = 6.62607015e-34, kC = 299792458.0;

TEST(PhotometryTest, TableHoldsTheStandardBandsBlueToRed) {
  const std::vector<std::string> expected = {"U", "B", "V", "R", "I", "J", "H", "K", "Ks"};
  EXPECT_EQ(VegaBandNames(), expected);
  double last = 0;
  for (const char* name : {"U", "B", "V", "R", "I", "J", "H", "K"}) {
    const PhotometricBand& b = VegaBand(name);
    EXPECT_GT(b.effective_wavelength_m, last) << name;
    last = b.effective_wavelength_m;
    EXPECT_FALSE(b.reference.empty());
    // The stored zero point is f_λ Δλ λ_eff / (h c).
    EXPECT_NEAR(
        b.zero_point_photons / (b.flux_density_w_m3 * b.bandwidth_m * b.effective_wavelength_m / (kH * kC)),
        1.0, 1e-14)
        << name;
  }
}

// The photon densities f_λ λ / (h c) in photons cm⁻² s⁻¹ Å⁻¹ tabulated with Bessell et al. (1998)'s table
// (see photometry.hpp); ours use the same λ_eff and f_λ with exact SI constants, so agree to ~0.1%.
TEST(PhotometryTest, PhotonDensitiesMatchTheTabulatedOnes) {
  const std::vector<std::pair<std::string, double>> published = {{"U", 756.1}, {"B", 1392.6}, {"V", 995.5},
                                                                 {"R", 702.0}, {"I", 452.0},  {"J", 193.1},
                                                                 {"H", 93.3},  {"K", 43.6}};
  for (const auto& [name, density] : published) {
    const PhotometricBand& b = VegaBand(name);
    const double per_cm2_s_angstrom = b.zero_point_photons / b.bandwidth_m * 1e-4 * 1e-10;
    EXPECT_NEAR(per_cm2_s_angstrom / density, 1.0, 2e-3) << name;
  }
}

TEST(PhotometryTest, MagnitudesAreLogarithmicAndInvertible) {
  const PhotometricBand& k = VegaBand("K");
  EXPECT_DOUBLE_EQ(PhotonIrradiance(0, k), k.zero_point_photons);
  EXPECT_NEAR(PhotonIrradiance(5, k) / PhotonIrradiance(0, k), 0.01, 1e-15);
  for (double m : {-1.5, 0.0, 7.25, 22.0})
    EXPECT_NEAR(MagnitudeFromIrradiance(PhotonIrradiance(m, k), k), m, 1e-12);
}

TEST(PhotometryTest, AreaAndThroughput) {
  LightCollectorOptions c;
  c.diameter_m = 2.0;
  c.obstruction = 0.5;
  c.throughput = 1.0;
  EXPECT_NEAR(c.Area(), M_PI * 0.75, 1e-14);
  // 1000 photons s⁻¹ m⁻² through 3π/4 m² at 40%.
  c.throughput = 0.4;
  EXPECT_NEAR(DetectedElectronRate(SourceFlux::Irradiance(1000), c), 1000 * M_PI * 0.75 * 0.4, 1e-9);
  c.collecting_area_m2 = 10.0;  // explicit area wins
  EXPECT_NEAR(DetectedElectronRate(SourceFlux::Irradiance(1000), c), 4000, 1e-9);
  // A detected rate bypasses the telescope.
  EXPECT_DOUBLE_EQ(DetectedElectronRate(SourceFlux::DetectedRate(123.0), c), 123.0);
}

TEST(PhotometryTest, FramesShareTheTotalExposure) {
  const LightCollectorOptions c;
  const SourceFlux s = SourceFlux::Magnitude(12, "K");
  const double rate = DetectedElectronRate(s, c);
  double sum = 0;
  const ExposurePlan plan{10.0, 16};
  for (int i = 0; i < plan.frames; ++i) sum += ElectronsPerFrame(s, c, plan);
  EXPECT_NEAR(sum / (rate * 10.0), 1.0, 1e-14);
}

}  // namespace
}  // namespace aosr
