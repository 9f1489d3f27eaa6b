#include "aosr/design/power_spectrum_fit.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>

#include "aosr/ao/random.hpp"
#include "aosr/core/error.hpp"
#include "aosr/core/levenberg_marquardt.hpp"
#include "aosr/core/fft.hpp"
#include "aosr/io/image_io.hpp"

namespace aosr {

namespace {

constexpr double kMinSlope = -2.0, kMaxSlope = 12.0;

std::string Fmt(const char* f, double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, f, v);
  return buf;
}

// |f|² at bin (ky, kx) of a rows x cols grid, cycles per HR pixel squared.
double FrequencySquared(Index ky, Index kx, Shape s) {
  const double vy = double(SignedFrequency(ky, s.rows)) / double(s.rows);
  const double vx = double(SignedFrequency(kx, s.cols)) / double(s.cols);
  return vy * vy + vx * vx;
}

// Patch origins along an axis of length len: 0, step, 2 step, ..., the last flush with the end.
std::vector<Index> PatchOrigins(Index len, Index m, Index step) {
  std::vector<Index> o;
  if (len == m) return {0};
  for (Index p = 0; p < len - m; p += step) o.push_back(p);
  if (o.empty() || o.back() != len - m) o.push_back(len - m);
  return o;
}

// The 1-D window.
std::vector<double> Window1d(SpectralWindow window, Index m) {
  std::vector<double> w(m, 1.0);
  if (window == SpectralWindow::kHann)
    for (Index j = 0; j < m; ++j) {
      const double s = std::sin(kPi * (double(j) + 0.5) / double(m));
      w[j] = s * s;
    }
  return w;
}

// Circular smoothing by the window's |Ŵ|² kernel: identity for rectangular (solvers/power_spectrum_model.hpp for Hann).
Image Smooth(const Image& s, SpectralWindow window) {
  return window == SpectralWindow::kRectangular ? s : HannWindowSmooth(s);
}

struct Annulus {
  std::vector<Index> bins;  // flat indices into the M x M grid
  double frequency = 0;     // mean |f|
  double f2 = 0;            // mean |f|²
  double power = 0;         // mean periodogram
};

// Parameters θ = (ln a, ln f0, β, ln w); the last only when fitting the floor.
PowerSpectrumModel ModelOf(const Eigen::VectorXd& theta) {
  PowerSpectrumModel m;
  m.amplitude = std::exp(theta[0]);
  m.corner = std::exp(theta[1]);
  m.slope = theta[2];
  m.floor = theta.size() > 3 ? std::exp(theta[3]) : 0.0;
  return m;
}

// Residuals ρ_b = sqrt(n_b)(ln P̄_b − ln m̄_b) and (if jac) their Jacobian w.r.t. θ.
Eigen::VectorXd Residuals(const Eigen::VectorXd& theta, const std::vector<Annulus>& annuli, Shape grid,
                          SpectralWindow window, Eigen::MatrixXd* jac, std::vector<double>* model_means = nullptr) {
  const PowerSpectrumModel m = ModelOf(theta);
  const Index p = theta.size();
  // The model and its partial derivatives on the grid, then smoothed by the window kernel (linear).
  std::vector<Image> g(1 + (jac ? p : 0), Image(grid.rows, grid.cols));
  const double f02 = m.corner * m.corner;
  for (Index ky = 0; ky < grid.rows; ++ky)
    for (Index kx = 0; kx < grid.cols; ++kx) {
      const double q = f02 + FrequencySquared(ky, kx, grid);
      const double pw = m.amplitude * std::pow(q, -0.5 * m.slope);
      g[0](ky, kx) = pw + m.floor;
      if (jac) {
        g[1](ky, kx) = pw;                          // ∂/∂ln a
        g[2](ky, kx) = -m.slope * f02 * pw / q;     // ∂/∂ln f0
        g[3](ky, kx) = -0.5 * std::log(q) * pw;     // ∂/∂β
        if (p > 3) g[4](ky, kx) = m.floor;          // ∂/∂ln w
      }
    }
  for (Image& t : g) t = Smooth(t, window);
  Eigen::VectorXd res(annuli.size());
  if (jac) jac->resize(Index(annuli.size()), p);
  if (model_means) model_means->assign(annuli.size(), 0.0);
  for (std::size_t b = 0; b < annuli.size(); ++b) {
    const Annulus& a = annuli[b];
    const double n = double(a.bins.size()), sq = std::sqrt(n);
    std::vector<double> mean(g.size(), 0.0);
    for (std::size_t k = 0; k < g.size(); ++k) {
      for (Index idx : a.bins) mean[k] += g[k].data()[idx];
      mean[k] /= n;
    }
    res[Index(b)] = sq * (std::log(a.power) - std::log(mean[0]));
    if (model_means) (*model_means)[b] = mean[0];
    if (jac)
      for (Index j = 0; j < p; ++j) (*jac)(Index(b), j) = -sq * mean[std::size_t(j) + 1] / mean[0];
  }
  return res;
}

// Start: a log grid of f0, at each (ln a, β) by weighted linear least squares of ln P̄_b ≈ ln a − (β/2) ln(f0² + f_b²).
Eigen::VectorXd Start(const std::vector<Annulus>& annuli, double f_lo, bool floor) {
  double best = std::numeric_limits<double>::infinity();
  Eigen::VectorXd theta(floor ? 4 : 3);
  const int steps = 64;
  for (int k = 0; k < steps; ++k) {
    const double f0 = f_lo * std::pow(0.5 / f_lo, double(k) / (steps - 1));
    Eigen::Matrix2d a = Eigen::Matrix2d::Zero();
    Eigen::Vector2d rhs = Eigen::Vector2d::Zero();
    for (const Annulus& an : annuli) {
      const double n = double(an.bins.size());
      const double u = -0.5 * std::log(f0 * f0 + an.f2), y = std::log(an.power);
      a(0, 0) += n, a(0, 1) += n * u, a(1, 1) += n * u * u;
      rhs[0] += n * y, rhs[1] += n * u * y;
    }
    a(1, 0) = a(0, 1);
    if (std::abs(a.determinant()) <= 1e-300) continue;
    const Eigen::Vector2d x = a.ldlt().solve(rhs);
    const double beta = std::clamp(x[1], kMinSlope, kMaxSlope);
    double sse = 0;
    for (const Annulus& an : annuli) {
      const double e = std::log(an.power) - (x[0] - 0.5 * beta * std::log(f0 * f0 + an.f2));
      sse += double(an.bins.size()) * e * e;
    }
    if (sse < best) {
      best = sse;
      theta[0] = x[0], theta[1] = std::log(f0), theta[2] = beta;
    }
  }
  if (floor) theta[3] = std::log(0.05 * annuli.back().power);
  return theta;
}

void CheckOptions(const char* fn, const PowerSpectrumFitOptions& o) {
  std::string why;
  if (!o.IsValid(&why)) throw InvalidArgument(std::string(fn) + ": options." + why);
}

}  // namespace

