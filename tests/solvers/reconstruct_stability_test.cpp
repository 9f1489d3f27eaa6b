// Stability of every reconstructor on the hard cases of the reconstructor issue, through the one entry point
// Reconstruct() (reconstruct.hpp) and, where a case is specific to a method, its own API. Each case asserts
// (1) a finite image, (2) an error bound that follows from the maths, and (3) a summary that tells the truth
// (termination, rank deficiency, iteration limit). Grids are 16–48 HR pixels so the executable runs in
// seconds. No test asserts wall time.
//
// The bounds, and why they hold:
//  * Prior-only error. With the gradient prior, λ → ∞ keeps only the data's DC: the flat image at the
//    truth's mean. A reconstruction that cannot beat that flat image has learnt nothing from the frames.
//  * Projection. Noise-free data and λ = 0: Tikhonov returns the minimum-norm solution A⁺Ax, the orthogonal
//    projection of x onto what the frames see, so ||x − x̂||² + ||x̂||² = ||x||² exactly (Pythagoras), and
//    x̂ = x when x has no content on the unseen frequencies (exact recovery).
//  * Blind frequencies. The pixel box vanishes on f_a ∈ {m_a, .., (r−1)m_a}: (r−1)(M_x + M_y) − (r−1)²
//    HR frequencies no design sees; a full raster (N = r²) sees every other one.
//  * Degenerate designs. Identical frames, or frames moved by whole camera pixels, make every A(u) rank 1:
//    (r² − 1)·m² unconstrained frequencies, and the estimate from N such frames at λ equals that from one
//    frame at λ/N.
//  * Linearity. Shift-and-add, Drizzle and fixed-λ Tikhonov are linear: a galaxy's reconstruction beside a
//    star 10⁶ times brighter equals its reconstruction alone up to rounding of the star's dynamic range.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cstring>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <string>

#include "../io/temp_dir.hpp"
#include "aosr/io/config.hpp"
#include "aosr/io/fits.hpp"
#include "aosr/scene/dataset.hpp"
#include "aosr/solvers/dataset_problem.hpp"
#include "aosr/solvers/reconstruct.hpp"
#include "reconstruct_stability_fixture.hpp"
#include "scene/dataset_fixture.hpp"
#include "support/testing.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

using namespace stability_test;  // NOLINT: test-local helpers
using test::ErrorOf;
using ::testing::AllOf;
using ::testing::HasSubstr;

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kInf = std::numeric_limits<double>::infinity();

// The checks every case makes of every method's result.
void ExpectSane(const Reconstruction& rec, const ReconstructionProblem& p, ReconstructionMethod m) {
  SCOPED_TRACE(ToString(m));
  ASSERT_EQ(ShapeOf(rec.image), p.model->hr_shape());
  EXPECT_TRUE(AllFinite(rec.image)) << rec.summary.BriefReport();
  EXPECT_TRUE(std::isfinite(rec.summary.final_cost)) << rec.summary.BriefReport();
  for (double v : rec.summary.frame_residual_rms) {
    EXPECT_TRUE(std::isfinite(v)) << rec.summary.BriefReport();
  }
  EXPECT_FALSE(rec.summary.method.empty());
}

// These tests read the summary's rank counts, which are made on request (count_unconstrained).
TikhonovOptions FixedLambda(double lambda, TikhonovPrior prior = TikhonovPrior::kGradient) {
  TikhonovOptions t;
  t.lambda_rule = TikhonovLambdaRule::kFixed;
  t.lambda = lambda;
  t.prior = prior;
  t.count_unconstrained = true;
  return t;
}

TikhonovOptions CountingDefaults() {
  TikhonovOptions t = ReconstructOptions().tikhonov;
  t.count_unconstrained = true;
  return t;
}

// ---------------------------------------------------------------------------------------------------------
// N < r²

TEST(ReconstructStabilityTest, FewerFramesThanRSquaredStaysBelowThePriorOnlyError) {
  const Shape hr{32, 32};
  const int r = 4;  // N = 4 < r² = 16
  const auto shifts = HalfPixelRaster(r);
  const auto model = Model(hr, r, shifts, 1.0);
  const Image truth = SmoothObject(hr);
  const double sigma = 0.01 * model->Render(truth)[0].maxCoeff();
  const ReconstructionProblem p = MakeProblem(model, AddNoise(model->Render(truth), sigma, 11), shifts);
  const double flat = FlatError(truth);
  for (ReconstructionMethod m : AllMethods()) {
    const Reconstruction rec = RunMethod(p, m);
    ExpectSane(rec, p, m);
    EXPECT_NE(rec.summary.termination, Termination::kFailed) << ToString(m) << ": " << rec.summary.BriefReport();
    EXPECT_LT(RelativeError(rec.image, truth), 0.8 * flat) << ToString(m);
  }
  // Tikhonov says how little the frames determine: every bin has rank <= N < r².
  const TikhonovResult t = ReconstructTikhonov(p, CountingDefaults());
  const Index m2 = model->lr_shape().size();
  EXPECT_EQ(t.summary.lr_bins, m2);
  EXPECT_EQ(t.summary.rank_deficient_bins, m2);
  EXPECT_GE(t.summary.unconstrained_frequencies, Index(r * r - 4) * m2);
  EXPECT_EQ(t.summary.woodbury_bins, m2 - 1);  // all but DC, where the gradient prior is 0
  EXPECT_THAT(t.summary.message, HasSubstr("HR frequencies unconstrained by the data"));

  // λ = 0 on noise-free frames: the orthogonal projection of the truth onto what the frames see.
  const ReconstructionProblem clean = MakeProblem(model, model->Render(truth), shifts);
  const TikhonovResult ls = ReconstructTikhonov(clean, FixedLambda(0.0));
  ASSERT_TRUE(AllFinite(ls.image));
  const double xx = truth.square().sum(), hh = ls.image.square().sum(), ee = (truth - ls.image).square().sum();
  EXPECT_NEAR(ee + hh, xx, 1e-8 * xx) << "x̂ is not the projection A⁺A x";
  EXPECT_LT(hh, xx);
  EXPECT_GT(ls.summary.unconstrained_frequencies, 0);
}

