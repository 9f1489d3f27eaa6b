#include "aosr/solvers/map.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <limits>
#include <random>
#include <stdexcept>
#include <thread>
#include <vector>

#include "aosr/core/parallel.hpp"
#include "aosr/solvers/tikhonov.hpp"
#include "solvers/map_fixtures.hpp"
#include "support/testing.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

using map_test::MakeProblem;
using map_test::NoisyFrames;
using map_test::Raster4;
using map_test::RelativeError;

// Taylor test (DESIGN.md §6) of ∇_z F for every likelihood x prior x positivity: the remainder
// |F(z + h d) − F(z) − h <∇F, d>| must fall 4x per halving of h. 16x16 HR grid, r = 2, 3 frames, random
// positive weights with two masked (NaN) pixels, Poisson with read noise and background.
TEST(MapTest, TaylorTestOfTheGradientForEveryCombination) {
  const Shape hr{16, 16};
  const auto model = map_test::RasterModel(hr, 2, {{0, 0}, {0.5, 1.0}, {1.3, 0.2}}, 1.0);
  const Image x_true = 10.0 + 20.0 * aosr::test::RandomImage(hr, 3, /*normal=*/false);
  ImageStack frames = NoisyFrames(*model, x_true, 2.0, 5);
  ImageStack weights;
  for (int i = 0; i < 3; ++i)
    weights.push_back(0.5 + aosr::test::RandomImage(model->lr_shape(), 10 + i, false));
  weights[1](2, 3) = 0;
  frames[1](2, 3) = std::numeric_limits<double>::quiet_NaN();
  weights[2](7, 0) = 0;
  frames[2](7, 0) = std::numeric_limits<double>::infinity();
  const ReconstructionProblem problem = MakeProblem(model, frames, weights);

  struct PriorCase {
    MapPrior prior;
    TikhonovPrior gamma;
  };
  const PriorCase priors[] = {{MapPrior::kTikhonov, TikhonovPrior::kIdentity},
                              {MapPrior::kTikhonov, TikhonovPrior::kGradient},
                              {MapPrior::kTikhonov, TikhonovPrior::kLaplacian},
                              {MapPrior::kCharbonnierTv, TikhonovPrior::kGradient},
                              {MapPrior::kHuberTv, TikhonovPrior::kGradient}};
  int seed = 100;
  for (MapLikelihood likelihood : {MapLikelihood::kGaussian, MapLikelihood::kPoisson})
    for (const PriorCase& pc : priors)
      for (MapPositivity positivity : {MapPositivity::kNone, MapPositivity::kSoftplus}) {
        MapOptions o;
        o.likelihood = likelihood;
        o.read_noise = 2.0;
        o.background = 3.0;
        o.prior = pc.prior;
        o.tikhonov_operator = pc.gamma;
        o.lambda = 0.7;
        o.epsilon = 3.0;  // typical |∇x| here is ~10: both regimes of the TV priors are exercised
        o.delta = 3.0;
        o.positivity = positivity;
        o.softplus_scale = positivity == MapPositivity::kSoftplus ? 5.0 : 0.0;
        const MapObjective f(problem, o);
        // A point with pixels on both sides of the softplus knee, and a random direction.
        const Image x = x_true * (0.7 + 0.6 * aosr::test::RandomImage(hr, seed++, false));
        const Vector z =
            f.ToParameters(x) + (positivity == MapPositivity::kSoftplus
                                     ? Vector(5.0 * AsVector(aosr::test::RandomImage(hr, seed++)))
                                     : Vector::Zero(hr.size()));
        const Vector d = AsVector(aosr::test::RandomImage(hr, seed++));
        Vector g;
        const MapObjective::Value v = f.Evaluate(z, &g);
        const std::string what = std::string(ToString(likelihood)) + " " + ToString(pc.prior) + "(" +
                                 ToString(pc.gamma) + ") " + ToString(positivity);
        ASSERT_TRUE(v.ok()) << what;
        EXPECT_NEAR(v.total, v.data + v.prior, 1e-12 * v.total);
        const double slope = g.dot(d);
        double h = 1e-3, previous = 0;
        for (int k = 0; k < 6; ++k, h /= 2) {
          const double remainder = std::abs(f.Evaluate(z + h * d).total - v.total - h * slope);
          ASSERT_GT(remainder, 1e-12 * v.total) << what << ": remainder at rounding level, the test is blind";
          if (k > 0) {
            const double ratio = previous / remainder;
            EXPECT_NEAR(ratio, 4.0, 0.4) << what << " h = " << h;
          }
          previous = remainder;
        }
      }
}

