#include "aosr/scene/star_metrics.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "aosr/scene/point_sources.hpp"
#include "support/testing.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

// A Gaussian blob of total flux f at (y, x), sigma s (HR px), plus a constant background.
void AddBlob(Image* img, double y, double x, double f, double s) {
  for (Index i = 0; i < img->rows(); ++i)
    for (Index j = 0; j < img->cols(); ++j)
      (*img)(i, j) += f / (2 * M_PI * s * s) * std::exp(-((i - y) * (i - y) + (j - x) * (j - x)) / (2 * s * s));
}

TEST(StarMetrics, IdenticalImagesHaveZeroErrors) {
  Image truth = Image::Constant(64, 64, 2.0);
  const std::vector<PointSource> cat = {{20.3, 30.6, 500.0}, {40.0, 15.2, 100.0}, {1.0, 1.0, 1e4}};
  for (const PointSource& s : cat) AddBlob(&truth, s.y, s.x, s.flux, 1.2);
  const StarMetrics m = MeasureStars(truth, truth, cat);
  ASSERT_EQ(m.stars.size(), 2u);
  EXPECT_EQ(m.skipped, 1);  // the star in the corner
  EXPECT_EQ(m.stars[0].truth.flux, 500.0);  // brightest measurable first
  EXPECT_EQ(m.median_abs_flux_error, 0.0);
  EXPECT_EQ(m.rms_position_error_px, 0.0);
}

TEST(StarMetrics, MeasuresFluxAndShiftErrors) {
  Image truth = Image::Constant(64, 64, 1.0), estimate = Image::Constant(64, 64, 3.0);  // backgrounds differ
  AddBlob(&truth, 30.0, 30.0, 1000.0, 1.0);
  AddBlob(&estimate, 30.25, 29.9, 900.0, 1.0);  // 10% faint, shifted by (+0.25, -0.1)
  const StarMetrics m = MeasureStars(truth, estimate, {{30.0, 30.0, 1000.0}});
  ASSERT_EQ(m.stars.size(), 1u);
  EXPECT_NEAR(m.stars[0].flux_error, -0.1, 2e-3);
  EXPECT_NEAR(m.stars[0].dy, 0.25, 0.02);
  EXPECT_NEAR(m.stars[0].dx, -0.1, 0.02);
}

TEST(StarMetrics, RejectsBadInput) {
  const Image a = Image::Zero(16, 16), b = Image::Zero(16, 17);
  EXPECT_THAT(test::ErrorOf([&] { MeasureStars(a, b, {}); }), ::testing::HasSubstr("estimate shape"));
  StarMetricsOptions o;
  o.annulus_inner_px = 2.0;
  EXPECT_THAT(test::ErrorOf([&] { MeasureStars(a, a, {}, o); }), ::testing::HasSubstr("annulus"));
}

}  // namespace
}  // namespace aosr
