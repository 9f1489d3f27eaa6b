// Bad input to VideoFileWriter (io/video_file.hpp): each option named, the image shape, a missing folder, a codec
// the build lacks, and writing after Close; none leaves a file behind.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "aosr/core/error.hpp"
#include "aosr/io/video_file.hpp"
#include "support/testing.hpp"
#include "temp_dir.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

using aosr::test::ErrorOf;
using ::testing::HasSubstr;
using testing_io::TempDir;

TEST(VideoFileErrorsTest, EachBadOptionIsNamed) {
  TempDir dir;
  const std::string path = dir.File("v.avi");
  struct Case {
    VideoFileOptions o;
    std::string field;
  };
  std::vector<Case> cases(5);
  cases[0].o.fps = 0;
  cases[0].field = "fps";
  cases[1].o.codec = "MJPEG";
  cases[1].field = "codec";
  cases[2].o.black = 1.0;  // = white
  cases[2].field = "black, white";
  cases[3].o.zoom = 17;
  cases[3].field = "zoom";
  cases[4].o.asinh_softening = 0;
  cases[4].field = "asinh_softening";
  for (const Case& c : cases) {
    std::string why;
    EXPECT_FALSE(c.o.IsValid(&why)) << c.field;
    EXPECT_THAT(why, HasSubstr(c.field));
    EXPECT_THAT(ErrorOf<InvalidArgument>([&] { VideoFileWriter w(path, {8, 8}, c.o); }), HasSubstr(c.field));
  }
  EXPECT_THAT(ErrorOf<InvalidArgument>([&] { VideoFileWriter w(path, {0, 8}); }), HasSubstr("image shape"));
  VideoFileOptions big;
  big.zoom = 16;
  EXPECT_THAT(ErrorOf<InvalidArgument>([&] { VideoFileWriter w(path, {600, 8}, big); }), HasSubstr("8192"));
  EXPECT_TRUE(dir.List().empty());
}

TEST(VideoFileErrorsTest, MissingFolderAndUnknownCodecNameThePath) {
  TempDir dir;
  const std::string nowhere = dir.File("no/such/folder/v.avi");
  EXPECT_THAT(ErrorOf<IoError>([&] { VideoFileWriter w(nowhere, {8, 8}); }), HasSubstr("folder does not exist"));
  VideoFileOptions o;
  o.codec = "ZZZZ";
  const std::string path = dir.File("v.avi");
  const std::string m = ErrorOf<IoError>([&] { VideoFileWriter w(path, {8, 8}, o); });
  EXPECT_THAT(m, HasSubstr(path));
  EXPECT_THAT(m, HasSubstr("ZZZZ"));
  EXPECT_TRUE(dir.List().empty());
}

TEST(VideoFileErrorsTest, WrongShapeAndWritingAfterClose) {
  TempDir dir;
  VideoFileWriter w(dir.File("v.avi"), {16, 16});
  EXPECT_THAT(ErrorOf<InvalidArgument>([&] { w.Write(Image::Zero(16, 8), "x"); }), HasSubstr("the video's shape"));
  w.Write(Image::Zero(16, 16), "x");
  w.Close();
  EXPECT_THAT(ErrorOf<InvalidArgument>([&] { w.Write(Image::Zero(16, 16), "x"); }), HasSubstr("closed"));
  w.Close();  // a second Close does nothing
  EXPECT_EQ(dir.List(), std::vector<std::string>{"v.avi"});
}

}  // namespace AOSR_TEST_NS
}  // namespace aosr
