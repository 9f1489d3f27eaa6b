// Bad memory sizes get clear errors (core/memory.hpp).
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cstdlib>
#include <limits>

#include "aosr/core/error.hpp"
#include "aosr/core/memory.hpp"
#include "support/testing.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

using ::testing::HasSubstr;

TEST(MemoryErrorsTest, MalformedSizesNameTheirSource) {
  for (const char* bad : {"", "abc", "12Q", "-5G", "0", "nan", "1e400", "8GG"}) {
    const std::string msg = test::ErrorOf<InvalidArgument>([&] { ParseByteSize(bad, "--memory-limit"); });
    EXPECT_THAT(msg, HasSubstr("--memory-limit")) << bad;
    EXPECT_THAT(msg, HasSubstr("not a memory size")) << bad;
  }
}

TEST(MemoryErrorsTest, ABadEnvironmentVariableIsNamed) {
  setenv("AOSR_MEMORY_LIMIT", "lots", 1);
  const std::string msg = test::ErrorOf<InvalidArgument>([] { CurrentMemoryLimit(); });
  unsetenv("AOSR_MEMORY_LIMIT");
  EXPECT_THAT(msg, HasSubstr("AOSR_MEMORY_LIMIT"));
  EXPECT_THAT(msg, HasSubstr("\"lots\""));
}

TEST(MemoryErrorsTest, ANegativeOrInfiniteLimitIsRefused) {
  EXPECT_THROW(SetMemoryLimitBytes(-1), InvalidArgument);
  EXPECT_THROW(SetMemoryLimitBytes(std::numeric_limits<double>::infinity()), InvalidArgument);
}

}  // namespace
}  // namespace aosr
