#include "aosr/solvers/shift_and_add.hpp"

#include <gtest/gtest.h>

#include "aosr/core/forward_model.hpp"
#include "aosr/core/operators.hpp"
#include "drizzle_fixture.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

// On a complete integer raster, mean shift-and-add of noise-free box-pixel frames equals the object
// blurred by the separable triangle c[d] = (r - |d|)/r² per axis (see shift_and_add.hpp).
TEST(ShiftAndAddTest, CompleteRasterGivesTheTriangleBlur) {
  const int r = 2;
  const Shape hr{16, 12};
  Image delta = Image::Zero(1, 1);
  delta(0, 0) = 1;
  std::vector<ComplexImage> otfs;
  std::vector<FrameOffset> offsets;
  for (int dy = 0; dy < r; ++dy)
    for (int dx = 0; dx < r; ++dx) {
      otfs.push_back(ShiftTransfer(hr, dy, dx));
      offsets.push_back({double(dy), double(dx)});
    }
  const MultiFrameModel m(hr, r, otfs);
  Image x = Image::Zero(hr.rows, hr.cols);
  x(7, 5) = 1.0;
  const Image sa = ShiftAndAdd(m.Render(x), offsets, r, Combine::kMean);
  Image tri(3, 3);
  const double t[3] = {0.5, 1.0, 0.5};
  for (int y = 0; y < 3; ++y)
    for (int c = 0; c < 3; ++c) tri(y, c) = t[y] * t[c] / (r * r);
  for (int y = 0; y < 3; ++y)
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(sa(6 + y, 4 + c), tri(y, c), 1e-12);
  EXPECT_NEAR(sa.sum(), 1.0, 1e-12);
  EXPECT_NEAR(ShiftAndAdd(m.Render(x), offsets, r, Combine::kMedian).sum(), 1.0, 0.5);
}

// The median combination per pixel: the middle value for an odd count, the mean of the two middle values for
// an even one, and over the unmasked frames only when weights mask some (the normalised-convolution path).
TEST(ShiftAndAddTest, MedianIsTheMiddleValueOfTheUnmaskedFrames) {
  const double values[4] = {1.0, 5.0, 2.0, 9.0};
  ImageStack frames;
  for (double v : values) frames.push_back(Image::Constant(3, 4, v));
  const std::vector<FrameOffset> zero(4, FrameOffset{0.0, 0.0});
  const Image even = ShiftAndAdd(frames, zero, 1, Combine::kMedian);
  EXPECT_DOUBLE_EQ(even(1, 2), 3.5);
  const ImageStack odd(frames.begin(), frames.begin() + 3);
  EXPECT_DOUBLE_EQ(ShiftAndAdd(odd, {zero.begin(), zero.begin() + 3}, 1, Combine::kMedian)(2, 3), 2.0);
  ImageStack weights(4, Image::Ones(3, 4));
  weights[3].setZero();  // the 9 is masked: the median of {1, 5, 2}
  const Image masked =
      ShiftAndAdd(test::RegistrationProblem({3, 4}, 1, frames, zero, weights), Combine::kMedian);
  EXPECT_DOUBLE_EQ(masked(0, 0), 2.0);
}

TEST(ShiftAndAddTest, BicubicPreservesAConstantFluxDensity) {
  const Image lr = Image::Constant(6, 7, 8.0);
  const Image hr = BicubicUpsample(lr, 2);
  EXPECT_EQ(hr.rows(), 12);
  EXPECT_NEAR(hr.maxCoeff(), 2.0, 1e-12);
  EXPECT_NEAR(hr.minCoeff(), 2.0, 1e-12);
}

}  // namespace
}  // namespace aosr
