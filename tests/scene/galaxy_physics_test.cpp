// Physics oracles for Sérsic galaxies: b_n against the defining equation, the analytic total flux and the
// half-light isophote measured on rendered, pixel-integrated images.
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>

#include "aosr/scene/galaxy.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

TEST(IncompleteGammaTest, ClosedForms) {
  for (double x : {0.0, 1e-3, 0.1, 0.7, 1.0, 2.5, 10.0, 40.0}) {
    EXPECT_NEAR(RegularisedGammaP(1.0, x), -std::expm1(-x), 1e-15) << x;
    EXPECT_NEAR(RegularisedGammaP(0.5, x), std::erf(std::sqrt(x)), 1e-14) << x;
    EXPECT_NEAR(RegularisedGammaP(3.0, x), 1.0 - std::exp(-x) * (1.0 + x + 0.5 * x * x), 1e-14) << x;
  }
  // Large a, near the median (both branches meet at x = a + 1).
  EXPECT_NEAR(RegularisedGammaP(40.0, 40.999999), RegularisedGammaP(40.0, 41.000001), 1e-6);
}

TEST(SersicBnTest, SolvesTheDefiningEquation) {
  EXPECT_NEAR(SersicBn(0.5), std::log(2.0), 1e-14);  // P(1, b) = 1 - e^-b = 1/2
  EXPECT_NEAR(SersicBn(1.0), 1.6783469900166608, 1e-12);
  for (double n = 0.21; n <= 20.0; n *= 1.13) {
    EXPECT_NEAR(RegularisedGammaP(2.0 * n, SersicBn(n)), 0.5, 1e-13) << "n = " << n;
  }
}

TEST(SersicBnTest, CiottiBertinExpansionIsWithin1e3ForHalfToTen) {
  double worst = 0.0, worst_n = 0.0;
  for (double n = 0.5; n <= 10.0 + 1e-9; n += 0.05) {
    // The exact solution by plain bisection on P(2n, b) = 1/2, independent of SersicBn's Newton iteration.
    double lo = 0.0, hi = 2.0 * n;
    for (int it = 0; it < 200; ++it) {
      const double mid = 0.5 * (lo + hi);
      (RegularisedGammaP(2.0 * n, mid) < 0.5 ? lo : hi) = mid;
    }
    const double exact = 0.5 * (lo + hi);
    EXPECT_NEAR(SersicBn(n), exact, 1e-12 * exact);
    const double err = std::abs(SersicBnCiottiBertin(n) - exact);
    if (err > worst) {
      worst = err;
      worst_n = n;
    }
    EXPECT_LT(err, 1e-3) << "n = " << n;
  }
  std::printf("Ciotti-Bertin b_n: worst |error| %.3g at n = %.2f over [0.5, 10]\n", worst, worst_n);
  for (double n : {0.25, 0.36, 1.0, 2.0, 4.0, 10.0})
    std::printf("  n = %5.2f: b_n = %.12f, expansion error %+.3g\n", n, SersicBn(n),
                SersicBnCiottiBertin(n) - SersicBn(n));
}

TEST(SersicGalaxyTest, EnclosedFractionIsHalfAtTheEffectiveRadius) {
  for (double n : {0.3, 0.5, 1.0, 4.0, 10.0}) {
    EXPECT_NEAR(SersicEnclosedFraction(n, 1.0), 0.5, 1e-13);
    EXPECT_EQ(SersicEnclosedFraction(n, 0.0), 0.0);
    EXPECT_LT(SersicEnclosedFraction(n, 0.5), 0.5);
  }
  // Exponential disc: P(2, b x) = 1 - e^{-b x}(1 + b x).
  const double b = SersicBn(1.0);
  EXPECT_NEAR(SersicEnclosedFraction(1.0, 2.0), 1.0 - std::exp(-2 * b) * (1 + 2 * b), 1e-14);
}

