// What every reconstructor reports (DESIGN.md §3: outcomes are data).
#pragma once

#include <string>
#include <vector>

namespace aosr {

enum class Termination {
  kConverged,        // met its stopping rule (or a direct solver finished)
  kMaxIterations,    // stopped at the iteration limit without meeting the stopping rule
  kStagnated,        // stopped because progress fell to rounding level before the stopping rule was met: the
                     // estimate is as good as double precision allows, the tolerance asked for more; see message
  kFailed,           // could not produce a trustworthy result; see message
  kUserCancelled,    // the caller's progress callback returned false (core/progress.hpp): stopped at the end of
                     // that iteration with the current (finite, unconverged) estimate; message says "cancelled
                     // by the caller"
};

const char* ToString(Termination t);

struct SolverSummary {
  std::string method;
  Termination termination = Termination::kConverged;
  std::string message;         // one line a person can act on
  int iterations = 0;          // 0 for direct solvers
  double final_cost = 0.0;     // the method's objective at the returned estimate (if defined)
  double seconds = 0.0;        // wall time of the solve
  std::vector<double> frame_residual_rms;  // RMS of y_i - A_i x per frame, in frame units

  std::string BriefReport() const;
};

}  // namespace aosr
