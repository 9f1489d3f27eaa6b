#include "aosr/io/fits.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <limits>
#include <map>

#include "aosr/core/error.hpp"
#include "temp_dir.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

using testing_io::ReadBytes;
using testing_io::TempDir;
using testing_io::WriteBytes;

// --- An independent oracle: FITS is 80-character ASCII cards in 2880-byte blocks, then big-endian
// --- data. The tests below read and write that layout by hand instead of trusting cfitsio twice.

// Keyword -> raw value text (before any '/ comment'), for the first header of a file.
std::map<std::string, std::string> RawHeader(const std::string& bytes) {
  std::map<std::string, std::string> cards;
  for (size_t at = 0; at + 80 <= bytes.size(); at += 80) {
    const std::string card = bytes.substr(at, 80);
    std::string name = card.substr(0, 8);
    name.erase(name.find_last_not_of(' ') + 1);
    if (name == "END") break;
    if (card.compare(8, 2, "= ") != 0) continue;
    std::string value = card.substr(10);
    value = value.substr(0, value.find('/'));
    value.erase(0, value.find_first_not_of(' '));
    value.erase(value.find_last_not_of(' ') + 1);
    cards[name] = value;
  }
  return cards;
}

// Offset of the first data byte: the header block(s) after the END card.
size_t DataOffset(const std::string& bytes) {
  for (size_t at = 0; at + 80 <= bytes.size(); at += 80) {
    if (bytes.compare(at, 8, "END     ") == 0) return (at / 2880 + 1) * 2880;
  }
  return std::string::npos;
}

double BigEndianDouble(const std::string& bytes, size_t at) {
  std::uint64_t bits = 0;
  for (int i = 0; i < 8; ++i) bits = (bits << 8) | static_cast<unsigned char>(bytes[at + i]);
  double v;
  std::memcpy(&v, &bits, 8);
  return v;
}

std::string Card(const std::string& name, const std::string& value) {
  char card[81];
  std::snprintf(card, sizeof card, "%-8s= %20s%50s", name.c_str(), value.c_str(), "");
  return std::string(card, 80);
}

std::string Pad(std::string s, char fill) {
  s.resize((s.size() + 2879) / 2880 * 2880, fill);
  return s;
}

// A hand-made HDU: cards + END padded with blanks, then data padded with zeros.
std::string Hdu(const std::vector<std::string>& cards, const std::string& data) {
  std::string header;
  for (const std::string& c : cards) header += c;
  header += "END" + std::string(77, ' ');
  return Pad(header, ' ') + (data.empty() ? "" : Pad(data, '\0'));
}

std::string BigEndian16(const std::vector<std::int16_t>& values) {
  std::string out;
  for (std::int16_t v : values) {
    const auto u = static_cast<std::uint16_t>(v);
    out += static_cast<char>(u >> 8);
    out += static_cast<char>(u & 0xff);
  }
  return out;
}

// value(y, x) = 100 y + x + frac: row and column are readable from the value.
Image Coded(Index rows, Index cols, double plane = 0.0, double frac = 0.0) {
  Image img(rows, cols);
  for (Index y = 0; y < rows; ++y)
    for (Index x = 0; x < cols; ++x) img(y, x) = 1000.0 * plane + 100.0 * y + x + frac;
  return img;
}

TEST(FitsTest, Float64RoundTripIsExactAndNaxis1IsColumns) {
  TempDir dir;
  const std::string path = dir.File("img.fits");
  const Image img = Coded(5, 7, 0.0, 0.123456789);
  WriteFits(path, img, {}, FitsType::kFloat64);

  const std::string bytes = ReadBytes(path);
  const auto cards = RawHeader(bytes);
  EXPECT_EQ(cards.at("BITPIX"), "-64");
  EXPECT_EQ(cards.at("NAXIS"), "2");
  EXPECT_EQ(cards.at("NAXIS1"), "7");  // x, columns
  EXPECT_EQ(cards.at("NAXIS2"), "5");  // y, rows
  // The file's first values are FITS pixels (1,1), (2,1), ...: our row 0, x increasing. No flip.
  const size_t data = DataOffset(bytes);
  ASSERT_NE(data, std::string::npos);
  EXPECT_EQ(BigEndianDouble(bytes, data), img(0, 0));
  EXPECT_EQ(BigEndianDouble(bytes, data + 8), img(0, 1));
  EXPECT_EQ(BigEndianDouble(bytes, data + 8 * 7), img(1, 0));

  const Image back = ReadFitsImage(path);
  ASSERT_EQ(back.rows(), 5);
  ASSERT_EQ(back.cols(), 7);
  EXPECT_TRUE((back == img).all());
}

