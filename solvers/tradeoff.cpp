#include "aosr/solvers/tradeoff.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "aosr/core/error.hpp"
#include "aosr/core/metrics.hpp"
#include "aosr/core/operators.hpp"
#include "aosr/scene/evaluation.hpp"
#include "aosr/solvers/reconstruct.hpp"

namespace aosr {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

std::string Fmt(const char* f, double v) {
  if (!std::isfinite(v)) return "—";
  char buf[64];
  std::snprintf(buf, sizeof buf, f, v);
  return buf;
}

nlohmann::json Number(double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr); }

// Reduced χ²: Σ w (y − A x)² over the number of weighted pixels.
double ReducedChiSquare(const ReconstructionProblem& p, const Image& x) {
  Index n = 0;
  for (int i = 0; i < p.frame_count(); ++i) n += (p.Weight(i).array() > 0).count();
  return n > 0 ? 2.0 * WeightedDataMisfit(p, x) / double(n) : kNaN;
}

}  // namespace

void CheckTradeoffOptions(const TradeoffOptions& o, const std::function<std::string(const char* field)>& name,
                          const char* caller) {
  const std::vector<std::string>& all = TradeoffMethods();
  for (const std::string& m : o.methods)
    if (std::find(all.begin(), all.end(), m) == all.end())
      throw InvalidArgument(caller, name("methods"), m,
                            "a list of shift-add, shift-add-median, drizzle, tikhonov, linear, tv, map");
  for (int cap : o.iterations)
    if (cap < 1 || cap > 1000000) throw InvalidArgument(caller, name("iterations"), std::to_string(cap), "caps in 1..1000000");
  for (double f : o.lambda_factors)
    if (!(std::isfinite(f) && f > 0) || f == 1.0)
      throw InvalidArgument(caller, name("lambda_factors"), ToString(f),
                            "finite factors > 0 other than 1 (the GCV row is always run)");
  for (double f : o.target_factors)
    if (!(std::isfinite(f) && f > 0 && f <= 10) || f == 1.0)
      throw InvalidArgument(caller, name("target_factors"), ToString(f),
                            "finite factors in (0, 10] other than 1 (the automatic target's row is always run)");
}

