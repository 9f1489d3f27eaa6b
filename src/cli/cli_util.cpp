#include "cli_util.hpp"

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <thread>

#include "aosr/core/error.hpp"
#include "aosr/core/fft.hpp"
#include "aosr/core/memory.hpp"
#include "aosr/core/parallel.hpp"

namespace aosr::cli {

Progress::Progress(bool enabled) : enabled_(enabled && isatty(fileno(stderr))) {}

void Progress::Step(const std::string& message) const {
  if (enabled_) std::fprintf(stderr, "[aosr] %s\n", message.c_str());
}

CLI::Validator NonNegativeFinite() {
  return CLI::Validator(
      [](std::string& text) -> std::string {
        double v = 0;
        std::size_t used = 0;
        try {
          v = std::stod(text, &used);
        } catch (const std::exception&) {
          return "expected a number, got '" + text + "'";
        }
        if (used != text.size() || !std::isfinite(v) || v < 0) return "must be a finite number >= 0, got " + text;
        return "";
      },
      "NUMBER >= 0");
}

void EnsureDirectory(const std::string& dir) {
  namespace fs = std::filesystem;
  std::error_code ec;
  if (fs::exists(dir, ec)) {
    if (!fs::is_directory(dir, ec)) throw IoError(dir, "exists and is not a directory");
    return;
  }
  if (!fs::create_directories(dir, ec) || ec) throw IoError(dir, "cannot create directory: " + ec.message());
}

void CheckWritableFile(const std::string& path) {
  namespace fs = std::filesystem;
  std::error_code ec;
  const fs::path p(path);
  if (fs::is_directory(p, ec)) throw IoError(path, "is a directory; give a file name");
  const fs::path dir = p.has_parent_path() ? p.parent_path() : fs::path(".");
  if (!fs::is_directory(dir, ec)) throw IoError(path, "its folder " + dir.string() + " does not exist");
}

std::string JoinPath(const std::string& dir, const std::string& name) {
  return (std::filesystem::path(dir) / name).string();
}

void AddExecutionOptions(CLI::App* cmd, ExecutionArgs* args, bool with_threads) {
  if (with_threads)
    cmd->add_option("--threads", args->threads,
                    "threads (0: all hardware threads); results are the same bytes for any count")
        ->capture_default_str()
        ->check(CLI::Range(0, 256));
  cmd->add_option("--fft-planner", args->fft_planner,
                  "FFTW planning: estimate (reproducible, default) | measure | patient (may be faster; the last "
                  "bits of results then vary from run to run)")
      ->capture_default_str()
      ->check(CLI::IsMember({"estimate", "measure", "patient"}));
  cmd->add_option("--memory-limit", args->memory_limit,
                  "refuse work whose estimated memory exceeds this, e.g. 8G (default: AOSR_MEMORY_LIMIT, else the "
                  "physical memory or what ulimit -v leaves)");
}

void ApplyExecution(const ExecutionArgs& args) {
  const int hw = int(std::max(1u, std::thread::hardware_concurrency()));
  SetDefaultThreads(args.threads > 0 ? std::min(args.threads, 256) : std::min(hw, 256));
  FftSettings fft;
  fft.planner = args.fft_planner == "measure"   ? FftSettings::Planner::kMeasure
                : args.fft_planner == "patient" ? FftSettings::Planner::kPatient
                                                : FftSettings::Planner::kEstimate;
  SetFftSettings(fft);
  if (!args.memory_limit.empty()) SetMemoryLimitBytes(ParseByteSize(args.memory_limit, "--memory-limit"));
}

}  // namespace aosr::cli