// ---------------------------------------------------------------------------------------------------------
// Degenerate designs: identical frames, whole-pixel offsets

TEST(ReconstructStabilityTest, IdenticalFramesAreReportedRankOneAndEqualOneFrameAtLambdaOverN) {
  const Shape hr{32, 32};
  const int r = 2, n = 4;
  const std::vector<Shift> zeros(n, {0.0, 0.0});
  const auto model = Model(hr, r, zeros, 1.0);
  const Image truth = SmoothObject(hr);
  const Image frame = AddNoise(model->Render(truth), 0.01, 3)[0];
  const ReconstructionProblem p = MakeProblem(model, ImageStack(n, frame), zeros);
  const Index m2 = model->lr_shape().size();

  const double lambda = 0.05;
  const TikhonovResult t = ReconstructTikhonov(p, FixedLambda(lambda));
  EXPECT_EQ(t.summary.rank_deficient_bins, m2);
  EXPECT_EQ(t.summary.unconstrained_frequencies, Index(r * r - 1) * m2);
  // N copies weigh the data N times: the same estimate as one frame at λ/N.
  const auto one = Model(hr, r, {{0.0, 0.0}}, 1.0);
  const TikhonovResult t1 = ReconstructTikhonov(MakeProblem(one, {frame}, {{0.0, 0.0}}), FixedLambda(lambda / n));
  EXPECT_LT(RelativeError(t.image, t1.image), 1e-10);

  const double flat = FlatError(truth);
  for (ReconstructionMethod m : AllMethods()) {
    const Reconstruction rec = RunMethod(p, m);
    ExpectSane(rec, p, m);
    EXPECT_NE(rec.summary.termination, Termination::kFailed) << ToString(m) << ": " << rec.summary.BriefReport();
    EXPECT_LT(RelativeError(rec.image, truth), flat) << ToString(m);
    if (m == ReconstructionMethod::kShiftAddMean || m == ReconstructionMethod::kShiftAddMedian) {
      // Zero offsets: every frame is the same upsampled image.
      Image up(hr.rows, hr.cols);
      for (Index y = 0; y < hr.rows; ++y)
        for (Index x = 0; x < hr.cols; ++x) up(y, x) = frame(y / r, x / r) / double(r * r);
      EXPECT_LT((rec.image - up).abs().maxCoeff(), 1e-12) << ToString(m);
    }
  }
}

TEST(ReconstructStabilityTest, WholePixelOffsetsAddNothing) {
  const Shape hr{32, 32};
  const int r = 2;
  const std::vector<Shift> whole = {{0, 0}, {0, 2}, {2, 0}, {2, 2}};  // whole camera pixels
  const std::vector<Shift> zeros(4, {0.0, 0.0});
  const auto model = Model(hr, r, whole, 1.0);
  const auto same = Model(hr, r, zeros, 1.0);
  const Image truth = SmoothObject(hr);
  // Noise-free: the frames are the first frame rolled by whole camera pixels (periodic model).
  const ReconstructionProblem p = MakeProblem(model, model->Render(truth), whole);
  const ReconstructionProblem q = MakeProblem(same, same->Render(truth), zeros);
  const Index m2 = model->lr_shape().size();

  const TikhonovResult t = ReconstructTikhonov(p, FixedLambda(0.01));
  const TikhonovResult tq = ReconstructTikhonov(q, FixedLambda(0.01));
  EXPECT_EQ(t.summary.rank_deficient_bins, m2);
  EXPECT_EQ(t.summary.unconstrained_frequencies, Index(r * r - 1) * m2);
  EXPECT_LT(RelativeError(t.image, tq.image), 1e-10) << "whole-pixel dithers must equal identical frames";

  for (ReconstructionMethod m : {ReconstructionMethod::kShiftAddMean, ReconstructionMethod::kShiftAddMedian,
                                 ReconstructionMethod::kDrizzle}) {
    const Reconstruction a = RunMethod(p, m), b = RunMethod(q, m);
    ExpectSane(a, p, m);
    // Registration undoes whole-pixel shifts exactly.
    EXPECT_LT((a.image - b.image).abs().maxCoeff(), 1e-12 * truth.maxCoeff()) << ToString(m);
  }
  for (ReconstructionMethod m : {ReconstructionMethod::kTikhonov, ReconstructionMethod::kTotalVariation,
                                 ReconstructionMethod::kMap}) {
    const Reconstruction a = RunMethod(p, m);
    ExpectSane(a, p, m);
    EXPECT_NE(a.summary.termination, Termination::kFailed) << ToString(m) << ": " << a.summary.BriefReport();
    EXPECT_LT(RelativeError(a.image, truth), FlatError(truth)) << ToString(m);
  }
}

// ---------------------------------------------------------------------------------------------------------
// λ → 0 and λ huge

