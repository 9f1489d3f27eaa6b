// Errors and the sky subtraction of scene/evaluation.hpp's public helpers.
#include "aosr/scene/evaluation.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>

#include "aosr/core/error.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

using ::testing::AllOf;
using ::testing::HasSubstr;
using ::testing::ThrowsMessage;

Image Ramp(Index rows, Index cols) {
  Image x(rows, cols);
  for (Index y = 0; y < rows; ++y)
    for (Index c = 0; c < cols; ++c) x(y, c) = 10.0 + std::sin(0.3 * double(y)) * std::cos(0.2 * double(c));
  return x;
}

// A constant added to the truth is the level difference exactly; subtract_sky removes it before scoring (RMSE 0),
// and reports it in Evaluation::sky; without it, the RMSE is the constant.
TEST(EvaluationErrorsTest, SkyLevelDifferenceIsTheAddedConstantAndSubtractSkyRemovesIt) {
  const Image t = Ramp(24, 30);
  const Image e = t.array() + 4.5;
  EXPECT_NEAR(SkyLevelDifference(t, e, 2), 4.5, 1e-12);
  EvaluationOptions o;
  o.crop_px = 2;
  EXPECT_NEAR(EvaluateReconstruction(t, e, {}, o).metrics.rmse, 4.5, 1e-12);
  o.subtract_sky = true;
  const Evaluation ev = EvaluateReconstruction(t, e, {}, o);
  EXPECT_NEAR(ev.sky, 4.5, 1e-12);
  EXPECT_LT(ev.metrics.rmse, 1e-12);
}

TEST(EvaluationErrorsTest, SkyLevelDifferenceRejectsShapesAndCropsNamingThem) {
  const Image t = Ramp(24, 30);
  EXPECT_THAT([&] { SkyLevelDifference(t, Ramp(24, 31), 0); },
              ThrowsMessage<InvalidArgument>(HasSubstr("estimate")));
  EXPECT_THAT([&] { SkyLevelDifference(t, t, 12); }, ThrowsMessage<InvalidArgument>(HasSubstr("crop_px")));
  EXPECT_THAT([&] { SkyLevelDifference(t, t, -1); }, ThrowsMessage<InvalidArgument>(HasSubstr("crop_px")));
}

TEST(EvaluationErrorsTest, OutputKeepsSkyNeedsAReadableFile) {
  EXPECT_ANY_THROW(OutputKeepsSky("/nonexistent/aosr_estimate.fits"));
}

// Rings: a negative count, too many for the field, a centre off the image and a shape mismatch are refused,
// naming what is wrong.
TEST(EvaluationErrorsTest, RingOptionsAreCheckedNamingTheField) {
  const Image t = Ramp(48, 48), e = Ramp(48, 48) * 1.01;
  EvaluationOptions o;
  o.rings = -1;
  EXPECT_THAT([&] { EvaluateReconstruction(t, e, {}, o); },
              ThrowsMessage<InvalidArgument>(AllOf(HasSubstr("EvaluateReconstruction"), HasSubstr("rings = -1"))));
  o.rings = 9;
  EXPECT_THAT([&] { EvaluateReconstruction(t, e, {}, o); },
              ThrowsMessage<InvalidArgument>(AllOf(HasSubstr("rings = 9"), HasSubstr("1 .. 3"))));
  o.rings = 2;
  o.ring_centre_y = 50.0;
  o.ring_centre_x = 3.0;
  EXPECT_THAT([&] { EvaluateReconstruction(t, e, {}, o); },
              ThrowsMessage<InvalidArgument>(AllOf(HasSubstr("centre"), HasSubstr("50, 3"))));
  o.ring_centre_y = 10.0;
  EXPECT_NO_THROW(EvaluateReconstruction(t, e, {}, o));
  EXPECT_THAT([&] { EvaluateReconstruction(t, Ramp(48, 47), {}, o); },
              ThrowsMessage<InvalidArgument>(HasSubstr("estimate")));
}

}  // namespace
}  // namespace aosr
