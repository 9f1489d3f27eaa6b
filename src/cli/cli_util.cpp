#include "cli_util.hpp"

#include <signal.h>

#include <csignal>

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
#include "aosr/scene/dataset.hpp"
#include "aosr/scene/evaluation.hpp"

namespace aosr::cli {

Progress::Progress(bool enabled, bool force) : enabled_(force || (enabled && isatty(fileno(stderr)))) {}

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

namespace {
std::string& CommandLineStorage() {
  static std::string line;
  return line;
}
}  // namespace

void SetCommandLine(int argc, const char* const* argv) {
  std::string line;
  for (int i = 0; i < argc; ++i) {
    const std::string a = argv[i];
    const bool plain = !a.empty() && a.find_first_not_of("abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ"
                                                          "0123456789-_./=,:+@%") == std::string::npos;
    std::string q = a;
    if (!plain) {
      q = "'";
      for (char c : a) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
      q += "'";
    }
    line += (i ? " " : "") + q;
  }
  CommandLineStorage() = line;
}

const std::string& CommandLine() { return CommandLineStorage(); }

std::string JoinPath(const std::string& dir, const std::string& name) {
  return (std::filesystem::path(dir) / name).string();
}

namespace {
volatile std::sig_atomic_t interrupt_flag_raised = 0;
void OnInterruptFlagSignal(int) {
  interrupt_flag_raised = 1;
  std::signal(SIGINT, SIG_DFL);  // a second Ctrl-C ends the process
}
}  // namespace

InterruptFlag::InterruptFlag(bool enabled) : enabled_(enabled) {
  interrupt_flag_raised = 0;
  if (!enabled_) return;
  auto* previous = new struct sigaction();
  struct sigaction action {};
  action.sa_handler = OnInterruptFlagSignal;
  sigemptyset(&action.sa_mask);
  sigaction(SIGINT, &action, previous);
  previous_ = previous;
}

InterruptFlag::~InterruptFlag() {
  if (!enabled_) return;
  auto* previous = static_cast<struct sigaction*>(previous_);
  sigaction(SIGINT, previous, nullptr);
  delete previous;
}

bool InterruptFlag::raised() const { return enabled_ && interrupt_flag_raised != 0; }

void AddExecutionOptions(CLI::App* cmd, ExecutionArgs* args, bool with_threads) {
  if (with_threads)
    cmd->add_option("--threads", args->threads,
                    "threads (0: all hardware threads); results are the same bytes for any count")
        ->capture_default_str()
        ->check(CLI::Range(0, 256));
  cmd->add_option("--fft-planner", args->fft_planner,
                  "FFTW planning: estimate (reproducible, default: the plans aosr ships in its FFTW wisdom, FFTW's "
                  "heuristics for other shapes) | heuristic (reproducible: FFTW_ESTIMATE's heuristics alone, slower at "
                  "512^2 and up) | measure | patient (time candidates for shapes the wisdom lacks; the last bits of "
                  "results then vary from run to run)")
      ->capture_default_str()
      ->check(CLI::IsMember({"estimate", "heuristic", "measure", "patient"}));
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
  fft.shipped_wisdom = args.fft_planner != "heuristic";
  SetFftSettings(fft);
  if (!args.memory_limit.empty()) SetMemoryLimitBytes(ParseByteSize(args.memory_limit, "--memory-limit"));
}

void AddAlignedScores(const Evaluation& e, nlohmann::json* j) {
  (*j)["aligned"] = {{"psnr_db", e.aligned.psnr}, {"ssim", e.aligned.ssim}, {"rmse", e.aligned.rmse}};
  (*j)["offset_hr_px"] = {{"dy", e.offset.dy}, {"dx", e.offset.dx}};
  (*j)["offset_measured_hr_px"] = {{"dy", e.measured_offset.dy}, {"dx", e.measured_offset.dx}};
  (*j)["offset_applied"] = e.offset_applied;
  if (e.offset_mas_known)
    (*j)["offset_mas"] = {{"dy", e.offset_mas[0]}, {"dx", e.offset_mas[1]}};
  else
    (*j)["offset_mas"] = nullptr;
}

std::string AlignedScoresLine(const Evaluation& e) {
  char buf[320];
  if (e.offset_mas_known)
    std::snprintf(buf, sizeof(buf), "aligned (offset dy, dx = %+.3f, %+.3f HR px = %+.2f, %+.2f mas): PSNR %.2f dB, SSIM %.4f",
                  e.offset.dy, e.offset.dx, e.offset_mas[0], e.offset_mas[1], e.aligned.psnr, e.aligned.ssim);
  else
    std::snprintf(buf, sizeof(buf), "aligned (offset dy, dx = %+.3f, %+.3f HR px): PSNR %.2f dB, SSIM %.4f", e.offset.dy,
                  e.offset.dx, e.aligned.psnr, e.aligned.ssim);
  std::string line = buf;
  if (!e.offset_applied) {
    // The measured offset would have lowered a score in the scored region (core/metrics.hpp): say so.
    std::snprintf(buf, sizeof(buf), " [measured %+.3f, %+.3f HR px, not applied: it lowered PSNR or SSIM]",
                  e.measured_offset.dy, e.measured_offset.dx);
    line += buf;
  }
  return line;
}

void ParseRingCentre(const std::string& command, const std::string& text, double* y, double* x) {
  const std::size_t comma = text.find(',');
  bool ok = comma != std::string::npos;
  if (ok) {
    try {
      std::size_t nx = 0, ny = 0;
      const std::string xs = text.substr(0, comma), ys = text.substr(comma + 1);
      *x = std::stod(xs, &nx);
      *y = std::stod(ys, &ny);
      ok = nx == xs.size() && ny == ys.size() && std::isfinite(*x) && std::isfinite(*y);
    } catch (const std::exception&) {
      ok = false;
    }
  }
  if (!ok)
    throw InvalidArgument(command, "--ring-centre", text,
                          "X,Y: two finite numbers, the column then the row of the centre in HR pixels (0-based pixel "
                          "centres), e.g. 100.5,20");
}

std::string RingsTable(const Evaluation& ev, double hr_mas, const std::string& indent) {
  const RingMetrics& rm = ev.rings;
  const bool stars = !ev.ring_stars.empty();
  std::string out;
  char buf[512];
  std::snprintf(buf, sizeof(buf), "%s%zu rings about (x, y) = (%.2f, %.2f) HR px, each aligned on its own (dynamic range L = %.4g):\n",
                indent.c_str(), rm.rings.size(), rm.centre_x, rm.centre_y, rm.peak);
  out += buf;
  std::snprintf(buf, sizeof(buf), "%s  ring  radius [HR px]%s   pixels  PSNR [dB]  aligned  SSIM    aligned  offset dy, dx [HR px]%s\n",
                indent.c_str(), hr_mas > 0 ? "  radius [arcsec]" : "", stars ? "  stars  flux bias" : "");
  out += buf;
  for (std::size_t k = 0; k < rm.rings.size(); ++k) {
    const RingScore& r = rm.rings[k];
    const AlignedImageMetrics& m = r.scores;
    char radius[64] = "", star_text[64] = "";
    if (hr_mas > 0) std::snprintf(radius, sizeof(radius), "  %6.3f - %6.3f", r.inner_px * hr_mas / 1000, r.outer_px * hr_mas / 1000);
    if (stars) {
      const RingPhotometry& p = ev.ring_stars[k];
      if (p.stars > 0)
        std::snprintf(star_text, sizeof(star_text), "  %5d  %+8.2f%%", p.stars, 100 * p.flux_bias);
      else
        std::snprintf(star_text, sizeof(star_text), "  %5d  %9s", 0, "-");
    }
    std::snprintf(buf, sizeof(buf), "%s  %4zu  %6.1f - %6.1f%s  %7lld  %9.2f  %7.2f  %.4f  %.4f   %+.3f, %+.3f%s%s\n",
                  indent.c_str(), k, r.inner_px, r.outer_px, radius, static_cast<long long>(r.pixels), m.raw.psnr,
                  m.aligned.psnr, m.raw.ssim, m.aligned.ssim, m.offset.dy, m.offset.dx,
                  m.offset_applied ? "" : " (not applied)", star_text);
    out += buf;
  }
  return out;
}

}  // namespace aosr::cli
