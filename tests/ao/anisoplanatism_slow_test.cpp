// The closed loop's off-axis Strehl against the analytic model (issue 31's target): the paper's system with the
// ideal sensor (so the analytic model without aliasing applies; loop_fixture.hpp), science at 0, theta0/2,
// theta0 and 2 theta0 along x (theta0 = 19.9" at K), three seeds x 1 s each (PSF every 4th frame). Stated
// tolerance: the seeds' mean long-exposure Strehl within 5 % (relative) of the analytic model's with the
// servo-lag cross term, or 2.5 standard errors of the mean where the seeds scatter more (at 2 theta0; measured:
// ratios 1.005, 1.003, 1.010 at 0, theta0/2, theta0, and 1.050 with a standard error of 14 % at 2 theta0). Printed beside it: the model without the cross term (the perfect-loop
// filter) and the MC's elongation and major-axis angle; at 2 theta0 the seeds' mean PSF must stretch along x
// (major axis within 20 degrees, elongation > 1.03; measured 1.14 at -14 degrees, the three seeds at -18, +32 and
// -15: the direction of one second of differential tilt is still noisy). One loop per seed records the four
// directions. Label slow (about 15 s).
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <algorithm>
#include <cstdio>
#include <vector>

#include "aosr/ao/analytic_ao.hpp"
#include "aosr/ao/anisoplanatism.hpp"
#include "aosr/ao/closed_loop.hpp"
#include "aosr/optics/psf_metrics.hpp"
#include "aosr/optics/pupil.hpp"
#include "loop_fixture.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

using test::kPaperDiameter;

constexpr double kArcsec = kPi / (180.0 * 3600.0);

TEST(AnisoplanatismSlowTest, ClosedLoopOffAxisStrehlMatchesTheAnalyticModel) {
  const Index n = 128;
  ControllerOptions control;  // gain 0.35, 1 frame of delay, 800 Hz
  const AtmosphereOptions atm = test::PaperAtmosphere(1);
  const double theta0 = IsoplanaticAngleRad(atm.r0_m, atm.r0_wavelength_m, 2.2e-6, atm.layers);
  const Image amplitude = CircularPupil(n, PupilGeometry{kPaperDiameter, 0.0});
  const auto t0 = std::chrono::steady_clock::now();
  // One loop per seed records the four directions (extra_science_directions: each direction the bytes of its
  // own loop, tests/ao/anisoplanatism_test.cpp), on screens built for 2 theta0.
  const std::vector<double> fractions = {0.0, 0.5, 1.0, 2.0};
  ClosedLoopOptions options = test::KBandScience(4);
  for (std::size_t k = 1; k < fractions.size(); ++k) options.extra_science_directions.push_back({fractions[k] * theta0, 0.0});
  std::vector<ClosedLoopResult> runs;  // per seed
  for (std::uint64_t seed : {41, 42, 43}) {
    test::LoopSystem system = test::MakePaperSystem(SensorKind::kIdeal, true, seed, control, n, 2.0 * theta0);
    runs.push_back(system.MakeLoop(options)->Run(1.0, 0.1));
  }
  for (std::size_t k = 0; k < fractions.size(); ++k) {
    const double fraction = fractions[k];
    AnalyticAoOptions a = test::PaperAnalytic(control, false);
    a.field_direction = {fraction * theta0, 0.0};
    const double model = AnalyticAoPsfCalculator(a, n, options.science).Compute(amplitude, Image::Zero(n, n)).strehl;
    a.anisoplanatism_servo_cross_term = false;
    const double filter = AnalyticAoPsfCalculator(a, n, options.science).Compute(amplitude, Image::Zero(n, n)).strehl;
    double mean = 0.0, sum2 = 0.0, elongation = 0.0;
    Image psf;
    for (std::size_t i = 0; i < runs.size(); ++i) {
      const ClosedLoopResult& r = k == 0 ? runs[i] : runs[i].extra_directions[k - 1];
      const PsfStats st = MeasurePsf(r.psf);
      std::printf("%.1f theta0 = %5.2f\", seed %lu: LE Strehl %.4f, elongation %.3f at %+.1f deg\n", fraction,
                  fraction * theta0 / kArcsec, static_cast<unsigned long>(41 + i), r.long_exposure_strehl,
                  st.Elongation(), st.major_axis_angle_rad * 180.0 / kPi);
      mean += r.long_exposure_strehl / 3.0;
      sum2 += r.long_exposure_strehl * r.long_exposure_strehl;
      psf = psf.size() == 0 ? Image(r.psf / 3.0) : Image(psf + r.psf / 3.0);
    }
    std::printf("%.1f theta0: closed loop %.4f, analytic %.4f (ratio %.3f), perfect-loop filter %.4f (ratio %.3f); "
                "%.0f s so far\n",
                fraction, mean, model, mean / model, filter, mean / filter,
                std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
    // Standard error of the 3-seed mean: the seeds scatter by 0.065 at 2 theta0 (1 s holds only a few
    // independent pupils of the 4 km layer's differential phase), 14 % of the mean, so the tolerance is the
    // larger of 5 % and 2.5 standard errors.
    const double se = std::sqrt(std::max(0.0, (sum2 - 3.0 * mean * mean) / 2.0) / 3.0);
    const double tolerance = std::max(0.05, 2.5 * se / model);
    std::printf("  standard error %.4f (%.1f %%): tolerance %.1f %%\n", se, 100.0 * se / model, 100.0 * tolerance);
    EXPECT_NEAR(mean / model, 1.0, tolerance) << fraction << " theta0";
    // The seeds' mean PSF at 2 theta0 stretches along the line to the guide star (x): major axis within 10 deg.
    const PsfStats mean_stats = MeasurePsf(psf);
    elongation = mean_stats.Elongation();
    std::printf("  mean PSF: elongation %.3f, major axis at %+.1f deg\n", elongation,
                mean_stats.major_axis_angle_rad * 180.0 / kPi);
    if (fraction == 2.0) {
      EXPECT_GT(elongation, 1.03);
      EXPECT_NEAR(mean_stats.major_axis_angle_rad * 180.0 / kPi, 0.0, 20.0);
    }
  }
}

}  // namespace
}  // namespace aosr
