#include "aosr/core/adjoint_test.hpp"

#include <cmath>
#include <random>

namespace aosr {

AdjointTestResult AdjointTest(const LinearOperator& op, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> n01;
  Vector x(op.cols()), y(op.rows());
  for (Index i = 0; i < x.size(); ++i) x[i] = n01(rng);
  for (Index i = 0; i < y.size(); ++i) y[i] = n01(rng);
  const Vector ax = op.Apply(x);
  const Vector aty = op.ApplyAdjoint(y);
  const double lhs = ax.dot(y), rhs = x.dot(aty);
  AdjointTestResult r;
  const double denom = std::abs(lhs) + std::abs(rhs);
  r.adjoint_error = denom > 0 ? std::abs(lhs - rhs) / denom : 0.0;
  const Vector ata = op.ApplyAdjoint(ax);
  const Vector normal = op.ApplyNormal(x);
  const double scale = ata.norm();
  r.normal_error = scale > 0 ? (ata - normal).norm() / scale : normal.norm();
  return r;
}

}  // namespace aosr
