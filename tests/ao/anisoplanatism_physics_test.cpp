// Physics oracles for anisoplanatism (include/aosr/ao/anisoplanatism.hpp, analytic_ao.hpp section 2,
// atmosphere.hpp and closed_loop.hpp "Off axis"): Fried's isoplanatic angle, the analytic anisoplanatism term
// against an independent quadrature and against Fried's full-band law, the off-axis Strehl against the
// extended Marechal law of that term, the elongation's direction and size against the differential tilt, no
// anisoplanatism with all the turbulence at the ground (analytic and Monte-Carlo, to the byte), and a short
// closed loop off axis against the analytic model (the 4-angle comparison is in anisoplanatism_slow_test.cpp).
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>

#include "aosr/ao/analytic_ao.hpp"
#include "aosr/ao/anisoplanatism.hpp"
#include "aosr/ao/closed_loop.hpp"
#include "aosr/ao/von_karman.hpp"
#include "aosr/optics/psf.hpp"
#include "aosr/optics/psf_metrics.hpp"
#include "aosr/optics/pupil.hpp"
#include "loop_fixture.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

using test::kPaperDiameter;

constexpr double kArcsec = kPi / (180.0 * 3600.0);
constexpr double kInf = std::numeric_limits<double>::infinity();

PsfSampling Nyquist(double wavelength_m, Index size) {
  return PsfSampling{wavelength_m, wavelength_m / (2.0 * kPaperDiameter), size, size};
}

// The paper system's analytic options at `wavelength_m` and direction (x, y) [arcsec] (loop_fixture.hpp).
AnalyticAoOptions PaperAt(double wavelength_m, double x_arcsec, double y_arcsec, bool aliasing = true) {
  ControllerOptions control;  // gain 0.35, 1 frame of delay, 800 Hz
  AnalyticAoOptions a = test::PaperAnalytic(control, aliasing);
  a.science_wavelength_m = wavelength_m;
  a.field_direction = {x_arcsec * kArcsec, y_arcsec * kArcsec};
  return a;
}

// Fried (1982): theta0 = [2.914 k^2 (sec z)^(8/3) sum Cn^2 dh h^(5/3)]^(-3/5), with the integrated Cn^2 from r0 =
// [0.423 k^2 sec z sum Cn^2 dh]^(-3/5) (r0 at the zenith, at the science wavelength). The library uses the
// exact structure-function constant (6.8839^(-3/5) = 0.31431), Fried's rounded constants give 2.914/0.423 =
// 6.8889: the two agree to 0.05 %. The paper atmosphere: h_bar = 2576 m, theta0 = 19.9" at K, 14.1" at H,
// 10.1" at J (issue 31: ~2.6 km, ~20", 14", 10").
TEST(AnisoplanatismPhysicsTest, IsoplanaticAngleIsFriedsFormula) {
  const AtmosphereOptions atm = test::PaperAtmosphere(1);
  const double h_bar = EffectiveTurbulenceAltitudeM(atm.layers);
  std::printf("h_bar = %.1f m\n", h_bar);
  EXPECT_NEAR(h_bar, 2576.0, 5.0);
  for (double zenith_deg : {0.0, 30.0}) {
    for (double lambda : {1.25e-6, 1.65e-6, 2.2e-6}) {
      const double z = zenith_deg * kPi / 180.0, sec = 1.0 / std::cos(z);
      const double k = 2.0 * kPi / lambda;
      const double r0 = ScaleR0(atm.r0_m, atm.r0_wavelength_m, lambda);
      const double cn2 = std::pow(r0, -5.0 / 3.0) / (0.423 * k * k);  // integrated Cn^2 dh [m^(1/3)]
      double moment = 0.0;
      for (const Layer& l : atm.layers) moment += l.cn2_fraction * cn2 * std::pow(l.altitude_m, 5.0 / 3.0);
      const double fried = std::pow(2.914 * k * k * std::pow(sec, 8.0 / 3.0) * moment, -3.0 / 5.0);
      const double theta0 = IsoplanaticAngleRad(atm.r0_m, atm.r0_wavelength_m, lambda, atm.layers, z);
      std::printf("zenith %2.0f deg, lambda %.2f um: theta0 %.3f arcsec (Fried's constants %.3f)\n", zenith_deg,
                  lambda * 1e6, theta0 / kArcsec, fried / kArcsec);
      EXPECT_NEAR(theta0 / fried, 1.0, 1e-3);
    }
  }
  const auto theta0 = [&](double lambda) {
    return IsoplanaticAngleRad(atm.r0_m, atm.r0_wavelength_m, lambda, atm.layers) / kArcsec;
  };
  EXPECT_NEAR(theta0(2.2e-6), 19.9, 0.2);
  EXPECT_NEAR(theta0(1.65e-6), 14.1, 0.2);
  EXPECT_NEAR(theta0(1.25e-6), 10.1, 0.2);
  // Ground turbulence only: no anisoplanatism at any angle.
  std::vector<Layer> ground = atm.layers;
  for (Layer& l : ground) l.altitude_m = 0.0;
  EXPECT_EQ(IsoplanaticAngleRad(atm.r0_m, atm.r0_wavelength_m, 2.2e-6, ground), kInf);
}

