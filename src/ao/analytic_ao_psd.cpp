// Analytic AO: the residual phase PSD terms, the error budget and the fitting tail (header sections 1, 2, 5).
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <vector>

#include "analytic_ao_internal.hpp"
#include "aosr/ao/von_karman.hpp"
#include "aosr/ao/analytic_ao.hpp"
#include "aosr/core/error.hpp"

namespace aosr {


namespace analytic_ao_internal {
namespace {

// q(x) is split at x = kTailSplit: quadrature below, asymptotic expansion above (error ~5e-5 there,
// falling as x^(-9/2)).
constexpr double kTailSplit = 30.0;

// (1 - J0(u)) / u^2, smooth with value 1/4 at u = 0 (series below 1e-3, where the difference cancels).
double OneMinusJ0OverU2(double u) {
  if (u < 1e-3) return 0.25 - u * u / 64.0;
  return (1.0 - std::cyl_bessel_j(0.0, u)) / (u * u);
}

// int_1^inf t^(-8/3) J0(x t) dt for large x, by three integrations by parts (J0 t = (t J1)'/x,
// J1 = -J0'/x): -J1(x)/x + (11/3) J0(x)/x^2 + (121/9) J1(x)/x^3 + O(x^(-9/2)).
double J0TailIntegralAsymptotic(double x) {
  const double j0 = std::cyl_bessel_j(0.0, x);
  const double j1 = std::cyl_bessel_j(1.0, x);
  return -j1 / x + (11.0 / 3.0) * j0 / (x * x) + (121.0 / 9.0) * j1 / (x * x * x);
}

// With u = x t,  q(x) = (5/3) x^(5/3) [ F(x) + R ],  F(x) = int_x^30 u^(-8/3) (1 - J0(u)) du,
// R = int_30^inf ... = 30^(-5/3) (3/5) q_asymptotic(30). The substitution u = w^3 turns F into
// int 3 (1 - J0(w^3)) / w^6 dw, whose integrand is smooth (3/4 at w = 0), tabulated cumulatively from
// w = 30^(1/3) down to 0 with Simpson's rule per cell.
struct TailTable {
  double step = 0.0;
  std::vector<double> cumulative;  // cumulative[i] = int_{i step}^{W} 3 g(w^3) dw
  double remainder = 0.0;          // R
};

double TailIntegrand(double w) { return 3.0 * OneMinusJ0OverU2(w * w * w); }

TailTable BuildTailTable() {
  TailTable t;
  const int cells = 4000;
  const double w_max = std::cbrt(kTailSplit);
  t.step = w_max / cells;
  t.cumulative.assign(cells + 1, 0.0);
  for (int i = cells - 1; i >= 0; --i) {
    const double a = i * t.step, b = (i + 1) * t.step;
    const double cell =
        t.step / 6.0 * (TailIntegrand(a) + 4.0 * TailIntegrand(0.5 * (a + b)) + TailIntegrand(b));
    t.cumulative[i] = t.cumulative[i + 1] + cell;
  }
  const double q_split = 1.0 - (5.0 / 3.0) * J0TailIntegralAsymptotic(kTailSplit);
  t.remainder = std::pow(kTailSplit, -5.0 / 3.0) * 0.6 * q_split;
  return t;
}

}  // namespace

double TailShape(double x) {
  if (!(x > 0.0)) return 0.0;
  if (x >= kTailSplit) return 1.0 - (5.0 / 3.0) * J0TailIntegralAsymptotic(x);
  static const TailTable table = BuildTailTable();
  const double w = std::cbrt(x);
  const std::size_t i = std::min(static_cast<std::size_t>(w / table.step), table.cumulative.size() - 2);
  const double w1 = (i + 1) * table.step;
  // The partial cell [w, w1] by Simpson's rule: O(step^5) per evaluation.
  const double partial =
      (w1 - w) / 6.0 * (TailIntegrand(w) + 4.0 * TailIntegrand(0.5 * (w + w1)) + TailIntegrand(w1));
  const double f = table.cumulative[i + 1] + partial;
  return (5.0 / 3.0) * std::pow(x, 5.0 / 3.0) * (f + table.remainder);
}

}  // namespace analytic_ao_internal

namespace {

// Fraction of the cell [c - h/2, c + h/2] below `edge` along one axis, for |c|: linear ramp over one cell.
double Ramp(double edge, double c, double h) { return std::clamp((edge - c) / h + 0.5, 0.0, 1.0); }

struct Wind {
  double weight;
  double vx, vy;  // [m/s]
};

}  // namespace

Image ResidualPsd::Total() const { return fitting + servo + noise + aliasing; }

AnalyticAoErrorBudget ResidualPsd::Budget() const {
  AnalyticAoErrorBudget b;
  const double cell = frequency_step_per_m * frequency_step_per_m;
  b.wavelength_m = wavelength_m;
  b.fitting_rad2 = fitting.sum() * cell + fitting_tail_rad2;
  b.servo_rad2 = servo.sum() * cell;
  b.noise_rad2 = noise.sum() * cell;
  b.aliasing_rad2 = aliasing.sum() * cell;
  return b;
}

double AnalyticAoErrorBudget::Nm(double rad2) const {
  return std::sqrt(std::max(rad2, 0.0)) * wavelength_m / kTwoPi * 1e9;
}

double AnalyticAoErrorBudget::MarechalStrehl() const { return std::exp(-TotalRad2()); }

std::string AnalyticAoErrorBudget::BriefReport() const {
  char buf[512];
  std::snprintf(buf, sizeof(buf),
                "AO error budget at %.3f um (nm RMS, rad^2):\n"
                "  fitting   %8.1f nm  %.4f\n"
                "  servo-lag %8.1f nm  %.4f\n"
                "  noise     %8.1f nm  %.4f\n"
                "  aliasing  %8.1f nm  %.4f\n"
                "  total     %8.1f nm  %.4f   exp(-sigma^2) = %.4f\n",
                wavelength_m * 1e6, Nm(fitting_rad2), fitting_rad2, Nm(servo_rad2), servo_rad2,
                Nm(noise_rad2), noise_rad2, Nm(aliasing_rad2), aliasing_rad2, TotalNm(), TotalRad2(),
                MarechalStrehl());
  return buf;
}

ResidualPsd ComputeResidualPsd(const AnalyticAoOptions& options, Index grid_n, double frequency_step_per_m) {
  const char* fn = "ComputeResidualPsd";
  analytic_ao_internal::CheckOptions(options, fn);
  CheckArgument(grid_n >= 8 && grid_n % 2 == 0, fn, "grid_n", grid_n, "even and >= 8");
  CheckArgument(std::isfinite(frequency_step_per_m) && frequency_step_per_m > 0.0, fn, "frequency_step_per_m",
                frequency_step_per_m, "> 0 and finite [cycles/m]");
  const double df = frequency_step_per_m;
  const double f_c = options.ControlRadius();
  const bool square = options.control_domain == ControlDomain::kSquare;
  const double f_t = (grid_n / 2 - 1) * df;
  const double needed = (square ? std::sqrt(2.0) : 1.0) * f_c + df;
  CheckArgument(
      f_t >= needed, fn, "grid_n * frequency_step_per_m / 2 - frequency_step_per_m",
      ToString(f_t) + " cycles/m",
      ">= " + ToString(needed) + " cycles/m: the grid's disk must hold the control region plus a cell");

  const double lambda = options.science_wavelength_m;
  const double r0 = options.R0At(lambda);
  const double amp =
      std::isinf(r0) ? 0.0 : VonKarmanPsdConstant() * std::pow(r0, -5.0 / 3.0);
  const double k0sq =
      std::isinf(options.outer_scale_m) ? 0.0 : 1.0 / (options.outer_scale_m * options.outer_scale_m);
  auto phi = [&](double f2) { return amp == 0.0 ? 0.0 : amp * std::pow(f2 + k0sq, -11.0 / 6.0); };

  const double period = 1.0 / options.loop_rate_hz;
  const analytic_ao_internal::LoopModel loop{options.loop_gain, options.loop_delay_frames};
  std::vector<Wind> winds;
  const int directions = options.average_wind_direction ? 24 : 1;
  for (const Layer& layer : options.layers) {
    if (layer.cn2_fraction == 0.0) continue;
    for (int q = 0; q < directions; ++q) {
      // Midpoints on [0, pi): |E(nu)|^2 is even in nu, so half a turn covers every direction.
      const double dir =
          options.average_wind_direction ? (q + 0.5) * kPi / directions : layer.wind_direction_rad;
      winds.push_back({layer.cn2_fraction / directions, layer.wind_speed_mps * std::cos(dir),
                       layer.wind_speed_mps * std::sin(dir)});
    }
  }

  // White noise of variance sigma_n^2 (at the reference wavelength) per frame, flat over the control region.
  const double control_area = square ? 4.0 * f_c * f_c : kPi * f_c * f_c;
  const double lambda_ratio = options.reference_wavelength_m / lambda;
  const double noise_psd =
      options.wfs_noise_rad2 > 0.0
          ? options.wfs_noise_rad2 * lambda_ratio * lambda_ratio / control_area * AnalyticAoNoiseGain(options)
          : 0.0;
  const bool aliasing = options.aliasing && options.loop_gain > 0.0 && amp > 0.0;
  const int orders = options.aliasing_orders;
  const double inv_d = 1.0 / options.actuator_pitch_m;

  ResidualPsd out;
  out.wavelength_m = lambda;
  out.frequency_step_per_m = df;
  out.tail_radius_per_m = f_t;
  out.fitting = Image::Zero(grid_n, grid_n);
  out.servo = Image::Zero(grid_n, grid_n);
  out.noise = Image::Zero(grid_n, grid_n);
  out.aliasing = Image::Zero(grid_n, grid_n);
  out.fitting_tail_rad2 = amp == 0.0 ? 0.0 : 1.2 * kPi * amp * std::pow(f_t * f_t + k0sq, -5.0 / 6.0);

  const Index c = grid_n / 2;
  for (Index i = 0; i < grid_n; ++i) {
    const double fy = (i - c) * df;
    for (Index j = 0; j < grid_n; ++j) {
      if (i == c && j == c) continue;  // piston
      const double fx = (j - c) * df;
      const double f2 = fx * fx + fy * fy;
      const double f = std::sqrt(f2);
      const double w_grid = Ramp(f_t, f, df);
      if (w_grid == 0.0) continue;
      const double w_ctrl =
          square ? Ramp(f_c, std::abs(fx), df) * Ramp(f_c, std::abs(fy), df) : Ramp(f_c, f, df);
      const double atm = phi(f2);
      out.fitting(i, j) = atm * (1.0 - w_ctrl) * w_grid;
      if (w_ctrl == 0.0) continue;
      double rejection = 0.0;
      for (const Wind& w : winds)
        rejection += w.weight * loop.At(kTwoPi * period * (fx * w.vx + fy * w.vy)).rejection;
      out.servo(i, j) = w_ctrl * atm * rejection;
      out.noise(i, j) = w_ctrl * noise_psd;
      if (!aliasing) continue;
      double alias = 0.0;
      for (int m = -orders; m <= orders; ++m) {
        const double ax = fx + m * inv_d;
        for (int n = -orders; n <= orders; ++n) {
          if (m == 0 && n == 0) continue;
          const double ay = fy + n * inv_d;
          // c_mn (header section 2); the sign (-1)^(m+n) drops out of c^2.
          const double term_y = n == 0 ? fx * fx : fx * fx * fy / ay;
          const double term_x = m == 0 ? fy * fy : fx * fy * fy / ax;
          const double coeff = (term_y + term_x) / f2;
          double transfer = 0.0;
          for (const Wind& w : winds)
            transfer += w.weight * loop.At(kTwoPi * period * (ax * w.vx + ay * w.vy)).noise;
          alias += coeff * coeff * phi(ax * ax + ay * ay) * transfer;
        }
      }
      out.aliasing(i, j) = w_ctrl * alias;
    }
  }
  return out;
}

AnalyticAoErrorBudget ComputeAnalyticAoErrorBudget(const AnalyticAoOptions& options) {
  analytic_ao_internal::CheckOptions(options, "ComputeAnalyticAoErrorBudget");
  // The smallest grid whose disk holds the control region plus a cell (f_t >= sqrt(2) f_c + df, with a
  // cell of margin): beyond it the analytic tail is exact, so a larger grid would add cost, not accuracy.
  const double df = 1.0 / (options.frequency_padding * options.diameter_m);
  const double reach =
      (options.control_domain == ControlDomain::kSquare ? std::sqrt(2.0) : 1.0) * options.ControlRadius();
  const Index half = static_cast<Index>(std::ceil(reach / df)) + 3;
  return ComputeResidualPsd(options, 2 * half, df).Budget();
}

}  // namespace aosr
