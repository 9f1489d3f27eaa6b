// Ceres' termination types in the solvers' vocabulary (summary.hpp), written once for every Ceres caller.
#pragma once

#include <ceres/types.h>

#include "aosr/solvers/summary.hpp"

namespace aosr {

// CONVERGENCE and USER_SUCCESS converged; NO_CONVERGENCE hit an iteration or time limit; anything else
// (FAILURE, USER_FAILURE) failed.
inline Termination TerminationOf(ceres::TerminationType t) {
  switch (t) {
    case ceres::CONVERGENCE:
    case ceres::USER_SUCCESS:
      return Termination::kConverged;
    case ceres::NO_CONVERGENCE:
      return Termination::kMaxIterations;
    default:
      return Termination::kFailed;
  }
}

}  // namespace aosr
