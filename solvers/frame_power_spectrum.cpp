#include "aosr/solvers/frame_power_spectrum.hpp"
#include "aosr/solvers/power_spectrum_model.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>

#include "aosr/core/error.hpp"
#include "aosr/core/levenberg_marquardt.hpp"
#include "aosr/core/fft.hpp"

namespace aosr {

namespace {

constexpr double kMaxSlope = 8.0, kMaxCorner = 0.5;

std::string Fmt(const char* f, double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, f, v);
  return buf;
}

// Everything of (1) that does not depend on θ.
struct Setup {
  Shape lr;
  int rr = 0;
  double r2 = 0;                  // r²
  std::vector<double> transfer;   // T_k(u), rr per LR bin
  std::vector<double> f2;     // |f_k|² per LR bin and k (cycles per HR pixel squared)
  bool hann = true;
  std::vector<std::vector<Index>> annuli;  // LR bins per annulus
  std::vector<double> power;               // P̄_b
  std::vector<double> radius;              // mean LR |u|, cycles per LR pixel
};

// The signal part of (1) for s = (f0² + f²)^(−β/2) (a = 1) on the LR grid, and (if wanted) its derivatives by
// ln f0 and β, each smoothed by the window kernel and averaged over the annuli.
struct Parts {
  std::vector<double> g, g_f0, g_beta;
};
Parts Signal(const Setup& s, double f0, double beta, bool derivatives) {
  const Index nb = s.lr.size();
  Image g(s.lr.rows, s.lr.cols), gf(s.lr.rows, s.lr.cols), gb(s.lr.rows, s.lr.cols);
  const double f02 = f0 * f0;
  for (Index u = 0; u < nb; ++u) {
    double sum = 0, sum_f = 0, sum_b = 0;
    for (int k = 0; k < s.rr; ++k) {
      const double t = s.transfer[u * s.rr + k];
      if (t == 0) continue;
      const double q = f02 + s.f2[u * s.rr + k];
      const double lq = std::log(q);
      const double v = t * std::exp(-0.5 * beta * lq);
      sum += v;
      if (derivatives) {
        sum_f += -beta * f02 / q * v;  // ∂/∂ ln f0
        sum_b += -0.5 * lq * v;        // ∂/∂β
      }
    }
    g.data()[u] = s.r2 * sum;
    gf.data()[u] = s.r2 * sum_f;
    gb.data()[u] = s.r2 * sum_b;
  }
  if (s.hann) {
    g = HannWindowSmooth(g);
    if (derivatives) gf = HannWindowSmooth(gf), gb = HannWindowSmooth(gb);
  }
  Parts p;
  auto mean = [&](const Image& img, std::vector<double>* out) {
    out->assign(s.annuli.size(), 0.0);
    for (std::size_t b = 0; b < s.annuli.size(); ++b) {
      for (Index u : s.annuli[b]) (*out)[b] += img.data()[u];
      (*out)[b] /= double(s.annuli[b].size());
    }
  };
  mean(g, &p.g);
  if (derivatives) mean(gf, &p.g_f0), mean(gb, &p.g_beta);
  return p;
}

// θ = (ln a, ln f0, β[, ln v]). Residuals ρ_b and (if jac) their Jacobian; *model the m̄_b.
Eigen::VectorXd Residuals(const Setup& s, const Eigen::VectorXd& theta, double fixed_v, Eigen::MatrixXd* jac,
                          std::vector<double>* model = nullptr) {
  const double a = std::exp(theta[0]), f0 = std::exp(theta[1]), beta = theta[2];
  const bool fit_v = theta.size() > 3;
  const double v = fit_v ? std::exp(theta[3]) : fixed_v;
  const Parts p = Signal(s, f0, beta, jac != nullptr);
  const Index nb = Index(s.annuli.size());
  Eigen::VectorXd res(nb);
  if (jac) jac->resize(nb, theta.size());
  if (model) model->assign(nb, 0.0);
  for (Index b = 0; b < nb; ++b) {
    const double sq = std::sqrt(double(s.annuli[b].size()));
    const double m = a * p.g[b] + v;
    res[b] = sq * (std::log(s.power[b]) - std::log(m));
    if (model) (*model)[b] = m;
    if (jac) {
      (*jac)(b, 0) = -sq * a * p.g[b] / m;
      (*jac)(b, 1) = -sq * a * p.g_f0[b] / m;
      (*jac)(b, 2) = -sq * a * p.g_beta[b] / m;
      if (fit_v) (*jac)(b, 3) = -sq * v / m;
    }
  }
  return res;
}

}  // namespace

