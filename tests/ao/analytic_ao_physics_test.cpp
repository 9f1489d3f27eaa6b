// Physics oracles for the analytic AO path: zero turbulence, flux, the structure function's limits, the
// extended Marechal law, the first-order halo = PSD law, Greenwood's servo-lag scaling, and the 8-m system
// of the issue (include/aosr/ao/analytic_ao.hpp).
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <limits>

#include "aosr/core/image.hpp"  // kPi
#include "aosr/ao/analytic_ao.hpp"
#include "aosr/optics/psf.hpp"
#include "aosr/optics/pupil.hpp"
#include "aosr/optics/zernike.hpp"

namespace aosr {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

// The system of the issue (item 9): 8 m, 17 x 17 DM (pitch 0.5 m), 800 Hz, integrator gain 0.35,
// r0 = 0.15 m at 550 nm, L0 = 30 m, three layers at 0/4/10 km carrying 70/25/5 % of Cn^2 with winds of
// 5/10/25 m/s, K band, bright guide star. "One frame of delay" is taken as k = 1 frame of read-out +
// computation after the WFS integration (total mean lag 2 T = 2.5 ms, header section 3); the k = 0
// reading (total lag T) is printed too. Wind directions are not given: 0, 60 and 120 degrees.
AnalyticAoOptions PaperSystem() {
  AnalyticAoOptions o;
  o.diameter_m = 8.0;
  o.actuator_pitch_m = 0.5;
  o.r0_m = 0.15;
  o.reference_wavelength_m = 0.55e-6;
  o.outer_scale_m = 30.0;
  o.layers = {{0.0, 0.70, 5.0, 0.0}, {4000.0, 0.25, 10.0, kPi / 3.0}, {10000.0, 0.05, 25.0, 2.0 * kPi / 3.0}};
  o.loop_rate_hz = 800.0;
  o.loop_gain = 0.35;
  o.loop_delay_frames = 1.0;
  o.wfs_noise_rad2 = 0.0;
  o.aliasing = true;
  o.science_wavelength_m = 2.2e-6;
  return o;
}

PsfSampling Sampling(double wavelength_m, double pitch_lod, Index size, double diameter_m = 8.0) {
  return PsfSampling{wavelength_m, pitch_lod * wavelength_m / diameter_m, size, size};
}

double Ms(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

// r0 = +inf: D_res = 0 and the analytic PSF is PsfCalculator's, for an obstructed pupil with an aberration
// (w_dm + w_static), to rounding; so is the Strehl.
TEST(AnalyticAoPhysicsTest, ZeroTurbulenceGivesTheTelescopePsf) {
  AnalyticAoOptions o = PaperSystem();
  o.r0_m = kInf;
  const Index n = 48;
  const Image pupil = CircularPupil(n, PupilGeometry{8.0, 0.14}, 3);
  const Image opd = Zernike(7, n) * 0.15e-6 + Zernike(12, n) * 0.08e-6;
  for (const PsfSampling& s : {Sampling(2.2e-6, 0.25, 96), Sampling(2.2e-6, 0.7, 41)}) {
    const AnalyticAoPsf a = AnalyticAoPsfFromPupil(o, pupil, opd, s);
    const Image reference = PsfFromPupil(pupil, opd, 8.0, s);
    EXPECT_LT((a.psf - reference).abs().maxCoeff(), 1e-10 * reference.maxCoeff());
    EXPECT_NEAR(a.strehl, StrehlFromPupil(pupil, opd, 2.2e-6), 1e-12);
    EXPECT_EQ(a.residual_variance_rad2, 0.0);
  }
}

// Flux: a window of exactly one period (n lambda/D) holds exp(-sigma_t^2), the light not scattered beyond
// the band by the fitting tail (header section 4); 1 without turbulence. A smaller window holds less.
TEST(AnalyticAoPhysicsTest, FluxNormalisation) {
  const AnalyticAoOptions o = PaperSystem();
  const Index n = 32;
  const Image pupil = CircularPupil(n, PupilGeometry{8.0, 0.0}, 1);
  const AnalyticAoPsfCalculator calc(o, n, Sampling(2.2e-6, 0.5, 2 * n));  // 2n pixels of lambda/(2D)
  const AnalyticAoPsf a = calc.Compute(pupil, Image::Zero(n, n));
  const double tail = calc.residual().psd().fitting_tail_rad2;
  EXPECT_NEAR(a.psf.sum(), std::exp(-tail), 1e-12);
  EXPECT_GT(a.psf.minCoeff(), -1e-15);
  const AnalyticAoPsf small = AnalyticAoPsfFromPupil(o, pupil, Image::Zero(n, n), Sampling(2.2e-6, 0.5, 24));
  EXPECT_LT(small.psf.sum(), a.psf.sum());
  EXPECT_GT(small.psf.sum(), 0.8);
  std::printf("period sum %.6f = exp(-sigma_t^2 = %.4f); 12 lambda/D window %.4f\n", a.psf.sum(), tail,
              small.psf.sum());
}

// D_res(0) = 0 and D_res -> 2 sigma^2 once the residual decorrelates (correlation length ~ d = D/16). For
// the paper system D_res at 0.75-1 D is within 1% of 2 sigma^2. A pure fitting residual (nothing inside the
// control square) keeps a weak long-range correlation along the axes, C(rho) ~ cos(2 pi f_c rho) / rho from
// the PSD's step at |fx| = f_c (the square "dark hole" edges of the PSF), so there the bound is 3%.
TEST(AnalyticAoPhysicsTest, StructureFunctionLimits) {
  AnalyticAoOptions fitting_only = PaperSystem();
  fitting_only.layers = {{0.0, 1.0, 0.0, 0.0}};
  fitting_only.aliasing = false;
  for (const AnalyticAoOptions& o : {fitting_only, PaperSystem()}) {
    const Index n = 64;
    const AnalyticAoResidual r(o, n);
    const Image& d = r.structure_function();
    EXPECT_EQ(d(n - 1, n - 1), 0.0);
    const double two_sigma2 = 2.0 * r.variance_rad2();
    // Separations of 0.75 D .. D along both axes and the diagonal.
    double worst = 0.0;
    for (Index k = 3 * n / 4; k <= n - 1; ++k) {
      for (double v : {d(n - 1, n - 1 + k), d(n - 1 + k, n - 1), d(n - 1 - k, n - 1 + k)})
        worst = std::max(worst, std::abs(v / two_sigma2 - 1.0));
    }
    std::printf("2 sigma^2 = %.4f rad^2; D_res(0.75..1 D) within %.2f%%; D_res(D/n) = %.4f\n", two_sigma2,
                100.0 * worst, d(n - 1, n));
    EXPECT_LT(worst, o.aliasing ? 0.01 : 0.03);
  }
}

// Extended Marechal: for sigma^2 < 0.5 rad^2 the long-exposure Strehl (PSF peak over the telescope's) is
// exp(-sigma^2) within 0.02 (the residual is mostly high-order: halo). Also S from the OTF equals the
// sampled peak, since the peak falls on the centre pixel.
TEST(AnalyticAoPhysicsTest, ExtendedMarechal) {
  const Index n = 64;
  const Image pupil = CircularPupil(n, PupilGeometry{8.0, 0.0}, 1);
  struct Case {
    double wavelength_m;
    double loop_rate_hz;
    double noise_rad2;
  };
  int checked = 0;
  for (const Case& c : {Case{2.2e-6, 800.0, 0.0}, Case{1.65e-6, 800.0, 0.0}, Case{1.25e-6, 800.0, 0.0},
                        Case{2.2e-6, 200.0, 0.0}, Case{1.65e-6, 200.0, 0.0}, Case{2.2e-6, 800.0, 1.0}}) {
    AnalyticAoOptions o = PaperSystem();
    o.science_wavelength_m = c.wavelength_m;
    o.loop_rate_hz = c.loop_rate_hz;
    o.wfs_noise_rad2 = c.noise_rad2;
    const PsfSampling s = Sampling(c.wavelength_m, 0.25, 128);
    const AnalyticAoPsfCalculator calc(o, n, s);
    const AnalyticAoPsf a = calc.Compute(pupil, Image::Zero(n, n));
    const Image telescope = PsfFromPupil(pupil, Image::Zero(n, n), 8.0, s);
    const double peak_strehl = PeakStrehl(a.psf, telescope);
    const double marechal = std::exp(-a.residual_variance_rad2);
    std::printf(
        "lambda %.2f um, %4.0f Hz, noise %.1f: sigma^2 = %.3f rad^2, S_peak = %.4f, exp(-sigma^2) = %.4f\n",
        c.wavelength_m * 1e6, c.loop_rate_hz, c.noise_rad2, a.residual_variance_rad2, peak_strehl, marechal);
    EXPECT_NEAR(peak_strehl, a.strehl, 1e-9);
    if (a.residual_variance_rad2 < 0.5) {
      EXPECT_NEAR(peak_strehl, marechal, 0.02);
      ++checked;
    }
  }
  EXPECT_GE(checked, 5);
}

// First-order halo: where the residual is small, exp(-D/2) ~ exp(-sigma^2) (1 + C(rho)), so beyond the
// core the PSF is the telescope's (times S) plus exp(-sigma^2) Phi_res(alpha / lambda) / lambda^2 per unit
// solid angle (convolved with the telescope PSF). Checked for a pure fitting residual (sigma^2 ~ 0.01)
// along +x from 1.25 to 3 control radii (the dark-hole edge is at lambda f_c = 8 lambda/D); the remaining
// excess grows as sigma^2 (second-order scattering Phi * Phi / 2). Inside the control region the halo
// vanishes (no servo, no aliasing): only the telescope PSF remains.
TEST(AnalyticAoPhysicsTest, HaloFollowsTheFittingPsd) {
  AnalyticAoOptions o = PaperSystem();
  o.r0_m = 0.6;
  o.layers = {{0.0, 1.0, 0.0, 0.0}};
  o.aliasing = false;
  const Index n = 64;
  const double lambda = o.science_wavelength_m;
  const double pitch_lod = 0.5;
  const PsfSampling s = Sampling(lambda, pitch_lod, 129);
  const Image pupil = CircularPupil(n, PupilGeometry{8.0, 0.0}, 1);
  const AnalyticAoPsf a = AnalyticAoPsfFromPupil(o, pupil, Image::Zero(n, n), s);
  const Image telescope = PsfFromPupil(pupil, Image::Zero(n, n), 8.0, s);
  const double r0 = o.R0At(lambda);
  const double c_vk = std::pow(24.0 / 5.0 * std::tgamma(1.2), 5.0 / 6.0) *
                      std::pow(std::tgamma(11.0 / 6.0), 2.0) / (2.0 * std::pow(kPi, 11.0 / 3.0));
  const double theta = s.pixel_scale_rad;
  for (double f_over_fc : {0.5, 1.25, 1.5, 2.0, 2.5, 3.0}) {
    const Index j = 64 + static_cast<Index>(std::lround(f_over_fc * o.ControlRadius() * lambda / theta));
    const double fx = (j - 64) * theta / lambda;
    const double phi = c_vk * std::pow(r0, -5.0 / 3.0) * std::pow(fx * fx + 1.0 / 900.0, -11.0 / 6.0);
    const double predicted = std::exp(-a.residual_variance_rad2) * phi / (lambda * lambda) * theta * theta;
    const double halo = a.psf(64, j) - a.strehl * telescope(64, j);
    std::printf("f = %.2f f_c: halo / (exp(-sigma^2) Phi theta^2 / lambda^2) = %.4f\n",
                fx / o.ControlRadius(), halo / predicted);
    if (f_over_fc < 1.0) {
      EXPECT_LT(std::abs(halo), 0.01 * predicted);
    } else {
      EXPECT_NEAR(halo / predicted, 1.0, 0.1);
    }
  }
}

// Greenwood: with an unbounded control region and a Kolmogorov PSD, sigma_servo^2 = v^(5/3) * const
// exactly (substitute u = f v in int Phi(f) |E(f.v)|^2 d^2f), i.e. (f_G / f_3dB)^(5/3) up to a constant set
// by the rejection curve's shape. A finite control region (f_c = 10 m^-1 here, d = 5 cm) pushes the
// exponent toward 2 at low speed (the whole region below the crossover f_3dB / v, |E|^2 ~ nu^2) and the
// grid's resolution of the lowest frequencies pulls it below 5/3 at high speed; between, at 15 -> 30 m/s
// (crossover 2 -> 1 m^-1, small error), it is 5/3 within 0.1. Zero gain: the servo term is the whole
// turbulence inside the control region.
TEST(AnalyticAoPhysicsTest, ServoLagFollowsGreenwood) {
  AnalyticAoOptions o;
  o.diameter_m = 8.0;
  o.actuator_pitch_m = 0.05;
  o.r0_m = 1.0;
  o.reference_wavelength_m = 2.2e-6;
  o.science_wavelength_m = 2.2e-6;
  o.outer_scale_m = kInf;
  o.loop_rate_hz = 800.0;
  o.loop_gain = 0.35;
  o.loop_delay_frames = 1.0;
  o.aliasing = false;
  // f_3dB: |E(f_3dB)|^2 = 1/2, by bisection on [0, 1/(2T)].
  double lo = 0.0, hi = o.loop_rate_hz / 2.0;
  for (int it = 0; it < 60; ++it) {
    const double mid = 0.5 * (lo + hi);
    (std::norm(AnalyticAoLoopTransfer(o, mid).rejection) < 0.5 ? lo : hi) = mid;
  }
  const double f3db = lo;
  double servo[2];
  const double speeds[2] = {15.0, 30.0};
  for (int i = 0; i < 2; ++i) {
    o.layers = {{0.0, 1.0, speeds[i], 0.0}};
    const AnalyticAoErrorBudget b = ComputeAnalyticAoErrorBudget(o);
    servo[i] = b.servo_rad2;
    const double greenwood = std::pow(0.4275 * speeds[i] / o.r0_m / f3db, 5.0 / 3.0);
    std::printf(
        "v = %.0f m/s: sigma_servo^2 = %.4f rad^2, (f_G/f_3dB)^(5/3) = %.4f (f_3dB = %.1f Hz), ratio %.3f\n",
        speeds[i], servo[i], greenwood, f3db, servo[i] / greenwood);
    EXPECT_LT(servo[i], 0.3);
    EXPECT_GT(servo[i] / greenwood, 0.3);
    EXPECT_LT(servo[i] / greenwood, 3.0);
  }
  const double exponent = std::log(servo[1] / servo[0]) / std::log(speeds[1] / speeds[0]);
  std::printf("servo-lag exponent %.3f (Greenwood 5/3)\n", exponent);
  EXPECT_NEAR(exponent, 5.0 / 3.0, 0.1);
}

// The system of the issue: K-band Strehl and error budget. The issue quotes ~0.87. Fitting alone gives
// exp(-0.107) = 0.90 and aliasing (~1/3 of fitting for a Shack-Hartmann) 0.034 rad^2 more, so the
// bracket 0.80-0.92 allows for the servo-lag and delay conventions while catching any lost or doubled term.
TEST(AnalyticAoPhysicsTest, PaperSystemKBand) {
  for (double delay : {1.0, 0.0}) {
    AnalyticAoOptions o = PaperSystem();
    o.loop_delay_frames = delay;
    const Index n = 64;
    const Image pupil = CircularPupil(n, PupilGeometry{8.0, 0.0}, 1);
    const AnalyticAoPsfCalculator calc(o, n, Sampling(2.2e-6, 0.25, 128));
    const AnalyticAoPsf a = calc.Compute(pupil, Image::Zero(n, n));
    const AnalyticAoErrorBudget& b = calc.residual().budget();
    std::printf(
        "8 m, 17x17 DM, 800 Hz, g = 0.35, k = %.0f frame (total lag %.2f ms): K-band Strehl %.4f "
        "(exp(-sigma^2) = %.4f)\n%s",
        delay, (delay + 1.0) / o.loop_rate_hz * 1e3, a.strehl, b.MarechalStrehl(), b.BriefReport().c_str());
    EXPECT_GT(a.strehl, 0.80);
    EXPECT_LT(a.strehl, 0.92);
    // Budget in the expected proportions: fitting dominates, aliasing ~ 1/3 of it, servo-lag small.
    EXPECT_NEAR(b.aliasing_rad2 / b.fitting_rad2, 0.32, 0.08);
    EXPECT_LT(b.servo_rad2, 0.2 * b.fitting_rad2);
    // The standalone budget (its own grid) agrees with the pupil-matched one.
    const AnalyticAoErrorBudget alone = ComputeAnalyticAoErrorBudget(o);
    EXPECT_NEAR(alone.TotalRad2() / b.TotalRad2(), 1.0, 1e-3);
  }
}

// Timing (printed, not asserted): the residual (PSD + structure function) once per configuration, then
// one 128 x 128 PSF at HR sampling (lambda/(4D)) per exposure.
TEST(AnalyticAoPhysicsTest, Timing) {
  const AnalyticAoOptions o = PaperSystem();
  for (Index n : {64, 128}) {
    const Image pupil = CircularPupil(n, PupilGeometry{8.0, 0.14}, 2);
    const Image opd = Zernike(5, n) * 50e-9;
    const PsfSampling s = Sampling(2.2e-6, 0.25, 128);
    AnalyticAoPsfCalculator(o, n, s).Compute(pupil, opd);  // warm the FFT plan cache
    auto t0 = std::chrono::steady_clock::now();
    const AnalyticAoPsfCalculator calc(o, n, s);
    const double t_build = Ms(t0);
    const int reps = 5;
    t0 = std::chrono::steady_clock::now();
    double sink = 0.0;
    for (int r = 0; r < reps; ++r) sink += calc.Compute(pupil, opd).psf(64, 64);
    const double t_psf = Ms(t0) / reps;
    std::printf("pupil n = %ld: residual + calculator %.1f ms, one 128x128 PSF %.2f ms (peak %.4f)\n",
                static_cast<long>(n), t_build, t_psf, sink / reps);
    EXPECT_GT(sink, 0.0);
  }
}

}  // namespace
}  // namespace aosr