Image GaussianRandomField(Shape shape, const PowerSpectrumModel& model, std::uint64_t seed) {
  const char* fn = "GaussianRandomField";
  CheckArgument(shape.rows >= 2 && shape.cols >= 2, fn, "shape", ToString(shape), "both sides >= 2");
  const Image s = PowerSpectrumGrid(model, shape);
  Image white(shape.rows, shape.cols);
  NormalGenerator gen(seed);
  gen.Fill(white.data(), white.size());
  // √s is real and symmetric, so the product's inverse transform is real (to rounding).
  const ComplexImage x = FftForward(white.cast<Complex>()) * s.sqrt().cast<Complex>();
  return FftInverse(x).real();
}

const char* ToString(SpectralWindow window) {
  return window == SpectralWindow::kHann ? "hann" : "rectangular";
}

const char* ToString(TrainingScaling scaling) {
  switch (scaling) {
    case TrainingScaling::kNone:
      return "none";
    case TrainingScaling::kPeak:
      return "peak";
    case TrainingScaling::kMean:
      return "mean";
  }
  return "unknown";
}

bool PowerSpectrumFitOptions::IsValid(std::string* why) const {
  auto fail = [why](const std::string& m) {
    if (why) *why = m;
    return false;
  };
  if (!(grid >= 8 && grid <= 4096)) return fail("grid must be in [8, 4096], got " + ToString(grid));
  if (!(patch_step >= 0 && patch_step <= 4096)) return fail("patch_step must be in [0, 4096], got " + ToString(patch_step));
  if (!(std::isfinite(scale_value) && scale_value > 0))
    return fail("scale_value must be finite and > 0, got " + ToString(scale_value));
  if (!(min_frequency >= 0 && min_frequency < 0.5))
    return fail("min_frequency must be 0 (automatic) or in (0, 0.5), got " + ToString(min_frequency));
  if (!(max_frequency > min_frequency && max_frequency <= 0.75))
    return fail("max_frequency must be in (min_frequency, 0.75], got " + ToString(max_frequency));
  if (max_iterations < 1) return fail("max_iterations must be >= 1, got " + ToString(max_iterations));
  if (!(tolerance > 0 && tolerance < 0.1)) return fail("tolerance must be in (0, 0.1), got " + ToString(tolerance));
  return true;
}

