#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>

#include "aosr/core/error.hpp"
#include "aosr/core/psf_field.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

using ::testing::HasSubstr;

TEST(PsfFieldGridErrorsTest, BadGridsAndArgumentsAreNamed) {
  EXPECT_THAT([] { PsfFieldGrid({16, 16}, 0, 3); }, ::testing::ThrowsMessage<InvalidArgument>(HasSubstr("grid")));
  EXPECT_THAT([] { PsfFieldGrid({16, 16}, 3, 65); }, ::testing::ThrowsMessage<InvalidArgument>(HasSubstr("1..64")));
  EXPECT_THAT([] { PsfFieldGrid({1, 16}, 2, 2); }, ::testing::ThrowsMessage<InvalidArgument>(HasSubstr("one node")));
  const PsfFieldGrid g({16, 16}, 2, 2);
  EXPECT_THAT([&] { g.Node(4); }, ::testing::ThrowsMessage<InvalidArgument>(HasSubstr("0..3")));
  EXPECT_THAT([&] { g.Weights(NAN, 0); }, ::testing::ThrowsMessage<InvalidArgument>(HasSubstr("finite")));
  EXPECT_THAT([&] { g.Interpolate({Image::Ones(4, 4)}, 0, 0); },
              ::testing::ThrowsMessage<InvalidArgument>(HasSubstr("one per node")));
  EXPECT_THAT([&] { g.Interpolate({Image::Ones(4, 4), Image::Ones(4, 4), Image::Ones(4, 4), Image::Ones(2, 2)}, 0, 0); },
              ::testing::ThrowsMessage<InvalidArgument>(HasSubstr("one shape")));
  EXPECT_THAT([] { PsfFieldGrid().Weights(0, 0); }, ::testing::ThrowsMessage<InvalidArgument>(HasSubstr("empty")));
}

}  // namespace AOSR_TEST_NS
}  // namespace aosr
