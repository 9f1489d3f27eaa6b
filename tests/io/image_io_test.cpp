#include "aosr/io/image_io.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>

#include "aosr/io/fits.hpp"
#include "temp_dir.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

using testing_io::TempDir;
using testing_io::WriteBytes;

// 1 x 11 ramp 0, 1, ..., 10.
Image Ramp() {
  Image img(1, 11);
  for (Index x = 0; x < 11; ++x) img(0, x) = static_cast<double>(x);
  return img;
}

ViewOptions With(Stretch s) {
  ViewOptions o;
  o.stretch = s;
  return o;
}

TEST(StretchTest, LinearMapsMinToZeroAndMaxToOne) {
  const Image t = ApplyStretch(Ramp(), {});
  for (Index x = 0; x < 11; ++x) EXPECT_DOUBLE_EQ(t(0, x), x / 10.0);
}

TEST(StretchTest, PercentilesInterpolateBetweenOrderStatisticsAndClip) {
  ViewOptions o;
  o.low_percentile = 10.0;   // rank 1.0 of 0..10 -> value 1
  o.high_percentile = 85.0;  // rank 8.5 -> value 8.5
  const Image t = ApplyStretch(Ramp(), o);
  EXPECT_EQ(t(0, 0), 0.0);
  EXPECT_EQ(t(0, 1), 0.0);
  EXPECT_DOUBLE_EQ(t(0, 4), 3.0 / 7.5);
  EXPECT_EQ(t(0, 9), 1.0);
  EXPECT_EQ(t(0, 10), 1.0);
}

TEST(StretchTest, LogAndAsinhMatchTheirFormulasAtKnownPoints) {
  const Image log = ApplyStretch(Ramp(), With(Stretch::kLog));
  EXPECT_EQ(log(0, 0), 0.0);
  EXPECT_DOUBLE_EQ(log(0, 10), 1.0);
  EXPECT_NEAR(log(0, 5), std::log10(501.0) / std::log10(1001.0), 1e-15);
  EXPECT_NEAR(log(0, 5), 0.89982, 1e-5);

  ViewOptions o = With(Stretch::kAsinh);
  o.asinh_softening = 0.2;
  const Image as = ApplyStretch(Ramp(), o);
  EXPECT_EQ(as(0, 0), 0.0);
  EXPECT_DOUBLE_EQ(as(0, 10), 1.0);
  EXPECT_NEAR(as(0, 2), std::asinh(1.0) / std::asinh(5.0), 1e-15);  // t = s
}

TEST(StretchTest, EveryStretchStaysInUnitIntervalAndIsMonotonic) {
  std::mt19937_64 rng(42);
  std::normal_distribution<double> n(3.0, 10.0);
  Image img(16, 9);
  for (Index i = 0; i < img.size(); ++i) img.data()[i] = n(rng);
  for (Stretch s : {Stretch::kLinear, Stretch::kLog, Stretch::kAsinh}) {
    ViewOptions o = With(s);
    o.low_percentile = 5;
    o.high_percentile = 95;
    const Image t = ApplyStretch(img, o);
    EXPECT_GE(t.minCoeff(), 0.0);
    EXPECT_LE(t.maxCoeff(), 1.0);
    for (Index i = 0; i < img.size(); ++i)
      for (Index j = 0; j < img.size(); ++j)
        if (img.data()[i] < img.data()[j]) {
          ASSERT_LE(t.data()[i], t.data()[j]) << "seed 42";
        }
  }
}

TEST(StretchTest, NonFinitePixelsAndConstantImages) {
  Image img = Ramp();
  img(0, 3) = std::numeric_limits<double>::quiet_NaN();
  img(0, 4) = std::numeric_limits<double>::infinity();
  img(0, 5) = -std::numeric_limits<double>::infinity();
  const Image t = ApplyStretch(img, {});
  EXPECT_EQ(t(0, 3), 0.0);
  EXPECT_EQ(t(0, 4), 1.0);
  EXPECT_EQ(t(0, 5), 0.0);
  EXPECT_DOUBLE_EQ(t(0, 6), 0.6);  // Inf did not enter the percentiles: range is still 0..10
  EXPECT_TRUE((ApplyStretch(Image::Constant(3, 3, 7.0), {}) == 0.0).all());
}

TEST(ViewOptionsTest, IsValidNamesTheBadField) {
  std::string why;
  EXPECT_TRUE(ViewOptions{}.IsValid(&why));
  ViewOptions o;
  o.low_percentile = 50;
  o.high_percentile = 50;
  EXPECT_FALSE(o.IsValid(&why));
  EXPECT_NE(why.find("low_percentile"), std::string::npos);
  o = {};
  o.bits = 12;
  EXPECT_FALSE(o.IsValid(&why));
  EXPECT_NE(why.find("bits"), std::string::npos);
  o = {};
  o.asinh_softening = 0.0;
  EXPECT_FALSE(o.IsValid(&why));
  EXPECT_NE(why.find("asinh_softening"), std::string::npos);
  o = ViewOptions{};
  o.png_compression = 10;
  EXPECT_FALSE(o.IsValid(&why));
  EXPECT_NE(why.find("png_compression"), std::string::npos);
  EXPECT_FALSE(o.IsValid(nullptr));
}

