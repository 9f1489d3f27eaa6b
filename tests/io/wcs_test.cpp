#include "aosr/io/wcs.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "aosr/core/error.hpp"
#include "temp_dir.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

using testing_io::TempDir;

constexpr double kRad = M_PI / 180.0;

Wcs Example() {
  Wcs w;
  w.crpix[0] = 512.5;
  w.crpix[1] = 300.25;
  w.crval[0] = 150.0;
  w.crval[1] = 30.0;
  w.cd[0][0] = -2.7e-4;
  w.cd[0][1] = 1.0e-5;
  w.cd[1][0] = 1.5e-5;
  w.cd[1][1] = 2.8e-4;
  return w;
}

// Intermediate world coordinates (ξ, η) [deg] of an aosr pixel: CD · (p − CRPIX), p = (x + 1, y + 1).
void Intermediate(const Wcs& w, double y, double x, double* xi, double* eta) {
  const double q1 = x + 1 - w.crpix[0], q2 = y + 1 - w.crpix[1];
  *xi = w.cd[0][0] * q1 + w.cd[0][1] * q2;
  *eta = w.cd[1][0] * q1 + w.cd[1][1] * q2;
}

// Paper [II]'s steps 3-4 for TAN collapse, with φ_p = 180°, to the classical gnomonic inverse (ξ, η in
// radians): α = α0 + atan2(ξ, cos δ0 − η sin δ0), δ = atan2(sin δ0 + η cos δ0, √(ξ² + (cos δ0 − η sin δ0)²)).
// An independent route to the same numbers.
SkyCoord Gnomonic(const Wcs& w, double y, double x) {
  double xi, eta;
  Intermediate(w, y, x, &xi, &eta);
  xi *= kRad, eta *= kRad;
  const double d0 = w.crval[1] * kRad;
  const double den = std::cos(d0) - eta * std::sin(d0);
  SkyCoord s;
  s.ra_deg = std::fmod(w.crval[0] + std::atan2(xi, den) / kRad + 360.0, 360.0);
  s.dec_deg = std::atan2(std::sin(d0) + eta * std::cos(d0), std::hypot(xi, den)) / kRad;
  return s;
}

TEST(WcsTest, OnTheMeridianDeclinationGrowsByTheArctangentOfTheOffset) {
  // By hand from [II] eqs. 54-55 and 2: a pixel q rows above the reference with CD = diag(−s, s) has ξ = 0,
  // η = q s, so φ = 180°, θ = 90° − atan(η) and α = α0, δ = asin(cos(θ − δ0)) = δ0 + atan(η) (η in rad).
  Wcs w;
  w.crpix[0] = 11;
  w.crpix[1] = 21;
  w.crval[0] = 40.0;
  w.crval[1] = 25.0;
  const double s = 1e-3;
  w.cd[0][0] = -s;
  w.cd[1][1] = s;
  for (double q : {-700.0, -3.0, 0.0, 0.5, 250.0, 5000.0}) {
    const SkyCoord sky = PixelToSky(w, {20 + q, 10});
    EXPECT_NEAR(sky.ra_deg, 40.0, 1e-12) << q;
    EXPECT_NEAR(sky.dec_deg, 25.0 + std::atan(q * s * kRad) / kRad, 1e-12) << q;
  }
  // On the equator along +x: ξ = −q s, δ0 = 0, so tan(α − α0) = ξ: +x is west (RA decreases).
  w.crval[1] = 0.0;
  for (double q : {-400.0, 1.0, 900.0}) {
    const SkyCoord sky = PixelToSky(w, {20, 10 + q});
    EXPECT_NEAR(sky.ra_deg, 40.0 + std::atan(-q * s * kRad) / kRad, 1e-12) << q;
    EXPECT_NEAR(sky.dec_deg, 0.0, 1e-12) << q;
  }
}