// With the Gaussian likelihood, unit weights, the Tikhonov prior and no positivity, F is half of
// tikhonov.hpp's objective at the same λ: MAP must converge to TikhonovFourier's exact solution.
TEST(MapTest, GaussianTikhonovConvergesToTheExactFourierSolution) {
  const Shape hr{64, 64};  // 32 x 32 LR, r = 2
  const auto model = Raster4(hr);
  const Image x_true = map_test::PiecewiseConstant(hr, 1.0, 2.0);
  const ReconstructionProblem problem = MakeProblem(model, NoisyFrames(*model, x_true, 0.05, 7));
  // Both with and without the Fourier preconditioner (z = C u: the wrapper's gradient C ∂F/∂z must be right for
  // L-BFGS to reach the exact minimiser, and the change of variables must not move it).
  for (MapPreconditioner pc : {MapPreconditioner::kFourier, MapPreconditioner::kNone})
  for (TikhonovPrior gamma : {TikhonovPrior::kIdentity, TikhonovPrior::kGradient}) {
    TikhonovOptions t;
    t.prior = gamma;
    t.lambda = gamma == TikhonovPrior::kIdentity ? 1e-2 : 3e-2;
    const Image exact = TikhonovFourier(*model, problem.frames, t);
    MapOptions o;
    o.prior = MapPrior::kTikhonov;
    o.tikhonov_operator = gamma;
    o.lambda = t.lambda;
    o.positivity = MapPositivity::kNone;
    o.max_iterations = 2000;
    o.function_tolerance = 1e-16;
    o.gradient_tolerance = 1e-9;
    o.parameter_tolerance = 1e-14;
    o.preconditioner = pc;
    const MapResult r = MapReconstruct(problem, o);  // from the flat mean image
    const double rel = RelativeError(r.image, exact);
    EXPECT_NE(r.summary.termination, Termination::kFailed) << r.summary.BriefReport();
    EXPECT_LT(rel, 1e-5) << ToString(gamma) << ": " << r.summary.BriefReport();
    // The objective at the exact solution is the minimum: MAP's cost may not be below it (beyond rounding).
    MapObjective f(problem, o);
    EXPECT_GE(r.summary.final_cost, f.Evaluate(AsVector(exact)).total * (1 - 1e-12));
    std::printf(
        "[ map vs Fourier Tikhonov, %s prior, preconditioner %d ] %d iterations, %d+%d evaluations, relative "
        "difference %.2e\n",
        ToString(gamma), int(pc), r.summary.iterations, r.summary.gradient_evaluations, r.summary.cost_evaluations,
        rel);
  }
}