TEST(ReconstructStabilityTest, LambdaToZeroRecoversNoiseFreeDataExactlyWhereWellPosed) {
  const Shape hr{32, 32};
  for (int r : {2, 3}) {
    const Shape g = r == 2 ? Shape{32, 32} : Shape{30, 30};
    SCOPED_TRACE("r = " + std::to_string(r));
    const auto shifts = FullRaster(r);  // N = r²
    const auto model = Model(g, r, shifts, 0.7);
    // Any object minus what no design can see (the pixel box's zeros).
    const Image truth = WithoutBlindFrequencies(test::RandomImage(g, 5, false) + SmoothObject(g), r);
    const ReconstructionProblem p = MakeProblem(model, model->Render(truth), shifts);
    for (double lambda : {0.0, 1e-12}) {
      const TikhonovResult t = ReconstructTikhonov(p, FixedLambda(lambda));
      EXPECT_LT(RelativeError(t.image, truth), 1e-6) << "lambda " << lambda;
      EXPECT_EQ(t.summary.unconstrained_frequencies, BlindFrequencyCount(g, r)) << t.summary.message;
    }
    // The same through Reconstruct (fixed λ = 0).
    ReconstructOptions o;
    o.tikhonov = FixedLambda(0.0);
    const Reconstruction rec = RunMethod(p, ReconstructionMethod::kTikhonov, o);
    EXPECT_EQ(rec.summary.termination, Termination::kConverged);
    EXPECT_LT(RelativeError(rec.image, truth), 1e-6);
    EXPECT_LT(*std::max_element(rec.summary.frame_residual_rms.begin(), rec.summary.frame_residual_rms.end()),
              1e-8 * truth.abs().maxCoeff());
  }
  // More frames than r² (two extra at fractional offsets): still exact.
  const int r = 2;
  std::vector<Shift> shifts = FullRaster(r);
  shifts.push_back({0.5, 0.25});
  shifts.push_back({1.25, 0.75});
  const auto model = Model(hr, r, shifts, 0.7);
  const Image truth = WithoutBlindFrequencies(SmoothObject(hr), r);
  const TikhonovResult t = ReconstructTikhonov(MakeProblem(model, model->Render(truth), shifts), FixedLambda(0.0));
  EXPECT_LT(RelativeError(t.image, truth), 1e-6);
}

TEST(ReconstructStabilityTest, HugeLambdaTendsToThePriorsNullSpaceFit) {
  const Shape hr{32, 32};
  const int r = 2;
  const auto shifts = HalfPixelRaster(r);
  const auto model = Model(hr, r, shifts, 1.0);
  const Image truth = SmoothObject(hr);
  const ReconstructionProblem p = MakeProblem(model, model->Render(truth), shifts);
  const double mean = truth.mean();
  for (double lambda : {1e12, 1e300}) {
    SCOPED_TRACE("lambda " + std::to_string(lambda));
    // Gradient and Laplacian priors charge nothing for a constant: the estimate tends to the flat image at
    // the data's mean (unit-sum PSFs conserve flux), with deviations O(λ₀/λ).
    for (TikhonovPrior prior : {TikhonovPrior::kGradient, TikhonovPrior::kLaplacian}) {
      ReconstructOptions o;
      o.tikhonov = FixedLambda(lambda, prior);
      const Reconstruction rec = RunMethod(p, ReconstructionMethod::kTikhonov, o);
      ExpectSane(rec, p, ReconstructionMethod::kTikhonov);
      EXPECT_LT((rec.image - mean).abs().maxCoeff(), 1e-6 * mean) << ToString(prior);
    }
    // The identity prior's null space is {0}.
    const TikhonovResult t = ReconstructTikhonov(p, FixedLambda(lambda, TikhonovPrior::kIdentity));
    EXPECT_LT(t.image.abs().maxCoeff(), 1e-6 * mean);
    // On the CG path too (one masked pixel breaks the Fourier structure): the result is the weighted
    // null-space fit to rounding, and the solve says it converged (tikhonov_cg.cpp, LargeLambdaExpansion).
    ReconstructionProblem masked = p;
    masked.weights = ImageStack(4, Image::Ones(16, 16));
    masked.weights[1](3, 4) = 0;
    const TikhonovResult c = ReconstructTikhonov(masked, FixedLambda(lambda));
    EXPECT_EQ(c.summary.method, "tikhonov-cg");
    EXPECT_TRUE(AllFinite(c.image));
    EXPECT_EQ(c.summary.termination, Termination::kConverged) << c.summary.message;
    // The oracle: the weighted least-squares fit of the frames by a flat object, aᵀWy / aᵀWa with a = A·1
    // (not the truth's mean: the masked pixel takes its share of the structure out of the weighted mean).
    const ImageStack a = model->Render(Image::Ones(hr.rows, hr.cols));
    double awy = 0, awa = 0;
    for (int i = 0; i < 4; ++i) {
      awy += (masked.weights[i] * a[i] * masked.frames[i]).sum();
      awa += (masked.weights[i] * a[i] * a[i]).sum();
    }
    EXPECT_LT((c.image - awy / awa).abs().maxCoeff(), 1e-9 * mean) << c.summary.message;
  }
  // TV with an overwhelming weight: also the flat image at the mean (TV, too, charges nothing for DC).
  ReconstructOptions o;
  o.auto_regularisation = false;
  o.tv.mu = 1e6;
  const Reconstruction tv = RunMethod(p, ReconstructionMethod::kTotalVariation, o);
  ExpectSane(tv, p, ReconstructionMethod::kTotalVariation);
  EXPECT_LT((tv.image - mean).abs().maxCoeff(), 1e-3 * mean) << tv.summary.BriefReport();
}

// Every λ from 1e-4 to the largest the options allow converges on the masked (CG) path, by design: PCG
// where the system is within double precision, the closed-form λ → ∞ expansion beyond (tikhonov_cg.cpp).
TEST(ReconstructStabilityTest, EveryLambdaConvergesOnTheConjugateGradientPath) {
  const Shape hr{32, 32};
  const auto shifts = HalfPixelRaster(2);
  const auto model = Model(hr, 2, shifts, 1.0);
  const Image truth = SmoothObject(hr);
  ReconstructionProblem p = MakeProblem(model, AddNoise(model->Render(truth), 0.01, 5), shifts);
  p.weights = ImageStack(4, Image::Ones(16, 16));
  p.weights[1](3, 4) = 0;
  p.weights[2](10, 2) = 0.25;
  for (TikhonovPrior prior : {TikhonovPrior::kGradient, TikhonovPrior::kLaplacian, TikhonovPrior::kIdentity})
    for (double lambda = 1e-4; lambda <= 1e300; lambda *= (lambda < 1e14 ? 10.0 : 1e19)) {
      SCOPED_TRACE(std::string(ToString(prior)) + " lambda " + ToString(lambda));
      const TikhonovResult c = ReconstructTikhonov(p, FixedLambda(lambda, prior));
      ASSERT_TRUE(AllFinite(c.image));
      EXPECT_EQ(c.summary.termination, Termination::kConverged) << c.summary.message;
    }
}

