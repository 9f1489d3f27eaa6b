// Physics oracles for the rotating planet (scene/planet.hpp): the disc's area and centroid, the linear
// limb-darkening law's disc-integrated flux π R² (1 − u/3), periodicity in the rotation period, the direction
// and rate of rotation (a surface spot at R sin(2π t / T)), the pole-on view, and the texture's determinism.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <utility>

#include "aosr/scene/planet.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

struct Moments {
  double flux = 0.0;
  double y = 0.0;  // centroid
  double x = 0.0;
};

Moments MomentsOf(const Image& img) {
  Moments m;
  for (Index y = 0; y < img.rows(); ++y)
    for (Index x = 0; x < img.cols(); ++x) {
      m.flux += img(y, x);
      m.y += img(y, x) * double(y);
      m.x += img(y, x) * double(x);
    }
  if (m.flux > 0.0) {
    m.y /= m.flux;
    m.x /= m.flux;
  }
  return m;
}

Image Uniform(int rows = 18, int cols = 36) { return Image::Ones(rows, cols); }

// A map of zeros but for one small bright cap (g(q) = (1 − q²)², radius `radius_deg`) at (lat, lon), on a
// 0.25° grid: fine enough that the bilinear lookup does not distort a 2° spot.
Image SpotMap(double lat_deg, double lon_deg, double radius_deg) {
  const int rows = 720, cols = 1440;
  Image map = Image::Zero(rows, cols);
  const double deg = kPi / 180.0;
  for (int i = 0; i < rows; ++i) {
    const double lat = (90.0 - (i + 0.5) * 180.0 / rows) * deg;
    for (int j = 0; j < cols; ++j) {
      const double lon = (j + 0.5) * 360.0 / cols * deg;
      const double cos_d = std::sin(lat) * std::sin(lat_deg * deg) +
                           std::cos(lat) * std::cos(lat_deg * deg) * std::cos(lon - lon_deg * deg);
      const double q = std::acos(std::min(1.0, cos_d)) / (radius_deg * deg);
      if (q < 1.0) map(i, j) = (1.0 - q * q) * (1.0 - q * q);
    }
  }
  return map;
}

// 1. The disc's area and centroid.
TEST(PlanetPhysicsTest, UniformDiscHasAreaPiR2AndCentredCentroid) {
  PlanetOptions o;
  o.radius_px = 20.0;
  o.supersample = 8;
  const Shape hr{64, 64};
  const Image img = RenderPlanet(hr, o, Uniform(), 0.0);
  const Moments m = MomentsOf(img);
  const double area = kPi * o.radius_px * o.radius_px;
  const double rel = m.flux / area - 1.0;
  std::printf(
      "R = 20, s = 8, centre (31.5, 31.5): flux / (pi R^2) - 1 = %+.3g, centroid offset (%.2g, %.2g)\n", rel,
      m.y - 31.5, m.x - 31.5);
  EXPECT_LT(std::abs(rel), 2e-3);
  EXPECT_NEAR(m.y, 31.5, 1e-3);
  EXPECT_NEAR(m.x, 31.5, 1e-3);
  EXPECT_LE(img.maxCoeff(), 1.0 + 1e-15);
  EXPECT_GE(img.minCoeff(), 0.0);
  // Nothing outside the disc's footprint.
  EXPECT_EQ(img(31, 31 + 22), 0.0);
  EXPECT_EQ(img(31 - 22, 31), 0.0);

  // Centres on a pixel centre or corner keep the sample grid symmetric about the disc: centroid exact.
  for (const auto& [cy, cx] : {std::pair{30.0, 33.0}, std::pair{30.5, 33.0}}) {
    o.centre_y = cy;
    o.centre_x = cx;
    const Moments sym = MomentsOf(RenderPlanet(hr, o, Uniform(), 0.0));
    EXPECT_NEAR(sym.y, cy, 1e-9);
    EXPECT_NEAR(sym.x, cx, 1e-9);
  }
  // An arbitrary sub-pixel centre: the sample grid is no longer symmetric about it, so area and centroid
  // carry the point sampling's (Gauss-circle) error. Over 200 random centres in [28, 36]², the worst
  // centroid errors were 1.2e-2 (s = 4), 3.7e-3 (s = 8) and 1.7e-3 px (s = 16); the worst flux errors
  // 1.4e-3, 5.9e-4 and 1.2e-4.
  o.centre_y = 30.37;
  o.centre_x = 33.81;
  for (int s : {8, 16}) {
    o.supersample = s;
    const Moments off = MomentsOf(RenderPlanet(hr, o, Uniform(), 0.0));
    std::printf(
        "R = 20, s = %2d, centre (30.37, 33.81): flux / (pi R^2) - 1 = %+.3g, centroid offset "
        "(%+.2g, %+.2g)\n",
        s, off.flux / area - 1.0, off.y - o.centre_y, off.x - o.centre_x);
    EXPECT_LT(std::abs(off.flux / area - 1.0), 2e-3) << s;
    EXPECT_NEAR(off.y, o.centre_y, 5e-3) << s;
    EXPECT_NEAR(off.x, o.centre_x, 5e-3) << s;
  }
}