TEST(FitsTest, Float32RoundTripEqualsFloatRounding) {
  TempDir dir;
  const std::string path = dir.File("img32.fits");
  const Image img = Coded(5, 7, 0.0, 0.1);
  WriteFits(path, img);  // float32 by default
  EXPECT_EQ(RawHeader(ReadBytes(path)).at("BITPIX"), "-32");
  const Image back = ReadFitsImage(path);
  ASSERT_EQ(ShapeOf(back), ShapeOf(img));
  for (Index y = 0; y < 5; ++y)
    for (Index x = 0; x < 7; ++x) EXPECT_EQ(back(y, x), static_cast<double>(static_cast<float>(img(y, x))));
  EXPECT_NEAR(back(4, 6), 406.1, 1e-4);
}

TEST(FitsTest, CubeRoundTripKeepsPlaneOrder) {
  TempDir dir;
  for (FitsType type : {FitsType::kFloat32, FitsType::kFloat64}) {
    const std::string path = dir.File(type == FitsType::kFloat32 ? "c32.fits" : "c64.fits");
    const ImageStack planes = {Coded(5, 7, 0), Coded(5, 7, 1), Coded(5, 7, 2)};
    WriteFitsCube(path, planes, {}, type);
    const auto cards = RawHeader(ReadBytes(path));
    EXPECT_EQ(cards.at("NAXIS"), "3");
    EXPECT_EQ(cards.at("NAXIS1"), "7");
    EXPECT_EQ(cards.at("NAXIS2"), "5");
    EXPECT_EQ(cards.at("NAXIS3"), "3");
    const FitsData data = ReadFits(path);
    ASSERT_EQ(data.planes.size(), 3u);
    for (size_t p = 0; p < 3; ++p) EXPECT_TRUE((data.planes[p] == planes[p]).all()) << "plane " << p;
  }
}

TEST(FitsTest, CubeOfOnePlaneReadsAsAnImage) {
  TempDir dir;
  WriteFitsCube(dir.File("one.fits"), {Coded(2, 3)});
  EXPECT_EQ(RawHeader(ReadBytes(dir.File("one.fits"))).at("NAXIS"), "3");
  EXPECT_EQ(ReadFitsImage(dir.File("one.fits")).cols(), 3);  // NAXIS3 = 1 is a single image.
}

TEST(FitsTest, NanAndInfSurvive) {
  TempDir dir;
  Image img = Coded(3, 4);
  img(1, 2) = std::numeric_limits<double>::quiet_NaN();
  img(0, 3) = std::numeric_limits<double>::infinity();
  img(2, 0) = -std::numeric_limits<double>::infinity();
  for (FitsType type : {FitsType::kFloat32, FitsType::kFloat64}) {
    WriteFits(dir.File("nan.fits"), img, {}, type);
    const Image back = ReadFitsImage(dir.File("nan.fits"));
    EXPECT_TRUE(std::isnan(back(1, 2)));
    EXPECT_EQ(back(0, 3), img(0, 3));
    EXPECT_EQ(back(2, 0), img(2, 0));
    EXPECT_EQ(back(2, 3), img(2, 3));
  }
}

