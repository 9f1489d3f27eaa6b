// Bad input to every public entry point of aosr::io gives a clear error naming what was wrong.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <filesystem>
#include <functional>
#include <limits>

#include "aosr/core/error.hpp"
#include "aosr/io/atomic_file.hpp"
#include "aosr/io/fits.hpp"
#include "aosr/io/image_io.hpp"
#include "aosr/io/wcs.hpp"
#include "temp_dir.hpp"
#include "support/testing.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

using aosr::test::ErrorOf;

using ::testing::HasSubstr;
using testing_io::ReadBytes;
using testing_io::TempDir;
using testing_io::WriteBytes;


Image Small() { return Image::Constant(3, 4, 1.5); }

TEST(FitsErrorsTest, MissingFileNamesThePath) {
  TempDir dir;
  const std::string path = dir.File("nowhere.fits");
  EXPECT_THAT(ErrorOf<IoError>([&] { ReadFits(path); }), HasSubstr(path));
  EXPECT_THAT(ErrorOf<IoError>([&] { ReadFitsImage(path); }), HasSubstr("no such file"));
  EXPECT_THAT(ErrorOf<IoError>([&] { ReadImage(dir.File("nowhere.png")); }), HasSubstr("nowhere.png"));
}

TEST(FitsErrorsTest, TextFileNamedFitsIsAnIoErrorWithPath) {
  TempDir dir;
  const std::string path = dir.File("bad.fits");
  WriteBytes(path, "this is not a FITS file\n");
  const std::string m = ErrorOf<IoError>([&] { ReadFits(path); });
  EXPECT_THAT(m, HasSubstr(path));
  EXPECT_THAT(m, HasSubstr("cfitsio"));
  EXPECT_THAT(ErrorOf<IoError>([&] { ReadImage(path); }), HasSubstr(path));
}

// Found by fuzz_calibration_set (a frame named /dev/zero hung the loader: the format probes read forever).
TEST(FitsErrorsTest, DevicesAreNotImageFiles) {
  EXPECT_THAT(ErrorOf<IoError>([] { ReadFits("/dev/zero"); }), HasSubstr("/dev/zero: is not a regular file"));
  EXPECT_THAT(ErrorOf<IoError>([] { ReadImage("/dev/zero"); }), HasSubstr("/dev/zero: is not a regular file"));
}

TEST(FitsErrorsTest, MessagesHoldNoStaleCfitsioText) {
  // cfitsio pushes an informational message for every HIERARCH keyword it writes.
  TempDir dir;
  FitsHeader h;
  h.Set("A_VERY_LONG_KEYWORD", 1);
  WriteFits(dir.File("h.fits"), Small(), h);
  WriteBytes(dir.File("bad.fits"), "not FITS");
  const std::string m = ErrorOf<IoError>([&] { ReadFits(dir.File("bad.fits")); });
  EXPECT_THAT(m, HasSubstr("bad.fits"));
  EXPECT_THAT(m, ::testing::Not(HasSubstr("A_VERY_LONG_KEYWORD")));
}

TEST(FitsErrorsTest, TruncatedFitsIsAnIoErrorWithPath) {
  TempDir dir;
  const std::string good = dir.File("good.fits");
  WriteFits(good, Image::Constant(40, 40, 2.0));  // 6400 data bytes: header block + 3 data blocks
  const std::string bytes = ReadBytes(good);
  ASSERT_EQ(bytes.size(), 4u * 2880u);
  // Header cut in the middle, and header intact but data cut short.
  for (size_t keep : {size_t{1000}, size_t{2880 + 100}}) {
    const std::string path = dir.File("cut" + std::to_string(keep) + ".fits");
    WriteBytes(path, bytes.substr(0, keep));
    EXPECT_THAT(ErrorOf<IoError>([&] { ReadFits(path); }), HasSubstr(path)) << keep;
  }
}