TEST(MapTest, HittingTheIterationLimitIsReportedWithAFiniteImage) {
  const Shape hr{64, 64};
  const auto model = Raster4(hr);
  const Image x_true = map_test::PiecewiseConstant(hr, 1.0, 2.0);
  const ReconstructionProblem problem = MakeProblem(model, NoisyFrames(*model, x_true, 0.05, 8));
  MapOptions o;
  o.max_iterations = 5;
  o.positivity = MapPositivity::kSoftplus;
  const MapResult r = MapReconstruct(problem, o);
  EXPECT_EQ(r.summary.termination, Termination::kMaxIterations) << r.summary.BriefReport();
  EXPECT_EQ(r.summary.iterations, 5);
  EXPECT_TRUE(AllFinite(r.image));
  EXPECT_LT(r.summary.final_cost, r.summary.initial_cost);
  EXPECT_EQ(r.summary.method, "map");
  EXPECT_NE(r.summary.message.find("NO_CONVERGENCE"), std::string::npos) << r.summary.message;
  ASSERT_EQ(r.summary.frame_residual_rms.size(), 4u);
  for (double rms : r.summary.frame_residual_rms) EXPECT_TRUE(std::isfinite(rms) && rms > 0);
  EXPECT_NEAR(r.summary.final_cost, r.summary.data_cost + r.summary.prior_cost, 1e-12 * r.summary.final_cost);

  // With a residual region (a tile's core): the RMS of y − A x − b over it, by hand, and the same image.
  ReconstructionProblem q = problem;
  q.residual_region = {3, 5, 20, 11};
  const MapResult rq = MapReconstruct(q, o);
  EXPECT_EQ((rq.image - r.image).abs().maxCoeff(), 0.0);
  const ImageStack predicted = model->Render(r.image);
  ASSERT_EQ(rq.summary.frame_residual_rms.size(), 4u);
  for (int i = 0; i < 4; ++i) {
    const Image d = problem.frames[i] - predicted[i] - o.background;
    const double expected = std::sqrt(d.block(3, 5, 20, 11).square().mean());
    EXPECT_NEAR(rq.summary.frame_residual_rms[i], expected, 1e-12 * expected) << i;
  }
}

// A point source on a dark sky: the unconstrained solution rings below zero; softplus keeps x >= 0 and
// the warm start's negative pixels are counted.
TEST(MapTest, SoftplusKeepsTheImageNonNegative) {
  const Shape hr{32, 32};
  const auto model = Raster4(hr, 0.8);
  Image x_true = Image::Constant(hr.rows, hr.cols, 0.01);
  x_true(10, 12) = 50;
  x_true(20, 21) = 20;
  const ReconstructionProblem problem = MakeProblem(model, NoisyFrames(*model, x_true, 0.02, 9));
  TikhonovOptions t;
  t.lambda = 1e-3;
  const Image tikhonov = TikhonovFourier(*model, problem.frames, t);
  ASSERT_LT(tikhonov.minCoeff(), -0.05) << "the test needs an unconstrained solution with negative lobes";
  MapOptions o;
  o.prior = MapPrior::kCharbonnierTv;
  o.lambda = 1e-3;
  o.positivity = MapPositivity::kSoftplus;
  const MapResult r = MapReconstruct(problem, o, tikhonov);
  EXPECT_NE(r.summary.termination, Termination::kFailed) << r.summary.BriefReport();
  EXPECT_GE(r.image.minCoeff(), 0.0);
  EXPECT_GT(r.summary.warm_start_pixels_raised, 0);
  EXPECT_GT(r.summary.softplus_scale, 0);
  EXPECT_LT(RelativeError(r.image, x_true), RelativeError(tikhonov, x_true));
}

// A masked pixel is never read: NaN there, or any other value, gives the identical result.
TEST(MapTest, MaskedNanPixelDoesNotChangeTheResult) {
  const Shape hr{32, 32};
  const auto model = Raster4(hr);
  const Image x_true = map_test::PiecewiseConstant(hr, 1.0, 2.0);
  ImageStack frames = NoisyFrames(*model, x_true, 0.05, 10);
  ImageStack weights(4, Image::Ones(16, 16));
  weights[2](5, 6) = 0;
  for (MapLikelihood likelihood : {MapLikelihood::kGaussian, MapLikelihood::kPoisson}) {
    MapOptions o;
    o.likelihood = likelihood;
    o.read_noise = 1.0;
    o.positivity = MapPositivity::kSoftplus;
    o.max_iterations = 50;
    frames[2](5, 6) = std::numeric_limits<double>::quiet_NaN();
    const MapResult with_nan = MapReconstruct(MakeProblem(model, frames, weights), o);
    frames[2](5, 6) = 1e6;
    const MapResult with_junk = MapReconstruct(MakeProblem(model, frames, weights), o);
    EXPECT_TRUE(AllFinite(with_nan.image));
    EXPECT_EQ((with_nan.image - with_junk.image).abs().maxCoeff(), 0.0) << ToString(likelihood);
    EXPECT_EQ(with_nan.summary.iterations, with_junk.summary.iterations);
    // ... and the mask matters: unmasked, the junk value pulls the estimate.
    const MapResult unmasked = MapReconstruct(MakeProblem(model, frames), o);
    EXPECT_GT((unmasked.image - with_junk.image).abs().maxCoeff(), 1.0);
  }
}

