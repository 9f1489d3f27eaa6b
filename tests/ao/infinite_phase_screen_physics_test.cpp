// The extruded (Assémat) screen keeps the von Kármán structure function after long extrusion, along and
// across the extrusion direction. Fixed seeds, printed on failure.
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <vector>

#include "aosr/ao/infinite_phase_screen.hpp"
#include "aosr/ao/von_karman.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

// Width 64, length 64, dx = 4 cm (2.56 m), r0 = 0.1 m, L0 = 10 m. After a burn-in of 10 window lengths
// (640 rows), 4 seeds x 80000 further rows are extruded; every new row contributes its across-row pairs
// and its pairs with the rows r behind it. The structure function must stay within 3% of the closed form
// from 1 pixel to a quarter of the width (16 px), along and across. Standard errors from 10 batches per seed
// (~0.3% at 16 px). A separate check at 32 px (half the width) uses 5%.
TEST(InfinitePhaseScreenPhysicsTest, StructureFunctionIsKeptAfterLongExtrusion) {
  InfinitePhaseScreenOptions o;
  o.width = 64;
  o.length = 64;
  o.pixel_scale_m = 0.04;
  o.r0_m = 0.1;
  o.L0_m = 10.0;
  const std::vector<Index> separations = {1, 2, 4, 8, 16, 32};
  const int kSeeds = 4, kBatches = 10, kRowsPerBatch = 8000;
  const std::uint64_t kFirstSeed = 4242;
  std::vector<std::vector<double>> across(separations.size()), along(separations.size());
  double extrude_ms = 0.0;
  for (int s = 0; s < kSeeds; ++s) {
    InfinitePhaseScreen screen(o, kFirstSeed + s);
    screen.Extrude(10 * o.length);
    for (int b = 0; b < kBatches; ++b) {
      std::vector<double> sa(separations.size(), 0.0), sl(separations.size(), 0.0);
      for (int t = 0; t < kRowsPerBatch; ++t) {
        const auto t0 = std::chrono::steady_clock::now();
        screen.Extrude(1);
        extrude_ms +=
            std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
        const Index last = o.length - 1;
        const double* row = screen.Row(last);
        for (std::size_t q = 0; q < separations.size(); ++q) {
          const Index r = separations[q];
          const double* behind = screen.Row(last - r);
          double a = 0.0, l = 0.0;
          for (Index k = 0; k + r < o.width; ++k) a += (row[k + r] - row[k]) * (row[k + r] - row[k]);
          for (Index k = 0; k < o.width; ++k) l += (row[k] - behind[k]) * (row[k] - behind[k]);
          sa[q] += a / static_cast<double>(o.width - r);
          sl[q] += l / static_cast<double>(o.width);
        }
      }
      for (std::size_t q = 0; q < separations.size(); ++q) {
        across[q].push_back(sa[q] / kRowsPerBatch);
        along[q].push_back(sl[q] / kRowsPerBatch);
      }
    }
  }
  std::printf("extrusion: %.4f ms per row (width 64, stencil %ld)\n",
              extrude_ms / (kSeeds * kBatches * kRowsPerBatch),
              static_cast<long>(InfinitePhaseScreen(o, 1).stencil_size()));
  auto summarise = [](const std::vector<double>& v, double* mean, double* se) {
    double m = 0.0, m2 = 0.0;
    for (double x : v) {
      m += x;
      m2 += x * x;
    }
    m /= v.size();
    m2 /= v.size();
    *mean = m;
    *se = std::sqrt(std::max(m2 - m * m, 0.0) / v.size());
  };
  for (std::size_t q = 0; q < separations.size(); ++q) {
    const double theory = VonKarmanStructureFunction(separations[q] * o.pixel_scale_m, o.r0_m, o.L0_m);
    double ma, sea, ml, sel;
    summarise(across[q], &ma, &sea);
    summarise(along[q], &ml, &sel);
    std::printf("  r = %2ld px: across %+.2f%% (se %.2f%%), along %+.2f%% (se %.2f%%)\n",
                static_cast<long>(separations[q]), 100 * (ma / theory - 1), 100 * sea / theory,
                100 * (ml / theory - 1), 100 * sel / theory);
    const double tol = separations[q] <= 16 ? 0.03 : 0.05;
    EXPECT_NEAR(ma / theory, 1.0, tol) << "across, r = " << separations[q] << ", seeds " << kFirstSeed << "+";
    EXPECT_NEAR(ml / theory, 1.0, tol) << "along, r = " << separations[q] << ", seeds " << kFirstSeed << "+";
  }
}

}  // namespace
}  // namespace aosr
