// Analytic AO: options validation and the control-loop transfer functions (header section 3).
#include <Eigen/Eigenvalues>
#include <cmath>
#include <limits>

#include "analytic_ao_internal.hpp"
#include "aosr/ao/analytic_ao.hpp"
#include "aosr/core/error.hpp"

namespace aosr {


namespace analytic_ao_internal {


void CheckOptions(const AnalyticAoOptions& options, const char* function) {
  std::string why;
  if (!options.IsValid(&why)) throw InvalidArgument(std::string(function) + ": invalid options. " + why);
}

// With s = sin(x/2) and phi = x (k + 1/2):  H_ol = -2 i g s exp(-i phi) / x^2, so
//   1 + H_ol = [ (x^2 - 2 g s sin phi) - 2 i g s cos phi ] / x^2 =: den / x^2,
//   |E|^2 = x^4 / |den|^2,   |H_n|^2 = |H_ol|^2 |E|^2 = 4 g^2 s^2 / |den|^2.
// Written this way (sin(x/2) rather than 1 - exp(-i x)) it loses no precision at small x.
LoopModel::Squares LoopModel::At(double x) const {
  Squares out;
  if (x == 0.0) {
    if (gain > 0.0) {
      out.rejection = 0.0;
      out.noise = 1.0;
    }
    return out;
  }
  const double s = std::sin(0.5 * x);
  const double phi = x * (delay_frames + 0.5);
  const double x2 = x * x;
  const double re = x2 - 2.0 * gain * s * std::sin(phi);
  const double im = -2.0 * gain * s * std::cos(phi);
  const double den = re * re + im * im;
  out.rejection = x2 * x2 / den;
  out.noise = 4.0 * gain * gain * s * s / den;
  return out;
}

}  // namespace analytic_ao_internal

namespace {


bool PositiveFinite(double v) { return std::isfinite(v) && v > 0.0; }

// Largest stable gain for a delay (bisection on the spectral radius), for error messages.
double MaxStableGain(double delay_frames) {
  double lo = 0.0, hi = 4.0;
  for (int it = 0; it < 50; ++it) {
    const double mid = 0.5 * (lo + hi);
    (AnalyticAoLoopSpectralRadius(mid, delay_frames) < 1.0 ? lo : hi) = mid;
  }
  return lo;
}

}  // namespace

double AnalyticAoOptions::R0At(double wavelength_m) const {
  return r0_m * std::pow(wavelength_m / reference_wavelength_m, 6.0 / 5.0);
}

bool AnalyticAoOptions::IsValid(std::string* why) const {
  if (!PositiveFinite(diameter_m)) {
    return Fail(why, "diameter_m = " + ToString(diameter_m) + "; allowed: > 0 and finite [m]");
  }
  if (!(PositiveFinite(actuator_pitch_m) && actuator_pitch_m < 0.5 * diameter_m)) {
    return Fail(why, "actuator_pitch_m = " + ToString(actuator_pitch_m) +
                         "; allowed: > 0 and < diameter_m / 2 = " + ToString(0.5 * diameter_m) + " [m]");
  }
  if (control_domain != ControlDomain::kSquare && control_domain != ControlDomain::kCircle) {
    return Fail(why, "control_domain = " + ToString(static_cast<int>(control_domain)) +
                         "; allowed: kSquare or kCircle");
  }
  if (!(r0_m > 0.0)) {  // also rejects NaN; +inf (no turbulence) is allowed
    return Fail(why, "r0_m = " + ToString(r0_m) + "; allowed: > 0 [m] (+inf: no turbulence)");
  }
  if (!PositiveFinite(reference_wavelength_m)) {
    return Fail(why, "reference_wavelength_m = " + ToString(reference_wavelength_m) +
                         "; allowed: > 0 and finite [m]");
  }
  if (!(outer_scale_m > 0.0)) {
    return Fail(why, "outer_scale_m = " + ToString(outer_scale_m) + "; allowed: > 0 [m] (+inf: Kolmogorov)");
  }
  if (layers.empty()) return Fail(why, "layers: empty; allowed: at least one layer");
  double fraction_sum = 0.0;
  for (std::size_t l = 0; l < layers.size(); ++l) {
    const Layer& layer = layers[l];
    const std::string name = "layers[" + std::to_string(l) + "].";
    if (!(std::isfinite(layer.altitude_m) && layer.altitude_m >= 0.0)) {
      return Fail(why,
                  name + "altitude_m = " + ToString(layer.altitude_m) + "; allowed: >= 0 and finite [m]");
    }
    if (!(layer.cn2_fraction >= 0.0 && layer.cn2_fraction <= 1.0)) {
      return Fail(why, name + "cn2_fraction = " + ToString(layer.cn2_fraction) + "; allowed: [0, 1]");
    }
    if (!(std::isfinite(layer.wind_speed_mps) && layer.wind_speed_mps >= 0.0)) {
      return Fail(why, name + "wind_speed_mps = " + ToString(layer.wind_speed_mps) +
                           "; allowed: >= 0 and finite [m/s]");
    }
    if (!std::isfinite(layer.wind_direction_rad)) {
      return Fail(why, name + "wind_direction_rad = " + ToString(layer.wind_direction_rad) +
                           "; allowed: finite [rad]");
    }
    fraction_sum += layer.cn2_fraction;
  }
  if (std::abs(fraction_sum - 1.0) > 1e-6) {
    return Fail(why, "layers[].cn2_fraction sum = " + ToString(fraction_sum) + "; allowed: 1 (within 1e-6)");
  }
  if (!PositiveFinite(loop_rate_hz)) {
    return Fail(why, "loop_rate_hz = " + ToString(loop_rate_hz) + "; allowed: > 0 and finite [Hz]");
  }
  if (!(loop_delay_frames >= 0.0 && loop_delay_frames <= 20.0)) {
    return Fail(why, "loop_delay_frames = " + ToString(loop_delay_frames) + "; allowed: [0, 20] [frames]");
  }
  if (!(std::isfinite(loop_gain) && loop_gain >= 0.0)) {
    return Fail(why, "loop_gain = " + ToString(loop_gain) + "; allowed: >= 0 and finite");
  }
  if (loop_gain > 0.0) {
    const double radius = AnalyticAoLoopSpectralRadius(loop_gain, loop_delay_frames);
    if (!(radius < 1.0)) {
      return Fail(why, "loop_gain = " + ToString(loop_gain) + " is unstable with loop_delay_frames = " +
                           ToString(loop_delay_frames) + " (closed-loop pole modulus " + ToString(radius) +
                           "); allowed: [0, " + ToString(MaxStableGain(loop_delay_frames)) + ")");
    }
  }
  if (!(std::isfinite(wfs_noise_rad2) && wfs_noise_rad2 >= 0.0)) {
    return Fail(why, "wfs_noise_rad2 = " + ToString(wfs_noise_rad2) + "; allowed: >= 0 and finite [rad^2]");
  }
  if (!PositiveFinite(science_wavelength_m)) {
    return Fail(why,
                "science_wavelength_m = " + ToString(science_wavelength_m) + "; allowed: > 0 and finite [m]");
  }
  if (frequency_padding < 2 || frequency_padding > 64) {
    return Fail(why, "frequency_padding = " + ToString(frequency_padding) + "; allowed: [2, 64]");
  }
  if (aliasing_orders < 1 || aliasing_orders > 10) {
    return Fail(why, "aliasing_orders = " + ToString(aliasing_orders) + "; allowed: [1, 10]");
  }
  return true;
}

double AnalyticAoLoopSpectralRadius(double gain, double delay_frames) {
  CheckArgument(std::isfinite(gain) && gain >= 0.0, "AnalyticAoLoopSpectralRadius", "gain", gain,
                ">= 0 and finite");
  CheckArgument(delay_frames >= 0.0 && delay_frames <= 20.0, "AnalyticAoLoopSpectralRadius", "delay_frames",
                delay_frames, "[0, 20]");
  // Closed loop (header section 3): z^(k+2) - z^(k+1) + g (1 - a) z + g a = 0 for k = floor(delay), a the
  // fraction. Roots = eigenvalues of the companion matrix of the monic polynomial.
  const int k = static_cast<int>(std::floor(delay_frames));
  const double a = delay_frames - k;
  const int degree = k + 2;
  Eigen::VectorXd c = Eigen::VectorXd::Zero(degree);  // c[i]: coefficient of z^i, i < degree
  c[degree - 1] -= 1.0;
  c[1] += gain * (1.0 - a);
  c[0] += gain * a;
  Eigen::MatrixXd companion = Eigen::MatrixXd::Zero(degree, degree);
  for (int i = 1; i < degree; ++i) companion(i, i - 1) = 1.0;
  for (int i = 0; i < degree; ++i) companion(i, degree - 1) = -c[i];
  const Eigen::VectorXcd roots = Eigen::EigenSolver<Eigen::MatrixXd>(companion, false).eigenvalues();
  return roots.cwiseAbs().maxCoeff();
}

LoopTransfer AnalyticAoLoopTransfer(const AnalyticAoOptions& options, double nu_hz) {
  analytic_ao_internal::CheckOptions(options, "AnalyticAoLoopTransfer");
  CheckArgument(std::isfinite(nu_hz), "AnalyticAoLoopTransfer", "nu_hz", nu_hz, "finite [Hz]");
  const double g = options.loop_gain;
  const double x = kTwoPi * nu_hz / options.loop_rate_hz;
  LoopTransfer out;
  if (x == 0.0) {
    out.open_loop = g > 0.0 ? Complex(0.0, -std::numeric_limits<double>::max()) : Complex(0.0, 0.0);
    out.rejection = g > 0.0 ? 0.0 : 1.0;
    out.noise = 1.0 - out.rejection;
    return out;
  }
  const double s = std::sin(0.5 * x);
  const double phi = x * (options.loop_delay_frames + 0.5);
  out.open_loop = Complex(0.0, -2.0 * g * s) * std::polar(1.0, -phi) / (x * x);
  out.rejection = 1.0 / (1.0 + out.open_loop);
  out.noise = out.open_loop * out.rejection;
  return out;
}

double AnalyticAoNoiseGain(const AnalyticAoOptions& options) {
  analytic_ao_internal::CheckOptions(options, "AnalyticAoNoiseGain");
  // G_n = (1/pi) int_0^pi |H_n(x)|^2 dx with x = 2 pi nu T (|H_n|^2 is even). Near 0, |H_n|^2 ~
  // g^2 / (x^2 + g^2), a peak of width g; the substitution x = g sinh(v) makes the integrand smooth
  // (~ g / cosh v) for every gain, and composite Simpson on 4096 intervals converges to ~1e-12.
  const double g = options.loop_gain;
  if (g == 0.0) return 0.0;
  const analytic_ao_internal::LoopModel loop{g, options.loop_delay_frames};
  const int intervals = 4096;
  const double v_max = std::asinh(kPi / g);
  const double h = v_max / intervals;
  auto integrand = [&](double v) { return loop.At(g * std::sinh(v)).noise * g * std::cosh(v); };
  double sum = integrand(0.0) + integrand(v_max);
  for (int i = 1; i < intervals; ++i) sum += (i % 2 == 1 ? 4.0 : 2.0) * integrand(i * h);
  return sum * h / 3.0 / kPi;
}

}  // namespace aosr
