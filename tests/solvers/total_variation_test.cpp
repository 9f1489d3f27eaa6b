#include "aosr/solvers/total_variation.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>
#include <memory>
#include <random>
#include <thread>
#include <vector>

#include "aosr/core/operators.hpp"
#include "aosr/core/parallel.hpp"
#include "aosr/solvers/conjugate_gradient.hpp"
#include "aosr/solvers/fourier_normal_system.hpp"
#include "aosr/solvers/tikhonov.hpp"
#include "support/testing.hpp"
#include "total_variation_fixture.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

using tv_test::NoisyProblem;
using tv_test::RasterModel;
using tv_test::RelativeDifference;
using tv_test::SmallProblem;

// The exact per-frequency x-update solves (w AᵀA + a ∇ᵀ∇ + b I) x = rhs: its residual in the spatial
// operator (built independently from the core primitives) vanishes, and CG on that operator agrees.
TEST(TotalVariationTest, FourierXUpdateEqualsConjugateGradientSolveOfTheSameSystem) {
  for (int r : {2, 3})
    for (auto [a, b] : std::vector<std::pair<double, double>>{{0.7, 0.0}, {0.7, 0.3}, {0.0, 0.2}}) {
      const Shape hr{6 * r, 8 * r};
      const auto m = RasterModel(hr, r, {{0, 0}, {0.5, 1}, {1.3, 0.2}}, 1.1);
      const double w = 2.5;
      FourierNormalSystem system(*m, w);
      system.Factorize(a, b);
      const Image rhs = test::RandomImage(hr, 7);
      const Image x = system.Solve(rhs);
      const OperatorPtr normal =
          Sum({Scale(w, Normal(m->Operator())), Scale(a, Normal(Gradient(hr, Boundary::kPeriodic))),
               Scale(b, Identity(hr.size()))});
      const double residual = (normal->Apply(AsVector(x)) - AsVector(rhs)).norm() / AsVector(rhs).norm();
      EXPECT_LT(residual, 1e-10) << "r=" << r << " a=" << a << " b=" << b;
      Vector xcg = Vector::Zero(hr.size());
      ConjugateGradientOptions cg;
      cg.max_iterations = 5000;
      // 1e-12, not 1e-13: this system's rounding floor 16ε(||b|| + ||N||·||x||)/||b|| is 3.4e-13, and CG now
      // reports a tolerance below its floor as stagnation (conjugate_gradient.hpp). 1e-12 is ample for the
      // 1e-8 agreement checked below.
      cg.tolerance = 1e-12;
      const SolverSummary s = ConjugateGradient(*normal, AsVector(rhs), &xcg, cg);
      ASSERT_EQ(s.termination, Termination::kConverged) << s.BriefReport();
      EXPECT_LT((AsVector(x) - xcg).norm() / xcg.norm(), 1e-8) << "r=" << r << " a=" << a << " b=" << b;
      EXPECT_EQ(system.singular_bins(), 0);
    }
}

// With a = b = 0 and fewer frames than r² every bin is singular: Solve returns the minimum-norm solution,
// which for a consistent right-hand side rhs = N x₀ solves the system and is no longer than x₀.
TEST(TotalVariationTest, SingularBinsGetTheMinimumNormSolution) {
  const Shape hr{12, 16};
  const auto m = RasterModel(hr, 2, {{0, 0}, {0.5, 1}}, 1.1);
  FourierNormalSystem system(*m, 1.0);
  system.Factorize(0.0, 0.0);
  EXPECT_EQ(system.singular_bins(), m->lr_shape().size());
  const Image x0 = test::RandomImage(hr, 3);
  const OperatorPtr normal = Normal(m->Operator());
  const Vector rhs = normal->Apply(AsVector(x0));
  const Image x = system.Solve(ToImage(rhs, hr));
  EXPECT_LT((normal->Apply(AsVector(x)) - rhs).norm() / rhs.norm(), 1e-9);
  EXPECT_LT(AsVector(x).norm(), AsVector(x0).norm());
}