// The expansion is the solution, not an approximation of it: just past the switch (ρ = 2e8) it agrees
// with the exact per-bin Fourier solve of the same (uniform-weight) problem, including the O(1/λ) part
// that makes the image differ from the flat fit.
TEST(ReconstructStabilityTest, LargeLambdaExpansionAgreesWithTheExactFourierSolve) {
  const Shape hr{32, 32};
  const int r = 2;
  const auto shifts = HalfPixelRaster(r);
  const auto model = Model(hr, r, shifts, 1.0);
  const ReconstructionProblem p = MakeProblem(model, model->Render(SmoothObject(hr)), shifts);
  const double gamma_min = 4 * std::pow(std::sin(M_PI / 32), 2);  // gradient prior, lowest non-zero bin
  const double lambda = 2e8 * (4.0 * r * r) / gamma_min;          // ρ = λ γ_min / (w_max N r²) = 2e8
  TikhonovOptions cg = FixedLambda(lambda);
  cg.method = TikhonovMethod::kConjugateGradient;
  TikhonovOptions fourier = FixedLambda(lambda);
  fourier.method = TikhonovMethod::kFourier;
  const TikhonovResult e = ReconstructTikhonov(p, cg), f = ReconstructTikhonov(p, fourier);
  ASSERT_THAT(e.summary.message, testing::HasSubstr("large-lambda expansion"));
  const double deviation = (f.image - f.image.mean()).abs().maxCoeff();  // the O(1/λ) structure
  ASSERT_GT(deviation, 1e-12 * f.image.mean());
  EXPECT_LT((e.image - f.image).abs().maxCoeff(), 1e-4 * deviation);
}

// The huge-λ solves are decided the same way every time: 200 repetitions give the same bytes and converge.
TEST(ReconstructStabilityTest, HugeLambdaSolvesAreTheSameTwoHundredTimes) {
  const Shape hr{32, 32};
  const auto shifts = HalfPixelRaster(2);
  const auto model = Model(hr, 2, shifts, 1.0);
  ReconstructionProblem p = MakeProblem(model, model->Render(SmoothObject(hr)), shifts);
  p.weights = ImageStack(4, Image::Ones(16, 16));
  p.weights[1](3, 4) = 0;
  for (double lambda : {1e9, 1e300}) {  // PCG just below the switch, the expansion far beyond it
    const TikhonovResult first = ReconstructTikhonov(p, FixedLambda(lambda));
    for (int k = 0; k < 200; ++k) {
      const TikhonovResult again = ReconstructTikhonov(p, FixedLambda(lambda));
      ASSERT_EQ(again.summary.termination, Termination::kConverged) << "repeat " << k << ": " << again.summary.message;
      ASSERT_EQ(std::memcmp(again.image.data(), first.image.data(), sizeof(double) * first.image.size()), 0)
          << "repeat " << k << " at lambda " << lambda;
    }
  }
}

// ---------------------------------------------------------------------------------------------------------
// Dynamic range: a star 10⁶ times brighter than a faint galaxy beside it

