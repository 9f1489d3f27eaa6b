// Bad options and inputs of the Tikhonov entry points, the padded model and preconditioned CG: each names
// the argument.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <functional>
#include <limits>

#include "aosr/core/operators.hpp"
#include "aosr/solvers/conjugate_gradient.hpp"
#include "aosr/solvers/padded_model.hpp"
#include "aosr/solvers/tikhonov.hpp"
#include "solvers/tikhonov_fixture.hpp"
#include "support/testing.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

using test::ErrorOf;
using ::testing::HasSubstr;

ReconstructionProblem Problem() {
  ReconstructionProblem p;
  p.model = std::make_shared<const MultiFrameModel>(test::RasterModel({16, 16}, 2, {{0, 0}, {1, 1}}, 1.0));
  p.frames = ImageStack(2, Image::Ones(8, 8));
  return p;
}

std::string ErrorOfSolve(const std::function<void(TikhonovOptions&)>& edit,
                         ReconstructionProblem p = Problem()) {
  TikhonovOptions o;
  edit(o);
  return ErrorOf([&] { ReconstructTikhonov(p, o); });
}

TEST(TikhonovErrorsTest, OptionsNameTheBadField) {
  EXPECT_THAT(ErrorOfSolve([](auto& o) { o.lambda = std::numeric_limits<double>::quiet_NaN(); }),
              HasSubstr("ReconstructTikhonov: options.lambda must be finite"));
  EXPECT_THAT(ErrorOfSolve([](auto& o) { o.spectrum_slope = -1; }), HasSubstr("options.spectrum_slope"));
  EXPECT_THAT(ErrorOfSolve([](auto& o) { o.spectrum_corner = 0.7; }), HasSubstr("options.spectrum_corner"));
  EXPECT_THAT(ErrorOfSolve([](auto& o) { o.lambda_rule = TikhonovLambdaRule::kDiscrepancy; }),
              HasSubstr("options.noise_sigma must be > 0 for the discrepancy rule"));
  EXPECT_THAT(ErrorOfSolve([](auto& o) { o.compute_std = true; }),
              HasSubstr("options.noise_sigma must be > 0 for compute_std"));
  EXPECT_THAT(ErrorOfSolve([](auto& o) { o.noise_sigma = -1; }), HasSubstr("options.noise_sigma"));
  EXPECT_THAT(ErrorOfSolve([](auto& o) {
                o.lambda_rule = TikhonovLambdaRule::kDiscrepancy;
                o.noise_sigma = 1;
                o.discrepancy_factor = 20;
              }),
              HasSubstr("options.discrepancy_factor"));
  EXPECT_THAT(ErrorOfSolve([](auto& o) {
                o.lambda_rule = TikhonovLambdaRule::kDiscrepancy;
                o.noise_sigma = 1;
                o.discrepancy_tolerance = 0;
              }),
              HasSubstr("options.discrepancy_tolerance"));
  EXPECT_THAT(ErrorOfSolve([](auto& o) { o.padding = -2; }), HasSubstr("options.padding"));
  EXPECT_THAT(ErrorOfSolve([](auto& o) { o.cg.max_iterations = 0; }), HasSubstr("options.cg.max_iterations"));
  EXPECT_THAT(ErrorOfSolve([](auto& o) { o.cg.tolerance = 2; }), HasSubstr("options.cg.tolerance"));
  EXPECT_THAT(ErrorOfSolve([](auto& o) {
                o.method = TikhonovMethod::kFourier;
                o.boundary = TikhonovBoundary::kZeroPadded;
              }),
              HasSubstr("method kFourier needs boundary kPeriodic"));
  EXPECT_THAT(ErrorOf([] { ParseTikhonovPrior("tv"); }), HasSubstr("power-spectrum"));
  EXPECT_EQ(ParseTikhonovPrior("power-spectrum"), TikhonovPrior::kPowerSpectrum);
}

TEST(TikhonovErrorsTest, GivenPowerSpectrumMustFitTheGridAndBeAPowerSpectrum) {
  auto with = [](Image s) {
    return [s](TikhonovOptions& o) {
      o.prior = TikhonovPrior::kPowerSpectrum;
      o.object_power_spectrum = s;
    };
  };
  EXPECT_THAT(ErrorOfSolve(with(Image::Ones(16, 12))), HasSubstr("options.object_power_spectrum shape"));
  Image neg = Image::Ones(16, 16);
  neg(3, 3) = 0;
  EXPECT_THAT(ErrorOfSolve(with(neg)), HasSubstr("object_power_spectrum must be finite and > 0"));
  Image asym = Image::Ones(16, 16);
  asym(1, 2) = 2;  // S(-f) at (15, 14) stays 1
  EXPECT_THAT(ErrorOfSolve(with(asym)), HasSubstr("must be symmetric"));
  EXPECT_THAT(ErrorOfSolve([](auto& o) {
                o.prior = TikhonovPrior::kPowerSpectrum;
                o.object_power_spectrum = Image::Ones(16, 16);
                o.boundary = TikhonovBoundary::kZeroPadded;
              }),
              HasSubstr("object_power_spectrum is tied to the model's grid"));
  TikhonovOptions o;
  o.prior = TikhonovPrior::kPowerSpectrum;
  o.object_power_spectrum = Image::Ones(16, 16);
  EXPECT_THAT(ErrorOf([&] { TikhonovPriorOperator({8, 8}, o); }),
              HasSubstr("TikhonovPriorSymbol: invalid options.object_power_spectrum shape"));
}

