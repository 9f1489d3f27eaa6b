// `aosr tradeoff DATASET -o DIR`: the accuracy/time trade-off of every reconstructor on the user's own
// dataset, as a table (tradeoff.md), as data (tradeoff.json) and as a picture (tradeoff.png, io/plot.hpp).
//
// Each method runs through Reconstruct() (solvers/reconstruct.hpp) with the defaults of `aosr reconstruct`,
// over its knob:
//   shift-add, shift-add-median, drizzle   one run (no knob)
//   tikhonov                               λ by GCV, then fixed λ = f · λ_GCV for each --lambda-factors f
//                                          (the fixed runs skip the GCV search, so they are also its cost)
//   linear                                 the target-PSF output (target_psf.hpp), the science output: its
//                                          automatic target (leakage bound), then Gaussian targets of
//                                          FWHM f · FWHM_auto for each --target-factors f: resolution bought
//                                          with noise and leakage. Scored against the truth seen through its
//                                          own effective PSF (what it estimates), with the target and
//                                          effective FWHM, the noise RMS and the leakage per row
//   tv, map                                one run per --iterations cap, each from scratch (the Tikhonov
//   pilot,
//                                          which also sets their weight, is part of every run's time)
// Per row: termination, iterations, wall seconds (Reconstruction::seconds_total: warm start and automatic
// weight included), and
//   with a truth     PSNR, SSIM, RMSE (core/metrics.hpp) on the truth cropped by the dataset's trustworthy
//                    border, crop = trustworthy_border_px · r HR px, exactly as bench/reconstruct_bench.cpp
//                    scores (so the numbers agree with the bench; the crop falls back to 0 when it would
//                    leave less than the 11 px SSIM window, as `aosr reconstruct` does);
//   always           the method's own final objective (Summary::final_cost: not comparable across methods),
//   the
//                    data misfit as the reduced χ² = Σ w (y − A x)² / n_w over the n_w weighted pixels (≈ 1
//                    when the residual is at the noise level with true inverse-variance weights; comparable
//                    across methods), and the relative change ‖x_k − x_{k−1}‖ / ‖x_k‖ from the previous row
//                    of the same method (previous cap, or next smaller λ).
// The picture: PSNR [dB] and SSIM against wall seconds (log axis), one curve per method, the fixed-λ Tikhonov
// points labelled with their λ and the linear ones with their target FWHM; without a truth, the misfit and the
// relative change (both log) instead, and the titles say so.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <memory>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "aosr/core/error.hpp"
#include "aosr/core/metrics.hpp"
#include "aosr/core/operators.hpp"
#include "aosr/core/parallel.hpp"
#include "aosr/io/atomic_file.hpp"
#include "aosr/io/plot.hpp"
#include "aosr/scene/dataset.hpp"
#include "aosr/scene/evaluation.hpp"
#include "aosr/solvers/dataset_problem.hpp"
#include "aosr/solvers/reconstruct.hpp"
#include "cli_util.hpp"
#include "commands.hpp"
#include "progress_bar.hpp"

