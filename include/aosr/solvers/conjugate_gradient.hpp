// Conjugate gradients for symmetric positive (semi-)definite systems  N x = b,  where N is given as a
// matrix-free LinearOperator (typically AᵀWA + λ ΓᵀΓ built from the shared forward model).
//
// Plain CG needs about √κ(N) iterations, κ the condition number. Preconditioned CG (PCG) runs the same
// recurrence on M⁻¹N, where the preconditioner M⁻¹ ≈ N⁻¹ is symmetric positive definite and cheap to apply;
// its cost then follows √κ(M⁻¹N). An exact inverse (M = N) converges in one iteration; an inverse of a
// nearby operator (e.g. the Fourier-diagonal uniform-weight Tikhonov inverse for a masked problem, see
// tikhonov.hpp) leaves M⁻¹N = I + (a few outlying eigenvalues), which CG resolves in as many iterations.
//
// Both variants stop when the true-system residual ||b − N x|| ≤ tolerance · ||b|| (not the
// preconditioned norm), so iteration counts of CG and PCG on one system are comparable; at
// max_iterations; or, with Termination::kStagnated, when the residual reaches the rounding floor
// 16ε(||b|| + ||N||·||x||) (||N|| estimated by the largest Rayleigh quotient seen) before the tolerance: a
// tolerance below what double precision can deliver for this system is reported, not iterated on.
// The summary says which.
#pragma once

#include "aosr/core/linear_operator.hpp"
#include "aosr/core/progress.hpp"
#include "aosr/solvers/summary.hpp"

namespace aosr {

struct ConjugateGradientOptions {
  int max_iterations = 500;   // >= 1
  double tolerance = 1e-10;   // relative residual ||b − N x|| / ||b||, in (0, 1)
  bool IsValid(std::string* why) const;
};

// Progress and cancellation of one solve (core/progress.hpp): a report per iteration (rate-limited) as
// `stage`, value the relative residual ("residual"). Returning false stops the solve with the current iterate
// and Termination::kUserCancelled. An empty callback (the default) costs nothing.
struct ConjugateGradientProgress {
  ProgressCallback callback;
  std::string stage = "cg";
};

// Solves normal * x = b starting from *x (its size must be normal.cols()). Returns the summary; never
// returns NaN silently: a non-finite iterate ends the solve with Termination::kFailed and restores the
// last finite iterate.
SolverSummary ConjugateGradient(const LinearOperator& normal, const Vector& b, Vector* x,
                                const ConjugateGradientOptions& options = {},
                                const ConjugateGradientProgress& progress = {});

// Preconditioned CG: `preconditioner` applies M⁻¹ (square, same size as `normal`, symmetric positive
// definite; only Apply is used). With the identity it takes the same iterations as ConjugateGradient.
// A preconditioner that is found not to be positive (rᵀM⁻¹r <= 0 for r != 0) ends the solve with
// Termination::kFailed and says so.
SolverSummary PreconditionedConjugateGradient(const LinearOperator& normal,
                                              const LinearOperator& preconditioner, const Vector& b, Vector* x,
                                              const ConjugateGradientOptions& options = {},
                                              const ConjugateGradientProgress& progress = {});

}  // namespace aosr
