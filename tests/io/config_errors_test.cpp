#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "aosr/core/error.hpp"
#include "aosr/io/config.hpp"
#include "support/testing.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

using aosr::test::ErrorOf;

using ::testing::AllOf;
using ::testing::HasSubstr;


TEST(ConfigErrorsTest, MessagesNameTheFileAndTheFullFieldPath) {
  const auto j = nlohmann::json::parse(R"({"a": {"layers": [{"x": 1}, {"x": -2}]}, "s": "k", "b": true})");
  const ConfigNode root(j, "f.json");
  const auto layers = root.Child("a").Array("layers");
  EXPECT_DOUBLE_EQ(layers[0].Number("x", 0, 1), 1.0);
  EXPECT_THAT(ErrorOf([&] { layers[1].Number("x", 0, 1); }), HasSubstr("f.json: a.layers[1].x = -2"));
  EXPECT_THAT(ErrorOf([&] { root.Positive("missing"); }), HasSubstr("missing = (missing)"));
  EXPECT_THAT(ErrorOf([&] { root.Choice("s", {"p", "q"}); }), HasSubstr("one of p, q"));
  EXPECT_THAT(ErrorOf([&] { root.Integer("b", 0, 2); }), HasSubstr("an integer"));
}

TEST(ConfigErrorsTest, UnknownFieldsAreErrorsButCommentsAreNot) {
  const auto j = nlohmann::json::parse(R"({"diameter_m": 8, "diamter_m": 8, "comment": "x"})");
  const ConfigNode root(j, "t.json");
  root.Positive("diameter_m");
  EXPECT_THAT(ErrorOf([&] { root.CheckNoOtherFields(); }), HasSubstr("diamter_m = (unknown field)"));
}

TEST(ConfigErrorsTest, MissingAndMalformedFiles) {
  EXPECT_THAT(ErrorOf<Error>([] { ReadJsonFile("/nonexistent/x.json"); }), HasSubstr("/nonexistent/x.json"));
  const std::string path = testing::TempDir() + "/aosr_bad.json";
  FILE* f = fopen(path.c_str(), "w");
  fputs("{\"a\": 1,,}", f);
  fclose(f);
  EXPECT_THAT(ErrorOf<Error>([&] { ReadJsonFile(path); }), HasSubstr("malformed JSON"));
  std::remove(path.c_str());
}

// Found by fuzz_design (fuzz/regressions/design/number-overflow.json): nlohmann's parser throws out_of_range,
// not parse_error, for a number beyond double's range; it escaped every JSON loader as a non-aosr exception.
TEST(ConfigErrorsTest, NumberBeyondDoubleRangeIsMalformedJson) {
  const std::string path = testing::TempDir() + "/aosr_overflow.json";
  FILE* f = fopen(path.c_str(), "w");
  fputs("{\"frames\": [{\"shift_px\": [1e937, 0]}]}", f);
  fclose(f);
  EXPECT_THAT(ErrorOf<InvalidArgument>([&] { ReadJsonFile(path); }),
              AllOf(HasSubstr(path), HasSubstr("malformed JSON"), HasSubstr("number overflow")));
  std::remove(path.c_str());
}

// Found by fuzz_calibration_set (a frame named /dev/zero hung the loader): a device never ends, so reading one
// as a config would fill the memory.
TEST(ConfigErrorsTest, DevicesAreNotConfigFiles) {
  EXPECT_THAT(ErrorOf<IoError>([] { ReadJsonFile("/dev/zero"); }),
              AllOf(HasSubstr("/dev/zero"), HasSubstr("not a regular file")));
}

}  // namespace
}  // namespace aosr