TradeoffSweep RunTradeoffSweep(const Dataset& d, const TradeoffOptions& options,
                               const std::function<void(const std::string&)>& step, const ProgressCallback& progress) {
  CheckTradeoffOptions(options, [](const char* f) { return std::string("options.") + f; }, "RunTradeoffSweep");
  TradeoffSweep out;
  for (const std::string& m : options.methods.empty() ? TradeoffMethods() : options.methods)
    if (std::find(out.methods.begin(), out.methods.end(), m) == out.methods.end()) out.methods.push_back(m);
  std::vector<int> caps = options.iterations;  // increasing: the change column compares each cap with the one before
  std::sort(caps.begin(), caps.end());
  caps.erase(std::unique(caps.begin(), caps.end()), caps.end());
  // As `aosr reconstruct` does: `auto` means background (source-independent) weights for the linear methods
  // (shift-add, drizzle, tikhonov) and the dataset's weights for tv and map (dataset_problem.hpp).
  DatasetProblemOptions dpo_model, dpo_photometric;
  dpo_model.weights = dpo_photometric.weights = options.weights;
  dpo_model.method = ReconstructionMethod::kTotalVariation;
  dpo_photometric.method = ReconstructionMethod::kDrizzle;
  const DatasetProblem dp = ProblemFromDataset(d, dpo_model);
  const DatasetProblem dp_photometric = ProblemFromDataset(d, dpo_photometric);
  out.weights_source = dp.weights_source;
  out.weights_source_linear = dp_photometric.weights_source;
  out.has_truth = d.truth.has_value();

  MetricOptions mo;
  mo.crop_px = int(d.trustworthy_border_px) * d.r;  // bench/reconstruct_bench.cpp's crop
  if (2 * mo.crop_px + kSsimWindow > std::min(d.hr_frame.rows, d.hr_frame.cols)) mo.crop_px = 0;

  std::vector<TradeoffRow>& rows = out.rows;
  const double hr_mas = DatasetHrPixelMas(d);
  // One run: the row (without the change column) and its estimate.
  const auto run = [&](const std::string& method, ReconstructOptions o, TradeoffRow row, Image* image) {
    o.method = ParseReconstructionMethod(method);
    const ReconstructionProblem& p = IsLinearMethod(o.method) ? dp_photometric.problem : dp.problem;
    if (step) step(method + " " + row.knob);
    o.progress = progress;
    Reconstruction rec = Reconstruct(p, o);
    if (rec.summary.termination == Termination::kUserCancelled) out.cancelled = true;
    row.method = method;
    row.iterations = rec.summary.iterations;
    row.termination = ToString(rec.summary.termination);
    row.message = rec.summary.message;
    row.seconds = rec.seconds_total;
    row.regularisation = rec.regularisation;
    // The baselines minimise nothing: their final_cost is a placeholder 0.
    const bool has_objective = method == "tikhonov" || method == "tv" || method == "map";
    row.objective = has_objective ? rec.summary.final_cost : kNaN;
    if (AllFinite(rec.image)) {
      row.misfit = ReducedChiSquare(p, rec.image);
      if (rec.linear) {
        row.target_fwhm = rec.linear->target_fwhm_hr_px;
        row.effective_fwhm = rec.linear->effective_fwhm_hr_px;
        row.noise_rms = rec.linear->noise_rms;
        row.leakage = rec.linear->leakage;
      }
      if (d.truth) {
        EvaluationOptions eo;
        eo.crop_px = mo.crop_px;
        eo.hr_pixel_mas = hr_mas;
        // The linear output estimates the truth seen through its effective PSF, sky included: scored against
        // that, its sky level subtracted (as `aosr reconstruct` scores it: against_truth_through_psf).
        eo.subtract_sky = rec.linear.has_value();
        const Image seen = rec.effective_psf.size() > 0
                               ? ToImage(PeriodicConvolutionFromKernel(d.hr_frame, rec.effective_psf)
                                             ->Apply(AsVector(*d.truth)),
                                         d.hr_frame)
                               : *d.truth;
        const Evaluation ev = EvaluateReconstruction(seen, rec.image, {}, eo);
        row.psnr = ev.metrics.psnr;
        row.ssim = ev.metrics.ssim;
        row.rmse = ev.metrics.rmse;
        row.aligned_psnr = ev.aligned.psnr;
        row.aligned_ssim = ev.aligned.ssim;
        row.offset_dy = ev.offset.dy;
        row.offset_dx = ev.offset.dx;
        if (ev.offset_mas_known) row.offset_dy_mas = ev.offset_mas[0], row.offset_dx_mas = ev.offset_mas[1];
      }
    }
    *image = std::move(rec.image);
    return row;
  };
  // Appends a row of a knob sweep, with its change from the sweep's previous estimate (empty: the first).
  const auto append = [&](TradeoffRow row, Image image, Image* previous) {
    if (previous->size() > 0 && previous->size() == image.size() && AllFinite(image) &&
        AllFinite(*previous)) {
      const double norm = image.matrix().norm();
      if (norm > 0) row.change = (image - *previous).matrix().norm() / norm;
    }
    rows.push_back(std::move(row));
    *previous = std::move(image);
  };

  for (const std::string& m : out.methods) {
    if (out.cancelled) break;
    const ReconstructOptions o;
    Image previous, image;
    if (m == "tikhonov") {
      // GCV first: its λ anchors the sweep. Rows in increasing λ, the GCV row among them (factor 1).
      TradeoffRow gcv_row;
      gcv_row.lambda_factor = 1.0;
      gcv_row.knob = "λ by GCV";
      Image gcv_image;
      gcv_row = run(m, o, gcv_row, &gcv_image);
      const double lambda_gcv = gcv_row.regularisation;
      gcv_row.knob = "λ by GCV = " + Fmt("%.3g", lambda_gcv);
      std::vector<double> factors = options.lambda_factors;
      factors.push_back(1.0);
      std::sort(factors.begin(), factors.end());
      factors.erase(std::unique(factors.begin(), factors.end()), factors.end());
      for (double f : factors) {
        if (f == 1.0) {
          append(gcv_row, gcv_image, &previous);
          continue;
        }
        ReconstructOptions fixed = o;
        fixed.tikhonov.lambda_rule = TikhonovLambdaRule::kFixed;
        fixed.tikhonov.lambda = f * lambda_gcv;
        TradeoffRow row;
        row.lambda_factor = f;
        row.knob = "λ = " + Fmt("%g", f) + " × GCV = " + Fmt("%.3g", f * lambda_gcv);
        row = run(m, fixed, row, &image);
        append(row, std::move(image), &previous);
      }
    } else if (m == "linear") {
      // The automatic target first: its FWHM anchors the sweep. Rows in increasing target width.
      TradeoffRow auto_row;
      auto_row.target_factor = 1.0;
      auto_row.knob = "target auto";
      Image auto_image;
      auto_row = run(m, o, auto_row, &auto_image);
      const double fwhm_auto = auto_row.target_fwhm;
      auto_row.knob = "target auto (FWHM " + Fmt("%.2f", fwhm_auto) + " HR px)";
      std::vector<double> factors = options.target_factors;
      factors.push_back(1.0);
      std::sort(factors.begin(), factors.end());
      factors.erase(std::unique(factors.begin(), factors.end()), factors.end());
      for (double f : factors) {
        if (f == 1.0 || !(fwhm_auto > 0)) {
          if (f == 1.0) append(auto_row, auto_image, &previous);
          continue;
        }
        ReconstructOptions gaussian = o;
        gaussian.linear.kind = TargetPsfKind::kGaussian;
        gaussian.linear.fwhm_hr_px = f * fwhm_auto;
        TradeoffRow row;
        row.target_factor = f;
        row.knob = "Gaussian FWHM " + Fmt("%g", f) + " × auto = " + Fmt("%.2f", f * fwhm_auto) + " HR px";
        row = run(m, gaussian, row, &image);
        append(row, std::move(image), &previous);
      }
    } else if (m == "tv" || m == "map") {
      for (int cap : caps) {
        ReconstructOptions capped = o;
        capped.tv.max_iterations = capped.map.max_iterations = cap;
        TradeoffRow row;
        row.iteration_cap = cap;
        row.knob = "cap " + std::to_string(cap);
        row = run(m, capped, row, &image);
        append(row, std::move(image), &previous);
      }
    } else {
      TradeoffRow row;
      row.knob = "—";
      row = run(m, o, row, &image);
      append(row, std::move(image), &previous);
    }
  }

  out.metric_crop_px = mo.crop_px;
  return out;
}

