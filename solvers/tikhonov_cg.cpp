// The conjugate-gradient path of tikhonov.hpp: (AᵀWA + λΓᵀΓ) x = AᵀWy on the periodic grid or on the
// zero-padded grid (padded_model.hpp), preconditioned by the exact Fourier inverse of the uniform-weight
// problem on the same grid.
#include <chrono>
#include <cmath>
#include <optional>

#include "aosr/core/error.hpp"
#include "aosr/core/operators.hpp"
#include "aosr/solvers/conjugate_gradient.hpp"
#include "aosr/solvers/padded_model.hpp"
#include "tikhonov_internal.hpp"

namespace aosr::tikhonov_internal {

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
  } else {
    grid.model = problem.model;
    grid.frames = problem.CleanFrames();
    for (int i = 0; i < n; ++i) grid.weights.push_back(problem.Weight(i));
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
  FourierSystem sys(pm, PriorSymbolImage(options, hr), options.rank_tolerance, options.bin_solver);

  TikhonovResult result;
  TikhonovSummary& s = result.summary;
  s.method = "tikhonov-cg";
  s.preconditioned = options.precondition;
  s.preconditioner_weight = w_bar;
  s.padding = padded ? padded->padding() : 0;
  Vector x = Vector::Zero(hr.size());
  SolverSummary last;
  // One solve at λ, warm-started from the previous x; returns Σ w (y − A x)².
  auto solve = [&](double lambda) {
    const OperatorPtr normal = Sum({atwa, Scale(lambda, gtg)});
    if (options.precondition) {
      Index wb = 0;
      const OperatorPtr m =
          FourierInverseOperator(hr, pm.r(), sys.Inverses(lambda / w_bar, nullptr, &wb), 1.0 / w_bar);
      s.woodbury_bins = wb;
      last = PreconditionedConjugateGradient(*normal, *m, b, &x, options.cg);
    } else {
      last = ConjugateGradient(*normal, b, &x, options.cg);
    }
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
      s.termination = Termination::kFailed;
      note += " not met: " + d.note;
    }
    note += ")";
  } else {
    solve(lambda);
  }
  s.final_solve_iterations = last.iterations;
  if (last.termination != Termination::kConverged && s.termination == Termination::kConverged)
    s.termination = last.termination;

  const Image x_grid = ToImage(x, hr);
  if (!AllFinite(x_grid))
    throw NumericalError(std::string(function) + ": the CG solve produced non-finite values");
  result.image = padded ? padded->CropObject(x_grid) : x_grid;
  s.lr_bins = sys.bins();
  s.rank_deficient_bins = sys.deficient_bins();
  s.unconstrained_frequencies = sys.unconstrained();
  FinishSummary(grid, x_grid, lambda, options, &s);
  s.message = "lambda " + ToString(lambda) + note + "; " + (options.precondition ? "preconditioned " : "") +
              "CG " + ToString(last.termination) + " after " + std::to_string(last.iterations) +
              " iterations (" + std::to_string(s.iterations) + " in all): " + last.message;
  if (padded)
    s.message +=
        "; zero-padded by " + std::to_string(s.padding) + " camera pixels to " + ToString(hr) + " HR";
  if (options.lambda_rule == TikhonovLambdaRule::kDiscrepancy)
    s.message += "; weighted residual " + ToString(s.weighted_residual) + " vs target " +
                 ToString(s.discrepancy_target);
  if (options.compute_std) {
    // Exact only when C is block-circulant (uniform weights, periodic): then w̄ = w₀ and the system is `sys`.
    if (!padded && problem.HasUniformWeights()) {
      s.std_computed = PosteriorStd(sys, lambda / w_bar, options.noise_sigma * options.noise_sigma / w_bar,
                                    &result.posterior_std, &s.mean_posterior_variance);
      if (!s.std_computed) s.message += "; posterior improper (a singular bin): no std map";
    } else {
      s.message +=
          "; posterior std not computed (no closed form with non-uniform weights or padded boundaries)";
    }
  }
  s.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return result;
}

}  // namespace aosr::tikhonov_internal