TEST(WcsTest, AgreesWithTheClassicalGnomonicFormulasAndWithWcslib) {
  const Wcs w = Example();
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(-3000, 3000);
  for (int k = 0; k < 200; ++k) {
    const double y = u(rng), x = u(rng);
    const SkyCoord a = PixelToSky(w, {y, x}), b = Gnomonic(w, y, x);
    EXPECT_LT(AngularSeparationDeg(a, b), 1e-11) << "seed 7, sample " << k;
  }
  // Values from astropy 5.2.1 (wcslib), all_pix2world(..., 1) of the same header at FITS pixels (1, 1) and
  // (2000, 1500), i.e. aosr (0, 0) and (1499, 1999):
  const SkyCoord p = PixelToSky(w, {0, 0});
  EXPECT_NEAR(p.ra_deg, 150.155870435681, 1e-10);
  EXPECT_NEAR(p.dec_deg, 29.908445940416, 1e-10);
  const SkyCoord q = PixelToSky(w, {1499, 1999});
  EXPECT_NEAR(q.ra_deg, 149.548476279025, 1e-10);
  EXPECT_NEAR(q.dec_deg, 30.357461940667, 1e-10);
  // Near the south pole, across RA = 0: astropy gives (290.071254928847, -89.478002669461) at FITS (500, -300).
  Wcs pole;
  pole.crpix[0] = 10;
  pole.crpix[1] = 20;
  pole.crval[0] = 359.9;
  pole.crval[1] = -89.5;
  pole.cd[0][0] = -1e-3;
  pole.cd[0][1] = pole.cd[1][0] = 0;
  pole.cd[1][1] = 1e-3;
  const SkyCoord s = PixelToSky(pole, {-301, 499});
  EXPECT_NEAR(s.ra_deg, 290.071254928847, 1e-9);
  EXPECT_NEAR(s.dec_deg, -89.478002669461, 1e-10);
}

TEST(WcsTest, PixelSkyPixelRoundTripsTo1e9Pixel) {
  // The floor is the sky coordinates' own rounding: RA near 123° is a double in degrees with a spacing of
  // 1.4e-14° = 2.5e-16 rad, 2.6e-10 of a 0.2" pixel but 5e-8 of a 1 mas one. So 1e-9 px for 0.2" pixels
  // (and the 0.1° wide field below), 1e-7 px for 1 mas pixels (aosr's HR pixels are ~10-30 mas).
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> u(-2000, 2000);
  const double arcsec = M_PI / 180 / 3600;
  for (const auto& [pixel_rad, tolerance] : {std::pair{0.2 * arcsec, 1e-9}, std::pair{1e-3 * arcsec, 1e-7}}) {
    for (double dec : {-89.9, -45.0, 0.0, 12.5, 60.0, 89.99, 90.0}) {
      Wcs w = TangentPlaneWcs(123.4, dec, pixel_rad, 33.0, {50.0, 70.0});
      for (int k = 0; k < 100; ++k) {
        const PixelCoord p{u(rng), u(rng)};
        const PixelCoord back = SkyToPixel(w, PixelToSky(w, p));
        ASSERT_NEAR(back.y, p.y, tolerance) << "seed 11, dec " << dec << ", pixel " << pixel_rad;
        ASSERT_NEAR(back.x, p.x, tolerance) << "seed 11, dec " << dec << ", pixel " << pixel_rad;
      }
    }
  }
  // A wide field too: 0.1° pixels out to ~60° from the reference point.
  const Wcs wide = TangentPlaneWcs(10, -30, 0.1 * kRad, -20, {0, 0});
  for (const PixelCoord p : {PixelCoord{1000, -1200}, PixelCoord{-1500, 300}}) {
    const PixelCoord back = SkyToPixel(wide, PixelToSky(wide, p));
    EXPECT_NEAR(back.y, p.y, 1e-9);
    EXPECT_NEAR(back.x, p.x, 1e-9);
  }
}

