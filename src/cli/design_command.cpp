// `aosr design SCENE`: the N per-exposure DM offsets that minimise the expected reconstruction MSE (objective A,
// design/design_objective.hpp) or the mean MAP reconstruction loss over training scenes (objective B,
// design/design_empirical.hpp) for the scene's telescope, AO system, camera, r and N, written as a design file
// (design/design_file.hpp) that a scene loads with "offsets": {"type": "design", "file": ...}.
#include <cstdio>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <utility>
#include <vector>

#include "aosr/calib/calibration_file.hpp"
#include "aosr/core/error.hpp"
#include "aosr/design/design_empirical.hpp"
#include "aosr/design/design_file.hpp"
#include "aosr/design/design_objective.hpp"
#include "aosr/design/design_optimizer.hpp"
#include "aosr/design/design_parameterisation.hpp"
#include "aosr/design/power_spectrum_fit.hpp"
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
  // Options given on the command line that belong to one objective only (checked in RunDesign).
  std::vector<std::pair<CLI::Option*, char>> objective_only;
  ExecutionArgs exec;
};

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
  const SceneSpec scene = LoadScene(a.scene);

  DesignParameterisationOptions po;
  po.kind = ParseDesignParameterisation(a.param);
  po.zernike_modes = a.modes;
  po.rms_max_m = a.rms_max_nm * 1e-9;
  po.strehl_min = a.strehl_min;
  DesignObjectiveOptions oo;
  oo.reconstructor.prior = ParseTikhonovPrior(a.prior);
  oo.reconstructor.lambda = a.lambda;
  oo.realisations = a.realisations;
  oo.screens = a.screens;
  oo.seed = a.seed;
  oo.threads = a.threads;
  DesignOptimizerOptions opt;
  opt.starts = a.starts;
  opt.max_iterations = a.iterations;
  opt.seed = a.seed;
  opt.progress = [&progress](const std::string& m) { progress.Step(m); };

  progress.Step("building the design model of " + scene.name + ": N = " + std::to_string(scene.frames) +
                ", r = " + std::to_string(scene.r));
  const DesignOptics optics = DesignOpticsFromScene(scene);
  std::unique_ptr<DesignCriterion> criterion;
  const EmpiricalDesignObjective* empirical = nullptr;
  nlohmann::json spectrum_record;  // objective A with --training: the fitted spectrum, for the file and --json
  EmpiricalDesignOptions eo;       // objective B's options (also its validation's)
  if (a.objective == "A") {
    if (!a.training.empty()) {
      // The Wiener variant: the object spectrum fitted to the training images (peak 1, their pixels as HR
      // pixels) and the Tikhonov power-spectrum prior that is its Wiener reconstructor for this noise.
      PowerSpectrumFitOptions fo;
      fo.grid = optics.grid;
      fo.scaling = TrainingScaling::kPeak;
      fo.scale_value = 1.0;
      const PowerSpectrumFit fit = FitPowerSpectrum(LoadTrainingImages(a.training), fo);
      oo.reconstructor = WienerPriorOptions(fit.model, a.noise_sigma, {optics.grid, optics.grid});
      oo.noise_sigma = a.noise_sigma;
      progress.Step("objective A, Wiener: spectrum of " + std::to_string(a.training.size()) + " training image(s): " +
                    fit.BriefReport());
      spectrum_record = {{"files", a.training},     {"amplitude", fit.model.amplitude}, {"corner", fit.model.corner},
                         {"slope", fit.model.slope}, {"residual_rms", fit.residual_rms},  {"patches", fit.patches},
                         {"noise_sigma", a.noise_sigma}, {"lambda", oo.reconstructor.lambda}};
    }
    criterion = std::make_unique<DesignObjective>(optics, scene.frames, oo);
  } else {
    const Shape hr{optics.grid, optics.grid};
    eo.training_scenes = a.training.empty() ? DefaultTrainingScenes(hr, a.training_scenes, a.seed)
                                            : TrainingScenesFromFiles(a.training, hr, a.training_zoom);
    eo.noise_sigma = a.noise_sigma;
    eo.noise_seed = a.seed;
    eo.loss = ParseDesignLoss(a.loss);
    eo.map.prior = ParseMapPrior(a.map_prior);
    // Automatic λ: the weight `aosr reconstruct -m map` chooses for such frames (reconstruct.hpp: λ = 2μ,
    // μ = 0.5 ρ √w̄ with whitened residuals ρ ≈ 1 and w̄ = 1/σ²) is 1/σ for the TV prior in these peak-1 units
    // (TV is 1-homogeneous), so the design is made for the reconstructor that will be run. (λ = 1, the
    // library's default, is ~30x weaker at the paper's noise; a design made for it lost 0.1-0.4 dB on held-out
    // scenes under the automatic weights: bench/results/design_tables.md.) The Tikhonov prior keeps λ = 1.
    eo.map.lambda = a.map_lambda >= 0 ? a.map_lambda
                                      : (ParseMapPrior(a.map_prior) == MapPrior::kCharbonnierTv ? 1.0 / a.noise_sigma : 1.0);
    eo.map.epsilon = a.epsilon;
    eo.realisations = a.realisations;
    eo.screens = a.screens;
    eo.seed = a.seed;
    eo.threads = a.threads;
    std::string why;
    if (!eo.IsValid(&why)) throw InvalidArgument("aosr design: objective B: " + why);
    progress.Step("objective B: " + std::to_string(eo.training_scenes.size()) + " training scene(s) of " +
                  ToString(hr) + (a.training.empty() ? " (dead leaves)" : " (files)") + ", loss " + a.loss +
                  ", MAP " + a.map_prior + " lambda " + ToString(eo.map.lambda));
    auto b = std::make_unique<EmpiricalDesignObjective>(optics, scene.frames, eo);
    empirical = b.get();
    criterion = std::move(b);
  }
  const DesignCriterion& objective = *criterion;
  const DesignParameterisation parameterisation(DesignPupilFromScene(scene), scene.frames, scene.r, po);
  DesignResult result = OptimizeDesign(objective, parameterisation, opt);
  // The optimiser only sees the sample it was built with (R realisations; for objective B also K scenes and
  // one noise draw each): a design can fit that sample's particulars. The design and the raster are re-judged
  // on a fresh sample (objective A: fresh realisations; B: also fresh noise and three fresh dead-leaves scenes)
  // and the raster is kept unless the design wins there too.
  nlohmann::json validation;
  const bool validate = a.validation_realisations > 0 && result.summary.improved &&
                        (a.objective == "B" || oo.realisations > 0);
  if (validate) {
    const std::uint64_t fresh = a.seed + 1000003;
    std::unique_ptr<DesignCriterion> check;
    if (a.objective == "A") {
      DesignObjectiveOptions vo = oo;
      vo.realisations = a.validation_realisations;
      vo.seed = fresh;
      check = std::make_unique<DesignObjective>(optics, scene.frames, vo);
    } else {
      EmpiricalDesignOptions ve = eo;
      ve.training_scenes = DefaultTrainingScenes({optics.grid, optics.grid}, 3, fresh);
      ve.noise_seed = fresh;
      ve.seed = fresh;
      if (ve.realisations > 0) ve.realisations = a.validation_realisations;
      check = std::make_unique<EmpiricalDesignObjective>(optics, scene.frames, ve);
    }
    const Vector raster_theta = parameterisation.RasterParameters();
    const double j_raster = check->Evaluate(parameterisation.Opds(raster_theta));
    const double j_design = check->Evaluate(result.opds);
    const bool keep = j_design < j_raster;
    validation = {{"realisations", check->realisations()}, {"seed", fresh}, {"objective_raster", j_raster},
                  {"objective_design", j_design}, {"kept", keep ? "design" : "raster"}};
    if (a.objective == "B") validation["scenes"] = "3 dead-leaves scenes (fresh seed), fresh noise";
    progress.Step("validation on a fresh sample: J raster " + ToString(j_raster) + ", design " +
                  ToString(j_design) + (keep ? ": design kept" : ": raster kept"));
    if (!keep) {
      result.parameters = raster_theta;
      result.coefficients = parameterisation.Coefficients(raster_theta);
      result.offsets = parameterisation.Offsets(raster_theta);
      result.opds = parameterisation.Opds(raster_theta);
      result.summary.final_objective = result.summary.final_cost = result.summary.initial_objective;
      result.summary.improved = false;
      result.summary.message += "; the design did not beat the raster on fresh realisations: raster kept";
    }
  }
  const std::vector<DesignFrameReport> reports = DescribeDesign(scene, parameterisation, result.opds);
  const std::string name = scene.name + "-" + a.param;
  nlohmann::json file = DesignFileJson(name, scene, result, objective, reports);
  if (!validation.is_null()) file["design"]["validation"] = validation;
  if (!spectrum_record.is_null()) file["design"]["object_spectrum"] = spectrum_record;
  if (!a.calibration.empty()) {
    // The frames become the commands that make a DM with the calibrated gains apply the design; the designed
    // (applied) offsets stay in the provenance.
    const Calibration cal = LoadCalibration(a.calibration);
    std::vector<std::string> notes;
    nlohmann::json designed = file["frames"];
    for (std::size_t i = 0; i < result.offsets.size(); ++i)
      file["frames"][i] = DmOffsetToJson(ApplyCalibration(result.offsets[i], cal, &notes));
    file["design"]["calibration"] = {{"file", a.calibration}, {"applied_frames", designed}, {"notes", notes}};
    for (const std::string& n : notes) progress.Step("calibration: " + n);
  }
  if (!a.output.empty()) WriteDesignFile(a.output, file);
  const DesignSummary& s = result.summary;

  if (a.json) {
    nlohmann::json j;
    j["scene"] = scene.source;
    j["parameterisation"] = s.parameterisation;
    j["parameters"] = s.parameters;
    j["frames"] = scene.frames;
    j["r"] = scene.r;
    j["ao_model"] = optics.ao ? "analytic" : "none";
    j["objective"] = a.objective;
    j["method"] = objective.method();
    if (empirical) j["last_evaluation"] = empirical->last_evaluation().BriefReport();
    j["realisations"] = objective.realisations();
    j["objective_raster"] = s.raster_objective;
    j["objective_start"] = s.initial_objective;
    j["objective_final"] = s.final_objective;
    j["improved"] = s.improved;
    j["validation"] = validation;
    j["object_spectrum"] = spectrum_record;
    j["starts"] = s.start_objectives;
    j["iterations"] = s.iterations;
    j["evaluations"] = s.evaluations;
    j["termination"] = ToString(s.termination);
    j["message"] = s.message;
    j["optimise_seconds"] = s.seconds;
    j["total_seconds"] = clock.Seconds();
    j["output"] = a.output.empty() ? nlohmann::json() : nlohmann::json(a.output);
    j["design"] = file;
    std::printf("%s\n", j.dump(2).c_str());
    return;
  }
  std::printf("aosr design: scene %s, N = %d, r = %d, %s offsets, AO model %s, %d realisation(s) x %d screens, "
              "grid %lld HR px\n",
              scene.name.c_str(), scene.frames, scene.r, s.parameterisation.c_str(), optics.ao ? "analytic" : "none",
              objective.realisations(), oo.screens, static_cast<long long>(optics.grid));
  std::printf("objective %s (%s)\n%s\n%s\n", a.objective.c_str(), objective.method(), s.FullReport().c_str(),
              s.message.c_str());
  if (empirical) std::printf("last evaluation: %s\n", empirical->last_evaluation().BriefReport().c_str());
  std::printf("%-6s %10s %10s %9s %9s %10s\n", "frame", "dy [px]", "dx [px]", "rms [nm]", "Strehl", "zernikes");
  for (std::size_t i = 0; i < result.offsets.size(); ++i) {
    const DmOffset& o = result.offsets[i];
    const std::size_t terms = o.actuators_m.empty() ? o.zernike.size() : o.actuators_m.size();
    std::printf("%-6zu %10.4f %10.4f %9.1f %9.4f %10zu\n", i, o.shift_y_px, o.shift_x_px, reports[i].rms_m * 1e9,
                reports[i].strehl, terms);
  }
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
  // Objective A only.
  for (CLI::Option* o : {cmd->get_option("--lambda"), cmd->get_option("--prior")}) a->objective_only.push_back({o, 'A'});
  AddExecutionOptions(cmd, &a->exec, /*with_threads=*/false);
  cmd->callback([a] { RunDesign(*a); });
}

}  // namespace aosr::cli
