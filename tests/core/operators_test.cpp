#include "aosr/core/operators.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <memory>

#include <random>

#include "aosr/core/adjoint_test.hpp"
#include "aosr/core/fft.hpp"
#include "support/testing.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

constexpr double kAdjointTol = 1e-10;

Image RandomImage(Shape s, std::uint64_t seed) { return aosr::test::RandomImage(s, seed, /*normal=*/false); }

Image GaussianKernel(Index n, double sigma) {
  Image k(n, n);
  for (Index y = 0; y < n; ++y)
    for (Index x = 0; x < n; ++x) {
      const double dy = y - n / 2, dx = x - n / 2;
      k(y, x) = std::exp(-(dx * dx + dy * dy) / (2 * sigma * sigma)) * (1.0 + 0.1 * dx);  // asymmetric
    }
  return k / k.sum();
}

TEST(OperatorsTest, EveryPrimitivePassesTheAdjointTest) {
  const Shape s{24, 30};
  std::vector<OperatorPtr> ops = {
      PeriodicConvolutionFromKernel(s, GaussianKernel(7, 1.5)),
      LinearConvolution(s, GaussianKernel(9, 2.0)),
      Decimate(s, 3),
      Mask(RandomImage(s, 3)),
      Gradient(s, Boundary::kPeriodic),
      Gradient(s, Boundary::kNeumann),
      ZeroPad(s, {40, 41}, 5, 7),
      Crop({40, 41}, s, 5, 7),
      Identity(s.size()),
  };
  for (const auto& op : ops) {
    const AdjointTestResult r = AdjointTest(*op, 7);
    EXPECT_LT(r.adjoint_error, kAdjointTol) << op->name();
    EXPECT_LT(r.normal_error, kAdjointTol) << op->name();
  }
}

// The shared-spectrum form (what MultiFrameModel's frame operators use): the same operator, bit for bit, as the
// copying form; adjoint-exact; and its refusals. HermitianProjectInPlace gives HermitianProjection's bytes.
TEST(OperatorsTest, SharedTransferFunctionConvolutionIsTheCopyingOne) {
  for (const Shape s : {Shape{24, 30}, Shape{23, 31}}) {
    const ComplexImage h = TransferFunction(s, GaussianKernel(7, 1.5));
    ComplexImage rough = h;
    rough(1, 0) += Complex(0.3, 0.2);  // not Hermitian on the self-conjugate column
    ComplexImage in_place = rough;
    HermitianProjectInPlace(&in_place, s.cols);
    const ComplexImage copied = HermitianProjection(rough, s.cols);
    EXPECT_EQ(std::memcmp(in_place.data(), copied.data(), sizeof(Complex) * copied.size()), 0) << ToString(s);
    const OperatorPtr a = PeriodicConvolution(s, rough);
    const OperatorPtr b = PeriodicConvolution(s, std::make_shared<const ComplexImage>(copied));
    const Vector x = AsVector(RandomImage(s, 5));
    const Vector ya = a->Apply(x), yb = b->Apply(x);
    EXPECT_EQ(std::memcmp(ya.data(), yb.data(), sizeof(double) * ya.size()), 0) << ToString(s);
    const AdjointTestResult r = AdjointTest(*b, 7);
    EXPECT_LT(r.adjoint_error, kAdjointTol);
    EXPECT_LT(r.normal_error, kAdjointTol);
  }
  const Shape s{24, 30};
  EXPECT_THAT(test::ErrorOf([&] { PeriodicConvolution(s, std::shared_ptr<const ComplexImage>()); }),
              ::testing::HasSubstr("otf_half"));
  EXPECT_THAT(test::ErrorOf([&] {
                PeriodicConvolution(s, std::make_shared<const ComplexImage>(ComplexImage::Zero(24, 15)));
              }),
              ::testing::HasSubstr("half spectrum"));
  ComplexImage bad = TransferFunction(s, GaussianKernel(7, 1.5));
  bad(2, 3) = Complex(std::nan(""), 0);
  EXPECT_FALSE(AllFinite(bad));
  EXPECT_THAT(test::ErrorOf([&] { PeriodicConvolution(s, bad); }), ::testing::HasSubstr("non-finite"));
}

TEST(OperatorsTest, CompositionsPassTheAdjointTest) {
  const Shape hr{32, 32};
  auto frame = [&](double sigma) {
    return Compose(Decimate(hr, 2), PeriodicConvolutionFromKernel(hr, GaussianKernel(9, sigma)));
  };
  const OperatorPtr a = Stack({frame(1.0), frame(1.5), frame(2.0)});
  EXPECT_LT(AdjointTest(*a).worst(), kAdjointTol) << a->name();
  const OperatorPtr b = Sum({Scale(0.5, Identity(hr.size())), PeriodicConvolutionFromKernel(hr, GaussianKernel(5, 1))});
  EXPECT_LT(AdjointTest(*b).worst(), kAdjointTol) << b->name();
  EXPECT_EQ(a->rows(), 3 * 16 * 16);
  EXPECT_EQ(a->cols(), hr.size());
}

TEST(OperatorsTest, DecimationAndConvolutionConserveFlux) {
  const Shape s{36, 48};
  const Image x = RandomImage(s, 11);
  const double flux = x.sum();
  const Vector d = Decimate(s, 4)->Apply(AsVector(x));
  EXPECT_NEAR(d.sum(), flux, 1e-12 * flux);
  const Vector c = PeriodicConvolutionFromKernel(s, GaussianKernel(11, 2.0))->Apply(AsVector(x));
  EXPECT_NEAR(c.sum(), flux, 1e-12 * flux);
}

TEST(OperatorsTest, DecimationSumsBlocks) {
  Image x(4, 6);
  for (Index i = 0; i < x.size(); ++i) x.data()[i] = i;
  const Image y = ToImage(Decimate({4, 6}, 2)->Apply(AsVector(x)), {2, 3});
  EXPECT_DOUBLE_EQ(y(0, 0), 0 + 1 + 6 + 7);
  EXPECT_DOUBLE_EQ(y(1, 2), 16 + 17 + 22 + 23);
}

TEST(OperatorsTest, ConvolutionWithShiftedDeltaShiftsTowardPositiveX) {
  const Shape s{8, 8};
  Image k = Image::Zero(5, 5);
  k(2, 3) = 1.0;  // centre is (2,2): a delta at +1 in x
  Image x = Image::Zero(8, 8);
  x(4, 4) = 1.0;
  const Image y = ToImage(PeriodicConvolutionFromKernel(s, k)->Apply(AsVector(x)), s);
  EXPECT_NEAR(y(4, 5), 1.0, 1e-14);
  const Image z = ToImage(LinearConvolution(s, k)->Apply(AsVector(x)), s);
  EXPECT_NEAR(z(4, 5), 1.0, 1e-14);
}

TEST(OperatorsTest, LinearConvolutionDoesNotWrap) {
  const Shape s{16, 16};
  Image x = Image::Zero(16, 16);
  x(0, 0) = 1.0;
  const Image y = ToImage(LinearConvolution(s, GaussianKernel(5, 1.0))->Apply(AsVector(x)), s);
  EXPECT_NEAR(y(15, 15), 0.0, 1e-15);  // FFT rounding only
  EXPECT_NEAR(y(0, 15), 0.0, 1e-15);
  EXPECT_GT(y(1, 1), 0.0);
}

}  // namespace
}  // namespace aosr
