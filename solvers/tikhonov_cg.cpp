// The conjugate-gradient path of tikhonov.hpp: (AᵀWA + λΓᵀΓ) x = AᵀWy on the periodic grid or on the
// zero-padded grid (padded_model.hpp), preconditioned by the exact Fourier inverse of the uniform-weight
// problem on the same grid.
#include <chrono>
#include <cmath>
#include <limits>
#include <memory>
#include <optional>

#include "aosr/ao/random.hpp"
#include "aosr/core/error.hpp"
#include "aosr/core/fft.hpp"
#include "aosr/core/operators.hpp"
#include "aosr/solvers/conjugate_gradient.hpp"
#include "aosr/solvers/fourier_normal_system.hpp"
#include "aosr/solvers/padded_model.hpp"
#include "tikhonov_internal.hpp"

namespace aosr::tikhonov_internal {

namespace {

// The λ → ∞ end of (4), in closed form. Write x = z + u, z in the prior's null space (the constant image for
// the gradient and Laplacian priors; {0} for the identity and power-spectrum priors), u orthogonal to it.
// Expanding (AᵀWA + λΓᵀΓ) x = AᵀWy in 1/λ:
//   order 1:    z₀ = c₀·1,  c₀ = aᵀWy / aᵀWa,  a = A·1 (the frames of a flat unit object): the weighted
//               fit of the data by the null space;
//   order 1/λ:  ΓᵀΓ u₁ = AᵀW(y − A z₀)  (its right-hand side has no null component, by the order-1 equation),
//               z₁ = −(aᵀW A u₁ / aᵀWa)·1,
// so x = z₀ + (u₁ + z₁)/λ + O(λ⁻²). The neglected term is smaller than the kept one by a factor
// ρ⁻¹ = ||AᵀWA|| / (λ γ_min), γ_min the smallest positive prior symbol, and ||AᵀWA|| <= w_max·N·r² (unit-sum
// PSFs, box pixels summing r² HR pixels). Where ρ >= 1e8 the truncation (ρ⁻² <= 1e-16 relative) is below
// double precision, while PCG on (4) there would have to resolve a system whose two halves differ in scale
// by more than 1/ε: its inner products lose every digit, and whether it stops depends on rounding. So the
// solver takes this expansion there: exact to rounding, at any λ up to the largest double, in 2 FFTs and
// three applications of A or Aᵀ.
class LargeLambdaExpansion {
 public:
  LargeLambdaExpansion(const MultiFrameModel& model, const Image& w_stack, const Vector& y, const Image& symbol)
      : model_(model), hr_(model.hr_shape()), w_(AsVector(w_stack)), y_(y), symbol_(symbol) {
    gamma_min_ = std::numeric_limits<double>::infinity();
    bool null_elsewhere = false;
    for (Index fy = 0; fy < symbol.rows(); ++fy)
      for (Index fx = 0; fx < symbol.cols(); ++fx) {
        const double g = symbol(fy, fx);
        if (g > 0)
          gamma_min_ = std::min(gamma_min_, g);
        else if (fy != 0 || fx != 0)
          null_elsewhere = true;
      }
    // Only a null space of constants (or none) has the closed form above; otherwise PCG stays in charge.
    usable_ = !null_elsewhere && std::isfinite(gamma_min_);
    has_null_ = symbol(0, 0) <= 0;
    data_norm_ = w_.maxCoeff() * double(model.frames()) * double(model.r() * model.r());
  }

  // ρ = λ γ_min / (w_max N r²): how far the prior outweighs the data on its range.
  double Ratio(double lambda) const { return data_norm_ > 0 ? lambda * gamma_min_ / data_norm_ : HUGE_VAL; }
  bool Applies(double lambda) const { return usable_ && Ratio(lambda) >= kMinRatio; }

  Vector Solve(double lambda) const {
    const OperatorPtr& a = model_.Operator();
    Vector z0 = Vector::Zero(hr_.size());
    Vector a1;
    double awa = 0;
    if (has_null_) {
      a1 = a->Apply(Vector::Ones(hr_.size()));
      awa = a1.dot(w_.cwiseProduct(a1));
      if (awa > 0) z0.setConstant(a1.dot(w_.cwiseProduct(y_)) / awa);
    }
    // u₁ = (ΓᵀΓ)⁺ AᵀW(y − A z₀), the pseudo-inverse applied per frequency (null frequency set to zero).
    const Vector g = a->ApplyAdjoint(w_.cwiseProduct(y_ - a->Apply(z0)));
    ComplexImage G = FftR2C(ToImage(g, hr_));
    for (Index fy = 0; fy < G.rows(); ++fy)
      for (Index fx = 0; fx < G.cols(); ++fx) {
        const double s = symbol_(fy, fx);
        G(fy, fx) = s > 0 ? G(fy, fx) / s : Complex(0);
      }
    Vector u1 = AsVector(FftC2R(G, hr_.cols));
    if (has_null_ && awa > 0) u1.array() -= a1.dot(w_.cwiseProduct(a->Apply(u1))) / awa;  // + z₁
    return z0 + u1 / lambda;
  }