// A FITS header whose NAXISn would need more memory than the limit, or more data than the file holds, is
// refused before anything is allocated: the header is a few bytes, the request it makes is not.
std::string FitsHeaderOnly(long naxis1, long naxis2, long naxis3) {
  std::string h;
  auto card = [&h](const std::string& text) {
    std::string c = text;
    c.resize(80, ' ');
    h += c;
  };
  card("SIMPLE  =                    T");
  card("BITPIX  =                  -64");
  card(naxis3 > 0 ? "NAXIS   =                    3" : "NAXIS   =                    2");
  card("NAXIS1  = " + std::string(20 - std::to_string(naxis1).size(), ' ') + std::to_string(naxis1));
  card("NAXIS2  = " + std::string(20 - std::to_string(naxis2).size(), ' ') + std::to_string(naxis2));
  if (naxis3 > 0) card("NAXIS3  = " + std::string(20 - std::to_string(naxis3).size(), ' ') + std::to_string(naxis3));
  card("END");
  h.resize(2880, ' ');
  return h + std::string(2880, '\0');  // one block of data, far less than the header promises
}

TEST(FitsErrorsTest, AHeaderAskingForMoreMemoryThanTheLimitIsRefusedBeforeAllocating) {
  TempDir dir;
  const std::string path = dir.File("bomb.fits");
  WriteBytes(path, FitsHeaderOnly(100000, 100000, 1000));  // 8e13 bytes of float64
  const std::string msg = ErrorOf<ResourceError>([&] { ReadFits(path); });
  EXPECT_THAT(msg, HasSubstr(path));
  EXPECT_THAT(msg, HasSubstr("1000 plane(s) of 100000x100000 pixels needs about 72.8 TiB of memory"));
}

TEST(FitsErrorsTest, AHeaderPromisingMoreDataThanTheFileHoldsIsTruncated) {
  TempDir dir;
  const std::string path = dir.File("liar.fits");
  WriteBytes(path, FitsHeaderOnly(1000, 1000, 0));  // 8 MB promised, 2880 bytes present
  const std::string msg = ErrorOf<IoError>([&] { ReadFits(path); });
  EXPECT_THAT(msg, HasSubstr(path));
  EXPECT_THAT(msg, HasSubstr("truncated: its header promises 1 plane(s) of 1000x1000 pixels (BITPIX -64, 7.63 MiB of data)"));
}

// A section of a cube: the planes' block, and a clear error outside the image or for a missing file.
TEST(FitsErrorsTest, SectionsOutsideTheImageAreRefused) {
  TempDir dir;
  const std::string path = dir.File("cube.fits");
  ImageStack planes;
  for (int p = 0; p < 2; ++p) {
    Image a(8, 10);
    for (Index y = 0; y < 8; ++y)
      for (Index x = 0; x < 10; ++x) a(y, x) = 100.0 * p + 10.0 * double(y) + double(x);
    planes.push_back(a);
  }
  WriteFitsCube(path, planes, {}, FitsType::kFloat64);
  const FitsImageInfo info = ReadFitsInfo(path);
  EXPECT_EQ(info.planes, 2);
  EXPECT_EQ(info.rows, 8);
  EXPECT_EQ(info.cols, 10);
  const FitsData s = ReadFitsSection(path, 3, 4, 5, 6);
  ASSERT_EQ(s.planes.size(), 2u);
  for (int p = 0; p < 2; ++p) EXPECT_TRUE((s.planes[p] == planes[p].block(3, 4, 5, 6)).all()) << p;
  EXPECT_THROW(ReadFitsSection(path, 4, 0, 5, 10), InvalidArgument);  // past the last row
  EXPECT_THROW(ReadFitsSection(path, 0, 5, 8, 6), InvalidArgument);   // past the last column
  EXPECT_THROW(ReadFitsSection(path, -1, 0, 2, 2), InvalidArgument);
  EXPECT_THROW(ReadFitsSection(path, 0, 0, 0, 2), InvalidArgument);
  try {
    ReadFitsSection(dir.File("missing.fits"), 0, 0, 1, 1);
    ADD_FAILURE() << "a missing file was read";
  } catch (const IoError& e) {
    EXPECT_NE(std::string(e.what()).find("missing.fits"), std::string::npos) << e.what();
  }
  EXPECT_THROW(ReadFitsInfo(dir.File("missing.fits")), IoError);
}

