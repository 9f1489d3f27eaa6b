// Bad input to objective B (design_empirical.hpp) gets a clear InvalidArgument (or IoError) naming what is wrong.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "aosr/design/design_empirical.hpp"
#include "design/design_fixture.hpp"
#include "support/testing.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

using ::testing::HasSubstr;
using test::ErrorOf;

EmpiricalDesignOptions Valid(const DesignOptics& optics) {
  EmpiricalDesignOptions o;
  o.training_scenes = DefaultTrainingScenes({optics.grid, optics.grid}, 1);
  return o;
}

TEST(EmpiricalDesignErrorsTest, ObjectiveRejectsBadOptions) {
  const DesignOptics optics = design_test::SmallOptics(false);
  auto error = [&](const std::function<void(EmpiricalDesignOptions&)>& change) {
    EmpiricalDesignOptions o = Valid(optics);
    change(o);
    return ErrorOf([&] { EmpiricalDesignObjective(optics, 2, o); });
  };
  EXPECT_THAT(error([](auto& o) { o.training_scenes.clear(); }), HasSubstr("training_scenes count = 0"));
  EXPECT_THAT(error([](auto& o) { o.training_scenes[0] = Image::Zero(8, 8); }),
              HasSubstr("options.training_scenes[0] shape"));
  EXPECT_THAT(error([](auto& o) { o.training_scenes[0](1, 1) = std::nan(""); }), HasSubstr("not finite"));
  EXPECT_THAT(error([](auto& o) { o.noise_sigma = 0; }), HasSubstr("noise_sigma"));
  EXPECT_THAT(error([](auto& o) { o.map.likelihood = MapLikelihood::kPoisson; o.map.read_noise = 1; }),
              HasSubstr("map.likelihood = poisson; allowed: gaussian"));
  EXPECT_THAT(error([](auto& o) { o.map.prior = MapPrior::kHuberTv; }), HasSubstr("map.prior = huber-tv"));
  EXPECT_THAT(error([](auto& o) { o.map.positivity = MapPositivity::kSoftplus; }), HasSubstr("map.positivity"));
  EXPECT_THAT(error([](auto& o) { o.map.background = 1; }), HasSubstr("map.background"));
  EXPECT_THAT(error([](auto& o) { o.map.epsilon = 0; }), HasSubstr("map.epsilon"));
  EXPECT_THAT(error([](auto& o) { o.loss_epsilon = -1; }), HasSubstr("loss_epsilon"));
  EXPECT_THAT(error([](auto& o) { o.realisations = 65; }), HasSubstr("realisations"));
  EXPECT_THAT(error([](auto& o) { o.map_tolerance = 0.1; }), HasSubstr("map_tolerance"));
  EXPECT_THAT(error([](auto& o) { o.newton_iterations = 0; }), HasSubstr("newton_iterations"));
  EXPECT_THAT(error([](auto& o) { o.adjoint.tolerance = 0; }), HasSubstr("adjoint."));
  EXPECT_THAT(ErrorOf([&] { EmpiricalDesignObjective(optics, 0, Valid(optics)); }), HasSubstr("frames"));
  DesignOptics bad = optics;
  bad.grid = 15;
  EXPECT_THAT(ErrorOf([&] { EmpiricalDesignObjective(bad, 2, Valid(optics)); }), HasSubstr("optics.grid"));
}

TEST(EmpiricalDesignErrorsTest, EvaluateRejectsBadOpds) {
  const DesignOptics optics = design_test::SmallOptics(false);
  const EmpiricalDesignObjective f(optics, 2, Valid(optics));
  EXPECT_THAT(ErrorOf([&] { f.Evaluate({Image::Zero(32, 32)}); }), HasSubstr("dm_opds count"));
  EXPECT_THAT(ErrorOf([&] { f.Evaluate({Image::Zero(32, 32), Image::Zero(16, 16)}); }), HasSubstr("shape"));
  Image nan = Image::Zero(32, 32);
  nan(16, 16) = std::nan("");
  EXPECT_THAT(ErrorOf([&] { f.EvaluateWithReport({Image::Zero(32, 32), nan}); }), HasSubstr("finite"));
}

TEST(EmpiricalDesignErrorsTest, HelpersRejectBadInput) {
  EXPECT_THAT(ErrorOf([] { ParseDesignLoss("l3"); }), HasSubstr("l1 or l2"));
  EXPECT_THAT(ErrorOf([] { DefaultTrainingScenes({16, 16}, 0); }), HasSubstr("count"));
  EXPECT_THAT(ErrorOf([] { TrainingScenesFromFiles({}, {16, 16}); }), HasSubstr("paths count"));
  EXPECT_THAT(ErrorOf([] { TrainingScenesFromFiles({"x.png"}, {16, 16}, 0.0); }), HasSubstr("zoom"));
  EXPECT_THAT(ErrorOf<IoError>([] { TrainingScenesFromFiles({"/nonexistent/scene.png"}, {16, 16}); }),
              HasSubstr("/nonexistent/scene.png"));
}

}  // namespace
}  // namespace aosr