bool FramePowerSpectrumOptions::IsValid(std::string* why) const {
  auto fail = [why](const std::string& m) {
    if (why) *why = m;
    return false;
  };
  if (!(min_radius >= 0 && min_radius <= 16))
    return fail("min_radius must be 0 (automatic) or in 1..16 LR bins, got " + std::to_string(min_radius));
  if (!(std::isfinite(noise_variance) && noise_variance >= 0))
    return fail("noise_variance must be finite and >= 0 (0: fitted), got " + ToString(noise_variance));
  if (!(max_iterations >= 1 && max_iterations <= 1000))
    return fail("max_iterations must be in 1..1000, got " + std::to_string(max_iterations));
  if (!(tolerance > 0 && tolerance < 0.1)) return fail("tolerance must be in (0, 0.1), got " + ToString(tolerance));
  return true;
}

double FramePowerSpectrumFit::ZeroFrequencyPower() const {
  return model.amplitude * std::pow(model.corner, -model.slope);
}

std::string FramePowerSpectrumFit::BriefReport() const {
  return "beta " + Fmt("%.3f", model.slope) + ", f0 " + Fmt("%.4g", model.corner) + " cyc/HR px, s(0) " +
         Fmt("%.4g", ZeroFrequencyPower()) + ", noise variance " + Fmt("%.4g", noise_variance) +
         (noise_fitted ? " (fitted)" : " (given)") + "; residual " + Fmt("%.3g", residual_rms) + " over " +
         std::to_string(annulus_bins.size()) + " annuli, " + std::to_string(iterations) + " iterations (" +
         (converged ? "converged" : "iteration cap") + ")";
}