// Overflowing data make the objective non-finite at the start: kFailed, Ceres not run, finite output.
TEST(MapTest, NonFiniteObjectiveEndsTheSolveAsFailedWithAFiniteImage) {
  const Shape hr{16, 16};
  const auto model = Raster4(hr);
  ImageStack frames = model->Render(Image::Ones(hr.rows, hr.cols));
  frames[0](3, 3) = 1e200;  // finite, but its square overflows
  const MapResult r = MapReconstruct(MakeProblem(model, frames), MapOptions{});
  EXPECT_EQ(r.summary.termination, Termination::kFailed);
  EXPECT_NE(r.summary.message.find("non-finite"), std::string::npos) << r.summary.message;
  EXPECT_TRUE(AllFinite(r.image));
}

// Without positivity the Poisson likelihood is still usable when every unmasked pixel has c = y + σ² > 0
// (here a bright sky): −c log μ is then a barrier at μ = 0, and trial steps that leave the domain are
// backed off by the line search. The estimate keeps μ > 0.
TEST(MapTest, PoissonWithoutPositivityStaysInItsDomain) {
  const Shape hr{32, 32};
  const auto model = Raster4(hr);
  Image x_true = Image::Constant(hr.rows, hr.cols, 5.0);
  x_true(8, 8) = 300;
  ImageStack frames = model->Render(x_true);
  std::mt19937_64 rng(11);
  std::normal_distribution<double> read(0.0, 1.0);
  for (Image& f : frames)
    for (Index i = 0; i < f.size(); ++i)
      f.data()[i] = std::poisson_distribution<int>(f.data()[i] + 0.5)(rng) + read(rng);
  MapOptions o;
  o.likelihood = MapLikelihood::kPoisson;
  o.background = 0.5;
  o.read_noise = 1.0;
  o.positivity = MapPositivity::kNone;
  o.lambda = 1e-1;
  o.epsilon = 0.5;
  o.max_iterations = 300;
  const MapResult r = MapReconstruct(MakeProblem(model, frames), o);
  EXPECT_NE(r.summary.termination, Termination::kFailed) << r.summary.BriefReport();
  EXPECT_TRUE(AllFinite(r.image));
  for (const Image& ax : model->Render(r.image)) EXPECT_GT(ax.minCoeff() + o.background + 1.0, 0.0);
}

TEST(MapTest, NamesRoundTrip) {
  for (MapLikelihood l : {MapLikelihood::kGaussian, MapLikelihood::kPoisson})
    EXPECT_EQ(ParseMapLikelihood(ToString(l)), l);
  for (MapPrior p : {MapPrior::kTikhonov, MapPrior::kCharbonnierTv, MapPrior::kHuberTv})
    EXPECT_EQ(ParseMapPrior(ToString(p)), p);
  for (MapPositivity p : {MapPositivity::kNone, MapPositivity::kSoftplus})
    EXPECT_EQ(ParseMapPositivity(ToString(p)), p);
  std::string why;
  EXPECT_TRUE(MapOptions{}.IsValid(&why)) << why;
}

