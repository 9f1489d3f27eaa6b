// Tikhonov's entry points: ReconstructTikhonov and TikhonovFourier, the dispatch between the exact Fourier path
// and the conjugate-gradient path (tikhonov_cg.cpp), the fitted prior, and the summary helpers both paths share.
// The rest lives beside it: tikhonov_prior.cpp (options and prior), tikhonov_fourier_system.cpp (the per-bin
// engine), tikhonov_spectral.cpp (its decomposition for the λ rules), tikhonov_lambda.cpp (λ searches),
// tikhonov_posterior.cpp (inverse operator and std map).
#include "aosr/solvers/tikhonov.hpp"

#include <chrono>
#include <cmath>

#include "aosr/core/error.hpp"
#include "aosr/core/operators.hpp"
#include "aosr/core/progress.hpp"
#include "tikhonov_internal.hpp"

namespace aosr {

namespace tikhonov_internal {

void FinishSummary(const ReconstructionProblem& solved, const Image& x, double lambda,
                   const TikhonovOptions& options, TikhonovSummary* s, const double* prior_norm2) {
  std::vector<double> rms;
  const double misfit = WeightedDataMisfit(solved, x, &rms);
  s->frame_residual_rms = rms;
  s->weighted_residual = 2.0 * misfit;
  const double gx2 = prior_norm2 ? *prior_norm2
                                 : TikhonovPriorOperator(ShapeOf(x), options)->Apply(AsVector(x)).squaredNorm();
  s->final_cost = 2.0 * misfit + lambda * gx2;
  s->lambda = lambda;
  s->solved_hr_shape = ShapeOf(x);
}

std::string CountUnconstrained(const FourierSystem& sys, bool count, TikhonovSummary* s) {
  s->unconstrained_counted = count || sys.ranks_made();
  if (!s->unconstrained_counted) {
    s->rank_deficient_bins = s->unconstrained_frequencies = -1;
    return "";
  }
  s->rank_deficient_bins = sys.deficient_bins();
  s->unconstrained_frequencies = sys.unconstrained();
  return "; " + std::to_string(sys.unconstrained()) + " of " + std::to_string(sys.model().hr_shape().size()) +
         " HR frequencies unconstrained by the data (" + std::to_string(sys.deficient_bins()) +
         " rank-deficient bins)";
}

namespace {

TikhonovResult FourierPath(const ReconstructionProblem& problem, const TikhonovOptions& options,
                           std::chrono::steady_clock::time_point start) {
  const MultiFrameModel& model = *problem.model;
  const double w0 = problem.weights.empty() ? 1.0 : problem.weights.front()(0, 0);
  FourierSystem sys(model, PriorSymbolImage(options, model.hr_shape()), options.rank_tolerance,
                    options.bin_solver);
  sys.SetData(problem.CleanFrames());
  TikhonovResult result;
  TikhonovSummary& s = result.summary;
  s.method = "tikhonov-fourier";
  std::string note;
  // λ' = λ / w₀ is the weight of the unit-weight objective the engine solves.
  double lambda_eff = options.lambda / w0;
  s.lambda_evaluations = 1;
  if (options.lambda_rule == TikhonovLambdaRule::kGcv) {
    std::string edge;
    lambda_eff = GcvSearch(sys, options, &s.gcv, &s.lambda_evaluations, &edge);
    note = " (GCV)" + edge;
  } else if (options.lambda_rule == TikhonovLambdaRule::kLcurve) {
    std::string edge;
    lambda_eff = LcurveSearch(sys, options, &s.lcurve_curvature, &s.lambda_evaluations, &edge);
    note = " (L-curve)" + edge;
  } else if (options.lambda_rule == TikhonovLambdaRule::kUpre) {
    std::string edge;
    lambda_eff = UpreSearch(sys, options, options.noise_sigma * options.noise_sigma / w0, &s.upre,
                            &s.lambda_evaluations, &edge);
    note = " (UPRE)" + edge;
  } else if (options.lambda_rule == TikhonovLambdaRule::kDiscrepancy) {
    const double n_w = double(model.frames()) * double(model.lr_shape().size());
    s.discrepancy_target = options.discrepancy_factor * options.noise_sigma * options.noise_sigma * n_w;
    sys.PrepareSpectral();  // the decomposition and λ₀ in one pass
    const LambdaSearch d = DiscrepancySearch(
        [&](double lam) { return w0 * sys.EvaluateSpectral(lam).residual2; }, s.discrepancy_target,
        sys.lambda0(), options.discrepancy_tolerance, options.discrepancy_max_evaluations);
    lambda_eff = d.lambda;
    s.lambda_evaluations = d.evaluations;
    note = " (discrepancy";
    if (!d.met) {
      s.termination = d.termination;
      note += " not met: " + d.note;
    }
    note += ")";
  }
  FourierSystem::Fit fit;
  result.image = sys.Solve(lambda_eff, &fit);
  s.woodbury_bins = fit.woodbury_bins;
  s.lr_bins = sys.bins();
  const std::string counts = CountUnconstrained(sys, options.count_unconstrained, &s);
  // ||Γx||² from the solve's spectrum (Parseval: the operator's norm to rounding, without a pass over the image).
  FinishSummary(problem, result.image, lambda_eff * w0, options, &s, &fit.prior2);
  s.message = "lambda " + ToString(s.lambda) + note + counts;
  if (options.lambda_rule == TikhonovLambdaRule::kDiscrepancy)
    s.message += "; weighted residual " + ToString(s.weighted_residual) + " vs target " +
                 ToString(s.discrepancy_target);
  if (options.compute_std) {
    s.std_computed = PosteriorStd(sys, lambda_eff, options.noise_sigma * options.noise_sigma / w0,
                                  &result.posterior_std, &s.mean_posterior_variance);
    if (!s.std_computed) s.message += "; posterior improper (a singular bin): no std map";
  }
  s.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return result;
}

}  // namespace

TikhonovResult FittedPrior(const char* function, const ReconstructionProblem& problem,
                           const TikhonovOptions& options, std::chrono::steady_clock::time_point start) {
  // The frames as the fit wants them: masked pixels filled with their frame's weighted mean (a hole would add
  // white power), and the white floor σ²·mean(1/w) when σ is known.
  const ImageStack clean = problem.CleanFrames();
  ImageStack filled;
  double inv_weight_sum = 0;
  Index weighted = 0;
  for (int i = 0; i < problem.frame_count(); ++i) {
    const Image w = problem.Weight(i);
    const auto on = w.array() > 0;
    const Index count = on.count();
    const double mean = count > 0 ? on.select(clean[i], 0.0).sum() / double(count) : 0.0;
    filled.push_back(on.select(clean[i], mean));
    inv_weight_sum += on.select(1.0 / w.array().max(1e-300), 0.0).sum();
    weighted += count;
  }
  const double mean_inv_weight = inv_weight_sum / double(std::max<Index>(1, weighted));
  FramePowerSpectrumOptions fo = options.spectrum_fit;
  fo.noise_variance = options.noise_sigma > 0 ? options.noise_sigma * options.noise_sigma * mean_inv_weight : 0.0;
  const FramePowerSpectrumFit fit = FitFramePowerSpectrum(*problem.model, filled, fo);
  TikhonovOptions o = options;
  o.prior = TikhonovPrior::kPowerSpectrum;
  o.spectrum_slope = fit.model.slope;
  o.spectrum_corner = fit.model.corner;
  std::string wiener;
  if (options.lambda_rule == TikhonovLambdaRule::kWiener) {
    // λ = σ²/s(0): σ² given, or v/mean(1/w) from the fitted floor v (tikhonov.hpp, kWiener).
    const double sigma2 = options.noise_sigma > 0 ? options.noise_sigma * options.noise_sigma
                                                  : fit.noise_variance / mean_inv_weight;
    o.lambda_rule = TikhonovLambdaRule::kFixed;
    o.lambda = sigma2 / fit.ZeroFrequencyPower();
    if (!(std::isfinite(o.lambda) && o.lambda >= 0))
      throw NumericalError(std::string(function) + ": the Wiener lambda of the fitted spectrum is not finite (" +
                           fit.BriefReport() + ")");
    wiener = "; lambda = sigma^2 / s(0) (Wiener, sigma " +
             std::string(options.noise_sigma > 0 ? "given" : "from the fitted noise floor") + ")";
    if (options.noise_sigma == 0 && !fit.noise_identified)
      wiener += "; the frames do not determine their noise floor, so this lambda is not a Wiener lambda: give "
                "noise_sigma";
  }
  TikhonovResult r = Reconstruct(function, problem, o);
  TikhonovSummary& s = r.summary;
  s.spectrum_fitted = true;
  s.fitted_spectrum = fit.model;
  s.fitted_noise_variance = fit.noise_variance;
  s.message += wiener + "; prior fitted to the frames: " + fit.BriefReport();
  if (options.lambda_rule == TikhonovLambdaRule::kWiener && options.noise_sigma == 0 && !fit.noise_identified)
    s.termination = Termination::kFailed;
  s.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return r;
}

TikhonovResult Reconstruct(const char* function, const ReconstructionProblem& problem,
                           const TikhonovOptions& options) {
  std::string why;
  if (!options.IsValid(&why)) throw InvalidArgument(std::string(function) + ": options." + why);
  problem.Validate(function);
  const auto start = std::chrono::steady_clock::now();
  const Shape hr = problem.model->hr_shape();
  if (options.object_power_spectrum.size() > 0 && ShapeOf(options.object_power_spectrum) != hr)
    throw InvalidArgument(function, "options.object_power_spectrum shape",
                          ToString(ShapeOf(options.object_power_spectrum)),
                          "the model's HR shape " + ToString(hr));
  if (!problem.weights.empty()) {
    bool any = false;
    for (const Image& w : problem.weights) any = any || (w.array() > 0).any();
    if (!any) throw InvalidArgument(function, "problem.weights", "all zero", "at least one weighted pixel");
  }
  // A space-variant model (forward_model.hpp, WithPsfField) has no exact Fourier solution: its operator path
  // (PCG, preconditioned by the Fourier inverse of its isoplanatic part) solves it.
  const bool fourier_exact = problem.HasUniformWeights() && options.boundary == TikhonovBoundary::kPeriodic &&
                             !problem.model->space_variant();
  if (options.prior == TikhonovPrior::kFitted) return FittedPrior(function, problem, options, start);
  if (options.method == TikhonovMethod::kFourier && !fourier_exact)
    throw InvalidArgument(
        function, "options.method", "kFourier",
        "kAuto or kConjugateGradient: the weights are not uniform, so no exact Fourier solution");
  const bool searched = options.lambda_rule == TikhonovLambdaRule::kGcv ||
                        options.lambda_rule == TikhonovLambdaRule::kLcurve ||
                        options.lambda_rule == TikhonovLambdaRule::kUpre;
  if (searched && !fourier_exact)
    throw InvalidArgument(
        function, "options.lambda_rule", std::string("k") + (options.lambda_rule == TikhonovLambdaRule::kGcv
                                                                ? "Gcv"
                                                                : options.lambda_rule == TikhonovLambdaRule::kLcurve
                                                                      ? "Lcurve"
                                                                      : "Upre"),
        "kFixed, kDiscrepancy or kWiener: GCV, the L-curve and UPRE need the exact influence-matrix trace or "
        "spectral sums, which only the Fourier path (uniform weights, periodic boundary) has (Reconstruct in "
        "reconstruct.hpp chooses them on the unweighted frames)");
  const bool use_cg = options.method == TikhonovMethod::kConjugateGradient || !fourier_exact;
  if (!use_cg) {
    // A direct solve, reported as one step (TikhonovOptions::progress): nothing is left to cut short when a
    // cancellation is seen, so the result is complete and says so (core/progress.hpp's rule for a last step).
    ProgressReporter stage(options.progress, "tikhonov", 1, "lambda");
    stage.Start();
    TikhonovResult r = FourierPath(problem, options, start);
    stage.Finish(1, r.summary.lambda);
    stage.RethrowIfThrown();
    return r;
  }
  return ConjugateGradientPath(function, problem, options, start);
}

}  // namespace tikhonov_internal

TikhonovResult ReconstructTikhonov(const ReconstructionProblem& problem, const TikhonovOptions& options) {
  return tikhonov_internal::Reconstruct("ReconstructTikhonov", problem, options);
}

Image TikhonovFourier(const MultiFrameModel& model, const ImageStack& frames, const TikhonovOptions& options,
                      TikhonovSummary* summary) {
  std::string why;
  if (!options.IsValid(&why)) throw InvalidArgument("TikhonovFourier: " + why);
  if (options.method == TikhonovMethod::kConjugateGradient)
    throw InvalidArgument("TikhonovFourier", "options.method", "kConjugateGradient",
                          "kAuto or kFourier (ReconstructTikhonov runs the iterative path)");
  if (options.boundary != TikhonovBoundary::kPeriodic)
    throw InvalidArgument("TikhonovFourier", "options.boundary", "kZeroPadded",
                          "kPeriodic (ReconstructTikhonov handles zero-padded boundaries)");
  model.Flatten(frames);  // checks count and shapes
  for (std::size_t i = 0; i < frames.size(); ++i)
    if (!AllFinite(frames[i]))
      throw InvalidArgument("TikhonovFourier", "frame " + std::to_string(i), "contains NaN or Inf",
                            "finite values (mask bad pixels: ReconstructTikhonov with weights)");
  ReconstructionProblem problem;
  // A non-owning handle: the problem lives only for this call.
  problem.model = std::shared_ptr<const MultiFrameModel>(&model, [](const MultiFrameModel*) {});
  problem.frames = frames;
  TikhonovOptions o = options;
  o.method = TikhonovMethod::kFourier;
  o.compute_std = false;
  TikhonovResult r = tikhonov_internal::Reconstruct("TikhonovFourier", problem, o);
  if (summary) *summary = r.summary;
  return std::move(r.image);
}

}  // namespace aosr