// The TV problem is convex: ADMM must reach the same optimum from x = 0 and from a random image.
// (Measured: 32x32 HR, μ = 0.05, ε_rel = 1e-7 takes about 1000-2000 iterations from either start.)
TEST(TotalVariationTest, ConvergesToTheSameOptimumFromTwoStarts) {
  for (bool positivity : {false, true}) {
    const ReconstructionProblem p = SmallProblem();
    TotalVariationOptions o;
    o.mu = 0.05;
    o.positivity = positivity;
    o.relative_tolerance = 1e-7;
    o.max_iterations = 20000;
    TotalVariationSummary s0, s1;
    const Image x0 = TotalVariationAdmm(p, o, &s0);
    const Image start = 3.0 * test::RandomImage(p.model->hr_shape(), 11);
    const Image x1 = TotalVariationAdmm(p, o, &s1, &start);
    ASSERT_EQ(s0.termination, Termination::kConverged) << s0.BriefReport();
    ASSERT_EQ(s1.termination, Termination::kConverged) << s1.BriefReport();
    EXPECT_LT(RelativeDifference(x0, x1), 1e-4) << "positivity " << positivity;
    EXPECT_LT(std::abs(s0.final_cost - s1.final_cost) / s0.final_cost, 1e-4) << "positivity " << positivity;
    EXPECT_EQ(s0.method, "tv");
    EXPECT_EQ(s0.x_update, TotalVariationXUpdate::kFourier);
    EXPECT_LE(s0.primal_residual, s0.primal_tolerance);
    EXPECT_LE(s0.dual_residual, s0.dual_tolerance);
    // The summary's cost is the objective at the returned image, and its data part is WeightedDataMisfit.
    EXPECT_NEAR(s0.final_cost, TotalVariationObjective(p, x0, o.mu), 1e-12 * s0.final_cost);
    EXPECT_NEAR(s0.data_misfit, WeightedDataMisfit(p, x0), 1e-12 * s0.data_misfit);
    EXPECT_EQ(s0.frame_residual_rms.size(), 4u);
  }
}

// The Tikhonov (gradient prior) solution is a feasible point of the TV problem; the TV optimum must be
// below it in the TV objective, and ADMM warm-started from it must improve on it.
TEST(TotalVariationTest, EndsBelowTheTikhonovSolutionInTheTvObjective) {
  const ReconstructionProblem p = SmallProblem();
  TikhonovOptions t;
  t.prior = TikhonovPrior::kGradient;
  t.lambda = 0.05;
  const Image x_tik = TikhonovFourier(*p.model, p.frames, t);
  TotalVariationOptions o;
  o.mu = 0.05;
  o.record_history = true;
  TotalVariationSummary s_cold, s_warm;
  const Image x_cold = TotalVariationAdmm(p, o, &s_cold);
  const Image x_warm = TotalVariationAdmm(p, o, &s_warm, &x_tik);
  const double f_tik = TotalVariationObjective(p, x_tik, o.mu);
  EXPECT_LT(s_cold.final_cost, f_tik);
  EXPECT_LT(s_warm.final_cost, f_tik);
  EXPECT_LT(TotalVariationObjective(p, x_cold, o.mu), f_tik);
  EXPECT_LT(TotalVariationObjective(p, x_warm, o.mu), f_tik);
  // The recorded objective ends far below where the cold start began, and the history is complete.
  ASSERT_EQ(s_cold.history_cost.size(), std::size_t(s_cold.iterations));
  EXPECT_EQ(s_cold.history_primal.size(), std::size_t(s_cold.iterations));
  EXPECT_EQ(s_cold.history_rho.size(), std::size_t(s_cold.iterations));
  EXPECT_LT(s_cold.history_cost.back(), s_cold.history_cost.front());
}

// Both x-update paths solve the same subproblem, so they reach the same optimum.
TEST(TotalVariationTest, FourierAndConjugateGradientPathsReachTheSameOptimum) {
  const ReconstructionProblem p = SmallProblem();
  TotalVariationOptions o;
  o.mu = 0.05;
  o.relative_tolerance = 1e-7;
  o.max_iterations = 20000;
  TotalVariationSummary sf, sc;
  o.x_update = TotalVariationXUpdate::kFourier;
  const Image xf = TotalVariationAdmm(p, o, &sf);
  o.x_update = TotalVariationXUpdate::kConjugateGradient;
  const Image xc = TotalVariationAdmm(p, o, &sc);
  ASSERT_EQ(sf.termination, Termination::kConverged) << sf.BriefReport();
  ASSERT_EQ(sc.termination, Termination::kConverged) << sc.BriefReport();
  EXPECT_EQ(sc.x_update, TotalVariationXUpdate::kConjugateGradient);
  EXPECT_GT(sc.cg_iterations, 0);
  EXPECT_EQ(sf.cg_iterations, 0);
  EXPECT_LT(RelativeDifference(xf, xc), 1e-4);
}