TEST(FitsErrorsTest, ReadFitsImageOnACubeMentionsPlanes) {
  TempDir dir;
  const std::string path = dir.File("cube.fits");
  WriteFitsCube(path, {Small(), Small(), Small()});
  const std::string m = ErrorOf<IoError>([&] { ReadFitsImage(path); });
  EXPECT_THAT(m, HasSubstr(path));
  EXPECT_THAT(m, HasSubstr("3 planes of 3x4"));
}

TEST(FitsErrorsTest, NoImageDataOrOneDimensionalData) {
  TempDir dir;
  auto card = [](const std::string& k, const std::string& v) {
    std::string c = k;
    c.resize(8, ' ');
    c += "= " + std::string(20 - std::min<size_t>(20, v.size()), ' ') + v;
    c.resize(80, ' ');
    return c;
  };
  std::string empty = card("SIMPLE", "T") + card("BITPIX", "8") + card("NAXIS", "0") + "END";
  empty.resize(2880, ' ');
  WriteBytes(dir.File("empty.fits"), empty);
  EXPECT_THAT(ErrorOf<IoError>([&] { ReadFits(dir.File("empty.fits")); }), HasSubstr("no image data"));

  std::string line =
      card("SIMPLE", "T") + card("BITPIX", "-32") + card("NAXIS", "1") + card("NAXIS1", "4") + "END";
  line.resize(2880, ' ');
  line += std::string(2880, '\0');
  WriteBytes(dir.File("line.fits"), line);
  EXPECT_THAT(ErrorOf<IoError>([&] { ReadFits(dir.File("line.fits")); }), HasSubstr("NAXIS = 1"));
}

TEST(FitsErrorsTest, WriteFitsCubeRejectsMismatchedOrEmptyPlanes) {
  TempDir dir;
  const std::string path = dir.File("cube.fits");
  EXPECT_THAT(ErrorOf<InvalidArgument>([&] {
                WriteFitsCube(path, {Small(), Image::Zero(4, 3)});
              }),
              HasSubstr("plane 1 shape = 4x3"));
  EXPECT_THAT(ErrorOf<InvalidArgument>([&] { WriteFitsCube(path, {}); }), HasSubstr("planes"));
  EXPECT_THAT(ErrorOf<InvalidArgument>([&] { WriteFits(path, Image()); }), HasSubstr("0x0"));
  EXPECT_FALSE(std::filesystem::exists(path));
}

TEST(FitsErrorsTest, Float32OverflowIsRefusedNotTurnedIntoInf) {
  TempDir dir;
  Image img = Small();
  img(1, 1) = 1e39;
  EXPECT_THAT(ErrorOf<InvalidArgument>([&] { WriteFits(dir.File("big.fits"), img); }),
              HasSubstr("kFloat64"));
  WriteFits(dir.File("big.fits"), img, {}, FitsType::kFloat64);  // fine in float64
}