TEST(FitsTest, HeaderKeywordsOfEachTypeRoundTrip) {
  TempDir dir;
  const std::string long_text(150, 'x');
  FitsHeader h;
  h.Set("FLAG", true, "a logical");
  h.Set("OFF", false);
  h.Set("NFRAMES", 12, "an integer");
  h.Set("BIG", 9007199254740993LL);  // 2^53 + 1: not representable as a double
  h.Set("NEG", -7L);
  h.Set("PIXSCALE", 0.1, "arcsec");
  h.Set("TINY", 1.0e-300);
  h.Set("THIRD", 1.0 / 3.0);
  h.Set("WHOLE", 2.0);
  h.Set("OBJECT", "O'Brien's star", "a quote inside");
  h.Set("EMPTY", "");
  h.Set("LONGTEXT", long_text);
  h.Set("seeing", 0.8);              // stored upper-case
  h.Set("WAVELENGTH_NM", 1650.0);    // > 8 characters: HIERARCH
  h.Set("NFRAMES", 13, "replaced");  // replaces, keeps position
  WriteFits(dir.File("h.fits"), Coded(2, 2), h);

  const FitsHeader r = ReadFits(dir.File("h.fits")).header;
  EXPECT_TRUE(r.GetBool("FLAG"));
  EXPECT_FALSE(r.GetBool("OFF"));
  EXPECT_EQ(r.GetInt("NFRAMES"), 13);
  EXPECT_EQ(r.Find("NFRAMES")->comment, "replaced");
  EXPECT_EQ(r.GetInt("BIG"), 9007199254740993LL);
  EXPECT_EQ(r.GetInt("NEG"), -7);
  EXPECT_EQ(r.GetDouble("PIXSCALE"), 0.1);
  EXPECT_EQ(r.Find("PIXSCALE")->comment, "arcsec");
  EXPECT_EQ(r.GetDouble("TINY"), 1.0e-300);
  EXPECT_EQ(r.GetDouble("THIRD"), 1.0 / 3.0);
  EXPECT_TRUE(std::holds_alternative<double>(r.Find("WHOLE")->value));  // "2." stays a real
  EXPECT_EQ(r.GetDouble("WHOLE"), 2.0);
  EXPECT_EQ(r.GetString("OBJECT"), "O'Brien's star");
  EXPECT_EQ(r.GetString("EMPTY"), "");
  EXPECT_EQ(r.GetString("LONGTEXT"), long_text);
  EXPECT_EQ(r.GetDouble("SEEING"), 0.8);
  EXPECT_EQ(r.GetDouble("wavelength_nm"), 1650.0);
  EXPECT_EQ(r.GetDouble("NFRAMES"), 13.0);  // an integer is also a double

  // Order is kept, and no structural keyword leaks into the user header.
  std::vector<std::string> names;
  for (const FitsKeyword& k : r.keywords()) names.push_back(k.name);
  const std::vector<std::string> expected = {"FLAG",     "OFF",      "NFRAMES", "BIG",          "NEG",
                                             "PIXSCALE", "TINY",     "THIRD",   "WHOLE",        "OBJECT",
                                             "EMPTY",    "LONGTEXT", "SEEING",  "WAVELENGTH_NM"};
  EXPECT_EQ(names, expected);
}

TEST(FitsTest, ReadsIntegerDataWithScalingBlankAndAnExtension) {
  // Hand-made: empty primary HDU, then an IMAGE extension of 16-bit integers, 3 columns x 2 rows,
  // physical = BZERO + BSCALE * stored, and stored -32768 (BLANK) meaning "no data".
  TempDir dir;
  const std::string primary = Hdu({Card("SIMPLE", "T"), Card("BITPIX", "8"), Card("NAXIS", "0"),
                                   Card("EXTEND", "T"), Card("TELESCOP", "'SIM     '")},
                                  "");
  const std::string ext =
      Hdu({Card("XTENSION", "'IMAGE   '"), Card("BITPIX", "16"), Card("NAXIS", "2"), Card("NAXIS1", "3"),
           Card("NAXIS2", "2"), Card("PCOUNT", "0"), Card("GCOUNT", "1"), Card("BSCALE", "0.5"),
           Card("BZERO", "100.0"), Card("BLANK", "-32768"), Card("EXPTIME", "1.5D+01")},
          BigEndian16({0, 2, 4, -2, -32768, 10}));
  WriteBytes(dir.File("int16.fits"), primary + ext);

  const FitsData data = ReadFits(dir.File("int16.fits"));
  ASSERT_EQ(data.planes.size(), 1u);
  const Image& img = data.planes[0];
  ASSERT_EQ(img.rows(), 2);
  ASSERT_EQ(img.cols(), 3);
  EXPECT_EQ(img(0, 0), 100.0);
  EXPECT_EQ(img(0, 1), 101.0);
  EXPECT_EQ(img(0, 2), 102.0);
  EXPECT_EQ(img(1, 0), 99.0);
  EXPECT_TRUE(std::isnan(img(1, 1)));
  EXPECT_EQ(img(1, 2), 105.0);
  EXPECT_EQ(data.header.GetDouble("EXPTIME"), 15.0);  // Fortran 'D' exponent
  EXPECT_FALSE(data.header.Has("BSCALE"));
  EXPECT_FALSE(data.header.Has("PCOUNT"));
  EXPECT_FALSE(data.header.Has("XTENSION"));
}