TEST(WcsTest, TangentPlaneOrientationFollowsThePositionAngle) {
  const double pixel = 10e-3 / 3600 * kRad;  // 10 mas
  const Wcs north_up = TangentPlaneWcs(200, 45, pixel, 0, {10, 10});
  const SkyCoord c = PixelToSky(north_up, {10, 10});
  EXPECT_NEAR(c.ra_deg, 200, 1e-12);
  EXPECT_NEAR(c.dec_deg, 45, 1e-12);
  EXPECT_NEAR(north_up.PixelScaleDeg(0) * 3600e3, 10, 1e-9);
  EXPECT_NEAR(north_up.PixelScaleDeg(1) * 3600e3, 10, 1e-9);
  // +y: north; +x: west (RA decreases).
  EXPECT_GT(PixelToSky(north_up, {110, 10}).dec_deg, 45);
  EXPECT_LT(PixelToSky(north_up, {10, 110}).ra_deg, 200);
  // PA 90: +y points east (RA increases), +x points north.
  const Wcs east_up = TangentPlaneWcs(200, 45, pixel, 90, {10, 10});
  EXPECT_GT(PixelToSky(east_up, {110, 10}).ra_deg, 200);
  EXPECT_NEAR(PixelToSky(east_up, {110, 10}).dec_deg, 45, 1e-6);
  EXPECT_GT(PixelToSky(east_up, {10, 110}).dec_deg, 45);
}

TEST(WcsTest, HeaderRoundTripThroughAFile) {
  TempDir dir;
  Wcs w = Example();
  w.radesys = "FK5";
  w.equinox = 2000.0;
  FitsHeader h;
  h.Set("OBJECT", "test");
  WriteWcs(w, &h);
  WriteFits(dir.File("a.fits"), Image::Zero(4, 5), h);
  const FitsData d = ReadFits(dir.File("a.fits"));
  ASSERT_TRUE(HasWcs(d.header));
  EXPECT_EQ(d.header.GetString("CTYPE1"), "RA---TAN");
  EXPECT_EQ(d.header.GetInt("WCSAXES"), 2);
  const Wcs back = WcsFromHeader(d.header);
  for (int i = 0; i < 2; ++i) {
    EXPECT_EQ(back.crpix[i], w.crpix[i]);
    EXPECT_EQ(back.crval[i], w.crval[i]);
    for (int j = 0; j < 2; ++j) EXPECT_EQ(back.cd[i][j], w.cd[i][j]);
  }
  EXPECT_EQ(back.radesys, "FK5");
  ASSERT_TRUE(back.equinox);
  EXPECT_EQ(*back.equinox, 2000.0);
  EXPECT_FALSE(HasWcs(FitsHeader{}));
}

