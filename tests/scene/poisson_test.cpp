#include "aosr/scene/poisson.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <map>

namespace aosr {
namespace AOSR_TEST_NS {

TEST(PoissonTest, LogPmfMatchesLgammaEverywhere) {
  for (double mean : {0.5, 9.99, 10.0, 123.4, 1e4, 1e8}) {
    const double s = std::sqrt(mean);
    for (double k : {0.0, 1.0, 2.0, 5.0, 31.0, 32.0, 33.0, std::floor(mean), std::floor(mean + 3 * s),
                     std::floor(mean + 10 * s + 40)}) {
      const double direct = k * std::log(mean) - mean - std::lgamma(k + 1);
      // The direct form loses ~mean·1e-16 to cancellation; ours does not, so compare to that accuracy.
      EXPECT_NEAR(PoissonLogPmf(k, mean), direct, 1e-12 * (1 + mean + std::fabs(direct)))
          << "k = " << k << ", mean = " << mean;
    }
  }
}

TEST(PoissonTest, ZeroMeanDrawsNothingAndSeedsReproduce) {
  PoissonGenerator a(7), b(7), c(8);
  EXPECT_EQ(a.Next(0.0), 0.0);
  EXPECT_EQ(a.uniform_draws(), 0);
  bool differs = false;
  for (double mean : {0.2, 3.0, 12.0, 5000.0, 0.2, 77.0}) {
    const double x = a.Next(mean), y = b.Next(mean), z = c.Next(mean);
    EXPECT_EQ(x, y);
    EXPECT_EQ(x, std::floor(x));
    EXPECT_GE(x, 0);
    differs |= x != z;
  }
  EXPECT_TRUE(differs);
  EXPECT_EQ(a.uniform_draws(), b.uniform_draws());
  for (int i = 0; i < 1000; ++i) {
    const double u = a.Uniform();
    EXPECT_GT(u, 0.0);
    EXPECT_LT(u, 1.0);
  }
}

// Pearson χ² of 2e5 deviates against the exact pmf, bins pooled so each expects >= 10, on both sides of the
// inversion/PTRS switch at 10. Fixed seeds; the bound is dof + 5·sqrt(2·dof) (a ~4σ event for a true fit).
TEST(PoissonTest, DeviatesFollowThePmf) {
  const int n = 200000;
  std::uint64_t seed = 1000;
  for (double mean : {0.05, 0.7, 3.7, 9.999, 10.0, 10.5, 31.3, 470.0, 1e5}) {
    PoissonGenerator g(++seed);
    std::map<long, long> counts;
    double sum = 0;
    for (int i = 0; i < n; ++i) {
      const double k = g.Next(mean);
      ++counts[static_cast<long>(k)];
      sum += k;
    }
    // Bins: [0 or lo .. hi] over ±8σ, pooled greedily until each expects >= 10; tails folded into the ends.
    const double s = std::sqrt(mean);
    const long lo = std::max(0L, static_cast<long>(std::floor(mean - 8 * s - 2)));
    const long hi = static_cast<long>(std::ceil(mean + 8 * s + 8));
    double chi2 = 0;
    int bins = 0;
    double expected = 0, observed = 0;
    auto flush = [&] {
      chi2 += (observed - expected) * (observed - expected) / expected;
      ++bins;
      expected = observed = 0;
    };
    for (long k = lo; k <= hi; ++k) {
      double p = std::exp(PoissonLogPmf(double(k), mean));
      double o = counts.count(k) ? double(counts[k]) : 0.0;
      if (k == lo) {  // fold the left tail
        for (const auto& [kk, c] : counts)
          if (kk < lo) o += c;
        for (long j = 0; j < lo; ++j) p += std::exp(PoissonLogPmf(double(j), mean));
      }
      if (k == hi) {  // fold the right tail
        for (const auto& [kk, c] : counts)
          if (kk > hi) o += c;
        double tail = 0;
        for (long j = hi + 1; j < hi + 20 * (s + 1); ++j) tail += std::exp(PoissonLogPmf(double(j), mean));
        p += tail;
      }
      expected += n * p;
      observed += o;
      if (expected >= 10) flush();
    }
    if (expected > 0) flush();
    const int dof = bins - 1;
    EXPECT_LT(chi2, dof + 5 * std::sqrt(2.0 * std::max(dof, 1))) << "mean " << mean << ", bins " << bins;
    EXPECT_NEAR(sum / n, mean, 5 * std::sqrt(mean / n)) << "mean " << mean;
  }
}

}  // namespace
}  // namespace aosr