TEST(SersicGalaxyTest, EffectiveIntensityAndProfile) {
  SersicGalaxy g;
  g.y = 10.0;
  g.x = 20.0;
  g.flux = 100.0;
  g.n = 1.0;
  g.half_light_radius_px = 4.0;
  g.axis_ratio = 0.5;
  g.position_angle_rad = M_PI / 2;  // major axis along y
  const double ie = g.EffectiveIntensity();
  // Exponential disc: F = 2π q R_e² I_e e^b / b² (Γ(2) = 1).
  const double b = SersicBn(1.0);
  EXPECT_NEAR(ie, 100.0 / (2 * M_PI * 0.5 * 16.0 * std::exp(b) / (b * b)), 1e-12 * ie);
  EXPECT_NEAR(g.Intensity(14.0, 20.0), ie, 1e-12 * ie);  // R_e along the major axis (y)
  EXPECT_NEAR(g.Intensity(10.0, 22.0), ie, 1e-12 * ie);  // q R_e along the minor axis (x)
  EXPECT_NEAR(g.Intensity(10.0, 20.0), ie * std::exp(b), 1e-12 * ie);
}

struct FluxCase {
  double n;
  double re;
  Index side;
};

TEST(SersicRenderTest, TotalFluxMatchesTheAnalyticValue) {
  for (const FluxCase& c : {FluxCase{0.5, 6.0, 128}, FluxCase{1.0, 8.0, 256}, FluxCase{2.0, 5.0, 256},
                            FluxCase{4.0, 3.0, 512}, FluxCase{8.0, 1.5, 512}}) {
    SersicGalaxy g;
    g.y = (c.side - 1) / 2.0 + 0.3;
    g.x = (c.side - 1) / 2.0 - 0.2;
    g.flux = 1000.0;
    g.n = c.n;
    g.half_light_radius_px = c.re;
    g.axis_ratio = 0.6;
    g.position_angle_rad = 0.7;
    const auto t0 = std::chrono::steady_clock::now();
    const Image img = RenderSersic({c.side, c.side}, g);
    const double ms =
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    // Light outside the field: at least that beyond the largest isophote inside it (semi-minor axis of the
    // ellipse inscribed in the field) is missing, and at most that beyond the inscribed circle's isophote.
    const double half = c.side / 2.0 - 1.0;  // inscribed circle, allowing for the centre offset
    const double missing_max = 1.0 - SersicEnclosedFraction(c.n, half / c.re);
    const double rel = img.sum() / g.flux - 1.0;
    std::printf("n = %4.1f R_e = %4.1f on %lld^2: sum/F - 1 = %+.3g (outside field <= %.2g), %.0f ms\n", c.n,
                c.re, static_cast<long long>(c.side), rel, missing_max, ms);
    EXPECT_NEAR(img.sum(), g.flux, 0.01 * g.flux);
    EXPECT_LE(img.sum(), g.flux * (1.0 + 1e-6));
    EXPECT_GE(img.sum(), g.flux * (1.0 - missing_max - 1e-6));
    EXPECT_GE(img.minCoeff(), 0.0);
  }
}

// Flux inside the ellipse R < radius, each pixel weighted by the fraction of its area inside (16 x 16
// sub-samples).
double FluxInside(const Image& img, const SersicGalaxy& g, double radius) {
  const double c = std::cos(g.position_angle_rad), s = std::sin(g.position_angle_rad);
  double total = 0.0;
  for (Index i = 0; i < img.rows(); ++i)
    for (Index j = 0; j < img.cols(); ++j) {
      int inside = 0;
      for (int a = 0; a < 16; ++a)
        for (int b = 0; b < 16; ++b) {
          const double dy = i - 0.5 + (a + 0.5) / 16 - g.y, dx = j - 0.5 + (b + 0.5) / 16 - g.x;
          const double u = dx * c + dy * s, v = (-dx * s + dy * c) / g.axis_ratio;
          if (u * u + v * v < radius * radius) ++inside;
        }
      total += img(i, j) * inside / 256.0;
    }
  return total;
}