TEST(WcsTest, CdAndPcCdeltAndCrotaFormsGiveTheSameMatrix) {
  // One rotated, anisotropic frame in the three forms of Greisen & Calabretta 2002, §2.1.2.
  const double rho = 25.0 * kRad, c1 = -2e-4, c2 = 3e-4;
  const double cd[2][2] = {{c1 * std::cos(rho), -c2 * std::sin(rho)}, {c1 * std::sin(rho), c2 * std::cos(rho)}};
  const auto base = [] {
    FitsHeader h;
    h.Set("CTYPE1", "RA---TAN");
    h.Set("CTYPE2", "DEC--TAN ");  // trailing blanks are not significant
    h.Set("CRPIX1", 100);          // integers are accepted for reals
    h.Set("CRPIX2", 50.5);
    h.Set("CRVAL1", -10.0);        // normalised to [0, 360)
    h.Set("CRVAL2", 20.0);
    return h;
  };
  FitsHeader with_cd = base();
  with_cd.Set("CD1_1", cd[0][0]);
  with_cd.Set("CD1_2", cd[0][1]);
  with_cd.Set("CD2_1", cd[1][0]);
  with_cd.Set("CD2_2", cd[1][1]);
  with_cd.Set("CDELT1", 99.0);  // ignored beside CD, as wcslib does
  FitsHeader with_pc = base();
  with_pc.Set("CDELT1", c1);
  with_pc.Set("CDELT2", c2);
  with_pc.Set("PC1_1", std::cos(rho));
  with_pc.Set("PC1_2", -std::sin(rho) * c2 / c1);
  with_pc.Set("PC2_1", std::sin(rho) * c1 / c2);
  with_pc.Set("PC2_2", std::cos(rho));
  FitsHeader with_crota = base();
  with_crota.Set("CDELT1", c1);
  with_crota.Set("CDELT2", c2);
  with_crota.Set("CROTA2", 25.0);
  for (const FitsHeader* h : {&with_cd, &with_pc, &with_crota}) {
    const Wcs w = WcsFromHeader(*h);
    EXPECT_EQ(w.crpix[0], 100.0);
    EXPECT_EQ(w.crval[0], 350.0);
    for (int i = 0; i < 2; ++i)
      for (int j = 0; j < 2; ++j) EXPECT_NEAR(w.cd[i][j], cd[i][j], 1e-18) << i << j;
  }
  // CDELT alone: a diagonal matrix. Missing CD elements are zero.
  FitsHeader plain = base();
  plain.Set("CDELT1", -1e-4);
  plain.Set("CDELT2", 1e-4);
  const Wcs p = WcsFromHeader(plain);
  EXPECT_EQ(p.cd[0][0], -1e-4);
  EXPECT_EQ(p.cd[0][1], 0.0);
  EXPECT_EQ(p.cd[1][1], 1e-4);
  FitsHeader sparse = base();
  sparse.Set("CD1_1", -1e-4);
  sparse.Set("CD2_2", 1e-4);
  EXPECT_EQ(WcsFromHeader(sparse).cd[1][0], 0.0);
  EXPECT_EQ(WcsFromHeader(sparse).radesys, "");  // not stated
}

TEST(WcsTest, HrGridMapsCameraPixelCentresToTheirHrCentres) {
  const Wcs lr = Example();
  for (int r : {1, 2, 3, 4, 8}) {
    const double dy = -0.75, dx = 1.3;
    const Wcs hr = HrWcs(lr, r, dy, dx);
    EXPECT_NEAR(hr.PixelScaleDeg(0), lr.PixelScaleDeg(0) / r, 1e-18);
    // Camera pixel c shows HR position (c + ½)·r − ½ − d of the object: same sky position.
    for (const PixelCoord c : {PixelCoord{0, 0}, PixelCoord{17.25, -3.5}, PixelCoord{299.25, 511.5}}) {
      const PixelCoord p{(c.y + 0.5) * r - 0.5 - dy, (c.x + 0.5) * r - 0.5 - dx};
      EXPECT_LT(AngularSeparationDeg(PixelToSky(lr, c), PixelToSky(hr, p)) / hr.PixelScaleDeg(0), 1e-9) << r;
    }
    const Wcs back = LrWcs(hr, r, dy, dx);
    for (int i = 0; i < 2; ++i) {
      EXPECT_NEAR(back.crpix[i], lr.crpix[i], 1e-12);
      for (int j = 0; j < 2; ++j) EXPECT_NEAR(back.cd[i][j], lr.cd[i][j], 1e-18);
    }
  }
  // r = 1 without offset: the same WCS.
  const Wcs same = HrWcs(lr, 1);
  EXPECT_EQ(same.crpix[0], lr.crpix[0]);
  EXPECT_EQ(same.crpix[1], lr.crpix[1]);
}

TEST(WcsTest, SetImageKeywordsWritesBunitAndTheWcsWhenGiven) {
  FitsHeader h;
  SetImageKeywords(std::nullopt, "electron", &h);
  EXPECT_EQ(h.GetString("BUNIT"), "electron");
  EXPECT_FALSE(HasWcs(h));
  SetImageKeywords(Example(), "", &h);
  EXPECT_TRUE(HasWcs(h));
  EXPECT_EQ(h.GetDouble("CRPIX2"), 300.25);
}

}  // namespace
}  // namespace aosr
