// `aosr calibrate`: fit per-mode DM gains from a calibration set (calib/calibrate.hpp), or synthesize a set with
// known gains (--synthesize).
#include <cstdio>
#include <filesystem>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "aosr/calib/calibrate.hpp"
#include "aosr/calib/calibration_file.hpp"
#include "aosr/calib/calibration_set.hpp"
#include "aosr/calib/report.hpp"
#include "aosr/core/error.hpp"
#include "aosr/io/atomic_file.hpp"
#include "cli_util.hpp"
#include "commands.hpp"

namespace aosr::cli {
namespace {

struct CalibrateArgs {
  std::string set;
  std::string out_dir;
  std::string synthesize;
  std::vector<double> gains;
  double nonlinear_above_nm = -1;
  double nonlinear_strength = -1;
  long long seed = -1;
  int threads = 2;
  int static_max_noll = 8;
  double tolerance = 0.05;
  bool fixed_source = false;
  bool json = false;
  ExecutionArgs exec;
};

void RunSynthesize(const CalibrateArgs& a) {
  SyntheticCalibrationOptions o = LoadSyntheticCalibrationSpec(a.synthesize);
  if (!a.gains.empty()) o.gains = a.gains;
  if (a.nonlinear_above_nm >= 0) o.nonlinear_above_m = a.nonlinear_above_nm * 1e-9;
  if (a.nonlinear_strength > 0) o.nonlinear_strength = a.nonlinear_strength;
  if (a.seed >= 0) o.seed = std::uint64_t(a.seed);
  std::string why;
  if (!o.IsValid(&why)) throw InvalidArgument("aosr calibrate --synthesize: " + why);
  const std::string manifest = JoinPath(a.out_dir, kCalibrationSetFileName);
  CheckNotSameFile(manifest, {a.synthesize});
  EnsureDirectory(a.out_dir);
  Stopwatch clock;
  CalibrationSet set = SynthesizeCalibrationSet(o);
  set.truth["spec"] = a.synthesize;
  WriteCalibrationSet(a.out_dir, set);
  if (a.json) {
    nlohmann::json j = {{"manifest", manifest}, {"frames", set.frames.size()}, {"modes", set.modes.size()},
                        {"frame_px", {set.shape().rows, set.shape().cols}}, {"seconds", clock.Seconds()},
                        {"truth", set.truth}};
    std::printf("%s\n", j.dump(2).c_str());
    return;
  }
  std::printf("aosr calibrate --synthesize: %zu frames of %s px for %zu modes written to %s (%.2f s)\n", set.frames.size(),
              ToString(set.shape()).c_str(), set.modes.size(), manifest.c_str(), clock.Seconds());
}

void RunCalibrate(const CalibrateArgs& a) {
  ExecutionArgs exec = a.exec;
  exec.threads = a.threads;
  ApplyExecution(exec);
  if (a.out_dir.empty()) throw InvalidArgument("aosr calibrate", "-o", "(missing)", "an output folder");
  if (!a.synthesize.empty()) {
    if (!a.set.empty())
      throw InvalidArgument("aosr calibrate", "SET", a.set, "no set folder with --synthesize (it writes one to -o)");
    RunSynthesize(a);
    return;
  }
  if (a.set.empty()) throw InvalidArgument("aosr calibrate", "SET", "(missing)", "a calibration set folder, or --synthesize SPEC");
  if (!a.gains.empty() || a.nonlinear_above_nm >= 0 || a.seed >= 0 || a.nonlinear_strength > 0)
    throw InvalidArgument("aosr calibrate", "--gains/--nonlinear-above/--nonlinear-strength/--seed", "given",
                          "only with --synthesize");
  const Progress progress(!a.json);
  Stopwatch clock;
  CalibrateOptions o;
  o.threads = a.threads;
  o.fit.static_max_noll = a.static_max_noll;
  o.fit.fit_source_size = !a.fixed_source;
  o.linearity.tolerance = a.tolerance;
  std::string why;
  if (!o.IsValid(&why)) throw InvalidArgument("aosr calibrate: " + why);
  const CalibrationSet set = LoadCalibrationSet(a.set);
  const std::string json_path = JoinPath(a.out_dir, "calibration.json"), png_path = JoinPath(a.out_dir, "report.png");
  const std::vector<std::string> inputs = CalibrationSetInputFiles(set);
  CheckNotSameFile(json_path, inputs);
  CheckNotSameFile(png_path, inputs);
  EnsureDirectory(a.out_dir);
  progress.Step("calibrating " + std::to_string(set.modes.size()) + " modes from " + std::to_string(set.frames.size()) +
                " frames on " + std::to_string(a.threads) + " thread(s)");
  const CalibrationResult result = Calibrate(set, o);
  nlohmann::json j = CalibrationToJson(set, result);
  WriteCalibrationJson(json_path, j);
  WriteCalibrationReport(png_path, set, result);
  const double total = clock.Seconds();
  if (a.json) {
    j["output"] = {{"calibration", json_path}, {"report", png_path}};
    j["total_seconds"] = total;
    std::printf("%s\n", j.dump(2).c_str());
    return;
  }
  std::printf("aosr calibrate: %s (%zu frames of %s px, %zu modes)\n", set.source.c_str(), set.frames.size(),
              ToString(set.shape()).c_str(), set.modes.size());
  std::printf("%s", result.BriefReport().c_str());
  std::printf("wrote %s and %s (%.2f s in total)\n", json_path.c_str(), png_path.c_str(), total);
}

}  // namespace

void RegisterCalibrate(CLI::App& app) {
  auto args = std::make_shared<CalibrateArgs>();
  CLI::App* cmd = app.add_subcommand(
      "calibrate",
      "Fit, mode by mode, the DM gain (applied / commanded power) from frames of a point source taken while single "
      "modes are poked at several amplitudes (a calibration set, data/calibration/README.md), with uncertainties, "
      "the per-amplitude gains and the linear range; writes calibration.json and report.png to -o. With "
      "--synthesize SPEC it instead writes a synthetic set with known gains, static aberration, non-linearity and "
      "noise (SPEC: data/calibration/*.json or a telescope preset).");
  cmd->add_option("set", args->set, "calibration set folder (or its calibration-set.json)");
  cmd->add_option("-o,--output", args->out_dir, "output folder (created if needed)")->required();
  cmd->add_option("--synthesize", args->synthesize, "write a synthetic set from this spec or telescope preset");
  cmd->add_option("--gains", args->gains, "--synthesize: true gain per mode, comma separated")->delimiter(',');
  cmd->add_option("--nonlinear-above", args->nonlinear_above_nm, "--synthesize: response non-linear above this |a| [nm]")
      ->check(NonNegativeFinite());
  cmd->add_option("--nonlinear-strength", args->nonlinear_strength,
                  "--synthesize: k of the non-linearity (0..1 saturates, 1..2 folds back)")
      ->check(CLI::Range(1e-6, 2.0));
  cmd->add_option("--seed", args->seed, "--synthesize: noise seed")->check(CLI::Range(0LL, (1LL << 62)));
  cmd->add_option("--threads", args->threads, "modes fitted in parallel")->capture_default_str()->check(CLI::Range(1, 256));
  cmd->add_option("--static-max-noll", args->static_max_noll,
                  "fit the static aberration Z4..Z<K> common to a mode's frames (0: none)")
      ->capture_default_str()
      ->check(CLI::Range(0, 37));
  cmd->add_option("--tolerance", args->tolerance, "relative gain change tolerated in the linear range")
      ->capture_default_str()
      ->check(CLI::Range(1e-6, 0.999));
  cmd->add_flag("--point-source", args->fixed_source, "do not fit the source size (a point source)");
  cmd->add_flag("--json", args->json, "print the calibration (or the synthetic set's summary) as JSON");
  AddExecutionOptions(cmd, &args->exec, /*with_threads=*/false);
  cmd->callback([args] { RunCalibrate(*args); });
}

}  // namespace aosr::cli
