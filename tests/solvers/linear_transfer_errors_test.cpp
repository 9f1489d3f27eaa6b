// Bad inputs of the exact-transfer entry points (solvers/linear_transfer.hpp): each names the function and field.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <limits>
#include <memory>

#include "aosr/solvers/linear_transfer.hpp"
#include "solvers/tikhonov_fixture.hpp"
#include "support/testing.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

using test::ErrorOf;
using ::testing::HasSubstr;

constexpr double kLinTransferNaN = std::numeric_limits<double>::quiet_NaN();

MultiFrameModel TransferErrorsModel() { return test::RasterModel({16, 16}, 2, {{0, 0}, {1, 1}}, 1.0); }

TEST(LinearTransferErrorsTest, TikhonovGridNamesTheBadInput) {
  const MultiFrameModel m = TransferErrorsModel();
  const TikhonovOptions o;
  EXPECT_THAT(ErrorOf([&] { TikhonovTransferGrid(m, {1.0}, o, 0.1); }),
              HasSubstr("TikhonovTransferGrid: invalid frame_weights = 1 values"));
  EXPECT_THAT(ErrorOf([&] { TikhonovTransferGrid(m, {1.0, -1.0}, o, 0.1); }), HasSubstr("frame_weights[1]"));
  EXPECT_THAT(ErrorOf([&] { TikhonovTransferGrid(m, {0.0, 0.0}, o, 0.1); }), HasSubstr("at least one frame"));
  EXPECT_THAT(ErrorOf([&] { TikhonovTransferGrid(m, {}, o, -1); }), HasSubstr("TikhonovTransferGrid: invalid lambda = -1"));
  EXPECT_THAT(ErrorOf([&] { TikhonovTransferGrid(m, {}, o, kLinTransferNaN); }), HasSubstr("lambda"));
  TikhonovOptions bad = o;
  bad.spectrum_slope = -1;
  bad.prior = TikhonovPrior::kPowerSpectrum;
  EXPECT_THAT(ErrorOf([&] { TikhonovTransferGrid(m, {}, bad, 0.1); }), HasSubstr("spectrum_slope"));
  TikhonovOptions fitted = o;
  fitted.prior = TikhonovPrior::kFitted;
  EXPECT_THAT(ErrorOf([&] { TikhonovTransferGrid(m, {}, fitted, 0.1); }),
              HasSubstr("invalid prior = fitted; allowed: the spectrum ReconstructTikhonov fitted"));
  fitted.prior = TikhonovPrior::kPowerSpectrum;
  fitted.object_power_spectrum = Image::Ones(8, 8);
  EXPECT_THAT(ErrorOf([&] { TikhonovTransferGrid(m, {}, fitted, 0.1); }), HasSubstr("object_power_spectrum shape"));
}

TEST(LinearTransferErrorsTest, CurveOptionsNameTheBadField) {
  const Image k = test::GaussianKernel(9, 1.0);
  auto err = [&](void (*edit)(TransferCurveOptions&)) {
    TransferCurveOptions o;
    edit(o);
    return ErrorOf([&] { KernelTransferCurve(k, o); });
  };
  EXPECT_THAT(err([](auto& o) { o.direction_x = o.direction_y = 0; }),
              HasSubstr("KernelTransferCurve: options.direction = (0, 0)"));
  EXPECT_THAT(err([](auto& o) { o.direction_y = kLinTransferNaN; }), HasSubstr("options.direction"));
  EXPECT_THAT(err([](auto& o) { o.curve_max = 1.5; }), HasSubstr("options.curve_max = 1.5"));
  EXPECT_THAT(err([](auto& o) { o.curve_max = 0; }), HasSubstr("options.curve_max"));
  EXPECT_THAT(err([](auto& o) {
                o.radial = true;
                o.curve_max = 0.7;
              }),
              HasSubstr("radial average stops at the HR Nyquist"));
  EXPECT_THAT(err([](auto& o) { o.curve_step = 0.6; }), HasSubstr("options.curve_step = 0.6"));
  EXPECT_THAT(err([](auto& o) { o.frequencies = {0.1, 0.7}; }), HasSubstr("options.frequencies: 0.7"));
}

TEST(LinearTransferErrorsTest, KernelsAndGridsMustHoldATransfer) {
  EXPECT_THAT(ErrorOf([] { KernelTransferCurve(Image()); }), HasSubstr("KernelTransferCurve: invalid kernel = empty"));
  Image k = test::GaussianKernel(9, 1.0);
  k(0, 0) = kLinTransferNaN;
  EXPECT_THAT(ErrorOf([&] { KernelTransferCurve(k); }), HasSubstr("non-finite"));
  EXPECT_THAT(ErrorOf([] { KernelTransferCurve(Image::Zero(4, 4)); }), HasSubstr("kernel sum"));
  TransferGrid g;
  EXPECT_THAT(ErrorOf([&] { GridTransferCurve(g); }), HasSubstr("GridTransferCurve: invalid grid"));
  g.transfer = ComplexImage::Ones(4, 4);
  g.alias = Image::Zero(4, 5);
  EXPECT_THAT(ErrorOf([&] { GridTransferCurve(g); }), HasSubstr("alias grid of its shape"));
  EXPECT_THAT(ErrorOf([] { SetDirectionFromEdge(SlantedEdgeMtf{}, nullptr); }), HasSubstr("SetDirectionFromEdge"));
}

TEST(LinearTransferErrorsTest, TikhonovCurveValidatesTheProblem) {
  ReconstructionProblem p;
  p.model = std::make_shared<const MultiFrameModel>(TransferErrorsModel());
  p.frames = ImageStack(1, Image::Ones(8, 8));
  EXPECT_THAT(ErrorOf([&] { TikhonovTransferCurve(p, TikhonovOptions{}, 0.1); }), HasSubstr("TikhonovTransferCurve"));
}

}  // namespace AOSR_TEST_NS
}  // namespace aosr