// Photon-noise-like weights (varying over two decades) and masked pixels: the split-data path and CG on the
// unsplit system solve the same convex problem, so they reach the same optimum, and the split path's
// stopping rule (whose dual part is a bound) does not stop early: its objective is as low as CG's.
TEST(TotalVariationTest, SplitDataPathAndConjugateGradientAgreeOnWeightedMaskedData) {
  for (bool positivity : {false, true}) {
    ReconstructionProblem p = SmallProblem();
    std::mt19937_64 rng(5);
    std::uniform_real_distribution<double> decades(-1.0, 1.0);
    p.weights.clear();
    for (std::size_t i = 0; i < p.frames.size(); ++i) {
      Image w(16, 16);
      for (Index k = 0; k < w.size(); ++k) w.data()[k] = 400.0 * std::pow(10.0, decades(rng));
      w(3, 4 + int(i)) = 0.0;  // a bad pixel per frame
      p.weights.push_back(w);
    }
    p.frames[1](3, 5) = std::numeric_limits<double>::quiet_NaN();
    TotalVariationOptions o;
    o.mu = 20.0;
    o.positivity = positivity;
    o.relative_tolerance = 1e-7;
    o.max_iterations = 20000;
    TotalVariationSummary ss, sc;
    o.x_update = TotalVariationXUpdate::kFourierSplit;
    const Image xs = TotalVariationAdmm(p, o, &ss);
    o.x_update = TotalVariationXUpdate::kConjugateGradient;
    const Image xc = TotalVariationAdmm(p, o, &sc);
    ASSERT_EQ(ss.termination, Termination::kConverged) << ss.BriefReport();
    ASSERT_EQ(sc.termination, Termination::kConverged) << sc.BriefReport();
    EXPECT_EQ(ss.x_update, TotalVariationXUpdate::kFourierSplit);
    EXPECT_EQ(ss.cg_iterations, 0);
    EXPECT_LT(RelativeDifference(xs, xc), 1e-4) << "positivity " << positivity;
    EXPECT_LT(std::abs(ss.final_cost - sc.final_cost) / sc.final_cost, 1e-5) << "positivity " << positivity;
    std::printf("positivity %d: split %d iterations, CG %d iterations (%d CG steps)\n", int(positivity),
                ss.iterations, sc.iterations, sc.cg_iterations);
  }
}

// With uniform weights the split path solves the same problem as the exact Fourier path.
TEST(TotalVariationTest, SplitDataPathMatchesTheFourierPathOnUniformWeights) {
  const ReconstructionProblem p = SmallProblem();
  TotalVariationOptions o;
  o.mu = 0.05;
  o.relative_tolerance = 1e-7;
  o.max_iterations = 20000;
  TotalVariationSummary sf, ss;
  o.x_update = TotalVariationXUpdate::kFourier;
  const Image xf = TotalVariationAdmm(p, o, &sf);
  o.x_update = TotalVariationXUpdate::kFourierSplit;
  const Image xs = TotalVariationAdmm(p, o, &ss);
  ASSERT_EQ(ss.termination, Termination::kConverged) << ss.BriefReport();
  EXPECT_LT(RelativeDifference(xf, xs), 1e-4);
  EXPECT_LT(std::abs(sf.final_cost - ss.final_cost) / sf.final_cost, 1e-6);
}

// A pixel with weight 0 is never read: a NaN there gives exactly what any finite value gives.
TEST(TotalVariationTest, MaskedNaNPixelDoesNotChangeTheOutput) {
  ReconstructionProblem p = SmallProblem();
  p.weights = ImageStack(p.frames.size(), Image::Ones(16, 16));
  p.weights[2](5, 9) = 0.0;
  TotalVariationOptions o;
  o.mu = 0.05;
  o.max_iterations = 100;
  ReconstructionProblem q = p;
  p.frames[2](5, 9) = std::numeric_limits<double>::quiet_NaN();
  q.frames[2](5, 9) = 1e6;
  TotalVariationSummary sp, sq;
  const Image xp = TotalVariationAdmm(p, o, &sp);
  const Image xq = TotalVariationAdmm(q, o, &sq);
  EXPECT_EQ(sp.x_update, TotalVariationXUpdate::kFourierSplit);  // a mask: the data term is split off
  ASSERT_TRUE(AllFinite(xp));
  EXPECT_LE((xp - xq).abs().maxCoeff(), 1e-12 * xq.abs().maxCoeff());
  EXPECT_EQ(sp.iterations, sq.iterations);
  for (double rms : sp.frame_residual_rms) EXPECT_TRUE(std::isfinite(rms));
}

TEST(TotalVariationTest, MaxIterationsIsReportedWithAFiniteResult) {
  const ReconstructionProblem p = SmallProblem();
  TotalVariationOptions o;
  o.mu = 0.05;
  o.max_iterations = 3;
  TotalVariationSummary s;
  const Image x = TotalVariationAdmm(p, o, &s);
  EXPECT_EQ(s.termination, Termination::kMaxIterations);
  EXPECT_EQ(s.iterations, 3);
  EXPECT_TRUE(AllFinite(x));
  EXPECT_TRUE(std::isfinite(s.final_cost));
  EXPECT_GT(s.primal_residual + s.dual_residual, 0.0);
  EXPECT_FALSE(s.message.empty());
}

