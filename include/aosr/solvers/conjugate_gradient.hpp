// Conjugate gradients for symmetric positive (semi-)definite systems  N x = b,  where N is given as a
// matrix-free LinearOperator (typically AᵀA + λ ΓᵀΓ built from the shared forward model).
// Stops when ||b - N x|| <= tolerance · ||b|| or at max_iterations; reports which in the summary.
#pragma once

#include "aosr/core/linear_operator.hpp"
#include "aosr/solvers/summary.hpp"

namespace aosr {

struct ConjugateGradientOptions {
  int max_iterations = 500;   // >= 1
  double tolerance = 1e-10;   // relative residual, in (0, 1)
  bool IsValid(std::string* why) const;
};

// Solves normal * x = b starting from *x (its size must be normal.cols()). Returns the summary; never
// returns NaN silently: a non-finite iterate ends the solve with Termination::kFailed and restores the
// last finite iterate.
SolverSummary ConjugateGradient(const LinearOperator& normal, const Vector& b, Vector* x,
                                const ConjugateGradientOptions& options = {});

}  // namespace aosr