TEST(FitsTest, WritesAtomicallyAndLeavesNoTemporaryFiles) {
  TempDir dir;
  WriteFits(dir.File("a.fits"), Coded(4, 4));
  WriteFits(dir.File("a.fits"), Coded(4, 5));  // replaces an existing file
  WriteFitsCube(dir.File("b.fits"), {Coded(2, 2), Coded(2, 2)});
  EXPECT_EQ(dir.List(), (std::vector<std::string>{"a.fits", "b.fits"}));
  EXPECT_EQ(ReadFitsImage(dir.File("a.fits")).cols(), 5);
}

TEST(FitsTest, PrimaryImageWithNamedExtensionsInOneFile) {
  TempDir dir;
  const std::string path = dir.File("rec.fits");
  FitsHeader h;
  h.Set("METHOD", "linear");
  FitsExtension psf{"PSF", {Coded(5, 5)}, {}, FitsType::kFloat64};
  psf.header.Set("COMMENTS", "effective PSF");
  FitsExtension corr{"NOISE_CORR", {Coded(3, 3), Coded(3, 3) * 2.0}, {}, FitsType::kFloat32};
  WriteFitsWithExtensions(path, Coded(4, 6), h, {psf, corr}, FitsType::kFloat64);
  EXPECT_EQ(dir.List(), std::vector<std::string>{"rec.fits"});  // one atomic write, no temporary left

  // ReadFits still reads the primary image, with its own header only.
  const FitsData primary = ReadFits(path);
  ASSERT_EQ(primary.planes.size(), 1u);
  EXPECT_TRUE((primary.planes[0] == Coded(4, 6)).all());
  EXPECT_EQ(primary.header.GetString("METHOD"), "linear");
  EXPECT_FALSE(primary.header.Has("EXTNAME"));

  EXPECT_EQ(FitsExtensionNames(path), (std::vector<std::string>{"PSF", "NOISE_CORR"}));
  const FitsData p = ReadFitsExtension(path, "psf");  // EXTNAME matches ignoring case
  ASSERT_EQ(p.planes.size(), 1u);
  EXPECT_TRUE((p.planes[0] == Coded(5, 5)).all());  // float64: exact
  EXPECT_EQ(p.header.GetString("EXTNAME"), "PSF");
  EXPECT_EQ(p.header.GetString("COMMENTS"), "effective PSF");
  const FitsData c = ReadFitsExtension(path, "NOISE_CORR");
  ASSERT_EQ(c.planes.size(), 2u);  // a cube extension
  EXPECT_TRUE((c.planes[1] == (Coded(3, 3) * 2.0).cast<float>().cast<double>()).all());

  // The layout by hand: the primary header says EXTEND, the first extension starts on a block boundary
  // after the primary's data with XTENSION = 'IMAGE'.
  const std::string bytes = ReadBytes(path);
  const std::size_t primary_end = 2880 + ((4 * 6 * 8 + 2879) / 2880) * 2880;
  ASSERT_GT(bytes.size(), primary_end + 80);
  EXPECT_EQ(bytes.substr(primary_end, 20), "XTENSION= 'IMAGE   '");

  // No extensions: the same file WriteFits writes.
  WriteFitsWithExtensions(dir.File("plain.fits"), Coded(4, 6), h, {}, FitsType::kFloat64);
  WriteFits(dir.File("ref.fits"), Coded(4, 6), h, FitsType::kFloat64);
  EXPECT_EQ(ReadBytes(dir.File("plain.fits")), ReadBytes(dir.File("ref.fits")));
  EXPECT_TRUE(FitsExtensionNames(dir.File("ref.fits")).empty());
}