// The flux does not depend on orientation or time for a uniform map, and the texture scales it linearly.
TEST(PlanetPhysicsTest, UniformDiscFluxIsIndependentOfOrientationAndTime) {
  PlanetOptions o;
  o.radius_px = 15.0;
  o.supersample = 6;
  o.rotation_period_s = 3.7;
  const Shape hr{40, 44};
  const double reference = RenderPlanet(hr, o, Uniform(), 0.0).sum();
  o.pole_angle_deg = 37.0;
  o.sub_observer_latitude_deg = -61.0;
  o.longitude0_deg = 123.0;
  o.limb_darkening = 0.0;
  EXPECT_NEAR(RenderPlanet(hr, o, Uniform(), 1.234).sum(), reference, 1e-10 * reference);
  EXPECT_NEAR(RenderPlanet(hr, o, 2.5 * Uniform(), 0.3).sum(), 2.5 * reference, 1e-10 * reference);
}

// 2. The linear law I(μ) = 1 − u (1 − μ): ∫ μ dA over the disc is (2/3) π R², so the flux is π R² (1 − u/3).
TEST(PlanetPhysicsTest, LinearLimbDarkeningFluxIsPiR2TimesOneMinusUOverThree) {
  PlanetOptions o;
  o.radius_px = 20.0;
  o.supersample = 8;
  const Shape hr{64, 64};
  for (double u : {0.0, 0.3, 0.6, 1.0}) {
    o.limb_darkening = u;
    const Image img = RenderPlanet(hr, o, Uniform(), 0.0);
    const double expected = kPi * o.radius_px * o.radius_px * (1.0 - u / 3.0);
    const double rel = img.sum() / expected - 1.0;
    std::printf("u = %.1f: flux / (pi R^2 (1 - u/3)) - 1 = %+.3g\n", u, rel);
    EXPECT_LT(std::abs(rel), 2e-3) << "u = " << u;
    // The centre pixel is at full brightness, I(1) = 1, to the pixel's own spread of μ.
    EXPECT_NEAR(img(31, 31), 1.0, 2e-3);
  }
  // The law's profile: the centre-to-limb ratio at μ = 0.6 (ρ = 0.8 R), sampled on a pixel centre.
  o.limb_darkening = 0.5;
  o.supersample = 16;
  o.centre_y = 32.0;
  o.centre_x = 32.0;
  const Image img = RenderPlanet(hr, o, Uniform(), 0.0);
  EXPECT_NEAR(img(32, 32 + 16), 1.0 - 0.5 * (1.0 - 0.6), 2e-3);
}

// 3. Periodicity: the rotation phase t / T is reduced modulo 1, so t = T gives t = 0's image.
TEST(PlanetPhysicsTest, ImageIsPeriodicInTheRotationPeriod) {
  PlanetTextureOptions to;
  to.band_wobble_deg = 5.0;
  const Image texture = PlanetTexture(to, 11);
  PlanetOptions o;
  o.radius_px = 24.0;
  o.rotation_period_s = 9.925 * 3600.0;  // Jupiter's System III
  o.pole_angle_deg = 20.0;
  o.sub_observer_latitude_deg = 15.0;
  o.longitude0_deg = 40.0;
  o.limb_darkening = 0.4;
  const Shape hr{56, 60};
  const double period = o.rotation_period_s;
  const Image at0 = RenderPlanet(hr, o, texture, 0.0);
  const double peak = at0.maxCoeff();
  const double d1 = (RenderPlanet(hr, o, texture, period) - at0).abs().maxCoeff() / peak;
  const double d2 = (RenderPlanet(hr, o, texture, 2.5 * period) - RenderPlanet(hr, o, texture, 0.5 * period))
                        .abs()
                        .maxCoeff() /
                    peak;
  std::printf("max |I(T) - I(0)| / peak = %.3g, max |I(2.5T) - I(0.5T)| / peak = %.3g\n", d1, d2);
  EXPECT_LE(d1, 1e-12);
  EXPECT_LE(d2, 1e-12);
  // ... and it does change in between (the test could fail).
  EXPECT_GT((RenderPlanet(hr, o, texture, 0.1 * period) - at0).abs().maxCoeff() / peak, 0.05);
  // Retrograde: the same periodicity.
  o.rotation_period_s = -period;
  EXPECT_LE((RenderPlanet(hr, o, texture, -3.0 * period) - at0).abs().maxCoeff() / peak, 1e-12);
}