TEST(ReconstructStabilityTest, StarAMillionTimesBrighterThanTheGalaxyBesideIt) {
  const Shape hr{48, 48};
  const int r = 2;
  const auto shifts = FullRaster(r);
  const auto model = Model(hr, r, shifts, 1.0);
  Image galaxy = Image::Zero(hr.rows, hr.cols);
  for (Index y = 0; y < hr.rows; ++y)
    for (Index x = 0; x < hr.cols; ++x) {
      const double dy = (y - 32.0) / 3.0, dx = (x - 32.0) / 5.0;
      galaxy(y, x) = std::exp(-0.5 * (dy * dy + dx * dx));  // peak 1 e- per HR px, 12–17 px from the star
    }
  Image star = Image::Zero(hr.rows, hr.cols);
  const double star_flux = 1e6 * galaxy.sum();
  star(20, 20) = star_flux;
  const Image truth = star + galaxy;
  // The galaxy's box leaves out the star's row and column: a point source has content on the blind
  // frequencies, which no method sees, so every estimate misses a (−1)^y line through the star.
  const auto galaxy_error = [&](const Image& x) {
    return Norm(x.block(25, 24, 15, 17) - galaxy.block(25, 24, 15, 17));
  };

  // Linear methods (fixed λ), noise-free: the galaxy comes out exactly as it does alone once the star's own
  // response is subtracted; the 10⁶ range costs only rounding. Flux is conserved to rounding.
  ReconstructOptions o;
  o.tikhonov = FixedLambda(1e-3);
  for (ReconstructionMethod m : {ReconstructionMethod::kShiftAddMean, ReconstructionMethod::kDrizzle,
                                 ReconstructionMethod::kTikhonov}) {
    const auto rec = [&](const Image& x) { return RunMethod(MakeProblem(model, model->Render(x), shifts), m, o); };
    const Reconstruction both = rec(truth), alone = rec(galaxy), s = rec(star);
    ExpectSane(both, MakeProblem(model, model->Render(truth), shifts), m);
    EXPECT_LT(Norm(both.image - s.image - alone.image), 1e-6 * Norm(alone.image)) << ToString(m);
    EXPECT_NEAR(both.image.sum(), truth.sum(), 1e-9 * truth.sum()) << ToString(m) << ": flux";
  }

  // Defaults on frames with noise at 1% of the galaxy's frame peak: finite, not failed, the flux kept (no
  // prior charges for DC) and the star on its pixel.
  const ImageStack noisy = AddNoise(model->Render(truth), 0.01 * model->Render(galaxy)[0].maxCoeff(), 2);
  const ReconstructionProblem p = MakeProblem(model, noisy, shifts);
  std::map<ReconstructionMethod, Reconstruction> out;
  for (ReconstructionMethod m : {ReconstructionMethod::kTikhonov, ReconstructionMethod::kTotalVariation,
                                 ReconstructionMethod::kMap}) {
    const Reconstruction& rec = out[m] = RunMethod(p, m);
    ExpectSane(rec, p, m);
    EXPECT_NE(rec.summary.termination, Termination::kFailed) << ToString(m) << ": " << rec.summary.BriefReport();
    EXPECT_NEAR(rec.image.sum(), truth.sum(), 1e-4 * truth.sum()) << ToString(m);
    Index iy, ix;
    rec.image.maxCoeff(&iy, &ix);
    EXPECT_EQ(iy, 20) << ToString(m);
    EXPECT_EQ(ix, 20) << ToString(m);
  }
  // Tikhonov: GCV runs to the smallest λ of its grid (the star's flat spectrum looks like signal) and says
  // so; at every λ the star's side lobes bury the galaxy (linear: its error there is the star's own).
  const Reconstruction& tik = out[ReconstructionMethod::kTikhonov];
  EXPECT_THAT(tik.summary.message, HasSubstr("GCV minimum at the smallest lambda"));
  EXPECT_GT(galaxy_error(tik.image), 100 * Norm(galaxy.block(25, 24, 15, 17)));
  // TV: ADMM stops when its residuals fall below ε_rel times the norms of ∇x, which the star dominates, so
  // what it leaves anywhere is of order ε_rel × the star: bounded by it at the default ε_rel = 1e-4 and, with
  // ε_rel = 1e-6, small against the galaxy itself.
  const double eps = TotalVariationOptions().relative_tolerance;
  EXPECT_LT(galaxy_error(out[ReconstructionMethod::kTotalVariation].image), eps * star_flux);
  ReconstructOptions tight;
  tight.tv.relative_tolerance = 1e-6;
  tight.tv.max_iterations = 5000;
  const Reconstruction tv = RunMethod(p, ReconstructionMethod::kTotalVariation, tight);
  EXPECT_EQ(tv.summary.termination, Termination::kConverged) << tv.summary.BriefReport();
  EXPECT_LT(galaxy_error(tv.image), 1e-6 * star_flux);
  EXPECT_LT(RelativeError(tv.image, truth), 1e-4);
  // MAP (L-BFGS from the Tikhonov estimate) improves on its warm start; if it claims convergence, it is close.
  const Reconstruction& map = out[ReconstructionMethod::kMap];
  EXPECT_LT(RelativeError(map.image, truth), RelativeError(tik.image, truth)) << map.summary.BriefReport();
  if (map.summary.termination == Termination::kConverged) {
    EXPECT_LT(RelativeError(map.image, truth), 1e-3);
  }
}

// ---------------------------------------------------------------------------------------------------------
// All-zero frames

TEST(ReconstructStabilityTest, AllZeroFramesGiveAZeroImage) {
  const Shape hr{32, 32};
  const auto shifts = HalfPixelRaster(2);
  const auto model = Model(hr, 2, shifts, 1.0);
  const ReconstructionProblem p = MakeProblem(model, ImageStack(4, Image::Zero(16, 16)), shifts);
  for (ReconstructionMethod m : AllMethods()) {
    const Reconstruction rec = RunMethod(p, m);
    ExpectSane(rec, p, m);
    EXPECT_NE(rec.summary.termination, Termination::kFailed) << ToString(m) << ": " << rec.summary.BriefReport();
    EXPECT_EQ(rec.image.abs().maxCoeff(), 0.0) << ToString(m);
  }
}

TEST(ReconstructStabilityTest, EveryPixelMaskedIsAnErrorOrAReportedFailure) {
  const Shape hr{32, 32};
  const auto shifts = HalfPixelRaster(2);
  const auto model = Model(hr, 2, shifts, 1.0);
  ReconstructionProblem p = MakeProblem(model, model->Render(SmoothObject(hr)), shifts,
                                        ImageStack(4, Image::Zero(16, 16)));
  p.frames[0](0, 0) = kNaN;  // never read
  for (ReconstructionMethod m : AllMethods()) {
    SCOPED_TRACE(ToString(m));
    if (m == ReconstructionMethod::kShiftAddMean || m == ReconstructionMethod::kShiftAddMedian ||
        m == ReconstructionMethod::kDrizzle) {
      const Reconstruction rec = RunMethod(p, m);  // nothing to combine: a zero image, said so
      EXPECT_EQ(rec.summary.termination, Termination::kFailed) << rec.summary.BriefReport();
      EXPECT_EQ(rec.image.abs().maxCoeff(), 0.0);
    } else {
      EXPECT_THAT(ErrorOf([&] { RunMethod(p, m); }), AllOf(HasSubstr("problem.weights"), HasSubstr("all zero")));
    }
  }
}

// ---------------------------------------------------------------------------------------------------------
// NaN / Inf pixels

