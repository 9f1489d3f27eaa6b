// Bad input to the MAP reconstructor is rejected with a message naming the argument, before Ceres is
// called (Ceres aborts or silently fails on invalid options).
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <functional>
#include <limits>

#include "aosr/core/error.hpp"
#include "aosr/solvers/map.hpp"
#include "solvers/map_fixtures.hpp"
#include "support/testing.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

using aosr::test::ErrorOf;
using ::testing::HasSubstr;

ReconstructionProblem SmallProblem() {
  const auto model = map_test::Raster4({16, 16});
  return map_test::MakeProblem(model, model->Render(Image::Ones(16, 16)));
}

TEST(MapErrorsTest, InvalidOptionsAreRejectedNamingTheField) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const ReconstructionProblem problem = SmallProblem();
  struct Bad {
    std::function<void(MapOptions&)> set;
    const char* field;
  };
  const Bad bad[] = {
      {[](MapOptions& o) { o.lambda = -1; }, "lambda"},
      {[&](MapOptions& o) { o.lambda = nan; }, "lambda"},
      {[](MapOptions& o) { o.epsilon = 0; }, "epsilon"},
      {[](MapOptions& o) { o.prior = MapPrior::kHuberTv, o.delta = -1; }, "delta"},
      {[](MapOptions& o) { o.read_noise = -1; }, "read_noise"},
      {[](MapOptions& o) { o.background = -0.5; }, "background"},
      {[](MapOptions& o) { o.likelihood = MapLikelihood::kPoisson; }, "background + read_noise^2"},
      {[](MapOptions& o) { o.softplus_scale = -1; }, "softplus_scale"},
      {[](MapOptions& o) { o.max_iterations = 0; }, "max_iterations"},
      {[](MapOptions& o) { o.function_tolerance = -1e-3; }, "function_tolerance"},
      {[](MapOptions& o) { o.gradient_tolerance = 1; }, "gradient_tolerance"},
      {[&](MapOptions& o) { o.parameter_tolerance = nan; }, "parameter_tolerance"},
      {[](MapOptions& o) { o.lbfgs_memory = 0; }, "lbfgs_memory"},
      {[](MapOptions& o) { o.prior = static_cast<MapPrior>(7); }, "prior"},
      {[](MapOptions& o) { o.likelihood = static_cast<MapLikelihood>(7); }, "likelihood"},
      {[](MapOptions& o) { o.positivity = static_cast<MapPositivity>(7); }, "positivity"},
      {[](MapOptions& o) { o.preconditioner = static_cast<MapPreconditioner>(7); }, "preconditioner"},
      {[](MapOptions& o) {
         o.prior = MapPrior::kTikhonov, o.tikhonov_operator = static_cast<TikhonovPrior>(9);
       },
       "tikhonov_operator"},
  };
  for (const Bad& b : bad) {
    MapOptions o;
    b.set(o);
    std::string why;
    EXPECT_FALSE(o.IsValid(&why)) << b.field;
    EXPECT_THAT(why, HasSubstr(b.field));
    EXPECT_THAT(ErrorOf([&] { MapReconstruct(problem, o); }), HasSubstr(std::string("options.") + b.field));
    EXPECT_THAT(ErrorOf([&] { MapObjective f(problem, o); }), HasSubstr(b.field));
  }
  // Fields a prior does not use are not checked.
  MapOptions o;
  o.prior = MapPrior::kTikhonov;
  o.epsilon = 0;
  o.delta = 0;
  EXPECT_TRUE(o.IsValid(nullptr));
}

TEST(MapErrorsTest, BadProblemsAndWarmStartsAreRejected) {
  ReconstructionProblem problem = SmallProblem();
  EXPECT_THAT(ErrorOf([&] { MapReconstruct(problem, {}, Image::Ones(16, 12)); }),
              HasSubstr("warm_start shape"));
  Image nan_start = Image::Ones(16, 16);
  nan_start(2, 2) = std::numeric_limits<double>::infinity();
  EXPECT_THAT(ErrorOf([&] { MapReconstruct(problem, {}, nan_start); }), HasSubstr("warm_start"));

  ReconstructionProblem unmasked_nan = problem;
  unmasked_nan.frames[3](1, 2) = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THAT(ErrorOf([&] { MapReconstruct(unmasked_nan, {}); }), HasSubstr("problem.frames[3](1, 2)"));

  ReconstructionProblem no_model = problem;
  no_model.model = nullptr;
  EXPECT_THAT(ErrorOf([&] { MapReconstruct(no_model, {}); }), HasSubstr("problem.model"));

  ReconstructionProblem bad_weights = problem;
  bad_weights.weights = ImageStack(4, Image::Ones(8, 8));
  bad_weights.weights[1](0, 0) = -1;
  EXPECT_THAT(ErrorOf([&] { MapReconstruct(bad_weights, {}); }), HasSubstr("problem.weights[1]"));

  // Poisson without positivity from a warm start whose mean A x + b + σ² is not positive.
  MapOptions poisson;
  poisson.likelihood = MapLikelihood::kPoisson;
  poisson.read_noise = 1.0;
  poisson.positivity = MapPositivity::kNone;
  EXPECT_THAT(ErrorOf([&] { MapReconstruct(problem, poisson, Image::Constant(16, 16, -1.0)); }),
              HasSubstr("warm_start"));
}

TEST(MapErrorsTest, ObjectiveRejectsWrongSizes) {
  const MapObjective f(SmallProblem(), MapOptions{});
  EXPECT_THAT(ErrorOf([&] { f.Evaluate(Vector::Zero(3)); }), HasSubstr("z size"));
  EXPECT_THAT(ErrorOf([&] { f.ToImage(Vector::Zero(3)); }), HasSubstr("z size"));
  EXPECT_THAT(ErrorOf([&] { f.ToParameters(Image::Ones(2, 2)); }), HasSubstr("x shape"));
  EXPECT_THAT(ErrorOf([&] { f.FrameResidualRms(Image::Ones(2, 2)); }), HasSubstr("x shape"));
}

TEST(MapErrorsTest, UnknownNamesAreRejected) {
  EXPECT_THAT(ErrorOf([] { ParseMapLikelihood("laplace"); }), HasSubstr("gaussian or poisson"));
  EXPECT_THAT(ErrorOf([] { ParseMapPrior("tv"); }), HasSubstr("tikhonov, charbonnier-tv or huber-tv"));
  EXPECT_THAT(ErrorOf([] { ParseMapPositivity("exp"); }), HasSubstr("none or softplus"));
}

}  // namespace
}  // namespace aosr