// A run resumed from its state (TotalVariationState: x, the splits, the scaled duals and ρ) continues where it
// stopped: K + K iterations equal 2K in one run to rounding (ρ fixed: residual balancing counts its updates per
// run), with and without positivity. Restarting from x alone (duals at 0, what `initial` does) is a different,
// farther path: its distance to the single run is orders of magnitude larger.
TEST(TotalVariationTest, ResumingFromTheStateContinuesTheRun) {
  for (bool positivity : {false, true}) {
    const ReconstructionProblem p = SmallProblem();
    TotalVariationOptions o;
    o.mu = 0.05;
    o.positivity = positivity;
    o.adaptive_rho = false;
    o.relative_tolerance = 1e-14;  // no stop before the iteration limit
    o.max_iterations = 40;
    const Image whole = TotalVariationAdmm(p, o);
    o.max_iterations = 20;
    TotalVariationState state;
    TotalVariationSummary first, second;
    const Image half = TotalVariationAdmm(p, o, &first, nullptr, &state);
    ASSERT_FALSE(state.empty());
    EXPECT_EQ(state.rho, first.final_rho);
    EXPECT_EQ(state.z.size(), 2 * p.model->hr_shape().size());
    EXPECT_EQ(state.v.size(), positivity ? p.model->hr_shape().size() : 0);
    ASSERT_TRUE(state.cache.system);  // the Fourier x-update's system, kept for the next run
    TotalVariationState uncached = state;
    uncached.cache = {};
    const Image resumed = TotalVariationAdmm(p, o, &second, nullptr, &state);
    EXPECT_EQ(second.initial_rho, first.final_rho);
    // Reusing the kept system changes no bit.
    const Image rebuilt = TotalVariationAdmm(p, o, nullptr, nullptr, &uncached);
    EXPECT_EQ(std::memcmp(resumed.data(), rebuilt.data(), sizeof(double) * std::size_t(resumed.size())), 0);
    EXPECT_LT(RelativeDifference(resumed, whole), 1e-12) << "positivity " << positivity;
    const Image restarted = TotalVariationAdmm(p, o, nullptr, &half);
    EXPECT_GT(RelativeDifference(restarted, whole), 1e3 * std::max(RelativeDifference(resumed, whole), 1e-15))
        << "positivity " << positivity;
  }
}

// The optional relative-change rule stops earlier than the residual rule, and says why.
TEST(TotalVariationTest, ChangeToleranceStopsOnASmallStep) {
  const ReconstructionProblem p = SmallProblem();
  TotalVariationOptions o;
  o.mu = 0.05;
  o.relative_tolerance = 1e-8;
  TotalVariationSummary s_residual, s_change;
  TotalVariationAdmm(p, o, &s_residual);
  o.change_tolerance = 1e-3;
  TotalVariationAdmm(p, o, &s_change);
  EXPECT_EQ(s_change.termination, Termination::kConverged) << s_change.BriefReport();
  EXPECT_LT(s_change.iterations, s_residual.iterations);
  EXPECT_NE(s_change.message.find("relative change"), std::string::npos) << s_change.message;
}

// Valid but absurdly scaled data (|y| ~ 1e300: every squared norm overflows) cannot be solved in double
// precision. That is reported as kFailed with a finite image, on both x-update paths; NaN never leaks.
TEST(TotalVariationTest, DataTooLargeForDoublePrecisionFailWithAFiniteResult) {
  for (TotalVariationXUpdate path : {TotalVariationXUpdate::kFourier, TotalVariationXUpdate::kFourierSplit,
                                     TotalVariationXUpdate::kConjugateGradient}) {
    ReconstructionProblem p = SmallProblem();
    for (Image& f : p.frames) f *= 1e300;
    TotalVariationOptions o;
    o.x_update = path;
    TotalVariationSummary s;
    const Image x = TotalVariationAdmm(p, o, &s);
    EXPECT_EQ(s.termination, Termination::kFailed) << s.BriefReport();
    EXPECT_TRUE(AllFinite(x));
    EXPECT_NE(s.message.find("double precision"), std::string::npos) << s.message;
  }
}