TEST(ReconstructStabilityTest, MaskedNonFinitePixelsAreNeverRead) {
  const Shape hr{32, 32};
  const auto shifts = HalfPixelRaster(2);
  const auto model = Model(hr, 2, shifts, 1.0);
  const Image truth = SmoothObject(hr);
  ReconstructionProblem a = MakeProblem(model, AddNoise(model->Render(truth), 0.01, 4), shifts,
                                        ImageStack(4, Image::Ones(16, 16)));
  ReconstructionProblem b = a;
  const std::vector<std::pair<int, std::pair<Index, Index>>> bad = {{0, {3, 4}}, {1, {10, 2}}, {3, {15, 15}}};
  for (std::size_t k = 0; k < bad.size(); ++k) {
    const auto [i, yx] = bad[k];
    a.frames[i](yx.first, yx.second) = k == 1 ? kInf : kNaN;
    b.frames[i](yx.first, yx.second) = 1e300;  // any value: the pixel is masked
    a.weights[i](yx.first, yx.second) = b.weights[i](yx.first, yx.second) = 0;
  }
  for (ReconstructionMethod m : AllMethods()) {
    const Reconstruction ra = RunMethod(a, m), rb = RunMethod(b, m);
    ExpectSane(ra, a, m);
    EXPECT_NE(ra.summary.termination, Termination::kFailed) << ToString(m) << ": " << ra.summary.BriefReport();
    EXPECT_EQ((ra.image - rb.image).abs().maxCoeff(), 0.0) << ToString(m) << ": a masked pixel was read";
    EXPECT_LT(RelativeError(ra.image, truth), FlatError(truth)) << ToString(m);
  }
}

TEST(ReconstructStabilityTest, UnmaskedNonFinitePixelsAreAClearError) {
  const Shape hr{32, 32};
  const auto shifts = HalfPixelRaster(2);
  const auto model = Model(hr, 2, shifts, 1.0);
  for (double bad : {kNaN, kInf, -kInf}) {
    ReconstructionProblem p = MakeProblem(model, model->Render(SmoothObject(hr)), shifts);
    p.frames[1](2, 3) = bad;
    for (ReconstructionMethod m : AllMethods())
      EXPECT_THAT(ErrorOf([&] { RunMethod(p, m); }),
                  AllOf(HasSubstr("Reconstruct"), HasSubstr("problem.frames[1](2, 3)"), HasSubstr("mask it")))
          << ToString(m) << " " << bad;
    // A weight map that leaves the pixel weighted is no excuse.
    p.weights = ImageStack(4, Image::Constant(16, 16, 0.5));
    EXPECT_THAT(ErrorOf([&] { RunMethod(p, ReconstructionMethod::kTikhonov); }), HasSubstr("problem.frames[1](2, 3)"));
  }
}

// ---------------------------------------------------------------------------------------------------------
// Saturation

TEST(ReconstructStabilityTest, SaturatedPixelsMaskedByWeightZeroBeatClippedData) {
  const Shape hr{32, 32};
  const int r = 2;
  const auto shifts = FullRaster(r);
  const auto model = Model(hr, r, shifts, 1.0);
  Image truth = SmoothObject(hr);
  truth(12, 20) += 400;  // a star that saturates the camera
  ImageStack frames = AddNoise(model->Render(truth), 0.02, 6);
  const double full_well = 0.3 * frames[0].maxCoeff();
  ImageStack weights;
  Index saturated = 0;
  for (Image& f : frames) {
    weights.push_back((f >= full_well).select(0.0, Image::Ones(16, 16)));
    saturated += (f >= full_well).count();
    f = f.min(full_well);
  }
  ASSERT_GT(saturated, 4);
  const ReconstructionProblem clipped = MakeProblem(model, frames, shifts);
  const ReconstructionProblem masked = MakeProblem(model, frames, shifts, weights);
  // Photometry of the star (5 x 5 HR box) and the error of the scene away from it (outside 9 x 9).
  const auto star_flux = [](const Image& x) { return x.block(10, 18, 5, 5).sum(); };
  const auto scene_error = [&](const Image& x) {
    Image d = x - truth;
    d.block(8, 16, 9, 9).setZero();
    Image t = truth;
    t.block(8, 16, 9, 9).setZero();
    return Norm(d) / Norm(t);
  };
  const double flux = star_flux(truth);
  // GCV runs to the edge of its grid when a star dominates the scene (and says so, below); a fixed λ, as a
  // user who knows the noise would set, keeps the automatic TV/MAP weights at the noise level. TV stops at
  // ε_rel = 1e-3: with masks its x-update is unpreconditioned CG, ~100 steps each here.
  ReconstructOptions o;
  o.tikhonov = FixedLambda(1e-2);
  o.tv.relative_tolerance = 1e-3;
  const double flat = FlatError(SmoothObject(hr));
  for (ReconstructionMethod m : AllMethods()) {
    SCOPED_TRACE(ToString(m));
    const Reconstruction a = RunMethod(masked, m, o);
    ExpectSane(a, masked, m);
    EXPECT_NE(a.summary.termination, Termination::kFailed) << a.summary.BriefReport();
    if (m == ReconstructionMethod::kShiftAddMean || m == ReconstructionMethod::kShiftAddMedian) {
      // No frame saw the star's core: the holes are zero, and the summary counts them.
      EXPECT_THAT(a.summary.message, HasSubstr("HR pixels reached by no valid frame"));
      EXPECT_LT(scene_error(a.image), 0.5 * flat);
    } else if (m == ReconstructionMethod::kDrizzle) {
      EXPECT_THAT(a.summary.message, HasSubstr("set to fill_value"));
      EXPECT_LT(scene_error(a.image), 0.5 * flat);
    } else {
      // Model-based: clipped values contradict the model, masked pixels do not; the edge-preserving priors
      // also keep the star's missing core from ringing over the scene.
      const Reconstruction b = RunMethod(clipped, m, o);
      EXPECT_LT(scene_error(a.image), scene_error(b.image));
      if (m != ReconstructionMethod::kTikhonov) {
        EXPECT_LT(scene_error(a.image), 0.5 * flat);
      }
      EXPECT_NEAR(star_flux(a.image), flux, 0.3 * flux);  // measured 0.76–0.85 of it, from the wings
    }
  }
  const TikhonovResult gcv = ReconstructTikhonov(clipped, ReconstructOptions().tikhonov);
  EXPECT_THAT(gcv.summary.message, HasSubstr("GCV minimum at the smallest lambda"));
}