// Progress (core/progress.hpp) through Ceres' IterationCallback: rising iterations that end at the summary's
// count, with the cost, which never increases along L-BFGS' accepted steps.
TEST(MapTest, ProgressReportsRisingIterationsEndingAtTheSummarysCount) {
  const Shape hr{32, 32};
  const auto model = Raster4(hr);
  const ReconstructionProblem problem =
      MakeProblem(model, NoisyFrames(*model, map_test::PiecewiseConstant(hr, 1.0, 2.0), 0.05, 21));
  for (int max_iterations : {500, 7}) {  // converged, then stopped at the limit
    MapOptions o;
    o.max_iterations = max_iterations;
    std::vector<Progress> seen;
    o.progress = [&seen](const Progress& q) {
      seen.push_back(q);
      return true;
    };
    const MapResult r = MapReconstruct(problem, o);
    ASSERT_FALSE(seen.empty());
    EXPECT_EQ(seen.front().iteration, 1);
    EXPECT_EQ(seen.back().iteration, r.summary.iterations) << r.summary.BriefReport();
    for (std::size_t i = 0; i < seen.size(); ++i) {
      EXPECT_EQ(seen[i].stage, "map");
      EXPECT_EQ(seen[i].total, max_iterations);
      EXPECT_EQ(seen[i].value_name, "cost");
      EXPECT_TRUE(std::isfinite(seen[i].value));
      if (i > 0) {
        EXPECT_GT(seen[i].iteration, seen[i - 1].iteration);
        EXPECT_LE(seen[i].value, seen[i - 1].value);
      }
    }
    EXPECT_EQ(r.summary.termination,
              max_iterations == 7 ? Termination::kMaxIterations : Termination::kConverged);
    EXPECT_NEAR(seen.back().value, r.summary.final_cost, 1e-9 * r.summary.final_cost);
  }
}

// Returning false stops after that iteration with kUserCancelled, that iterate and a finite image. The
// second delivery is forced by sleeping past the 0.2 s interval inside the first (no wall time is asserted).
TEST(MapTest, ProgressCallbackReturningFalseCancelsAfterThatIteration) {
  const Shape hr{32, 32};
  const auto model = Raster4(hr);
  const ReconstructionProblem problem =
      MakeProblem(model, NoisyFrames(*model, map_test::PiecewiseConstant(hr, 1.0, 2.0), 0.05, 22));
  for (int cancel_at_call : {1, 2}) {
    MapOptions o;
    o.positivity = MapPositivity::kSoftplus;
    int calls = 0;
    double reported_cost = 0;
    o.progress = [&](const Progress& q) {
      reported_cost = q.value;
      if (++calls == cancel_at_call) return false;
      std::this_thread::sleep_for(std::chrono::milliseconds(250));
      return true;
    };
    const MapResult r = MapReconstruct(problem, o);
    EXPECT_EQ(r.summary.termination, Termination::kUserCancelled) << r.summary.BriefReport();
    EXPECT_EQ(r.summary.iterations, cancel_at_call);
    EXPECT_EQ(calls, cancel_at_call);
    EXPECT_THAT(r.summary.message, ::testing::HasSubstr("cancelled by the caller"));
    EXPECT_TRUE(AllFinite(r.image));
    EXPECT_GE(r.image.minCoeff(), 0.0);
    // The image is the iterate the callback saw, not the warm start.
    EXPECT_NEAR(r.summary.final_cost, reported_cost, 1e-9 * reported_cost);
    EXPECT_LT(r.summary.final_cost, r.summary.initial_cost);
  }
}

