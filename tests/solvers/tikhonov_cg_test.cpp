// The conjugate-gradient path of tikhonov.hpp: weights, masks and zero-padded boundaries.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <limits>

#include "aosr/core/operators.hpp"
#include "aosr/solvers/padded_model.hpp"
#include "aosr/solvers/tikhonov.hpp"
#include "solvers/tikhonov_fixture.hpp"
#include "support/testing.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

using test::RasterModel;

std::shared_ptr<const MultiFrameModel> Shared(MultiFrameModel m) {
  return std::make_shared<const MultiFrameModel>(std::move(m));
}

ReconstructionProblem NoisyProblem(Shape hr, int r, const std::vector<std::pair<double, double>>& shifts,
                                   double sigma, std::uint64_t seed) {
  ReconstructionProblem p;
  p.model = Shared(RasterModel(hr, r, shifts, 1.0));
  p.frames = test::AddNoise(p.model->Render(1.0 + test::RandomImage(hr, seed, false)), sigma, seed + 1);
  return p;
}

// Weights: 1 everywhere but `fraction` of the pixels of every frame masked (fixed seed).
ImageStack MaskSome(const ReconstructionProblem& p, double fraction, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u01;
  ImageStack w;
  for (const Image& f : p.frames) {
    Image m = Image::Ones(f.rows(), f.cols());
    for (Index i = 0; i < m.size(); ++i)
      if (u01(rng) < fraction) m.data()[i] = 0;
    w.push_back(m);
  }
  return w;
}

// With uniform weights the CG path solves the same problem as the Fourier path: equal to 1e-8, with and
// without the preconditioner, which is then the exact inverse (one iteration).
TEST(TikhonovCgTest, UniformWeightsGiveTheFourierAnswer) {
  for (TikhonovPrior prior : {TikhonovPrior::kGradient, TikhonovPrior::kPowerSpectrum}) {
    ReconstructionProblem p = NoisyProblem({32, 40}, 2, {{0, 0}, {0.5, 1}, {1.3, 0.2}}, 0.02, 4);
    p.weights = ImageStack(3, Image::Constant(16, 20, 2.5));
    TikhonovOptions o;
    o.prior = prior;
    o.lambda = 0.05;
    o.compute_std = true;
    o.noise_sigma = 0.02;
    const TikhonovResult fourier = ReconstructTikhonov(p, o);
    ASSERT_EQ(fourier.summary.method, "tikhonov-fourier");
    o.method = TikhonovMethod::kConjugateGradient;
    o.cg.tolerance = 1e-13;
    o.cg.max_iterations = 5000;
    for (bool precondition : {true, false}) {
      o.precondition = precondition;
      const TikhonovResult cg = ReconstructTikhonov(p, o);
      ASSERT_EQ(cg.summary.method, "tikhonov-cg");
      ASSERT_EQ(cg.summary.termination, Termination::kConverged) << cg.summary.BriefReport();
      const double rel = (cg.image - fourier.image).matrix().norm() / fourier.image.matrix().norm();
      EXPECT_LT(rel, 1e-8) << ToString(prior) << (precondition ? " preconditioned" : " plain");
      std::printf("%s, uniform weights, %s: %d CG iterations, |x_cg - x_fourier| / |x| = %.2e\n",
                  ToString(prior), precondition ? "preconditioned" : "plain", cg.summary.iterations, rel);
      if (precondition) {
        EXPECT_LE(cg.summary.iterations, 2);
      }
      ASSERT_TRUE(cg.summary.std_computed);  // uniform weights: the closed form still applies
      EXPECT_LT((cg.posterior_std - fourier.posterior_std).abs().maxCoeff(),
                1e-12 * fourier.posterior_std.maxCoeff());
      EXPECT_NEAR(cg.summary.final_cost, fourier.summary.final_cost, 1e-9 * fourier.summary.final_cost);
    }
  }
}