// Stars on a dark sky with noise: the unconstrained optimum dips below zero, the constrained one does not,
// and the constraint can only raise the optimal objective.
TEST(TotalVariationTest, PositivityHoldsWhenEnabled) {
  const Shape hr{36, 36};
  const auto m = RasterModel(hr, 3, {{0, 0}, {1.3, 0.4}, {2.1, 2.2}}, 1.4);
  Image truth = Image::Zero(hr.rows, hr.cols);
  std::mt19937_64 rng(3);
  std::uniform_int_distribution<int> pick(0, 35);
  for (int k = 0; k < 8; ++k) truth(pick(rng), pick(rng)) += 5.0 + k;
  const ReconstructionProblem p = NoisyProblem(m, truth, 0.1, 2);
  TotalVariationOptions o;
  o.mu = 0.05;
  o.relative_tolerance = 1e-6;
  o.max_iterations = 20000;
  TotalVariationSummary s_free, s_pos;
  const Image x_free = TotalVariationAdmm(p, o, &s_free);
  o.positivity = true;
  const Image x_pos = TotalVariationAdmm(p, o, &s_pos);
  EXPECT_EQ(s_pos.termination, Termination::kConverged) << s_pos.BriefReport();
  EXPECT_LT(x_free.minCoeff(), -0.01) << "the test needs a problem where the constraint is active";
  EXPECT_GE(x_pos.minCoeff(), 0.0);
  EXPECT_GT(s_pos.final_cost, s_free.final_cost * (1 - 1e-6));
}

// Above a critical μ the TV optimum is the constant c that best fits the data: with unit-sum PSFs every
// LR pixel of A·1 is r², so c = mean(y) / r² (exact for uniform weights).
TEST(TotalVariationTest, LargeMuGivesTheConstantThatFitsTheData) {
  const ReconstructionProblem p = SmallProblem();
  double mean = 0;
  for (const Image& f : p.frames) mean += f.mean();
  const double c = mean / p.frame_count() / 4.0;
  TotalVariationOptions o;
  o.mu = 1e4;
  o.relative_tolerance = 1e-8;
  TotalVariationSummary s;
  const Image x = TotalVariationAdmm(p, o, &s);
  EXPECT_EQ(s.termination, Termination::kConverged) << s.BriefReport();
  EXPECT_LT(x.maxCoeff() - x.minCoeff(), 1e-6 * c);
  EXPECT_NEAR(x.mean(), c, 1e-6 * c);
}

// Residual balancing rescues a badly scaled ρ: from 1000x too small, fixed-ρ ADMM does not reach the
// tolerance in 2000 iterations, adaptive ADMM does, at the same optimum as a well-scaled run.
TEST(TotalVariationTest, AdaptiveRhoRecoversFromABadInitialRho) {
  const ReconstructionProblem p = SmallProblem();
  TotalVariationOptions o;
  o.mu = 0.05;
  o.relative_tolerance = 1e-5;
  o.max_iterations = 2000;
  TotalVariationSummary s_auto, s_fixed, s_adaptive;
  const Image x_auto = TotalVariationAdmm(p, o, &s_auto);
  ASSERT_EQ(s_auto.termination, Termination::kConverged) << s_auto.BriefReport();
  o.rho = 1e-3 * s_auto.initial_rho;
  o.adaptive_rho = false;
  TotalVariationAdmm(p, o, &s_fixed);
  o.adaptive_rho = true;
  const Image x_adaptive = TotalVariationAdmm(p, o, &s_adaptive);
  EXPECT_EQ(s_fixed.termination, Termination::kMaxIterations) << s_fixed.BriefReport();
  EXPECT_EQ(s_adaptive.termination, Termination::kConverged) << s_adaptive.BriefReport();
  EXPECT_GT(s_adaptive.rho_updates, 0);
  EXPECT_GT(s_adaptive.final_rho, 10 * s_adaptive.initial_rho);
  EXPECT_LT(RelativeDifference(x_auto, x_adaptive), 1e-3);
}

// The objective and ρ are invariant to scaling: multiplying weights and μ by the same factor scales the
// objective and must leave the estimate and the iteration count unchanged (ρ₀ scales with the weights).
TEST(TotalVariationTest, ScalingWeightsAndMuTogetherChangesNothing) {
  const ReconstructionProblem p = SmallProblem();
  ReconstructionProblem q = p;
  q.weights = ImageStack(p.frames.size(), Image::Constant(16, 16, 64.0));
  TotalVariationOptions o;
  o.mu = 0.05;
  TotalVariationSummary sp, sq;
  const Image xp = TotalVariationAdmm(p, o, &sp);
  o.mu *= 64.0;
  const Image xq = TotalVariationAdmm(q, o, &sq);
  EXPECT_EQ(sq.x_update, TotalVariationXUpdate::kFourier);
  EXPECT_NEAR(sq.initial_rho, 64.0 * sp.initial_rho, 1e-9 * sq.initial_rho);
  EXPECT_EQ(sp.iterations, sq.iterations);
  EXPECT_LT(RelativeDifference(xp, xq), 1e-9);
  EXPECT_NEAR(sq.final_cost, 64.0 * sp.final_cost, 1e-9 * sq.final_cost);
}

