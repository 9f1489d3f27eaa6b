#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <limits>

#include "aosr/core/error.hpp"
#include "aosr/scene/objects.hpp"
#include "support/testing.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

using aosr::test::ErrorOf;

using ::testing::AllOf;
using ::testing::HasSubstr;


constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kInf = std::numeric_limits<double>::infinity();

TEST(ObjectsErrorsTest, EmptyShape) {
  EXPECT_THAT(ErrorOf([] { UsafTarget({0, 10}); }), AllOf(HasSubstr("UsafTarget"), HasSubstr("shape = 0x10")));
  EXPECT_THAT(ErrorOf([] { UsafBars({10, 0}, {}); }), AllOf(HasSubstr("UsafBars"), HasSubstr("shape")));
  EXPECT_THAT(ErrorOf([] { UsafElements({0, 0}, {}); }), AllOf(HasSubstr("UsafElements"), HasSubstr("shape")));
  EXPECT_THAT(ErrorOf([] { DemoObject({0, 128}); }), AllOf(HasSubstr("DemoObject"), HasSubstr("shape")));
  EXPECT_THAT(ErrorOf([] { DemoObject({63, 128}); }), AllOf(HasSubstr("DemoObject"), HasSubstr(">= 64")));
  Image empty;
  EXPECT_THAT(ErrorOf([&] { AddPointSources(&empty, {{0, 0, 1}}); }),
              AllOf(HasSubstr("AddPointSources"), HasSubstr("image")));
  EXPECT_THAT(ErrorOf([] { AddPointSources(nullptr, {}); }),
              AllOf(HasSubstr("AddPointSources"), HasSubstr("nullptr")));
}

TEST(ObjectsErrorsTest, GroupRange) {
  UsafOptions opts;
  opts.first_group = 1;
  opts.last_group = 0;
  EXPECT_THAT(ErrorOf([&] { UsafTarget({64, 64}, opts); }),
              AllOf(HasSubstr("UsafTarget"), HasSubstr("last_group = 0"), HasSubstr("first_group = 1")));
  EXPECT_THAT(ErrorOf([&] { UsafTargetSize(opts); }), HasSubstr("last_group"));
  opts.first_group = -11;
  EXPECT_THAT(ErrorOf([&] { UsafBars({64, 64}, opts); }), HasSubstr("first_group = -11"));
  EXPECT_THAT(ErrorOf([] { UsafFrequency(0, 7); }), AllOf(HasSubstr("UsafFrequency"), HasSubstr("element = 7")));
  EXPECT_THAT(ErrorOf([] { UsafFrequency(0, 0); }), HasSubstr("element = 0"));
  EXPECT_THAT(ErrorOf([] { UsafFrequency(13, 1); }), HasSubstr("group = 13"));
  std::string why;
  opts = UsafOptions{};
  opts.last_group = -3;
  EXPECT_FALSE(opts.IsValid(&why));
  EXPECT_THAT(why, HasSubstr("last_group"));
}

TEST(ObjectsErrorsTest, OtherOptions) {
  UsafOptions opts;
  opts.pixels_per_mm = 0.0;
  EXPECT_THAT(ErrorOf([&] { UsafTarget({64, 64}, opts); }),
              AllOf(HasSubstr("UsafTarget"), HasSubstr("pixels_per_mm = 0")));
  opts.pixels_per_mm = kInf;
  EXPECT_THAT(ErrorOf([&] { UsafTarget({64, 64}, opts); }), HasSubstr("pixels_per_mm"));
  opts = UsafOptions{};
  opts.bar_value = kNaN;
  EXPECT_THAT(ErrorOf([&] { UsafTarget({64, 64}, opts); }), HasSubstr("bar_value"));
  opts = UsafOptions{};
  opts.background = kInf;
  EXPECT_THAT(ErrorOf([&] { UsafTarget({64, 64}, opts); }), HasSubstr("background"));
  opts = UsafOptions{};
  opts.supersample = -1;
  EXPECT_THAT(ErrorOf([&] { UsafTarget({64, 64}, opts); }), HasSubstr("supersample = -1"));
}

TEST(ObjectsErrorsTest, PointSources) {
  Image img = Image::Zero(10, 12);
  const Image before = img;
  EXPECT_THAT(ErrorOf([&] { AddPointSources(&img, {{1, 1, 1}, {2, 2, kNaN}}); }),
              AllOf(HasSubstr("AddPointSources"), HasSubstr("sources[1].flux")));
  EXPECT_THAT(ErrorOf([&] { AddPointSources(&img, {{1, 1, kInf}}); }), HasSubstr("sources[0].flux"));
  EXPECT_THAT(ErrorOf([&] { AddPointSources(&img, {{9.5, 1, 1}}); }),
              AllOf(HasSubstr("sources[0].y = 9.5"), HasSubstr("[0, 9]")));
  EXPECT_THAT(ErrorOf([&] { AddPointSources(&img, {{1, -0.1, 1}}); }), HasSubstr("sources[0].x = -0.1"));
  EXPECT_THAT(ErrorOf([&] { AddPointSources(&img, {{kNaN, 1, 1}}); }), HasSubstr("sources[0].y"));
  // Validation happens before any flux is added.
  EXPECT_TRUE((img == before).all());
}

}  // namespace
}  // namespace aosr
