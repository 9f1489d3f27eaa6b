// The terminal side of library progress (core/progress.hpp): one stderr line per report of a long run (TV,
// MAP, their pilot), e.g.
//
//   tv 412/1000 [########............] primal/tol 3.1  0:05 elapsed, <=0:07 left
//
// redrawn in place with \r on a terminal and erased when the run ends, or, when forced into a file or a
// pipe (--progress), written as whole lines at most once a second. Nothing ever goes to stdout, so --json
// output stays clean. The time left is the linear extrapolation elapsed · (total − i) / i to the stage's
// iteration limit: an upper bound when the solver converges before it.
#pragma once

#include <cstdio>
#include <string>

#include "aosr/core/progress.hpp"

namespace aosr::cli {

class ProgressBar {
 public:
  enum class Mode {
    kOff,     // nothing is drawn; Callback() is empty, so the solvers pay nothing
    kRedraw,  // one line redrawn with \r (stderr is a terminal)
    kLines,   // whole lines, at most one a second per stage plus each stage's first and last (logs)
  };
  // The rule of `aosr reconstruct` and `aosr tradeoff`: kOff under --json or when stderr is not a terminal,
  // unless --progress (`force`) is given; then kRedraw on a terminal, else kLines.
  static Mode Choose(bool json, bool force);

  explicit ProgressBar(Mode mode, std::FILE* out = stderr);
  ~ProgressBar();  // Clear()
  ProgressBar(const ProgressBar&) = delete;
  ProgressBar& operator=(const ProgressBar&) = delete;

  bool enabled() const { return mode_ != Mode::kOff; }
  // The callback to put in ReconstructOptions::progress (empty when off). It never cancels. It refers to
  // this object, which must outlive the runs it is given to.
  ProgressCallback Callback();
  // Ends the current display: kRedraw erases its line, kLines writes the last report not yet written.
  // Call before other stderr output and when a run ends.
  void Clear();

  // One report as text, without line ends; bar_width characters of bar when p.total > 0 (0: no bar).
  static std::string Format(const aosr::Progress& p, int bar_width = 20);
  // Seconds as m:ss, or h:mm:ss from an hour on ("?" if not finite or negative).
  static std::string Duration(double seconds);

 private:
  void Draw(const aosr::Progress& p);
  void WriteLine(const aosr::Progress& p);

  Mode mode_;
  std::FILE* out_;
  int width_ = 80;             // terminal columns (kRedraw); a line is cut to width_ − 1 so it never wraps
  std::size_t drawn_ = 0;      // characters of the line on screen (kRedraw)
  bool pending_ = false;       // kLines: `last_` not yet written
  aosr::Progress last_;        // kLines: the latest report
  std::string written_stage_;  // kLines: stage of the last written line
  double written_at_ = -1.0;   // kLines: elapsed_seconds of the last written line
  int seen_iteration_ = -1;    // kLines: iteration of the latest report (iterations rise within a run)
};

}  // namespace aosr::cli