TEST(TotalVariationTest, IsotropicTotalVariationOfSimpleImages) {
  EXPECT_EQ(IsotropicTotalVariation(Image::Constant(5, 7, 3.0)), 0.0);
  // A vertical step of height h across a periodic 6x8 image has two edges of 6 pixels each.
  Image step = Image::Zero(6, 8);
  step.rightCols(4) = 2.0;
  EXPECT_DOUBLE_EQ(IsotropicTotalVariation(step), 2 * 6 * 2.0);
  // A single bright pixel: two differences of 1 at its upper and left neighbours, and one of √2 at itself.
  Image dot = Image::Zero(5, 5);
  dot(2, 2) = 1.0;
  EXPECT_DOUBLE_EQ(IsotropicTotalVariation(dot), 2.0 + std::sqrt(2.0));
}

// Progress (core/progress.hpp): the callback sees rising iterations that end at the summary's count.
TEST(TotalVariationTest, ProgressReportsRisingIterationsEndingAtTheSummarysCount) {
  const ReconstructionProblem p = SmallProblem();
  for (int max_iterations : {1000, 40}) {  // converged, then stopped at the limit
    TotalVariationOptions o;
    o.max_iterations = max_iterations;
    std::vector<Progress> seen;
    o.progress = [&seen](const Progress& q) {
      seen.push_back(q);
      return true;
    };
    TotalVariationSummary s;
    TotalVariationAdmm(p, o, &s);
    ASSERT_FALSE(seen.empty());
    EXPECT_EQ(seen.front().iteration, 1);
    EXPECT_EQ(seen.back().iteration, s.iterations) << s.BriefReport();
    for (std::size_t i = 0; i < seen.size(); ++i) {
      EXPECT_EQ(seen[i].stage, "tv");
      EXPECT_EQ(seen[i].total, max_iterations);
      EXPECT_EQ(seen[i].value_name, "primal/tol");
      EXPECT_TRUE(std::isfinite(seen[i].value) && seen[i].value >= 0);
      if (i > 0) {
        EXPECT_GT(seen[i].iteration, seen[i - 1].iteration);
        EXPECT_GE(seen[i].elapsed_seconds, seen[i - 1].elapsed_seconds);
      }
    }
    EXPECT_EQ(s.termination, max_iterations == 40 ? Termination::kMaxIterations : Termination::kConverged);
    EXPECT_NEAR(seen.back().value, s.primal_residual / s.primal_tolerance, 1e-12 * seen.back().value);
  }
}

// Returning false stops after that iteration with kUserCancelled and a finite estimate. The second
// delivery is forced by sleeping past the 0.2 s interval inside the first (no wall time is asserted).
TEST(TotalVariationTest, ProgressCallbackReturningFalseCancelsAfterThatIteration) {
  const ReconstructionProblem p = SmallProblem();
  for (int cancel_at_call : {1, 2}) {
    TotalVariationOptions o;
    o.positivity = true;
    int calls = 0;
    o.progress = [&](const Progress&) {
      if (++calls == cancel_at_call) return false;
      std::this_thread::sleep_for(std::chrono::milliseconds(250));
      return true;
    };
    TotalVariationSummary s;
    const Image x = TotalVariationAdmm(p, o, &s);
    EXPECT_EQ(s.termination, Termination::kUserCancelled) << s.BriefReport();
    EXPECT_EQ(s.iterations, cancel_at_call);
    EXPECT_EQ(calls, cancel_at_call);
    EXPECT_THAT(s.message, ::testing::HasSubstr("cancelled by the caller"));
    EXPECT_STREQ(ToString(s.termination), "cancelled");
    EXPECT_TRUE(AllFinite(x));
    EXPECT_GE(x.minCoeff(), 0.0);
    EXPECT_TRUE(std::isfinite(s.final_cost));
  }
}

