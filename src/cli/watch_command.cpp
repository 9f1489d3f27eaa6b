// `aosr watch DIR --model DATASET -o OUT`: the live quick-look (solvers/quick_look.hpp). Reconstructs the frames
// a camera writes into DIR as they complete, refreshes OUT/quicklook.fits and OUT/quicklook.png after each
// output, logs one JSON line per file to OUT/watch.jsonl and reports the latency when it stops (after --frames
// files, --idle-timeout seconds without one, or SIGINT/SIGTERM).
#include <algorithm>
#include <atomic>
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "aosr/core/error.hpp"
#include "aosr/scene/dataset.hpp"
#include "aosr/solvers/quick_look.hpp"
#include "cli_util.hpp"
#include "commands.hpp"
#include "stream_options.hpp"

namespace aosr::cli {
namespace {

namespace fs = std::filesystem;
constexpr const char* kWatchCmd = "aosr watch";

struct WatchArgs {
  std::string directory, model, out;
  StreamArgs stream;
  std::string phase_key = "DMPHASE";
  std::string time_key;
  bool existing = false;
  int frames = 0;
  double idle_timeout = 0;
  double poll_interval = 1.0;
  double abandon_after = 60.0;
  bool no_png = false;
  std::string stretch = "asinh";
  bool force = false;
  bool json = false;
  bool quiet = false;
  ExecutionArgs exec;
};

std::atomic<bool> g_stop{false};
extern "C" void WatchStopHandler(int) { g_stop.store(true); }

double Percentile(std::vector<double> v, double p) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  const double rank = p / 100.0 * double(v.size() - 1);
  const std::size_t lo = std::size_t(rank);
  const std::size_t hi = std::min(lo + 1, v.size() - 1);
  return v[lo] + (rank - double(lo)) * (v[hi] - v[lo]);
}

void RunWatch(const WatchArgs& a) {
  ApplyExecution(a.exec);
  QuickLookOptions o;
  o.video = StreamVideoOptions(a.stream, kWatchCmd);
  o.problem = StreamProblemOptions(a.stream);
  o.phase_key = a.phase_key;
  o.time_key = a.time_key;
  o.write_png = !a.no_png;
  o.view.stretch = a.stretch == "log" ? Stretch::kLog : a.stretch == "linear" ? Stretch::kLinear : Stretch::kAsinh;
  o.watch.existing = a.existing;
  o.watch.poll_interval_s = a.poll_interval;
  o.watch.abandon_after_s = a.abandon_after;
  {
    std::string why;
    if (!o.IsValid(&why)) throw InvalidArgument(std::string(kWatchCmd) + ": " + why);
  }
  std::error_code ec;
  if (!fs::is_directory(a.directory, ec)) throw IoError(a.directory, "is not a directory (the folder the camera writes into)");
  // The quick-look must not land among the frames it watches (it would be read back as one).
  if (fs::exists(a.out, ec) && fs::equivalent(a.out, a.directory, ec))
    throw InvalidArgument(kWatchCmd, "-o", a.out, "a folder other than the watched one");
  const Dataset d = LoadDataset(a.model);
  const std::set<fs::path> inputs = DatasetInputFiles(d);
  const std::string log_path = JoinPath(a.out, "watch.jsonl");
  for (const std::string name : {"quicklook.fits", "quicklook.png", "watch.jsonl"}) {
    const std::string p = JoinPath(a.out, name);
    if (inputs.count(fs::weakly_canonical(p)))
      throw InvalidArgument(kWatchCmd, "-o", a.out, "a folder where no output overwrites an input of the model (" + p + ")");
    if (fs::exists(p, ec) && !a.force) throw IoError(p, "exists; pass --force to overwrite it");
  }
  EnsureDirectory(a.out);
  o.output_dir = a.out;
  QuickLook ql(a.directory, d, o);
  // The log is written as events come (a crash keeps what came before); its lines are complete JSON objects.
  std::ofstream log(log_path, std::ios::trunc);
  if (!log) throw IoError(log_path, "cannot be written");

  std::signal(SIGINT, WatchStopHandler);
  std::signal(SIGTERM, WatchStopHandler);
  if (!a.quiet && !a.json)
    std::printf("aosr watch: %s (%s), %d phases, %s, %s window; quick-look in %s\n", a.directory.c_str(),
                ql.using_inotify() ? "inotify" : "scanning", ql.video().slot_count(), ToString(o.video.method),
                ToString(o.video.window), a.out.c_str());
  std::fflush(stdout);
  std::vector<double> latency, read, rec, write;
  int files = 0;
  Stopwatch idle;
  std::string stop_reason = "signal";
  while (!g_stop.load()) {
    if (a.frames > 0 && files >= a.frames) {
      stop_reason = "frames";
      break;
    }
    if (a.idle_timeout > 0 && idle.Seconds() >= a.idle_timeout) {
      stop_reason = "idle";
      break;
    }
    // Short waits, so that a signal or the idle limit is seen within 0.2 s.
    std::optional<QuickLookEvent> e = ql.Next(0.2);
    if (!e) continue;
    idle = Stopwatch();
    ++files;
    nlohmann::json j;
    j["file"] = e->file;
    j["status"] = e->status;
    if (!e->message.empty()) j["message"] = e->message;
    if (e->slot >= 0) j["phase"] = e->slot;
    if (e->frame >= 0) j["frame"] = e->frame;
    if (e->status == "used" || e->status == "late") j["time_s"] = e->time_s;
    j["read_ms"] = 1e3 * e->read_s;
    if (e->output) {
      j["output"] = e->output->index;
      j["path"] = e->output->path;
      j["frames"] = e->output->frames;
      j["reconstruct_ms"] = 1e3 * e->reconstruct_s;
      read.push_back(1e3 * e->read_s);
      rec.push_back(1e3 * e->reconstruct_s);
    }
    if (e->written_output >= 0) {
      j["written"] = e->written_output;
      j["write_ms"] = 1e3 * e->write_s;
      j["latency_ms"] = 1e3 * e->latency_s;
      latency.push_back(1e3 * e->latency_s);
      write.push_back(1e3 * e->write_s);
    }
    log << j.dump() << '\n' << std::flush;
    if (!a.quiet && !a.json) {
      if (e->output && e->written_output >= 0)
        std::printf("%-7s %s phase %d -> output %d (%s), written with latency %.1f ms\n", e->status.c_str(),
                    fs::path(e->file).filename().c_str(), e->slot, e->output->index, e->output->path.c_str(),
                    1e3 * e->latency_s);
      else if (e->output)
        std::printf("%-7s %s phase %d -> output %d (%s), not written: a newer file is waiting\n", e->status.c_str(),
                    fs::path(e->file).filename().c_str(), e->slot, e->output->index, e->output->path.c_str());
      else
        std::printf("%-7s %s%s%s\n", e->status.c_str(), fs::path(e->file).filename().c_str(),
                    e->message.empty() ? "" : ": ", e->message.c_str());
      std::fflush(stdout);
    }
  }
  std::signal(SIGINT, SIG_DFL);
  std::signal(SIGTERM, SIG_DFL);
  // Steady state: the first output builds the slot filter (or chooses λ, μ) and is reported apart. Latencies are
  // those of the written outputs (quick_look.hpp).
  std::vector<double> steady(latency.size() > 1 ? latency.begin() + 1 : latency.end(), latency.end());
  if (a.json) {
    nlohmann::json j;
    j["files"] = files;
    j["used"] = ql.used();
    j["late"] = ql.late();
    j["rejected"] = ql.rejected();
    j["incomplete"] = ql.incomplete();
    j["outputs"] = ql.outputs();
    j["written"] = int(latency.size());
    j["superseded"] = ql.superseded();
    j["stopped_by"] = stop_reason;
    j["inotify"] = ql.using_inotify();
    j["first_latency_ms"] = latency.empty() ? 0.0 : latency.front();
    j["latency_ms"] = {{"p50", Percentile(steady, 50)}, {"p95", Percentile(steady, 95)},
                       {"p99", Percentile(steady, 99)}, {"max", steady.empty() ? 0.0 : *std::max_element(steady.begin(), steady.end())}};
    j["read_ms_p50"] = Percentile(read, 50);
    j["reconstruct_ms_p50"] = Percentile(std::vector<double>(rec.size() > 1 ? rec.begin() + 1 : rec.end(), rec.end()), 50);
    j["write_ms_p50"] = Percentile(write, 50);
    j["log"] = log_path;
    j["quicklook"] = JoinPath(a.out, "quicklook.fits");
    std::printf("%s\n", j.dump(2).c_str());
    return;
  }
  std::printf("aosr watch: stopped by %s after %d files: %d used, %d late, %d rejected, %d incomplete; %d outputs, "
              "%d written (%d superseded by a newer one)\n",
              stop_reason.c_str(), files, ql.used(), ql.late(), ql.rejected(), ql.incomplete(), ql.outputs(),
              int(latency.size()), ql.superseded());
  if (!latency.empty())
    std::printf("  latency (file complete -> quick-look written): first %.1f ms; then p50 %.1f, p95 %.1f, max %.1f ms\n",
                latency.front(), Percentile(steady, 50), Percentile(steady, 95),
                steady.empty() ? 0.0 : *std::max_element(steady.begin(), steady.end()));
  std::printf("  log %s\n", log_path.c_str());
}

}  // namespace