// The answer solves the weighted normal equations (AᵀWA + λΓᵀΓ)x = AᵀWy, rebuilt here from the primitives,
// and the summary's residuals are WeightedDataMisfit's.
TEST(TikhonovCgTest, WeightedSolutionSolvesTheWeightedNormalEquations) {
  ReconstructionProblem p = NoisyProblem({24, 24}, 3, {{0, 0}, {1, 2}, {2, 1}, {0.5, 0.5}}, 0.01, 7);
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> u(0.25, 2.0);
  for (int i = 0; i < 4; ++i) {
    Image w(8, 8);
    for (Index k = 0; k < w.size(); ++k) w.data()[k] = u(rng);
    w(i, 2 * i) = 0;
    p.weights.push_back(w);
  }
  TikhonovOptions o;
  o.prior = TikhonovPrior::kLaplacian;
  o.lambda = 0.01;
  const TikhonovResult res = ReconstructTikhonov(p, o);
  ASSERT_EQ(res.summary.method, "tikhonov-cg");
  ASSERT_EQ(res.summary.termination, Termination::kConverged) << res.summary.BriefReport();
  const Shape hr = p.model->hr_shape();
  std::vector<OperatorPtr> weighted;
  Vector rhs = Vector::Zero(hr.size());
  for (int i = 0; i < 4; ++i) {
    const OperatorPtr ai = p.model->FrameOperator(i);
    weighted.push_back(Compose(Adjoint(ai), Compose(Mask(p.weights[i]), ai)));
    rhs += ai->ApplyAdjoint(AsVector(p.weights[i]).cwiseProduct(AsVector(p.frames[i])));
  }
  weighted.push_back(Scale(o.lambda, Normal(TikhonovPriorOperator(hr, o))));
  const Vector resid = Sum(weighted)->Apply(AsVector(res.image)) - rhs;
  EXPECT_LT(resid.norm() / rhs.norm(), 1e-9);
  std::vector<double> rms;
  const double misfit = WeightedDataMisfit(p, res.image, &rms);
  EXPECT_NEAR(res.summary.weighted_residual, 2 * misfit, 1e-12 * misfit);
  ASSERT_EQ(res.summary.frame_residual_rms.size(), 4u);
  for (int i = 0; i < 4; ++i) EXPECT_DOUBLE_EQ(res.summary.frame_residual_rms[i], rms[i]);

  // A residual region (a tile's core, solvers/tiling.cpp): the RMS over its weighted pixels, by hand; the cost
  // still covers every pixel.
  ReconstructionProblem q = p;
  q.residual_region = {2, 1, 5, 6};
  const TikhonovResult in_region = ReconstructTikhonov(q, o);
  EXPECT_EQ((in_region.image - res.image).abs().maxCoeff(), 0.0);
  EXPECT_DOUBLE_EQ(in_region.summary.weighted_residual, res.summary.weighted_residual);
  const ImageStack predicted = p.model->Render(res.image);
  ASSERT_EQ(in_region.summary.frame_residual_rms.size(), 4u);
  for (int i = 0; i < 4; ++i) {
    double ss = 0, n = 0;
    for (Index y = 2; y < 7; ++y)
      for (Index x = 1; x < 7; ++x)
        if (p.weights[i](y, x) > 0) ss += std::pow(p.frames[i](y, x) - predicted[i](y, x), 2), n += 1;
    EXPECT_NEAR(in_region.summary.frame_residual_rms[i], std::sqrt(ss / n), 1e-12 * std::sqrt(ss / n)) << i;
  }
  q.residual_region = {4, 4, 5, 5};  // beyond the 8 x 8 frames
  EXPECT_THROW(ReconstructTikhonov(q, o), InvalidArgument);
}