TEST(TikhonovErrorsTest, ProblemInputsNameTheArgument) {
  ReconstructionProblem p = Problem();
  p.model = nullptr;
  EXPECT_THAT(ErrorOfSolve([](auto&) {}, p), HasSubstr("ReconstructTikhonov: problem.model is null"));
  p = Problem();
  p.frames[1](2, 3) = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THAT(ErrorOfSolve([](auto&) {}, p), HasSubstr("problem.frames[1](2, 3)"));
  p.weights = ImageStack(2, Image::Ones(8, 8));
  p.weights[1](2, 3) = 0;  // masked: fine
  EXPECT_EQ(ErrorOfSolve([](auto&) {}, p), "no exception");
  p.weights[0](0, 0) = -1;
  EXPECT_THAT(ErrorOfSolve([](auto&) {}, p), HasSubstr("problem.weights[0]"));
  p.weights = ImageStack(2, Image::Zero(8, 8));
  EXPECT_THAT(ErrorOfSolve([](auto&) {}, p), HasSubstr("problem.weights = all zero"));
  p = Problem();
  p.frames.pop_back();
  EXPECT_THAT(ErrorOfSolve([](auto&) {}, p), HasSubstr("problem.frames.size()"));
}

TEST(TikhonovErrorsTest, PathsThatTheProblemDoesNotAllow) {
  ReconstructionProblem p = Problem();
  p.weights = ImageStack(2, Image::Ones(8, 8));
  p.weights[0](1, 1) = 0.5;
  EXPECT_THAT(ErrorOfSolve([](auto& o) { o.method = TikhonovMethod::kFourier; }, p),
              HasSubstr("options.method = kFourier"));
  EXPECT_THAT(ErrorOfSolve([](auto& o) { o.lambda_rule = TikhonovLambdaRule::kGcv; }, p),
              HasSubstr("options.lambda_rule = kGcv"));
  EXPECT_THAT(ErrorOfSolve([](auto& o) {
                o.lambda_rule = TikhonovLambdaRule::kGcv;
                o.boundary = TikhonovBoundary::kZeroPadded;
              }),
              HasSubstr("options.lambda_rule = kGcv"));
  const ReconstructionProblem q = Problem();
  TikhonovOptions o;
  o.method = TikhonovMethod::kConjugateGradient;
  EXPECT_THAT(ErrorOf([&] { TikhonovFourier(*q.model, q.frames, o); }),
              HasSubstr("TikhonovFourier: invalid options.method"));
  o.method = TikhonovMethod::kAuto;
  o.boundary = TikhonovBoundary::kZeroPadded;
  EXPECT_THAT(ErrorOf([&] { TikhonovFourier(*q.model, q.frames, o); }), HasSubstr("options.boundary"));
}

TEST(TikhonovErrorsTest, PaddedModelRejectsBadInputs) {
  const ImageStack k = {test::GaussianKernel(5, 1.0)};
  EXPECT_THAT(ErrorOf([&] { PaddedModel::FromKernels({16, 16}, 2, k, -1); }), HasSubstr("padding"));
  EXPECT_THAT(ErrorOf([&] { PaddedModel::FromKernels({15, 16}, 2, k, 1); }), HasSubstr("frame HR shape"));
  EXPECT_THAT(ErrorOf([&] { PaddedModel::FromKernels({16, 16}, 0, k, 1); }), HasSubstr("invalid r"));
  EXPECT_THAT(ErrorOf([&] { PaddedModel::FromKernels({16, 16}, 2, {}, 1); }), HasSubstr("centred_psfs"));
  EXPECT_THAT(ErrorOf([&] {
                PaddedModel::FromKernels({8, 8}, 2, {Image::Ones(31, 31)}, 1);
              }),
              HasSubstr("centred_psfs[0] shape"));
  const PaddedModel m = PaddedModel::FromKernels({16, 16}, 2, k, 2);
  EXPECT_THAT(ErrorOf([&] { m.EmbedFrames({Image::Ones(8, 7)}); }), HasSubstr("frame 0 shape"));
  EXPECT_THAT(ErrorOf([&] { m.EmbedFrames({}); }), HasSubstr("frame count"));
  EXPECT_THAT(ErrorOf([&] { m.CropObject(Image::Ones(16, 16)); }), HasSubstr("object shape"));
  EXPECT_THAT(ErrorOf([&] { m.Render(Image::Ones(16, 16)); }), HasSubstr("PaddedModel::Render"));
  EXPECT_THAT(ErrorOf([&] { PaddedModel::SuggestPadding(m.periodic(), 0.0); }), HasSubstr("tail_fraction"));
}

