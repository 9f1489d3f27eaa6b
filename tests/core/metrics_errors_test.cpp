#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <limits>
#include <string>

#include "aosr/core/error.hpp"
#include "aosr/core/metrics.hpp"
#include "support/testing.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

using aosr::test::ErrorOf;

using ::testing::AllOf;
using ::testing::HasSubstr;


Image Ramp(Index rows, Index cols) {
  Image img(rows, cols);
  for (Index i = 0; i < img.size(); ++i) img.data()[i] = 0.01 * i;
  return img;
}

TEST(MetricsErrorsTest, ShapeMismatchNamesTheEstimateShape) {
  const Image a = Ramp(20, 20), b = Ramp(20, 21);
  EXPECT_THAT(ErrorOf([&] { Rmse(a, b); }), AllOf(HasSubstr("Rmse"), HasSubstr("estimate shape"),
                                                    HasSubstr("20x21"), HasSubstr("20x20")));
  EXPECT_THAT(ErrorOf([&] { Psnr(a, b); }), AllOf(HasSubstr("Psnr"), HasSubstr("estimate shape")));
  EXPECT_THAT(ErrorOf([&] { Ssim(a, b); }), AllOf(HasSubstr("Ssim"), HasSubstr("estimate shape")));
  EXPECT_THAT(ErrorOf([&] { SsimMap(a, b); }), AllOf(HasSubstr("SsimMap"), HasSubstr("estimate shape")));
  EXPECT_THAT(ErrorOf([&] { CompareImages(a, b); }),
              AllOf(HasSubstr("CompareImages"), HasSubstr("estimate shape")));
}

TEST(MetricsErrorsTest, EmptyImagesAreRejected) {
  const Image empty;
  EXPECT_THAT(ErrorOf([&] { Rmse(empty, empty); }), AllOf(HasSubstr("Rmse"), HasSubstr("truth")));
}

TEST(MetricsErrorsTest, CropLeavingLessThanTheSsimWindow) {
  const Image a = Ramp(20, 30);
  MetricOptions opts;
  opts.crop_px = 5;  // leaves 10 x 20: smaller than the 11 x 11 window
  EXPECT_THAT(ErrorOf([&] { Ssim(a, a, opts); }),
              AllOf(HasSubstr("Ssim"), HasSubstr("crop_px = 5"), HasSubstr("11x11")));
  EXPECT_THAT(ErrorOf([&] { CompareImages(a, a, opts); }),
              AllOf(HasSubstr("CompareImages"), HasSubstr("crop_px")));
  // RMSE and PSNR only need one pixel: crop 5 is fine for them, crop 10 is not.
  EXPECT_NO_THROW(Rmse(a, a, opts));
  opts.crop_px = 10;
  EXPECT_THAT(ErrorOf([&] { Rmse(a, a, opts); }), AllOf(HasSubstr("Rmse"), HasSubstr("crop_px = 10")));
  EXPECT_THAT(ErrorOf([&] { Psnr(a, a, opts); }), AllOf(HasSubstr("Psnr"), HasSubstr("crop_px")));
  // An image smaller than the window fails even without a crop.
  EXPECT_THAT(ErrorOf([&] { Ssim(Ramp(10, 40), Ramp(10, 40)); }), HasSubstr("SSIM window"));
}

TEST(MetricsErrorsTest, NonFiniteValuesNameTheImage) {
  const Image good = Ramp(16, 16);
  Image bad = good;
  bad(3, 4) = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THAT(ErrorOf([&] { Rmse(good, bad); }), AllOf(HasSubstr("Rmse"), HasSubstr("estimate"),
                                                         HasSubstr("NaN")));
  EXPECT_THAT(ErrorOf([&] { Ssim(bad, good); }), AllOf(HasSubstr("Ssim"), HasSubstr("truth"),
                                                         HasSubstr("NaN")));
  bad(3, 4) = std::numeric_limits<double>::infinity();
  EXPECT_THAT(ErrorOf([&] { Psnr(bad, good); }), AllOf(HasSubstr("Psnr"), HasSubstr("truth")));
}