TEST(PlanetPhysicsTest, CentralMeridianDecreasesForProgradeRotation) {
  PlanetOptions o;
  o.radius_px = 10.0;
  o.rotation_period_s = 100.0;
  o.longitude0_deg = 30.0;
  EXPECT_DOUBLE_EQ(PlanetCentralMeridianDeg(o, 0.0), 30.0);
  EXPECT_NEAR(PlanetCentralMeridianDeg(o, 25.0), 300.0, 1e-12);  // 30 − 90, modulo 360
  EXPECT_NEAR(PlanetCentralMeridianDeg(o, 50.0), 210.0, 1e-12);
  EXPECT_DOUBLE_EQ(PlanetCentralMeridianDeg(o, 100.0), 30.0);
  o.rotation_period_s = -100.0;
  EXPECT_NEAR(PlanetCentralMeridianDeg(o, 25.0), 120.0, 1e-12);
  o.rotation_period_s = 0.0;
  EXPECT_DOUBLE_EQ(PlanetCentralMeridianDeg(o, 1e9), 30.0);
  // The disc centre sees the central meridian at the sub-observer latitude.
  o.rotation_period_s = 100.0;
  o.sub_observer_latitude_deg = 25.0;
  const PlanetSurfacePoint c = PlanetSurfaceAt({21, 21}, o, 10.0, 10.0, 25.0);
  ASSERT_TRUE(c.on_disc);
  EXPECT_NEAR(c.latitude_deg, 25.0, 1e-12);
  EXPECT_NEAR(c.longitude_deg, 300.0, 1e-12);
  EXPECT_DOUBLE_EQ(c.mu, 1.0);
  EXPECT_FALSE(PlanetSurfaceAt({21, 21}, o, 10.0, 20.5, 0.0).on_disc);
  // With the pole up and B = 25°, the north pole is visible at R cos B above the centre (toward row 0).
  const PlanetSurfacePoint pole =
      PlanetSurfaceAt({21, 21}, o, 10.0 - 10.0 * std::cos(25.0 * kPi / 180.0), 10.0, 0.0);
  ASSERT_TRUE(pole.on_disc);
  EXPECT_NEAR(pole.latitude_deg, 90.0, 1e-6);
}