void RegisterWatch(CLI::App& app) {
  auto a = std::make_shared<WatchArgs>();
  CLI::App* cmd = app.add_subcommand(
      "watch",
      "Live quick-look: reconstructs the frames a camera writes into DIR (one FITS file per frame, the DM phase "
      "index in a header keyword) as each file completes, with the phases' model from a dataset taken with the same "
      "design. After each output, OUT/quicklook.fits (e- per HR pixel, HR WCS) and OUT/quicklook.png are replaced "
      "atomically; OUT/watch.jsonl gets one line per file (used, late, rejected or incomplete, with the latency). "
      "Half-written files are never read. Stops after --frames files, --idle-timeout seconds without one, or "
      "Ctrl-C, and prints the latency.");
  cmd->add_option("directory", a->directory, "the folder the camera writes frames into")->required();
  cmd->add_option("--model", a->model, "dataset (folder or manifest) of the same design: the phases' PSFs, the detector")
      ->required();
  cmd->add_option("-o,--output", a->out, "output folder (created if needed; not the watched one)")->required();
  AddStreamOptions(cmd, &a->stream);
  cmd->add_option("--phase-key", a->phase_key, "FITS keyword with the frame's DM phase index (0-based)")->capture_default_str();
  cmd->add_option("--time-key", a->time_key, "FITS keyword with the frame's time in seconds (default: the file's time)");
  cmd->add_flag("--existing", a->existing, "also reconstruct the frames already in the folder (in name order)");
  cmd->add_option("--frames", a->frames, "stop after this many files (0: no limit)")->capture_default_str()->check(CLI::Range(0, 1 << 30));
  cmd->add_option("--idle-timeout", a->idle_timeout, "stop after this many seconds without a new file (0: never)")
      ->capture_default_str()
      ->check(NonNegativeFinite());
  cmd->add_option("--poll-interval", a->poll_interval, "seconds between scans of the folder (the fallback without inotify)")
      ->capture_default_str()
      ->check(CLI::Range(1e-3, 3600.0));
  cmd->add_option("--abandon-after", a->abandon_after, "seconds a half-written file may stay unchanged before it is reported incomplete")
      ->capture_default_str()
      ->check(CLI::Range(1e-3, 1e6));
  cmd->add_flag("--no-png", a->no_png, "write quicklook.fits only");
  cmd->add_option("--stretch", a->stretch, "quicklook.png display stretch: asinh | log | linear")
      ->capture_default_str()
      ->check(CLI::IsMember({"asinh", "log", "linear"}));
  cmd->add_flag("--force", a->force, "overwrite an earlier quick-look and log in OUT");
  cmd->add_flag("--quiet", a->quiet, "no line per file (the log still has them)");
  cmd->add_flag("--json", a->json, "print the summary as JSON (and no line per file)");
  AddExecutionOptions(cmd, &a->exec);
  cmd->callback([a] { RunWatch(*a); });
}

}  // namespace aosr::cli