nlohmann::json TradeoffRowJson(const TradeoffRow& r) {
  nlohmann::json j = {{"method", r.method},
                      {"knob", r.knob},
                      {"iterations", r.iterations},
                      {"termination", r.termination},
                      {"message", r.message},
                      {"seconds", r.seconds},
                      {"regularisation", r.regularisation},
                      {"psnr_db", Number(r.psnr)},
                      {"ssim", Number(r.ssim)},
                      {"rmse", Number(r.rmse)},
                      {"aligned", {{"psnr_db", Number(r.aligned_psnr)}, {"ssim", Number(r.aligned_ssim)}}},
                      {"offset_hr_px", {{"dy", Number(r.offset_dy)}, {"dx", Number(r.offset_dx)}}},
                      {"offset_mas", std::isfinite(r.offset_dy_mas)
                                         ? nlohmann::json{{"dy", r.offset_dy_mas}, {"dx", r.offset_dx_mas}}
                                         : nlohmann::json(nullptr)},
                      {"objective", Number(r.objective)},
                      {"misfit", Number(r.misfit)},
                      {"change", Number(r.change)}};
  if (std::isfinite(r.lambda_factor)) j["lambda_factor"] = r.lambda_factor;
  if (r.iteration_cap > 0) j["iteration_cap"] = r.iteration_cap;
  if (r.method == "linear") {
    j["target_factor"] = Number(r.target_factor);
    j["target_fwhm_hr_px"] = Number(r.target_fwhm);
    j["effective_fwhm_hr_px"] = Number(r.effective_fwhm);
    j["noise_rms"] = Number(r.noise_rms);
    j["leakage"] = Number(r.leakage);
    j["scored_through"] = "its effective PSF";
  }
  return j;
}

}  // namespace aosr
