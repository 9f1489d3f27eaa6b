#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <limits>
#include <memory>

#include "aosr/core/error.hpp"
#include "aosr/solvers/total_variation.hpp"
#include "support/testing.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

using aosr::test::ErrorOf;
using ::testing::HasSubstr;

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kInf = std::numeric_limits<double>::infinity();

ReconstructionProblem Problem() {
  Image k = Image::Zero(3, 3);
  k(1, 1) = 1;
  ReconstructionProblem p;
  p.model = std::make_shared<const MultiFrameModel>(MultiFrameModel::FromKernels({8, 8}, 2, {k, k}));
  p.frames = ImageStack(2, Image::Ones(4, 4));
  return p;
}

// Each invalid field is named, both by IsValid and by the entry point.
TEST(TotalVariationErrorsTest, BadOptionsNameTheField) {
  struct Case {
    const char* field;
    void (*set)(TotalVariationOptions*);
  };
  const Case cases[] = {
      {"mu", [](TotalVariationOptions* o) { o->mu = -1; }},
      {"mu", [](TotalVariationOptions* o) { o->mu = kNaN; }},
      {"rho", [](TotalVariationOptions* o) { o->rho = -0.5; }},
      {"rho", [](TotalVariationOptions* o) { o->rho = kInf; }},
      {"rho_balance", [](TotalVariationOptions* o) { o->rho_balance = 1.0; }},
      {"rho_factor", [](TotalVariationOptions* o) { o->rho_factor = 0.5; }},
      {"max_rho_updates", [](TotalVariationOptions* o) { o->max_rho_updates = -1; }},
      {"relaxation", [](TotalVariationOptions* o) { o->relaxation = 2.0; }},
      {"relaxation", [](TotalVariationOptions* o) { o->relaxation = 0.5; }},
      {"absolute_tolerance", [](TotalVariationOptions* o) { o->absolute_tolerance = -1e-9; }},
      {"relative_tolerance", [](TotalVariationOptions* o) { o->relative_tolerance = 0; }},
      {"relative_tolerance", [](TotalVariationOptions* o) { o->relative_tolerance = 1; }},
      {"change_tolerance", [](TotalVariationOptions* o) { o->change_tolerance = -0.1; }},
      {"max_iterations", [](TotalVariationOptions* o) { o->max_iterations = 0; }},
      {"cg_tolerance", [](TotalVariationOptions* o) { o->cg_tolerance = 0; }},
      {"cg_max_iterations", [](TotalVariationOptions* o) { o->cg_max_iterations = 0; }},
  };
  const ReconstructionProblem p = Problem();
  for (const Case& c : cases) {
    TotalVariationOptions o;
    c.set(&o);
    std::string why;
    EXPECT_FALSE(o.IsValid(&why)) << c.field;
    EXPECT_THAT(why, HasSubstr(c.field));
    EXPECT_THAT(ErrorOf([&] { TotalVariationAdmm(p, o); }),
                AllOf(HasSubstr("TotalVariationAdmm"), HasSubstr(c.field)));
  }
  std::string why;
  EXPECT_TRUE(TotalVariationOptions{}.IsValid(&why)) << why;
}

TEST(TotalVariationErrorsTest, BadProblemIsRejectedBeforeAnyWork) {
  ReconstructionProblem p = Problem();
  p.model = nullptr;
  EXPECT_THAT(ErrorOf([&] { TotalVariationAdmm(p); }), HasSubstr("problem.model"));
  p = Problem();
  p.frames[1](2, 3) = kNaN;  // weighted (no weights: all 1), so an error
  EXPECT_THAT(ErrorOf([&] { TotalVariationAdmm(p); }), HasSubstr("problem.frames[1](2, 3)"));
  p = Problem();
  p.frames.pop_back();
  EXPECT_THAT(ErrorOf([&] { TotalVariationAdmm(p); }), HasSubstr("problem.frames.size()"));
}

TEST(TotalVariationErrorsTest, BadInitialImageIsNamed) {
  const ReconstructionProblem p = Problem();
  const Image wrong = Image::Zero(4, 4);
  EXPECT_THAT(ErrorOf([&] { TotalVariationAdmm(p, {}, nullptr, &wrong); }), HasSubstr("initial shape"));
  Image nan = Image::Zero(8, 8);
  nan(3, 3) = kNaN;
  EXPECT_THAT(ErrorOf([&] { TotalVariationAdmm(p, {}, nullptr, &nan); }), HasSubstr("initial"));
}