std::string PowerSpectrumFit::BriefReport() const {
  std::string s = "a " + Fmt("%.4g", model.amplitude) + ", f0 " + Fmt("%.4g", model.corner) + ", beta " +
                  Fmt("%.3f", model.slope) + " (floor " + Fmt("%.3g", model.floor) + "), residual " +
                  Fmt("%.3g", residual_rms) + " over " + std::to_string(annulus_bins.size()) + " annuli, " +
                  std::to_string(patches) + " patches of " + std::to_string(periodogram.rows()) + "x" +
                  std::to_string(periodogram.cols()) + " from " + std::to_string(images) + " images, " +
                  std::to_string(iterations) + " iterations (" + (converged ? "converged" : "iteration cap") + ")";
  return s;
}

PowerSpectrumFit FitPowerSpectrum(const std::vector<Image>& images, const PowerSpectrumFitOptions& options) {
  const char* fn = "FitPowerSpectrum";
  CheckOptions(fn, options);
  CheckArgument(!images.empty(), fn, "images", "none", "at least one training image");
  const Index m = options.grid;
  const Shape grid{m, m};
  // Validate every image before computing anything.
  for (std::size_t i = 0; i < images.size(); ++i) {
    const Image& img = images[i];
    const std::string name = "images[" + std::to_string(i) + "]";
    CheckArgument(img.rows() >= m && img.cols() >= m, fn, name + " shape", ToString(ShapeOf(img)),
                  "at least the grid, " + ToString(grid));
    CheckArgument(AllFinite(img), fn, name, "non-finite pixels", "finite values");
    CheckArgument(img.maxCoeff() > img.minCoeff(), fn, name, "a constant image",
                  "an image with variance (a constant has no spectrum to fit)");
    if (options.scaling == TrainingScaling::kPeak)
      CheckArgument(img.maxCoeff() > 0, fn, name + " maximum", img.maxCoeff(), "> 0 for scaling = peak");
    if (options.scaling == TrainingScaling::kMean)
      CheckArgument(img.mean() > 0, fn, name + " mean", img.mean(), "> 0 for scaling = mean");
  }
  PowerSpectrumFit out;
  out.images = int(images.size());
  const Index step = options.patch_step > 0 ? options.patch_step
                                            : (options.window == SpectralWindow::kHann ? m / 2 : m);
  const std::vector<double> w1 = Window1d(options.window, m);
  Image w(m, m);
  for (Index y = 0; y < m; ++y)
    for (Index x = 0; x < m; ++x) w(y, x) = w1[y] * w1[x];
  const double w_sum = w.sum(), w2_sum = w.square().sum();
  Image acc = Image::Zero(m, m);
  for (const Image& raw : images) {
    double scale = 1.0;
    if (options.scaling == TrainingScaling::kPeak) scale = options.scale_value / raw.maxCoeff();
    if (options.scaling == TrainingScaling::kMean) scale = options.scale_value / raw.mean();
    out.scales.push_back(scale);
    const Image img = (raw - raw.mean()) * scale;
    for (Index oy : PatchOrigins(img.rows(), m, step))
      for (Index ox : PatchOrigins(img.cols(), m, step)) {
        const Image patch = img.block(oy, ox, m, m);
        const double c = (w * patch).sum() / w_sum;
        const ComplexImage spec = FftForward((w * (patch - c)).cast<Complex>());
        acc += spec.abs2() / w2_sum;
        ++out.patches;
      }
  }
  out.periodogram = acc / double(out.patches);
  out.mean_power = out.periodogram.mean();
  CheckArgument(out.mean_power > 0, fn, "images", "no power in any patch", "patches with variance");

  // Annuli.
  const double f_lo = options.min_frequency > 0 ? options.min_frequency
                                                : (options.window == SpectralWindow::kHann ? 2.0 : 1.0) / double(m);
  const double f_hi = options.max_frequency;
  std::map<Index, Annulus> by_radius;
  for (Index ky = 0; ky < m; ++ky)
    for (Index kx = 0; kx < m; ++kx) {
      const double f2 = FrequencySquared(ky, kx, grid), f = std::sqrt(f2);
      if (f < f_lo * (1 - 1e-12) || f > f_hi * (1 + 1e-12)) continue;
      Annulus& a = by_radius[Index(std::llround(f * double(m)))];
      a.bins.push_back(ky * m + kx);
      a.frequency += f, a.f2 += f2, a.power += out.periodogram(ky, kx);
    }
  // Annuli whose power is at rounding level (below 1e-12 of the largest) carry no information for a log fit.
  double top = 0;
  for (auto& [radius, a] : by_radius) {
    const double n = double(a.bins.size());
    a.frequency /= n, a.f2 /= n, a.power /= n;
    top = std::max(top, a.power);
  }
  std::vector<Annulus> annuli;
  int dropped = 0;
  for (auto& [radius, a] : by_radius) {
    if (a.power > 1e-12 * top) annuli.push_back(std::move(a));
    else ++dropped;
  }
  const std::size_t params = options.fit_floor ? 4 : 3;
  CheckArgument(annuli.size() >= 5, fn, "images", std::to_string(annuli.size()) + " annuli with power in [" +
                Fmt("%.4g", f_lo) + ", " + Fmt("%.4g", f_hi) + "] cycles/px", "at least 5 (widen the frequency range or the grid)");

  // Levenberg-Marquardt from the grid-search start, within the bounds (core/levenberg_marquardt.hpp).
  LevenbergMarquardtOptions lm;
  lm.max_iterations = options.max_iterations;
  lm.tolerance = options.tolerance;
  const LevenbergMarquardtResult fit = LevenbergMarquardt(
      [&](const Eigen::VectorXd& t, Eigen::MatrixXd* jac) { return Residuals(t, annuli, grid, options.window, jac); },
      Start(annuli, f_lo, options.fit_floor),
      [&](Eigen::VectorXd t) {
        t[1] = std::clamp(t[1], std::log(1e-8), std::log(100.0));
        t[2] = std::clamp(t[2], kMinSlope, kMaxSlope);
        if (params > 3) t[3] = std::max(t[3], std::log(1e-300));
        return t;
      },
      lm);
  const Eigen::VectorXd& theta = fit.theta;
  out.iterations = fit.iterations;
  out.converged = fit.converged;
  out.model = ModelOf(theta);
  out.spectrum = PowerSpectrumGrid(out.model, grid);
  std::vector<double> means;
  Eigen::VectorXd res = Residuals(theta, annuli, grid, options.window, nullptr, &means);
  double n_total = 0;
  for (const Annulus& a : annuli) {
    out.annulus_frequency.push_back(a.frequency);
    out.annulus_power.push_back(a.power);
    out.annulus_bins.push_back(int(a.bins.size()));
    n_total += double(a.bins.size());
  }
  out.annulus_model = means;
  out.residual_rms = std::sqrt(res.squaredNorm() / n_total);
  out.message = std::string(out.converged ? "converged" : "iteration cap reached") + "; " +
                std::to_string(annuli.size()) + " annuli in [" + Fmt("%.4g", f_lo) + ", " + Fmt("%.4g", f_hi) +
                "] cycles/px, window " + ToString(options.window) + ", step " + std::to_string(step) + " px";
  if (dropped > 0) out.message += "; " + std::to_string(dropped) + " annuli without power left out";
  return out;
}

