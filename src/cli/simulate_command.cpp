// `aosr simulate SCENE`: compile a scene file into its pipeline, print the plan or run it, and write the
// dataset (scene/dataset.hpp) that the reconstructors read.
#include <algorithm>
#include <cstdio>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "aosr/calib/calibration_file.hpp"
#include "aosr/core/error.hpp"
#include "aosr/core/memory.hpp"
#include "aosr/io/config.hpp"
#include "aosr/scene/dataset.hpp"
#include "aosr/scene/pipeline.hpp"
#include "aosr/scene/scene_spec.hpp"
#include "cli_util.hpp"
#include "commands.hpp"

namespace aosr::cli {
namespace {

struct SimulateArgs {
  std::string scene;
  std::string out_dir;
  std::vector<std::string> sets;
  bool plan = false;
  bool json = false;
  std::string calibration;
  ExecutionArgs exec;
};

// Applies one "--set a.b.c=VALUE" to the scene's JSON. VALUE is JSON if it parses as JSON (numbers, true,
// [64, 64], {"peak_e": 100}), else a string; a dotted key walks objects, a numeric part indexes an array
// (objects.0.flux.peak_e=50). The scene parser validates the result like any other field.
void ApplySet(const std::string& text, nlohmann::json* scene) {
  const std::string allowed = "KEY=VALUE with KEY a dotted field path of the scene, e.g. r=4 or detector.noise=none";
  const auto eq = text.find('=');
  if (eq == std::string::npos || eq == 0) throw InvalidArgument("aosr simulate", "--set", text, allowed);
  const std::string key = text.substr(0, eq), value = text.substr(eq + 1);
  std::string pointer;
  std::size_t start = 0;
  while (true) {
    const auto dot = key.find('.', start);
    const std::string part = key.substr(start, dot == std::string::npos ? std::string::npos : dot - start);
    if (part.empty()) throw InvalidArgument("aosr simulate", "--set", text, allowed);
    for (char c : part) pointer += c == '~' ? "~0" : c == '/' ? "~1" : std::string(1, c);
    if (dot == std::string::npos) break;
    pointer += '/';
    start = dot + 1;
  }
  nlohmann::json parsed = nlohmann::json::parse(value, nullptr, /*allow_exceptions=*/false);
  if (parsed.is_discarded()) parsed = value;
  try {
    (*scene)[nlohmann::json::json_pointer("/" + pointer)] = std::move(parsed);
  } catch (const nlohmann::json::exception& e) {
    throw InvalidArgument("aosr simulate", "--set", text, allowed + " (" + e.what() + ")");
  }
}

nlohmann::json PlanJson(const ScenePipeline& p) {
  const SceneGeometry& g = p.geometry();
  nlohmann::json j;
  j["scene"] = p.scene().name;
  j["source"] = p.scene().source;
  j["frames"] = p.scene().frames;
  j["r"] = g.r;
  j["sky_oversampling"] = p.scene().sky_oversampling;
  j["frame_shape"] = {g.frame.rows, g.frame.cols};
  j["hr_shape"] = {g.hr_frame.rows, g.hr_frame.cols};
  j["padded_shape"] = {g.padded.rows, g.padded.cols};
  j["psf_size_px"] = g.psf_size;
  j["trustworthy_border_px"] = g.trustworthy_border_px;
  j["estimated_peak_bytes"] = p.estimated_peak_bytes();
  double total = 0;
  j["stages"] = nlohmann::json::array();
  for (const PipelineStage& s : p.stages()) {
    j["stages"].push_back({{"name", s.name}, {"count", s.count}, {"estimated_s", s.estimated_s}, {"detail", s.detail}});
    total += s.estimated_s;
  }
  j["total_estimated_s"] = total;
  return j;
}

void RunSimulate(const SimulateArgs& args) {
  ApplyExecution(args.exec);
  const Progress progress(!args.json);
  Stopwatch clock;
  // The scene parses (and every file it names is checked) before anything is computed.
  nlohmann::json scene_json = ReadJsonFile(args.scene);
  for (const std::string& s : args.sets) ApplySet(s, &scene_json);
  SceneSpec parsed = ParseScene(scene_json, args.scene);
  if (!args.calibration.empty()) {
    // Simulate the real DM: it applies each commanded mode times its calibrated gain.
    const Calibration cal = LoadCalibration(args.calibration);
    std::vector<std::string> notes;
    for (DmOffset& o : parsed.offsets.frames) o = DmResponse(o, cal, &notes);
    for (const std::string& n : notes) progress.Step("calibration: " + n);
    scene_json["comment_calibration"] = "offsets applied through the DM gains of " + args.calibration +
                                        " (the manifest's offsets are the applied ones)";
  }
  const ScenePipeline pipeline(std::move(parsed));
  const SceneSpec& scene = pipeline.scene();

  if (args.plan) {
    if (args.json) std::printf("%s\n", PlanJson(pipeline).dump(2).c_str());
    else std::printf("%s", pipeline.PlanReport().c_str());
    return;
  }
  if (!args.out_dir.empty()) PrepareSimulationOutput(args.out_dir, scene);  // fail before the simulation

  progress.Step("simulating " + scene.name + ": " + std::to_string(scene.Exposures()) + " frames of " +
                ToString(scene.frame) + " pixels, r = " + std::to_string(scene.r));
  const Simulation sim = pipeline.Run();
  if (!args.out_dir.empty()) {
    progress.Step("writing " + args.out_dir);
    WriteSimulation(args.out_dir, scene, pipeline, sim, &scene_json);
  }

  const SceneGeometry& g = sim.geometry;
  if (args.json) {
    nlohmann::json j = PlanJson(pipeline);
    j["timings"] = nlohmann::json::array();
    for (const StageTiming& t : sim.timings) j["timings"].push_back({{"stage", t.name}, {"seconds", t.seconds}});
    j["simulate_seconds"] = sim.seconds;
    j["strehl"] = sim.strehl;
    j["exposures"] = scene.Exposures();
    if (!sim.times_s.empty()) j["times_s"] = sim.times_s;
    j["psf_window_fraction"] = sim.psf_window_fraction;
    j["distinct_psfs"] = sim.counters.psfs_computed;
    j["stars"] = sim.stars.size();
    j["truth_total_e"] = sim.truth.sum();
    j["output"] = args.out_dir.empty() ? nlohmann::json() : nlohmann::json(args.out_dir);
    j["manifest"] = args.out_dir.empty() ? nlohmann::json() : nlohmann::json(JoinPath(args.out_dir, kManifestFileName));
    j["total_seconds"] = clock.Seconds();
    j["peak_rss_bytes"] = PeakResidentBytes();  // the whole process, for comparison with the estimate
    std::printf("%s\n", j.dump(2).c_str());
    return;
  }
  const std::string sequence = scene.sequence.enabled() ? " in a sequence of " + std::to_string(scene.Exposures()) + " exposures" : "";
  std::printf("aosr simulate: scene %s: N = %d frames%s of %s px, r = %d, HR %s, PSF %lld^2 (border %lld px)\n",
              scene.name.c_str(), scene.frames, sequence.c_str(), ToString(g.frame).c_str(), g.r, ToString(g.hr_frame).c_str(),
              static_cast<long long>(g.psf_size), static_cast<long long>(g.trustworthy_border_px));
  std::printf("%-20s %10s\n", "stage", "seconds");
  for (const StageTiming& t : sim.timings) std::printf("%-20s %10.4f\n", t.name.c_str(), t.seconds);
  std::printf("%-20s %10.4f\n", "total", sim.seconds);
  double lo = 1, hi = 0;
  for (double s : sim.strehl) lo = std::min(lo, s), hi = std::max(hi, s);
  if (!sim.strehl.empty())
    std::printf("Strehl %.4g .. %.4g over %d exposures (%d distinct PSFs)\n", lo, hi, scene.Exposures(), sim.counters.psfs_computed);
  if (!args.out_dir.empty()) std::printf("dataset written to %s\n", JoinPath(args.out_dir, kManifestFileName).c_str());
}

}  // namespace

void RegisterSimulate(CLI::App& app) {
  auto args = std::make_shared<SimulateArgs>();
  CLI::App* cmd = app.add_subcommand(
      "simulate",
      "Simulate the N frames of a scene file (data/scenes/README.md): object, optics, AO, DM offsets and "
      "detector, building only the effects the scene enables. --plan prints the compiled stages with their "
      "estimated cost and computes nothing; -o writes frames, masks, weights, truth, PSFs and a manifest.json "
      "that `aosr` reconstructors read.");
  cmd->add_option("scene", args->scene, "scene file (.json)")->required();
  CLI::Option* out = cmd->add_option(
      "-o,--output", args->out_dir,
      "write frames.fits, valid.fits, weights.fits, truth.fits, psfs.fits, expected.fits and manifest.json here");
  CLI::Option* plan = cmd->add_flag("--plan", args->plan, "print the compiled pipeline and its cost estimate; run nothing");
  plan->excludes(out);
  cmd->add_flag("--json", args->json, "print the plan or the run's summary as JSON (no progress messages)");
  cmd->add_option("--calibration", args->calibration,
                  "calibration.json (aosr calibrate): the simulated DM applies each commanded mode times its "
                  "calibrated gain (pair with aosr design --calibration, which writes the compensating commands)")
      ->check(CLI::ExistingFile);
  cmd->add_option("--set", args->sets,
                  "override a scene field before parsing, KEY=VALUE with a dotted KEY and a JSON (or plain string) "
                  "VALUE, e.g. --set r=4 --set detector.noise=none; repeatable")
      ->expected(1)
      ->multi_option_policy(CLI::MultiOptionPolicy::TakeAll);
  AddExecutionOptions(cmd, &args->exec);
  cmd->callback([args] { RunSimulate(*args); });
}

}  // namespace aosr::cli
