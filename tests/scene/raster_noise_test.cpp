#include <gtest/gtest.h>

#include <cmath>
#include <set>

#include "aosr/scene/noise.hpp"
#include "aosr/scene/raster.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

TEST(RasterTest, CompleteRasterVisitsEveryHrPhaseOnceAndIsCentred) {
  for (int r : {2, 3, 4}) {
    const auto o = ClassicRaster(r * r, r);
    ASSERT_EQ(o.size(), std::size_t(r * r));
    std::set<std::pair<long, long>> phases;
    double my = 0, mx = 0;
    for (const auto& f : o) {
      // Relative to the first frame, each offset is a whole number of HR pixels in 0..r-1.
      const double dy = f.dy - o[0].dy, dx = f.dx - o[0].dx;
      EXPECT_NEAR(dy, std::round(dy), 1e-12);
      phases.insert({std::lround(dy) % r, std::lround(dx) % r});
      my += f.dy;
      mx += f.dx;
    }
    EXPECT_EQ(phases.size(), std::size_t(r * r)) << "r = " << r;
    EXPECT_NEAR(my, 0, 1e-12);
    EXPECT_NEAR(mx, 0, 1e-12);
  }
}

TEST(RasterTest, TwoFramesAreTheDiagonalHalfPixelPair) {
  const auto o = ClassicRaster(2, 4);
  EXPECT_DOUBLE_EQ(o[1].dy - o[0].dy, 2.0);
  EXPECT_DOUBLE_EQ(o[1].dx - o[0].dx, 2.0);
}

TEST(NoiseTest, GaussianNoiseHasTheStatedSigmaAndIsReproducible) {
  const double sigma = 0.37;
  const std::uint64_t seed = 12345;
  ImageStack a(1, Image::Zero(1000, 1000)), b = a;
  AddGaussianNoise(&a, sigma, seed);
  AddGaussianNoise(&b, sigma, seed);
  EXPECT_TRUE((a[0] == b[0]).all()) << "seed " << seed;
  const double mean = a[0].mean();
  const double var = (a[0] - mean).square().mean();
  // 1e6 samples: the standard error of the variance is sqrt(2/1e6) = 0.14% relative.
  EXPECT_NEAR(std::sqrt(var) / sigma, 1.0, 0.005) << "seed " << seed;
  EXPECT_NEAR(mean, 0.0, 5 * sigma / 1000) << "seed " << seed;
  EXPECT_DOUBLE_EQ(NoiseSigmaFromPeakFraction({Image::Constant(2, 2, 4.0)}, 0.01), 0.04);
}

}  // namespace
}  // namespace aosr