TEST(FitsErrorsTest, HeaderAccessNamesKeywordAndType) {
  FitsHeader h;
  h.Set("EXPTIME", 1.5);
  h.Set("OBJECT", "M31");
  EXPECT_THAT(ErrorOf<InvalidArgument>([&] { h.GetDouble("GAIN"); }), HasSubstr("GAIN"));
  EXPECT_THAT(ErrorOf<InvalidArgument>([&] { h.GetInt("EXPTIME"); }), HasSubstr("a real"));
  EXPECT_THAT(ErrorOf<InvalidArgument>([&] { h.GetDouble("OBJECT"); }), HasSubstr("a string"));
  EXPECT_THAT(ErrorOf<InvalidArgument>([&] { h.GetBool("OBJECT"); }), HasSubstr("OBJECT"));
  EXPECT_THAT(ErrorOf<InvalidArgument>([&] { h.GetString("EXPTIME"); }), HasSubstr("EXPTIME"));
  EXPECT_THAT(ErrorOf<InvalidArgument>([&] { h.Set("NAXIS3", 2); }), HasSubstr("NAXIS3"));
  EXPECT_THAT(ErrorOf<InvalidArgument>([&] { h.Set("A=B", 2); }), HasSubstr("A=B"));
  EXPECT_THAT(ErrorOf<InvalidArgument>([&] { h.Set("X", std::numeric_limits<double>::quiet_NaN()); }),
              HasSubstr("NaN"));
  EXPECT_THAT(ErrorOf<InvalidArgument>([&] { h.Set("X", "tab\there"); }), HasSubstr("printable ASCII"));
}

TEST(ImageIoErrorsTest, UnknownExtensionIsNamed) {
  TempDir dir;
  EXPECT_THAT(ErrorOf<InvalidArgument>([&] { WriteViewImage(dir.File("out.jpg"), Small()); }),
              HasSubstr("'.jpg'"));
  EXPECT_THAT(ErrorOf<InvalidArgument>([&] { WriteViewImage(dir.File("noext"), Small()); }),
              HasSubstr("file extension"));
  ViewOptions o;
  o.bits = 32;
  EXPECT_THAT(ErrorOf<InvalidArgument>([&] { WriteViewImage(dir.File("out.png"), Small(), o); }),
              HasSubstr("TIFF only"));
  o.bits = 8;
  o.high_percentile = 120;
  EXPECT_THAT(ErrorOf<InvalidArgument>([&] { ApplyStretch(Small(), o); }), HasSubstr("high_percentile"));
  EXPECT_TRUE(dir.List().empty());
}

TEST(ImageIoErrorsTest, CorruptImageFileNamesThePath) {
  TempDir dir;
  const std::string path = dir.File("bad.png");
  WriteBytes(path, "not a png");
  EXPECT_THAT(ErrorOf<IoError>([&] { ReadImage(path); }), HasSubstr(path));
}

TEST(ImageIoErrorsTest, MontageArguments) {
  EXPECT_THAT(ErrorOf<InvalidArgument>([] { Montage({}, 2, 0, 0.0); }), HasSubstr("tiles"));
  EXPECT_THAT(ErrorOf<InvalidArgument>([] { Montage({Image::Zero(2, 2)}, 0, 0, 0.0); }),
              HasSubstr("columns"));
  EXPECT_THAT(ErrorOf<InvalidArgument>([] { Montage({Image::Zero(2, 2)}, 1, -1, 0.0); }),
              HasSubstr("gap_px"));
  EXPECT_THAT(ErrorOf<InvalidArgument>([] {
                Montage({Image::Zero(2, 2), Image()}, 1, 0, 0.0);
              }),
              HasSubstr("tile 1"));
}

TEST(AtomicFileErrorsTest, WriteIntoMissingDirectoryNamesThePath) {
  TempDir dir;
  const std::string path = dir.File("missing/sub/out.fits");
  EXPECT_THAT(ErrorOf<IoError>([&] { WriteFits(path, Small()); }), HasSubstr(path));
  EXPECT_THAT(ErrorOf<IoError>([&] { WriteViewImage(dir.File("missing/out.png"), Small()); }),
              HasSubstr("does not exist"));
  EXPECT_TRUE(dir.List().empty());
}