TEST(MetricsErrorsTest, NegativeOrNonFinitePeakAndNegativeCrop) {
  const Image a = Ramp(16, 16);
  MetricOptions opts;
  opts.peak = -1.0;
  EXPECT_THAT(ErrorOf([&] { Psnr(a, a, opts); }), AllOf(HasSubstr("Psnr"), HasSubstr("peak = -1")));
  EXPECT_THAT(ErrorOf([&] { Ssim(a, a, opts); }), AllOf(HasSubstr("Ssim"), HasSubstr("peak")));
  opts.peak = std::numeric_limits<double>::infinity();
  EXPECT_THAT(ErrorOf([&] { CompareImages(a, a, opts); }), HasSubstr("peak"));
  opts = MetricOptions{};
  opts.crop_px = -2;
  EXPECT_THAT(ErrorOf([&] { Rmse(a, a, opts); }), AllOf(HasSubstr("Rmse"), HasSubstr("crop_px = -2")));
}

TEST(MetricsErrorsTest, ConstantTruthNeedsAnExplicitPeak) {
  const Image flat = Image::Constant(16, 16, 0.5);
  const Image other = Image::Constant(16, 16, 0.4);
  EXPECT_THAT(ErrorOf([&] { Psnr(flat, other); }), AllOf(HasSubstr("Psnr"), HasSubstr("peak")));
  EXPECT_THAT(ErrorOf([&] { Ssim(flat, other); }), AllOf(HasSubstr("Ssim"), HasSubstr("peak")));
  // RMSE does not need a dynamic range.
  EXPECT_NEAR(Rmse(flat, other), 0.1, 1e-15);
}

TEST(MetricsErrorsTest, OffsetAndShiftArguments) {
  const Image a = Ramp(20, 20), b = Ramp(20, 21);
  EXPECT_THAT(ErrorOf([&] { MeasureImageOffset(a, b); }),
              AllOf(HasSubstr("MeasureImageOffset"), HasSubstr("estimate shape"), HasSubstr("20x21")));
  EXPECT_THAT(ErrorOf([&] { CompareImagesAligned(a, b); }), HasSubstr("estimate shape"));
  EXPECT_THAT(ErrorOf([&] { MeasureImageOffset(Image::Constant(20, 20, 1.0), a); }),
              AllOf(HasSubstr("MeasureImageOffset"), HasSubstr("truth"), HasSubstr("constant")));
  EXPECT_THAT(ErrorOf([&] { MeasureImageOffset(a, Image::Zero(20, 20)); }),
              AllOf(HasSubstr("estimate"), HasSubstr("constant")));
  Image nan = a;
  nan(3, 3) = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THAT(ErrorOf([&] { MeasureImageOffset(a, nan); }), AllOf(HasSubstr("estimate"), HasSubstr("finite")));
  EXPECT_THAT(ErrorOf([&] { FourierShiftImage(a, std::numeric_limits<double>::infinity(), 0.0); }),
              AllOf(HasSubstr("FourierShiftImage"), HasSubstr("dy")));
  EXPECT_THAT(ErrorOf([&] { FourierShiftImage(Image(), 0.0, 0.0); }),
              AllOf(HasSubstr("FourierShiftImage"), HasSubstr("non-empty")));
}