// 4. Rotation direction and rate. A small spot on the equator at the central meridian at t = 0, seen
// equator-on (B = 0) with the pole up: the surface moves toward +x (planet.hpp), so the spot's image sits at
// x − c_x = R sin(2π t / T) and reaches the right limb (+x) after T/4, the left limb (−x) at −T/4. The spot's
// own extent and foreshortening bias its light centroid slightly inward (cos of the offset across the spot).
TEST(PlanetPhysicsTest, SpotMovesAsRSinOmegaTTowardPlusX) {
  const Image map = SpotMap(0.0, 0.0, 2.0);  // at longitude 0: the lookup wraps across the map's edge
  PlanetOptions o;
  o.radius_px = 40.0;
  o.rotation_period_s = 10.0;
  o.longitude0_deg = 0.0;
  o.supersample = 4;
  const Shape hr{96, 96};
  const double c = 47.5, r = o.radius_px, t_period = o.rotation_period_s;

  const Moments m0 = MomentsOf(RenderPlanet(hr, o, map, 0.0));
  ASSERT_GT(m0.flux, 0.0);
  EXPECT_NEAR(m0.x, c, 1e-6);
  EXPECT_NEAR(m0.y, c, 1e-6);
  for (double frac : {0.01, 0.03, 0.0625, 0.125}) {
    const double t = frac * t_period;
    const Moments m = MomentsOf(RenderPlanet(hr, o, map, t));
    const double expected = r * std::sin(kTwoPi * t / t_period);
    std::printf("t = %.4f T: spot x - c = %.4f px, R sin(2 pi t/T) = %.4f px (%+.2f%%), y - c = %+.2g\n",
                frac, m.x - c, expected, 100.0 * ((m.x - c) / expected - 1.0), m.y - c);
    EXPECT_NEAR(m.x - c, expected, 0.01 * expected) << "t = " << t;
    EXPECT_NEAR(m.y, c, 1e-6);
  }
  // Toward the right limb: at 0.2 T the spot is at R sin 72° = 0.95 R.
  const Moments late = MomentsOf(RenderPlanet(hr, o, map, 0.2 * t_period));
  EXPECT_NEAR(late.x - c, r * std::sin(0.4 * kPi), 0.01 * r);
  // A quarter period: on the right limb (+x), half hidden and the rest foreshortened to a sliver R (1 − cos
  // r_s) wide. The 2° spot's sliver (0.02 px) falls between the sub-samples, so a 10° spot shows it.
  const Image big = SpotMap(0.0, 0.0, 10.0);
  const Moments b0 = MomentsOf(RenderPlanet(hr, o, big, 0.0));
  const Moments q = MomentsOf(RenderPlanet(hr, o, big, 0.25 * t_period));
  std::printf("t = T/4 (10-degree spot): x - c = %.3f px (R = %.0f), flux %.3g of t = 0's\n", q.x - c, r,
              q.flux / b0.flux);
  EXPECT_GT(q.x - c, 0.97 * r);
  EXPECT_LT(q.flux, 0.1 * b0.flux);
  EXPECT_GT(q.flux, 0.0);
  const Moments mq = MomentsOf(RenderPlanet(hr, o, big, -0.25 * t_period));
  EXPECT_LT(mq.x - c, -0.97 * r);
  // Half a period: on the far side.
  EXPECT_EQ(RenderPlanet(hr, o, map, 0.5 * t_period).sum(), 0.0);

  // Retrograde: the other way.
  o.rotation_period_s = -t_period;
  const Moments retro = MomentsOf(RenderPlanet(hr, o, map, 0.0625 * t_period));
  EXPECT_NEAR(retro.x - c, -r * std::sin(kTwoPi * 0.0625), 0.01 * r * std::sin(kTwoPi * 0.0625));

  // Pole at position angle 90° (pointing to +x): the motion is along +y (ξ = (cos P, sin P)).
  o.rotation_period_s = t_period;
  o.pole_angle_deg = 90.0;
  const Moments p90 = MomentsOf(RenderPlanet(hr, o, map, 0.0625 * t_period));
  const double expected = r * std::sin(kTwoPi * 0.0625);
  std::printf("pole angle 90: spot (y - c, x - c) = (%.4f, %+.2g), expected (%.4f, 0)\n", p90.y - c,
              p90.x - c, expected);
  EXPECT_NEAR(p90.y - c, expected, 0.01 * expected);
  EXPECT_NEAR(p90.x, c, 1e-6);
}

// 5. Pole-on (B = +90°): the north pole at the disc centre; a latitude-only map gives a rotationally
// symmetric image (checked under the square grid's exact symmetries: transpose and both flips), whatever the
// time, pole angle and rotation; the whole visible hemisphere is north.
TEST(PlanetPhysicsTest, PoleOnViewIsRotationallySymmetric) {
  PlanetTextureOptions to;
  to.spots = 0;  // bands only, no wobble: depends on latitude only
  to.bands = 5;
  to.band_contrast = 0.6;
  const Image bands = PlanetTexture(to, 1);
  PlanetOptions o;
  o.radius_px = 25.0;
  o.sub_observer_latitude_deg = 90.0;
  o.rotation_period_s = 7.0;
  o.limb_darkening = 0.5;
  o.pole_angle_deg = 33.0;
  const Shape hr{60, 60};
  const Image img = RenderPlanet(hr, o, bands, 1.9);
  const double peak = img.maxCoeff();
  const Image transposed = img.transpose();
  const double d_transpose = (img - transposed).abs().maxCoeff() / peak;
  const double d_flip_y = (img - img.colwise().reverse()).abs().maxCoeff() / peak;
  const double d_flip_x = (img - img.rowwise().reverse()).abs().maxCoeff() / peak;
  std::printf("pole-on asymmetry / peak: transpose %.2g, flip y %.2g, flip x %.2g\n", d_transpose, d_flip_y,
              d_flip_x);
  EXPECT_LE(d_transpose, 1e-12);
  EXPECT_LE(d_flip_y, 1e-12);
  EXPECT_LE(d_flip_x, 1e-12);
  // The centre is the pole, μ = 1 there.
  const PlanetSurfacePoint centre = PlanetSurfaceAt(hr, o, 29.5, 29.5, 1.9);
  EXPECT_NEAR(centre.latitude_deg, 90.0, 1e-9);
  // The visible hemisphere is all north: a map bright only north of the equator renders as a uniform one, and
  // one bright only to the south renders nothing (bar the bilinear blend across the equator's half row, which
  // only the limb's sliver at μ → 0 reaches).
  Image north = Image::Zero(180, 360), south = Image::Zero(180, 360);
  north.topRows(90).setOnes();
  south.bottomRows(90).setOnes();
  o.limb_darkening = 0.0;
  const double uniform_flux = RenderPlanet(hr, o, Uniform(), 0.0).sum();
  EXPECT_NEAR(RenderPlanet(hr, o, north, 0.0).sum(), uniform_flux, 2e-3 * uniform_flux);
  EXPECT_LT(RenderPlanet(hr, o, south, 0.0).sum(), 2e-3 * uniform_flux);
  // South pole on: the reverse.
  o.sub_observer_latitude_deg = -90.0;
  EXPECT_LT(RenderPlanet(hr, o, north, 0.0).sum(), 2e-3 * uniform_flux);
  EXPECT_NEAR(PlanetSurfaceAt(hr, o, 29.5, 29.5, 0.0).latitude_deg, -90.0, 1e-9);

  // The same map seen equator-on is not symmetric under the transpose (so the check above can fail).
  o.sub_observer_latitude_deg = 0.0;
  o.pole_angle_deg = 0.0;
  const Image side = RenderPlanet(hr, o, bands, 0.0);
  const Image side_t = side.transpose();
  EXPECT_GT((side - side_t).abs().maxCoeff() / side.maxCoeff(), 0.1);
}

