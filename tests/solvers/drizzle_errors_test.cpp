#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <limits>
#include <memory>

#include "aosr/solvers/drizzle.hpp"
#include "support/testing.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

using aosr::test::ErrorOf;
using ::testing::HasSubstr;

ReconstructionProblem Good() {
  ReconstructionProblem p;
  p.model = std::make_shared<const MultiFrameModel>(
      MultiFrameModel::FromKernels({8, 8}, 2, ImageStack(2, Image::Ones(1, 1))));
  p.frames = ImageStack(2, Image::Ones(4, 4));
  p.offsets = {{0.0, 0.0}, {0.5, 0.5}};
  return p;
}

TEST(DrizzleErrorsTest, TheGoodProblemRuns) {
  EXPECT_EQ(Drizzle(Good()).summary.termination, Termination::kConverged);
}

TEST(DrizzleErrorsTest, RejectsBadPixfrac) {
  for (double bad : {0.0, -0.5, 1.5, std::numeric_limits<double>::quiet_NaN()}) {
    DrizzleOptions o;
    o.pixfrac = bad;
    std::string why;
    EXPECT_FALSE(o.IsValid(&why));
    EXPECT_THAT(why, HasSubstr("pixfrac"));
    EXPECT_THAT(ErrorOf([&] { Drizzle(Good(), o); }), HasSubstr("pixfrac")) << bad;
  }
}

TEST(DrizzleErrorsTest, RejectsUnknownKernels) {
  EXPECT_THAT(ErrorOf([] { ParseDrizzleKernel("tophat"); }),
              HasSubstr("invalid kernel = \"tophat\"; allowed: square, turbo, point, gaussian or lanczos3"));
  EXPECT_THAT(ErrorOf([] { ParseDrizzleKernel("Square"); }), HasSubstr("ParseDrizzleKernel"));
  DrizzleOptions o;
  o.kernel = static_cast<DrizzleKernel>(42);
  EXPECT_THAT(ErrorOf([&] { Drizzle(Good(), o); }), HasSubstr("kernel must be square, turbo"));
}

TEST(DrizzleErrorsTest, RejectsInfiniteFillValueButAllowsNaN) {
  DrizzleOptions o;
  o.fill_value = std::numeric_limits<double>::infinity();
  EXPECT_THAT(ErrorOf([&] { Drizzle(Good(), o); }), HasSubstr("fill_value"));
  o.fill_value = std::numeric_limits<double>::quiet_NaN();
  EXPECT_TRUE(o.IsValid(nullptr));
}

TEST(DrizzleErrorsTest, RejectsMismatchedShapes) {
  ReconstructionProblem p = Good();
  p.frames[1] = Image::Ones(4, 5);
  EXPECT_THAT(ErrorOf([&] { Drizzle(p); }), HasSubstr("problem.frames[1] shape"));
  p = Good();
  p.weights = {Image::Ones(4, 4), Image::Ones(3, 4)};
  EXPECT_THAT(ErrorOf([&] { Drizzle(p); }), HasSubstr("problem.weights[1] shape"));
  p = Good();
  p.frames.push_back(Image::Ones(4, 4));
  EXPECT_THAT(ErrorOf([&] { Drizzle(p); }), HasSubstr("frame count"));
}

TEST(DrizzleErrorsTest, RejectsNegativeOrNonFiniteWeights) {
  ReconstructionProblem p = Good();
  p.weights = {Image::Ones(4, 4), Image::Ones(4, 4)};
  p.weights[0](1, 2) = -1.0;
  EXPECT_THAT(ErrorOf([&] { Drizzle(p); }), HasSubstr("problem.weights[0]"));
  p.weights[0](1, 2) = std::numeric_limits<double>::infinity();
  EXPECT_THAT(ErrorOf([&] { Drizzle(p); }), HasSubstr(">= 0"));
}

TEST(DrizzleErrorsTest, RejectsUnmaskedNaNPixels) {
  ReconstructionProblem p = Good();
  p.frames[1](2, 3) = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THAT(ErrorOf([&] { Drizzle(p); }), HasSubstr("problem.frames[1](2, 3)"));
  p.weights = {Image::Ones(4, 4), Image::Ones(4, 4)};
  p.weights[1](2, 3) = 0.0;  // masked: allowed
  EXPECT_EQ(ErrorOf([&] { Drizzle(p); }), "no exception");
}

TEST(DrizzleErrorsTest, RequiresOneFiniteOffsetPerFrame) {
  ReconstructionProblem p = Good();
  p.offsets.clear();
  EXPECT_THAT(ErrorOf([&] { Drizzle(p); }),
              HasSubstr("problem.offsets.size() = 0; allowed: one offset per frame (2)"));
  p.offsets = {{0.0, 0.0}, {std::numeric_limits<double>::quiet_NaN(), 0.0}};
  EXPECT_THAT(ErrorOf([&] { Drizzle(p); }), HasSubstr("problem.offsets[1]"));
  p.offsets = {{0.0, std::numeric_limits<double>::infinity()}, {0.0, 0.0}};
  EXPECT_THAT(ErrorOf([&] { Drizzle(p); }), HasSubstr("problem.offsets[0]"));
}

TEST(DrizzleErrorsTest, RejectsAMissingModel) {
  ReconstructionProblem p = Good();
  p.model.reset();
  EXPECT_THAT(ErrorOf([&] { Drizzle(p); }), HasSubstr("Drizzle: problem.model is null"));
}

TEST(DrizzleErrorsTest, ContributedNamesItsArgument) {
  DrizzleOptions o;
  const DrizzleResult d = Drizzle(Good(), o);
  EXPECT_THAT(ErrorOf([&] { d.Contributed(2, 0, 0); }), HasSubstr("invalid frame = 2"));
  EXPECT_THAT(ErrorOf([&] { d.Contributed(0, 8, 0); }), HasSubstr("invalid pixel = (8, 0)"));
  o.compute_context = false;
  const DrizzleResult n = Drizzle(Good(), o);
  EXPECT_THAT(ErrorOf([&] { n.Contributed(0, 0, 0); }), HasSubstr("compute_context"));
}

}  // namespace
}  // namespace aosr