TEST(MetricsErrorsTest, RingArguments) {
  const Image a = Ramp(64, 64), b = Ramp(64, 64) * 1.1;
  // K < 1, and the options' own check.
  EXPECT_THAT(ErrorOf([&] { CompareImagesInRings(a, b, RingOptions{0}); }),
              AllOf(HasSubstr("CompareImagesInRings"), HasSubstr("rings = 0"), HasSubstr(">= 1")));
  std::string why;
  EXPECT_FALSE((RingOptions{-2}).IsValid(&why));
  EXPECT_THAT(why, HasSubstr("rings = -2"));
  // Too many rings for the field: rings from 0 to hypot(31.5, 31.5) = 44.5 px at >= 11 px: at most 4.
  EXPECT_THAT(ErrorOf([&] { CompareImagesInRings(a, b, RingOptions{5}); }),
              AllOf(HasSubstr("CompareImagesInRings"), HasSubstr("invalid rings = 5"), HasSubstr("1 .. 4"),
                    HasSubstr("11 px wide")));
  // A centre off the image, or not finite.
  EXPECT_THAT(ErrorOf([&] { CompareImagesInRings(a, b, RingOptions{2, 10.0, 64.0}); }),
              AllOf(HasSubstr("CompareImagesInRings"), HasSubstr("centre"), HasSubstr("10, 64"),
                    HasSubstr("-0.5 <= x <= 63.5")));
  EXPECT_THAT(ErrorOf([&] { CompareImagesInRings(a, b, RingOptions{2, -3.0, 5.0}); }),
              AllOf(HasSubstr("centre"), HasSubstr("-3, 5")));
  EXPECT_THAT(ErrorOf([&] { CompareImagesInRings(a, b, RingOptions{2, std::numeric_limits<double>::infinity(), 5.0}); }),
              AllOf(HasSubstr("CompareImagesInRings"), HasSubstr("centre"), HasSubstr("finite")));
  // Sizes that differ, values that are not finite, a crop that leaves less than the SSIM window.
  EXPECT_THAT(ErrorOf([&] { CompareImagesInRings(a, Ramp(64, 63), RingOptions{2}); }),
              AllOf(HasSubstr("CompareImagesInRings"), HasSubstr("estimate shape"), HasSubstr("64x63")));
  Image nan = b;
  nan(3, 3) = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THAT(ErrorOf([&] { CompareImagesInRings(a, nan, RingOptions{2}); }),
              AllOf(HasSubstr("CompareImagesInRings"), HasSubstr("estimate"), HasSubstr("finite")));
  EXPECT_THAT(ErrorOf([&] { CompareImagesInRings(a, b, RingOptions{1}, MetricOptions{27, 0.0}); }),
              AllOf(HasSubstr("CompareImagesInRings"), HasSubstr("crop_px")));
}

TEST(MetricsErrorsTest, WindowArguments) {
  const Image a = Ramp(20, 20), b = Ramp(20, 20) + 1.0;
  EXPECT_THAT(ErrorOf([&] { MeasureImageOffsetInWindow(a, b, Image::Ones(20, 21)); }),
              AllOf(HasSubstr("MeasureImageOffsetInWindow"), HasSubstr("window shape"), HasSubstr("20x21")));
  Image negative = Image::Ones(20, 20);
  negative(2, 2) = -1.0;
  EXPECT_THAT(ErrorOf([&] { MeasureImageOffsetInWindow(a, b, negative); }),
              AllOf(HasSubstr("MeasureImageOffsetInWindow"), HasSubstr("window"), HasSubstr(">= 0")));
  EXPECT_THAT(ErrorOf([&] { MeasureImageOffsetInWindow(a, b, Image::Zero(20, 20)); }),
              AllOf(HasSubstr("window"), HasSubstr("positive sum")));
  // Structure only outside the window: the truth is constant where it looks.
  Image flat_inside = a;
  flat_inside.block(5, 5, 10, 10).setConstant(0.5);
  Image inside = Image::Zero(20, 20);
  inside.block(6, 6, 8, 8).setOnes();
  EXPECT_THAT(ErrorOf([&] { MeasureImageOffsetInWindow(flat_inside, b, inside); }),
              AllOf(HasSubstr("truth"), HasSubstr("constant under the window")));
  EXPECT_THAT(ErrorOf([&] { ScoreWindow(Shape{20, 20}, 10); }), AllOf(HasSubstr("ScoreWindow"), HasSubstr("crop_px")));
  EXPECT_THAT(ErrorOf([&] { ScoreWindow(Shape{20, 20}, 0, ScoreRing{5, 5, 4, 3}); }),
              AllOf(HasSubstr("ScoreWindow"), HasSubstr("outer_px")));
}

}  // namespace
}  // namespace aosr