// The anisoplanatism term without the cross term is Phi(f) 2 (1 - cos 2 pi f.(h theta)) inside the square
// control region. (a) Its variance against an independent midpoint quadrature over the square, 8x finer than
// the model's grid: within 1 %. (b) Fried's law: over the whole plane the filter integrates to (theta/theta0)^(5/3)
// for Kolmogorov turbulence (a radial quadrature, within 0.5 %: the theta0 constant and the filter agree); and the
// model inside a circular control region (L0 = 30 m) against the same radial quadrature there, within 2 %. (With
// L0 = infinity the law is not a test of the model: a fifth of Fried's variance at 10" lies at scales beyond the
// PSD grid's period K D = 32 m, where f^(-11/3) (2 pi f s)^2 ~ f^(-5/3) still carries weight; a finite outer scale
// removes it, which is also why Fried's law overstates the anisoplanatism of real atmospheres.)
TEST(AnisoplanatismPhysicsTest, AnalyticTermIsTheFilterIntegratedOverTheControlRegion) {
  {
    AnalyticAoOptions o = PaperAt(2.2e-6, 20.0, 0.0, false);
    o.anisoplanatism_servo_cross_term = false;
    const double aniso = ComputeAnalyticAoErrorBudget(o).anisoplanatism_rad2;
    const double fc = o.ControlRadius();
    const double r0 = o.R0At(o.science_wavelength_m);
    const double step = 1.0 / (8.0 * o.frequency_padding * o.diameter_m);
    const int cells = static_cast<int>(std::lround(2.0 * fc / step));
    double sum = 0.0;
    for (int i = 0; i < cells; ++i) {
      const double fy = -fc + (i + 0.5) * step;
      for (int j = 0; j < cells; ++j) {
        const double fx = -fc + (j + 0.5) * step;
        double filter = 0.0;
        for (const Layer& l : o.layers)
          filter += l.cn2_fraction * 2.0 * (1.0 - std::cos(2.0 * kPi * fx * l.altitude_m * o.field_direction.x_rad));
        sum += VonKarmanPsd(std::hypot(fx, fy), r0, o.outer_scale_m) * filter;
      }
    }
    sum *= step * step;
    std::printf("K, 20\": anisoplanatism in the control region %.4f rad^2, quadrature %.4f\n", aniso, sum);
    EXPECT_NEAR(aniso / sum, 1.0, 0.01);
  }
  {
    // (b) One layer at 10 km, circular control region. The angular mean of 2 (1 - cos 2 pi f.s) is
    // 2 (1 - J0(2 pi f s)), so the variance is the radial integral I(f0, f1) = int 2 pi f Phi(f) 2 (1 - J0) df,
    // computed here on a logarithmic grid (f = e^u, 40000 steps from 1e-8 to 1e4 /m).
    const double lambda = 2.2e-6;
    const auto radial = [&](double r0, double L0, double s, double f1) {
      const double u0 = std::log(1e-8), u1 = std::log(f1);
      const int steps = 40000;
      const double du = (u1 - u0) / steps;
      double sum = 0.0;
      for (int i = 0; i <= steps; ++i) {
        const double f = std::exp(u0 + i * du);
        const double v = 2.0 * kPi * f * f * VonKarmanPsd(f, r0, L0) * 2.0 * (1.0 - std::cyl_bessel_j(0.0, 2.0 * kPi * f * s));
        sum += (i == 0 || i == steps ? 0.5 : 1.0) * v;
      }
      return sum * du;
    };
    AnalyticAoOptions o;
    o.diameter_m = 8.0;
    o.actuator_pitch_m = 0.5;
    o.control_domain = ControlDomain::kCircle;
    o.r0_m = 0.15;
    o.reference_wavelength_m = 0.5e-6;
    o.outer_scale_m = 30.0;
    o.layers = {Layer{10000.0, 1.0, 10.0, 0.0}};
    o.aliasing = false;
    o.anisoplanatism_servo_cross_term = false;
    o.science_wavelength_m = lambda;
    const double r0 = o.R0At(lambda);
    const double theta0 = IsoplanaticAngleRad(o.r0_m, o.reference_wavelength_m, lambda, o.layers);
    for (double theta : {10.0 * kArcsec, 30.0 * kArcsec}) {
      const double s = 10000.0 * theta;
      // Fried's law: Kolmogorov, the whole plane.
      const double fried = FriedAnisoplanaticVarianceRad2(theta, theta0);
      const double kolmogorov = radial(r0, kInf, s, 1e4);
      o.field_direction = {theta * std::cos(0.3), theta * std::sin(0.3)};
      const double model = ComputeAnalyticAoErrorBudget(o).anisoplanatism_rad2;
      const double band = radial(r0, o.outer_scale_m, s, o.ControlRadius());
      std::printf("one layer at 10 km, %2.0f\": Kolmogorov whole plane %.4f rad^2, Fried (theta/theta0)^(5/3) %.4f; "
                  "L0 = 30 m inside the control disk: model %.4f, radial quadrature %.4f\n",
                  theta / kArcsec, kolmogorov, fried, model, band);
      EXPECT_NEAR(kolmogorov / fried, 1.0, 0.005);
      EXPECT_NEAR(model / band, 1.0, 0.02);
    }
  }
}

