#include "aosr/solvers/summary.hpp"

#include <sstream>

namespace aosr {

const char* ToString(Termination t) {
  switch (t) {
    case Termination::kConverged: return "converged";
    case Termination::kMaxIterations: return "max-iterations";
    case Termination::kStagnated: return "stagnated";
    case Termination::kFailed: return "failed";
    case Termination::kUserCancelled: return "cancelled";
  }
  return "unknown";
}

std::string SolverSummary::BriefReport() const {
  std::ostringstream os;
  os << method << ": " << ToString(termination) << ", " << iterations << " iterations, cost " << final_cost
     << ", " << seconds << " s";
  if (!message.empty()) os << " (" << message << ")";
  return os.str();
}

}  // namespace aosr