FramePowerSpectrumFit FitFramePowerSpectrum(const MultiFrameModel& model, const ImageStack& frames,
                                            const FramePowerSpectrumOptions& options) {
  const char* fn = "FitFramePowerSpectrum";
  std::string why;
  if (!options.IsValid(&why)) throw InvalidArgument(std::string(fn) + ": options." + why);
  const Shape lr = model.lr_shape(), hr = model.hr_shape();
  const int n = model.frames(), r = model.r(), rr = r * r;
  CheckArgument(int(frames.size()) == n && n > 0, fn, "frames", std::to_string(frames.size()) + " frames",
                "one per model frame (" + std::to_string(n) + ")");
  for (int i = 0; i < n; ++i) {
    const std::string name = "frames[" + std::to_string(i) + "]";
    CheckArgument(ShapeOf(frames[i]) == lr, fn, name + " shape", ToString(ShapeOf(frames[i])), ToString(lr));
    CheckArgument(AllFinite(frames[i]), fn, name, "non-finite pixels", "finite values (fill masked pixels)");
    CheckArgument(frames[i].maxCoeff() > frames[i].minCoeff(), fn, name, "a constant frame", "a frame with variance");
  }
  Setup s;
  s.lr = lr;
  s.rr = rr;
  s.r2 = double(rr);
  s.hann = options.hann_window;
  const int min_radius = options.min_radius > 0 ? options.min_radius : (s.hann ? 2 : 1);

  // The periodogram P̄(u): mean removed (window-weighted), windowed, |DFT|² / Σw², averaged over frames.
  Image w = Image::Ones(lr.rows, lr.cols);
  if (s.hann)
    for (Index y = 0; y < lr.rows; ++y)
      for (Index x = 0; x < lr.cols; ++x) {
        const double a = std::sin(kPi * (double(y) + 0.5) / double(lr.rows));
        const double b = std::sin(kPi * (double(x) + 0.5) / double(lr.cols));
        w(y, x) = a * a * b * b;
      }
  const double w_sum = w.sum(), w2_sum = w.square().sum();
  Image periodogram = Image::Zero(lr.rows, lr.cols);
  for (const Image& f : frames) {
    const double c = (w * f).sum() / w_sum;
    periodogram += FftForward((w * (f - c)).cast<Complex>()).abs2() / w2_sum;
  }
  periodogram /= double(n);

  // T_k(u) and |f_k|² per LR bin.
  s.transfer.assign(std::size_t(lr.size()) * rr, 0.0);
  s.f2.assign(std::size_t(lr.size()) * rr, 0.0);
  for (Index uy = 0; uy < lr.rows; ++uy)
    for (Index ux = 0; ux < lr.cols; ++ux) {
      const Eigen::MatrixXcd a = model.AliasedSystem(uy, ux);
      const Index u = uy * lr.cols + ux;
      for (int ky = 0; ky < r; ++ky)
        for (int kx = 0; kx < r; ++kx) {
          const int k = ky * r + kx;
          s.transfer[u * rr + k] = a.col(k).squaredNorm() / double(n);
          const double vy = double(SignedFrequency(uy + ky * lr.rows, hr.rows)) / double(hr.rows);
          const double vx = double(SignedFrequency(ux + kx * lr.cols, hr.cols)) / double(hr.cols);
          s.f2[u * rr + k] = vy * vy + vx * vx;
        }
    }

  // Annuli of LR radius.
  std::map<Index, std::vector<Index>> by_radius;
  std::map<Index, double> radius_sum;
  for (Index uy = 0; uy < lr.rows; ++uy)
    for (Index ux = 0; ux < lr.cols; ++ux) {
      const double fy = double(SignedFrequency(uy, lr.rows)) / double(lr.rows);
      const double fx = double(SignedFrequency(ux, lr.cols)) / double(lr.cols);
      const double f = std::sqrt(fy * fy + fx * fx);
      const Index rad = Index(std::llround(f * double(std::max(lr.rows, lr.cols))));
      if (rad < min_radius) continue;
      by_radius[rad].push_back(uy * lr.cols + ux);
      radius_sum[rad] += f;
    }
  double top = 0;
  std::vector<double> powers;
  for (auto& [rad, bins] : by_radius) {
    double p = 0;
    for (Index u : bins) p += periodogram.data()[u];
    powers.push_back(p / double(bins.size()));
    top = std::max(top, powers.back());
  }
  std::size_t idx = 0;
  for (auto& [rad, bins] : by_radius) {
    const double p = powers[idx++];
    if (!(p > 1e-14 * top)) continue;
    s.power.push_back(p);
    s.radius.push_back(radius_sum[rad] / double(bins.size()));
    s.annuli.push_back(bins);
  }
  CheckArgument(s.annuli.size() >= 4, fn, "frames", std::to_string(s.annuli.size()) + " annuli with power",
                "at least 4 (a larger LR grid)");

  // Start: a grid over (f0, β); at each point (a, v) >= 0 by least squares on the relative misfit.
  const bool fit_v = options.noise_variance == 0;
  const double f0_min = 1.0 / double(std::max(hr.rows, hr.cols));
  const double v_min = 1e-12 * top;
  const Index nb = Index(s.annuli.size());
  double best = std::numeric_limits<double>::infinity();
  Eigen::VectorXd theta(fit_v ? 4 : 3);
  for (int i = 0; i < 10; ++i) {
    const double f0 = f0_min * std::pow(kMaxCorner / f0_min, double(i) / 9.0);
    for (int j = 0; j <= 8; ++j) {
      const double beta = double(j);
      const Parts p = Signal(s, f0, beta, false);
      // Minimise Σ n_b (1 − (a g_b + v)/P̄_b)² over a (and v).
      double a = 0, v = fit_v ? 0 : options.noise_variance;
      Eigen::Matrix2d m = Eigen::Matrix2d::Zero();
      Eigen::Vector2d rhs = Eigen::Vector2d::Zero();
      for (Index b = 0; b < nb; ++b) {
        const double wt = double(s.annuli[b].size()), x0 = p.g[b] / s.power[b], x1 = 1.0 / s.power[b];
        m(0, 0) += wt * x0 * x0, m(0, 1) += wt * x0 * x1, m(1, 1) += wt * x1 * x1;
        rhs[0] += wt * x0, rhs[1] += wt * x1;
      }
      m(1, 0) = m(0, 1);
      if (fit_v) {
        const Eigen::Vector2d sol = m.ldlt().solve(rhs);
        a = sol[0], v = sol[1];
        if (!(v > v_min)) v = v_min, a = (rhs[0] - m(0, 1) * v) / m(0, 0);
      } else {
        a = (rhs[0] - m(0, 1) * v) / m(0, 0);
      }
      if (!(a > 0) || !std::isfinite(a)) continue;
      double cost = 0;
      for (Index b = 0; b < nb; ++b) {
        const double e = std::log(s.power[b]) - std::log(a * p.g[b] + v);
        cost += double(s.annuli[b].size()) * e * e;
      }
      if (cost < best) {
        best = cost;
        theta[0] = std::log(a), theta[1] = std::log(f0), theta[2] = beta;
        if (fit_v) theta[3] = std::log(v);
      }
    }
  }
  CheckArgument(std::isfinite(best), fn, "frames", "no positive object power in the band",
                "frames whose periodogram rises above the noise floor somewhere");

  // Levenberg-Marquardt within the bounds.
  FramePowerSpectrumFit out;
  const double fixed_v = options.noise_variance;
  LevenbergMarquardtOptions lm;
  lm.max_iterations = options.max_iterations;
  lm.tolerance = options.tolerance;
  const LevenbergMarquardtResult fit = LevenbergMarquardt(
      [&](const Eigen::VectorXd& t, Eigen::MatrixXd* jac) { return Residuals(s, t, fixed_v, jac); }, theta,
      [&](Eigen::VectorXd t) {
        t[1] = std::clamp(t[1], std::log(f0_min), std::log(kMaxCorner));
        t[2] = std::clamp(t[2], 0.0, kMaxSlope);
        if (fit_v) t[3] = std::max(t[3], std::log(v_min));
        return t;
      },
      lm);
  theta = fit.theta;
  out.iterations = fit.iterations;
  out.converged = fit.converged;
  out.model.amplitude = std::exp(theta[0]);
  out.model.corner = std::exp(theta[1]);
  out.model.slope = theta[2];
  out.model.floor = 0;
  out.noise_variance = fit_v ? std::exp(theta[3]) : fixed_v;
  out.noise_fitted = fit_v;
  const Eigen::VectorXd res = Residuals(s, theta, fixed_v, nullptr, &out.annulus_model);
  double n_total = 0;
  for (Index b = 0; b < nb; ++b) {
    out.annulus_frequency.push_back(s.radius[b]);
    out.annulus_power.push_back(s.power[b]);
    out.annulus_bins.push_back(int(s.annuli[b].size()));
    n_total += double(s.annuli[b].size());
  }
  out.residual_rms = std::sqrt(res.squaredNorm() / n_total);
  if (fit_v) {
    double largest_share = 0;
    for (Index b = 0; b < nb; ++b) largest_share = std::max(largest_share, out.noise_variance / s.power[b]);
    out.noise_identified = largest_share >= 0.01;
  }
  out.message = std::string(out.converged ? "converged" : "iteration cap reached") + "; " + std::to_string(nb) +
                " annuli from LR radius " + std::to_string(min_radius) + ", window " +
                (s.hann ? "hann" : "rectangular");
  if (!out.noise_identified)
    out.message += "; noise floor not identified (the object's power exceeds it 100x at every frequency)";
  if (out.model.slope <= 0 || out.model.slope >= kMaxSlope) out.message += "; slope at its bound";
  if (out.model.corner <= f0_min * (1 + 1e-9) || out.model.corner >= kMaxCorner * (1 - 1e-9))
    out.message += "; corner at its bound";
  return out;
}

}  // namespace aosr