// All the turbulence at the ground: a direction 40" away sees exactly the guide star's phase. The analytic
// anisoplanatism term is exactly 0 and the PSF the same bytes; the closed loop's off-axis PSF is the on-axis one
// to the byte (the layer is read at the same place).
TEST(AnisoplanatismPhysicsTest, GroundTurbulenceShowsNoAnisoplanatism) {
  const Index n = 128;
  const Image amplitude = CircularPupil(n, PupilGeometry{kPaperDiameter, 0.0});
  AnalyticAoOptions on = PaperAt(2.2e-6, 0.0, 0.0);
  for (Layer& l : on.layers) l.altitude_m = 0.0;
  AnalyticAoOptions off = on;
  off.field_direction = {40.0 * kArcsec, -10.0 * kArcsec};
  const PsfSampling s = Nyquist(2.2e-6, 64);
  const AnalyticAoPsf a_on = AnalyticAoPsfCalculator(on, n, s).Compute(amplitude, Image::Zero(n, n));
  const AnalyticAoPsfCalculator off_calc(off, n, s);
  const AnalyticAoPsf a_off = off_calc.Compute(amplitude, Image::Zero(n, n));
  EXPECT_EQ(off_calc.residual().budget().anisoplanatism_rad2, 0.0);
  EXPECT_TRUE((a_on.psf == a_off.psf).all());

  ControllerOptions control;
  auto run = [&](const FieldDirection& direction) {
    AoSystemSpec spec;
    spec.amplitude = amplitude;
    spec.diameter_m = kPaperDiameter;
    spec.dm.actuators_across = 17;
    spec.dm.pitch_m = 0.5;
    spec.atmosphere = test::PaperAtmosphere(5);
    for (Layer& l : spec.atmosphere->layers) l.altitude_m = 0.0;
    spec.atmosphere->max_field_angle_rad = 50.0 * kArcsec;
    spec.sensor = SensorKind::kIdeal;
    spec.control = control;
    AoSystem system = BuildAoSystem(spec);
    ClosedLoopOptions options = test::KBandScience(2);
    options.science = s;
    options.science_direction = direction;
    return system.MakeLoop(options)->Run(0.05, 0.02);
  };
  const ClosedLoopResult m_on = run({});
  const ClosedLoopResult m_off = run(off.field_direction);
  std::printf("ground layers only: closed loop Strehl %.4f on axis, %.4f at (40\", -10\")\n",
              m_on.long_exposure_strehl, m_off.long_exposure_strehl);
  EXPECT_TRUE((m_on.psf == m_off.psf).all());
  EXPECT_EQ(m_on.long_exposure_strehl, m_off.long_exposure_strehl);
}

