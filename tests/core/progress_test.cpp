// The method side of the progress contract (core/progress.hpp): what is delivered, cancellation, exceptions.
// No test depends on wall time: an interval of 0 delivers everything, one of an hour only what is always
// delivered (the first and the last report).
#include "aosr/core/progress.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>
#include <vector>

#include "support/testing.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

using ::testing::HasSubstr;

constexpr double kHour = 3600.0;

TEST(ProgressReporterTest, EmptyCallbackIsInactiveAndNeverCancels) {
  ProgressReporter r(ProgressCallback(), "tv", 10, "cost");
  EXPECT_FALSE(r.active());
  EXPECT_TRUE(r.Start());
  for (int k = 1; k <= 10; ++k) EXPECT_TRUE(r.Report(k, 1.0, k == 10));
  r.Finish(10, 1.0);
  EXPECT_FALSE(r.cancelled());
  r.RethrowIfThrown();
}

TEST(ProgressReporterTest, ZeroIntervalDeliversEveryReportWithItsFields) {
  std::vector<Progress> seen;
  ProgressReporter r(
      [&](const Progress& p) {
        seen.push_back(p);
        return true;
      },
      "map", 5, "cost", 0.0);
  EXPECT_TRUE(r.active());
  EXPECT_TRUE(r.Start());
  for (int k = 1; k <= 3; ++k) EXPECT_TRUE(r.Report(k, 10.0 / k));
  r.Finish(3, 10.0 / 3);  // already delivered: not again
  ASSERT_EQ(seen.size(), 4u);
  EXPECT_EQ(seen[0].iteration, 0);
  EXPECT_TRUE(std::isnan(seen[0].value));
  for (int k = 1; k <= 3; ++k) {
    EXPECT_EQ(seen[k].stage, "map");
    EXPECT_EQ(seen[k].iteration, k);
    EXPECT_EQ(seen[k].total, 5);
    EXPECT_EQ(seen[k].value, 10.0 / k);
    EXPECT_EQ(seen[k].value_name, "cost");
    EXPECT_GE(seen[k].elapsed_seconds, seen[k - 1].elapsed_seconds);
  }
}

TEST(ProgressReporterTest, LongIntervalDeliversOnlyTheFirstAndTheLast) {
  std::vector<int> seen;
  ProgressReporter r(
      [&](const Progress& p) {
        seen.push_back(p.iteration);
        return true;
      },
      "tv", 100, "", kHour);
  for (int k = 1; k <= 100; ++k) r.Report(k, 0.0, k == 100);
  EXPECT_EQ(seen, (std::vector<int>{1, 100}));

  // A stage that ends early without knowing it: Finish delivers its last iteration, once.
  seen.clear();
  ProgressReporter early(
      [&](const Progress& p) {
        seen.push_back(p.iteration);
        return true;
      },
      "tv", 100, "", kHour);
  for (int k = 1; k <= 7; ++k) early.Report(k, 0.0);
  early.Finish(7, 0.0);
  early.Finish(7, 0.0);
  EXPECT_EQ(seen, (std::vector<int>{1, 7}));
}

TEST(ProgressReporterTest, FalseCancelsAndStaysCancelled) {
  int calls = 0;
  ProgressReporter r(
      [&](const Progress& p) {
        ++calls;
        return p.iteration < 2;
      },
      "tv", 0, "", 0.0);
  EXPECT_TRUE(r.Report(1, 0.0));
  EXPECT_FALSE(r.cancelled());
  EXPECT_FALSE(r.Report(2, 0.0));
  EXPECT_TRUE(r.cancelled());
  EXPECT_FALSE(r.Report(3, 0.0));  // not called again
  EXPECT_EQ(calls, 2);
  r.RethrowIfThrown();  // a cancellation is not an error
}

TEST(ProgressReporterTest, ACallbacksExceptionCancelsAndIsRethrownLater) {
  ProgressReporter r([](const Progress&) -> bool { throw std::runtime_error("interrupted by the user"); },
                     "map", 10, "cost", 0.0);
  EXPECT_FALSE(r.Report(1, 0.0));  // caught here, so it never crosses the solver
  EXPECT_TRUE(r.cancelled());
  EXPECT_THAT(test::ErrorOf<std::runtime_error>([&] { r.RethrowIfThrown(); }),
              HasSubstr("interrupted by the user"));
}

TEST(ProgressReporterTest, BadIntervalIsRefused) {
  EXPECT_THAT(
      test::ErrorOf([] { ProgressReporter r([](const Progress&) { return true; }, "tv", 1, "", -1.0); }),
      HasSubstr("min_interval_seconds"));
}

}  // namespace
}  // namespace aosr