// The automatic ρ₀ = tr(AᵀWA) / tr(∇ᵀ∇), which the solver sums over the OTFs' half spectra (Parseval), is the
// trace ratio computed with the operators themselves: Σ_i (Σ_p w_i[p]) ||A_iᵀ e||² / (4n) for an LR delta e.
// Even and odd HR widths (the half spectrum's last column is its own mirror only for even widths), varying
// weights.
TEST(TotalVariationTest, AutomaticRhoIsTheTraceRatioOfTheOperators) {
  for (const Shape hr : {Shape{30, 42}, Shape{30, 45}}) {
    const auto model = RasterModel(hr, 3, {{0, 0}, {0.4, 1.3}, {1.7, 0.2}}, 1.2);
    ReconstructionProblem p = NoisyProblem(model, tv_test::Blocks(hr), 0.05, 5);
    std::mt19937_64 rng(6);
    std::uniform_real_distribution<double> weight(0.5, 2.0);
    p.weights.clear();
    for (const Image& f : p.frames) {
      Image w(f.rows(), f.cols());
      for (Index q = 0; q < w.size(); ++q) w.data()[q] = weight(rng);
      p.weights.push_back(w);
    }
    Vector delta = Vector::Zero(model->lr_shape().size());
    delta[0] = 1.0;
    double trace = 0;
    for (int i = 0; i < model->frames(); ++i)
      trace += p.weights[i].sum() * model->FrameOperator(i)->ApplyAdjoint(delta).squaredNorm();
    const double expected = trace / (4.0 * double(hr.size()));
    TotalVariationOptions o;
    o.max_iterations = 1;
    TotalVariationSummary s;
    TotalVariationAdmm(p, o, &s);
    EXPECT_NEAR(s.initial_rho, expected, 1e-12 * expected) << ToString(hr);
  }
}

// The callback cannot change the maths: a callback that always continues gives the same bits as none.
TEST(TotalVariationTest, ProgressCallbackLeavesTheResultBitIdentical) {
  for (TotalVariationXUpdate path :
       {TotalVariationXUpdate::kFourier, TotalVariationXUpdate::kConjugateGradient}) {
    const ReconstructionProblem p = SmallProblem(3);
    TotalVariationOptions o;
    o.x_update = path;
    o.max_iterations = 300;
    TotalVariationSummary s0, s1;
    const Image x0 = TotalVariationAdmm(p, o, &s0);
    int calls = 0;
    o.progress = [&calls](const Progress&) { return ++calls > 0; };
    const Image x1 = TotalVariationAdmm(p, o, &s1);
    EXPECT_GT(calls, 0);
    EXPECT_TRUE((x0 == x1).all()) << ToString(path);
    EXPECT_EQ(s0.iterations, s1.iterations);
    EXPECT_EQ(s0.termination, s1.termination);
    EXPECT_EQ(s0.final_cost, s1.final_cost);
    EXPECT_EQ(s0.message, s1.message);
  }
}

// The ADMM iteration written plainly with the core operators (∇ and ∇ᵀ from core/operators.hpp, one step
// per line, every array whole), on the Fourier path at a fixed ρ: the reference for the solver's fused pixel
// pass (total_variation.cpp), which forms the same iterates row by row in blocks. 200 x 192 HR has three
// row blocks, the last one short, so the block seams and the periodic wrap are both crossed.
struct ReferenceAdmm {
  Image x;
  double primal = 0, dual = 0;
};
ReferenceAdmm PlainAdmm(const ReconstructionProblem& p, const Image& x0, double mu, double rho, double alpha,
                        bool positivity, int iterations) {
  const MultiFrameModel& model = *p.model;
  const Shape hr = model.hr_shape();
  const Index n = hr.size();
  const OperatorPtr grad = Gradient(hr, Boundary::kPeriodic);
  const Vector aty = model.Operator()->ApplyAdjoint(model.Flatten(p.frames));
  FourierNormalSystem system(model, 1.0);
  system.Factorize(rho, positivity ? rho : 0.0);
  // The solver's start: z = ∇x₀, v = max(x₀, 0), duals 0.
  Vector x = AsVector(x0), z = grad->Apply(x), u = Vector::Zero(2 * n), v = x.cwiseMax(0.0), s = Vector::Zero(n);
  ReferenceAdmm out;
  for (int k = 0; k < iterations; ++k) {
    Vector rhs = aty + rho * grad->ApplyAdjoint(z - u);
    if (positivity) rhs += rho * (v - s);
    x = AsVector(system.Solve(ToImage(rhs, hr)));
    const Vector g = grad->Apply(x);
    const Vector g_hat = alpha * g + (1 - alpha) * z;
    const Vector w = g_hat + u;
    Vector z_new(2 * n);
    for (Index q = 0; q < n; ++q) {
      const double norm = std::hypot(w[q], w[n + q]);
      const double f = norm > mu / rho ? 1.0 - mu / rho / norm : 0.0;
      z_new[q] = f * w[q];
      z_new[n + q] = f * w[n + q];
    }
    u += g_hat - z_new;
    double primal2 = (g - z_new).squaredNorm();
    Vector kt_dz = grad->ApplyAdjoint(z_new - z);
    z = z_new;
    if (positivity) {
      const Vector v_hat = alpha * x + (1 - alpha) * v;
      const Vector v_new = (v_hat + s).cwiseMax(0.0);
      s += v_hat - v_new;
      primal2 += (x - v_new).squaredNorm();
      kt_dz += v_new - v;
      v = v_new;
    }
    out.primal = std::sqrt(primal2);
    out.dual = rho * kt_dz.norm();
  }
  out.x = ToImage(x, hr);
  if (positivity) out.x = out.x.cwiseMax(0.0);
  return out;
}