// A 4 x 6 image with distinct values in [0, 1], min 0 and max 1 so the stretch is the identity.
Image UnitTestPattern() {
  Image img(4, 6);
  for (Index y = 0; y < 4; ++y)
    for (Index x = 0; x < 6; ++x) img(y, x) = (6.0 * y + x) / 23.0;
  return img;
}

TEST(ViewImageTest, PngRoundTripsWithinQuantisation) {
  TempDir dir;
  const Image img = UnitTestPattern();
  for (int bits : {8, 16}) {
    ViewOptions o;
    o.bits = bits;
    const std::string path = dir.File("view" + std::to_string(bits) + ".PNG");  // case-insensitive
    WriteViewImage(path, img, o);
    const Image back = ReadImage(path);
    ASSERT_EQ(ShapeOf(back), ShapeOf(img));
    const double step = 1.0 / ((1 << bits) - 1);
    EXPECT_LE((back - img).abs().maxCoeff(), 0.5 * step + 1e-7) << bits << " bits";
  }
  EXPECT_EQ(dir.List().size(), 2u);  // no temporary files left
}

TEST(ViewImageTest, FloatTiffRoundTripsToFloatPrecision) {
  TempDir dir;
  ViewOptions o;
  o.bits = 32;
  const Image img = UnitTestPattern();
  WriteViewImage(dir.File("view.tiff"), img, o);
  const Image back = ReadImage(dir.File("view.tiff"));
  ASSERT_EQ(ShapeOf(back), ShapeOf(img));
  EXPECT_LE((back - img).abs().maxCoeff(), 1e-7);
  o.bits = 16;
  WriteViewImage(dir.File("view16.tif"), img, o);
  EXPECT_LE((ReadImage(dir.File("view16.tif")) - img).abs().maxCoeff(), 0.5 / 65535 + 1e-7);
}

TEST(ReadImageTest, FirstFileRowIsRowZeroAndColourIsAveraged) {
  TempDir dir;
  // Binary PPM, 2 columns x 2 rows, written top row first: (R,G,B) per pixel.
  const std::string ppm = std::string("P6\n2 2\n255\n") + std::string(
                                                              "\xff\x00\x00"
                                                              "\x00\x00\x00"
                                                              "\x00\x33\x66"
                                                              "\xff\xff\xff",
                                                              12);
  WriteBytes(dir.File("rgb.ppm"), ppm);
  const Image img = ReadImage(dir.File("rgb.ppm"));
  ASSERT_EQ(img.rows(), 2);
  ASSERT_EQ(img.cols(), 2);
  EXPECT_NEAR(img(0, 0), 1.0 / 3.0, 1e-6);
  EXPECT_NEAR(img(0, 1), 0.0, 1e-6);
  EXPECT_NEAR(img(1, 0), (0x33 + 0x66) / 255.0 / 3.0, 1e-6);
  EXPECT_NEAR(img(1, 1), 1.0, 1e-6);
}

TEST(ReadImageTest, ReadsFitsThroughCfitsio) {
  TempDir dir;
  Image img(2, 3);
  img << 1, 2, 3, 4, 5, 6;
  WriteFits(dir.File("a.fits"), img, {}, FitsType::kFloat64);
  EXPECT_TRUE((ReadImage(dir.File("a.fits")) == img).all());
  // A FITS file is recognised by its first card even without the extension.
  std::filesystem::rename(dir.File("a.fits"), dir.File("a.dat"));
  EXPECT_TRUE((ReadImage(dir.File("a.dat")) == img).all());
}

TEST(MontageTest, TilesAreCentredInCellsLeftToRightTopToBottom) {
  const Image a = Image::Constant(2, 2, 1.0);
  const Image b = Image::Constant(3, 3, 2.0);
  const Image c = Image::Constant(1, 1, 3.0);
  const Image m = Montage({a, b, c}, 2, 1, -1.0);
  // Cells 3x3, 2 columns, 2 rows, 1-pixel gaps: 7 x 7.
  ASSERT_EQ(m.rows(), 7);
  ASSERT_EQ(m.cols(), 7);
  Image expected = Image::Constant(7, 7, -1.0);
  expected.block(0, 0, 2, 2) = 1.0;  // a: offset (3-2)/2 = 0
  expected.block(0, 4, 3, 3) = 2.0;  // b: column 1 starts at 3 + 1
  expected(5, 1) = 3.0;              // c: row 1 starts at 4, centred at +1
  EXPECT_TRUE((m == expected).all()) << m;
}

TEST(MontageTest, FewerTilesThanColumnsMakeOneRow) {
  const Image m = Montage({Image::Zero(2, 3), Image::Ones(2, 3)}, 5, 0, 9.0);
  ASSERT_EQ(m.rows(), 2);
  ASSERT_EQ(m.cols(), 6);
  EXPECT_EQ(m(1, 2), 0.0);
  EXPECT_EQ(m(1, 3), 1.0);
}

}  // namespace
}  // namespace aosr
