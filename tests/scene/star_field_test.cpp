#include "aosr/scene/star_field.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

namespace aosr {
namespace AOSR_TEST_NS {

TEST(StarFieldTest, DeterministicPerSeedAndInTheField) {
  const Shape hr{100, 150};
  StarFieldOptions options;
  options.count = 500;
  const std::vector<PointSource> a = StarField(hr, options, 11), b = StarField(hr, options, 11);
  const std::vector<PointSource> c = StarField(hr, options, 12);
  ASSERT_EQ(a.size(), 500u);
  ASSERT_EQ(c.size(), 500u);
  int differing = 0;
  for (std::size_t k = 0; k < a.size(); ++k) {
    EXPECT_EQ(a[k].y, b[k].y);
    EXPECT_EQ(a[k].x, b[k].x);
    EXPECT_EQ(a[k].flux, b[k].flux);
    if (a[k].y != c[k].y) ++differing;
    EXPECT_GE(a[k].y, -0.5);
    EXPECT_LT(a[k].y, hr.rows - 0.5);
    EXPECT_GE(a[k].x, -0.5);
    EXPECT_LT(a[k].x, hr.cols - 0.5);
    EXPECT_GE(a[k].flux, options.luminosity.flux_min);
    EXPECT_LE(a[k].flux, options.luminosity.flux_max);
  }
  EXPECT_EQ(differing, 500);
}

TEST(StarFieldTest, MarginIsRespected) {
  StarFieldOptions options;
  options.count = 300;
  options.margin_px = 10.0;
  for (const PointSource& s : StarField({64, 64}, options, 5)) {
    EXPECT_GE(s.y, 9.5);
    EXPECT_LT(s.y, 53.5);
    EXPECT_GE(s.x, 9.5);
    EXPECT_LT(s.x, 53.5);
  }
}

TEST(StarFieldTest, MinimumSeparationIsRespectedAndFluxesDoNotDependOnIt) {
  const Shape hr{128, 128};
  StarFieldOptions options;
  options.count = 400;
  options.min_separation_px = 4.0;  // packing fraction 400 π 4 / 128² = 0.31
  const std::vector<PointSource> stars = StarField(hr, options, 21);
  ASSERT_EQ(stars.size(), 400u);
  double closest = 1e300;
  for (std::size_t i = 0; i < stars.size(); ++i)
    for (std::size_t j = i + 1; j < stars.size(); ++j)
      closest = std::min(closest, std::hypot(stars[i].y - stars[j].y, stars[i].x - stars[j].x));
  std::printf("closest pair at %.3f px (min_separation_px = 4)\n", closest);
  EXPECT_GE(closest, 4.0);

  StarFieldOptions poisson = options;
  poisson.min_separation_px = 0.0;
  const std::vector<PointSource> free = StarField(hr, poisson, 21);
  for (std::size_t k = 0; k < stars.size(); ++k) EXPECT_EQ(stars[k].flux, free[k].flux);
  // AssignFluxes draws the same fluxes for given positions.
  const std::vector<PointSource> assigned = AssignFluxes(stars, options.luminosity, 21);
  for (std::size_t k = 0; k < stars.size(); ++k) {
    EXPECT_EQ(assigned[k].flux, stars[k].flux);
    EXPECT_EQ(assigned[k].y, stars[k].y);
  }
}

TEST(StarFieldTest, PoissonFieldHasTheExpectedNearestNeighbourDistances) {
  // For a uniform field of density rho, P(nearest neighbour < d) = 1 - exp(-pi rho d²) (edge effects aside).
  const Shape hr{400, 400};
  StarFieldOptions options;
  options.count = 2000;
  const std::vector<PointSource> stars = StarField(hr, options, 99);
  const double rho = options.count / double(hr.size());
  const double d = 0.5 / std::sqrt(rho);  // the median-ish scale
  int close = 0, counted = 0;
  for (std::size_t i = 0; i < stars.size(); ++i) {
    if (stars[i].y < 20 || stars[i].y > 379 || stars[i].x < 20 || stars[i].x > 379) continue;  // avoid edges
    ++counted;
    double nearest = 1e300;
    for (std::size_t j = 0; j < stars.size(); ++j)
      if (j != i) nearest = std::min(nearest, std::hypot(stars[i].y - stars[j].y, stars[i].x - stars[j].x));
    if (nearest < d) ++close;
  }
  const double expected = 1.0 - std::exp(-M_PI * rho * d * d);
  const double measured = double(close) / counted;
  std::printf("P(nn < %.2f px): measured %.4f, expected %.4f (n = %d)\n", d, measured, expected, counted);
  EXPECT_NEAR(measured, expected, 4.0 * std::sqrt(expected * (1 - expected) / counted));
}

TEST(LuminosityFunctionTest, QuantileInvertsTheCdfAndMatchesClosedForms) {
  for (double alpha : {0.0, 1.0, 1.5, 2.0, 2.5, 3.0}) {
    LuminosityFunction lf{alpha, 2.0, 5000.0};
    EXPECT_DOUBLE_EQ(lf.Quantile(0.0), 2.0);
    EXPECT_NEAR(lf.Quantile(1.0), 5000.0, 1e-9 * 5000.0);
    for (double u : {0.01, 0.3, 0.5, 0.77, 0.999}) EXPECT_NEAR(lf.Cdf(lf.Quantile(u)), u, 1e-12) << alpha;
  }
  // alpha = 0 is uniform; alpha = 2 has quantile 1/(1/F_min - u (1/F_min - 1/F_max)).
  LuminosityFunction uniform{0.0, 1.0, 3.0};
  EXPECT_NEAR(uniform.Quantile(0.25), 1.5, 1e-14);
  EXPECT_NEAR(uniform.MeanFlux(), 2.0, 1e-14);
  LuminosityFunction two{2.0, 1.0, 1000.0};
  EXPECT_NEAR(two.Quantile(0.5), 1.0 / (1.0 - 0.5 * (1.0 - 1e-3)), 1e-12);
  // Mean for alpha = 2: ln(F_max/F_min) / (1/F_min - 1/F_max).
  EXPECT_NEAR(two.MeanFlux(), std::log(1000.0) / (1.0 - 1e-3), 1e-12);
  LuminosityFunction one{1.0, 1.0, 100.0};  // mean (F_max - F_min) / ln(F_max/F_min)
  EXPECT_NEAR(one.MeanFlux(), 99.0 / std::log(100.0), 1e-12);
}

TEST(LuminosityFunctionTest, SampledFluxesFollowTheLaw) {
  // Kolmogorov-Smirnov distance of 20000 fluxes against the CDF, and the sample mean against MeanFlux.
  for (double alpha : {1.5, 2.0, 2.5}) {
    StarFieldOptions options;
    options.count = 20000;
    options.luminosity = {alpha, 1.0, 1000.0};
    std::vector<PointSource> stars = StarField({256, 256}, options, 2024);
    std::vector<double> f;
    for (const PointSource& s : stars) f.push_back(s.flux);
    std::sort(f.begin(), f.end());
    double ks = 0.0, mean = 0.0, mean2 = 0.0;
    for (std::size_t k = 0; k < f.size(); ++k) {
      const double cdf = options.luminosity.Cdf(f[k]);
      ks = std::max({ks, std::abs(cdf - double(k) / f.size()), std::abs(cdf - double(k + 1) / f.size())});
      mean += f[k];
      mean2 += f[k] * f[k];
    }
    mean /= f.size();
    const double sem = std::sqrt((mean2 / f.size() - mean * mean) / f.size());
    std::printf("alpha %.1f: KS distance %.4f (1%% critical value %.4f), mean %.3f vs %.3f (sem %.3f)\n",
                alpha, ks, 1.63 / std::sqrt(double(f.size())), mean, options.luminosity.MeanFlux(), sem);
    EXPECT_LT(ks, 1.63 / std::sqrt(double(f.size())));
    EXPECT_NEAR(mean, options.luminosity.MeanFlux(), 4.0 * sem);
  }
}

}  // namespace
}  // namespace aosr
