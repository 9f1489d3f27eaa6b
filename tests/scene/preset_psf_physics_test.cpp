// The paper-8m preset off axis (issue 31): Fried's isoplanatic angle of its atmosphere at K, H and J, and the
// analytic PSF's Strehl ratio off/on axis at K and J, 20" and 40" from the guide star, against the issue's
// numbers (theta0 ~ 20", 14", 10"; ratios 0.59 at K 20", 0.20 at J 20", 0.22 at K 40", computed there as
// exp(-sigma^2) of the anisoplanatism filter inside the control region). The preset's model includes the
// servo-lag x anisoplanatism cross term and the Strehl is the PSF's peak, which the near-core halo of the
// low-order anisoplanatic phase lifts above exp(-sigma^2) (ao/anisoplanatism_physics_test.cpp): stated tolerance
// [issue - 0.02, issue + 0.08] on each ratio (measured 0.632, 0.250, 0.293). The core's major axis lies along x
// within 10 degrees (measured -8.9, 0.0, -6.0 at Nyquist sampling; the on-axis core is round there, and the few
// degrees are most likely the servo-lag cross term with the preset's winds at 0, 60, 135 degrees: not pinned down).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include "aosr/ao/anisoplanatism.hpp"
#include "aosr/scene/preset_psf.hpp"
#include "aosr/scene/telescope.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

constexpr double kArcsec = M_PI / (180.0 * 3600.0);

TEST(PresetPsfPhysicsTest, PaperPresetIsoplanaticAngleAndOffAxisStrehl) {
  TelescopePreset preset = LoadTelescopePreset("paper-8m");
  ASSERT_TRUE(preset.atmosphere.has_value());
  const AtmosphereOptions& atm = *preset.atmosphere;
  EXPECT_NEAR(EffectiveTurbulenceAltitudeM(atm.layers), 2576.0, 5.0);
  const double k = IsoplanaticAngleRad(atm.r0_m, atm.r0_wavelength_m, 2.2e-6, atm.layers) / kArcsec;
  const double h = IsoplanaticAngleRad(atm.r0_m, atm.r0_wavelength_m, 1.65e-6, atm.layers) / kArcsec;
  const double j = IsoplanaticAngleRad(atm.r0_m, atm.r0_wavelength_m, 1.25e-6, atm.layers) / kArcsec;
  std::printf("paper-8m: theta0 = %.2f\" (K), %.2f\" (H), %.2f\" (J)\n", k, h, j);
  EXPECT_NEAR(k, 20.0, 0.5);
  EXPECT_NEAR(h, 14.0, 0.5);
  EXPECT_NEAR(j, 10.0, 0.5);

  struct Case {
    double wavelength_m, arcsec, issue_ratio;
  };
  for (const Case c : {Case{2.2e-6, 20.0, 0.59}, Case{1.25e-6, 20.0, 0.20}, Case{2.2e-6, 40.0, 0.22}}) {
    preset.science_wavelength_m = c.wavelength_m;
    PresetPsfOptions o;
    o.pixel_lod = 0.5;
    o.size = 128;
    const PresetPsf on = ComputePresetPsf(preset, o);
    o.field_direction = {c.arcsec * kArcsec, 0.0};
    const PresetPsf off = ComputePresetPsf(preset, o);
    const double ratio = off.strehl / on.strehl;
    std::printf("%.2f um, %2.0f\": Strehl %.4f on axis, %.4f off (ratio %.3f; issue %.2f); elongation %.3f at "
                "%+.1f deg (on axis %.3f at %+.1f deg)\n",
                c.wavelength_m * 1e6, c.arcsec, on.strehl, off.strehl, ratio, c.issue_ratio, off.elongation,
                off.major_axis_angle_deg, on.elongation, on.major_axis_angle_deg);
    EXPECT_GT(ratio, c.issue_ratio - 0.02);
    EXPECT_LT(ratio, c.issue_ratio + 0.08);
    EXPECT_GT(off.elongation, 1.05);
    EXPECT_GT(off.elongation, on.elongation);
    EXPECT_NEAR(off.major_axis_angle_deg, 0.0, 10.0);
  }
}

}  // namespace
}  // namespace aosr