// The callback cannot change the maths: a callback that always continues gives the same bits as none.
TEST(MapTest, ProgressCallbackLeavesTheResultBitIdentical) {
  const Shape hr{32, 32};
  const auto model = Raster4(hr);
  const ReconstructionProblem problem =
      MakeProblem(model, NoisyFrames(*model, map_test::PiecewiseConstant(hr, 1.0, 2.0), 0.05, 23));
  MapOptions o;
  o.positivity = MapPositivity::kSoftplus;
  const MapResult r0 = MapReconstruct(problem, o);
  int calls = 0;
  o.progress = [&calls](const Progress&) { return ++calls > 0; };
  const MapResult r1 = MapReconstruct(problem, o);
  EXPECT_GT(calls, 0);
  EXPECT_TRUE((r0.image == r1.image).all());
  EXPECT_EQ(r0.summary.iterations, r1.summary.iterations);
  EXPECT_EQ(r0.summary.termination, r1.summary.termination);
  EXPECT_EQ(r0.summary.final_cost, r1.summary.final_cost);
  EXPECT_EQ(r0.summary.gradient_evaluations, r1.summary.gradient_evaluations);
}

// The objective's pixel passes run in fixed blocks of pixels on the default thread count (map.cpp): the
// value, the gradient and a short solve must be the same bits on 1, 2 and 3 threads. 192x192 HR (3 blocks;
// the frames 4 x 96^2, 3 blocks), Poisson + Charbonnier TV + softplus and Gaussian + Huber TV.
TEST(MapTest, ObjectiveAndSolveAreBitIdenticalOnOneTwoAndThreeThreads) {
  const Shape hr{192, 192};
  const auto model = Raster4(hr);
  const Image x_true = map_test::PiecewiseConstant(hr, 5.0, 20.0);
  const ReconstructionProblem problem = MakeProblem(model, NoisyFrames(*model, x_true, 0.5, 31));
  const int saved = DefaultThreads();
  for (const bool poisson : {true, false}) {
    MapOptions o;
    o.likelihood = poisson ? MapLikelihood::kPoisson : MapLikelihood::kGaussian;
    o.prior = poisson ? MapPrior::kCharbonnierTv : MapPrior::kHuberTv;
    o.positivity = poisson ? MapPositivity::kSoftplus : MapPositivity::kNone;
    o.read_noise = 1.0;
    o.lambda = 0.05;
    o.max_iterations = 8;
    const Vector z = MapObjective(problem, o).ToParameters(x_true * (0.9 + 0.2 * aosr::test::RandomImage(hr, 32, false)));
    std::vector<MapObjective::Value> values;
    std::vector<Vector> gradients;
    std::vector<MapResult> results;
    for (int threads : {1, 2, 3}) {
      SetDefaultThreads(threads);
      const MapObjective f(problem, o);
      Vector g;
      values.push_back(f.Evaluate(z, &g));
      gradients.push_back(g);
      results.push_back(MapReconstruct(problem, o));
    }
    SetDefaultThreads(saved);
    for (int k = 1; k < 3; ++k) {
      EXPECT_EQ(values[k].total, values[0].total) << "poisson " << poisson << ", thread case " << k;
      EXPECT_EQ(values[k].prior, values[0].prior);
      EXPECT_TRUE(gradients[k] == gradients[0]) << "poisson " << poisson << ", thread case " << k;
      EXPECT_TRUE((results[k].image == results[0].image).all()) << "poisson " << poisson << ", thread case " << k;
      EXPECT_EQ(results[k].summary.final_cost, results[0].summary.final_cost);
    }
  }
}

// A callback's exception (a binding's KeyboardInterrupt, say) stops the solve and reaches the caller intact;
// it never crosses Ceres.
TEST(MapTest, ProgressCallbackExceptionReachesTheCaller) {
  const Shape hr{16, 16};
  const auto model = Raster4(hr);
  const ReconstructionProblem problem =
      MakeProblem(model, NoisyFrames(*model, map_test::PiecewiseConstant(hr, 1.0, 2.0), 0.05, 24));
  MapOptions o;
  o.progress = [](const Progress&) -> bool { throw std::runtime_error("KeyboardInterrupt"); };
  EXPECT_THAT(test::ErrorOf<std::runtime_error>([&] { MapReconstruct(problem, o); }),
              ::testing::HasSubstr("KeyboardInterrupt"));
}

}  // namespace
}  // namespace aosr