// 6. The procedural map: deterministic, seed-dependent, finite and positive, bands averaging 1 over the
// sphere.
TEST(PlanetPhysicsTest, TextureIsDeterministicPositiveAndMeanOne) {
  PlanetTextureOptions to;
  to.band_wobble_deg = 4.0;
  const Image a = PlanetTexture(to, 2024), b = PlanetTexture(to, 2024), c = PlanetTexture(to, 2025);
  ASSERT_EQ(a.rows(), to.rows);
  ASSERT_EQ(a.cols(), to.cols);
  EXPECT_EQ(std::memcmp(a.data(), b.data(), sizeof(double) * a.size()), 0);
  EXPECT_NE(std::memcmp(a.data(), c.data(), sizeof(double) * a.size()), 0);
  EXPECT_TRUE(AllFinite(a));
  EXPECT_GT(a.minCoeff(), 0.0);
  EXPECT_GE(a.minCoeff(), (1.0 - to.band_contrast) / (1.0 + to.band_contrast) - 1e-12);

  // Area-weighted mean: bands alone exactly 1; with spots, 1 + about spots x contrast x r_s² / 12.
  const auto area_mean = [](const Image& m) {
    double sum = 0.0, weights = 0.0;
    for (Index i = 0; i < m.rows(); ++i) {
      const double w = std::cos((90.0 - (i + 0.5) * 180.0 / m.rows()) * kPi / 180.0);
      sum += w * m.row(i).sum();
      weights += w * m.cols();
    }
    return sum / weights;
  };
  PlanetTextureOptions plain = to;
  plain.spots = 0;
  plain.band_wobble_deg = 0.0;  // bands depending on latitude only
  EXPECT_NEAR(area_mean(PlanetTexture(plain, 3)), 1.0, 1e-12);
  to.spots = 20;
  to.rows = 360;
  to.cols = 720;
  const double rs = to.spot_radius_deg * kPi / 180.0;
  const double spot_share = area_mean(PlanetTexture(to, 5)) - 1.0;
  std::printf("spots' share of the mean: %.4g, r_s^2/12 x 20 = %.4g\n", spot_share, 20 * rs * rs / 12.0);
  EXPECT_NEAR(spot_share, 20 * rs * rs / 12.0, 0.05 * 20 * rs * rs / 12.0);

  // The bands alone are symmetric about the equator and independent of longitude.
  const Image bands = PlanetTexture(plain, 9);
  EXPECT_LE((bands - bands.colwise().reverse()).abs().maxCoeff(), 1e-12);
  for (Index j = 1; j < bands.cols(); ++j) EXPECT_EQ((bands.col(j) - bands.col(0)).abs().maxCoeff(), 0.0);
  // Even `bands`: a bright zone at the equator.
  EXPECT_NEAR(bands(44, 0), bands.maxCoeff(), 0.05);
}

}  // namespace AOSR_TEST_NS
}  // namespace aosr
