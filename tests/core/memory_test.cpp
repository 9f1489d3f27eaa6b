// Memory bounds (core/memory.hpp): sizes parse, format and are checked against the limit in force.
#include "aosr/core/memory.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cstdlib>
#include <limits>
#include <vector>

#include "aosr/core/error.hpp"
#include "support/testing.hpp"

namespace aosr {
namespace {

using ::testing::HasSubstr;

// Restores the process's limit (and the environment variable) after each test.
class MemoryTest : public ::testing::Test {
 protected:
  void SetUp() override {
    if (const char* e = std::getenv("AOSR_MEMORY_LIMIT")) saved_ = e, had_ = true;
    unsetenv("AOSR_MEMORY_LIMIT");
  }
  void TearDown() override {
    SetMemoryLimitBytes(0);
    if (had_) setenv("AOSR_MEMORY_LIMIT", saved_.c_str(), 1);
    else unsetenv("AOSR_MEMORY_LIMIT");
  }
  std::string saved_;
  bool had_ = false;
};

TEST_F(MemoryTest, ParsesSizesInPowersOf1024) {
  EXPECT_EQ(ParseByteSize("123", "x"), 123.0);
  EXPECT_EQ(ParseByteSize("4K", "x"), 4096.0);
  EXPECT_EQ(ParseByteSize("512M", "x"), 512.0 * 1024 * 1024);
  EXPECT_EQ(ParseByteSize("8G", "x"), 8.0 * 1024 * 1024 * 1024);
  EXPECT_EQ(ParseByteSize("8GiB", "x"), 8.0 * 1024 * 1024 * 1024);
  EXPECT_EQ(ParseByteSize("1.5t", "x"), 1.5 * 1024 * 1024 * 1024 * 1024);
}

TEST_F(MemoryTest, FormatsWithBinaryUnits) {
  EXPECT_EQ(FormatBytes(800), "800 B");
  EXPECT_EQ(FormatBytes(12 * 1024.0), "12 KiB");
  EXPECT_EQ(FormatBytes(1.5 * 1024 * 1024 * 1024), "1.5 GiB");
  EXPECT_EQ(FormatBytes(1e300), "8.67e+281 EiB");
}

TEST_F(MemoryTest, TheMachineLimitIsPositiveAndNamed) {
  const MemoryLimit m = CurrentMemoryLimit();
  EXPECT_GT(m.bytes, 64.0 * 1024 * 1024);
  EXPECT_FALSE(m.source.empty());
}

TEST_F(MemoryTest, SetLimitBeatsTheEnvironmentWhichBeatsTheMachine) {
  setenv("AOSR_MEMORY_LIMIT", "2G", 1);
  EXPECT_EQ(CurrentMemoryLimit().bytes, 2.0 * 1024 * 1024 * 1024);
  EXPECT_THAT(CurrentMemoryLimit().source, HasSubstr("AOSR_MEMORY_LIMIT=2G"));
  SetMemoryLimitBytes(1e6);
  EXPECT_EQ(CurrentMemoryLimit().bytes, 1e6);
  SetMemoryLimitBytes(0);
  EXPECT_EQ(CurrentMemoryLimit().bytes, 2.0 * 1024 * 1024 * 1024);
}

TEST_F(MemoryTest, CheckPassesWhatFitsAndRefusesWhatDoesNot) {
  SetMemoryLimitBytes(1024.0 * 1024 * 1024);
  EXPECT_NO_THROW(CheckMemory(1024.0 * 1024 * 1024, "exactly the limit"));
  const std::string msg = test::ErrorOf<ResourceError>([] { CheckMemory(3.0 * 1024 * 1024 * 1024 * 1024, "a cube of 1e6 planes"); });
  EXPECT_THAT(msg, HasSubstr("a cube of 1e6 planes needs about 3 TiB of memory"));
  EXPECT_THAT(msg, HasSubstr("the limit of 1 GiB"));
  EXPECT_THAT(msg, HasSubstr("AOSR_MEMORY_LIMIT"));
}

TEST_F(MemoryTest, NonFiniteEstimatesAreRefused) {
  EXPECT_THROW(CheckMemory(std::numeric_limits<double>::infinity(), "inf"), ResourceError);
  EXPECT_THROW(CheckMemory(std::numeric_limits<double>::quiet_NaN(), "nan"), ResourceError);
  EXPECT_THROW(CheckMemory(-1.0, "negative"), ResourceError);
}

TEST_F(MemoryTest, PeakResidentSizeGrowsWithWhatIsTouched) {
  const double before = PeakResidentBytes();
  EXPECT_GT(before, 0.0);
  std::vector<double> touched(64 * 1024 * 1024 / 8, 1.0);  // 64 MiB written
  EXPECT_GE(PeakResidentBytes(), before);
  EXPECT_GE(PeakResidentBytes(), 64.0 * 1024 * 1024);
  EXPECT_EQ(touched[12345], 1.0);
}

}  // namespace
}  // namespace aosr
