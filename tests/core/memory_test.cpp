// Memory bounds (core/memory.hpp): sizes parse, format and are checked against the limit in force.
#include "aosr/core/memory.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <sys/resource.h>

#include <cstdlib>
#include <cstring>
#include <limits>
#include <vector>

#include "aosr/core/error.hpp"
#include "support/testing.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

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

// The allocator tuning keeps freed image-sized blocks for reuse: a loop that allocates, writes and frees three
// 8 MiB arrays (a 1024^2 image each, as the solvers' temporaries and Ceres's L-BFGS vectors do) page-faults
// them in once, not on every pass. glibc's defaults trim the heap's free top above twice the largest block
// freed so far (16 MiB here), so the 24 MiB freed each pass would be faulted in again: ~6000 faults a pass.
TEST_F(MemoryTest, TunedAllocatorReusesFreedImageSizedBlocks) {
#if defined(AOSR_TEST_ASAN) || defined(AOSR_TEST_TSAN)
  GTEST_SKIP() << "a sanitizer's allocator replaces glibc's";
#else
  const char* opt_out = std::getenv("AOSR_MALLOC_TUNING");
  const std::string saved = opt_out ? opt_out : "";
  setenv("AOSR_MALLOC_TUNING", "0", 1);
  EXPECT_FALSE(TuneAllocatorForLargeArrays()) << "AOSR_MALLOC_TUNING=0 leaves the settings alone";
  if (opt_out) setenv("AOSR_MALLOC_TUNING", saved.c_str(), 1);
  else unsetenv("AOSR_MALLOC_TUNING");
  if (!TuneAllocatorForLargeArrays()) GTEST_SKIP() << "not glibc, or malloc settings chosen in the environment";

  // 8 MiB (a 1024^2 image) and 40 MiB, above glibc's largest mmap threshold (a 2176^2 HR window's arrays are
  // 38 MiB): without M_MMAP_MAX = 0 every 40 MiB block was mapped and unmapped, ~10000 faults a block.
  for (const std::size_t bytes : {std::size_t(8) << 20, std::size_t(40) << 20}) {
    auto pass = [bytes] {
      void* blocks[3];
      for (void*& b : blocks) {
        b = std::malloc(bytes);
        ASSERT_NE(b, nullptr);
        std::memset(b, 1, bytes);
      }
      for (void* b : blocks) std::free(b);
    };
    pass();  // the first pass faults the blocks in
    auto faults = [] {
      rusage u{};
      getrusage(RUSAGE_SELF, &u);
      return u.ru_minflt;
    };
    const long before = faults();
    for (int i = 0; i < 20; ++i) pass();
    // 20 passes x 3 blocks = 60 x bytes / 4 KiB pages if each pass were faulted in again (120k at 8 MiB, 600k at
    // 40 MiB); reuse leaves a few dozen.
    EXPECT_LT(faults() - before, 1000) << (bytes >> 20) << " MiB blocks";
  }
#endif
}

}  // namespace
}  // namespace aosr