ReconstructionProblem ThreeBlockProblem() {
  const Shape hr{200, 192};
  return NoisyProblem(RasterModel(hr, 2, {{0, 0}, {0, 1}, {1, 0}, {1, 1}}, 1.0), tv_test::Blocks(hr), 0.05, 17);
}

TEST(TotalVariationTest, FusedPixelPassMatchesThePlainIteration) {
  const ReconstructionProblem p = ThreeBlockProblem();
  for (const bool positivity : {false, true}) {
    TotalVariationOptions o;
    o.mu = 0.02;
    o.rho = 0.05;
    o.adaptive_rho = false;
    o.relaxation = 1.6;
    o.positivity = positivity;
    o.x_update = TotalVariationXUpdate::kFourier;
    o.max_iterations = 12;
    o.absolute_tolerance = 0;
    o.relative_tolerance = 1e-12;  // no early stop
    TotalVariationSummary s;
    const Image x0 = 0.9 * tv_test::Blocks(p.model->hr_shape()) + 0.05 * test::RandomImage(p.model->hr_shape(), 8, true);
    const Image x = TotalVariationAdmm(p, o, &s, &x0);
    const ReferenceAdmm ref = PlainAdmm(p, x0, o.mu, o.rho, o.relaxation, positivity, o.max_iterations);
    ASSERT_EQ(s.iterations, o.max_iterations) << s.BriefReport();
    EXPECT_LT(RelativeDifference(x, ref.x), 1e-12) << "positivity " << positivity;
    EXPECT_NEAR(s.primal_residual, ref.primal, 1e-10 * ref.primal) << "positivity " << positivity;
    EXPECT_NEAR(s.dual_residual, ref.dual, 1e-10 * ref.dual) << "positivity " << positivity;
  }
}

// The pixel passes run in fixed row blocks and the per-bin solves per bin, so the thread count is not in the
// result: images, residual histories and costs are the same bits on 1, 2 and 3 threads, on every x-update
// path (three row blocks, the last one short; positivity on the Fourier path, a masked pixel on the split).
TEST(TotalVariationTest, ResultIsBitIdenticalOnOneTwoAndThreeThreads) {
  ReconstructionProblem masked = ThreeBlockProblem();
  masked.weights = ImageStack(masked.frames.size(), Image::Ones(100, 96));
  masked.weights[1](7, 11) = 0.0;
  struct Case {
    const char* name;
    const ReconstructionProblem* problem;
    TotalVariationXUpdate path;
    bool positivity;
  };
  const ReconstructionProblem uniform = ThreeBlockProblem();
  const std::vector<Case> cases = {{"fourier", &uniform, TotalVariationXUpdate::kFourier, false},
                                   {"fourier+positivity", &uniform, TotalVariationXUpdate::kFourier, true},
                                   {"split", &masked, TotalVariationXUpdate::kFourierSplit, false},
                                   {"cg", &uniform, TotalVariationXUpdate::kConjugateGradient, false}};
  const int saved = DefaultThreads();
  for (const Case& c : cases) {
    TotalVariationOptions o;
    o.mu = 0.02;
    o.x_update = c.path;
    o.positivity = c.positivity;
    o.max_iterations = c.path == TotalVariationXUpdate::kConjugateGradient ? 8 : 40;
    o.record_history = true;
    std::vector<Image> images;
    std::vector<TotalVariationSummary> summaries;
    for (int threads : {1, 2, 3}) {
      SetDefaultThreads(threads);
      TotalVariationSummary s;
      images.push_back(TotalVariationAdmm(*c.problem, o, &s));
      summaries.push_back(s);
    }
    SetDefaultThreads(saved);
    for (int k = 1; k < 3; ++k) {
      EXPECT_TRUE((images[k] == images[0]).all()) << c.name << ", thread case " << k;
      EXPECT_EQ(summaries[k].iterations, summaries[0].iterations) << c.name;
      EXPECT_EQ(summaries[k].history_primal, summaries[0].history_primal) << c.name;
      EXPECT_EQ(summaries[k].history_dual, summaries[0].history_dual) << c.name;
      EXPECT_EQ(summaries[k].history_rho, summaries[0].history_rho) << c.name;
      EXPECT_EQ(summaries[k].final_cost, summaries[0].final_cost) << c.name;
    }
  }
}

}  // namespace
}  // namespace aosr