// A state from another grid or positivity setting, or with non-finite values, is refused by name; an empty
// state is simply filled.
TEST(TotalVariationErrorsTest, StateThatDoesNotFitIsRefused) {
  const ReconstructionProblem p = Problem();
  TotalVariationOptions o;
  o.max_iterations = 3;
  TotalVariationState state;
  TotalVariationAdmm(p, o, nullptr, nullptr, &state);
  ASSERT_FALSE(state.empty());
  TotalVariationState wrong = state;
  wrong.x = Image::Zero(4, 4);
  EXPECT_THAT(ErrorOf([&] { TotalVariationAdmm(p, o, nullptr, nullptr, &wrong); }), HasSubstr("state"));
  o.positivity = true;  // the state has no positivity split
  wrong = state;
  EXPECT_THAT(ErrorOf([&] { TotalVariationAdmm(p, o, nullptr, nullptr, &wrong); }), HasSubstr("positivity"));
  o.positivity = false;
  wrong = state;
  wrong.u[5] = kNaN;
  EXPECT_THAT(ErrorOf([&] { TotalVariationAdmm(p, o, nullptr, nullptr, &wrong); }), HasSubstr("non-finite"));
  wrong = state;
  wrong.rho = std::numeric_limits<double>::infinity();
  EXPECT_THAT(ErrorOf([&] { TotalVariationAdmm(p, o, nullptr, nullptr, &wrong); }), HasSubstr("state"));
}

TEST(TotalVariationErrorsTest, FourierXUpdateNeedsUniformWeights) {
  ReconstructionProblem p = Problem();
  p.weights = ImageStack(2, Image::Ones(4, 4));
  p.weights[0](1, 1) = 0;
  TotalVariationOptions o;
  o.x_update = TotalVariationXUpdate::kFourier;
  EXPECT_THAT(ErrorOf([&] { TotalVariationAdmm(p, o); }), AllOf(HasSubstr("x_update"), HasSubstr("uniform")));
}

TEST(TotalVariationErrorsTest, FourierNormalSystemChecksItsArguments) {
  const ReconstructionProblem p = Problem();
  EXPECT_THAT(ErrorOf([&] { FourierNormalSystem(*p.model, 0.0); }), HasSubstr("data_weight"));
  EXPECT_THAT(ErrorOf([&] { FourierNormalSystem(*p.model, kNaN); }), HasSubstr("data_weight"));
  FourierNormalSystem system(*p.model, 1.0);
  EXPECT_THAT(ErrorOf([&] { system.Solve(Image::Zero(8, 8)); }), HasSubstr("Factorize"));
  EXPECT_THAT(ErrorOf([&] { system.Factorize(-1, 0); }), HasSubstr("gradient_weight"));
  EXPECT_THAT(ErrorOf([&] { system.Factorize(1, kInf); }), HasSubstr("identity_weight"));
  system.Factorize(1, 0);
  EXPECT_THAT(ErrorOf([&] { system.Solve(Image::Zero(8, 6)); }), HasSubstr("rhs shape"));
  Image nan = Image::Zero(8, 8);
  nan(0, 0) = kNaN;
  EXPECT_THAT(ErrorOf([&] { system.Solve(nan); }), HasSubstr("rhs"));
  Image x;
  const ImageStack v(p.frames.size(), Image::Zero(p.model->lr_shape().rows, p.model->lr_shape().cols));
  EXPECT_THAT(ErrorOf([&] { system.SolveWithData(Image::Zero(8, 8), ImageStack(1, v[0]), &x, nullptr); }),
              HasSubstr("v frames"));
  ImageStack bad = v;
  bad[0](0, 0) = kNaN;
  EXPECT_THAT(ErrorOf([&] { system.SolveWithData(Image::Zero(8, 8), bad, &x, nullptr); }), HasSubstr("v"));
  EXPECT_THAT(ErrorOf([&] { system.SolveWithData(Image::Zero(8, 8), v, nullptr, nullptr); }), HasSubstr("x"));
}

TEST(TotalVariationErrorsTest, ObjectiveChecksItsArguments) {
  const ReconstructionProblem p = Problem();
  EXPECT_THAT(ErrorOf([&] { TotalVariationObjective(p, Image::Zero(8, 8), -1); }), HasSubstr("mu"));
  EXPECT_THAT(ErrorOf([&] { TotalVariationObjective(p, Image::Zero(4, 4), 1); }), HasSubstr("x shape"));
  EXPECT_THAT(ErrorOf([&] { IsotropicTotalVariation(Image()); }), HasSubstr("x shape"));
}

}  // namespace
}  // namespace aosr
