#include "aosr/solvers/conjugate_gradient.hpp"

#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cmath>
#include <random>

namespace aosr {
namespace AOSR_TEST_NS {

// A dense symmetric matrix as a LinearOperator.
class DenseOp final : public LinearOperator {
 public:
  explicit DenseOp(Eigen::MatrixXd m) : LinearOperator(m.rows(), m.cols(), "Dense"), m_(std::move(m)) {}

 private:
  void ApplyImpl(ConstRef x, Ref y) const override { y = m_ * x; }
  void ApplyAdjointImpl(ConstRef y, Ref x) const override { x = m_.transpose() * y; }
  Eigen::MatrixXd m_;
};

// SPD with eigenvalues spread over 1 .. 1e4 (κ = 1e4), in a random basis.
Eigen::MatrixXd IllConditioned(int n, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> n01;
  Eigen::MatrixXd g(n, n);
  for (Index i = 0; i < g.size(); ++i) g.data()[i] = n01(rng);
  const Eigen::MatrixXd q = Eigen::HouseholderQR<Eigen::MatrixXd>(g).householderQ();
  Eigen::VectorXd d(n);
  for (int i = 0; i < n; ++i) d[i] = std::pow(1e4, double(i) / (n - 1));
  return q * d.asDiagonal() * q.transpose();
}

TEST(ConjugateGradientTest, SolvesAnSpdSystem) {
  const Eigen::MatrixXd a = IllConditioned(60, 1);
  const Vector b = Vector::LinSpaced(60, -1, 2);
  Vector x = Vector::Zero(60);
  const SolverSummary s = ConjugateGradient(DenseOp(a), b, &x);
  ASSERT_EQ(s.termination, Termination::kConverged) << s.BriefReport();
  EXPECT_LT((a * x - b).norm(), 1e-10 * b.norm() * 1.0001);
  // Rounding spoils the n-step termination of exact arithmetic at κ = 1e4; the κ bound ½√κ ln(2/tol) holds.
  EXPECT_LE(s.iterations, 0.5 * std::sqrt(1e4) * std::log(2 / 1e-10));
}

// A tolerance below what double precision can deliver is reported as stagnation at the rounding floor,
// not iterated on to the cap; the iterate returned is as accurate as the system allows.
TEST(ConjugateGradientTest, ToleranceBelowRoundingStopsAsStagnated) {
  const Eigen::MatrixXd a = IllConditioned(60, 3);
  const Vector b = Vector::LinSpaced(60, -1, 2);
  Vector x = Vector::Zero(60);
  ConjugateGradientOptions o;
  o.tolerance = 1e-19;  // below ε: unreachable
  o.max_iterations = 5000;
  const SolverSummary s = ConjugateGradient(DenseOp(a), b, &x, o);
  EXPECT_EQ(s.termination, Termination::kStagnated) << s.BriefReport();
  EXPECT_LT(s.iterations, 1000) << "stagnation must be detected, not run to the cap";
  EXPECT_LT((a * x - b).norm(), 1e-12 * b.norm()) << "the stagnated iterate is still the solution to rounding";
  EXPECT_NE(s.message.find("rounding floor"), std::string::npos) << s.message;
}

// The identity preconditioner is plain CG; the exact inverse converges in one step; a good approximate
// inverse (the exact one of a rank-2 perturbation) in about three.
TEST(ConjugateGradientTest, PreconditioningCutsIterations) {
  const int n = 80;
  const Eigen::MatrixXd a = IllConditioned(n, 2);
  const Vector b = Vector::LinSpaced(n, 1, 3);
  ConjugateGradientOptions o;
  o.tolerance = 1e-12;
  Vector x0 = Vector::Zero(n), x1 = Vector::Zero(n), x2 = Vector::Zero(n), x3 = Vector::Zero(n);
  const SolverSummary plain = ConjugateGradient(DenseOp(a), b, &x0, o);
  const SolverSummary ident =
      PreconditionedConjugateGradient(DenseOp(a), DenseOp(Eigen::MatrixXd::Identity(n, n)), b, &x1, o);
  EXPECT_EQ(plain.iterations, ident.iterations);
  EXPECT_LT((x0 - x1).norm(), 1e-12 * x0.norm());
  const Eigen::MatrixXd inv = a.inverse();
  const SolverSummary exact = PreconditionedConjugateGradient(DenseOp(a), DenseOp(inv), b, &x2, o);
  EXPECT_EQ(exact.termination, Termination::kConverged);
  EXPECT_EQ(exact.iterations, 1);
  Eigen::MatrixXd nearby = a;
  const Vector u = Vector::Ones(n), v = Vector::LinSpaced(n, 0, 1);
  nearby += 50 * u * u.transpose() + 20 * v * v.transpose();
  const SolverSummary approx =
      PreconditionedConjugateGradient(DenseOp(a), DenseOp(nearby.inverse()), b, &x3, o);
  EXPECT_EQ(approx.termination, Termination::kConverged) << approx.BriefReport();
  EXPECT_LE(approx.iterations, 4);
  EXPECT_GT(plain.iterations, 40);
  EXPECT_LT((a * x3 - b).norm(), 1e-11 * b.norm());
}

TEST(ConjugateGradientTest, NonPositivePreconditionerIsReportedNotThrown) {
  const int n = 10;
  const Eigen::MatrixXd a = IllConditioned(n, 3);
  Vector x = Vector::Zero(n);
  const SolverSummary s = PreconditionedConjugateGradient(
      DenseOp(a), DenseOp(-Eigen::MatrixXd::Identity(n, n)), Vector::Ones(n), &x);
  EXPECT_EQ(s.termination, Termination::kFailed);
  EXPECT_NE(s.message.find("not positive definite"), std::string::npos) << s.message;
  EXPECT_TRUE(x.allFinite());
}

}  // namespace
}  // namespace aosr
