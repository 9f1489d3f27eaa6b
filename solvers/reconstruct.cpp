#include "aosr/solvers/reconstruct.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <vector>

#include "aosr/core/error.hpp"
#include "aosr/core/memory.hpp"

namespace aosr {
namespace {

constexpr const char* kReconstructFn = "Reconstruct";

double Quantile(const Image& x, double q) {
  std::vector<double> v(x.data(), x.data() + x.size());
  const std::size_t k = std::min(v.size() - 1, std::size_t(q * double(v.size() - 1) + 0.5));
  std::nth_element(v.begin(), v.begin() + k, v.end());
  return v[k];
}

// GCV, the L-curve and UPRE need a Fourier-exact problem (tikhonov.hpp). For weighted or masked data choose λ
// by the rule on the same frames with uniform weights, then scale it by the mean positive weight (λ and the
// weights enter (1) together). Masked pixels enter that choice as zeros: harmless for the λ of a few bad
// pixels. UPRE's noise level on the unweighted frames is the mean pixel variance, σ²·mean(1/w).
TikhonovOptions WithGcvLambda(const ReconstructionProblem& problem, TikhonovOptions t) {
  const bool searched = t.lambda_rule == TikhonovLambdaRule::kGcv || t.lambda_rule == TikhonovLambdaRule::kLcurve ||
                        t.lambda_rule == TikhonovLambdaRule::kUpre;
  const bool space_variant = problem.model->space_variant();
  if (!searched || (problem.HasUniformWeights() && !space_variant)) return t;
  double sum = 0, inv_sum = 0;
  Index count = 0;
  for (int i = 0; i < problem.frame_count(); ++i) {
    const Image w = problem.Weight(i);
    sum += (w > 0).select(w, 0.0).sum();
    inv_sum += (w > 0).select(1.0 / w.max(1e-300), 0.0).sum();
    count += (w > 0).count();
  }
  ReconstructionProblem uniform = problem;
  uniform.frames = problem.CleanFrames();
  uniform.weights.clear();
  // A space-variant model: the rule runs on its isoplanatic part (the PSFs it was built around).
  if (space_variant) uniform.model = std::make_shared<const MultiFrameModel>(problem.model->Isoplanatic());
  TikhonovOptions g = t;
  g.compute_std = false;
  if (count > 0) g.noise_sigma = t.noise_sigma * std::sqrt(inv_sum / double(count));
  const double lambda_uniform = ReconstructTikhonov(uniform, g).summary.lambda;
  t.lambda_rule = TikhonovLambdaRule::kFixed;
  t.lambda = lambda_uniform * (count > 0 ? sum / double(count) : 1.0);
  return t;
}

// The GCV Tikhonov estimate and the noise variance (in weight units) it leaves in the residual.
struct Pilot {
  TikhonovResult tikhonov;
  double contrast = 1.0;  // s of the rule in reconstruct.hpp
  double mu = 0.0;        // μ of that rule
};

// With `fixed` (ReconstructOptions::fixed_automatic) the pilot runs at its λ and reports its μ and contrast.
Pilot RunPilot(const ReconstructionProblem& problem, const TikhonovOptions& base,
               const std::optional<AutomaticRegularisation>& fixed = std::nullopt) {
  TikhonovOptions t = base;
  if (fixed) {
    t.lambda_rule = TikhonovLambdaRule::kFixed;
    t.lambda = fixed->pilot_lambda;
  } else {
    t = WithGcvLambda(problem, base);
  }
  t.compute_std = false;
  Pilot p;
  p.tikhonov = ReconstructTikhonov(problem, t);
  p.contrast = Quantile(p.tikhonov.image, 0.995) - Quantile(p.tikhonov.image, 0.5);
  if (!(p.contrast > 0)) p.contrast = std::max(1e-12, p.tikhonov.image.abs().maxCoeff());
  Index weighted = 0;
  double weight_sum = 0;
  for (int i = 0; i < problem.frame_count(); ++i) {
    const Image w = problem.Weight(i);
    weighted += (w > 0).count();
    weight_sum += (w > 0).select(w, 0.0).sum();
  }
  const double n = double(std::max<Index>(1, weighted));
  const double rho = std::sqrt(std::max(p.tikhonov.summary.weighted_residual / n, 1e-300));
  p.mu = 0.5 * rho * std::sqrt(weight_sum / n);
  if (fixed) {
    p.mu = fixed->mu;
    p.contrast = fixed->contrast;
  }
  return p;
}

// The pilot as the progress stage "pilot": iteration 0 of 1 when it starts, 1 of 1 (value λ) when it ends. A
// cancellation asked at either point is honoured after the pilot (a direct solve), whose estimate is then the
// result: *cancelled is set.
Pilot RunPilotStage(const ReconstructionProblem& problem, const TikhonovOptions& base,
                    const std::optional<AutomaticRegularisation>& fixed, const ProgressCallback& progress,
                    bool* cancelled) {
  ProgressReporter stage(progress, "pilot", 1, "lambda");
  stage.Start();
  Pilot p = RunPilot(problem, base, fixed);
  stage.Finish(1, p.tikhonov.summary.lambda);
  stage.RethrowIfThrown();
  *cancelled = stage.cancelled();
  return p;
}

// The result of a run cancelled during its pilot: the pilot's Tikhonov estimate, reported as cancelled.
void CancelledAfterPilot(Pilot p, Reconstruction* out) {
  out->image = std::move(p.tikhonov.image);
  out->regularisation = p.tikhonov.summary.lambda;
  out->summary = p.tikhonov.summary;
  out->summary.termination = Termination::kUserCancelled;
  out->summary.message = "cancelled by the caller after the pilot stage; the image is its Tikhonov estimate";
  out->summary.message += " (lambda " + ToString(out->regularisation) + ")";
}

}  // namespace

const char* ToString(ReconstructionMethod m) {
  switch (m) {
    case ReconstructionMethod::kShiftAddMean: return "shift-add";
    case ReconstructionMethod::kShiftAddMedian: return "shift-add-median";
    case ReconstructionMethod::kDrizzle: return "drizzle";
    case ReconstructionMethod::kTikhonov: return "tikhonov";
    case ReconstructionMethod::kLinear: return "linear";
    case ReconstructionMethod::kTotalVariation: return "tv";
    case ReconstructionMethod::kMap: return "map";
  }
  return "unknown";
}

const std::vector<ReconstructionMethod>& ReconstructionMethods() {
  static const std::vector<ReconstructionMethod> methods = {
      ReconstructionMethod::kShiftAddMean, ReconstructionMethod::kShiftAddMedian, ReconstructionMethod::kDrizzle,
      ReconstructionMethod::kTikhonov,     ReconstructionMethod::kLinear,         ReconstructionMethod::kTotalVariation,
      ReconstructionMethod::kMap};
  return methods;
}

ReconstructionMethod ParseReconstructionMethod(const std::string& name) {
  std::string allowed;
  for (ReconstructionMethod m : ReconstructionMethods()) {
    if (name == ToString(m)) return m;
    allowed += (allowed.empty() ? "" : " | ") + std::string(ToString(m));
  }
  throw InvalidArgument("ParseReconstructionMethod", "method", name, allowed);
}

AutomaticRegularisation ChooseAutomaticRegularisation(const ReconstructionProblem& problem,
                                                      const ReconstructOptions& options) {
  problem.Validate("ChooseAutomaticRegularisation");
  std::string why;
  if (!options.tikhonov.IsValid(&why))
    throw InvalidArgument("ChooseAutomaticRegularisation: options.tikhonov." + why);
  const Pilot p = RunPilot(problem, options.tikhonov);
  return {p.tikhonov.summary.lambda, p.mu, p.contrast};
}

double EstimateSolveBytes(ReconstructionMethod method, int frames, double hr_pixels, bool weighted) {
  // HR-sized double arrays held at the peak. Every model-based method holds the model's N half spectra (N
  // arrays) and per-bin matrices of N x r² complex entries per LR frequency or the data's spectra (about N
  // more); then its own: Tikhonov's solution, right-hand side and spectra (the posterior std and the CG path
  // of weighted data add some), the linear method's target, kernels and noise probes, TV's ADMM variables and
  // its pilot, MAP's L-BFGS history.
  const double n = frames;
  double arrays = 0;
  switch (method) {
    // Peak RSS of `aosr reconstruct` at 1024² HR, N = 4 (less the process's 40 MB), in HR arrays: Tikhonov 21,
    // linear 29, TV 38, MAP 90 (Ceres's L-BFGS keeps its own copies), Drizzle 18. Weighted Tikhonov (the CG
    // path) and TV, whose pilot it is, measured at 1088² and 2176² HR, N = 4 (stop 44): 37-39 and 41 arrays.
    case ReconstructionMethod::kTikhonov: arrays = 2 * n + (weighted ? 32 : 14); break;
    case ReconstructionMethod::kLinear: arrays = 2 * n + (weighted ? 24 : 22); break;
    case ReconstructionMethod::kTotalVariation: arrays = 2 * n + 34; break;
    case ReconstructionMethod::kMap: arrays = 2 * n + 84; break;
    default: arrays = 2 * n + 12; break;
  }
  return 8.0 * arrays * hr_pixels;
}

Reconstruction Reconstruct(const ReconstructionProblem& problem, const ReconstructOptions& options) {
  problem.Validate(kReconstructFn);
  {
    const Shape hr = problem.model->hr_shape();
    CheckMemory(EstimateSolveBytes(options.method, problem.frame_count(), double(hr.rows) * double(hr.cols),
                                   !problem.HasUniformWeights()),
                std::string(kReconstructFn) + ": " + ToString(options.method) + " on the HR grid " + ToString(hr) + " from " +
                    std::to_string(problem.frame_count()) + " frames");
  }
  std::string why;
  const auto check = [&why](bool ok, const char* what) {
    if (!ok) throw InvalidArgument(std::string(kReconstructFn) + ": options." + what + "." + why);
  };
  const auto start = std::chrono::steady_clock::now();
  Reconstruction out;
  switch (options.method) {
    case ReconstructionMethod::kShiftAddMean:
    case ReconstructionMethod::kShiftAddMedian: {
      CheckArgument(problem.offsets.size() == problem.frames.size(), kReconstructFn, "problem.offsets",
                    std::to_string(problem.offsets.size()) + " entries", "one per frame for shift-and-add");
      out.image = ShiftAndAdd(problem,
                              options.method == ReconstructionMethod::kShiftAddMean ? Combine::kMean : Combine::kMedian,
                              &out.summary);
      WeightedDataMisfit(problem, out.image, &out.summary.frame_residual_rms);
      break;
    }
    case ReconstructionMethod::kDrizzle: {
      check(options.drizzle.IsValid(&why), "drizzle");
      DrizzleResult d = Drizzle(problem, options.drizzle);
      out.image = std::move(d.image);
      out.aux = std::move(d.weight);
      out.aux_name = "weight";
      out.summary = d.summary;
      // A NaN fill value is the astronomers' INDEF: keep it out of the misfit.
      if (AllFinite(out.image)) WeightedDataMisfit(problem, out.image, &out.summary.frame_residual_rms);
      break;
    }
    case ReconstructionMethod::kTikhonov: {
      check(options.tikhonov.IsValid(&why), "tikhonov");
      TikhonovOptions t = WithGcvLambda(problem, options.tikhonov);
      if (options.progress) t.progress = options.progress;
      TikhonovResult r = ReconstructTikhonov(problem, t);
      out.image = std::move(r.image);
      if (r.summary.std_computed) {
        out.aux = std::move(r.posterior_std);
        out.aux_name = "posterior-std";
      }
      out.regularisation = r.summary.lambda;
      out.summary = r.summary;
      if (t.lambda_rule != options.tikhonov.lambda_rule)
        out.summary.message += std::string("; λ by ") +
                               (options.tikhonov.lambda_rule == TikhonovLambdaRule::kGcv      ? "GCV"
                                : options.tikhonov.lambda_rule == TikhonovLambdaRule::kLcurve ? "the L-curve"
                                                                                              : "UPRE") +
                               " on the unweighted frames, scaled by the mean weight";
      break;
    }
    case ReconstructionMethod::kLinear: {
      check(options.linear.IsValid(&why), "linear");
      TargetPsfResult r = ReconstructTargetPsf(problem, options.linear);
      out.image = std::move(r.image);
      if (r.noise_std.size()) {
        out.aux = std::move(r.noise_std);
        out.aux_name = "noise-std";
      }
      out.effective_psf = std::move(r.effective_psf);
      out.noise_correlation = std::move(r.noise_correlation);
      out.leakage_spectrum = std::move(r.leakage_spectrum);
      out.regularisation = r.summary.kappa;
      out.summary = r.summary;
      out.linear = r.summary;
      break;
    }
    case ReconstructionMethod::kTotalVariation: {
      TotalVariationOptions tv = options.tv;
      if (options.progress) tv.progress = options.progress;
      Image initial;
      if (options.auto_regularisation) {
        bool cancelled = false;
        Pilot p = RunPilotStage(problem, options.tikhonov, options.fixed_automatic, tv.progress, &cancelled);
        if (cancelled) {
          CancelledAfterPilot(std::move(p), &out);
          break;
        }
        tv.mu = p.mu;
        initial = p.tikhonov.image;
      }
      check(tv.IsValid(&why), "tv");
      TotalVariationSummary s;
      out.image = TotalVariationAdmm(problem, tv, &s, initial.size() ? &initial : nullptr);
      out.regularisation = tv.mu;
      out.summary = s;
      break;
    }
    case ReconstructionMethod::kMap: {
      MapOptions m = options.map;
      if (options.progress) m.progress = options.progress;
      bool cancelled = false;
      Pilot p = RunPilotStage(problem, options.tikhonov,
                              options.auto_regularisation ? options.fixed_automatic : std::nullopt, m.progress,
                              &cancelled);
      if (cancelled) {
        CancelledAfterPilot(std::move(p), &out);
        break;
      }
      if (options.auto_regularisation) {
        m.lambda = 2 * p.mu;
        m.epsilon = 1e-3 * p.contrast;
        m.delta = 1e-3 * p.contrast;
      }
      check(m.IsValid(&why), "map");
      Image warm = p.tikhonov.image;
      if (m.positivity == MapPositivity::kSoftplus) warm = warm.max(0.0);
      MapResult r = MapReconstruct(problem, m, warm);
      out.image = std::move(r.image);
      out.regularisation = m.lambda;
      out.summary = r.summary;
      break;
    }
  }
  if (!AllFinite(out.image) &&
      !(options.method == ReconstructionMethod::kDrizzle && std::isnan(options.drizzle.fill_value))) {
    out.image.setZero();
    out.summary.termination = Termination::kFailed;
    out.summary.message = "non-finite estimate discarded (image zeroed): " + out.summary.message;
  }
  out.seconds_total = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return out;
}

}  // namespace aosr
