#include "aosr/solvers/map.hpp"

#include <ceres/first_order_function.h>
#include <ceres/gradient_problem.h>
#include <ceres/gradient_problem_solver.h>
#include <ceres/iteration_callback.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <tuple>
#include <utility>
#include <vector>
#include <limits>
#include <memory>

#include "aosr/core/error.hpp"
#include "aosr/core/operators.hpp"
#include "aosr/core/parallel.hpp"
#include "aosr/solvers/ceres_termination.hpp"

namespace aosr {

const char* ToString(MapLikelihood l) {
  switch (l) {
    case MapLikelihood::kGaussian:
      return "gaussian";
    case MapLikelihood::kPoisson:
      return "poisson";
  }
  return "unknown";
}

const char* ToString(MapPrior p) {
  switch (p) {
    case MapPrior::kTikhonov:
      return "tikhonov";
    case MapPrior::kCharbonnierTv:
      return "charbonnier-tv";
    case MapPrior::kHuberTv:
      return "huber-tv";
  }
  return "unknown";
}

const char* ToString(MapPositivity p) {
  switch (p) {
    case MapPositivity::kNone:
      return "none";
    case MapPositivity::kSoftplus:
      return "softplus";
  }
  return "unknown";
}

MapLikelihood ParseMapLikelihood(const std::string& name) {
  if (name == "gaussian") return MapLikelihood::kGaussian;
  if (name == "poisson") return MapLikelihood::kPoisson;
  throw InvalidArgument("ParseMapLikelihood", "likelihood", name, "gaussian or poisson");
}

MapPrior ParseMapPrior(const std::string& name) {
  if (name == "tikhonov") return MapPrior::kTikhonov;
  if (name == "charbonnier-tv") return MapPrior::kCharbonnierTv;
  if (name == "huber-tv") return MapPrior::kHuberTv;
  throw InvalidArgument("ParseMapPrior", "prior", name, "tikhonov, charbonnier-tv or huber-tv");
}

MapPositivity ParseMapPositivity(const std::string& name) {
  if (name == "none") return MapPositivity::kNone;
  if (name == "softplus") return MapPositivity::kSoftplus;
  throw InvalidArgument("ParseMapPositivity", "positivity", name, "none or softplus");
}

bool MapOptions::IsValid(std::string* why) const {
  auto fail = [why](const std::string& m) {
    if (why) *why = m;
    return false;
  };
  auto finite_nonneg = [](double v) { return std::isfinite(v) && v >= 0; };
  if (likelihood != MapLikelihood::kGaussian && likelihood != MapLikelihood::kPoisson)
    return fail("likelihood must be kGaussian or kPoisson");
  if (prior != MapPrior::kTikhonov && prior != MapPrior::kCharbonnierTv && prior != MapPrior::kHuberTv)
    return fail("prior must be kTikhonov, kCharbonnierTv or kHuberTv");
  if (preconditioner != MapPreconditioner::kNone && preconditioner != MapPreconditioner::kFourier)
    return fail("preconditioner must be kNone or kFourier");
  if (positivity != MapPositivity::kNone && positivity != MapPositivity::kSoftplus)
    return fail("positivity must be kNone or kSoftplus");
  if (prior == MapPrior::kTikhonov && tikhonov_operator != TikhonovPrior::kIdentity &&
      tikhonov_operator != TikhonovPrior::kGradient && tikhonov_operator != TikhonovPrior::kLaplacian)
    return fail("tikhonov_operator must be identity, gradient or laplacian");
  if (!finite_nonneg(read_noise))
    return fail("read_noise must be finite and >= 0, got " + ToString(read_noise));
  if (!finite_nonneg(background))
    return fail("background must be finite and >= 0, got " + ToString(background));
  if (likelihood == MapLikelihood::kPoisson && !(background + read_noise * read_noise > 0))
    return fail(
        "background + read_noise^2 must be > 0 for the Poisson likelihood (the log needs a floor), got " +
        ToString(background + read_noise * read_noise));
  if (!finite_nonneg(lambda)) return fail("lambda must be finite and >= 0, got " + ToString(lambda));
  if (prior == MapPrior::kCharbonnierTv && !(std::isfinite(epsilon) && epsilon > 0))
    return fail("epsilon must be finite and > 0 for the Charbonnier prior, got " + ToString(epsilon));
  if (prior == MapPrior::kHuberTv && !(std::isfinite(delta) && delta > 0))
    return fail("delta must be finite and > 0 for the Huber prior, got " + ToString(delta));
  if (!finite_nonneg(softplus_scale))
    return fail("softplus_scale must be finite and >= 0 (0: automatic), got " + ToString(softplus_scale));
  if (max_iterations < 1) return fail("max_iterations must be >= 1, got " + ToString(max_iterations));
  if (!(function_tolerance >= 0 && function_tolerance < 1))
    return fail("function_tolerance must be in [0, 1), got " + ToString(function_tolerance));
  if (!(gradient_tolerance >= 0 && gradient_tolerance < 1))
    return fail("gradient_tolerance must be in [0, 1), got " + ToString(gradient_tolerance));
  if (!(parameter_tolerance >= 0 && parameter_tolerance < 1))
    return fail("parameter_tolerance must be in [0, 1), got " + ToString(parameter_tolerance));
  if (lbfgs_memory < 1 || lbfgs_memory > 1000)
    return fail("lbfgs_memory must be in 1..1000, got " + ToString(lbfgs_memory));
  return true;
}

namespace {

// softplus(t) = log(1 + e^t) and its derivative σ(t) = 1/(1 + e^{-t}), without overflow.
inline double Softplus(double t) { return t > 0 ? t + std::log1p(std::exp(-t)) : std::log1p(std::exp(t)); }
inline double Logistic(double t) {
  if (t >= 0) return 1.0 / (1.0 + std::exp(-t));
  const double e = std::exp(t);
  return e / (1.0 + e);
}
// softplus⁻¹(u) = log(e^u − 1) = u + log(1 − e^{-u}) for u > 0.
inline double InverseSoftplus(double u) { return u + std::log(-std::expm1(-u)); }

// The objective's pixel passes run over a fixed partition of [0, n) into blocks of kPassBlock pixels (a
// function of n only), in parallel; block sums are added in block order afterwards, so the value and the
// gradient do not depend on the thread count. They are most of an evaluation besides the model's FFTs
// (softplus and the prior's square roots per pixel), and Ceres' own L-BFGS vector work is serial.
constexpr Index kPassBlock = 16384;

// fn(begin, end) -> that block's sum; returns the sum over blocks in order.
template <typename Fn>
double BlockedSum(Index n, const Fn& fn) {
  const Index blocks = (n + kPassBlock - 1) / kPassBlock;
  std::vector<double> partial(std::size_t(std::max<Index>(blocks, 0)), 0.0);
  ParallelFor(blocks, [&](Index b) { partial[std::size_t(b)] = fn(b * kPassBlock, std::min(n, (b + 1) * kPassBlock)); });
  double sum = 0;
  for (double v : partial) sum += v;
  return sum;
}

}  // namespace

MapObjective::MapObjective(const ReconstructionProblem& problem, const MapOptions& options)
    : options_(options) {
  std::string why;
  if (!options.IsValid(&why)) throw InvalidArgument("MapObjective: options." + why);
  problem.Validate("MapObjective");
  const MultiFrameModel& model = *problem.model;
  hr_ = model.hr_shape();
  frames_ = problem.frame_count();
  lr_ = model.lr_shape();
  lr_size_ = lr_.size();
  CheckArgument(hr_.size() <= std::numeric_limits<int>::max(), "MapObjective", "problem.model HR size",
                hr_.size(), "at most INT_MAX parameters (Ceres counts them in int)");
  a_ = model.Operator();
  y_ = model.Flatten(problem.CleanFrames());
  w_.resize(y_.size());
  for (int i = 0; i < frames_; ++i) w_.segment(i * lr_size_, lr_size_) = AsVector(problem.Weight(i));
  if (options.likelihood == MapLikelihood::kPoisson) {
    const double s2 = options.read_noise * options.read_noise;
    c_.resize(y_.size());
    for (Index p = 0; p < y_.size(); ++p) {
      w_[p] = w_[p] > 0 ? 1.0 : 0.0;
      c_[p] = w_[p] > 0 ? std::max(y_[p] + s2, 0.0) : 0.0;
    }
  }
  if (options.prior == MapPrior::kTikhonov) {
    if (options.tikhonov_operator != TikhonovPrior::kIdentity)
      gamma_ = TikhonovPriorOperator(hr_, options.tikhonov_operator);
  } else {
    gamma_ = Gradient(hr_, Boundary::kPeriodic);
  }
  if (options.positivity == MapPositivity::kSoftplus) {
    scale_ = options.softplus_scale;
    if (scale_ == 0) {
      double sum = 0, count = 0;
      for (Index p = 0; p < y_.size(); ++p)
        if (w_[p] > 0) sum += y_[p] - options.background, count += 1;
      const double mean = count > 0 ? sum / (count * model.r() * model.r()) : 0.0;
      scale_ = (std::isfinite(mean) && mean > 0) ? 0.01 * mean : 1.0;
    }
  }
}

MapObjective::Value MapObjective::Evaluate(const Eigen::Ref<const Vector>& z, Vector* gradient) const {
  CheckArgument(z.size() == num_parameters(), "MapObjective::Evaluate", "z size", z.size(),
                std::to_string(num_parameters()));
  Value v;
  const Index n = num_parameters();
  const bool softplus = options_.positivity == MapPositivity::kSoftplus;
  // x(z) and dx/dz.
  Vector x(n), dxdz;
  if (softplus) {
    dxdz.resize(n);
    BlockedSum(n, [&](Index p0, Index p1) {
      for (Index p = p0; p < p1; ++p) {
        const double t = z[p] / scale_;
        x[p] = scale_ * Softplus(t);
        dxdz[p] = Logistic(t);
      }
      return 0.0;
    });
  } else {
    x = z;
  }

  // Data term and its derivative with respect to the modelled data A x (stacked over frames).
  const Vector ax = a_->Apply(x);
  Vector dl(ax.size());
  const double b = options_.background;
  if (options_.likelihood == MapLikelihood::kGaussian) {
    const double data = BlockedSum(ax.size(), [&](Index p0, Index p1) {
      double sum = 0;
      for (Index p = p0; p < p1; ++p) {
        const double e = w_[p] > 0 ? y_[p] - ax[p] - b : 0.0;  // masked pixels are never read
        sum += w_[p] * e * e;
        dl[p] = -w_[p] * e;
      }
      return sum;
    });
    v.data = 0.5 * data;
  } else {
    const double floor = b + options_.read_noise * options_.read_noise;
    // A block that meets μ <= 0 (out of the domain) or NaN stops there and returns +inf or NaN; the sum
    // carries it (NaN wins over inf, as a NaN anywhere means a non-finite evaluation).
    const double data = BlockedSum(ax.size(), [&](Index p0, Index p1) {
      double sum = 0;
      for (Index p = p0; p < p1; ++p) {
        if (w_[p] == 0) {
          dl[p] = 0;
          continue;
        }
        const double mu = ax[p] + floor, c = c_[p];
        if (!(mu > 0)) return std::isnan(mu) ? std::numeric_limits<double>::quiet_NaN()
                                             : std::numeric_limits<double>::infinity();
        // μ − c − c log(μ/c) = (μ − c) − c log1p((μ − c)/c): accurate near the minimum μ = c.
        sum += c > 0 ? (mu - c) - c * std::log1p((mu - c) / c) : mu;
        dl[p] = 1.0 - c / mu;
      }
      return sum;
    });
    if (!std::isfinite(data)) {
      if (std::isnan(data)) v.finite = false;
      else v.in_domain = false;
      v.data = v.total = data;
      return v;
    }
    v.data = data;
  }

  // Prior term λ R and its x-gradient λ ∇R.
  const double lambda = options_.lambda;
  Vector gx;
  if (gradient) gx = a_->ApplyAdjoint(dl);
  double r = 0;
  if (options_.prior == MapPrior::kTikhonov) {
    if (!gamma_) {  // Γ = I
      r = 0.5 * x.squaredNorm();
      if (gradient) gx.noalias() += lambda * x;
    } else {
      const Vector gam = gamma_->Apply(x);
      r = 0.5 * gam.squaredNorm();
      if (gradient) gx.noalias() += lambda * gamma_->ApplyAdjoint(gam);
    }
  } else {
    // g = [D_y x; D_x x]; q = ∂R/∂g = g · φ'(t)/t pixel-wise, with φ'(t)/t = 1/sqrt(t² + ε²) (Charbonnier)
    // or 1/max(t, δ) (Huber).
    Vector g = gamma_->Apply(x);
    const bool charbonnier = options_.prior == MapPrior::kCharbonnierTv;
    const double eps = options_.epsilon, delta = options_.delta;
    r = BlockedSum(n, [&](Index p0, Index p1) {
      double sum = 0;
      for (Index p = p0; p < p1; ++p) {
        const double gy = g[p], gxp = g[n + p];
        const double t2 = gy * gy + gxp * gxp;
        double k;
        if (charbonnier) {
          const double rho = std::sqrt(t2 + eps * eps);
          sum += t2 / (rho + eps);  // = rho − ε without cancellation
          k = 1.0 / rho;
        } else {
          const double t = std::sqrt(t2);
          if (t <= delta) {
            sum += t2 / (2 * delta);
            k = 1.0 / delta;
          } else {
            sum += t - 0.5 * delta;
            k = 1.0 / t;
          }
        }
        g[p] = k * gy;
        g[n + p] = k * gxp;
      }
      return sum;
    });
    if (gradient) gx.noalias() += lambda * gamma_->ApplyAdjoint(g);
  }
  v.prior = lambda * r;
  v.total = v.data + v.prior;
  v.finite = std::isfinite(v.total);
  if (gradient) {
    if (softplus) gx.array() *= dxdz.array();  // chain rule: ∂F/∂z = σ(z/s) ∂F/∂x
    *gradient = std::move(gx);
    v.finite = v.finite && gradient->allFinite();
  }
  return v;
}

Image MapObjective::ToImage(const Eigen::Ref<const Vector>& z) const {
  CheckArgument(z.size() == num_parameters(), "MapObjective::ToImage", "z size", z.size(),
                std::to_string(num_parameters()));
  Image x(hr_.rows, hr_.cols);
  Eigen::Map<Vector> xv(x.data(), x.size());
  if (options_.positivity == MapPositivity::kSoftplus) {
    for (Index p = 0; p < xv.size(); ++p) xv[p] = scale_ * Softplus(z[p] / scale_);
  } else {
    xv = z;
  }
  return x;
}

Vector MapObjective::ToParameters(const Image& x, Index* raised) const {
  CheckArgument(ShapeOf(x) == hr_, "MapObjective::ToParameters", "x shape", ToString(ShapeOf(x)),
                "the model's HR shape " + ToString(hr_));
  CheckArgument(AllFinite(x), "MapObjective::ToParameters", "x", "(non-finite values)", "finite values");
  Vector z = AsVector(x);
  Index count = 0;
  if (options_.positivity == MapPositivity::kSoftplus) {
    const double floor = scale_ * std::log(2.0);
    for (Index p = 0; p < z.size(); ++p) {
      if (!(z[p] > floor)) {
        z[p] = 0.0;
        ++count;
      } else {
        z[p] = scale_ * InverseSoftplus(z[p] / scale_);
      }
    }
  }
  if (raised) *raised = count;
  return z;
}

std::vector<double> MapObjective::FrameResidualRms(const Image& x, const LrRegion& region) const {
  CheckArgument(ShapeOf(x) == hr_, "MapObjective::FrameResidualRms", "x shape", ToString(ShapeOf(x)),
                ToString(hr_));
  const LrRegion g = region.all() ? LrRegion{0, 0, lr_.rows, lr_.cols} : region;
  CheckArgument(g.rows > 0 && g.cols > 0 && g.y0 >= 0 && g.x0 >= 0 && g.y0 + g.rows <= lr_.rows &&
                    g.x0 + g.cols <= lr_.cols,
                "MapObjective::FrameResidualRms", "region", std::to_string(g.rows) + " x " + std::to_string(g.cols),
                "a rectangle inside " + ToString(lr_));
  const Vector ax = a_->Apply(AsVector(x));
  std::vector<double> rms;
  for (int i = 0; i < frames_; ++i) {
    double sum = 0, count = 0;
    for (Index y = g.y0; y < g.y0 + g.rows; ++y)
      for (Index p = i * lr_size_ + y * lr_.cols + g.x0, e = p + g.cols; p < e; ++p)
        if (w_[p] > 0) {
          const double d = y_[p] - ax[p] - options_.background;
          sum += d * d;
          count += 1;
        }
    rms.push_back(count > 0 ? std::sqrt(sum / count) : 0.0);
  }
  return rms;
}

namespace {

// What the Ceres callbacks share: the lowest-cost finite point evaluated, and whether a non-finite cost or
// gradient was seen (which ends the solve).
struct Tracker {
  bool non_finite = false;
  double best_cost = std::numeric_limits<double>::infinity();
  Vector best_z;
  int cost_evaluations = 0;
  int gradient_evaluations = 0;
};

// Adapts MapObjective to Ceres. Out-of-domain points (kPoisson without positivity) return false, which
// Ceres' line search treats as "too far" and contracts; non-finite values also return false and are
// recorded so that the callback below aborts the solve.
class CeresObjective : public ceres::FirstOrderFunction {
 public:
  // `c` (optional): the preconditioner; Ceres then works on u with z = C u and ∂F/∂u = C ∂F/∂z (C = Cᵀ).
  CeresObjective(const MapObjective& objective, Tracker* tracker, OperatorPtr c = nullptr)
      : objective_(objective), tracker_(tracker), c_(std::move(c)) {}