TEST(SersicRenderTest, HalfLightIsophoteContainsHalfTheLight) {
  for (double n : {0.5, 1.0, 4.0}) {
    for (double q : {1.0, 0.5}) {
      SersicGalaxy g;
      g.y = 127.3;
      g.x = 128.6;
      g.flux = 1.0;
      g.n = n;
      g.half_light_radius_px = 12.0;
      g.axis_ratio = q;
      g.position_angle_rad = 0.4;
      const Image img = RenderSersic({256, 256}, g);
      const double half = FluxInside(img, g, g.half_light_radius_px) / g.flux;
      std::printf("n = %.1f q = %.1f: flux inside R_e = %.5f\n", n, q, half);
      EXPECT_NEAR(half, 0.5, 0.01);
    }
  }
}

TEST(SersicRenderTest, CuspPixelsConvergeWithTheTolerance) {
  // The central pixels of an n = 4 galaxy with R_e = 1.5 px hold a steep cusp: the default tolerance agrees
  // with a 1e-10 rendering to ~1e-6 of each pixel.
  SersicGalaxy g;
  g.y = 16.0;
  g.x = 16.25;
  g.n = 4.0;
  g.half_light_radius_px = 1.5;
  g.flux = 1.0;
  const Image fine = RenderSersic({32, 32}, g, {1e-10, 40});
  const Image coarse = RenderSersic({32, 32}, g);
  const double worst = ((coarse - fine).abs() / fine.abs().max(1e-300)).maxCoeff();
  std::printf("n = 4 cusp: worst pixel relative difference default vs 1e-10: %.3g; central pixel %.6f\n",
              worst, fine(16, 16));
  EXPECT_LT(std::abs(coarse(16, 16) - fine(16, 16)), 1e-5 * fine(16, 16));
  EXPECT_LT((coarse - fine).abs().sum(), 1e-5);
}

TEST(GalaxyFieldTest, DeterministicAndWithinTheRanges) {
  GalaxyFieldOptions options;
  options.count = 25;
  options.margin_px = 8.0;
  const Shape hr{128, 160};
  const std::vector<SersicGalaxy> a = GalaxyField(hr, options, 3), b = GalaxyField(hr, options, 3);
  ASSERT_EQ(a.size(), 25u);
  for (std::size_t k = 0; k < a.size(); ++k) {
    EXPECT_EQ(a[k].x, b[k].x);
    EXPECT_EQ(a[k].n, b[k].n);
    EXPECT_EQ(a[k].flux, b[k].flux);
    EXPECT_GE(a[k].y, 7.5);
    EXPECT_LT(a[k].y, hr.rows - 8.5);
    EXPECT_GE(a[k].n, options.n_min);
    EXPECT_LE(a[k].n, options.n_max);
    EXPECT_GE(a[k].half_light_radius_px, options.re_min_px);
    EXPECT_LE(a[k].half_light_radius_px, options.re_max_px);
    EXPECT_GE(a[k].axis_ratio, options.q_min);
    EXPECT_LE(a[k].axis_ratio, options.q_max);
    EXPECT_GE(a[k].flux, options.flux.flux_min);
    EXPECT_LE(a[k].flux, options.flux.flux_max);
    std::string why;
    EXPECT_TRUE(a[k].IsValid(&why)) << why;
  }
  const auto t0 = std::chrono::steady_clock::now();
  const Image img = RenderGalaxies(hr, a);
  const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  double total = 0.0;
  for (const SersicGalaxy& g : a) total += g.flux;
  std::printf("galaxy field: %zu galaxies on %s in %.0f ms, in-field flux %.4f of total\n", a.size(),
              ToString(hr).c_str(), ms, img.sum() / total);
  EXPECT_LE(img.sum(), total * (1 + 1e-6));
  EXPECT_GT(img.sum(), 0.8 * total);
}

}  // namespace
}  // namespace aosr
