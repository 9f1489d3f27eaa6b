// `aosr design SCENE`: the N per-exposure DM offsets that minimise the expected reconstruction MSE (objective A,
// solvers/design_objective.hpp) for the scene's telescope, AO system, camera, r and N, written as a design file
// (solvers/design_file.hpp) that a scene loads with "offsets": {"type": "design", "file": ...}.
#include <cstdio>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>

#include "aosr/calib/calibration_file.hpp"
#include "aosr/core/error.hpp"
#include "aosr/scene/scene_spec.hpp"
#include "aosr/solvers/design_file.hpp"
#include "aosr/solvers/design_objective.hpp"
#include "aosr/solvers/design_optimizer.hpp"
#include "aosr/solvers/design_parameterisation.hpp"
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
};

void RunDesign(const DesignArgs& a) {
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
  const DesignObjective objective(optics, scene.frames, oo);
  const DesignParameterisation parameterisation(DesignPupilFromScene(scene), scene.frames, scene.r, po);
  const DesignResult result = OptimizeDesign(objective, parameterisation, opt);
  const std::vector<DesignFrameReport> reports = DescribeDesign(scene, parameterisation, result.opds);
  const std::string name = scene.name + "-" + a.param;
  nlohmann::json file = DesignFileJson(name, scene, result, objective, reports);
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
    j["realisations"] = objective.realisations();
    j["objective_raster"] = s.raster_objective;
    j["objective_start"] = s.initial_objective;
    j["objective_final"] = s.final_objective;
    j["improved"] = s.improved;
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
  std::printf("%s\n%s\n", s.FullReport().c_str(), s.message.c_str());
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
      "realisations, with the PSF mismatch of the reconstructor's nominal model counted), by L-BFGS from the "
      "classic raster and perturbed starts. -o writes a design file that scenes load with "
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
  cmd->callback([a] { RunDesign(*a); });
}

}  // namespace aosr::cli