  std::string Describe(double lambda) const {
    return "lambda beyond the CG range (lambda*gamma_min/(w_max*N*r^2) = " + ToString(Ratio(lambda)) +
           " >= 1e8): solved by the large-lambda expansion, null-space fit + first-order term, exact to "
           "rounding";
  }

  static constexpr double kMinRatio = 1e8;

 private:
  const MultiFrameModel& model_;
  Shape hr_;
  Vector w_, y_;
  Image symbol_;
  double gamma_min_ = 0, data_norm_ = 0;
  bool usable_ = false, has_null_ = false;
};

}  // namespace

TikhonovResult ConjugateGradientPath(const char* function, const ReconstructionProblem& problem,
                                     const TikhonovOptions& options,
                                     std::chrono::steady_clock::time_point start) {
  const int n = problem.frame_count();
  // The grid solved on, as a ReconstructionProblem whose model is periodic there: the original problem
  // (explicit weights, masked pixels zeroed), or its embedding in the padded grid with weight 0 outside the
  // frames' window.
  std::optional<PaddedModel> padded;
  ReconstructionProblem grid;
  if (options.boundary == TikhonovBoundary::kZeroPadded) {
    const int pad = options.padding >= 0 ? options.padding : PaddedModel::SuggestPadding(*problem.model);
    padded = PaddedModel::FromPeriodicModel(*problem.model, pad);
    grid.model = padded->periodic_ptr();
    grid.frames = padded->EmbedFrames(problem.CleanFrames());
    grid.weights = padded->EmbedWeights(problem.weights);
    // The residuals where the caller asked, moved into the padded grid (outside the frames' window every
    // weight is 0, so every pixel of the grid means the frames' window).
    const LrRegion& g = problem.residual_region;
    if (!g.all()) grid.residual_region = LrRegion{g.y0 + pad, g.x0 + pad, g.rows, g.cols};
  } else {
    grid.model = problem.model;
    grid.frames = problem.CleanFrames();
    for (int i = 0; i < n; ++i) grid.weights.push_back(problem.Weight(i));
    grid.residual_region = problem.residual_region;
  }
  const MultiFrameModel& pm = *grid.model;
  const Shape hr = pm.hr_shape(), lr = pm.lr_shape();

  // W as one diagonal over the stacked frames (row-major concatenation = vertical stack of the maps).
  Image w_stack(Index(n) * lr.rows, lr.cols);
  for (int i = 0; i < n; ++i) w_stack.middleRows(Index(i) * lr.rows, lr.rows) = grid.weights[i];
  const Index n_w = (w_stack > 0).count();
  const double w_bar = w_stack.sum() / double(n_w);  // mean positive weight: the preconditioner's w̄
  const OperatorPtr& a = pm.Operator();
  const OperatorPtr w_op = Mask(w_stack);
  const OperatorPtr atwa = Compose(Adjoint(a), Compose(w_op, a));
  const OperatorPtr gtg = Normal(TikhonovPriorOperator(hr, options));
  const Vector y = pm.Flatten(grid.frames);
  const Vector b = a->ApplyAdjoint(w_op->Apply(y));
  const Image prior_symbol = PriorSymbolImage(options, hr);
  FourierSystem sys(pm, prior_symbol, options.rank_tolerance, options.bin_solver);

  TikhonovResult result;
  TikhonovSummary& s = result.summary;
  s.method = "tikhonov-cg";
  s.preconditioned = options.precondition;
  s.preconditioner_weight = w_bar;
  s.padding = padded ? padded->padding() : 0;
  Vector x = Vector::Zero(hr.size());
  SolverSummary last;
  const LargeLambdaExpansion expansion(pm, w_stack, y, prior_symbol);
  // The preconditioner M = (w̄ AᵀA + λΓᵀΓ)⁻¹, the exact inverse of the uniform-weight problem on the same grid,
  // per LR bin by FourierNormalSystem: in the Woodbury form where N < r² it holds an N x N factor per bin and
  // the model's aliased system for half the bins (about N + 4 HR arrays) instead of an r² x r² inverse for every
  // bin (2 r² HR arrays, 32 at r = 4: the weighted path's largest allocation before), and it applies with real
  // FFTs. Laid out on first use, refactorised for each λ.
  std::shared_ptr<FourierNormalSystem> precond_system;
  auto preconditioner = [&](double lambda) -> OperatorPtr {
    if (!precond_system || precond_system.use_count() > 1)  // a live operator keeps its own factors
      precond_system = std::make_shared<FourierNormalSystem>(pm, w_bar);
    precond_system->Factorize(lambda * prior_symbol);
    return NormalSystemInverse(precond_system);
  };
  // Every PCG solve reports to options.progress (stage "tikhonov-cg"); once one is cancelled, no further solve
  // runs (a λ search returns the last iterate, the std draws are skipped).
  const ConjugateGradientOptions& cg = options.cg;
  const ConjugateGradientProgress cg_progress{options.progress, "tikhonov-cg"};
  bool cancelled = false;
  // One solve at λ, warm-started from the previous x; returns Σ w (y − A x)².
  auto solve = [&](double lambda) {
    if (cancelled) {
      const Vector res = y - a->Apply(x);
      return res.dot(AsVector(w_stack).cwiseProduct(res));
    }
    if (expansion.Applies(lambda)) {
      x = expansion.Solve(lambda);
      last = SolverSummary();
      last.method = "large-lambda-expansion";
      last.message = expansion.Describe(lambda);
      const Vector res = y - a->Apply(x);
      return res.dot(AsVector(w_stack).cwiseProduct(res));
    }
    const OperatorPtr normal = Sum({atwa, Scale(lambda, gtg)});
    if (options.precondition) {
      const OperatorPtr m = preconditioner(lambda);
      s.woodbury_bins = precond_system->woodbury_bins();
      last = PreconditionedConjugateGradient(*normal, *m, b, &x, cg, cg_progress);
    } else {
      last = ConjugateGradient(*normal, b, &x, cg, cg_progress);
    }
    if (last.termination == Termination::kUserCancelled) cancelled = true;
    s.iterations += last.iterations;
    const Vector res = y - a->Apply(x);
    return res.dot(AsVector(w_stack).cwiseProduct(res));
  };

  double lambda = options.lambda;
  std::string note;
  s.lambda_evaluations = 1;
  if (options.lambda_rule == TikhonovLambdaRule::kGcv) {
    // Reached only for Fourier-exact problems (uniform weights, periodic): GCV there is exact.
    sys.SetData(grid.frames);
    std::string edge;
    lambda = w_bar * GcvSearch(sys, options, &s.gcv, &s.lambda_evaluations, &edge);
    note = " (GCV, Fourier)" + edge;
    solve(lambda);
  } else if (options.lambda_rule == TikhonovLambdaRule::kDiscrepancy) {
    s.discrepancy_target =
        options.discrepancy_factor * options.noise_sigma * options.noise_sigma * double(n_w);
    const LambdaSearch d =
        DiscrepancySearch(solve, s.discrepancy_target, w_bar * sys.lambda0(), options.discrepancy_tolerance,
                          options.discrepancy_max_evaluations);
    lambda = d.lambda;  // the last λ solved: x belongs to it
    s.lambda_evaluations = d.evaluations;
    note = " (discrepancy";
    if (!d.met) {
      s.termination = d.termination;
      note += " not met: " + d.note;
    }
    note += ")";
  } else {
    solve(lambda);
  }
  s.final_solve_iterations = last.iterations;
  if (last.termination != Termination::kConverged && s.termination == Termination::kConverged)
    s.termination = last.termination;
  if (cancelled) s.termination = Termination::kUserCancelled;

  const Image x_grid = ToImage(x, hr);
  if (!AllFinite(x_grid))
    throw NumericalError(std::string(function) + ": the CG solve produced non-finite values");
  result.image = padded ? padded->CropObject(x_grid) : x_grid;
  s.lr_bins = sys.bins();
  CountUnconstrained(sys, options.count_unconstrained, &s);
  FinishSummary(grid, x_grid, lambda, options, &s);
  if (last.method == "large-lambda-expansion")
    s.message = "lambda " + ToString(lambda) + note + "; " + last.message;
  else
    s.message = "lambda " + ToString(lambda) + note + "; " + (options.precondition ? "preconditioned " : "") +
                "CG " + ToString(last.termination) + " after " + std::to_string(last.iterations) +
                " iterations (" + std::to_string(s.iterations) + " in all): " + last.message;
  if (padded)
    s.message +=
        "; zero-padded by " + std::to_string(s.padding) + " camera pixels to " + ToString(hr) + " HR";
  if (options.lambda_rule == TikhonovLambdaRule::kDiscrepancy)
    s.message += "; weighted residual " + ToString(s.weighted_residual) + " vs target " +
                 ToString(s.discrepancy_target);
  if (options.compute_std && cancelled) {
    s.message += "; posterior std not computed (cancelled by the caller)";
  } else if (options.compute_std) {
    // Exact only when C is block-circulant (uniform weights, periodic): then w̄ = w₀ and the system is `sys`.
    if (!padded && problem.HasUniformWeights()) {
      s.std_computed = PosteriorStd(sys, lambda / w_bar, options.noise_sigma * options.noise_sigma / w_bar,
                                    &result.posterior_std, &s.mean_posterior_variance);
      if (!s.std_computed) s.message += "; posterior improper (a singular bin): no std map";
    } else if (last.method == "large-lambda-expansion") {
      s.message += "; posterior std not computed (λ beyond the reach of iteration: large-λ expansion)";
    } else {
      // Perturbation-optimisation draws of the posterior (tikhonov.hpp, compute_std): each b_s has covariance
      // σ²Q, so Q⁻¹ b_s has covariance σ²Q⁻¹ = C.
      const OperatorPtr normal = Sum({atwa, Scale(lambda, gtg)});
      const OperatorPtr prior_op = TikhonovPriorOperator(hr, options);
      const OperatorPtr m = preconditioner(lambda);
      const Vector sqrt_w = AsVector(w_stack).cwiseMax(0.0).cwiseSqrt();
      ConjugateGradientOptions draw_cg = cg;
      draw_cg.tolerance = std::max(options.cg.tolerance, 1e-6);  // the draws' sampling error is ~√(2/K)
      Image sum2 = Image::Zero(hr.rows, hr.cols), sum4 = Image::Zero(hr.rows, hr.cols);
      int draw_iterations = 0;
      bool ok = true;
      for (int k = 0; k < options.std_samples && ok; ++k) {
        NormalGenerator gen(DeriveSeed(options.std_seed, std::uint64_t(k)));
        Vector z1(sqrt_w.size()), z2(prior_op->rows());
        gen.Fill(z1.data(), z1.size());
        gen.Fill(z2.data(), z2.size());
        const Vector b_s = options.noise_sigma * (a->ApplyAdjoint(sqrt_w.cwiseProduct(z1)) +
                                                  std::sqrt(lambda) * prior_op->ApplyAdjoint(z2));
        Vector xs = Vector::Zero(hr.size());
        const SolverSummary d = options.precondition
                                    ? PreconditionedConjugateGradient(*normal, *m, b_s, &xs, draw_cg, cg_progress)
                                    : ConjugateGradient(*normal, b_s, &xs, draw_cg, cg_progress);
        draw_iterations += d.iterations;
        cancelled = d.termination == Termination::kUserCancelled;
        ok = d.termination == Termination::kConverged || d.termination == Termination::kStagnated;
        const Image x2 = ToImage(xs, hr).square();
        sum2 += x2;
        sum4 += x2.square();
      }
      if (ok) {
        const double kk = options.std_samples;
        const Image var = sum2 / kk;
        const Image var_se = ((sum4 / kk - var.square()).max(0.0) / (kk - 1.0)).sqrt();
        const Image sd = var.sqrt();
        const Image sd_se = (var > 0).select(var_se / (2.0 * sd.max(1e-300)), 0.0);
        result.posterior_std = padded ? padded->CropObject(sd) : sd;
        result.posterior_std_error = padded ? padded->CropObject(sd_se) : sd_se;
        s.std_computed = true;
        s.std_samples = options.std_samples;
        s.mean_posterior_variance = result.posterior_std.square().mean();
        s.message += "; posterior std from " + std::to_string(options.std_samples) + " posterior draws (" +
                     std::to_string(draw_iterations) + " PCG iterations)";
      } else if (cancelled) {
        s.termination = Termination::kUserCancelled;
        s.message += "; posterior std not computed (cancelled by the caller)";
      } else {
        s.message += "; posterior std not computed (a posterior draw's PCG did not converge)";
      }
    }
  }
  s.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return result;
}

}  // namespace aosr::tikhonov_internal