TEST(AtomicFileErrorsTest, FailingWriterLeavesDestinationUntouchedAndNoTemporary) {
  TempDir dir;
  const std::string path = dir.File("result.txt");
  WriteBytes(path, "original");
  std::string seen_tmp;
  EXPECT_THAT(ErrorOf<std::runtime_error>([&] {
                AtomicWrite(path, [&](const std::string& tmp) {
                  seen_tmp = tmp;
                  WriteBytes(tmp, "half-written");
                  throw std::runtime_error("writer failed");
                });
              }),
              HasSubstr("writer failed"));
  EXPECT_THAT(seen_tmp, HasSubstr(path + ".tmp-"));
  EXPECT_EQ(ReadBytes(path), "original");
  EXPECT_EQ(dir.List(), std::vector<std::string>{"result.txt"});

  // A writer that creates nothing is an error too, and the destination survives.
  EXPECT_THAT(ErrorOf<IoError>([&] { AtomicWrite(path, [](const std::string&) {}); }),
              HasSubstr("did not create"));
  EXPECT_EQ(ReadBytes(path), "original");
}

TEST(AtomicFileErrorsTest, CheckNotSameFileSeesThroughRelativePaths) {
  TempDir dir;
  std::filesystem::create_directories(dir.path() / "sub");
  const std::string input = dir.File("in.fits");
  WriteBytes(input, "x");
  const std::string other_spelling = (dir.path() / "sub" / ".." / "." / "in.fits").string();
  EXPECT_THAT(ErrorOf<InvalidArgument>([&] {
                CheckNotSameFile(other_spelling, {dir.File("a.fits"), input});
              }),
              HasSubstr("never overwrites an input"));
  // A path relative to the current directory.
  const auto cwd = std::filesystem::current_path();
  std::filesystem::current_path(dir.path() / "sub");
  EXPECT_THROW(CheckNotSameFile("../in.fits", {input}), InvalidArgument);
  EXPECT_NO_THROW(CheckNotSameFile("in.fits", {input}));  // sub/in.fits is another file
  std::filesystem::current_path(cwd);
  // A symlink to the input is the input.
  std::filesystem::create_symlink(input, dir.File("link.fits"));
  EXPECT_THROW(CheckNotSameFile(dir.File("link.fits"), {input}), InvalidArgument);
  EXPECT_NO_THROW(CheckNotSameFile(dir.File("out.fits"), {input}));
}


// ---- FITS extensions -------------------------------------------------------------------------------------

TEST(FitsExtensionErrorsTest, BadExtensionsAreNamedAndNothingIsWritten) {
  TempDir dir;
  const std::string path = dir.File("x.fits");
  const FitsExtension good{"PSF", {Small()}, {}, FitsType::kFloat32};
  EXPECT_THAT(ErrorOf<InvalidArgument>([&] { WriteFitsWithExtensions(path, Small(), {}, {good, good}); }),
              HasSubstr("not used by another extension"));
  FitsExtension lower = good;
  lower.name = "psf";
  EXPECT_THAT(ErrorOf<InvalidArgument>([&] { WriteFitsWithExtensions(path, Small(), {}, {good, lower}); }),
              HasSubstr("ignoring case"));
  FitsExtension unnamed = good;
  unnamed.name = "";
  EXPECT_THAT(ErrorOf<InvalidArgument>([&] { WriteFitsWithExtensions(path, Small(), {}, {unnamed}); }),
              HasSubstr("extension 0 name"));
  FitsExtension empty{"NOISE_CORR", {}, {}, FitsType::kFloat32};
  EXPECT_THAT(ErrorOf<InvalidArgument>([&] { WriteFitsWithExtensions(path, Small(), {}, {empty}); }),
              HasSubstr("extension NOISE_CORR planes"));
  FitsExtension mixed{"NOISE_CORR", {Small(), Image::Zero(2, 2)}, {}, FitsType::kFloat32};
  EXPECT_THAT(ErrorOf<InvalidArgument>([&] { WriteFitsWithExtensions(path, Small(), {}, {mixed}); }),
              HasSubstr("extension NOISE_CORR plane 1 shape"));
  FitsExtension renamed = good;
  renamed.header.Set("EXTNAME", "OTHER");
  EXPECT_THAT(ErrorOf<InvalidArgument>([&] { WriteFitsWithExtensions(path, Small(), {}, {renamed}); }),
              HasSubstr("EXTNAME = OTHER"));
  FitsExtension huge{"BIG", {Image::Constant(2, 2, 1e300)}, {}, FitsType::kFloat32};
  EXPECT_THAT(ErrorOf<InvalidArgument>([&] { WriteFitsWithExtensions(path, Small(), {}, {huge}); }),
              HasSubstr("extension BIG pixel value"));
  EXPECT_TRUE(dir.List().empty());
}