TEST(FitsTest, PathsWithBracketsArePlainFileNames) {
  // cfitsio would parse "x[1].fits" as extended syntax; the diskfile calls must not.
  TempDir dir;
  const std::string path = dir.File("frame[1](a).fits");
  WriteFits(path, Coded(2, 3));
  EXPECT_TRUE((ReadFitsImage(path) == Coded(2, 3)).all());
}

TEST(FitsHeaderTest, SetNormalisesNamesAndRefusesStructuralOnes) {
  FitsHeader h;
  h.Set("gain", 2.5);
  EXPECT_TRUE(h.Has("GAIN"));
  EXPECT_TRUE(h.Has("Gain"));
  EXPECT_EQ(h.keywords().front().name, "GAIN");
  EXPECT_TRUE(FitsHeader::IsStructural("NAXIS2"));
  EXPECT_TRUE(FitsHeader::IsStructural("bitpix"));
  EXPECT_FALSE(FitsHeader::IsStructural("NAXISX"));
  EXPECT_THROW(h.Set("NAXIS1", 3), InvalidArgument);
  EXPECT_THROW(h.Set("BZERO", 0.0), InvalidArgument);
}


// FitsRowWriter: rows in any order (unwritten ones read 0), the header and extensions added at the end, the
// file in place only after Finish, bytes of the pixels as WriteFits writes them; without Finish, no file and no
// temporary is left.
TEST(FitsTest, RowWriterWritesRowsInAnyOrderAndAppearsOnlyWhenFinished) {
  TempDir dir;
  const std::string path = dir.File("rows.fits"), whole = dir.File("whole.fits");
  const Image img = Coded(9, 7, 0.0, 0.123456789);
  FitsHeader h;
  h.Set("METHOD", std::string("tikhonov"), "written at the end");
  for (int k = 0; k < 60; ++k) h.Set("KEY" + std::to_string(k), double(k), "a reconstruction's worth of keywords");
  FitsExtension e;
  e.name = "PSF";
  e.planes = {Coded(3, 3, 1.0, 0.5)};
  e.type = FitsType::kFloat64;
  {
    FitsRowWriter w(path, {9, 7}, FitsType::kFloat64);
    w.WriteRows(6, img.middleRows(6, 3));
    w.WriteRows(0, img.middleRows(0, 2));  // rows 2..5 never written
    EXPECT_FALSE(std::filesystem::exists(path)) << "not before Finish";
    w.Finish(h, {e});
  }
  const FitsData back = ReadFits(path);
  Image expected = img;
  expected.middleRows(2, 4).setZero();
  EXPECT_TRUE((back.planes.at(0) == expected).all());
  EXPECT_EQ(back.header.GetString("METHOD"), "tikhonov");
  EXPECT_EQ(back.header.GetDouble("KEY59"), 59.0);
  EXPECT_TRUE((ReadFitsExtension(path, "PSF").planes.at(0) == e.planes[0]).all());
  // Float32 rows: the same values as WriteFits writes.
  {
    FitsRowWriter w(path, {9, 7});
    for (Index y = 8; y >= 0; --y) w.WriteRows(y, img.middleRows(y, 1));
    w.Finish(h);
  }
  WriteFits(whole, img, h);
  EXPECT_TRUE((ReadFitsImage(path) == ReadFitsImage(whole)).all());
  // Abandoned (an error or a cancelled run): nothing new appears, the previous file stays, no temporary is left.
  {
    FitsRowWriter w(dir.File("gone.fits"), {9, 7});
    w.WriteRows(0, img.middleRows(0, 3));
  }
  EXPECT_FALSE(std::filesystem::exists(dir.File("gone.fits")));
  EXPECT_EQ(dir.List(), (std::vector<std::string>{"rows.fits", "whole.fits"}));
  EXPECT_THROW(FitsRowWriter(dir.File("no/such/folder.fits"), {9, 7}), IoError);
  FitsRowWriter w(dir.File("bad.fits"), {9, 7});
  EXPECT_THROW(w.WriteRows(8, img.middleRows(0, 2)), InvalidArgument);  // past the last row
}

