#include "aosr/scene/image_object.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>

#include "aosr/core/error.hpp"
#include "aosr/io/fits.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

using ::testing::HasSubstr;

// A reproducible non-trivial image (no randomness needed).
Image Pattern(Index rows, Index cols) {
  Image img(rows, cols);
  for (Index i = 0; i < rows; ++i)
    for (Index j = 0; j < cols; ++j)
      img(i, j) = 1.0 + std::sin(0.37 * i) * std::cos(0.23 * j + 0.1 * i) + 0.01 * j;
  return img;
}

std::string TempPath(const std::string& name) {
  return (std::filesystem::temp_directory_path() /
          ("aosr_image_object_" + std::to_string(::getpid()) + "_" + name))
      .string();
}

TEST(ResampleAreaTest, ConservesFluxDownAndUp) {
  struct Case {
    Index h, w, H, W;
    ImageFit fit;
  };
  for (const Case& c : {Case{100, 75, 32, 24, ImageFit::kCrop}, Case{30, 20, 45, 30, ImageFit::kCrop},
                        Case{7, 5, 70, 50, ImageFit::kCrop}, Case{33, 41, 17, 23, ImageFit::kStretch},
                        Case{13, 9, 64, 100, ImageFit::kStretch}, Case{64, 64, 64, 64, ImageFit::kCrop}}) {
    const Image src = Pattern(c.h, c.w);
    const Image out = ResampleArea(src, {c.H, c.W}, c.fit, PixelValues::kFluxPerPixel);
    ASSERT_EQ(out.rows(), c.H);
    ASSERT_EQ(out.cols(), c.W);
    EXPECT_NEAR(out.sum(), src.sum(), 1e-12 * src.sum()) << c.h << "x" << c.w << " -> " << c.H << "x" << c.W;
  }
  // Identity for equal shapes.
  const Image src = Pattern(20, 30);
  EXPECT_LT((ResampleArea(src, {20, 30}) - src).abs().maxCoeff(), 1e-14);
}

TEST(ResampleAreaTest, IntegerDownsamplingIsBlockSums) {
  const Image src = Pattern(12, 18);
  const Image out = ResampleArea(src, {4, 6}, ImageFit::kCrop, PixelValues::kFluxPerPixel);
  for (Index i = 0; i < 4; ++i)
    for (Index j = 0; j < 6; ++j) EXPECT_NEAR(out(i, j), src.block(3 * i, 3 * j, 3, 3).sum(), 1e-13);
  const Image mean = ResampleArea(src, {4, 6});
  EXPECT_NEAR(mean(1, 2), src.block(3, 6, 3, 3).mean(), 1e-13);
}

TEST(ResampleAreaTest, ConstantStaysConstant) {
  const Image src = Image::Constant(37, 53, 0.625);
  for (ImageFit fit : {ImageFit::kCrop, ImageFit::kStretch})
    for (Shape s : {Shape{64, 64}, Shape{10, 30}, Shape{100, 7}}) {
      const Image out = ResampleArea(src, s, fit);
      EXPECT_LT((out - 0.625).abs().maxCoeff(), 1e-14) << ToString(s);
    }
}

TEST(ResampleAreaTest, CropKeepsTheCentreAndSquarePixels) {
  // A 10x20 source onto a square grid: the central 10x10 window, i.e. columns 5..14.
  Image src = Image::Zero(10, 20);
  src.block(0, 5, 10, 10).setOnes();
  const Image out = ResampleArea(src, {5, 5}, ImageFit::kCrop, PixelValues::kFluxPerPixel);
  EXPECT_LT((out - 4.0).abs().maxCoeff(), 1e-14);  // each output pixel sums a 2x2 block of ones
  // Crop through the middle of source pixels: the covered fraction contributes.
  const Image one = ResampleArea(Image::Ones(3, 4), {1, 1}, ImageFit::kCrop, PixelValues::kFluxPerPixel);
  EXPECT_NEAR(one(0, 0), 9.0, 1e-14);  // the central 3x3 window of a 3x4 image
}

TEST(MakeImageObjectTest, BackgroundClipAndNormalisation) {
  Image src = Image::Constant(40, 40, 10.0);
  src.block(15, 15, 10, 10).array() += 5.0;
  ImageObjectOptions o;
  o.background = ImageBackground::kMedian;
  o.values = PixelValues::kFluxPerPixel;
  Image out = MakeImageObject(src, {20, 20}, o);
  EXPECT_NEAR(out.sum(), 500.0, 1e-10);  // only the 10x10 excess of 5 remains
  o.background = ImageBackground::kBorderMedian;
  EXPECT_NEAR(MakeImageObject(src, {20, 20}, o).sum(), 500.0, 1e-10);
  o.background = ImageBackground::kMinimum;
  EXPECT_NEAR(MakeImageObject(src, {20, 20}, o).minCoeff(), 0.0, 1e-12);

  o.background = ImageBackground::kNone;
  o.normalisation = FluxNormalisation::kTotalFlux;
  o.total_flux = 3.0;
  EXPECT_NEAR(MakeImageObject(src, {64, 64}, o).sum(), 3.0, 1e-12);
  o.normalisation = FluxNormalisation::kPeak;
  o.peak_value = 2.0;
  EXPECT_NEAR(MakeImageObject(src, {64, 64}, o).maxCoeff(), 2.0, 1e-12);

  // Clipping: background subtraction of the median leaves negative noise that clip_negative removes.
  Image noisy = Pattern(30, 30);
  o = {};
  o.background = ImageBackground::kMedian;
  EXPECT_GE(MakeImageObject(noisy, {30, 30}, o).minCoeff(), 0.0);
  o.clip_negative = false;
  EXPECT_LT(MakeImageObject(noisy, {30, 30}, o).minCoeff(), 0.0);
}

TEST(LoadImageObjectTest, ReadsFitsAndConservesFlux) {
  const std::string path = TempPath("flux.fits");
  const Image src = Pattern(48, 36);
  WriteFits(path, src, {}, FitsType::kFloat64);
  ImageObjectOptions o;
  o.values = PixelValues::kFluxPerPixel;
  const Image out = LoadImageObject(path, {128, 96}, o);
  EXPECT_NEAR(out.sum(), src.sum(), 1e-12 * src.sum());
  o.normalisation = FluxNormalisation::kTotalFlux;
  o.total_flux = 1.0;
  EXPECT_NEAR(LoadImageObject(path, {16, 12}, o).sum(), 1.0, 1e-12);
  std::filesystem::remove(path);
}

TEST(LoadImageObjectTest, MissingFileIsAnIoErrorNamingThePath) {
  const std::string path = TempPath("does_not_exist.png");
  try {
    LoadImageObject(path, {32, 32});
    FAIL() << "no exception";
  } catch (const IoError& e) {
    EXPECT_EQ(e.path(), path);
    EXPECT_THAT(e.what(), HasSubstr(path));
  }
}

TEST(LoadImageObjectTest, FileProblemsNameThePath) {
  const std::string path = TempPath("zero.fits");
  WriteFits(path, Image::Zero(8, 8));
  ImageObjectOptions o;
  o.normalisation = FluxNormalisation::kTotalFlux;
  try {
    LoadImageObject(path, {16, 16}, o);
    FAIL() << "no exception";
  } catch (const InvalidArgument& e) {
    EXPECT_THAT(e.what(), HasSubstr(path));
    EXPECT_THAT(e.what(), HasSubstr("total_flux"));
  }
  std::filesystem::remove(path);
}

}  // namespace
}  // namespace aosr