  bool Evaluate(const double* parameters, double* cost, double* gradient) const override {
    const Eigen::Map<const Vector> u(parameters, objective_.num_parameters());
    const Vector z = c_ ? c_->Apply(u) : Vector(u);
    Vector g;
    const MapObjective::Value v = objective_.Evaluate(z, gradient ? &g : nullptr);
    ++(gradient ? tracker_->gradient_evaluations : tracker_->cost_evaluations);
    if (!v.finite) tracker_->non_finite = true;
    if (!v.ok()) return false;
    *cost = v.total;
    if (gradient) Eigen::Map<Vector>(gradient, g.size()) = c_ ? c_->Apply(g) : g;
    if (v.total < tracker_->best_cost) {
      tracker_->best_cost = v.total;
      tracker_->best_z = z;
    }
    return true;
  }
  int NumParameters() const override { return static_cast<int>(objective_.num_parameters()); }

 private:
  const MapObjective& objective_;
  Tracker* tracker_;
  OperatorPtr c_;
};

// C = M^(-1/2) and C⁻¹ = M^(1/2) as Fourier multipliers (MapOptions::preconditioner), M from the problem, the
// options and the warm start x0.
std::pair<OperatorPtr, OperatorPtr> FourierPreconditioner(const ReconstructionProblem& problem,
                                                          const MapOptions& options, const Image& x0) {
  const MultiFrameModel& model = *problem.model;
  const Shape hr = model.hr_shape();
  const int r = model.r();
  // Mean data curvature per modelled pixel.
  double sum = 0, count = 0;
  const double s2 = options.read_noise * options.read_noise;
  for (int i = 0; i < problem.frame_count(); ++i) {
    const Image w = problem.Weight(i);
    for (Index p = 0; p < w.size(); ++p) {
      if (!(w.data()[p] > 0)) continue;
      sum += options.likelihood == MapLikelihood::kGaussian
                 ? w.data()[p]
                 : 1.0 / std::max(problem.frames[i].data()[p] + s2, 1.0);
      count += 1;
    }
  }
  const double wbar = count > 0 ? sum / count : 1.0;
  // κ: the prior's curvature scale at the warm start.
  double kappa = 1.0;
  TikhonovPrior gamma = options.tikhonov_operator;
  if (options.prior != MapPrior::kTikhonov) {
    gamma = TikhonovPrior::kGradient;
    const Vector g = Gradient(hr, Boundary::kPeriodic)->Apply(AsVector(x0));
    const Index n = hr.size();
    std::vector<double> k(n);
    for (Index p = 0; p < n; ++p) {
      const double t = std::hypot(g[p], g[n + p]);
      k[p] = options.prior == MapPrior::kCharbonnierTv ? 1.0 / std::sqrt(t * t + options.epsilon * options.epsilon)
                                                       : 1.0 / std::max(t, options.delta);
    }
    std::nth_element(k.begin(), k.begin() + n / 2, k.end());
    kappa = k[n / 2];
  }
  ComplexImage m(hr.rows, hr.cols / 2 + 1);
  double m_max = 0;
  for (Index fy = 0; fy < hr.rows; ++fy)
    for (Index fx = 0; fx < m.cols(); ++fx) {
      double data = 0;
      for (int i = 0; i < model.frames(); ++i) data += std::norm(model.PixelTransfer(fy, fx) * model.Otf(i, fy, fx));
      const double value = wbar * data / double(r * r) +
                           options.lambda * kappa * TikhonovPriorSymbol(gamma, hr, fy, fx);
      m(fy, fx) = value;
      m_max = std::max(m_max, value);
    }
  const double floor = 1e-12 * (m_max > 0 ? m_max : 1.0);
  ComplexImage c(m.rows(), m.cols()), c_inv(m.rows(), m.cols());
  for (Index k = 0; k < m.size(); ++k) {
    const double v = std::max(m.data()[k].real(), floor);
    c.data()[k] = 1.0 / std::sqrt(v);
    c_inv.data()[k] = std::sqrt(v);
  }
  return {PeriodicConvolution(hr, c), PeriodicConvolution(hr, c_inv)};
}

class AbortOnNonFinite : public ceres::IterationCallback {
 public:
  explicit AbortOnNonFinite(const Tracker* tracker) : tracker_(tracker) {}
  ceres::CallbackReturnType operator()(const ceres::IterationSummary&) override {
    return tracker_->non_finite ? ceres::SOLVER_ABORT : ceres::SOLVER_CONTINUE;
  }

