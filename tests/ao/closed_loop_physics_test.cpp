// Physics of the closed loop (closed_loop.hpp, control.hpp): convergence on a static aberration to the DM
// fitting residual, holding a DM offset applied through the reference slopes, the paper's system against
// the analytic AO model, a long-exposure PSF that lands on the optical axis with every sensor, and a DM offset
// that moves it where commanded (with the offsets' on-sky calibration). Fixed seeds; tolerances stated at each check. Kept short (a few seconds of CPU):
// longer, more precise versions are in closed_loop_slow_test.cpp.
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "aosr/ao/analytic_ao.hpp"
#include "aosr/ao/closed_loop.hpp"
#include "aosr/optics/psf.hpp"
#include "aosr/optics/psf_metrics.hpp"
#include "aosr/optics/zernike.hpp"
#include "loop_fixture.hpp"

namespace aosr {
namespace {

using test::KBandScience;
using test::kPaperDiameter;
using test::MakePaperSystem;
using test::SensorKind;

// Piston-removed, amplitude-weighted RMS [m].
double PupilRms(const Image& w, const Image& a) {
  const double sa = a.sum();
  const double mean = (a * w).sum() / sa;
  return std::sqrt((a * (w - mean).square()).sum() / sa);
}

// Low and mid orders the 17 x 17 DM reaches (Zernike radial orders 2 .. 6, ~124 nm RMS), optionally with a
// 20 nm RMS Z70 (radial order 11) beyond the DM's control radius, which a Shack-Hartmann aliases.
Image StaticAberration(Index n, bool high_order) {
  Image w = 80e-9 * ZernikeUnmasked(4, n) + 60e-9 * ZernikeUnmasked(6, n) + 50e-9 * ZernikeUnmasked(9, n) +
            40e-9 * ZernikeUnmasked(16, n) + 30e-9 * ZernikeUnmasked(29, n);
  if (high_order) w += 20e-9 * ZernikeUnmasked(70, n);
  return w;
}

// The preset's loop: pseudo-open-loop integrator, gain 0.35, one frame of delay.
ControllerOptions PreSetControl() {
  ControllerOptions control;
  control.gain = 0.35;
  control.delay_frames = 1;
  control.law = ControlLaw::kPseudoOpenLoop;
  return control;
}

// K-band science PSF every 2nd frame on a 64 x 64 Nyquist grid (32 lambda/D).
ClosedLoopOptions NyquistScience64() {
  ClosedLoopOptions options = KBandScience(2);
  options.science.rows = options.science.cols = 64;
  return options;
}

const char* Name(SensorKind kind) {
  return kind == SensorKind::kIdeal ? "ideal" : kind == SensorKind::kGeometric ? "geometric" : "diffractive";
}

TEST(ClosedLoopPhysicsTest, StaticAberrationConvergesToTheDmFittingResidual) {
  // Gain 0.5, one frame of delay, 60 frames, no turbulence (the error decays as sqrt(0.5)^n: 1e-9 after 60).
  //  * Ideal sensor: the loop converges to the least-squares DM fit itself; its residual equals
  //    DmFitter::Residual within 1e-4 of the fitting residual's RMS (the control matrix cuts the modes of the
  //    barely lit rim actuators, whose fit the loop therefore does not reproduce exactly).
  //  * Geometric SH: the loop converges exactly (1e-6) to its own fixed point w - H M G w (M: the control
  //    matrix), the DM fitting residual of the sensor's least-squares reconstructor. That reconstructor
  //    minimises slope errors, not OPD errors: for the low orders the DM reaches, its residual is 1.0 - 1.6x
  //    the OPD least-squares fitting residual (measured 1.48x: 8.1 against 5.5 nm, from 123 nm; the
  //    difference lies both at the rim and inside), and with order-11 content beyond the DM's reach the SH
  //    also aliases it into the slopes (measured 17.0 against 11.5 nm; printed, not bounded).
  //  * Diffractive SH: non-linear, so only the comparison with the fitting residual (1.0 - 1.6x).
  const Index n = 128;
  ControllerOptions control;
  control.gain = 0.5;
  control.delay_frames = 1;
  for (bool high_order : {false, true}) {
    const Image aberration = StaticAberration(n, high_order);
    for (SensorKind kind : {SensorKind::kIdeal, SensorKind::kGeometric, SensorKind::kDiffractive}) {
      test::LoopSystem s = MakePaperSystem(kind, false, 1, control, n);
      ClosedLoopOptions options = KBandScience();
      options.compute_psf = false;
      options.common_static_opd_m = aberration;
      ClosedLoop loop(s.amplitude, kPaperDiameter, nullptr, s.dm, s.wfs.get(), s.controller.get(), options);
      const ClosedLoopResult r = loop.Run(60 / 800.0);
      DmFitter fitter(s.dm, s.amplitude);
      const Image fit_residual = fitter.Residual(aberration);
      const double fit_rms = PupilRms(fit_residual, s.amplitude);
      const double loop_rms = r.residual_rms_m.back();
      const double distance = PupilRms(loop.residual_opd_m() - fit_residual, s.amplitude);
      std::printf(
          "%-11s %s: initial %.2f nm, after 60 frames %.3f nm; DM fitting residual %.3f nm; "
          "|loop - fit| %.3g nm\n",
          Name(kind), high_order ? "with Z70" : "low order", r.residual_rms_m[0] * 1e9, loop_rms * 1e9,
          fit_rms * 1e9, distance * 1e9);
      EXPECT_NEAR(r.residual_rms_m[50] / loop_rms, 1.0, 1e-3) << Name(kind);  // converged
      if (kind == SensorKind::kIdeal) {
        EXPECT_LT(distance, 1e-4 * fit_rms);
      } else if (kind == SensorKind::kGeometric) {
        const Vector c = -s.control_matrix.matrix * s.wfs->MeasureNoiseless(aberration);
        const Image fixed_point = aberration + s.dm->Opd(c);
        EXPECT_LT(PupilRms(loop.residual_opd_m() - fixed_point, s.amplitude), 1e-6 * loop_rms);
        if (!high_order) {
          EXPECT_GE(loop_rms / fit_rms, 1.0);
          EXPECT_LT(loop_rms / fit_rms, 1.6);
        }
      } else if (!high_order) {
        EXPECT_GE(loop_rms / fit_rms, 1.0);
        EXPECT_LT(loop_rms / fit_rms, 1.6);
      }
    }
  }
}

TEST(ClosedLoopPhysicsTest, ReferenceSlopeOffsetMakesTheLoopHoldTheShape) {
  // No turbulence. The offset shape is DM-representable and visible to the SH: the mirror's OPD for the
  // least-squares fit of a mix of Zernikes (so it has no waffle). After convergence the residual (what the
  // science camera sees) equals the shape within 1% RMS (stated tolerance; piston removed).
  const Index n = 128;
  ControllerOptions control;
  control.gain = 0.5;
  for (SensorKind kind : {SensorKind::kIdeal, SensorKind::kGeometric, SensorKind::kDiffractive}) {
    test::LoopSystem s = MakePaperSystem(kind, false, 1, control, n);
    DmFitter fitter(s.dm, s.amplitude);
    const Image target = 60e-9 * ZernikeUnmasked(2, n) + 50e-9 * ZernikeUnmasked(5, n) +
                         40e-9 * ZernikeUnmasked(8, n) + 30e-9 * ZernikeUnmasked(13, n);
    const Image shape = s.dm->Opd(fitter.Fit(target));
    ClosedLoopOptions options = KBandScience();
    options.compute_psf = false;
    ClosedLoop loop(s.amplitude, kPaperDiameter, nullptr, s.dm, s.wfs.get(), s.controller.get(), options);
    const std::vector<ClosedLoopResult> r = loop.RunSubExposures({shape}, 60 / 800.0, 0.0);
    const double error = PupilRms(loop.residual_opd_m() - shape, s.amplitude) / PupilRms(shape, s.amplitude);
    std::printf("%-11s holds the %.1f nm RMS offset shape to %.3g (relative RMS)\n", Name(kind),
                PupilRms(shape, s.amplitude) * 1e9, error);
    EXPECT_LT(error, 0.01);
  }
}

TEST(ClosedLoopPhysicsTest, DmGainScalesTheCorrectionButNotTheFixedPoint) {
  // A mirror whose stroke is g times the commanded one (ClosedLoopOptions::dm_gain), geometric SH (linear),
  // no turbulence, a static aberration, no delay. Frame 0 sees the aberration w (flat mirror); frame 1 sees
  // w + g H c_1 with c_1 the same command whatever g, so its correction (residual_1 - w) is exactly g times
  // the correct mirror's (1e-9 relative). The integrator and the POL controller both converge to a fixed
  // point where the reconstructed residual vanishes, M G r = 0, which does not involve g: after 80 frames the
  // residuals with g = 0.9, 1.1 and 1 agree within 1e-6 of their RMS. A DM gain error changes the loop's
  // dynamics (its effective gain k g), not what it converges to.
  const Index n = 64;
  const Image aberration = 80e-9 * ZernikeUnmasked(4, n) + 60e-9 * ZernikeUnmasked(6, n) + 40e-9 * ZernikeUnmasked(16, n);
  for (ControlLaw law : {ControlLaw::kIntegrator, ControlLaw::kPseudoOpenLoop}) {
    ControllerOptions control;
    control.gain = 0.4;
    control.delay_frames = 0;
    control.law = law;
    auto residual = [&](double g, int frames) {
      test::LoopSystem s = MakePaperSystem(SensorKind::kGeometric, false, 1, control, n);
      ClosedLoopOptions options = KBandScience();
      options.compute_psf = false;
      options.common_static_opd_m = aberration;
      options.dm_gain = g;
      ClosedLoop loop(s.amplitude, kPaperDiameter, nullptr, s.dm, s.wfs.get(), s.controller.get(), options);
      loop.Run(frames / 800.0);
      return std::make_pair(Image(loop.residual_opd_m()), Image(s.amplitude));
    };
    const auto [r1, amp] = residual(1.0, 2);
    const double correction = PupilRms(r1 - aberration, amp);
    ASSERT_GT(correction, 1e-9);
    const auto [end1, amp_end] = residual(1.0, 80);
    for (double g : {0.9, 1.1}) {
      const Image rg = residual(g, 2).first;
      EXPECT_NEAR(PupilRms((rg - aberration) - g * (r1 - aberration), amp) / correction, 0.0, 1e-9) << "g " << g;
      const Image end_g = residual(g, 80).first;
      const double end_rms = PupilRms(end1, amp_end);
      std::printf("law %d, dm_gain %.1f: first correction %.2f nm (x%.4f), converged residual %.3f nm, differs by %.3g\n",
                  int(law), g, PupilRms(rg - aberration, amp) * 1e9, PupilRms(rg - aberration, amp) / correction,
                  PupilRms(end_g, amp_end) * 1e9, PupilRms(end_g - end1, amp_end) / end_rms);
      EXPECT_LT(PupilRms(end_g - end1, amp_end), 1e-6 * end_rms) << "g " << g;
    }
  }
}

TEST(ClosedLoopPhysicsTest, PaperSystemAgainstTheAnalyticModel) {
  // The paper's system (loop_fixture.hpp), noiseless, integrator gain 0.35, one frame of delay (mean lag 2 T,
  // analytic_ao.hpp's convention), K-band PSF every 4th frame, 0.1 s settling then 0.4 s recorded. Stated
  // tolerances: the ideal sensor's long-exposure Strehl within 0.02 of AnalyticAoPsfCalculator with aliasing
  // off; the diffractive SH (Nyquist pixels, 16 x 16 px = 8 lambda/d, plain centre of gravity) in 0.6 - 0.87.
  ControllerOptions control;
  control.gain = 0.35;
  control.delay_frames = 1;
  const ClosedLoopOptions options = KBandScience(4);
  AnalyticAoPsfCalculator analytic(test::PaperAnalytic(control, false), 128, options.science);
  const Image amplitude = CircularPupil(128, PupilGeometry{kPaperDiameter, 0.0});
  const AnalyticAoPsf model = analytic.Compute(amplitude, Image::Zero(128, 128));
  AnalyticAoPsfCalculator analytic_alias(test::PaperAnalytic(control, true), 128, options.science);
  const AnalyticAoPsf model_alias = analytic_alias.Compute(amplitude, Image::Zero(128, 128));
  std::printf("analytic: Strehl %.4f without aliasing, %.4f with\n%s\n", model.strehl, model_alias.strehl,
              analytic.residual().budget().BriefReport().c_str());
  for (SensorKind kind : {SensorKind::kIdeal, SensorKind::kDiffractive}) {
    const auto t0 = std::chrono::steady_clock::now();
    test::LoopSystem s = MakePaperSystem(kind, true, 11, control);
    ClosedLoop loop(s.amplitude, kPaperDiameter, s.atmosphere.get(), s.dm, s.wfs.get(), s.controller.get(),
                    options);
    const auto t1 = std::chrono::steady_clock::now();
    const ClosedLoopResult r = loop.Run(0.4, 0.1);
    const auto t2 = std::chrono::steady_clock::now();
    const double peak = PeakStrehl(
        r.psf, PsfCalculator(128, kPaperDiameter, options.science).Compute(amplitude, Image::Zero(128, 128)));
    std::printf("%s: %s; peak Strehl of the PSF %.4f; set-up %.2f s, %.3f ms per frame\n",
                s.wfs->Describe().c_str(), r.BriefReport().c_str(), peak,
                std::chrono::duration<double>(t1 - t0).count(),
                1e3 * std::chrono::duration<double>(t2 - t1).count() / (r.steps + r.settling_steps));
    if (kind == SensorKind::kIdeal) {
      EXPECT_NEAR(r.long_exposure_strehl, model.strehl, 0.02);
    } else {
      EXPECT_GT(r.long_exposure_strehl, 0.6);
      EXPECT_LT(r.long_exposure_strehl, 0.87);
    }
    EXPECT_EQ(r.clipped_frames, 0);
  }
}

TEST(ClosedLoopPhysicsTest, LongExposurePsfLandsOnTheAxisWithEverySensor) {
  // A closed loop holds no tilt: the long-exposure K-band PSF's core (psf_metrics.hpp's core centroid, radius
  // 2 lambda/D) lands on the optical axis within 0.01 lambda/D (2.75 mas on 8 m at 2.2 um) for every sensor
  // model, at r0 = 0.08, 0.15 (the preset's) and 0.25 m, and for the diffractive SH with photon noise from
  // guide stars of R = 8 (the preset's, ~960 photo-electrons per lenslet per frame), 11 (~60) and 13 (~10,
  // the faint end where the loop still closes). Issue 23: the diffractive SH held (0.18, 0.14) lambda/D at the
  // preset's r0 (the spot-centring convention, shack_hartmann.hpp "Sampling").
  //
  // Statistics. One short exposure leaves a random residual tilt of a few 0.01 lambda/D (the SH senses the
  // mean gradient, the core follows the least-squares tilt; they differ by the turbulence's coma: measured
  // 0.01 - 0.06 lambda/D per 0.4 s at r0 = 0.15 m), which would need minutes of simulated time to average
  // below 0.01. Antithetic pairs remove it instead: the atmosphere and its negation
  // (AtmosphereOptions::antithetic) are equally likely, and a loop without bias turns -OPD into the PSF
  // inverted through the axis (linear sensors and control; the diffractive spot of -OPD is the inverted
  // spot), so the pair's mean centroid is the bias alone: exactly 0 for noiseless sensors (checked to 1e-6
  // lambda/D; the old convention gave ~0.15), and 0 up to the photon noise's own random tilt with noise,
  // which is not antithetic: measured 0.002 - 0.005 lambda/D RMS per pair at R = 11 and 0.018 at R = 13 over
  // 0.1 s, so the pair mean is averaged over 3 and 6 noise seeds there (standard errors ~0.002 and ~0.0075;
  // the 0.01 bound is a loose check at R = 13, where BroadSymmetricSpotsReadNoTilt in
  // shack_hartmann_physics_test.cpp shows the noisy centroid unbiased to a much tighter bound). The paper's
  // system with the preset's loop (pseudo-open-loop integrator, gain 0.35, one frame of delay), 0.05 s
  // settling then 0.05 s (noiseless) or 0.1 s (noisy) recorded, PSF every 2nd frame on a 64 x 64 Nyquist grid
  // (32 lambda/D). At r0 = 0.08 m the DM's 5 um stroke clips some frames (printed): clipping is odd too.
  const ControllerOptions control = PreSetControl();
  const ClosedLoopOptions options = NyquistScience64();
  const double lod_px = 2.0;  // Nyquist science pixels
  struct Case {
    SensorKind kind;
    double r0_m;
    double magnitude;  // < 0: noiseless sensor
  };
  std::vector<Case> cases;
  for (double r0 : {0.08, 0.15, 0.25}) {
    for (SensorKind kind : {SensorKind::kIdeal, SensorKind::kGeometric, SensorKind::kDiffractive})
      cases.push_back({kind, r0, -1.0});
  }
  for (double mag : {8.0, 11.0, 13.0}) cases.push_back({SensorKind::kDiffractive, 0.15, mag});
  // One calibrated system per sensor model (the interaction matrix depends on neither the atmosphere nor the
  // noise); each run gets a fresh atmosphere, sensor (noise seed) and controller.
  std::map<SensorKind, AoSystem> systems;
  for (SensorKind kind : {SensorKind::kIdeal, SensorKind::kGeometric, SensorKind::kDiffractive}) {
    AoSystemSpec spec;
    spec.amplitude = CircularPupil(128, PupilGeometry{kPaperDiameter, 0.0});
    spec.diameter_m = kPaperDiameter;
    spec.dm.actuators_across = 17;
    spec.dm.pitch_m = 0.5;
    spec.sensor = kind;
    spec.wfs = test::PaperSensor(kind == SensorKind::kGeometric ? ShackHartmannMode::kGeometric
                                                                 : ShackHartmannMode::kDiffractive);
    spec.control = control;
    systems.emplace(kind, BuildAoSystem(spec));
  }
  std::printf("sensor        r0 [m]  R mag  LE Strehl   centroid (y, x) [lambda/D]: atmosphere, antithetic, pair mean\n");
  for (const Case& c : cases) {
   const int noise_seeds = c.magnitude < 10 ? 1 : c.magnitude < 12 ? 3 : 6;
   double mean_y = 0.0, mean_x = 0.0;
   for (int ns = 0; ns < noise_seeds; ++ns) {
    double centroid[2][2];
    double strehl = 0.0;
    int clipped = 0;
    for (int anti = 0; anti < 2; ++anti) {
      AoSystem& s = systems.at(c.kind);
      AtmosphereOptions atmosphere = test::PaperAtmosphere(23);
      atmosphere.r0_m = c.r0_m;
      atmosphere.antithetic = anti == 1;
      s.atmosphere = std::make_unique<Atmosphere>(atmosphere, 128, kPaperDiameter);
      if (c.kind != SensorKind::kIdeal) {
        ShackHartmannOptions wfs = test::PaperSensor(c.kind == SensorKind::kGeometric ? ShackHartmannMode::kGeometric
                                                                                      : ShackHartmannMode::kDiffractive);
        wfs.noise.frame_time_s = control.frame_time_s();
        if (c.magnitude >= 0) {
          wfs.noise.photon_noise = true;
          wfs.noise.guide_star_magnitude = c.magnitude;
          wfs.noise.throughput = 0.5;  // the preset's
          wfs.noise.seed = 5 + ns;
        }
        s.wfs = std::make_unique<ShackHartmann>(s.amplitude, kPaperDiameter, wfs);
      }
      s.controller = std::make_unique<Controller>(s.control_matrix.matrix, s.interaction_matrix, control);
      auto loop = s.MakeLoop(options);
      const ClosedLoopResult r = loop->Run(c.magnitude < 0 ? 0.05 : 0.1, 0.05);
      const auto core = CoreCentroid(r.psf, 2.0 * lod_px);
      centroid[anti][0] = (core.first - 32) / lod_px;
      centroid[anti][1] = (core.second - 32) / lod_px;
      strehl += 0.5 * r.long_exposure_strehl;
      clipped += r.clipped_frames;
    }
    const double my = 0.5 * (centroid[0][0] + centroid[1][0]), mx = 0.5 * (centroid[0][1] + centroid[1][1]);
    std::printf("%-12s  %.2f  %5s  %.4f     %+.4f, %+.4f   %+.4f, %+.4f   %+.5f, %+.5f   (%d frames clipped)\n",
                Name(c.kind), c.r0_m, c.magnitude >= 0 ? std::to_string(int(c.magnitude)).c_str() : "-", strehl,
                centroid[0][0], centroid[0][1], centroid[1][0], centroid[1][1], my, mx, clipped);
    mean_y += my / noise_seeds;
    mean_x += mx / noise_seeds;
   }
   const double my = mean_y, mx = mean_x;
   if (noise_seeds > 1) std::printf("    mean over %d noise seeds: %+.5f, %+.5f\n", noise_seeds, my, mx);
    EXPECT_LT(std::abs(my), 0.01) << Name(c.kind) << " r0 " << c.r0_m << " mag " << c.magnitude;
    EXPECT_LT(std::abs(mx), 0.01) << Name(c.kind) << " r0 " << c.r0_m << " mag " << c.magnitude;
    if (c.magnitude < 0) {
      EXPECT_LT(std::abs(my), 1e-6) << Name(c.kind) << " r0 " << c.r0_m;
      EXPECT_LT(std::abs(mx), 1e-6) << Name(c.kind) << " r0 " << c.r0_m;
    }
  }
}

TEST(ClosedLoopPhysicsTest, OffsetsLandWhereCommandedWithOnSkyCalibration) {
  // Where a designed offset puts the image (OffsetCalibration, closed_loop.hpp). The DM offset is the mirror's
  // least-squares fit of a tilt that moves the image by c = 0.25 lambda/D on each axis at K (the paper's raster
  // step at r = 2), applied through the reference slopes in closed loop on the paper's system (r0 0.15 m, the
  // preset's loop, noiseless sensors), 0.05 s settling then 0.05 s recorded, K-band PSF on a 64 x 64 Nyquist
  // grid. Position: the long-exposure PSF's core centroid (radius 2 lambda/D), as a fraction of c.
  // Statistics: antithetic pairs as in LongExposurePsfLandsOnTheAxisWithEverySensor, but with the same offset
  // in both (the PSF of (-atmosphere, c) is the inversion of that of (atmosphere, -c)): the turbulence's random
  // tilt is odd and cancels in the pair's mean, the sensor's gain is even and stays, so the pair mean is
  // g c, the offset's gain for that realisation.
  // Measured (seeds 23 and 24, 2026-11-27): the ideal and geometric sensors move the image by 1.0000 +- 1e-4
  // of c (the pair mean removes the turbulence; the fitted tilt is the commanded one); the diffractive SH with
  // flat reference slopes by 1.13 - 1.16 (its closed-loop tip/tilt gain is 0.85 - 0.87: it holds the offset's
  // tilt ~1/0.86 too far), the effect kFlat keeps; with kOnSky by 0.984 - 0.999. Bounds: linear sensors within
  // 0.002 of 1, kOnSky within 0.03, kFlat above 1.08. One seed here (seed 24 gave the same to 0.015).
  const ControllerOptions control = PreSetControl();
  const ClosedLoopOptions options = NyquistScience64();
  const double lod_px = 2.0;
  const double c_lod = 0.25;
  const double shift_rad = c_lod * 2.2e-6 / kPaperDiameter;
  struct Case {
    SensorKind kind;
    OffsetCalibration calibration;
  };
  const std::vector<Case> cases = {{SensorKind::kIdeal, OffsetCalibration::kOnSky},
                                   {SensorKind::kGeometric, OffsetCalibration::kOnSky},
                                   {SensorKind::kDiffractive, OffsetCalibration::kFlat},
                                   {SensorKind::kDiffractive, OffsetCalibration::kOnSky}};
  std::printf("sensor        calibration  seed  tilt gain (y, x)   image position / commanded (y, x)\n");
  for (const Case& c : cases) {
    for (std::uint64_t seed : {23u}) {
      double position[2] = {0.0, 0.0};
      double gain[2] = {0.0, 0.0};
      for (int anti = 0; anti < 2; ++anti) {
        test::LoopSystem s = MakePaperSystem(c.kind, true, seed, control);
        AtmosphereOptions atmosphere = test::PaperAtmosphere(seed);
        atmosphere.antithetic = anti == 1;
        Atmosphere turbulence(atmosphere, 128, kPaperDiameter);
        DmFitter fitter(s.dm, s.amplitude);
        Image tilt(128, 128);
        for (Index i = 0; i < 128; ++i)
          for (Index k = 0; k < 128; ++k)
            tilt(i, k) = shift_rad * kPaperDiameter / 128.0 * (double(i) + double(k) + 1.0 - 128.0);
        const Image shape = s.dm->Opd(fitter.Fit(tilt));
        ClosedLoopOptions o = options;
        o.offset_calibration = c.calibration;
        ClosedLoop loop(s.amplitude, kPaperDiameter, &turbulence, s.dm, s.wfs.get(), s.controller.get(), o);
        const ClosedLoopResult r = loop.RunSubExposures({shape}, 0.05, 0.05).front();
        const auto core = CoreCentroid(r.psf, 2.0 * lod_px);
        position[0] += 0.5 * (core.first - 32) / lod_px / c_lod;
        position[1] += 0.5 * (core.second - 32) / lod_px / c_lod;
        gain[0] += 0.5 * r.tilt_gain[0];
        gain[1] += 0.5 * r.tilt_gain[1];
      }
      std::printf("%-12s  %-11s  %4d  %.3f, %.3f       %.4f, %.4f\n", Name(c.kind),
                  c.calibration == OffsetCalibration::kFlat ? "flat" : "on-sky", int(seed), gain[0], gain[1],
                  position[0], position[1]);
      for (int axis = 0; axis < 2; ++axis) {
        if (c.calibration == OffsetCalibration::kFlat) {
          EXPECT_GT(position[axis], 1.08) << Name(c.kind) << " seed " << seed << " axis " << axis;
        } else {
          EXPECT_NEAR(position[axis], 1.0, c.kind == SensorKind::kDiffractive ? 0.03 : 0.002)
              << Name(c.kind) << " seed " << seed << " axis " << axis;
        }
      }
    }
  }
}

}  // namespace
}  // namespace aosr

