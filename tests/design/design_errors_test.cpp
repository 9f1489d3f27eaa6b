// Bad input to the phase-design entry points gets a clear InvalidArgument naming what is wrong.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "aosr/core/memory.hpp"
#include "aosr/design/design_file.hpp"
#include "aosr/design/design_objective.hpp"
#include "aosr/design/design_optimizer.hpp"
#include "aosr/design/design_parameterisation.hpp"
#include "design/design_fixture.hpp"
#include "support/testing.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

using ::testing::AllOf;
using ::testing::HasSubstr;
using test::ErrorOf;

TEST(DesignErrorsTest, ParameterisationRejectsBadOptionsAndInfeasibleRasters) {
  const DesignOptics optics = design_test::SmallOptics(false);
  DesignPupil pupil = design_test::SmallPupil(optics);
  DesignParameterisationOptions o;
  o.zernike_modes = 1;
  EXPECT_THAT(ErrorOf([&] { DesignParameterisation(pupil, 3, 2, o); }), HasSubstr("zernike_modes"));
  o = DesignParameterisationOptions();
  o.rms_max_m = 1e-9;  // far below the raster's tilt
  EXPECT_THAT(ErrorOf([&] { DesignParameterisation(pupil, 3, 2, o); }), HasSubstr("rms_max_m"));
  o = DesignParameterisationOptions();
  o.strehl_min = 1.0;
  EXPECT_THAT(ErrorOf([&] { DesignParameterisation(pupil, 3, 2, o); }), HasSubstr("strehl_min"));
  o = DesignParameterisationOptions();
  o.kind = DesignParameterisationKind::kActuators;
  pupil.dm = nullptr;
  EXPECT_THAT(ErrorOf([&] { DesignParameterisation(pupil, 3, 2, o); }), HasSubstr("pupil.dm"));
  EXPECT_THAT(ErrorOf([&] { ParseDesignParameterisation("modal"); }), HasSubstr("raster, tiptilt, zernike or actuators"));
  const DesignParameterisation p(design_test::SmallPupil(optics), 3, 2, DesignParameterisationOptions());
  EXPECT_THAT(ErrorOf([&] { p.Opds(Vector::Zero(3)); }), HasSubstr("theta size"));
}

TEST(DesignErrorsTest, ObjectiveRejectsBadOpticsOptionsAndOpds) {
  DesignOptics optics = design_test::SmallOptics(false);
  DesignObjectiveOptions o;
  o.reconstructor.lambda = 0;
  EXPECT_THAT(ErrorOf([&] { DesignObjective(optics, 2, o); }), HasSubstr("lambda"));
  o = DesignObjectiveOptions();
  o.reconstructor.lambda_rule = TikhonovLambdaRule::kGcv;
  EXPECT_THAT(ErrorOf([&] { DesignObjective(optics, 2, o); }), HasSubstr("lambda_rule"));
  o = DesignObjectiveOptions();
  o.realisations = -1;
  EXPECT_THAT(ErrorOf([&] { DesignObjective(optics, 2, o); }), HasSubstr("realisations"));
  optics.grid = 15;
  EXPECT_THAT(ErrorOf([&] { DesignObjective(optics, 2, DesignObjectiveOptions()); }), HasSubstr("optics.grid"));
  optics = design_test::SmallOptics(false);
  optics.hr_pixel_rad *= 3;  // coarser than λ/D
  EXPECT_THAT(ErrorOf([&] { DesignObjective(optics, 2, DesignObjectiveOptions()); }), HasSubstr("hr_pixel_rad"));
  // Each count within its range, together 64 x 1024 x 256 residual screens: refused before any is drawn.
  o = DesignObjectiveOptions();
  o.realisations = 64;
  o.screens = 256;
  SetMemoryLimitBytes(1024.0 * 1024 * 1024);  // the screens alone are 128 GiB: refused on any machine
  const std::string memory = ErrorOf<ResourceError>([&] { DesignObjective(design_test::SmallOptics(true), 1024, o); });
  SetMemoryLimitBytes(0);
  EXPECT_THAT(memory, HasSubstr("a design of 1024 frames on the 16^2 grid with 64 realisations x 256 screens of 32^2"));
  EXPECT_THAT(memory, HasSubstr("of memory (estimate), more than the limit"));
  const DesignObjective f(design_test::SmallOptics(false), 2, DesignObjectiveOptions());
  EXPECT_THAT(ErrorOf([&] { f.Evaluate({Image::Zero(32, 32)}); }), HasSubstr("dm_opds count"));
  EXPECT_THAT(ErrorOf([&] { f.Evaluate({Image::Zero(32, 32), Image::Zero(16, 16)}); }), HasSubstr("shape"));
  Image nan = Image::Zero(32, 32);
  nan(16, 16) = std::nan("");
  EXPECT_THAT(ErrorOf([&] { f.Evaluate({Image::Zero(32, 32), nan}); }), HasSubstr("finite"));
}

// The modal content's fit: an OPD off the pupil's grid, a non-finite OPD and a report without the 36
// coefficients are refused, naming what is wrong.
TEST(DesignErrorsTest, ModalContentRejectsMismatchedOpdsAndReports) {
  DesignPupil pupil;
  pupil.amplitude = Image::Constant(32, 32, 1.0);
  EXPECT_THAT(ErrorOf([&] { ModalContentJson(pupil, {Image::Zero(32, 32), Image::Zero(16, 16)}); }),
              AllOf(HasSubstr("opds[1] shape"), HasSubstr("16x16"), HasSubstr("the pupil grid 32x32")));
  Image nan = Image::Zero(32, 32);
  nan(3, 4) = std::nan("");
  EXPECT_THAT(ErrorOf([&] { ModalContentJson(pupil, {nan}); }), HasSubstr("finite"));
  DesignFrameReport r;
  r.zernike_m = Vector::Zero(3);
  EXPECT_THAT(ErrorOf([&] { ModalContentJson(std::vector<DesignFrameReport>{r}); }),
              AllOf(HasSubstr("zernike_m size"), HasSubstr("36")));
  EXPECT_EQ(ModalContentJson(pupil, {Image::Zero(32, 32)})["frames"].size(), 1u);
}

TEST(DesignErrorsTest, OptimizerRejectsBadOptionsAndMismatchedParts) {
  const DesignOptics optics = design_test::SmallOptics(false);
  const DesignObjective f(optics, 2, DesignObjectiveOptions());
  const DesignParameterisation p3(design_test::SmallPupil(optics), 3, 2, DesignParameterisationOptions());
  EXPECT_THAT(ErrorOf([&] { OptimizeDesign(f, p3, DesignOptimizerOptions()); }), HasSubstr("frames"));
  const DesignParameterisation p2(design_test::SmallPupil(optics), 2, 2, DesignParameterisationOptions());
  DesignOptimizerOptions o;
  o.starts = 0;
  EXPECT_THAT(ErrorOf([&] { OptimizeDesign(f, p2, o); }), HasSubstr("starts"));
  o = DesignOptimizerOptions();
  o.function_tolerance = 0;
  EXPECT_THAT(ErrorOf([&] { OptimizeDesign(f, p2, o); }), HasSubstr("function_tolerance"));
}

}  // namespace
}  // namespace aosr
