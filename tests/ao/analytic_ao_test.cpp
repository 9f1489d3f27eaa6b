// Unit tests of the analytic AO model: options, loop transfer functions, PSD terms and their integrals,
// structure-function geometry (include/aosr/ao/analytic_ao.hpp).
#include "aosr/core/image.hpp"  // kPi
#include "aosr/ao/analytic_ao.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <iostream>
#include <limits>
#include <string>
#include <utility>

namespace aosr {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

// The von Karman constant, written out independently of the library.
double VonKarmanC() {
  return std::pow(24.0 / 5.0 * std::tgamma(1.2), 5.0 / 6.0) * std::pow(std::tgamma(11.0 / 6.0), 2.0) /
         (2.0 * std::pow(kPi, 11.0 / 3.0));
}

// A pure fitting case: Kolmogorov, frozen turbulence (no servo-lag), no aliasing, no noise. r0 is given at
// the science wavelength so (d/r0) is the science-band ratio.
AnalyticAoOptions PureFitting(ControlDomain domain) {
  AnalyticAoOptions o;
  o.diameter_m = 8.0;
  o.actuator_pitch_m = 0.5;
  o.control_domain = domain;
  o.r0_m = 0.4;
  o.reference_wavelength_m = 2.2e-6;
  o.science_wavelength_m = 2.2e-6;
  o.outer_scale_m = kInf;
  o.layers = {Layer{0.0, 1.0, 0.0, 0.0}};
  o.aliasing = false;
  return o;
}

TEST(AnalyticAoTest, DefaultOptionsAreValidAndR0ScalesAsLambdaToTheSixFifths) {
  AnalyticAoOptions o;
  std::string why;
  EXPECT_TRUE(o.IsValid(&why)) << why;
  EXPECT_NEAR(o.R0At(2.0 * o.reference_wavelength_m), o.r0_m * std::pow(2.0, 1.2), 1e-15);
  EXPECT_DOUBLE_EQ(o.ControlRadius(), 1.0);  // 1/(2 * 0.5 m)
  o.r0_m = kInf;
  o.outer_scale_m = kInf;
  EXPECT_TRUE(o.IsValid(&why)) << why;
}

TEST(AnalyticAoTest, LoopTransferLimits) {
  AnalyticAoOptions o;
  o.loop_rate_hz = 1000.0;
  o.loop_gain = 0.4;
  o.loop_delay_frames = 1.0;
  // Integrator: full rejection of the static component, unit noise transfer there.
  const LoopTransfer dc = AnalyticAoLoopTransfer(o, 0.0);
  EXPECT_EQ(std::abs(dc.rejection), 0.0);
  EXPECT_EQ(std::abs(dc.noise - Complex(1.0, 0.0)), 0.0);
  // E + H_n = 1 at every frequency, and |E| ~ 2 pi nu T / g at low frequency.
  for (double nu : {-300.0, 0.01, 1.0, 40.0, 499.0, 3000.0}) {
    const LoopTransfer t = AnalyticAoLoopTransfer(o, nu);
    EXPECT_NEAR(std::abs(t.rejection + t.noise - Complex(1.0, 0.0)), 0.0, 1e-12) << nu;
    EXPECT_NEAR(std::abs(t.rejection), std::abs(1.0 / (1.0 + t.open_loop)), 1e-12) << nu;
  }
  const double nu = 0.01;
  EXPECT_NEAR(std::abs(AnalyticAoLoopTransfer(o, nu).rejection), 2.0 * kPi * nu / 1000.0 / 0.4, 1e-6);
  // Far above the loop bandwidth the loop does nothing: |E| -> 1.
  EXPECT_NEAR(std::abs(AnalyticAoLoopTransfer(o, 1e6).rejection), 1.0, 1e-6);
  // Zero gain: open loop everywhere.
  o.loop_gain = 0.0;
  for (double f : {0.0, 3.0, 200.0}) {
    EXPECT_EQ(std::abs(AnalyticAoLoopTransfer(o, f).rejection - Complex(1.0, 0.0)), 0.0) << f;
    EXPECT_EQ(std::abs(AnalyticAoLoopTransfer(o, f).noise), 0.0) << f;
  }
}

// Discrete closed-loop poles: z^2 - z + g = 0 for k = 1 (stable for g < 1), z (z - 1 + g) for k = 0 (g < 2).
TEST(AnalyticAoTest, StabilityLimitsOfTheIntegrator) {
  EXPECT_NEAR(AnalyticAoLoopSpectralRadius(0.5, 1.0), std::sqrt(0.5), 1e-12);
  EXPECT_LT(AnalyticAoLoopSpectralRadius(0.99, 1.0), 1.0);
  EXPECT_GT(AnalyticAoLoopSpectralRadius(1.01, 1.0), 1.0);
  EXPECT_LT(AnalyticAoLoopSpectralRadius(1.99, 0.0), 1.0);
  EXPECT_GT(AnalyticAoLoopSpectralRadius(2.01, 0.0), 1.0);
  // A fractional delay lies between its integer neighbours.
  EXPECT_GT(AnalyticAoLoopSpectralRadius(0.9, 1.5), AnalyticAoLoopSpectralRadius(0.9, 1.0));
  EXPECT_LT(AnalyticAoLoopSpectralRadius(0.9, 1.5), AnalyticAoLoopSpectralRadius(0.9, 2.0));
  AnalyticAoOptions o;
  o.loop_delay_frames = 1.0;
  o.loop_gain = 1.05;
  std::string why;
  EXPECT_FALSE(o.IsValid(&why));
  EXPECT_NE(why.find("loop_gain"), std::string::npos) << why;
}

// For small g, |H_n|^2 ~ g^2 / (x^2 + g^2), whose integral gives G_n -> g/2 (the discrete integrator's
// g / (2 - g) to first order). G_n grows with the gain and vanishes at g = 0.
TEST(AnalyticAoTest, NoiseGain) {
  AnalyticAoOptions o;
  o.loop_delay_frames = 1.0;
  o.loop_gain = 1e-3;
  EXPECT_NEAR(AnalyticAoNoiseGain(o) / 5e-4, 1.0, 5e-3);
  o.loop_gain = 0.0;
  EXPECT_EQ(AnalyticAoNoiseGain(o), 0.0);
  double previous = 0.0;
  for (double g : {0.1, 0.3, 0.5, 0.7}) {
    o.loop_gain = g;
    const double gain = AnalyticAoNoiseGain(o);
    EXPECT_GT(gain, previous) << g;
    previous = gain;
    std::cout << "noise gain g = " << g << " (k = 1): G_n = " << gain
              << " (discrete k = 0 integrator: " << g / (2.0 - g) << ")\n";
  }
}

// sigma_fit^2 for a circular domain of radius f_c has the closed form
//     int_{f > f_c} c r0^(-5/3) f^(-11/3) 2 pi f df = (6 pi / 5) c r0^(-5/3) f_c^(-5/3)
//                                                  = (6 pi / 5) c 2^(5/3) (d/r0)^(5/3) = 0.2740 (d/r0)^(5/3).
// The library's grid sum (with one-cell ramps at the domain edge) plus analytic tail must match to 1e-3.
TEST(AnalyticAoTest, FittingVarianceOfACircularDomainMatchesTheClosedForm) {
  const AnalyticAoOptions o = PureFitting(ControlDomain::kCircle);
  const double ratio53 = std::pow(o.actuator_pitch_m / o.r0_m, 5.0 / 3.0);
  const double expected = 1.2 * kPi * VonKarmanC() * std::pow(2.0, 5.0 / 3.0) * ratio53;
  const AnalyticAoErrorBudget b = ComputeAnalyticAoErrorBudget(o);
  EXPECT_NEAR(b.fitting_rad2 / expected, 1.0, 1e-3);
  EXPECT_EQ(b.servo_rad2, 0.0);
  EXPECT_EQ(b.noise_rad2, 0.0);
  EXPECT_EQ(b.aliasing_rad2, 0.0);
  // The pupil-matched grid of AnalyticAoResidual agrees as well.
  const AnalyticAoResidual r(o, 64);
  EXPECT_NEAR(r.budget().fitting_rad2 / expected, 1.0, 1e-3);
  std::cout << "circular domain: sigma_fit^2 = " << b.fitting_rad2 / ratio53 << " (d/r0)^(5/3), closed form "
            << expected / ratio53 << "\n";
}

// Square domain |fx|, |fy| < f_c: in polar coordinates the domain edge is at f_c / max(|cos t|, |sin t|), so
//     sigma^2 = c r0^(-5/3) (3/5) f_c^(-5/3) * 8 int_0^{pi/4} cos(t)^(5/3) dt,
// a 1-D integral done here by Simpson's rule: an independent check of the library's 2-D grid.
TEST(AnalyticAoTest, FittingVarianceOfTheSquareDomain) {
  const AnalyticAoOptions o = PureFitting(ControlDomain::kSquare);
  const int intervals = 2000;
  const double h = kPi / 4.0 / intervals;
  double sum = 1.0 + std::pow(std::cos(kPi / 4.0), 5.0 / 3.0);
  for (int i = 1; i < intervals; ++i) sum += (i % 2 ? 4.0 : 2.0) * std::pow(std::cos(i * h), 5.0 / 3.0);
  const double angular = 8.0 * sum * h / 3.0;
  const double f_c = o.ControlRadius();
  const double expected =
      VonKarmanC() * std::pow(o.r0_m, -5.0 / 3.0) * 0.6 * std::pow(f_c, -5.0 / 3.0) * angular;
  const AnalyticAoErrorBudget b = ComputeAnalyticAoErrorBudget(o);
  EXPECT_NEAR(b.fitting_rad2 / expected, 1.0, 1e-3);
  const double coefficient = b.fitting_rad2 / std::pow(o.actuator_pitch_m / o.r0_m, 5.0 / 3.0);
  std::cout << "square domain: sigma_fit^2 = " << coefficient << " (d/r0)^(5/3) (1-D quadrature: "
            << expected / std::pow(o.actuator_pitch_m / o.r0_m, 5.0 / 3.0) << ")\n";
  EXPECT_NEAR(coefficient, 0.2314, 5e-4);
}

// The budget converges with the frequency padding K (low-frequency resolution): K = 4 (default) is within
// 1% of K = 8 for a full system with servo-lag and aliasing.
TEST(AnalyticAoTest, BudgetConvergesWithFrequencyPadding) {
  AnalyticAoOptions o;
  o.layers = {{0.0, 0.6, 8.0, 0.3}, {5000.0, 0.4, 20.0, 2.0}};
  o.wfs_noise_rad2 = 0.2;
  AnalyticAoErrorBudget b[2];
  for (int i = 0; i < 2; ++i) {
    o.frequency_padding = 4 * (i + 1);
    b[i] = ComputeAnalyticAoErrorBudget(o);
  }
  EXPECT_NEAR(b[0].fitting_rad2 / b[1].fitting_rad2, 1.0, 1e-2);
  EXPECT_NEAR(b[0].servo_rad2 / b[1].servo_rad2, 1.0, 1e-2);
  EXPECT_NEAR(b[0].noise_rad2 / b[1].noise_rad2, 1.0, 1e-2);
  EXPECT_NEAR(b[0].aliasing_rad2 / b[1].aliasing_rad2, 1.0, 1e-2);
  // The noise term is sigma_n^2 (lambda_ref/lambda)^2 G_n (its PSD integrates to that over the domain).
  const double ratio = o.reference_wavelength_m / o.science_wavelength_m;
  EXPECT_NEAR(b[1].noise_rad2 / (o.wfs_noise_rad2 * ratio * ratio * AnalyticAoNoiseGain(o)), 1.0, 1e-3);
}

// The aliasing coefficient, re-derived numerically from the Shack-Hartmann model: sub-aperture phase
// differences G_x(f) = 2i sin(pi fx d) sinc(fy d), G_y(f) = 2i sin(pi fy d) sinc(fx d), sampled on the
// pitch-d lattice (so f_mn = f + (m, n)/d lands on f) and inverted by the least-squares Fourier
// reconstructor: c_mn = (G_x(f)* G_x(f_mn) + G_y(f)* G_y(f_mn)) / (|G_x(f)|^2 + |G_y(f)|^2). With frozen
// turbulence (|H_n(0)|^2 = 1) the aliasing PSD at a controlled cell is sum c_mn^2 Phi(f_mn).
TEST(AnalyticAoTest, AliasingMatchesTheShackHartmannModel) {
  AnalyticAoOptions o;
  o.layers = {Layer{0.0, 1.0, 0.0, 0.0}};
  o.aliasing_orders = 3;
  const Index p = 112;
  const double df = 1.0 / (4.0 * o.diameter_m);
  const ResidualPsd psd = ComputeResidualPsd(o, p, df);
  const double d = o.actuator_pitch_m;
  const double r0 = o.R0At(o.science_wavelength_m);
  auto phi = [&](double fx, double fy) {
    return VonKarmanC() * std::pow(r0, -5.0 / 3.0) *
           std::pow(fx * fx + fy * fy + 1.0 / (o.outer_scale_m * o.outer_scale_m), -11.0 / 6.0);
  };
  auto sinc = [](double u) { return u == 0.0 ? 1.0 : std::sin(kPi * u) / (kPi * u); };
  auto gx = [&](double fx, double fy) { return Complex(0.0, 2.0 * std::sin(kPi * fx * d) * sinc(fy * d)); };
  auto gy = [&](double fx, double fy) { return Complex(0.0, 2.0 * std::sin(kPi * fy * d) * sinc(fx * d)); };
  for (const auto& cell : {std::pair<Index, Index>{3, 5}, {-7, 20}, {0, 11}, {-25, -30}, {16, 0}}) {
    const Index i = p / 2 + cell.first, j = p / 2 + cell.second;
    const double fx = cell.second * df, fy = cell.first * df;
    const Complex ax = gx(fx, fy), ay = gy(fx, fy);
    const double norm = std::norm(ax) + std::norm(ay);
    double expected = 0.0;
    for (int m = -3; m <= 3; ++m) {
      for (int n = -3; n <= 3; ++n) {
        if (m == 0 && n == 0) continue;
        const double bx = fx + m / d, by = fy + n / d;
        const Complex c = (std::conj(ax) * gx(bx, by) + std::conj(ay) * gy(bx, by)) / norm;
        EXPECT_NEAR(c.imag(), 0.0, 1e-12);
        expected += std::norm(c) * phi(bx, by);
      }
    }
    EXPECT_NEAR(psd.aliasing(i, j) / expected, 1.0, 1e-10) << cell.first << "," << cell.second;
  }
}

// M = 3 aliasing orders hold all but < 1% of the aliasing variance (the terms fall as |f_mn|^(-11/3)).
TEST(AnalyticAoTest, AliasingOrdersConverge) {
  AnalyticAoOptions o;
  o.aliasing_orders = 3;
  const double m3 = ComputeAnalyticAoErrorBudget(o).aliasing_rad2;
  o.aliasing_orders = 8;
  const double m8 = ComputeAnalyticAoErrorBudget(o).aliasing_rad2;
  EXPECT_LT(m3, m8);
  EXPECT_GT(m3 / m8, 0.99);
}

// Averaging the wind over directions gives an isotropic servo PSD (f -> rotated f by 90 degrees equal).
TEST(AnalyticAoTest, DirectionAveragedWindIsIsotropic) {
  AnalyticAoOptions o;
  o.layers = {Layer{0.0, 1.0, 20.0, 0.3}};
  o.average_wind_direction = true;
  const Index p = 112;
  const ResidualPsd psd = ComputeResidualPsd(o, p, 1.0 / (4.0 * o.diameter_m));
  for (Index a = 1; a < 30; a += 4)
    for (Index b = -29; b < 30; b += 7) {
      const double v = psd.servo(p / 2 + a, p / 2 + b);
      EXPECT_NEAR(psd.servo(p / 2 - b, p / 2 + a), v, 1e-12 * v) << a << "," << b;
    }
  o.average_wind_direction = false;
  const ResidualPsd directed = ComputeResidualPsd(o, p, 1.0 / (4.0 * o.diameter_m));
  EXPECT_GT(std::abs(directed.servo(p / 2 + 20, p / 2) - directed.servo(p / 2, p / 2 + 20)),
            0.1 * directed.servo(p / 2 + 20, p / 2));
}

// PSD terms are even in f (real covariance) and non-negative; the piston cell is empty.
TEST(AnalyticAoTest, PsdTermsAreEvenAndNonNegative) {
  AnalyticAoOptions o;
  o.layers = {{0.0, 0.5, 12.0, 0.7}, {8000.0, 0.5, 30.0, -1.2}};
  o.wfs_noise_rad2 = 0.1;
  const Index p = 96;
  const ResidualPsd psd = ComputeResidualPsd(o, p, 1.0 / (4.0 * o.diameter_m));
  for (const Image* term : {&psd.fitting, &psd.servo, &psd.noise, &psd.aliasing}) {
    EXPECT_GE(term->minCoeff(), 0.0);
    EXPECT_EQ((*term)(p / 2, p / 2), 0.0);
    for (Index i = 1; i < p; ++i)
      for (Index j = 1; j < p; ++j)
        ASSERT_NEAR((*term)(i, j), (*term)(p - i, p - j), 1e-12 * term->maxCoeff());
  }
  EXPECT_GT(psd.servo.sum(), 0.0);
  EXPECT_GT(psd.aliasing.sum(), 0.0);
}

// Zero gain: nothing is corrected, the "servo" term inside the control region is the turbulence itself,
// and fitting + servo is the von Karman PSD on every cell of the grid's disk; noise and aliasing vanish.
TEST(AnalyticAoTest, ZeroGainLeavesTheTurbulenceUncorrected) {
  AnalyticAoOptions o;
  o.loop_gain = 0.0;
  o.wfs_noise_rad2 = 0.3;
  const Index p = 112;
  const double df = 1.0 / (4.0 * o.diameter_m);
  const ResidualPsd psd = ComputeResidualPsd(o, p, df);
  EXPECT_EQ(psd.noise.abs().maxCoeff(), 0.0);
  EXPECT_EQ(psd.aliasing.abs().maxCoeff(), 0.0);
  const double r0 = o.R0At(o.science_wavelength_m);
  const double f_t = psd.tail_radius_per_m;
  double max_rel = 0.0;
  for (Index i = 0; i < p; ++i) {
    for (Index j = 0; j < p; ++j) {
      const double fx = (j - p / 2) * df, fy = (i - p / 2) * df;
      const double f = std::hypot(fx, fy);
      if (f == 0.0 || f > f_t - df) continue;  // piston cell, and the one-cell ramp at the disk's edge
      const double phi = VonKarmanC() * std::pow(r0, -5.0 / 3.0) *
                         std::pow(f * f + 1.0 / (o.outer_scale_m * o.outer_scale_m), -11.0 / 6.0);
      max_rel = std::max(max_rel, std::abs(psd.fitting(i, j) + psd.servo(i, j) - phi) / phi);
    }
  }
  EXPECT_LT(max_rel, 1e-12);
  EXPECT_GT(psd.servo.sum(), 0.0);
}

TEST(AnalyticAoTest, StructureFunctionGeometry) {
  AnalyticAoOptions o;
  o.layers = {{0.0, 1.0, 15.0, 0.4}};
  const Index n = 32;
  const AnalyticAoResidual r(o, n);
  const Image& d = r.structure_function();
  ASSERT_EQ(d.rows(), 2 * n - 1);
  ASSERT_EQ(d.cols(), 2 * n - 1);
  EXPECT_EQ(d(n - 1, n - 1), 0.0);
  EXPECT_GE(d.minCoeff(), 0.0);
  EXPECT_DOUBLE_EQ(r.separation_step_m(), o.diameter_m / n);
  // D(rho) = D(-rho).
  for (Index i = 0; i < 2 * n - 1; ++i)
    for (Index j = 0; j < 2 * n - 1; ++j) ASSERT_NEAR(d(i, j), d(2 * n - 2 - i, 2 * n - 2 - j), 1e-12);
  // The in-band part differs from the total by the tail, which is 2 sigma_t^2 q(.) >= 0 and -> 2 sigma_t^2.
  const Image tail = d - r.in_band_structure_function();
  EXPECT_EQ(tail(n - 1, n - 1), 0.0);
  EXPECT_NEAR(tail(n - 1, 0), 2.0 * r.psd().fitting_tail_rad2, 3e-3 * r.psd().fitting_tail_rad2);
}

TEST(AnalyticAoTest, BudgetUnitsAndReport) {
  AnalyticAoErrorBudget b;
  b.wavelength_m = 2.2e-6;
  b.fitting_rad2 = 0.1;
  b.servo_rad2 = 0.02;
  b.aliasing_rad2 = 0.03;
  EXPECT_NEAR(b.TotalRad2(), 0.15, 1e-15);
  EXPECT_NEAR(b.Nm(1.0), 2.2e-6 / (2.0 * kPi) * 1e9, 1e-9);
  EXPECT_NEAR(b.MarechalStrehl(), std::exp(-0.15), 1e-15);
  const std::string report = b.BriefReport();
  for (const char* word : {"fitting", "servo-lag", "noise", "aliasing", "total", "nm"})
    EXPECT_NE(report.find(word), std::string::npos) << report;
}

}  // namespace
}  // namespace aosr