namespace aosr {
namespace {

// The WFS-noise term of the analytic model, measured through the sensor and the reconstructor
// (MeasureWfsNoiseRad2): (1) photon-limited, its variance scales as 1/flux (2.5 magnitudes = 10x); (2) a closed
// loop with no turbulence and that noisy sensor is driven by the noise alone, and its residual variance is the
// per-frame variance times the discrete loop's noise gain. The loop of closed_loop.cpp with delay_frames = 1 is,
// per controlled mode, e_{k+1} = e_k - g (e_{k-1} + n_k) (the measurement sees the mirror one update late): an
// AR(2) process whose variance per unit noise variance is (1 + g) g / ((1 - g)(2 + g)) = 0.309 at g = 0.35
// (a scalar simulation of the recursion gives 0.307). Measured: 1.03-1.05 of that (the noisy spots move with
// the residual, which the flat-wavefront measurement leaves out); bound 10 %. The analytic model's hybrid
// continuous/discrete G_n (analytic_ao.hpp section 3: WFS integration and zero-order hold) is 0.277, 10 % below
// the discrete loop's; checked to stay within 15 %.
TEST(ClosedLoopPhysicsTest, WfsNoiseMeasuredThroughTheReconstructorPredictsTheNoiseDrivenResidual) {
  ControllerOptions control;  // the paper's loop: 800 Hz, gain 0.35, one frame of delay
  const double wavelength = 550e-9;
  std::vector<double> measured;
  for (double magnitude : {10.0, 12.5}) {
    AoSystem s = MakePaperSystem(SensorKind::kDiffractive, false, 1, control);
    ShackHartmannOptions wfs = test::PaperSensor(ShackHartmannMode::kDiffractive);
    wfs.noise.frame_time_s = control.frame_time_s();
    wfs.noise.photon_noise = true;
    wfs.noise.guide_star_magnitude = magnitude;
    wfs.noise.throughput = 0.5;
    wfs.noise.seed = 11;
    s.wfs = std::make_unique<ShackHartmann>(s.amplitude, kPaperDiameter, wfs);
    s.controller = std::make_unique<Controller>(s.control_matrix.matrix, s.interaction_matrix, control);
    const double per_frame = MeasureWfsNoiseRad2(s, wavelength, 400);
    measured.push_back(per_frame);
    ClosedLoopOptions options;
    options.compute_psf = false;
    const ClosedLoopResult r = s.MakeLoop(options)->Run(0.4, 0.05);
    const double residual = std::pow(2 * kPi / wavelength * r.RmsResidualM(), 2);
    const double g = control.gain;
    const double discrete_gain = (1 + g) * g / ((1 - g) * (2 + g));
    const double predicted = discrete_gain * per_frame;
    const double analytic_gain = AnalyticAoNoiseGain(test::PaperAnalytic(control, false));
    std::printf("R = %.1f: per-frame noise %.4g rad^2 at 550 nm, closed-loop residual %.4g rad^2, predicted %.4g "
                "(ratio %.3f); noise gain: discrete %.4f, analytic %.4f\n",
                magnitude, per_frame, residual, predicted, residual / predicted, discrete_gain, analytic_gain);
    EXPECT_GT(per_frame, 0.0);
    EXPECT_NEAR(residual / predicted, 1.0, 0.10) << "R = " << magnitude;
    EXPECT_NEAR(analytic_gain / discrete_gain, 1.0, 0.15);
  }
  EXPECT_NEAR(measured[1] / measured[0], 10.0, 1.5);
  // A noiseless sensor measures no noise.
  AoSystem quiet = MakePaperSystem(SensorKind::kDiffractive, false, 1, control);
  EXPECT_EQ(MeasureWfsNoiseRad2(quiet, wavelength, 3), 0.0);
}

}  // namespace
}  // namespace aosr