TEST(TikhonovErrorsTest, PreconditionedCgRejectsBadInputs) {
  const OperatorPtr a = Identity(4), wrong = Identity(5);
  Vector x = Vector::Zero(4);
  EXPECT_THAT(ErrorOf([&] { PreconditionedConjugateGradient(*a, *wrong, Vector::Ones(4), &x); }),
              HasSubstr("PreconditionedConjugateGradient: invalid preconditioner"));
  ConjugateGradientOptions o;
  o.max_iterations = 0;
  EXPECT_THAT(ErrorOf([&] { PreconditionedConjugateGradient(*a, *a, Vector::Ones(4), &x, o); }),
              HasSubstr("options.max_iterations must be >= 1"));
  EXPECT_THAT(ErrorOf([&] { ConjugateGradient(*a, Vector::Ones(3), &x); }), HasSubstr("b size"));
  Vector bad = Vector::Ones(4);
  bad[2] = std::numeric_limits<double>::infinity();
  EXPECT_THAT(ErrorOf([&] { PreconditionedConjugateGradient(*a, *a, bad, &x); }), HasSubstr("b or x"));
}

TEST(TikhonovErrorsTest, LambdaRulesAndTheFittedPriorNameTheBadField) {
  EXPECT_THAT(ErrorOfSolve([](auto& o) { o.lambda_rule = TikhonovLambdaRule::kUpre; }),
              HasSubstr("options.noise_sigma must be > 0 for the upre rule"));
  EXPECT_THAT(ErrorOfSolve([](auto& o) { o.lambda_rule = TikhonovLambdaRule::kWiener; }),
              HasSubstr("options.lambda_rule kWiener needs prior kFitted"));
  EXPECT_THAT(ErrorOfSolve([](auto& o) {
                o.lambda_rule = TikhonovLambdaRule::kLcurve;
                o.gcv_steps_per_decade = 0;
              }),
              HasSubstr("options.gcv_decades must be in (0, 20] and gcv_steps_per_decade"));
  EXPECT_THAT(ErrorOfSolve([](auto& o) {
                o.prior = TikhonovPrior::kFitted;
                o.object_power_spectrum = Image::Ones(16, 16);
              }),
              HasSubstr("options.object_power_spectrum must be empty for prior kFitted"));
  EXPECT_THAT(ErrorOfSolve([](auto& o) {
                o.prior = TikhonovPrior::kFitted;
                o.spectrum_fit.min_radius = 40;
              }),
              HasSubstr("options.spectrum_fit.min_radius"));
  EXPECT_THAT(ErrorOfSolve([](auto& o) {
                o.prior = TikhonovPrior::kFitted;
                o.spectrum_fit.max_iterations = 0;
              }),
              HasSubstr("options.spectrum_fit.max_iterations"));
  // The searching rules need the Fourier-exact problem; the Wiener rule does not.
  ReconstructionProblem weighted = Problem();
  weighted.weights = ImageStack(2, Image::Ones(8, 8));
  weighted.weights[0](0, 0) = 0.5;
  EXPECT_THAT(ErrorOfSolve([](auto& o) { o.lambda_rule = TikhonovLambdaRule::kLcurve; }, weighted),
              HasSubstr("invalid options.lambda_rule = kLcurve"));
  EXPECT_THAT(ErrorOfSolve(
                  [](auto& o) {
                    o.lambda_rule = TikhonovLambdaRule::kUpre;
                    o.noise_sigma = 1;
                  },
                  weighted),
              HasSubstr("kUpre"));
  EXPECT_THAT(ErrorOf([] { ParseTikhonovLambdaRule("morozov"); }),
              HasSubstr("fixed, gcv, discrepancy, lcurve, upre or wiener"));
  EXPECT_EQ(ParseTikhonovLambdaRule("upre"), TikhonovLambdaRule::kUpre);
  EXPECT_EQ(ParseTikhonovLambdaRule("lcurve"), TikhonovLambdaRule::kLcurve);
  EXPECT_EQ(ParseTikhonovPrior("fitted"), TikhonovPrior::kFitted);
}

}  // namespace
}  // namespace aosr