// ---------------------------------------------------------------------------------------------------------
// Odd and prime sizes; r = 1 and r = 8

TEST(ReconstructStabilityTest, OddAndPrimeImageSizes) {
  struct Case {
    Shape hr;
    int r;
  };
  // LR 13 x 17 (primes) at r = 2; LR 7 x 7 at r = 3 (odd HR 21); 23 x 29 (prime HR) at r = 1.
  for (const Case& c : {Case{{26, 34}, 2}, Case{{21, 21}, 3}, Case{{23, 29}, 1}}) {
    SCOPED_TRACE(ToString(c.hr) + " r = " + std::to_string(c.r));
    const auto shifts = FullRaster(c.r);
    const auto model = Model(c.hr, c.r, shifts, 0.7);
    const Image smooth = SmoothObject(c.hr);
    // Exact recovery of the visible part from noise-free frames.
    const Image visible = WithoutBlindFrequencies(smooth, c.r);
    const TikhonovResult t =
        ReconstructTikhonov(MakeProblem(model, model->Render(visible), shifts), FixedLambda(0.0));
    EXPECT_LT(RelativeError(t.image, visible), 1e-6);
    EXPECT_EQ(t.summary.unconstrained_frequencies, BlindFrequencyCount(c.hr, c.r));
    // Every method on noisy frames.
    const ReconstructionProblem p = MakeProblem(model, AddNoise(model->Render(smooth), 0.01, 8), shifts);
    for (ReconstructionMethod m : AllMethods()) {
      const Reconstruction rec = RunMethod(p, m);
      ExpectSane(rec, p, m);
      EXPECT_NE(rec.summary.termination, Termination::kFailed) << ToString(m) << ": " << rec.summary.BriefReport();
      EXPECT_LT(RelativeError(rec.image, smooth), 0.5 * FlatError(smooth)) << ToString(m);
    }
  }
}

TEST(ReconstructStabilityTest, ROneIsDeconvolutionAndTheBaselinesReturnTheFrame) {
  const Shape hr{24, 24};
  const std::vector<Shift> shifts = {{0, 0}};
  const auto model = Model(hr, 1, shifts, 0.7);
  const Image truth = SmoothObject(hr);
  const Image frame = AddNoise(model->Render(truth), 0.005, 9)[0];
  const ReconstructionProblem p = MakeProblem(model, {frame}, shifts);
  for (ReconstructionMethod m : AllMethods()) {
    const Reconstruction rec = RunMethod(p, m);
    ExpectSane(rec, p, m);
    EXPECT_NE(rec.summary.termination, Termination::kFailed) << ToString(m) << ": " << rec.summary.BriefReport();
    if (m == ReconstructionMethod::kShiftAddMean || m == ReconstructionMethod::kShiftAddMedian ||
        m == ReconstructionMethod::kDrizzle) {
      EXPECT_LT((rec.image - frame).abs().maxCoeff(), 1e-12) << ToString(m) << ": r = 1, no shift";
    } else {
      EXPECT_LT(RelativeError(rec.image, truth), RelativeError(frame, truth)) << ToString(m) << ": no deblurring";
    }
  }
  // Noise-free, λ = 0: an exact deconvolution (the Gaussian OTF has no zero on this grid).
  const TikhonovResult t = ReconstructTikhonov(MakeProblem(model, model->Render(truth), shifts), FixedLambda(0.0));
  EXPECT_LT(RelativeError(t.image, truth), 1e-6);
  EXPECT_EQ(t.summary.unconstrained_frequencies, 0);
}

TEST(ReconstructStabilityTest, REightWithFourFrames) {
  const Shape hr{32, 32};
  const int r = 8;  // LR 4 x 4, N = 4 of r² = 64
  const auto shifts = HalfPixelRaster(r);
  const auto model = Model(hr, r, shifts, 2.0);
  const Image truth = SmoothObject(hr);
  const ReconstructionProblem p = MakeProblem(model, AddNoise(model->Render(truth), 0.02, 10), shifts);
  for (ReconstructionMethod m : AllMethods()) {
    const Reconstruction rec = RunMethod(p, m);
    ExpectSane(rec, p, m);
    EXPECT_NE(rec.summary.termination, Termination::kFailed) << ToString(m) << ": " << rec.summary.BriefReport();
    EXPECT_LT(RelativeError(rec.image, truth), FlatError(truth)) << ToString(m);
  }
  const TikhonovResult t = ReconstructTikhonov(p, CountingDefaults());
  EXPECT_EQ(t.summary.rank_deficient_bins, 16);
  EXPECT_GE(t.summary.unconstrained_frequencies, Index(64 - 4) * 16);
}

// ---------------------------------------------------------------------------------------------------------
// Iteration limits

