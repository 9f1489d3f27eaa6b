// Small helpers shared by the CLI subcommands: progress on a terminal, timing, output folders.
#pragma once

#include <CLI/CLI.hpp>
#include <chrono>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <set>
#include <string>

namespace aosr {
struct Dataset;
struct Evaluation;
}

namespace aosr::cli {

// Prints "[aosr] message" to stderr when stderr is a terminal and `enabled`, or always when `force` (a
// command's --progress, for logs); silent otherwise (so --json output and pipes stay clean). Never stdout.
// The per-iteration line of long solves is progress_bar.hpp's.
class Progress {
 public:
  explicit Progress(bool enabled, bool force = false);
  void Step(const std::string& message) const;

 private:
  bool enabled_;
};

// Wall-clock stopwatch in seconds.
class Stopwatch {
 public:
  Stopwatch() : start_(std::chrono::steady_clock::now()) {}
  double Seconds() const { return std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count(); }

 private:
  std::chrono::steady_clock::time_point start_;
};

// A CLI11 validator for finite numbers >= 0 whose message states the rule plainly.
CLI::Validator NonNegativeFinite();

// Creates `dir` (and parents) if needed; IoError naming it if it cannot be made or is not a directory.
void EnsureDirectory(const std::string& dir);

// Checks before any computation that `path` can be written: its folder exists and it is not a folder.
void CheckWritableFile(const std::string& path);

// Execution settings every computing command takes (DESIGN.md §3: threads and planner rigour are settings,
// not maths). Results are bit-identical for any --threads with the default planner; --fft-planner measure
// may be faster on some shapes but makes the last bits of results depend on the run.
struct ExecutionArgs {
  int threads = 0;                     // 0: every hardware thread
  std::string fft_planner = "estimate";  // estimate | measure | patient
  std::string memory_limit;            // empty: AOSR_MEMORY_LIMIT or the machine's (core/memory.hpp)
};
// Ctrl-C as a request to stop (a tiled reconstruction stops cleanly between iterations): while an enabled
// InterruptFlag lives, the first SIGINT only raises the flag (and puts back the default action, so a second
// one ends the process at once); the previous action is restored when it is destroyed. Disabled: nothing is
// installed and raised() stays false. One at a time.
class InterruptFlag {
 public:
  explicit InterruptFlag(bool enabled);
  ~InterruptFlag();
  InterruptFlag(const InterruptFlag&) = delete;
  InterruptFlag& operator=(const InterruptFlag&) = delete;
  bool raised() const;  // safe from any thread

 private:
  bool enabled_;
  void* previous_ = nullptr;  // the previous struct sigaction
};

// Adds --threads, --fft-planner and --memory-limit to `cmd` (--threads only if `with_threads`: design and calibrate have
// their own, which ApplyExecution is then given).
void AddExecutionOptions(CLI::App* cmd, ExecutionArgs* args, bool with_threads = true);
// Sets aosr's default thread count and FFT planner from `args`.
void ApplyExecution(const ExecutionArgs& args);

// The command line the program was started with (main() records it), shell-quoted where needed, for reports
// that say what produced them. Empty until SetCommandLine.
void SetCommandLine(int argc, const char* const* argv);
const std::string& CommandLine();

// The alignment part of an evaluation (scene/evaluation.hpp) as JSON members added to `*j`: "aligned" {psnr_db,
// ssim, rmse}, "offset_hr_px" {dy, dx} (as applied), "offset_measured_hr_px" {dy, dx}, "offset_applied" and
// "offset_mas" {dy, dx} (null when the pixel scale is unknown). The same names in `aosr evaluate`, the reconstruct
// summary and the tradeoff table.
void AddAlignedScores(const Evaluation& e, nlohmann::json* j);
// One text line: "aligned (offset dy, dx = ... HR px = ... mas): PSNR ... dB, SSIM ..." (and, when the measured
// offset was not applied, " [measured ..., not applied: ...]").
std::string AlignedScoresLine(const Evaluation& e);

// --ring-centre "X,Y" [HR px, column then row] -> (*y, *x); InvalidArgument naming `command` and --ring-centre.
void ParseRingCentre(const std::string& command, const std::string& text, double* y, double* x);
// The rings of an evaluation (scene/evaluation.hpp) as a text table, each line starting with `indent`: radius (and
// in arcsec when hr_mas > 0), pixels, PSNR and SSIM raw and aligned, the offset, and with a catalogue the stars and
// their photometric bias. The same table in `aosr evaluate --rings` and `aosr reconstruct --rings`.
std::string RingsTable(const Evaluation& e, double hr_mas, const std::string& indent);

// Joins a directory and a file name.
std::string JoinPath(const std::string& dir, const std::string& name);

}  // namespace aosr::cli