TikhonovOptions WienerPriorOptions(const PowerSpectrumModel& model, double noise_sigma, Shape hr) {
  const char* fn = "WienerPriorOptions";
  std::string why;
  if (!model.IsValid(&why)) throw InvalidArgument(std::string(fn) + ": model." + why);
  CheckArgument(std::isfinite(noise_sigma) && noise_sigma > 0, fn, "noise_sigma", noise_sigma, "finite and > 0");
  CheckArgument(hr.rows >= 1 && hr.cols >= 1, fn, "hr", ToString(hr), "both sides >= 1");
  TikhonovOptions o;
  o.prior = TikhonovPrior::kPowerSpectrum;
  o.lambda_rule = TikhonovLambdaRule::kFixed;
  const double s2 = noise_sigma * noise_sigma;
  if (model.floor == 0 && model.corner <= 0.5 && model.slope >= 0 && model.slope <= 8) {
    o.spectrum_slope = model.slope;
    o.spectrum_corner = model.corner;
    o.lambda = s2 * std::pow(model.corner, model.slope) / model.amplitude;
  } else {
    const Image s = PowerSpectrumGrid(model, hr);
    o.object_power_spectrum = s / s(0, 0);
    o.lambda = s2 / s(0, 0);
  }
  CheckArgument(std::isfinite(o.lambda) && o.lambda > 0, fn, "model", "a spectrum whose Wiener lambda is not finite",
                "a model with finite, positive s(0)");
  return o;
}

std::vector<Image> LoadTrainingImages(const std::vector<std::string>& paths) {
  const char* fn = "LoadTrainingImages";
  CheckArgument(!paths.empty(), fn, "paths", "none", "at least one image file");
  std::vector<Image> out;
  for (std::size_t i = 0; i < paths.size(); ++i) {
    Image img = ReadImage(paths[i]);
    CheckArgument(img.size() > 0 && AllFinite(img), fn, "paths[" + std::to_string(i) + "]", paths[i],
                  "an image file with finite pixels");
    out.push_back(std::move(img));
  }
  return out;
}

}  // namespace aosr
