#include "aosr/core/image.hpp"  // kPi
#include "aosr/optics/aperture.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <iostream>
#include <random>

#include "aosr/optics/pupil.hpp"

namespace aosr {
namespace {

constexpr double kSqrt3 = 1.7320508075688772935;

// Area [m^2] of the aperture image on the n x n grid spanning D.
double AreaM2(const Image& a, double diameter_m) {
  const double pixel = diameter_m / static_cast<double>(a.rows());
  return a.sum() * pixel * pixel;
}

// Area of {x >= 0, |y| <= w/2, x^2 + y^2 <= r^2}: one radial vane of width w inside a disk of radius r,
//     F(r) = h sqrt(r^2 - h^2) + r^2 asin(h / r)   (h = w/2, r >= h),   pi r^2 / 2 for r < h (a half disk).
double VaneInDisk(double r, double w) {
  const double h = 0.5 * w;
  if (r <= h) return 0.5 * kPi * r * r;
  return h * std::sqrt(r * r - h * h) + r * r * std::asin(h / r);
}

ApertureGeometry Circular(double diameter, double obstruction, int vanes, double width, double offset) {
  ApertureGeometry g;
  g.pupil = PupilGeometry{diameter, obstruction};
  g.spiders.count = vanes;
  g.spiders.width_m = width;
  g.spiders.angle_offset_rad = offset;
  return g;
}

// Keck-like primary: 36 hexagonal segments of 1.8 m corner to corner (flat-to-flat 1.8 sqrt(3)/2 m), 3 rings
// without the central segment, 3 mm gaps, on an 11 m grid (11.4 m for wider gaps, which push the outer
// corners beyond 5.5 m).
ApertureGeometry Keck(double gap_m = 0.003, double rotation = 0.0) {
  ApertureGeometry g;
  g.pupil = PupilGeometry{gap_m > 0.005 ? 11.4 : 11.0, 0.0};
  g.outline = ApertureOutline::kHexSegments;
  g.segments.rings = 3;
  g.segments.flat_to_flat_m = 1.8 * kSqrt3 / 2.0;
  g.segments.gap_m = gap_m;
  g.segments.central_segment = false;
  g.segments.rotation_rad = rotation;
  return g;
}

TEST(ApertureTest, PlainCircleIsExactlyCircularPupil) {
  for (Index n : {64, 65, 128}) {
    for (double obstruction : {0.0, 0.3}) {
      for (int s : {1, 8}) {
        const Image a = Aperture(n, Circular(8.0, obstruction, 0, 0.0, 0.0), s);
        const Image b = CircularPupil(n, PupilGeometry{8.0, obstruction}, s);
        EXPECT_TRUE((a == b).all()) << "n " << n << ", obstruction " << obstruction << ", supersample " << s;
      }
    }
  }
}

// Spider areas. n = 256, supersample s = 16. Oracle: disk minus obstruction minus count * (F(R) - F(R_obs))
// where no vanes overlap outside the obstruction, and for the unobstructed cross pi R^2 - (4 F(R) - w^2) (two
// full strips overlapping in a w x w square).
// Discretisation: a vane edge parallel to the grid is quantised to the sub-pixel pitch D/(n s) (2.0 mm for
// D = 8.2 m), so an axis-aligned vane's area can be off by up to D/(n s w) of itself: 3.9% for a 5 cm vane
// here (measured 3.92%: the worst case), 2.3% for 8 cm. Vanes at general angles cross the sub-grid at all
// phases and the errors average out (measured 0.002% - 0.5%). The disk's own edge adds ~1e-5 relative
// (pupil_test). Tolerances: the vane-blocked area within 1.05 D/(n s w) (aligned) or 1% (rotated) of itself,
// and the total area within that error plus 2e-5. (s = 64 reduces the aligned error 4-fold.)
TEST(ApertureTest, SpiderAreasMatchTheAnalyticArea) {
  struct Case {
    double diameter, obstruction;
    int vanes;
    double width, offset;
    bool aligned;
  };
  const Case cases[] = {
      {8.2, 0.14, 4, 0.05, 0.0, true},       // VLT-like cross along the axes
      {8.2, 0.14, 4, 0.05, 0.3, false},      // the same, rotated
      {8.0, 0.3, 3, 0.10, kPi / 2, true},    // three vanes at 120°, one along +y
      {8.0, 0.0, 4, 0.08, 0.0, true},        // unobstructed cross
      {39.0, 0.28, 6, 0.5, kPi / 6, false},  // ELT-like six vanes
  };
  const Index n = 256;
  const int s = 16;
  for (const Case& c : cases) {
    const double r = 0.5 * c.diameter, r_obs = c.obstruction * r;
    const double annulus = kPi * (r * r - r_obs * r_obs);
    const double blocked = c.obstruction > 0.0
                               ? c.vanes * (VaneInDisk(r, c.width) - VaneInDisk(r_obs, c.width))
                               : 4.0 * VaneInDisk(r, c.width) - c.width * c.width;
    const Image with = Aperture(n, Circular(c.diameter, c.obstruction, c.vanes, c.width, c.offset), s);
    const Image without = Aperture(n, Circular(c.diameter, c.obstruction, 0, 0.0, 0.0), s);
    const double area = AreaM2(with, c.diameter);
    const double measured_blocked = AreaM2(without, c.diameter) - area;
    const double vane_tolerance = c.aligned ? 1.05 * c.diameter / (n * s * c.width) : 0.01;
    std::cout << c.vanes << " vanes of " << c.width << " m at " << c.offset << " rad: area " << area
              << " m^2 (analytic " << annulus - blocked << ", rel. error " << area / (annulus - blocked) - 1
              << "); blocked " << measured_blocked << " (analytic " << blocked << ", rel. error "
              << measured_blocked / blocked - 1 << ", bound " << vane_tolerance << ")\n";
    EXPECT_NEAR(measured_blocked / blocked, 1.0, vane_tolerance);
    EXPECT_NEAR(area / (annulus - blocked), 1.0, vane_tolerance * blocked / annulus + 2e-5);
    EXPECT_TRUE((with >= 0.0).all() && (with <= 1.0).all());
  }
}

TEST(ApertureTest, SpidersAreSymmetric) {
  const Image cross = Aperture(128, Circular(8.0, 0.14, 4, 0.1, 0.0), 8);
  EXPECT_TRUE((cross == cross.colwise().reverse()).all());
  EXPECT_TRUE((cross == cross.rowwise().reverse()).all());
  EXPECT_TRUE((cross == cross.transpose()).all());
  // Three vanes, one along +y (larger row): mirror-symmetric about the y axis only.
  const Image tripod = Aperture(128, Circular(8.0, 0.2, 3, 0.1, kPi / 2), 8);
  EXPECT_TRUE((tripod == tripod.rowwise().reverse()).all());
  EXPECT_FALSE((tripod == tripod.colwise().reverse()).all());
  // The vane along +y (larger row index) covers 80% of the column just left of the centre for rows above the
  // centre (x in [-D/n, 0], vane |x| <= 5 cm), and nothing below it.
  EXPECT_LT(tripod(120, 63), 0.5);
  EXPECT_EQ(tripod(8, 63), 1.0);
  // A vane much narrower than a pixel still removes its area with supersampling, and vanishes without.
  const Image thin = Aperture(128, Circular(8.0, 0.14, 4, 0.005, 0.0), 16);
  const Image thin_binary = Aperture(128, Circular(8.0, 0.14, 4, 0.005, 0.0), 1);
  EXPECT_LT(thin.sum(), CircularPupil(128, PupilGeometry{8.0, 0.14}, 16).sum());
  EXPECT_TRUE((thin_binary == CircularPupil(128, PupilGeometry{8.0, 0.14}, 1)).all());
}

TEST(ApertureTest, KeckLikeSegmentLayout) {
  const ApertureGeometry g = Keck();
  EXPECT_EQ(SegmentCount(g.segments), 36);
  const Eigen::Matrix2Xd centres = SegmentCentres(g.segments);
  ASSERT_EQ(centres.cols(), 36);
  const double p = g.segments.flat_to_flat_m + g.segments.gap_m;
  // Ring 1 first: six centres at distance p.
  for (int q = 0; q < 6; ++q) EXPECT_NEAR(centres.col(q).norm(), p, 1e-12);
  // The outermost corner belongs to a corner segment of ring 3 (centre 3p along a lattice direction) and sits
  // at 30° from it: (3p + f/2, f/(2 sqrt 3)).
  const double f = g.segments.flat_to_flat_m;
  EXPECT_NEAR(SegmentedOuterRadius(g.segments), std::hypot(3 * p + f / 2, f / (2 * kSqrt3)), 1e-12);
  std::cout << "Keck-like outer radius " << SegmentedOuterRadius(g.segments) << " m\n";
  // Counts for other ring numbers: 1 + 3 R (R + 1).
  SegmentGeometry s = g.segments;
  s.central_segment = true;
  for (int rings : {0, 1, 2, 5}) {
    s.rings = rings;
    EXPECT_EQ(SegmentCount(s), 1 + 3 * rings * (rings + 1));
  }
}

// Segment area: 36 (sqrt 3 / 2) f^2 = 75.76 m^2. n = 256 on 11 m (4.3 mm sub-pixel pitch at supersample 16,
// more than the 3 mm gap): the gaps (0.38% of the cell area) are resolved on average because two thirds of
// the gap edges cross the sub-grid at +-60° (the third run along the columns at rotation 0). Measured: total
// area within 1.6e-5 (3 mm gaps) and 1.1e-4 (5 cm gaps, rotation 0), 1.4e-6 rotated; the gap area itself
// (cell area minus segment area) within 1.5% (3 mm) and 0.06% (5 cm). Tolerances: 5e-4 on the total, 5% / 1%
// on the gaps.
TEST(ApertureTest, SegmentedAreaMatchesHexagonAreaWithGaps) {
  const Index n = 256;
  const int s = 16;
  for (double gap : {0.003, 0.05}) {
    for (double rotation : {0.0, 0.25}) {
      const ApertureGeometry g = Keck(gap, rotation);
      const double f = g.segments.flat_to_flat_m, p = f + gap;
      const double segment_area = 36.0 * kSqrt3 / 2.0 * f * f;
      const double area = AreaM2(Aperture(n, g, s), g.pupil.diameter_m);
      ApertureGeometry no_gap = g;
      no_gap.segments.gap_m = 0.0;
      no_gap.segments.flat_to_flat_m = p;  // the cells themselves
      const double cell_area = 36.0 * kSqrt3 / 2.0 * p * p;
      const double gap_area = AreaM2(Aperture(n, no_gap, s), g.pupil.diameter_m) - area;
      std::cout << "gap " << gap << " m, rotation " << rotation << ": area " << area << " m^2 (analytic "
                << segment_area << ", rel. error " << area / segment_area - 1 << "); gaps " << gap_area
                << " m^2 (analytic " << cell_area - segment_area << ")\n";
      EXPECT_NEAR(area / segment_area, 1.0, 5e-4);
      EXPECT_NEAR(gap_area / (cell_area - segment_area), 1.0, gap < 0.01 ? 0.05 : 0.01);
    }
  }
}

TEST(ApertureTest, SegmentedApertureIsMirrorSymmetricAndMatchesABruteForceHexagonTest) {
  const ApertureGeometry g = Keck(0.02);
  const Image a = Aperture(128, g, 8);
  EXPECT_TRUE((a == a.colwise().reverse()).all());
  EXPECT_TRUE((a == a.rowwise().reverse()).all());
  EXPECT_EQ(a(64, 64), 0.0);  // the missing central segment
  // Brute force at the pixel centres (supersample 1), rotated lattice: a point is on the mirror when it lies
  // in some segment {d : |d . u_k| <= f/2, k = 0, 1, 2}.
  for (double rotation : {0.0, 0.2}) {
    const ApertureGeometry h = Keck(0.02, rotation);
    const Image binary = Aperture(128, h, 1);
    const Eigen::Matrix2Xd centres = SegmentCentres(h.segments);
    const double half_f = 0.5 * h.segments.flat_to_flat_m, pixel = h.pupil.diameter_m / 128;
    int mismatches = 0;
    for (Index i = 0; i < 128; ++i) {
      for (Index k = 0; k < 128; ++k) {
        const double y = (i - 63.5) * pixel, x = (k - 63.5) * pixel;
        bool inside = false;
        for (Index q = 0; q < centres.cols() && !inside; ++q) {
          bool in = true;
          for (int j = 0; j < 3; ++j) {
            const double t = rotation + j * kPi / 3;
            in = in &&
                 std::abs((x - centres(0, q)) * std::cos(t) + (y - centres(1, q)) * std::sin(t)) <= half_f;
          }
          inside = in;
        }
        mismatches += (inside ? 1.0 : 0.0) != binary(i, k);
      }
    }
    EXPECT_EQ(mismatches, 0) << "rotation " << rotation;
    EXPECT_NEAR(binary.sum() / a.size(),
                36 * kSqrt3 / 2 * std::pow(2 * half_f, 2) / std::pow(h.pupil.diameter_m, 2), 0.01);
  }
}

TEST(ApertureTest, SegmentsWithObstructionAndSpiders) {
  // A secondary obstruction smaller than the missing central segment changes nothing; spiders remove area.
  ApertureGeometry g = Keck(0.003);
  const Image bare = Aperture(128, g, 8);
  g.pupil.obstruction = 1.4 / 11.0;  // 1.4 m < f = 1.56 m
  EXPECT_TRUE((Aperture(128, g, 8) == bare).all());
  g.spiders.count = 6;
  g.spiders.width_m = 0.05;
  g.spiders.angle_offset_rad = kPi / 6;
  const Image with_spiders = Aperture(128, g, 8);
  EXPECT_LT(with_spiders.sum(), bare.sum());
  EXPECT_TRUE((with_spiders <= bare + 1e-15).all());
}

TEST(ApertureTest, ResampleMaskConservesAreaAndAveragesBlocks) {
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  Image random(64, 64);
  for (Index p = 0; p < random.size(); ++p) random.data()[p] = uniform(rng);
  // Same size: unchanged.
  EXPECT_TRUE((ResampleMask(random, 64) == random).all());
  // Integer factor: block means.
  const Image blocks = ResampleMask(random, 16);
  EXPECT_NEAR(blocks(3, 5), random.block(12, 20, 4, 4).mean(), 1e-15);
  // Any factor, non-square input: the mean transmission is conserved exactly.
  Image rect(300, 170);
  for (Index p = 0; p < rect.size(); ++p) rect.data()[p] = uniform(rng) > 0.5 ? 1.0 : 0.0;
  for (Index n : {7, 128, 401}) {
    EXPECT_NEAR(ResampleMask(rect, n).mean(), rect.mean(), 1e-13) << "n " << n;
  }
  EXPECT_TRUE((ResampleMask(Image::Constant(200, 100, 0.5), 33) - 0.5).abs().maxCoeff() < 1e-15);
  // A finely sampled binary disk resampled to 128 is CircularPupil's grey disk to within a sub-pixel count.
  const Image fine = CircularPupil(1024, PupilGeometry{8.0, 0.3});
  const Image coarse = ResampleMask(fine, 128);
  const Image grey = CircularPupil(128, PupilGeometry{8.0, 0.3}, 8);
  EXPECT_NEAR(coarse.mean(), fine.mean(), 1e-13);
  EXPECT_LT((coarse - grey).abs().maxCoeff(), 0.1);
  EXPECT_TRUE((coarse == coarse.transpose()).all());
}

}  // namespace
}  // namespace aosr