// A masked pixel is never read: NaN there gives exactly the answer that any finite value gives.
TEST(TikhonovCgTest, MaskedNaNPixelDoesNotChangeTheResult) {
  ReconstructionProblem p = NoisyProblem({32, 32}, 2, {{0, 0}, {0, 1}, {1, 0}, {1, 1}}, 0.02, 11);
  p.weights = MaskSome(p, 0.02, 5);
  p.weights[1](3, 5) = 0;
  p.weights[2].col(7).setZero();  // a bad column
  ReconstructionProblem finite = p, nan = p;
  finite.frames[1](3, 5) = 1e6;
  finite.frames[2].col(7).setConstant(-1e6);
  nan.frames[1](3, 5) = std::numeric_limits<double>::quiet_NaN();
  nan.frames[2].col(7).setConstant(std::numeric_limits<double>::infinity());
  TikhonovOptions o;
  o.lambda = 0.02;
  const TikhonovResult a = ReconstructTikhonov(finite, o), b = ReconstructTikhonov(nan, o);
  ASSERT_EQ(b.summary.termination, Termination::kConverged) << b.summary.BriefReport();
  ASSERT_TRUE(AllFinite(b.image));
  EXPECT_EQ((a.image - b.image).abs().maxCoeff(), 0.0);
  for (double rms : b.summary.frame_residual_rms) EXPECT_TRUE(std::isfinite(rms));
  // And the mask matters: unmasking the garbage moves the answer.
  finite.weights[1](3, 5) = 1;
  EXPECT_GT((ReconstructTikhonov(finite, o).image - a.image).abs().maxCoeff(), 1.0);
}

// What the Fourier preconditioner buys: iterations to the same tolerance, with and without, for masked
// pixels (2% and 10%, with non-uniform weights) and for a zero-padded boundary. Counts are reported. With
// masks, M⁻¹N = I − M⁻¹AᵀW_cA differs from I on a subspace of dimension ≤ N·(masked pixels), so the
// preconditioned count is about that, whatever the blur's conditioning: asserted to be cut at least 3x.
// With a zero-padded boundary every padded LR pixel is "masked" and the slow modes are pad-region objects
// that only the prior constrains (eigenvalues λ|Γ̂|²/(|A|² + λ|Γ̂|²) of M⁻¹N, the same spread as N's own):
// the Fourier preconditioner then helps little, which is asserted as "no worse" and reported.
TEST(TikhonovCgTest, FourierPreconditionerCutsTheIterationCount) {
  struct Case {
    const char* name;
    double masked;
    TikhonovBoundary boundary;
  };
  for (const Case& c : {Case{"2% masked", 0.02, TikhonovBoundary::kPeriodic},
                        Case{"10% masked, weights 0.5..1.5", 0.10, TikhonovBoundary::kPeriodic},
                        Case{"zero-padded boundary", 0.0, TikhonovBoundary::kZeroPadded}}) {
    ReconstructionProblem p = NoisyProblem({64, 64}, 2, {{0, 0}, {0.5, 1}, {1, 0.25}}, 0.01, 13);
    if (c.masked > 0) p.weights = MaskSome(p, c.masked, 17);
    if (c.masked > 0.05)
      for (Image& w : p.weights) w *= 1.0 + 0.5 * test::RandomImage(ShapeOf(w), 19, false) - 0.25;
    TikhonovOptions o;
    o.lambda = c.boundary == TikhonovBoundary::kZeroPadded ? 1e-2 : 1e-3;
    o.boundary = c.boundary;
    o.padding = 2;
    o.cg.tolerance = 1e-10;
    o.cg.max_iterations = 5000;
    o.precondition = false;
    const TikhonovResult plain = ReconstructTikhonov(p, o);
    o.precondition = true;
    const TikhonovResult pre = ReconstructTikhonov(p, o);
    ASSERT_EQ(plain.summary.termination, Termination::kConverged) << plain.summary.BriefReport();
    ASSERT_EQ(pre.summary.termination, Termination::kConverged) << pre.summary.BriefReport();
    std::printf("%-30s CG iterations: %4d plain, %3d preconditioned (%s)\n", c.name, plain.summary.iterations,
                pre.summary.iterations, pre.summary.message.c_str());
    if (c.boundary == TikhonovBoundary::kPeriodic) {
      EXPECT_LT(3 * pre.summary.iterations, plain.summary.iterations) << c.name;
    } else {
      EXPECT_LE(pre.summary.iterations, plain.summary.iterations) << c.name;
    }
    EXPECT_LT((pre.image - plain.image).matrix().norm() / plain.image.matrix().norm(), 1e-6) << c.name;
  }
}