TEST(ReconstructStabilityTest, IterationLimitsAreReportedWithAFiniteImage) {
  const Shape hr{32, 32};
  const auto shifts = HalfPixelRaster(2);
  const auto model = Model(hr, 2, shifts, 1.0);
  const Image truth = Blocks(hr);
  const ReconstructionProblem p = MakeProblem(model, AddNoise(model->Render(truth), 0.02, 12), shifts);
  // MAP: Ceres stops at its iteration limit (NO_CONVERGENCE) and the summary says so.
  ReconstructOptions o;
  o.map.max_iterations = 3;
  const Reconstruction map = RunMethod(p, ReconstructionMethod::kMap, o);
  ExpectSane(map, p, ReconstructionMethod::kMap);
  EXPECT_EQ(map.summary.termination, Termination::kMaxIterations) << map.summary.BriefReport();
  EXPECT_EQ(map.summary.iterations, 3);
  EXPECT_THAT(map.summary.message, HasSubstr("Maximum number of iterations"));
  // Its own API: from a flat start, the cost has gone down, never up.
  MapOptions mo;
  mo.max_iterations = 2;
  mo.positivity = MapPositivity::kSoftplus;
  const MapResult mr = MapReconstruct(p, mo);
  EXPECT_EQ(mr.summary.termination, Termination::kMaxIterations);
  EXPECT_TRUE(AllFinite(mr.image));
  EXPECT_LE(mr.summary.final_cost, mr.summary.initial_cost);
  EXPECT_GE(mr.image.minCoeff(), 0.0);
  // TV (ADMM).
  o.tv.max_iterations = 4;
  const Reconstruction tv = RunMethod(p, ReconstructionMethod::kTotalVariation, o);
  ExpectSane(tv, p, ReconstructionMethod::kTotalVariation);
  EXPECT_EQ(tv.summary.termination, Termination::kMaxIterations) << tv.summary.BriefReport();
  EXPECT_EQ(tv.summary.iterations, 4);
  EXPECT_THAT(tv.summary.message, HasSubstr("iteration limit reached"));
  // Tikhonov's CG path (a masked pixel makes it iterate).
  ReconstructionProblem masked = p;
  masked.weights = ImageStack(4, Image::Ones(16, 16));
  masked.weights[2](5, 5) = 0;
  o.tikhonov = FixedLambda(1e-6);
  o.tikhonov.cg.max_iterations = 1;
  o.tikhonov.precondition = false;
  const Reconstruction t = RunMethod(masked, ReconstructionMethod::kTikhonov, o);
  ExpectSane(t, masked, ReconstructionMethod::kTikhonov);
  EXPECT_EQ(t.summary.termination, Termination::kMaxIterations) << t.summary.BriefReport();
}

// ---------------------------------------------------------------------------------------------------------
// Bad input

TEST(ReconstructStabilityTest, BadInputGetsAClearError) {
  const Shape hr{32, 32};
  const auto shifts = HalfPixelRaster(2);
  const auto model = Model(hr, 2, shifts, 1.0);
  const ReconstructionProblem good = MakeProblem(model, model->Render(SmoothObject(hr)), shifts);
  for (ReconstructionMethod m : AllMethods()) {
    SCOPED_TRACE(ToString(m));
    ReconstructionProblem p = good;
    p.frames[2] = Image::Zero(16, 17);  // frames of different shapes
    EXPECT_THAT(ErrorOf([&] { RunMethod(p, m); }), AllOf(HasSubstr("problem.frames[2] shape"), HasSubstr("16x17")));
    p = good;
    p.frames.pop_back();  // fewer frames than the model
    EXPECT_THAT(ErrorOf([&] { RunMethod(p, m); }), HasSubstr("problem.frames.size()"));
    p = good;
    p.weights = ImageStack(4, Image::Ones(16, 16));
    p.weights[3](1, 1) = -1;  // negative weight
    EXPECT_THAT(ErrorOf([&] { RunMethod(p, m); }), AllOf(HasSubstr("problem.weights[3]"), HasSubstr(">= 0")));
    p.weights[3](1, 1) = kNaN;
    EXPECT_THAT(ErrorOf([&] { RunMethod(p, m); }), HasSubstr("problem.weights[3]"));
    p = good;
    p.model = nullptr;
    EXPECT_THAT(ErrorOf([&] { RunMethod(p, m); }), HasSubstr("problem.model is null"));
  }
  ReconstructionProblem p = good;
  p.offsets.clear();  // registration methods need offsets
  EXPECT_THAT(ErrorOf([&] { RunMethod(p, ReconstructionMethod::kShiftAddMean); }), HasSubstr("problem.offsets"));
  EXPECT_THAT(ErrorOf([&] { RunMethod(p, ReconstructionMethod::kDrizzle); }), HasSubstr("offsets"));
  ReconstructOptions o;
  o.tikhonov.lambda = -1;
  EXPECT_THAT(ErrorOf([&] { RunMethod(good, ReconstructionMethod::kTikhonov, o); }), HasSubstr("lambda"));
}

// A dataset on disk whose manifest does not match its files is refused before any reconstruction; the
// matching one runs through every method.
TEST(ReconstructStabilityTest, DatasetManifestMustMatchItsFiles) {
  testing_io::TempDir dir;
  test::SimulateInto(dir.File("scene.json"), test::SmallDatasetScene(), dir.File("sim"));
  const DatasetProblem dp = ProblemFromDataset(LoadDataset(dir.File("sim")));
  for (ReconstructionMethod m : AllMethods()) {
    const Reconstruction rec = RunMethod(dp.problem, m);
    ExpectSane(rec, dp.problem, m);
  }
  nlohmann::json manifest = ReadJsonFile(dir.File("sim/manifest.json"));
  const auto load_error = [&](const nlohmann::json& m) {
    test::WriteJson(dir.File("sim/broken.json"), m);
    return ErrorOf([&] { ProblemFromDataset(LoadDataset(dir.File("sim/broken.json"))); });
  };
  nlohmann::json m = manifest;
  m["frame_shape"] = {32, 31};
  EXPECT_THAT(load_error(m), AllOf(HasSubstr("broken.json"), HasSubstr("frame_shape")));
  m = manifest;
  m["valid"] = "truth.fits";  // a file of the wrong shape
  EXPECT_THAT(load_error(m), AllOf(HasSubstr("broken.json"), HasSubstr("valid")));
  m = manifest;
  m["r"] = 4;  // the PSFs and truth were made at r = 2
  EXPECT_THAT(load_error(m), HasSubstr("broken.json"));
  // Negative weights in the file.
  ImageStack planes = ReadFits(dir.File("sim/weights.fits")).planes;
  planes[0](4, 4) = -2;
  WriteFitsCube(dir.File("sim/negative_weights.fits"), planes);
  m = manifest;
  m["weights"] = "negative_weights.fits";
  EXPECT_THAT(load_error(m), AllOf(HasSubstr("broken.json"), HasSubstr("weights")));
}

}  // namespace
}  // namespace aosr
