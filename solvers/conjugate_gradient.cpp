#include "aosr/solvers/conjugate_gradient.hpp"

#include <chrono>
#include <cmath>

#include "aosr/core/error.hpp"

namespace aosr {

bool ConjugateGradientOptions::IsValid(std::string* why) const {
  if (max_iterations < 1) return *why = "max_iterations must be >= 1", false;
  if (!(tolerance > 0 && tolerance < 1)) return *why = "tolerance must be in (0, 1)", false;
  return true;
}

SolverSummary ConjugateGradient(const LinearOperator& normal, const Vector& b, Vector* x,
                                const ConjugateGradientOptions& options) {
  std::string why;
  if (!options.IsValid(&why)) throw InvalidArgument("ConjugateGradient: " + why);
  CheckArgument(normal.rows() == normal.cols(), "ConjugateGradient", "normal", normal.name(), "a square operator");
  CheckArgument(x != nullptr && x->size() == normal.cols(), "ConjugateGradient", "x size",
                x ? x->size() : -1, std::to_string(normal.cols()));
  CheckArgument(b.size() == normal.rows(), "ConjugateGradient", "b size", b.size(), std::to_string(normal.rows()));
  CheckArgument(b.allFinite() && x->allFinite(), "ConjugateGradient", "b or x", "non-finite values", "finite");
  const auto start = std::chrono::steady_clock::now();
  SolverSummary s;
  s.method = "conjugate-gradient";
  const double bnorm = b.norm();
  Vector r = b - normal.Apply(*x);
  Vector p = r, q(b.size());
  double rr = r.squaredNorm();
  s.termination = Termination::kMaxIterations;
  if (bnorm == 0 || std::sqrt(rr) <= options.tolerance * bnorm) s.termination = Termination::kConverged;
  while (s.termination == Termination::kMaxIterations && s.iterations < options.max_iterations) {
    normal.Apply(p, q);
    const double pq = p.dot(q);
    if (!(pq > 0)) {  // zero curvature: x is a least-squares solution within the range already reached
      s.termination = std::isfinite(pq) ? Termination::kConverged : Termination::kFailed;
      s.message = "stopped on non-positive curvature p'Np = " + ToString(pq);
      break;
    }
    const double alpha = rr / pq;
    x->noalias() += alpha * p;
    r.noalias() -= alpha * q;
    const double rr_new = r.squaredNorm();
    ++s.iterations;
    if (!std::isfinite(rr_new)) {
      x->noalias() -= alpha * p;
      s.termination = Termination::kFailed;
      s.message = "non-finite residual; returned the last finite iterate";
      break;
    }
    if (std::sqrt(rr_new) <= options.tolerance * bnorm) s.termination = Termination::kConverged;
    p = r + (rr_new / rr) * p;
    rr = rr_new;
  }
  s.final_cost = bnorm > 0 ? std::sqrt(rr) / bnorm : 0.0;
  if (s.message.empty()) s.message = "relative residual " + ToString(s.final_cost);
  s.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return s;
}

}  // namespace aosr