namespace aosr::cli {
namespace {

namespace fs = std::filesystem;
constexpr const char* kCmd = "aosr tradeoff";
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
const char* const kAllMethods[] = {"shift-add", "shift-add-median", "drizzle", "tikhonov", "linear", "tv", "map"};

struct TradeoffArgs {
  std::string dataset;
  std::string out_dir;
  std::vector<std::string> methods;  // empty: all
  std::vector<int> iterations = {10, 30, 100, 300};
  std::vector<double> lambda_factors = {0.01, 0.1, 10, 100};
  std::vector<double> target_factors = {0.9, 1.25, 1.5, 2.0};
  std::string weights = "auto";
  bool force = false;
  bool json = false;
  bool progress = false;  // --progress: progress on stderr even under --json or without a terminal
  ExecutionArgs exec;
};

struct Row {
  std::string method;
  std::string knob;             // human-readable knob setting, "-" for none
  double lambda_factor = kNaN;  // tikhonov: λ / λ_GCV (1 for the GCV row)
  int iteration_cap = 0;        // tv, map
  double target_factor = kNaN;  // linear: target FWHM / the automatic target's (1 for the automatic row)
  // linear: the target's and the effective PSF's FWHM [HR px], the output's noise RMS (frame units per HR
  // pixel) and its leakage U (target_psf.hpp).
  double target_fwhm = kNaN, effective_fwhm = kNaN, noise_rms = kNaN, leakage = kNaN;
  int iterations = 0;
  std::string termination, message;
  double seconds = 0, regularisation = 0;
  double psnr = kNaN, ssim = kNaN, rmse = kNaN;
  // After removing the global sub-pixel offset (scene/evaluation.hpp), and the offset [HR px, mas].
  double aligned_psnr = kNaN, aligned_ssim = kNaN, offset_dy = kNaN, offset_dx = kNaN, offset_dy_mas = kNaN,
         offset_dx_mas = kNaN;
  double objective = kNaN, misfit = kNaN, change = kNaN;
};

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

std::vector<std::string> Methods(const TradeoffArgs& a) {
  std::vector<std::string> out;
  const std::vector<std::string> asked =
      a.methods.empty() ? std::vector<std::string>(std::begin(kAllMethods), std::end(kAllMethods))
                        : a.methods;
  for (const std::string& m : asked) {
    if (std::find(std::begin(kAllMethods), std::end(kAllMethods), m) == std::end(kAllMethods))
      throw InvalidArgument(
          kCmd, "--methods", m,
          "a comma-separated list of shift-add, shift-add-median, drizzle, tikhonov, linear, tv, map");
    if (std::find(out.begin(), out.end(), m) == out.end()) out.push_back(m);
  }
  return out;
}

std::string Markdown(const TradeoffArgs& a, const Dataset& d, const DatasetProblem& dp,
                     const DatasetProblem& dp_photometric, int crop_px,
                     const std::vector<Row>& rows) {
  const bool truth = d.truth.has_value();
  std::ostringstream os;
  os << "# Accuracy against time: " << a.dataset << "\n\n"
     << "Command: `" << CommandLine() << "` (aosr " << AOSR_VERSION << ", " << DefaultThreads()
     << " thread(s)).\n\n"
     << "Dataset: " << d.size() << " frames of " << ToString(d.frame) << " camera px, r = " << d.r << " (HR "
     << ToString(d.hr_frame) << "); weights: " << dp.weights_source
     << (dp_photometric.weights_source != dp.weights_source
             ? " (shift-add, drizzle, tikhonov: " + dp_photometric.weights_source + ")"
             : std::string())
     << "; "
     << (truth ? "truth given: PSNR/SSIM (core/metrics.hpp, L = the cropped truth's range) on the truth " +
                     (crop_px > 0 ? "cropped by " + std::to_string(crop_px) +
                                        " HR px per side (the dataset's trustworthy border), as "
                                        "bench/reconstruct_bench.cpp scores."
                                  : std::string("uncropped: the trustworthy border (") +
                                        std::to_string(d.trustworthy_border_px * d.r) +
                                        " HR px) would leave less than the 11 px SSIM window.")
               : std::string(
                     "no truth in the dataset: PSNR/SSIM cannot be computed; judge by the data misfit and "
                     "the change between knob settings."))
     << "\n\n"
     << "Columns: time = Reconstruction::seconds_total (tv and map include their Tikhonov pilot; every run "
        "starts "
        "from scratch); objective = the method's own final cost (not comparable across methods); misfit = "
        "reduced "
        "chi^2, sum w (y - A x)^2 / n_w over the weighted pixels (about 1 at the noise level with true "
        "inverse-variance weights); change = |x_k - x_(k-1)| / |x_k| from the previous row of the same "
        "method "
        "(previous iteration cap, or the next smaller lambda). Wall times depend on the machine and its "
        "load.\n\n";
  if (truth)
    os << "Aligned PSNR/SSIM: after moving the estimate back by its global sub-pixel offset against the truth "
          "(upsampled cross-correlation, core/metrics.hpp CompareImagesAligned); offset = (dy, dx) in HR px"
       << (std::isfinite(rows.empty() ? kNaN : rows.front().offset_dy_mas) ? " and mas" : "")
       << ": an astrometric error, judged apart from resolution.\n\n";
  os << "| method | knob | iterations | termination | time [s] |"
     << (truth ? " PSNR [dB] | SSIM | aligned PSNR [dB] | aligned SSIM | offset [HR px] |" : "")
     << " objective | misfit | change |\n"
     << "|---|---|---:|---|---:|" << (truth ? "---:|---:|---:|---:|---:|" : "") << "---:|---:|---:|\n";
  for (const Row& r : rows) {
    os << "| " << r.method << " | " << r.knob << " | " << r.iterations << " | " << r.termination << " | "
       << Fmt("%.3f", r.seconds) << " | ";
    if (truth) {
      os << Fmt("%.2f", r.psnr) << " | " << Fmt("%.4f", r.ssim) << " | " << Fmt("%.2f", r.aligned_psnr) << " | "
         << Fmt("%.4f", r.aligned_ssim) << " | ";
      if (std::isfinite(r.offset_dy))
        os << Fmt("%+.3f", r.offset_dy) << ", " << Fmt("%+.3f", r.offset_dx)
           << (std::isfinite(r.offset_dy_mas) ? " (" + Fmt("%+.2f", r.offset_dy_mas) + ", " + Fmt("%+.2f", r.offset_dx_mas) + " mas)"
                                              : std::string())
           << " | ";
      else
        os << "— | ";
    }
    os << Fmt("%.4g", r.objective) << " | " << Fmt("%.4g", r.misfit) << " | " << Fmt("%.3g", r.change)
       << " |\n";
  }
  // The linear output's own knob: what each target costs in noise and leakage.
  bool any_linear = false;
  for (const Row& r : rows) any_linear = any_linear || r.method == "linear";
  if (any_linear) {
    os << "\nlinear (the target-PSF output): PSNR/SSIM above are against the truth seen through the row's own "
          "effective PSF, which is what the output estimates (not comparable with the other rows). Per target:\n\n"
       << "| target | target FWHM [HR px] | effective FWHM [HR px] | noise RMS | leakage U |"
       << (truth ? " PSNR through its PSF [dB] |" : "") << "\n|---|---:|---:|---:|---:|" << (truth ? "---:|" : "")
       << "\n";
    for (const Row& r : rows) {
      if (r.method != "linear") continue;
      os << "| " << r.knob << " | " << Fmt("%.2f", r.target_fwhm) << " | " << Fmt("%.2f", r.effective_fwhm) << " | "
         << Fmt("%.4g", r.noise_rms) << " | " << Fmt("%.3g", r.leakage) << " |"
         << (truth ? " " + Fmt("%.2f", r.psnr) + " |" : "") << "\n";
    }
  }
  os << "\n![accuracy against time](tradeoff.png)\n";
  return os.str();
}

nlohmann::json RowJson(const Row& r) {
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

std::vector<LinePlot> Panels(const std::string& name, bool truth, const std::vector<std::string>& methods,
                             const std::vector<Row>& rows) {
  LinePlot a, b;
  a.x.label = b.x.label = "wall time [s]";
  a.x.log = b.x.log = true;
  if (truth) {
    a.title = name + ": PSNR against wall time";
    a.y.label = "PSNR [dB]";
    b.title = name + ": SSIM against wall time";
    b.y.label = "SSIM";
  } else {
    a.title = name + " (no truth): data misfit against wall time";
    a.y.label = "misfit (reduced chi^2)";
    a.y.log = true;
    b.title = name + " (no truth): change from the previous knob";
    b.y.label = "relative change |x_k - x_k-1| / |x_k|";
    b.y.log = true;
  }
  // One curve per method; Tikhonov as two: the GCV run (it pays the λ search) and the fixed-λ sweep in
  // increasing λ (each one solve).
  const auto add = [&](const std::string& label, const auto& take, const auto& point_label) {
    PlotSeries sa, sb;
    sa.label = sb.label = label;
    for (const Row& r : rows) {
      if (!take(r)) continue;
      sa.point_labels.push_back(point_label(r));
      sb.point_labels.push_back(point_label(r));
      const double t = std::max(r.seconds, 1e-6);  // a log axis: a run faster than a microsecond sits at 1 us
      const auto positive = [](double v) { return v > 0 ? v : kNaN; };
      sa.x.push_back(t);
      sb.x.push_back(t);
      sa.y.push_back(truth ? r.psnr : positive(r.misfit));
      sb.y.push_back(truth ? r.ssim : positive(r.change));
    }
    a.series.push_back(sa);
    b.series.push_back(sb);
  };
  const auto none = [](const Row&) { return std::string(); };
  for (const std::string& m : methods) {
    if (m == "tikhonov") {
      add("tikhonov (GCV)", [](const Row& r) { return r.method == "tikhonov" && r.lambda_factor == 1.0; }, none);
      add("tikhonov (fixed lambda)", [](const Row& r) { return r.method == "tikhonov" && r.lambda_factor != 1.0; },
          [](const Row& r) { return "lambda " + Fmt("%.2g", r.regularisation); });
    } else if (m == "linear") {
      add(truth ? "linear (vs truth through its PSF)" : "linear (target widths)",
          [](const Row& r) { return r.method == "linear"; },
          [](const Row& r) { return "FWHM " + Fmt("%.1f", r.target_fwhm); });
    } else {
      add(m == "tv" || m == "map" ? m + " (iteration caps)" : m, [&m](const Row& r) { return r.method == m; }, none);
    }
  }
  return {a, b};
}

void RunTradeoff(const TradeoffArgs& a) {
  ApplyExecution(a.exec);
  const Progress progress(!a.json, a.progress);
  ProgressBar bar(ProgressBar::Choose(a.json, a.progress));
  // Options, checked before anything is read or computed.
  const std::vector<std::string> methods = Methods(a);
  std::vector<int> caps =
      a.iterations;  // increasing: the change column compares each cap with the one before
  for (int cap : caps)
    if (cap < 1 || cap > 1000000)
      throw InvalidArgument(kCmd, "--iterations", std::to_string(cap), "caps in 1..1000000");
  std::sort(caps.begin(), caps.end());
  caps.erase(std::unique(caps.begin(), caps.end()), caps.end());
  for (double f : a.lambda_factors)
    if (!(std::isfinite(f) && f > 0) || f == 1.0)
      throw InvalidArgument(kCmd, "--lambda-factors", ToString(f),
                            "finite factors > 0 other than 1 (the GCV row is always run)");
  for (double f : a.target_factors)
    if (!(std::isfinite(f) && f > 0 && f <= 10) || f == 1.0)
      throw InvalidArgument(kCmd, "--target-factors", ToString(f),
                            "finite factors in (0, 10] other than 1 (the automatic target's row is always run)");
  DatasetProblemOptions dpo;
  dpo.weights = ParseDatasetWeights(a.weights);
  const std::string md_path = JoinPath(a.out_dir, "tradeoff.md"),
                    json_path = JoinPath(a.out_dir, "tradeoff.json"),
                    png_path = JoinPath(a.out_dir, "tradeoff.png");
  const std::vector<std::string> outputs = {md_path, json_path, png_path};
  {
    std::error_code ec;
    if (fs::exists(a.out_dir, ec) && !fs::is_directory(a.out_dir, ec))
      throw IoError(a.out_dir, "exists and is not a directory");
    for (const std::string& p : outputs) {
      if (fs::is_directory(p, ec)) throw IoError(p, "is a directory; remove it or choose another -o");
      if (fs::exists(p, ec) && !a.force) throw IoError(p, "exists; pass --force to overwrite it");
    }
  }

  progress.Step("reading " + a.dataset);
  const Dataset d = LoadDataset(a.dataset);
  const std::set<fs::path> inputs = DatasetInputFiles(d);
  for (const std::string& p : outputs)
    if (inputs.count(fs::weakly_canonical(p)))
      throw InvalidArgument(kCmd, "-o", a.out_dir,
                            "a folder where no output (" + p + ") is one of the dataset's input files");
  // As `aosr reconstruct` does: `--weights auto` means background (source-independent) weights for the
  // linear methods (shift-add, drizzle, tikhonov) and the dataset's weights for tv and map (dataset_problem.hpp).
  DatasetProblemOptions dpo_model = dpo, dpo_photometric = dpo;
  dpo_model.method = ReconstructionMethod::kTotalVariation;
  dpo_photometric.method = ReconstructionMethod::kDrizzle;
  const DatasetProblem dp = ProblemFromDataset(d, dpo_model);
  const DatasetProblem dp_photometric = ProblemFromDataset(d, dpo_photometric);
  EnsureDirectory(a.out_dir);

  MetricOptions mo;
  mo.crop_px = int(d.trustworthy_border_px) * d.r;  // bench/reconstruct_bench.cpp's crop
  if (2 * mo.crop_px + kSsimWindow > std::min(d.hr_frame.rows, d.hr_frame.cols)) mo.crop_px = 0;

  std::vector<Row> rows;
  const double hr_mas = DatasetHrPixelMas(d);
  // One run: the row (without the change column) and its estimate.
  const auto run = [&](const std::string& method, ReconstructOptions o, Row row, Image* image) {
    o.method = ParseReconstructionMethod(method);
    const ReconstructionProblem& p = IsLinearMethod(o.method) ? dp_photometric.problem : dp.problem;
    progress.Step(method + " " + row.knob);
    o.progress = bar.Callback();
    Reconstruction rec = Reconstruct(p, o);
    bar.Clear();
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
  const auto append = [&](Row row, Image image, Image* previous) {
    if (previous->size() > 0 && previous->size() == image.size() && AllFinite(image) &&
        AllFinite(*previous)) {
      const double norm = image.matrix().norm();
      if (norm > 0) row.change = (image - *previous).matrix().norm() / norm;
    }
    rows.push_back(std::move(row));
    *previous = std::move(image);
  };

  for (const std::string& m : methods) {
    const ReconstructOptions o;
    Image previous, image;
    if (m == "tikhonov") {
      // GCV first: its λ anchors the sweep. Rows in increasing λ, the GCV row among them (factor 1).
      Row gcv_row;
      gcv_row.lambda_factor = 1.0;
      gcv_row.knob = "λ by GCV";
      Image gcv_image;
      gcv_row = run(m, o, gcv_row, &gcv_image);
      const double lambda_gcv = gcv_row.regularisation;
      gcv_row.knob = "λ by GCV = " + Fmt("%.3g", lambda_gcv);
      std::vector<double> factors = a.lambda_factors;
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
        Row row;
        row.lambda_factor = f;
        row.knob = "λ = " + Fmt("%g", f) + " × GCV = " + Fmt("%.3g", f * lambda_gcv);
        row = run(m, fixed, row, &image);
        append(row, std::move(image), &previous);
      }
    } else if (m == "linear") {
      // The automatic target first: its FWHM anchors the sweep. Rows in increasing target width.
      Row auto_row;
      auto_row.target_factor = 1.0;
      auto_row.knob = "target auto";
      Image auto_image;
      auto_row = run(m, o, auto_row, &auto_image);
      const double fwhm_auto = auto_row.target_fwhm;
      auto_row.knob = "target auto (FWHM " + Fmt("%.2f", fwhm_auto) + " HR px)";
      std::vector<double> factors = a.target_factors;
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
        Row row;
        row.target_factor = f;
        row.knob = "Gaussian FWHM " + Fmt("%g", f) + " × auto = " + Fmt("%.2f", f * fwhm_auto) + " HR px";
        row = run(m, gaussian, row, &image);
        append(row, std::move(image), &previous);
      }
    } else if (m == "tv" || m == "map") {
      for (int cap : caps) {
        ReconstructOptions capped = o;
        capped.tv.max_iterations = capped.map.max_iterations = cap;
        Row row;
        row.iteration_cap = cap;
        row.knob = "cap " + std::to_string(cap);
        row = run(m, capped, row, &image);
        append(row, std::move(image), &previous);
      }
    } else {
      Row row;
      row.knob = "—";
      row = run(m, o, row, &image);
      append(row, std::move(image), &previous);
    }
  }

  // Outputs: the JSON, the picture, then the table that shows the picture.
  std::string name = fs::path(d.manifest_path).parent_path().filename().string();
  if (name.empty()) name = "dataset";
  nlohmann::json j = {{"command", CommandLine()},
                      {"dataset", a.dataset},
                      {"frames", d.size()},
                      {"r", d.r},
                      {"hr_shape", {d.hr_frame.rows, d.hr_frame.cols}},
                      {"weights", dp.weights_source},
                      {"weights_linear_methods", dp_photometric.weights_source},
                      {"threads", DefaultThreads()},
                      {"has_truth", d.truth.has_value()},
                      {"metric_crop_px", d.truth ? nlohmann::json(mo.crop_px) : nlohmann::json(nullptr)},
                      {"outputs", {{"markdown", md_path}, {"json", json_path}, {"plot", png_path}}},
                      {"rows", nlohmann::json::array()}};
  for (const Row& r : rows) j["rows"].push_back(RowJson(r));
  progress.Step("writing " + a.out_dir);
  const std::string json_text = j.dump(2) + "\n";
  AtomicWrite(json_path, [&](const std::string& tmp) {
    std::FILE* f = std::fopen(tmp.c_str(), "wb");
    if (!f) throw IoError(json_path, "cannot open for writing");
    const bool ok = std::fwrite(json_text.data(), 1, json_text.size(), f) == json_text.size();
    if (std::fclose(f) != 0 || !ok) throw IoError(json_path, "cannot write");
  });
  FigureOptions fo;
  fo.columns = 2;
  WriteFigure(png_path, Panels(name, d.truth.has_value(), methods, rows), fo);
  const std::string md = Markdown(a, d, dp, dp_photometric, mo.crop_px, rows);
  AtomicWrite(md_path, [&](const std::string& tmp) {
    std::FILE* f = std::fopen(tmp.c_str(), "wb");
    if (!f) throw IoError(md_path, "cannot open for writing");
    const bool ok = std::fwrite(md.data(), 1, md.size(), f) == md.size();
    if (std::fclose(f) != 0 || !ok) throw IoError(md_path, "cannot write");
  });

  if (a.json) {
    std::printf("%s", json_text.c_str());
    return;
  }
  std::printf("%s\nwrote %s, %s and %s\n", md.c_str(), md_path.c_str(), json_path.c_str(), png_path.c_str());
}

}  // namespace

void RegisterTradeoff(CLI::App& app) {
  auto a = std::make_shared<TradeoffArgs>();
  CLI::App* cmd = app.add_subcommand(
      "tradeoff",
      "Accuracy against wall time of every reconstructor on a dataset: shift-add, shift-add-median, drizzle, "
      "tikhonov (GCV and fixed lambdas around it), linear (its automatic target and Gaussian targets around it, "
      "scored through its own PSF, with noise and leakage), tv and map (over iteration caps). Writes DIR/tradeoff.md "
      "(table and command line), DIR/tradeoff.json (the rows) and DIR/tradeoff.png (PSNR and SSIM against "
      "seconds; without a truth, the data misfit and the change between knob settings).");
  cmd->add_option("dataset", a->dataset, "dataset folder or manifest")->required();
  cmd->add_option("-o,--output", a->out_dir,
                  "output folder (created if needed; the dataset is never written)")
      ->required();
  cmd->add_option(
         "--methods", a->methods,
         "comma-separated subset of shift-add,shift-add-median,drizzle,tikhonov,linear,tv,map (default: all)")
      ->delimiter(',');
  cmd->add_option("--iterations", a->iterations, "comma-separated iteration caps of tv and map")
      ->delimiter(',')
      ->capture_default_str();
  cmd->add_option("--lambda-factors", a->lambda_factors,
                  "comma-separated multiples of the GCV lambda run as fixed-lambda Tikhonov")
      ->delimiter(',')
      ->capture_default_str();
  cmd->add_option("--target-factors", a->target_factors,
                  "linear: comma-separated multiples of the automatic target's FWHM run as Gaussian targets")
      ->delimiter(',')
      ->capture_default_str();
  cmd->add_option("--weights", a->weights,
                  "auto | dataset (inverse variances) | mask (uniform on valid pixels)")
      ->capture_default_str();
  cmd->add_flag("--force", a->force, "overwrite tradeoff.md/.json/.png if they exist");
  cmd->add_flag("--json", a->json, "print tradeoff.json to stdout instead of the table");
  cmd->add_flag(
      "--progress", a->progress,
      "show progress on stderr even with --json or when stderr is not a terminal (then as lines, at "
      "most one a second; by default it shows only on a terminal without --json)");
  AddExecutionOptions(cmd, &a->exec);
  cmd->callback([a] { RunTradeoff(*a); });
}

}  // namespace aosr::cli