// The off-axis Strehl against the extended Marechal law of the anisoplanatism term alone: S(theta)/S(0) ~
// exp(-sigma_aniso^2). The coherent core follows the law; but the anisoplanatic phase lives at low spatial
// frequencies (f < 1/(h theta), a few lambda/D from the core), so the light it scatters lands close to the core
// and adds to the peak: the PSF's peak ratio sits above exp(-sigma^2), more so as sigma^2 grows (measured +0.035
// at K 20", +0.05 at J 20", +0.07 at K 40"). Stated tolerance: ratio in [0.98 exp(-sigma^2), exp(-sigma^2) + 0.08].
// Printed:
// the issue's numbers (0.53 rad^2 at K 20", ratio 0.59; 1.6 at J 20", 0.20; 1.5 at K 40", 0.22), with and
// without the servo-lag cross term.
TEST(AnisoplanatismPhysicsTest, OffAxisStrehlFollowsTheMarechalLawOfTheTerm) {
  const Index n = 128;
  const Image amplitude = CircularPupil(n, PupilGeometry{kPaperDiameter, 0.0});
  struct Case {
    double lambda, arcsec;
  };
  for (const Case c : {Case{2.2e-6, 20.0}, Case{1.25e-6, 20.0}, Case{2.2e-6, 40.0}}) {
    const PsfSampling s = Nyquist(c.lambda, 128);
    const double s0 = AnalyticAoPsfCalculator(PaperAt(c.lambda, 0.0, 0.0), n, s)
                          .Compute(amplitude, Image::Zero(n, n))
                          .strehl;
    for (bool cross : {true, false}) {
      AnalyticAoOptions o = PaperAt(c.lambda, c.arcsec, 0.0);
      o.anisoplanatism_servo_cross_term = cross;
      const AnalyticAoPsfCalculator calc(o, n, s);
      const double st = calc.Compute(amplitude, Image::Zero(n, n)).strehl;
      const ResidualPsd& psd = calc.residual().psd();
      const double sigma2 = calc.residual().budget().anisoplanatism_rad2;
      const TiltVariance tilt = ZernikeTiltVariance(psd.anisoplanatism, psd.frequency_step_per_m, kPaperDiameter, 0.0);
      const double marechal = std::exp(-sigma2);
      std::printf("%.2f um, %2.0f\" (%s cross term): anisoplanatism %.3f rad^2 (tilt %.3f), Strehl %.4f / %.4f = "
                  "%.3f, exp(-sigma^2) = %.3f\n",
                  c.lambda * 1e6, c.arcsec, cross ? "with" : "without", sigma2,
                  tilt.parallel_rad2 + tilt.perpendicular_rad2, st, s0, st / s0, marechal);
      EXPECT_GT(st / s0, 0.98 * marechal);
      EXPECT_LT(st / s0, marechal + 0.08);
    }
  }
}