TEST(FitsExtensionErrorsTest, AMissingExtensionNamesThePathAndWhatIsThere) {
  TempDir dir;
  const std::string path = dir.File("x.fits");
  WriteFitsWithExtensions(path, Small(), {}, {{"PSF", {Small()}, {}, FitsType::kFloat32}});
  const std::string m = ErrorOf<IoError>([&] { ReadFitsExtension(path, "NOISE_CORR"); });
  EXPECT_THAT(m, HasSubstr(path));
  EXPECT_THAT(m, HasSubstr("no extension named NOISE_CORR (its extensions: PSF)"));
  WriteFits(dir.File("plain.fits"), Small());
  EXPECT_THAT(ErrorOf<IoError>([&] { ReadFitsExtension(dir.File("plain.fits"), "PSF"); }), HasSubstr("extensions: none"));
  EXPECT_THAT(ErrorOf<IoError>([&] { ReadFitsExtension(dir.File("nowhere.fits"), "PSF"); }), HasSubstr("no such file"));
}

// ---- WCS ---------------------------------------------------------------------------------------------------

FitsHeader TanHeader() {
  FitsHeader h;
  h.Set("CTYPE1", "RA---TAN");
  h.Set("CTYPE2", "DEC--TAN");
  h.Set("CRPIX1", 10.0);
  h.Set("CRPIX2", 10.0);
  h.Set("CRVAL1", 150.0);
  h.Set("CRVAL2", 2.0);
  h.Set("CD1_1", -1e-5);
  h.Set("CD2_2", 1e-5);
  return h;
}

std::string WcsError(const std::function<void(FitsHeader&)>& edit) {
  FitsHeader h = TanHeader();
  edit(h);
  return ErrorOf<InvalidArgument>([&] { WcsFromHeader(h); });
}

TEST(WcsErrorsTest, UnsupportedProjectionsAndDistortionsAreRefusedByName) {
  EXPECT_NO_THROW(WcsFromHeader(TanHeader()));
  EXPECT_THAT(WcsError([](FitsHeader& h) { h.Set("CTYPE1", "RA---SIN"); }),
              HasSubstr("CTYPE1 = 'RA---SIN'; allowed: 'RA---TAN': only the gnomonic TAN projection is supported, not SIN"));
  EXPECT_THAT(WcsError([](FitsHeader& h) { h.Set("CTYPE2", "DEC--TAN-SIP"); }),
              HasSubstr("-SIP is not supported"));
  EXPECT_THAT(WcsError([](FitsHeader& h) { h.Set("A_ORDER", 3); }), HasSubstr("SIP is not supported"));
  EXPECT_THAT(WcsError([](FitsHeader& h) { h.Set("PV2_1", 0.1); }), HasSubstr("TPV distortion"));
  EXPECT_THAT(WcsError([](FitsHeader& h) { h.Set("CPDIS1", "LOOKUP"); }), HasSubstr("distortion tables"));
  EXPECT_THAT(WcsError([](FitsHeader& h) { h.Set("CTYPE1", "GLON-TAN"); }), HasSubstr("CTYPE1 = 'GLON-TAN'"));
  EXPECT_THAT(WcsError([](FitsHeader& h) { h.Set("CTYPE1", "DEC--TAN"); }), HasSubstr("in this order"));
  EXPECT_THAT(WcsError([](FitsHeader& h) { h.Set("CUNIT1", "rad"); }), HasSubstr("CUNIT1 = 'RAD'"));
  EXPECT_THAT(WcsError([](FitsHeader& h) { h.Set("LONPOLE", 0.0); }), HasSubstr("LONPOLE"));
}

