// `aosr design SCENE`: the N per-exposure DM offsets that minimise the expected reconstruction MSE (objective A,
// design/design_objective.hpp) or the mean MAP reconstruction loss over training scenes (objective B,
// design/design_empirical.hpp) for the scene's telescope, AO system, camera, r and N, written as a design file
// (design/design_file.hpp) that a scene loads with "offsets": {"type": "design", "file": ...}.
#include <cmath>
#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <utility>
#include <vector>

#include "aosr/calib/calibration_file.hpp"
#include "aosr/core/error.hpp"
#include "aosr/design/design_file.hpp"
#include "aosr/design/design_study.hpp"
#include "aosr/io/plot.hpp"
#include "aosr/scene/scene_spec.hpp"
#include "cli_util.hpp"
#include "commands.hpp"

namespace aosr::cli {
namespace {

struct DesignArgs {
  std::string scene;
  std::string output;
  std::string param = "zernike";
  int modes = 20;
  double rms_max_nm = 0.0;
  double strehl_min = 0.0;
  int starts = 3;
  int realisations = 2;
  int screens = 4;
  double lambda = 1e-2;
  std::string prior = "gradient";
  int iterations = 100;
  int threads = 2;
  std::uint64_t seed = 1;
  bool json = false;
  std::string calibration;
  std::string modes_plot;  // PNG of the modal content (design and raster); empty: none
  // Objective B (--objective B only).
  std::string objective = "A";
  std::string loss = "l1";
  int training_scenes = 3;
  std::vector<std::string> training;
  double training_zoom = 1.0;
  double noise_sigma = 0.04;
  int validation_realisations = 4;
  CLI::Option* noise_sigma_option = nullptr;
  double map_lambda = -1.0;  // < 0: automatic (below)
  double epsilon = 1e-3;
  std::string map_prior = "charbonnier-tv";
  double min_gain_db = 0.2;
  int sky_oversampling = 4;
  // Options given on the command line that belong to one objective only (checked in RunDesign).
  std::vector<std::pair<CLI::Option*, char>> objective_only;
  ExecutionArgs exec;
};

// The modal content as the seed paper draws it: per Noll mode, the RMS over the N offsets of the design and of
// the classic raster (markers joined by lines, log scale; the raster is tip and tilt only).
void WriteModesPlot(const std::string& path, const nlohmann::json& mc, const std::string& scene) {
  LinePlot p;
  p.title = "modal content of the offsets (" + scene + ")";
  p.x.label = "Noll index j";
  p.y.label = "RMS over the offsets [nm]";
  p.y.log = true;  // tip/tilt carry ~100x the rest: a log axis shows both (modes below 1e-3 nm are not drawn)
  const std::vector<int> noll = mc["noll"].get<std::vector<int>>();
  for (const auto& [label, rms] : {std::pair<std::string, nlohmann::json>{"design", mc["rms_over_frames_nm"]},
                                   {"raster", mc["raster"]["rms_over_frames_nm"]}}) {
    PlotSeries s;
    s.label = label;
    s.x.assign(noll.begin(), noll.end());
    s.y = rms.get<std::vector<double>>();
    for (double& v : s.y)
      if (!(v >= 1e-3)) v = std::numeric_limits<double>::quiet_NaN();
    p.series.push_back(s);
  }
  FigureOptions f;
  f.columns = 1;
  WriteFigure(path, {p}, f);
}

void RunDesign(const DesignArgs& a) {
  ExecutionArgs exec = a.exec;
  exec.threads = a.threads;
  ApplyExecution(exec);
  for (const auto& [option, objective] : a.objective_only)
    if (option->count() > 0 && a.objective[0] != objective)
      throw InvalidArgument("aosr design", option->get_name(), "given with --objective " + a.objective,
                            std::string("only with --objective ") + objective);
  if (a.objective == "B" && !a.training.empty() && a.objective_only[0].first->count() > 0)
    throw InvalidArgument("aosr design", "--training-scenes", std::to_string(a.training_scenes),
                          "not with --training (the files are the training scenes)");
  if (a.objective == "A" && a.training.empty() && a.noise_sigma_option->count() > 0)
    throw InvalidArgument("aosr design", "--noise-sigma", ToString(a.noise_sigma),
                          "with --objective B, or with --training (objective A's Wiener design); without a fitted "
                          "spectrum objective A's design does not depend on the noise");
  const Progress progress(!a.json);
  Stopwatch clock;
  if (!a.output.empty()) CheckWritableFile(a.output);
  if (!a.modes_plot.empty()) CheckWritableFile(a.modes_plot);
  std::error_code ec;
  if (!a.modes_plot.empty() && (a.modes_plot == a.output || std::filesystem::equivalent(a.modes_plot, a.scene, ec)))
    throw InvalidArgument("aosr design", "--modes-plot", a.modes_plot, "a file other than the scene and -o's design file");
  const SceneSpec scene = LoadScene(a.scene);

  DesignStudyOptions so;
  so.param = a.param;
  so.modes = a.modes;
  so.rms_max_nm = a.rms_max_nm;
  so.strehl_min = a.strehl_min;
  so.starts = a.starts;
  so.realisations = a.realisations;
  so.screens = a.screens;
  so.lambda = a.lambda;
  so.prior = a.prior;
  so.iterations = a.iterations;
  so.threads = a.threads;
  so.seed = a.seed;
  so.objective = a.objective;
  so.loss = a.loss;
  so.training_scenes = a.training_scenes;
  so.training = a.training;
  so.training_zoom = a.training_zoom;
  so.noise_sigma = a.noise_sigma;
  so.validation_realisations = a.validation_realisations;
  so.map_lambda = a.map_lambda;
  so.epsilon = a.epsilon;
  so.map_prior = a.map_prior;
  so.min_gain_db = a.min_gain_db;
  so.sky_oversampling = a.sky_oversampling;
  // The study itself is the library's (design/design_study.hpp), shared with the Python aosr.design().
  DesignStudy study = RunDesignStudy(scene, so, [&progress](const std::string& m) { progress.Step(m); });
  const DesignResult& result = study.result;
  const std::vector<DesignFrameReport>& reports = study.reports;
  nlohmann::json& file = study.file;
  if (!a.calibration.empty()) {
    // The frames become the commands that make a DM with the calibrated gains apply the design; the designed
    // (applied) offsets stay in the provenance.
    std::vector<std::string> notes;
    ApplyCalibrationToDesignFile(a.calibration, result.offsets, &file, &notes);
    for (const std::string& n : notes) progress.Step("calibration: " + n);
  }
  if (!a.output.empty()) WriteDesignFile(a.output, file);
  if (!a.modes_plot.empty()) WriteModesPlot(a.modes_plot, file["design"]["modal_content"], scene.name);
  const DesignSummary& s = result.summary;

  if (a.json) {
    nlohmann::json j = study.summary;
    j["total_seconds"] = clock.Seconds();
    j["output"] = a.output.empty() ? nlohmann::json() : nlohmann::json(a.output);
    j["design"] = file;
    std::printf("%s\n", j.dump(2).c_str());
    return;
  }
  std::printf("aosr design: scene %s, N = %d, r = %d, %s offsets, AO model %s, %d realisation(s) x %d screens, "
              "grid %lld HR px\n",
              scene.name.c_str(), scene.frames, scene.r, s.parameterisation.c_str(), study.ao ? "analytic" : "none",
              study.realisations, a.screens, static_cast<long long>(study.grid));
  std::printf("objective %s (%s)\n%s\n%s\n", a.objective.c_str(), study.method.c_str(), s.FullReport().c_str(),
              s.message.c_str());
  if (!study.last_evaluation.empty()) std::printf("last evaluation: %s\n", study.last_evaluation.c_str());
  std::printf("%-6s %10s %10s %9s %9s %10s\n", "frame", "dy [px]", "dx [px]", "rms [nm]", "Strehl", "zernikes");
  for (std::size_t i = 0; i < result.offsets.size(); ++i) {
    const DmOffset& o = result.offsets[i];
    const std::size_t terms = o.actuators_m.empty() ? o.zernike.size() : o.actuators_m.size();
    std::printf("%-6zu %10.4f %10.4f %9.1f %9.4f %10zu\n", i, o.shift_y_px, o.shift_x_px, reports[i].rms_m * 1e9,
                reports[i].strehl, terms);
  }
  // Modal content: the modes carrying at least 1 % of the largest RMS over the offsets (file: every mode).
  const nlohmann::json& mc = file["design"]["modal_content"];
  const std::vector<double> rms = mc["rms_over_frames_nm"].get<std::vector<double>>();
  const double top = rms.empty() ? 0.0 : *std::max_element(rms.begin(), rms.end());
  const std::vector<double> beyond = mc["beyond_nm"].get<std::vector<double>>();
  std::string modes;
  char buf[32];
  for (std::size_t k = 0; k < rms.size(); ++k) {
    if (!(top > 0 && rms[k] >= 0.01 * top)) continue;
    std::snprintf(buf, sizeof buf, "Z%zu %.3g", k + 2, rms[k]);
    modes += (modes.empty() ? "" : ", ") + std::string(buf);
  }
  std::printf("modal content, RMS over the offsets per Noll mode [nm]: %s (beyond Z%d: at most %.3g nm)\n",
              modes.empty() ? "none" : modes.c_str(), kModalContentNoll,
              beyond.empty() ? 0.0 : *std::max_element(beyond.begin(), beyond.end()));
  const DesignGain& g = study.gain;
  std::printf("expected gain over the raster: %s\nbasis: %s\nadvice: %s: %s\n",
              g.BriefReport().substr(0, g.BriefReport().find(" (")).c_str(), g.basis.c_str(),
              g.advice == "design" ? "use the design" : "keep the raster", g.reason.c_str());
  if (g.sky_oversampling > 1 && std::isfinite(g.hr_sky_db))
    std::printf("on the HR grid's own sky (what objective A optimises): %+.2f dB; the advice is judged on the sky %dx "
                "finer (--sky-oversampling)\n", g.hr_sky_db, g.sky_oversampling);
  if (g.sky_oversampling > 1)
    // The error bar of this prediction, measured: bench/results/design_continuous_sky.md (rerun it after changing
    // objective A, its check or the reconstructors, and update these figures).
    std::printf("how far off it can be: on held-out skies 4x finer than the HR grid, GCV-Tikhonov reconstructions gained "
                "between 1.1 dB less and 0.5 dB more than this prediction in the five cells measured, TV between 2.7 dB "
                "less and 1.7 dB more (bench/results/design_continuous_sky.md)\n");
  std::printf("total %.2f s%s\n", clock.Seconds(), a.output.empty() ? "" : ("; design written to " + a.output).c_str());
}

}  // namespace

void RegisterDesign(CLI::App& app) {
  auto a = std::make_shared<DesignArgs>();
  CLI::App* cmd = app.add_subcommand(
      "design",
      "Design the N per-exposure DM offsets of a scene (telescope, AO, camera, r, N) that minimise the expected "
      "MSE of the Tikhonov/Wiener reconstruction (objective A: closed form per frequency, averaged over AO PSF "
      "realisations, with the PSF mismatch of the reconstructor's nominal model counted) or the mean loss of the "
      "MAP reconstruction of training scenes (objective B), by L-BFGS from the classic raster and perturbed starts. -o writes a design file that scenes load with "
      "\"offsets\": {\"type\": \"design\", \"file\": ...}.");
  cmd->add_option("scene", a->scene, "scene file (.json)")->required();
  cmd->add_option("-o,--output", a->output, "write the design file (JSON) here");
  cmd->add_option("--modes-plot", a->modes_plot,
                  "write a PNG of the offsets' modal content: per Noll mode, the RMS over the N offsets of the design "
                  "and of the raster (the design file holds the numbers)");
  cmd->add_option("--calibration", a->calibration,
                  "calibration.json (aosr calibrate): write the commands that make the calibrated DM apply the design")
      ->check(CLI::ExistingFile);
  cmd->add_option("--param", a->param, "parameterisation: raster (evaluate only), tiptilt, zernike or actuators")
      ->check(CLI::IsMember({"raster", "tiptilt", "zernike", "actuators"}))
      ->capture_default_str();
  cmd->add_option("--modes", a->modes, "Zernike modes per exposure (Noll 2 .. J+1)")->check(CLI::Range(2, 200))->capture_default_str();
  cmd->add_option("--rms-max", a->rms_max_nm, "bound on each offset's pupil RMS [nm]; 0: none")
      ->check(NonNegativeFinite())
      ->capture_default_str();
  cmd->add_option("--strehl-min", a->strehl_min, "lower bound on the Strehl each offset keeps (tip/tilt excluded); 0: none")
      ->check(CLI::Range(0.0, 0.999))
      ->capture_default_str();
  cmd->add_option("--starts", a->starts, "optimiser starts (the raster, then perturbed copies)")->check(CLI::Range(1, 64))->capture_default_str();
  cmd->add_option("--realisations", a->realisations, "AO PSF realisations averaged (0: frames follow the nominal model)")
      ->check(CLI::Range(0, 64))
      ->capture_default_str();
  cmd->add_option("--screens", a->screens, "residual phase screens averaged per exposure and realisation")
      ->check(CLI::Range(1, 256))
      ->capture_default_str();
  cmd->add_option("--lambda", a->lambda, "Tikhonov lambda of the reconstructor (unit noise weights)")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  cmd->add_option("--prior", a->prior, "reconstructor prior: identity, gradient, laplacian or power-spectrum")
      ->check(CLI::IsMember({"identity", "gradient", "laplacian", "power-spectrum"}))
      ->capture_default_str();
  cmd->add_option("--iterations", a->iterations, "L-BFGS iterations per start")->check(CLI::Range(1, 100000))->capture_default_str();
  cmd->add_option("--threads", a->threads, "threads for the PSFs and their gradients")->check(CLI::Range(1, 64))->capture_default_str();
  cmd->add_option("--seed", a->seed, "seed of the residual screens and the perturbed starts")->capture_default_str();
  cmd->add_flag("--json", a->json, "print the summary and the design as JSON (no progress messages)");
  cmd->add_option("--objective", a->objective,
                  "A: closed-form expected Tikhonov MSE; B: mean MAP reconstruction loss over training scenes "
                  "(implicit gradient; slower, to confirm or refine A)")
      ->check(CLI::IsMember({"A", "B"}))
      ->capture_default_str();
  // Objective B only (the first entry is --training-scenes, checked against --training).
  a->objective_only.push_back(
      {cmd->add_option("--training-scenes", a->training_scenes, "objective B: dead-leaves training scenes K")
           ->check(CLI::Range(1, 64))
           ->capture_default_str(),
       'B'});
  cmd->add_option("--training", a->training,
                  "training images (PNG/TIFF/FITS; pixels taken as HR pixels, scaled to peak 1). Objective A: fit "
                  "their power spectrum and design for the matching Wiener reconstructor; objective B: the "
                  "training scenes")
      ->check(CLI::ExistingFile);
  a->objective_only.push_back(
      {cmd->add_option("--training-zoom", a->training_zoom,
                       "objective B: source pixels per HR pixel of the --training crops")
           ->check(CLI::PositiveNumber)
           ->capture_default_str(),
       'B'});
  a->objective_only.push_back({cmd->add_option("--loss", a->loss, "objective B: loss, l1 (smoothed) or l2")
                                   ->check(CLI::IsMember({"l1", "l2"}))
                                   ->capture_default_str(),
                               'B'});
  a->noise_sigma_option = cmd->add_option("--noise-sigma", a->noise_sigma,
                  "noise sigma per LR pixel for scenes of peak 1 (objective B; objective A with --training)")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  cmd->add_option("--validation-realisations", a->validation_realisations,
                  "AO PSF realisations (fresh seed) on which the design must beat the raster, else the raster "
                  "is kept (objective B: also fresh noise and 3 fresh dead-leaves scenes); 0: no check")
      ->check(CLI::Range(0, 64))
      ->capture_default_str();
  a->objective_only.push_back(
      {cmd->add_option("--map-prior", a->map_prior, "objective B: MAP prior, charbonnier-tv or tikhonov")
           ->check(CLI::IsMember({"charbonnier-tv", "tikhonov"}))
           ->capture_default_str(),
       'B'});
  a->objective_only.push_back(
      {cmd->add_option("--map-lambda", a->map_lambda,
                       "objective B: MAP lambda (weights 1/sigma^2); default: 1/sigma for the TV prior (the weight "
                       "aosr reconstruct -m map chooses), 1 for tikhonov")
           ->check(NonNegativeFinite()),
       'B'});
  a->objective_only.push_back(
      {cmd->add_option("--epsilon", a->epsilon, "objective B: Charbonnier epsilon of the MAP prior (1e-3: aosr reconstruct's 1e-3 x contrast at peak 1)")
           ->check(CLI::PositiveNumber)
           ->capture_default_str(),
       'B'});
  cmd->add_option("--min-gain", a->min_gain_db,
                  "smallest expected gain over the raster [dB] for which the design is advised and kept (it must also "
                  "exceed 2 standard errors over the validation realisations); else the raster is kept")
      ->check(NonNegativeFinite())
      ->capture_default_str();
  cmd->add_option("--sky-oversampling", a->sky_oversampling,
                  "objective A: judge the design on frames of a sky this many times finer than the HR grid, a stand-in "
                  "for a real sky (the optimiser works on the HR grid's own sky, which overstates designs that only "
                  "move the PSFs against that grid); 1: on the HR grid's sky")
      ->check(CLI::Range(1, 16))
      ->capture_default_str();
  // Objective A only.
  for (CLI::Option* o : {cmd->get_option("--lambda"), cmd->get_option("--prior"), cmd->get_option("--sky-oversampling")})
    a->objective_only.push_back({o, 'A'});
  AddExecutionOptions(cmd, &a->exec, /*with_threads=*/false);
  cmd->callback([a] { RunDesign(*a); });
}

}  // namespace aosr::cli
