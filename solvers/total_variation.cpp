#include "aosr/solvers/total_variation.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <memory>
#include <sstream>

#include "aosr/core/error.hpp"
#include "aosr/core/fft.hpp"
#include "aosr/core/operators.hpp"
#include "aosr/solvers/conjugate_gradient.hpp"

namespace aosr {

const char* ToString(TotalVariationXUpdate x_update) {
  switch (x_update) {
    case TotalVariationXUpdate::kAuto:
      return "auto";
    case TotalVariationXUpdate::kFourier:
      return "fourier";
    case TotalVariationXUpdate::kConjugateGradient:
      return "conjugate-gradient";
  }
  return "unknown";
}

bool TotalVariationOptions::IsValid(std::string* why) const {
  auto fail = [why](const std::string& m) {
    if (why) *why = m;
    return false;
  };
  auto finite_at_least = [](double v, double lo) { return std::isfinite(v) && v >= lo; };
  if (!finite_at_least(mu, 0)) return fail("mu must be finite and >= 0, got " + ToString(mu));
  if (!finite_at_least(rho, 0))
    return fail("rho must be finite and >= 0 (0: automatic), got " + ToString(rho));
  if (!(std::isfinite(rho_balance) && rho_balance > 1))
    return fail("rho_balance must be finite and > 1, got " + ToString(rho_balance));
  if (!(std::isfinite(rho_factor) && rho_factor > 1))
    return fail("rho_factor must be finite and > 1, got " + ToString(rho_factor));
  if (max_rho_updates < 0) return fail("max_rho_updates must be >= 0, got " + ToString(max_rho_updates));
  if (!(relaxation >= 1 && relaxation <= 1.9))
    return fail("relaxation must be in [1, 1.9], got " + ToString(relaxation));
  if (!finite_at_least(absolute_tolerance, 0))
    return fail("absolute_tolerance must be finite and >= 0, got " + ToString(absolute_tolerance));
  if (!(relative_tolerance > 0 && relative_tolerance < 1))
    return fail("relative_tolerance must be in (0, 1), got " + ToString(relative_tolerance));
  if (!(change_tolerance >= 0 && change_tolerance < 1))
    return fail("change_tolerance must be in [0, 1) (0: off), got " + ToString(change_tolerance));
  if (max_iterations < 1) return fail("max_iterations must be >= 1, got " + ToString(max_iterations));
  if (!(cg_tolerance > 0 && cg_tolerance < 1))
    return fail("cg_tolerance must be in (0, 1), got " + ToString(cg_tolerance));
  if (cg_max_iterations < 1)
    return fail("cg_max_iterations must be >= 1, got " + ToString(cg_max_iterations));
  if (x_update != TotalVariationXUpdate::kAuto && x_update != TotalVariationXUpdate::kFourier &&
      x_update != TotalVariationXUpdate::kConjugateGradient)
    return fail("x_update must be auto, fourier or conjugate-gradient");
  return true;
}

// ---------------------------------------------------------------------------------------------------------
// FourierNormalSystem

namespace {

// Symbol of ∇ᵀ∇ for periodic forward differences at full-spectrum HR bin (fy, fx):
// |e^{2πi f_y/M_y} − 1|² + |e^{2πi f_x/M_x} − 1|² = 4 sin²(π f_y/M_y) + 4 sin²(π f_x/M_x).
double GradientSymbol(Shape hr, Index fy, Index fx) {
  const double sy = std::sin(M_PI * double(fy) / double(hr.rows));
  const double sx = std::sin(M_PI * double(fx) / double(hr.cols));
  return 4.0 * (sy * sy + sx * sx);
}

// Solves L Lᴴ x = b in place (v: b in, x out) for the lower factor L stored row-major with 1/L_ii on its
// diagonal. RR > 0 is the size at compile time; 0 means `n` at run time.
template <int RR>
void CholeskySubstitution(const Complex* l, int n, Complex* v) {
  const int size = RR > 0 ? RR : n;
  for (int i = 0; i < size; ++i) {  // L w = b
    Complex s = v[i];
    for (int j = 0; j < i; ++j) s -= l[i * size + j] * v[j];
    v[i] = s * l[i * size + i].real();
  }
  for (int i = size - 1; i >= 0; --i) {  // Lᴴ x = w
    Complex s = v[i];
    for (int j = i + 1; j < size; ++j) s -= std::conj(l[j * size + i]) * v[j];
    v[i] = s * l[i * size + i].real();
  }
}

}  // namespace

FourierNormalSystem::FourierNormalSystem(const MultiFrameModel& model, double data_weight)
    : hr_(model.hr_shape()), lr_(model.lr_shape()), r_(model.r()) {
  CheckArgument(std::isfinite(data_weight) && data_weight > 0, "FourierNormalSystem", "data_weight",
                data_weight, "finite and > 0");
  const int rr = r_ * r_;
  const Index bins = lr_.size();
  gram_.resize(bins * rr * rr);
  symbol_.resize(bins * rr);
  const double scale = double(rr) * data_weight;  // F(AᵀA x) = r² A(u)ᴴA(u) X(u) per bin (Parseval)
  for (Index uy = 0; uy < lr_.rows; ++uy)
    for (Index ux = 0; ux < lr_.cols; ++ux) {
      const Index bin = uy * lr_.cols + ux;
      const Eigen::MatrixXcd a = model.AliasedSystem(uy, ux);
      const Eigen::MatrixXcd g = scale * (a.adjoint() * a);
      for (int i = 0; i < rr; ++i)
        for (int j = 0; j < rr; ++j) gram_[(bin * rr + i) * rr + j] = g(i, j);
      for (int ky = 0; ky < r_; ++ky)
        for (int kx = 0; kx < r_; ++kx)
          symbol_[bin * rr + ky * r_ + kx] = GradientSymbol(hr_, uy + ky * lr_.rows, ux + kx * lr_.cols);
    }
}

void FourierNormalSystem::Factorize(double gradient_weight, double identity_weight) {
  CheckArgument(std::isfinite(gradient_weight) && gradient_weight >= 0, "FourierNormalSystem::Factorize",
                "gradient_weight", gradient_weight, "finite and >= 0");
  CheckArgument(std::isfinite(identity_weight) && identity_weight >= 0, "FourierNormalSystem::Factorize",
                "identity_weight", identity_weight, "finite and >= 0");
  const int rr = r_ * r_;
  const Index bins = lr_.size();
  factor_.assign(bins * rr * rr, Complex(0));
  pseudo_inverse_.assign(bins, Eigen::MatrixXcd());
  singular_bins_ = 0;
  Eigen::MatrixXcd k(rr, rr);
  for (Index bin = 0; bin < bins; ++bin) {
    for (int i = 0; i < rr; ++i)
      for (int j = 0; j < rr; ++j) k(i, j) = gram_[(bin * rr + i) * rr + j];
    for (int i = 0; i < rr; ++i) k(i, i) += gradient_weight * symbol_[bin * rr + i] + identity_weight;
    const double scale = k.diagonal().real().cwiseAbs().maxCoeff();
    const Eigen::LLT<Eigen::MatrixXcd> llt(k);
    bool ok = llt.info() == Eigen::Success && scale > 0;
    if (ok) {
      const Eigen::MatrixXcd l = llt.matrixL();
      // A pivot below 1e-12 of the largest diagonal entry means the matrix is singular to rounding:
      // the Cholesky "solution" would be noise of size 1e12. Use the pseudo-inverse instead.
      for (int i = 0; i < rr && ok; ++i) ok = std::norm(l(i, i)) > 1e-12 * scale;
      if (ok)  // the diagonal of L is real and positive: store 1/L_ii there (no complex division in Solve)
        for (int i = 0; i < rr; ++i)
          for (int j = 0; j <= i; ++j)
            factor_[(bin * rr + i) * rr + j] = i == j ? 1.0 / l(i, i).real() : l(i, j);
    }
    if (!ok) {
      ++singular_bins_;
      const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXcd> eig(k);
      const Eigen::VectorXd& ev = eig.eigenvalues();
      const double floor = 1e-12 * std::max(ev.cwiseAbs().maxCoeff(), 0.0);
      Eigen::VectorXd inv = Eigen::VectorXd::Zero(rr);
      for (int i = 0; i < rr; ++i)
        if (ev[i] > floor && ev[i] > 0) inv[i] = 1.0 / ev[i];
      pseudo_inverse_[bin] = eig.eigenvectors() * inv.asDiagonal() * eig.eigenvectors().adjoint();
    }
  }
  factorized_ = true;
}

Image FourierNormalSystem::Solve(const Image& rhs) const {
  if (!factorized_) throw InvalidArgument("FourierNormalSystem::Solve: call Factorize first");
  CheckArgument(ShapeOf(rhs) == hr_, "FourierNormalSystem::Solve", "rhs shape", ToString(ShapeOf(rhs)),
                "the HR shape " + ToString(hr_));
  CheckArgument(AllFinite(rhs), "FourierNormalSystem::Solve", "rhs", "(non-finite values)", "finite values");
  const int rr = r_ * r_;
  // The rhs is real, so its spectrum is Hermitian and the half spectrum (columns 0 .. M_x/2) holds it all:
  // a bin's aliased value at a column beyond M_x/2 is the conjugate of the mirrored stored one. Every HR
  // frequency belongs to exactly one bin, so each stored value is written back exactly once.
  ComplexImage half = FftR2C(rhs);
  const Index half_cols = half.cols();
  auto get = [&](Index fy, Index fx) {
    return fx < half_cols ? half(fy, fx) : std::conj(half((hr_.rows - fy) % hr_.rows, hr_.cols - fx));
  };
  Complex work[64];  // r² <= 64 covers r <= 8; larger r uses a heap buffer
  std::vector<Complex> heap;
  Complex* v = work;
  if (rr > 64) {
    heap.resize(rr);
    v = heap.data();
  }
  // Solutions go to a separate half spectrum: a bin may read the mirror of a value another bin writes.
  ComplexImage out(half.rows(), half_cols);
  for (Index uy = 0; uy < lr_.rows; ++uy)
    for (Index ux = 0; ux < lr_.cols; ++ux) {
      const Index bin = uy * lr_.cols + ux;
      for (int ky = 0; ky < r_; ++ky)
        for (int kx = 0; kx < r_; ++kx) v[ky * r_ + kx] = get(uy + ky * lr_.rows, ux + kx * lr_.cols);
      if (pseudo_inverse_[bin].size() == 0) {
        const Complex* l = &factor_[bin * rr * rr];
        switch (rr) {  // fixed sizes let the compiler unroll the common r = 2, 3
          case 4:
            CholeskySubstitution<4>(l, rr, v);
            break;
          case 9:
            CholeskySubstitution<9>(l, rr, v);
            break;
          default:
            CholeskySubstitution<0>(l, rr, v);
            break;
        }
      } else {
        const Eigen::VectorXcd x = pseudo_inverse_[bin] * Eigen::Map<const Eigen::VectorXcd>(v, rr);
        for (int i = 0; i < rr; ++i) v[i] = x[i];
      }
      for (int ky = 0; ky < r_; ++ky)
        for (int kx = 0; kx < r_; ++kx) {
          const Index fx = ux + kx * lr_.cols;
          if (fx < half_cols) out(uy + ky * lr_.rows, fx) = v[ky * r_ + kx];
        }
    }
  return FftC2R(out, hr_.cols);
}

// ---------------------------------------------------------------------------------------------------------
// Objective

double IsotropicTotalVariation(const Image& x) {
  CheckArgument(x.size() > 0, "IsotropicTotalVariation", "x shape", ToString(ShapeOf(x)), "non-empty");
  const Index rows = x.rows(), cols = x.cols();
  double tv = 0;
  for (Index y = 0; y < rows; ++y) {
    const Index yn = y + 1 < rows ? y + 1 : 0;
    for (Index c = 0; c < cols; ++c) {
      const Index cn = c + 1 < cols ? c + 1 : 0;
      const double dy = x(yn, c) - x(y, c), dx = x(y, cn) - x(y, c);
      tv += std::sqrt(dy * dy + dx * dx);
    }
  }
  return tv;
}

double TotalVariationObjective(const ReconstructionProblem& problem, const Image& x, double mu) {
  problem.Validate("TotalVariationObjective");
  CheckArgument(std::isfinite(mu) && mu >= 0, "TotalVariationObjective", "mu", mu, "finite and >= 0");
  CheckArgument(ShapeOf(x) == problem.model->hr_shape(), "TotalVariationObjective", "x shape",
                ToString(ShapeOf(x)), "the model's HR shape " + ToString(problem.model->hr_shape()));
  CheckArgument(AllFinite(x), "TotalVariationObjective", "x", "(non-finite values)", "finite values");
  return WeightedDataMisfit(problem, x) + mu * IsotropicTotalVariation(x);
}

// ---------------------------------------------------------------------------------------------------------
// ADMM

namespace {

constexpr const char* kFunction = "TotalVariationAdmm";

// Isotropic shrinkage in place: g_p <- max(0, 1 - t/||g_p||) g_p, with g = [g_y; g_x] (n each).
void Shrink(double t, Index n, Vector* g) {
  double* gy = g->data();
  double* gx = g->data() + n;
  for (Index p = 0; p < n; ++p) {
    const double norm = std::sqrt(gy[p] * gy[p] + gx[p] * gx[p]);
    const double f = norm > t ? 1.0 - t / norm : 0.0;
    gy[p] *= f;
    gx[p] *= f;
  }
}

// The weights of all frames stacked like MultiFrameModel::Flatten (ones when the problem has none).
Vector StackedWeights(const ReconstructionProblem& problem) {
  const Index lr = problem.model->lr_shape().size();
  Vector w(problem.frame_count() * lr);
  for (int i = 0; i < problem.frame_count(); ++i) w.segment(i * lr, lr) = AsVector(problem.Weight(i));
  return w;
}

// ρ₀ = tr(AᵀWA) / tr(∇ᵀ∇). With periodic convolution every row of A_i has the same norm, ||A_iᵀ e||² for
// an LR delta e, so tr(A_iᵀ W_i A_i) = (Σ_p w_i[p]) ||A_iᵀ e||²; tr(∇ᵀ∇) = 4n (periodic differences).
double AutomaticRho(const ReconstructionProblem& problem) {
  const MultiFrameModel& model = *problem.model;
  const Shape lr = model.lr_shape();
  Vector delta = Vector::Zero(lr.size());
  delta[0] = 1.0;
  double trace = 0;
  for (int i = 0; i < model.frames(); ++i)
    trace += problem.Weight(i).sum() * model.FrameOperator(i)->ApplyAdjoint(delta).squaredNorm();
  const double rho = trace / (4.0 * double(model.hr_shape().size()));
  return rho > 0 && std::isfinite(rho) ? rho : 1.0;
}

}  // namespace

Image TotalVariationAdmm(const ReconstructionProblem& problem, const TotalVariationOptions& options,
                         TotalVariationSummary* summary, const Image* initial) {
  std::string why;
  if (!options.IsValid(&why)) throw InvalidArgument(std::string(kFunction) + ": invalid options: " + why);
  problem.Validate(kFunction);
  const MultiFrameModel& model = *problem.model;
  const Shape hr = model.hr_shape();
  const Index n = hr.size();
  if (initial) {
    CheckArgument(ShapeOf(*initial) == hr, kFunction, "initial shape", ToString(ShapeOf(*initial)),
                  "the model's HR shape " + ToString(hr));
    CheckArgument(AllFinite(*initial), kFunction, "initial", "(non-finite values)", "finite values");
  }
  const bool uniform = problem.HasUniformWeights();
  if (options.x_update == TotalVariationXUpdate::kFourier && !uniform)
    throw InvalidArgument(
        kFunction, "options.x_update", "fourier",
        "auto or conjugate-gradient when the weights are not uniform (masked or varying pixels)");
  const bool fourier = options.x_update == TotalVariationXUpdate::kFourier ||
                       (options.x_update == TotalVariationXUpdate::kAuto && uniform);
  const auto start = std::chrono::steady_clock::now();

  TotalVariationSummary s;
  s.method = "tv";
  s.mu = options.mu;
  s.x_update = fourier ? TotalVariationXUpdate::kFourier : TotalVariationXUpdate::kConjugateGradient;

  // Data: AᵀW y with unweighted pixels zeroed (they are never read, problem.hpp).
  const OperatorPtr& a = model.Operator();
  const Vector weights = StackedWeights(problem);
  const Vector y = model.Flatten(problem.CleanFrames());
  const Vector aty = a->ApplyAdjoint(weights.cwiseProduct(y));
  const OperatorPtr grad = Gradient(hr, Boundary::kPeriodic);

  // x-update machinery for the current ρ.
  double rho = options.rho > 0 ? options.rho : AutomaticRho(problem);
  s.initial_rho = rho;
  const bool pos = options.positivity;
  std::unique_ptr<FourierNormalSystem> fourier_system;
  OperatorPtr data_normal, cg_normal;
  if (fourier) {
    fourier_system = std::make_unique<FourierNormalSystem>(model, weights[0]);
  } else {
    const Shape stacked{Index(model.frames()) * model.lr_shape().rows, model.lr_shape().cols};
    data_normal = Normal(Compose(Mask(ToImage(weights.cwiseSqrt(), stacked)), a));
  }
  auto prepare = [&](double rho_now) {
    if (fourier) {
      fourier_system->Factorize(rho_now, pos ? rho_now : 0.0);
      s.singular_bins = std::max(s.singular_bins, fourier_system->singular_bins());
    } else {
      std::vector<OperatorPtr> parts = {data_normal, Scale(rho_now, Normal(grad))};
      if (pos) parts.push_back(Scale(rho_now, Identity(n)));
      cg_normal = Sum(parts);
    }
  };
  prepare(rho);
  ConjugateGradientOptions cg_options;
  cg_options.tolerance = options.cg_tolerance;
  cg_options.max_iterations = options.cg_max_iterations;

  // State: x, z = ∇x (+ u), v = x (+ s). Start consistent with x, duals at zero.
  Vector x = initial ? Vector(AsVector(*initial)) : Vector(Vector::Zero(n));
  Vector gx = grad->Apply(x);
  Vector z = gx, u = Vector::Zero(2 * n);
  Vector v, sv;
  if (pos) {
    v = x.cwiseMax(0.0);
    sv = Vector::Zero(n);
  }
  const double alpha = options.relaxation;
  const double sqrt_p = std::sqrt(double((pos ? 3 : 2) * n)), sqrt_n = std::sqrt(double(n));
  // Work vectors, allocated once (an iteration allocates only inside the FFTs).
  Vector rhs(n), x_prev(n), z_prev(2 * n), v_prev(pos ? n : 0), vhat(pos ? n : 0), dual(n), ktu(n),
      diff(2 * n);

  auto objective = [&](const Vector& xx) {
    const Vector r = a->Apply(xx) - y;
    return 0.5 * weights.dot(r.cwiseAbs2()) + options.mu * IsotropicTotalVariation(AsImage(xx, hr));
  };

  s.termination = Termination::kMaxIterations;
  int still_iterations = 0;  // consecutive iterations in which x did not move beyond rounding
  // Squared norms of the data-sized vectors must exist in double precision, or no residual is meaningful.
  bool failed = !std::isfinite(aty.squaredNorm());
  if (failed)
    s.message = "the data are too large for double precision (||AᵀWy||² overflows); rescale the frames";
  for (int k = 0; !failed && k < options.max_iterations; ++k) {
    // x-update: (AᵀWA + ρ∇ᵀ∇ + ρ_v I) x = AᵀWy + ρ∇ᵀ(z − u) + ρ_v(v − s).
    x_prev = x;
    diff = z - u;
    grad->ApplyAdjoint(diff, rhs);
    rhs = aty + rho * rhs;
    if (pos) rhs += rho * (v - sv);
    if (!std::isfinite(rhs.squaredNorm())) {
      failed = true;
      s.message = "x-update right-hand side overflows double precision at iteration " +
                  std::to_string(k + 1) + "; returned the last finite iterate";
      break;
    }
    if (fourier) {
      const Image xi = fourier_system->Solve(AsImage(rhs, hr));
      x = AsVector(xi);
    } else {
      const SolverSummary cg = ConjugateGradient(*cg_normal, rhs, &x, cg_options);
      s.cg_iterations += cg.iterations;
      if (cg.termination == Termination::kMaxIterations) ++s.cg_unconverged;
      if (cg.termination == Termination::kFailed) x.setConstant(std::numeric_limits<double>::quiet_NaN());
    }
    if (!x.allFinite()) {
      x = x_prev;
      failed = true;
      s.message = "non-finite x-update at iteration " + std::to_string(k + 1) + " (rho " + ToString(rho) +
                  "); returned the last finite iterate";
      break;
    }

    // z-update (relaxed), dual update.
    grad->Apply(x, gx);
    z_prev = z;
    diff = alpha * gx + (1 - alpha) * z_prev;  // ĝ
    z = diff + u;
    Shrink(options.mu / rho, n, &z);
    u += diff - z;
    if (pos) {
      v_prev = v;
      vhat = alpha * x + (1 - alpha) * v_prev;
      v = (vhat + sv).cwiseMax(0.0);
      sv += vhat - v;
    }

    // Residuals and tolerances (Boyd §3.3.1).
    double primal2 = (gx - z).squaredNorm(), kx2 = gx.squaredNorm(), zeta2 = z.squaredNorm();
    diff = z - z_prev;
    grad->ApplyAdjoint(diff, dual);
    if (pos) {
      primal2 += (x - v).squaredNorm();
      kx2 += x.squaredNorm();
      zeta2 += v.squaredNorm();
      dual += v - v_prev;
    }
    const double primal = std::sqrt(primal2);
    const double dual_res = rho * dual.norm();
    grad->ApplyAdjoint(u, ktu);
    if (pos) ktu += sv;
    const double eps_pri =
        sqrt_p * options.absolute_tolerance + options.relative_tolerance * std::sqrt(std::max(kx2, zeta2));
    const double eps_dual =
        sqrt_n * options.absolute_tolerance + options.relative_tolerance * rho * ktu.norm();
    s.iterations = k + 1;
    s.primal_residual = primal;
    s.dual_residual = dual_res;
    s.primal_tolerance = eps_pri;
    s.dual_tolerance = eps_dual;
    if (options.record_history) {
      s.history_primal.push_back(primal);
      s.history_dual.push_back(dual_res);
      s.history_primal_tolerance.push_back(eps_pri);
      s.history_dual_tolerance.push_back(eps_dual);
      s.history_rho.push_back(rho);
      s.history_cost.push_back(objective(pos ? Vector(x.cwiseMax(0.0)) : x));
    }
    if (!std::isfinite(primal) || !std::isfinite(dual_res)) {
      x = x_prev;
      failed = true;
      s.message = "non-finite ADMM residuals at iteration " + std::to_string(k + 1) +
                  "; returned the last finite iterate";
      break;
    }
    if (primal <= eps_pri && dual_res <= eps_dual) {
      s.termination = Termination::kConverged;
      s.message = "primal and dual residuals within tolerance";
      break;
    }
    if (options.change_tolerance > 0 && (x - x_prev).norm() <= options.change_tolerance * x.norm()) {
      s.termination = Termination::kConverged;
      s.message = "relative change of x below change_tolerance";
      break;
    }
    // Stagnation: x has not moved beyond rounding (4ε relative) for 3 iterations while the residuals still
    // exceed tolerances that double precision cannot resolve for this problem: stop and say so.
    if ((x - x_prev).norm() <= 4 * std::numeric_limits<double>::epsilon() * x.norm()) {
      if (++still_iterations >= 3) {
        s.termination = Termination::kStagnated;
        s.message = "x unchanged to rounding for 3 iterations with the residuals above tolerance";
        break;
      }
    } else {
      still_iterations = 0;
    }

    // Residual balancing on the tolerance-normalised residuals.
    if (options.adaptive_rho && s.rho_updates < options.max_rho_updates && eps_pri > 0 && eps_dual > 0) {
      const double rp = primal / eps_pri, rd = dual_res / eps_dual;
      double factor = 1;
      if (rp > options.rho_balance * rd)
        factor = options.rho_factor;
      else if (rd > options.rho_balance * rp)
        factor = 1.0 / options.rho_factor;
      if (factor != 1) {
        rho *= factor;
        u /= factor;  // the unscaled dual ρu is unchanged
        if (pos) sv /= factor;
        ++s.rho_updates;
        prepare(rho);
      }
    }
  }
  if (failed) s.termination = Termination::kFailed;
  s.final_rho = rho;

  Image out = ToImage(x, hr);
  if (pos) out = out.cwiseMax(0.0);
  if (!AllFinite(out)) throw NumericalError("TotalVariationAdmm: the estimate is not finite");  // unreachable
  s.data_misfit = WeightedDataMisfit(problem, out, &s.frame_residual_rms);
  s.total_variation = IsotropicTotalVariation(out);
  s.final_cost = s.data_misfit + options.mu * s.total_variation;
  if (!std::isfinite(s.final_cost) && !failed) {
    s.termination = Termination::kFailed;
    s.message = "the objective at the estimate overflows double precision (" + s.message + ")";
  }
  std::ostringstream msg;
  if (s.message.empty())
    msg << "iteration limit reached";
  else
    msg << s.message;
  msg << "; primal " << s.primal_residual << " (tol " << s.primal_tolerance << "), dual " << s.dual_residual
      << " (tol " << s.dual_tolerance << "); rho " << s.initial_rho << " -> " << rho << " (" << s.rho_updates
      << " updates); x-update " << ToString(s.x_update);
  if (!fourier) msg << " (" << s.cg_iterations << " CG steps, " << s.cg_unconverged << " unconverged)";
  if (s.singular_bins > 0) msg << "; " << s.singular_bins << " singular bins (pseudo-inverse)";
  s.message = msg.str();
  s.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  if (summary) *summary = std::move(s);
  return out;
}

}  // namespace aosr
