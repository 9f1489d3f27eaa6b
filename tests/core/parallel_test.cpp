#include "aosr/core/parallel.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <atomic>
#include <stdexcept>
#include <vector>

#include "aosr/core/error.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

TEST(ParallelForTest, CallsEveryIndexExactlyOnce) {
  for (int threads : {1, 2, 3, 8})
    for (Index count : {0, 1, 2, 7, 1000}) {
      std::vector<std::atomic<int>> hits(count);
      ParallelFor(count, threads, [&](Index k) { hits[k].fetch_add(1); });
      for (Index k = 0; k < count; ++k) EXPECT_EQ(hits[k].load(), 1) << threads << " threads, k " << k;
    }
}

TEST(ParallelForTest, NestedLoopsRunAndCoverEverything) {
  std::vector<std::atomic<int>> hits(40 * 30);
  ParallelFor(40, 2, [&](Index i) { ParallelFor(30, 2, [&](Index j) { hits[i * 30 + j].fetch_add(1); }); });
  for (auto& h : hits) EXPECT_EQ(h.load(), 1);
}

TEST(ParallelForTest, RethrowsTheTasksException) {
  EXPECT_THROW(ParallelFor(100, 2, [](Index k) {
                 if (k == 37) throw std::runtime_error("task 37");
               }),
               std::runtime_error);
  // The pool is usable afterwards.
  std::atomic<Index> sum{0};
  ParallelFor(10, 2, [&](Index k) { sum += k; });
  EXPECT_EQ(sum.load(), 45);
}

TEST(ParallelForErrorsTest, BadArgumentsAreNamed) {
  EXPECT_THAT([] { ParallelFor(3, 0, [](Index) {}); },
              testing::ThrowsMessage<InvalidArgument>(testing::HasSubstr("threads")));
  EXPECT_THAT([] { SetDefaultThreads(0); }, testing::ThrowsMessage<InvalidArgument>(testing::HasSubstr("threads")));
}

}  // namespace
}  // namespace aosr
