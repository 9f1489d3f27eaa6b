#include "aosr/solvers/conjugate_gradient.hpp"

#include <chrono>
#include <algorithm>
#include <cmath>
#include <limits>

#include "aosr/core/error.hpp"

namespace aosr {

bool ConjugateGradientOptions::IsValid(std::string* why) const {
  auto fail = [why](const std::string& m) {
    if (why) *why = m;
    return false;
  };
  if (max_iterations < 1) return fail("max_iterations must be >= 1, got " + std::to_string(max_iterations));
  if (!(tolerance > 0 && tolerance < 1))
    return fail("tolerance must be in (0, 1), got " + ToString(tolerance));
  return true;
}

namespace {

// The CG recurrence on M⁻¹N (M⁻¹ = I when `preconditioner` is null). Residuals r are of the true system.
SolverSummary Solve(const char* function, const LinearOperator& normal, const LinearOperator* preconditioner,
                    const Vector& b, Vector* x, const ConjugateGradientOptions& options,
                    const ConjugateGradientProgress& progress) {
  std::string why;
  if (!options.IsValid(&why)) throw InvalidArgument(std::string(function) + ": options." + why);
  CheckArgument(normal.rows() == normal.cols(), function, "normal", normal.name(), "a square operator");
  if (preconditioner)
    CheckArgument(preconditioner->rows() == normal.rows() && preconditioner->cols() == normal.cols(),
                  function, "preconditioner",
                  preconditioner->name() + " (" + std::to_string(preconditioner->rows()) + "x" +
                      std::to_string(preconditioner->cols()) + ")",
                  "a square operator of the normal's size " + std::to_string(normal.rows()));
  CheckArgument(x != nullptr && x->size() == normal.cols(), function, "x size", x ? x->size() : -1,
                std::to_string(normal.cols()));
  CheckArgument(b.size() == normal.rows(), function, "b size", b.size(), std::to_string(normal.rows()));
  CheckArgument(b.allFinite() && x->allFinite(), function, "b or x", "non-finite values", "finite");
  const auto start = std::chrono::steady_clock::now();
  SolverSummary s;
  s.method = preconditioner ? "preconditioned-conjugate-gradient" : "conjugate-gradient";
  const double bnorm = b.norm();
  Vector r = b - normal.Apply(*x);
  Vector z = preconditioner ? preconditioner->Apply(r) : r;
  Vector p = z, q(b.size());
  double rz = r.dot(z);
  double rnorm = r.norm();
  // Stagnation: in double precision the residual of the computed x cannot fall below about
  // ε(||b|| + ||N||·||x||) (rounding of b − Nx). ||N|| is estimated from below by the largest Rayleigh
  // quotient p'Np/p'p seen. Once the residual reaches kFloorFactor times that floor without meeting the
  // tolerance, further iterations only stir rounding: stop and say so (Termination::kStagnated).
  constexpr double kFloorFactor = 16.0;
  const double eps = std::numeric_limits<double>::epsilon();
  double n_norm = 0;
  auto floor = [&] { return kFloorFactor * eps * (bnorm + n_norm * x->norm()); };
  s.termination = Termination::kMaxIterations;
  if (bnorm == 0 || rnorm <= options.tolerance * bnorm) s.termination = Termination::kConverged;
  ProgressReporter reporter(progress.callback, progress.stage, options.max_iterations, "residual");
  auto relative = [&] { return bnorm > 0 ? rnorm / bnorm : 0.0; };
  while (s.termination == Termination::kMaxIterations && s.iterations < options.max_iterations) {
    if (!(rz > 0)) {
      // r != 0 here, so rᵀM⁻¹r <= 0 means M⁻¹ is not positive definite, or that r is rounding noise.
      if (rnorm <= floor()) {
        s.termination = Termination::kStagnated;
        s.message = "residual at the rounding floor (r'M^-1 r = " + ToString(rz) + ")";
      } else {
        s.termination = Termination::kFailed;
        s.message = "preconditioner not positive definite: r'M^-1 r = " + ToString(rz);
      }
      break;
    }
    normal.Apply(p, q);
    const double pq = p.dot(q);
    if (!(pq > 0)) {  // zero curvature: x is a least-squares solution within the range already reached
      s.termination = std::isfinite(pq) ? Termination::kConverged : Termination::kFailed;
      s.message = "stopped on non-positive curvature p'Np = " + ToString(pq);
      break;
    }
    n_norm = std::max(n_norm, pq / p.squaredNorm());
    const double alpha = rz / pq;
    x->noalias() += alpha * p;
    r.noalias() -= alpha * q;
    const double rnorm_new = r.norm();
    ++s.iterations;
    if (!std::isfinite(rnorm_new)) {
      x->noalias() -= alpha * p;
      s.termination = Termination::kFailed;
      s.message = "non-finite residual; returned the last finite iterate";
      break;
    }
    rnorm = rnorm_new;
    if (rnorm <= options.tolerance * bnorm) {
      s.termination = Termination::kConverged;
      break;
    }
    if (rnorm <= floor()) {
      s.termination = Termination::kStagnated;
      s.message = "residual " + ToString(rnorm / bnorm) + " (relative) reached the rounding floor " +
                  ToString(floor() / bnorm) + " = 16 eps (||b|| + ||N|| ||x||) / ||b|| before the tolerance " +
                  ToString(options.tolerance);
      break;
    }
    if (preconditioner) {
      preconditioner->Apply(r, z);
    } else {
      z = r;
    }
    const double rz_new = r.dot(z);
    p = z + (rz_new / rz) * p;
    rz = rz_new;
    if (!reporter.Report(s.iterations, relative(), s.iterations == options.max_iterations)) {
      s.termination = Termination::kUserCancelled;
      s.message = "cancelled by the caller after " + std::to_string(s.iterations) + " iterations (relative residual " +
                  ToString(relative()) + ")";
      break;
    }
  }
  reporter.Finish(s.iterations, relative());
  reporter.RethrowIfThrown();
  s.final_cost = bnorm > 0 ? rnorm / bnorm : 0.0;
  if (s.message.empty()) s.message = "relative residual " + ToString(s.final_cost);
  s.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return s;
}

}  // namespace

SolverSummary ConjugateGradient(const LinearOperator& normal, const Vector& b, Vector* x,
                                const ConjugateGradientOptions& options, const ConjugateGradientProgress& progress) {
  return Solve("ConjugateGradient", normal, nullptr, b, x, options, progress);
}

SolverSummary PreconditionedConjugateGradient(const LinearOperator& normal,
                                              const LinearOperator& preconditioner, const Vector& b,
                                              Vector* x, const ConjugateGradientOptions& options,
                                              const ConjugateGradientProgress& progress) {
  return Solve("PreconditionedConjugateGradient", normal, &preconditioner, b, x, options, progress);
}

}  // namespace aosr
