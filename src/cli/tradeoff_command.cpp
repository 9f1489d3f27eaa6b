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
#include "aosr/solvers/tradeoff.hpp"
#include "cli_util.hpp"
#include "commands.hpp"
#include "progress_bar.hpp"

namespace aosr::cli {
namespace {

namespace fs = std::filesystem;
using Row = TradeoffRow;
constexpr const char* kCmd = "aosr tradeoff";
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

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

std::string Fmt(const char* f, double v) {
  if (!std::isfinite(v)) return "—";
  char buf[64];
  std::snprintf(buf, sizeof buf, f, v);
  return buf;
}


std::string Markdown(const TradeoffArgs& a, const Dataset& d, const TradeoffSweep& sweep,
                     const std::vector<Row>& rows) {
  const bool truth = d.truth.has_value();
  const int crop_px = sweep.metric_crop_px;
  std::ostringstream os;
  os << "# Accuracy against time: " << a.dataset << "\n\n"
     << "Command: `" << CommandLine() << "` (aosr " << AOSR_VERSION << ", " << DefaultThreads()
     << " thread(s)).\n\n"
     << "Dataset: " << d.size() << " frames of " << ToString(d.frame) << " camera px, r = " << d.r << " (HR "
     << ToString(d.hr_frame) << "); weights: " << sweep.weights_source
     << (sweep.weights_source_linear != sweep.weights_source
             ? " (shift-add, drizzle, tikhonov: " + sweep.weights_source_linear + ")"
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
  // Options, checked before anything is read or computed (in the CLI's words).
  TradeoffOptions to;
  to.methods = a.methods;
  to.iterations = a.iterations;
  to.lambda_factors = a.lambda_factors;
  to.target_factors = a.target_factors;
  to.weights = ParseDatasetWeights(a.weights);
  CheckTradeoffOptions(to, [](const char* field) {
    std::string n = std::string("--") + field;
    std::replace(n.begin(), n.end(), '_', '-');
    return n;
  }, kCmd);
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
  EnsureDirectory(a.out_dir);
  const TradeoffSweep sweep = RunTradeoffSweep(
      d, to,
      [&](const std::string& m) {
        bar.Clear();
        progress.Step(m);
      },
      bar.Callback());
  bar.Clear();
  const std::vector<Row>& rows = sweep.rows;
  const std::vector<std::string>& methods = sweep.methods;
  // Outputs: the JSON, the picture, then the table that shows the picture.
  std::string name = fs::path(d.manifest_path).parent_path().filename().string();
  if (name.empty()) name = "dataset";
  nlohmann::json j = {{"command", CommandLine()},
                      {"dataset", a.dataset},
                      {"frames", d.size()},
                      {"r", d.r},
                      {"hr_shape", {d.hr_frame.rows, d.hr_frame.cols}},
                      {"weights", sweep.weights_source},
                      {"weights_linear_methods", sweep.weights_source_linear},
                      {"threads", DefaultThreads()},
                      {"has_truth", d.truth.has_value()},
                      {"metric_crop_px", d.truth ? nlohmann::json(sweep.metric_crop_px) : nlohmann::json(nullptr)},
                      {"outputs", {{"markdown", md_path}, {"json", json_path}, {"plot", png_path}}},
                      {"rows", nlohmann::json::array()}};
  for (const Row& r : rows) j["rows"].push_back(TradeoffRowJson(r));
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
  const std::string md = Markdown(a, d, sweep, rows);
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
