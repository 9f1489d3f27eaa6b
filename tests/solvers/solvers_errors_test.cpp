#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <limits>

#include "aosr/core/error.hpp"
#include "aosr/core/operators.hpp"
#include "aosr/solvers/shift_and_add.hpp"
#include "aosr/solvers/tikhonov.hpp"
#include "support/testing.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

using aosr::test::ErrorOf;

using ::testing::HasSubstr;


MultiFrameModel Model() {
  Image k = Image::Zero(3, 3);
  k(1, 1) = 1;
  return MultiFrameModel::FromKernels({8, 8}, 2, {k, k});
}

TEST(SolversErrorsTest, TikhonovRejectsNaNFrames) {
  ImageStack y(2, Image::Ones(4, 4));
  y[1](2, 3) = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THAT(ErrorOf([&] { TikhonovFourier(Model(), y, {}); }), HasSubstr("frame 1"));
}

TEST(SolversErrorsTest, TikhonovRejectsWrongShapesAndCounts) {
  EXPECT_THAT(ErrorOf([&] { TikhonovFourier(Model(), ImageStack(2, Image::Ones(4, 5)), {}); }),
              HasSubstr("frame 0 shape"));
  EXPECT_THAT(ErrorOf([&] { TikhonovFourier(Model(), ImageStack(3, Image::Ones(4, 4)), {}); }),
              HasSubstr("frame count"));
}

TEST(SolversErrorsTest, TikhonovRejectsNegativeLambda) {
  TikhonovOptions o;
  o.lambda = -1;
  EXPECT_THAT(ErrorOf([&] { TikhonovFourier(Model(), ImageStack(2, Image::Ones(4, 4)), o); }), HasSubstr("lambda"));
  EXPECT_THAT(ErrorOf([&] { ParseTikhonovPrior("tv"); }), HasSubstr("identity, gradient, laplacian, power-spectrum or fitted"));
}

TEST(SolversErrorsTest, ModelRejectsRThatDoesNotDivideTheGrid) {
  Image k = Image::Ones(1, 1);
  EXPECT_THAT(ErrorOf([&] { MultiFrameModel::FromKernels({9, 8}, 2, {k}); }), HasSubstr("divisor"));
}

TEST(SolversErrorsTest, ShiftAndAddRejectsMismatchedInputs) {
  ImageStack y = {Image::Ones(4, 4), Image::Ones(4, 5)};
  EXPECT_THAT(ErrorOf([&] { ShiftAndAdd(y, {{}, {}}, 2, Combine::kMean); }), HasSubstr("frame 1 shape"));
  ImageStack z(2, Image::Ones(4, 4));
  EXPECT_THAT(ErrorOf([&] { ShiftAndAdd(z, {{}}, 2, Combine::kMean); }), HasSubstr("offsets count"));
  EXPECT_THAT(ErrorOf([&] { BicubicUpsample(z[0], 0); }), HasSubstr("r"));
}

}  // namespace
}  // namespace aosr