 private:
  const Tracker* tracker_;
};

// Hands each completed L-BFGS iteration (Ceres' iteration 0 is the start, not reported) to the caller's
// progress callback; a cancellation ends the solve as a Ceres USER_SUCCESS, which keeps the current iterate.
class ReportProgress : public ceres::IterationCallback {
 public:
  ReportProgress(ProgressReporter* reporter, int max_iterations)
      : reporter_(reporter), max_iterations_(max_iterations) {}
  ceres::CallbackReturnType operator()(const ceres::IterationSummary& summary) override {
    if (summary.iteration < 1) return ceres::SOLVER_CONTINUE;
    const bool last = summary.iteration >= max_iterations_;
    if (!reporter_->Report(summary.iteration, summary.cost, last) && !last) {
      cancelled_at_ = summary.iteration;
      return ceres::SOLVER_TERMINATE_SUCCESSFULLY;
    }
    return ceres::SOLVER_CONTINUE;
  }
  int cancelled_at() const { return cancelled_at_; }  // 0: not cancelled

 private:
  ProgressReporter* reporter_;
  int max_iterations_;
  int cancelled_at_ = 0;
};

}  // namespace

MapResult MapReconstruct(const ReconstructionProblem& problem, const MapOptions& options,
                         const Image& warm_start) {
  const auto start = std::chrono::steady_clock::now();
  std::string why;
  if (!options.IsValid(&why)) throw InvalidArgument("MapReconstruct: options." + why);
  problem.Validate("MapReconstruct");
  const MapObjective objective(problem, options);
  const Shape hr = objective.hr_shape();

  // The starting image.
  Image x0;
  if (warm_start.size() == 0) {
    double sum = 0, count = 0;
    for (int i = 0; i < problem.frame_count(); ++i) {
      const Image w = problem.Weight(i);
      for (Index p = 0; p < w.size(); ++p)
        if (w.data()[p] > 0) sum += problem.frames[i].data()[p] - options.background, count += 1;
    }
    const int r = problem.model->r();
    const double mean = count > 0 ? sum / (count * r * r) : 0.0;
    x0 = Image::Constant(hr.rows, hr.cols, std::isfinite(mean) && mean > 0 ? mean : 0.0);
  } else {
    CheckArgument(ShapeOf(warm_start) == hr, "MapReconstruct", "warm_start shape",
                  ToString(ShapeOf(warm_start)), "the model's HR shape " + ToString(hr) + " (or empty)");
    CheckArgument(AllFinite(warm_start), "MapReconstruct", "warm_start", "(non-finite values)",
                  "finite values");
    x0 = warm_start;
  }

  MapResult result;
  MapSummary& s = result.summary;
  s.method = "map";
  s.softplus_scale = objective.softplus_scale();
  Vector z = objective.ToParameters(x0, &s.warm_start_pixels_raised);
  Vector g0;
  const MapObjective::Value v0 = objective.Evaluate(z, &g0);
  if (!v0.in_domain)
    throw InvalidArgument("MapReconstruct", "warm_start",
                          "(A x + background + read_noise^2 <= 0 on an unmasked pixel)",
                          "a warm start inside the Poisson likelihood's domain, or positivity = kSoftplus");
  s.initial_cost = v0.total;

  auto finish = [&](const Vector& z_final) {
    result.image = objective.ToImage(z_final);
    const MapObjective::Value v = objective.Evaluate(z_final);
    s.final_cost = v.total;
    s.data_cost = v.data;
    s.prior_cost = v.prior;
    s.frame_residual_rms = objective.FrameResidualRms(result.image, problem.residual_region);
    s.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  };

  if (!v0.finite) {  // nothing Ceres could do: report, return the (finite) start
    s.termination = Termination::kFailed;
    s.message = "non-finite objective or gradient at the warm start (cost " + ToString(v0.total) +
                "); Ceres not run; returned the warm start";
    finish(z);
    return result;
  }

  ceres::GradientProblemSolver::Options ceres_options;
  ceres_options.line_search_direction_type = ceres::LBFGS;
  ceres_options.line_search_type = ceres::WOLFE;
  ceres_options.max_lbfgs_rank = options.lbfgs_memory;
  ceres_options.use_approximate_eigenvalue_bfgs_scaling = options.lbfgs_eigenvalue_scaling;
  ceres_options.max_num_iterations = options.max_iterations;
  ceres_options.function_tolerance = options.function_tolerance;
  ceres_options.gradient_tolerance = options.gradient_tolerance * g0.lpNorm<Eigen::Infinity>();
  ceres_options.parameter_tolerance = options.parameter_tolerance;
  ceres_options.logging_type = ceres::SILENT;
  Tracker tracker;
  AbortOnNonFinite abort_callback(&tracker);
  ceres_options.callbacks.push_back(&abort_callback);
  ProgressReporter reporter(options.progress, "map", options.max_iterations, "cost");
  ReportProgress progress_callback(&reporter, options.max_iterations);
  if (reporter.active()) ceres_options.callbacks.push_back(&progress_callback);
  std::string ceres_why;
  if (!ceres_options.IsValid(
          &ceres_why))  // our IsValid should make this unreachable; never hand Ceres bad input
    throw InvalidArgument("MapReconstruct: options rejected by Ceres: " + ceres_why);

  OperatorPtr c, c_inv;
  if (options.preconditioner == MapPreconditioner::kFourier) {
    std::tie(c, c_inv) = FourierPreconditioner(problem, options, x0);
    // Ceres' gradient rule is absolute: relative to the initial gradient in u, as without preconditioning.
    ceres_options.gradient_tolerance = options.gradient_tolerance * c->Apply(g0).lpNorm<Eigen::Infinity>();
  }
  ceres::GradientProblem ceres_problem(new CeresObjective(objective, &tracker, c));  // owns the function
  ceres::GradientProblemSolver::Summary ceres_summary;
  tracker.best_cost = v0.total;
  tracker.best_z = z;
  Vector u_solved = c_inv ? c_inv->Apply(z) : z;
  ceres::Solve(ceres_options, ceres_problem, u_solved.data(), &ceres_summary);
  const Vector z_solved = c ? c->Apply(u_solved) : u_solved;

  s.iterations = std::max<int>(0, static_cast<int>(ceres_summary.iterations.size()) - 1);
  s.cost_evaluations = tracker.cost_evaluations;
  s.gradient_evaluations = tracker.gradient_evaluations;
  s.message = ceres_summary.BriefReport() + "; " + ceres_summary.message;
  s.termination = TerminationOf(ceres_summary.termination_type);
  if (progress_callback.cancelled_at() > 0 && !tracker.non_finite) {
    s.termination = Termination::kUserCancelled;
    s.message = "cancelled by the caller after iteration " +
                std::to_string(progress_callback.cancelled_at()) + "; " + s.message;
  }
  if (tracker.non_finite) {
    s.termination = Termination::kFailed;
    s.message =
        "non-finite cost or gradient at a trial point; returned the lowest-cost finite iterate. " + s.message;
  }
  // Ceres leaves the parameters untouched on failure: fall back to the best finite point evaluated (never
  // worse than the last accepted iterate).
  const bool usable = ceres_summary.IsSolutionUsable() && !tracker.non_finite && z_solved.allFinite();
  finish(usable ? z_solved : tracker.best_z);
  if (!result.image.allFinite()) {  // unreachable in exact arithmetic (softplus of finite z is finite)
    s.termination = Termination::kFailed;
    s.message = "non-finite image; returned the warm start. " + s.message;
    finish(z);
  }
  reporter.Finish(s.iterations, s.final_cost);
  reporter.RethrowIfThrown();
  return result;
}

}  // namespace aosr