// The core stretches along the line to the guide star, by the differential tilt. With wind directions averaged
// (a round on-axis core), at 20" from the guide star at K in two directions: the major axis within 2 degrees
// of the direction, an elongation above 1.02 (3 % at K, 20"), and the excess of the squared FWHM along it over across it,
// F_par^2 - F_perp^2, within 25 % of 8 ln 2 (s_par^2 - s_perp^2) from the term's tilt variances (a Gaussian
// jitter on a near-Gaussian core; anisoplanatism.hpp).
TEST(AnisoplanatismPhysicsTest, ElongationLiesAlongTheGuideStarLineWithTheDifferentialTilt) {
  const Index n = 128;
  const Image amplitude = CircularPupil(n, PupilGeometry{kPaperDiameter, 0.0});
  const double lambda = 2.2e-6;
  const PsfSampling s{lambda, lambda / (8.0 * kPaperDiameter), 128, 128};  // lambda/(8D): the core well sampled
  AnalyticAoOptions round = PaperAt(lambda, 0.0, 0.0);
  round.average_wind_direction = true;
  const PsfStats on = MeasurePsf(AnalyticAoPsfCalculator(round, n, s).Compute(amplitude, Image::Zero(n, n)).psf);
  std::printf("on axis: FWHM %.3f x %.3f px (elongation %.4f)\n", on.fwhm_major_px, on.fwhm_minor_px,
              on.Elongation());
  EXPECT_LT(on.Elongation(), 1.01);
  for (double angle_deg : {0.0, 30.0, -60.0}) {
    const double psi = angle_deg * kPi / 180.0;
    AnalyticAoOptions o = round;
    o.field_direction = {20.0 * kArcsec * std::cos(psi), 20.0 * kArcsec * std::sin(psi)};
    const AnalyticAoPsfCalculator calc(o, n, s);
    const PsfStats st = MeasurePsf(calc.Compute(amplitude, Image::Zero(n, n)).psf);
    const ResidualPsd& psd = calc.residual().psd();
    const TiltVariance tilt = ZernikeTiltVariance(psd.anisoplanatism, psd.frequency_step_per_m, kPaperDiameter, psi);
    const double px = s.pixel_scale_rad;
    const double par = TiltCoefficientToAngleRad(std::sqrt(tilt.parallel_rad2), lambda, kPaperDiameter) / px;
    const double perp = TiltCoefficientToAngleRad(std::sqrt(tilt.perpendicular_rad2), lambda, kPaperDiameter) / px;
    const double predicted = 8.0 * std::log(2.0) * (par * par - perp * perp);
    const double measured = st.fwhm_major_px * st.fwhm_major_px - st.fwhm_minor_px * st.fwhm_minor_px;
    std::printf("20\" at %+.0f deg: FWHM %.3f x %.3f px (elongation %.3f), major axis at %+.2f deg; differential "
                "tilt %.3f px along, %.3f across; F_par^2 - F_perp^2 = %.3f px^2, 8 ln 2 (s_par^2 - s_perp^2) = "
                "%.3f\n",
                angle_deg, st.fwhm_major_px, st.fwhm_minor_px, st.Elongation(),
                st.major_axis_angle_rad * 180.0 / kPi, par, perp, measured, predicted);
    EXPECT_GT(st.Elongation(), 1.02);
    EXPECT_NEAR(st.major_axis_angle_rad * 180.0 / kPi, angle_deg, 2.0);
    EXPECT_NEAR(measured / predicted, 1.0, 0.25);
  }
}

// A short closed loop off axis (ideal sensor: the analytic model without aliasing applies) at theta0 = 19.9"
// along x against the analytic model with the cross term: long-exposure Strehl within 10 % (relative; 0.4 s
// leaves a few per cent of sampling scatter; the 5 % comparison at 0, theta0/2, theta0 and 2 theta0 over longer
// runs is anisoplanatism_slow_test.cpp). The elongation (3 % here) is printed, not checked: 0.4 s of one
// realisation leaves its direction to chance (22 degrees off x at this seed); the slow test checks it.
TEST(AnisoplanatismPhysicsTest, ShortClosedLoopOffAxisAgainstTheAnalyticModel) {
  const Index n = 128;
  ControllerOptions control;
  const AtmosphereOptions atm = test::PaperAtmosphere(1);
  const double theta0 = IsoplanaticAngleRad(atm.r0_m, atm.r0_wavelength_m, 2.2e-6, atm.layers);
  ClosedLoopOptions options = test::KBandScience(4);
  options.science_direction = {theta0, 0.0};
  AnalyticAoOptions a = test::PaperAnalytic(control, false);
  a.field_direction = options.science_direction;
  const Image amplitude = CircularPupil(n, PupilGeometry{kPaperDiameter, 0.0});
  const double model = AnalyticAoPsfCalculator(a, n, options.science).Compute(amplitude, Image::Zero(n, n)).strehl;
  const auto t0 = std::chrono::steady_clock::now();
  test::LoopSystem system = test::MakePaperSystem(SensorKind::kIdeal, true, 31, control, n, theta0);
  const ClosedLoopResult r = system.MakeLoop(options)->Run(0.4, 0.1);
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  const PsfStats st = MeasurePsf(r.psf);
  std::printf("closed loop at theta0 = %.2f\": %s; analytic %.4f (ratio %.3f); elongation %.3f at %+.1f deg; "
              "%.1f s\n",
              theta0 / kArcsec, r.BriefReport().c_str(), model, r.long_exposure_strehl / model, st.Elongation(),
              st.major_axis_angle_rad * 180.0 / kPi, seconds);
  EXPECT_NEAR(r.long_exposure_strehl / model, 1.0, 0.10);
  EXPECT_EQ(r.clipped_frames, 0);
}

}  // namespace
}  // namespace aosr