TEST(WcsErrorsTest, MissingAndInconsistentKeywordsAreNamed) {
  EXPECT_THAT(ErrorOf<InvalidArgument>([] { WcsFromHeader(FitsHeader{}); }), HasSubstr("CTYPE1 = (missing)"));
  EXPECT_THAT(WcsError([](FitsHeader& h) { h.Set("CRPIX2", "ten"); }), HasSubstr("CRPIX2 = 'ten'; allowed: a real"));
  EXPECT_THAT(WcsError([](FitsHeader& h) { h.Set("CRVAL2", 95.0); }), HasSubstr("CRVAL2 = 95"));
  EXPECT_THAT(WcsError([](FitsHeader& h) { h.Set("PC1_1", 1.0); }), HasSubstr("either a CDi_j matrix or PCi_j"));
  EXPECT_THAT(WcsError([](FitsHeader& h) { h.Set("CD2_2", 0.0); }), HasSubstr("invertible"));
  FitsHeader pc;
  const FitsHeader tan = TanHeader();
  for (const FitsKeyword& k : tan.keywords())
    if (k.name.rfind("CD", 0) != 0) pc.Set(k.name, k.value);
  pc.Set("PC1_1", 1.0);
  EXPECT_THAT(ErrorOf<InvalidArgument>([&] { WcsFromHeader(pc); }), HasSubstr("CDELT1 = (missing)"));
  pc.Set("CDELT1", -1e-5);
  pc.Set("CDELT2", 1e-5);
  EXPECT_NO_THROW(WcsFromHeader(pc));
  pc.Set("CROTA2", 10.0);
  EXPECT_THAT(ErrorOf<InvalidArgument>([&] { WcsFromHeader(pc); }), HasSubstr("either PCi_j or CROTA2"));
}

TEST(WcsErrorsTest, EntryPointsNameTheirArguments) {
  const Wcs w = WcsFromHeader(TanHeader());
  EXPECT_THAT(ErrorOf<InvalidArgument>([&] { SkyToPixel(w, {330.0, -2.0}); }), HasSubstr("less than 90 deg"));
  EXPECT_THAT(ErrorOf<InvalidArgument>([&] { SkyToPixel(w, {150.0, 91.0}); }), HasSubstr("sky.dec_deg = 91"));
  EXPECT_THAT(ErrorOf<InvalidArgument>([&] { PixelToSky(w, {std::nan(""), 0}); }), HasSubstr("PixelToSky: invalid pixel"));
  EXPECT_THAT(ErrorOf<InvalidArgument>([] { TangentPlaneWcs(0, 0, 0.0, 0, {0, 0}); }), HasSubstr("pixel_rad = 0"));
  EXPECT_THAT(ErrorOf<InvalidArgument>([] { TangentPlaneWcs(0, -91, 1e-8, 0, {0, 0}); }), HasSubstr("dec_deg = -91"));
  EXPECT_THAT(ErrorOf<InvalidArgument>([&] { HrWcs(w, 0); }), HasSubstr("HrWcs: invalid r = 0"));
  Wcs singular = w;
  singular.cd[0][0] = singular.cd[1][1] = 0;
  FitsHeader h;
  EXPECT_THAT(ErrorOf<InvalidArgument>([&] { WriteWcs(singular, &h); }), HasSubstr("WriteWcs: invalid CD matrix determinant"));
  h.Set("CDELT1", 1.0);
  EXPECT_THAT(ErrorOf<InvalidArgument>([&] { WriteWcs(w, &h); }), HasSubstr("CDELT1 present"));
}

}  // namespace
}  // namespace aosr