// FitsCubeWriter: planes appended past the reserved count (the cube grows) or fewer (it is cut), the same values
// as WriteFitsCubeWithExtensions writes, header and extensions at the end, one plane as a 2-D image, the file only
// after Finish, and no file or temporary without it.
TEST(FitsTest, CubeWriterAppendsPlanesGrowsAndCutsAndAppearsOnlyWhenFinished) {
  TempDir dir;
  ImageStack planes;
  for (int k = 0; k < 5; ++k) planes.push_back(Coded(9, 7, 0.1 * k, 0.123456789));
  FitsHeader h;
  h.Set("METHOD", std::string("linear"), "written at the end");
  for (int k = 0; k < 60; ++k) h.Set("KEY" + std::to_string(k), double(k), "a movie's worth of keywords");
  FitsExtension times;
  times.name = "TIMES";
  times.planes = {Coded(5, 4, 2.0, 0.25)};
  times.type = FitsType::kFloat64;
  WriteFitsCubeWithExtensions(dir.File("whole.fits"), planes, h, {times});
  for (Index reserve : {0, 2, 5, 9}) {
    const std::string path = dir.File("cube" + std::to_string(reserve) + ".fits");
    {
      FitsCubeWriter w(path, {9, 7}, reserve);
      for (const Image& p : planes) w.Append(p);
      EXPECT_EQ(w.planes(), 5);
      EXPECT_FALSE(std::filesystem::exists(path)) << "not before Finish";
      w.Finish(h, {times});
    }
    const FitsData back = ReadFits(path), whole = ReadFits(dir.File("whole.fits"));
    ASSERT_EQ(back.planes.size(), 5u) << "reserve " << reserve;
    for (std::size_t k = 0; k < 5; ++k) EXPECT_TRUE((back.planes[k] == whole.planes[k]).all()) << k;
    EXPECT_EQ(back.header.GetString("METHOD"), "linear");
    EXPECT_EQ(back.header.GetDouble("KEY59"), 59.0);
    EXPECT_TRUE((ReadFitsExtension(path, "TIMES").planes.at(0) == times.planes[0]).all());
  }
  // One plane: a 2-D image (ReadFitsImage refuses cubes), in double precision when asked.
  {
    FitsCubeWriter w(dir.File("one.fits"), {9, 7}, 4, FitsType::kFloat64);
    w.Append(planes[3]);
    w.Finish({});
  }
  EXPECT_TRUE((ReadFitsImage(dir.File("one.fits")) == planes[3]).all());
  // Abandoned, refused planes, finishing twice or empty, a missing folder.
  {
    FitsCubeWriter w(dir.File("gone.fits"), {9, 7});
    w.Append(planes[0]);
    EXPECT_THROW(w.Append(Image::Zero(7, 9)), InvalidArgument);
    EXPECT_THROW(w.Append(Image::Constant(9, 7, 1e39)), InvalidArgument);  // beyond float32
  }
  EXPECT_FALSE(std::filesystem::exists(dir.File("gone.fits")));
  {
    FitsCubeWriter w(dir.File("empty.fits"), {9, 7});
    EXPECT_THROW(w.Finish({}), InvalidArgument);
  }
  {
    FitsCubeWriter w(dir.File("twice.fits"), {9, 7});
    w.Append(planes[0]);
    w.Finish({});
    EXPECT_THROW(w.Append(planes[1]), InvalidArgument);
    EXPECT_THROW(w.Finish({}), InvalidArgument);
  }
  EXPECT_THROW(FitsCubeWriter(dir.File("no/such/folder.fits"), {9, 7}), IoError);
  EXPECT_EQ(dir.List(), (std::vector<std::string>{"cube0.fits", "cube2.fits", "cube5.fits", "cube9.fits", "one.fits",
                                                  "twice.fits", "whole.fits"}));
}

}  // namespace
}  // namespace aosr
