#include "progress_bar.hpp"

#include <sys/ioctl.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>

namespace aosr::cli {

ProgressBar::Mode ProgressBar::Choose(bool json, bool force) {
  const bool tty = isatty(fileno(stderr)) != 0;
  if (force) return tty ? Mode::kRedraw : Mode::kLines;
  return !json && tty ? Mode::kRedraw : Mode::kOff;
}

ProgressBar::ProgressBar(Mode mode, std::FILE* out) : mode_(mode), out_(out) {
  if (mode_ == Mode::kRedraw) {
    winsize ws{};
    if (ioctl(fileno(out_), TIOCGWINSZ, &ws) == 0 && ws.ws_col >= 20) width_ = ws.ws_col;
  }
}

ProgressBar::~ProgressBar() { Clear(); }

ProgressCallback ProgressBar::Callback() {
  if (mode_ == Mode::kOff) return {};
  return [this](const aosr::Progress& p) {
    Draw(p);
    return true;
  };
}

std::string ProgressBar::Duration(double seconds) {
  if (!(std::isfinite(seconds) && seconds >= 0)) return "?";
  const long long s = static_cast<long long>(std::llround(seconds));
  char buf[32];
  if (s >= 3600)
    std::snprintf(buf, sizeof buf, "%lld:%02lld:%02lld", s / 3600, (s / 60) % 60, s % 60);
  else
    std::snprintf(buf, sizeof buf, "%lld:%02lld", s / 60, s % 60);
  return buf;
}

std::string ProgressBar::Format(const aosr::Progress& p, int bar_width) {
  std::string line = p.stage;
  char buf[64];
  if (p.total > 0) {
    std::snprintf(buf, sizeof buf, " %d/%d", p.iteration, p.total);
    line += buf;
    const double f = std::clamp(double(p.iteration) / double(p.total), 0.0, 1.0);
    if (bar_width > 0) {
      const int filled = static_cast<int>(f * bar_width);
      line += " [" + std::string(filled, '#') + std::string(bar_width - filled, '.') + "]";
    }
  } else {
    std::snprintf(buf, sizeof buf, " %d", p.iteration);
    line += buf;
  }
  if (!p.value_name.empty() && std::isfinite(p.value)) {
    std::snprintf(buf, sizeof buf, " %.3g", p.value);
    line += " " + p.value_name + buf;
  }
  line += "  " + Duration(p.elapsed_seconds) + " elapsed";
  // Linear extrapolation to the iteration limit: an upper bound for solvers that stop when converged.
  if (p.total > 0 && p.iteration > 0 && p.iteration < p.total)
    line +=
        ", <=" + Duration(p.elapsed_seconds * double(p.total - p.iteration) / double(p.iteration)) + " left";
  return line;
}

void ProgressBar::Draw(const aosr::Progress& p) {
  if (mode_ == Mode::kRedraw) {
    // Never wider than the terminal (a wrapped line cannot be redrawn with \r): drop the bar, then cut.
    std::string text = Format(p);
    if (text.size() > std::size_t(width_ - 1)) text = Format(p, 0);
    if (text.size() > std::size_t(width_ - 1)) text.resize(std::size_t(width_ - 1));
    const std::size_t pad = drawn_ > text.size() ? drawn_ - text.size() : 0;
    std::fprintf(out_, "\r%s%s", text.c_str(), std::string(pad, ' ').c_str());
    std::fflush(out_);
    drawn_ = text.size() + pad;
    return;
  }
  if (mode_ != Mode::kLines) return;
  // A new run (another stage, or the same stage started again) first flushes the previous run's last report.
  const bool new_run = p.stage != written_stage_ || p.iteration <= seen_iteration_;
  seen_iteration_ = p.iteration;
  if (new_run) {
    if (pending_ && !written_stage_.empty()) WriteLine(last_);
    WriteLine(p);
    return;
  }
  if (p.iteration == 0 || (p.total > 0 && p.iteration >= p.total) || p.elapsed_seconds - written_at_ >= 1.0) {
    WriteLine(p);
  } else {
    last_ = p;
    pending_ = true;
  }
}

void ProgressBar::WriteLine(const aosr::Progress& p) {
  std::fprintf(out_, "[aosr] %s\n", Format(p).c_str());
  std::fflush(out_);
  written_stage_ = p.stage;
  written_at_ = p.elapsed_seconds;
  pending_ = false;
}

void ProgressBar::Clear() {
  if (mode_ == Mode::kRedraw && drawn_ > 0) {
    std::fprintf(out_, "\r%s\r", std::string(drawn_, ' ').c_str());
    std::fflush(out_);
    drawn_ = 0;
  } else if (mode_ == Mode::kLines) {
    if (pending_) WriteLine(last_);
    written_stage_.clear();
    written_at_ = -1.0;
    seen_iteration_ = -1;
  }
}

}  // namespace aosr::cli