// The discrepancy rule on the CG path: Σ w (y − Ax)² = τσ²n_w over the weighted pixels only.
TEST(TikhonovCgTest, DiscrepancyOnTheWeightedPath) {
  const double sigma = 0.03;
  ReconstructionProblem p = NoisyProblem({32, 32}, 2, {{0, 0}, {0, 1}, {1, 0}, {1, 1}}, sigma, 23);
  p.weights = MaskSome(p, 0.05, 29);
  Index n_w = 0;
  for (const Image& w : p.weights) n_w += (w > 0).count();
  TikhonovOptions o;
  o.lambda_rule = TikhonovLambdaRule::kDiscrepancy;
  o.noise_sigma = sigma;
  const TikhonovResult res = ReconstructTikhonov(p, o);
  ASSERT_EQ(res.summary.termination, Termination::kConverged) << res.summary.BriefReport();
  const double target = sigma * sigma * double(n_w);
  EXPECT_DOUBLE_EQ(res.summary.discrepancy_target, target);
  EXPECT_NEAR(2 * WeightedDataMisfit(p, res.image), target, 1e-4 * target);
  std::printf("discrepancy on the CG path: lambda %.4g after %d solves, %d PCG iterations in all\n",
              res.summary.lambda, res.summary.lambda_evaluations, res.summary.iterations);
}

// Light from outside the field: frames of an object larger than the field (a bright source just beyond
// the left edge, a ramp) rendered by the padded model. The periodic reconstruction must explain that light
// by wrapping, and rings; the zero-padded one models it. Error inside the field, noise-free, small λ.
TEST(TikhonovCgTest, ZeroPaddedBoundaryRemovesTheWrapAroundError) {
  const int r = 2;
  const Shape hr{48, 48};
  const auto model = Shared(RasterModel(hr, r, {{0, 0}, {0, 1}, {1, 0}, {1, 1}}, 1.5));
  const PaddedModel padded = PaddedModel::FromPeriodicModel(*model, 4);
  const Shape big = padded.padded_hr_shape();
  Image truth(big.rows, big.cols);
  for (Index y = 0; y < big.rows; ++y)
    for (Index x = 0; x < big.cols; ++x) truth(y, x) = 1.0 + 0.03 * double(x) + 0.02 * double(y);
  const Index top = Index(padded.padding()) * r;
  truth(top + 20, top - 2) += 200.0;  // just outside the field, on the left
  ReconstructionProblem p;
  p.model = model;
  p.frames = padded.Render(truth);
  TikhonovOptions o;
  o.lambda = 1e-3;
  o.cg.max_iterations = 20000;
  o.cg.tolerance = 1e-9;
  const TikhonovResult periodic = ReconstructTikhonov(p, o);
  o.boundary = TikhonovBoundary::kZeroPadded;
  o.padding = 4;
  const TikhonovResult zp = ReconstructTikhonov(p, o);
  ASSERT_EQ(zp.summary.termination, Termination::kConverged) << zp.summary.BriefReport();
  EXPECT_EQ(zp.summary.padding, 4);
  EXPECT_EQ(zp.summary.solved_hr_shape, big);
  const Image window = padded.CropObject(truth);
  // Compare away from the outermost camera pixel, which neither can pin down exactly.
  auto rms = [&](const Image& x) {
    return std::sqrt((x - window).block(4, 4, hr.rows - 8, hr.cols - 8).square().mean());
  };
  std::printf("interior RMS error: periodic %.4g, zero-padded %.4g (%s)\n", rms(periodic.image),
              rms(zp.image), zp.summary.message.c_str());
  EXPECT_LT(rms(zp.image), 0.2 * rms(periodic.image));

  // The residual region moves into the padded grid with the frames: the whole frame as a region is every pixel.
  ReconstructionProblem q = p;
  q.residual_region = {0, 0, hr.rows / r, hr.cols / r};
  const TikhonovResult zq = ReconstructTikhonov(q, o);
  ASSERT_EQ(zq.summary.frame_residual_rms.size(), zp.summary.frame_residual_rms.size());
  for (std::size_t i = 0; i < zq.summary.frame_residual_rms.size(); ++i)
    EXPECT_NEAR(zq.summary.frame_residual_rms[i], zp.summary.frame_residual_rms[i],
                1e-12 * zp.summary.frame_residual_rms[i]) << i;
}

}  // namespace
}  // namespace aosr
