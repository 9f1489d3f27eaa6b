// Telescope apertures beyond the plain (obstructed) disk: spider vanes, hexagonal segmented primaries with
// gaps, and arbitrary masks supplied as images, all on pupil.hpp's n x n grid spanning the diameter D.
//
// Geometry (metres in the pupil, origin at the pupil centre, x toward +column, y toward +row, angles from +x
// toward +y; the grid is pupil.hpp's: pixel centre (i, k) at y = (i - (n-1)/2) D/n, x = (k - (n-1)/2) D/n):
//
//  * Outline. kCircular: the disk r <= D/2 (CircularPupil's). kHexSegments: the union of regular hexagonal
//    segments of flat-to-flat size f, whose centres lie on a hexagonal lattice of pitch p = f + g (g: the gap
//    between the facing flats of neighbouring segments). Lattice vectors p (cos t, sin t) and
//    p (cos(t + 60°), sin(t + 60°)) with t = segments.rotation_rad; neighbouring segments face each other
//    with a flat, so each hexagon is {d : |d . u_k| <= f/2, u_k = (cos(t + k 60°), sin(t + k 60°)), k = 0, 1,
//    2}. Segment (a, b) (centre a p u_0 + b p u_1) lies in ring max(|a|, |b|, |a + b|); rings 0..R hold 1 + 3
//    R (R + 1) segments (R = 3: 37; without the central segment, Keck's 36). Area of one segment: (sqrt(3)/2)
//    f^2. The segments must fit inside the grid (outermost corner <= D/2); they are not clipped by the
//    circle.
//  * Central obstruction. The disk r < obstruction * D/2 is opaque (pupil.obstruction, PupilGeometry's
//    meaning), for both outlines. For a segmented primary it models the secondary mirror's shadow.
//  * Spiders. `count` radial vanes of width w, starting at the pupil centre; vane k runs along
//    u = (cos a_k, sin a_k), a_k = angle_offset_rad + 2 pi k / count, and blocks {p : p . u >= 0, |p . v| <=
//    w/2} (v = u rotated by +90°). Two opposite vanes make one full strip of width w across the pupil (4
//    vanes: a cross, as on the VLT or Gemini to a first approximation; real vanes are often offset from the
//    centre, which this model does not represent). Where no vanes overlap outside the obstruction (i.e. the
//    obstruction radius exceeds w / (2 sin(pi / count))), a vane removes exactly
//        F(R) - F(R_obs),   F(r) = h sqrt(r^2 - h^2) + r^2 asin(h / r),   h = w/2,
//    of a disk of radius R (the area of the half-strip inside the annulus), which the tests check.
//  * Transmission is outline AND NOT obstruction AND NOT spiders: the result is in [0, 1].
//
// Sampling (the rule of pupil.hpp, extended): with supersample = 1 a pixel transmits 1 when its centre does,
// else 0 (so a plain circular aperture equals CircularPupil(n, pupil, 1) exactly). With supersample s > 1 a
// pixel holds the fraction of an s x s grid of sub-pixel centres that transmit: grey, anti-aliased edges
// whose sum estimates the aperture area. Pixels whose centre lies farther than half a pixel diagonal from
// every edge (circle, obstruction, vane or hexagon boundary) are uniform and are not subsampled, so the cost
// is O(n^2 + s^2 * (edge pixels)). The per-pixel error of a covered fraction is at most ~ 1/s for a straight
// edge crossing the pixel (one sub-row or sub-column misjudged); along an edge the errors of neighbouring
// pixels largely cancel unless the edge is aligned with the sub-grid. The worst case is a vane parallel to
// the grid axes: its width is quantised to the sub-pixel pitch D/(n s), so its area can be off by up to D/(n
// s w) of itself (3.9% for a 5 cm vane at n = 256, s = 16 on 8.2 m; vanes at general angles: 0.002 - 0.5%).
// Measured (tests/optics/aperture_test.cpp, n = 256, s = 16): spidered disks within 2e-5 (rotated vanes) to
// 6e-4 (axis-aligned vanes) of the analytic area; the Keck-like 36-segment primary within 1.6e-5 with 3 mm
// gaps. Vanes narrower than a pixel need s >= 4 to be represented at all (with s = 1 a vane of width < D/n
// can fall between pixel centres and vanish).
//
// Masks given as images (e.g. a measured pupil read through aosr::io; optics does not depend on io) are
// resampled by ResampleMask: exact area-weighted averaging of the piecewise-constant input over each output
// pixel (the limit of infinite supersampling), which conserves the transmitted area and gives grey edges.
#pragma once

#include <string>

#include "aosr/core/image.hpp"
#include "aosr/optics/pupil.hpp"

namespace aosr {

struct SpiderGeometry {
  // Number of radial vanes, 0 .. 64. 0: no spiders. 4 at 90° is the common cross; 3 at 120° is also common.
  int count = 0;
  // Width w of each vane [m]; finite, > 0 when count > 0 and < D. Typical: 0.02 - 0.05 m on 8 m telescopes.
  double width_m = 0.0;
  // Azimuth of the first vane [rad] from +x toward +y (larger row); finite. Vane k is at
  // angle_offset_rad + 2 pi k / count. 0 with count = 4 puts the vanes along the grid axes.
  double angle_offset_rad = 0.0;
};

struct SegmentGeometry {
  // Number of rings of segments around the central one, 0 .. 50. 3 gives 37 positions (Keck: 36 segments
  // because the central one is missing); 0 is a single segment.
  int rings = 0;
  // Flat-to-flat size f of each hexagonal segment's reflective surface [m]; > 0 and finite.
  // Keck: 1.8 m corner to corner, i.e. f = 1.8 * sqrt(3)/2 = 1.5588 m.
  double flat_to_flat_m = 0.0;
  // Gap g between the facing flats of neighbouring segments [m]; >= 0, finite and < f. Keck: ~3 mm.
  // The lattice pitch (distance between neighbouring segment centres) is f + g.
  double gap_m = 0.0;
  // Whether the central segment (ring 0) is present. false for Keck, whose central position holds the hole.
  bool central_segment = true;
  // Rotation t of the segment lattice [rad]; finite. 0: a lattice direction (and the normal of one flat)
  // points along +x, so segments have corners along +-y.
  double rotation_rad = 0.0;
};

enum class ApertureOutline {
  kCircular,     // disk of diameter pupil.diameter_m (CircularPupil's outline)
  kHexSegments,  // hexagonal segments (`segments`), which must fit inside the grid
};

// The full aperture description. Fields not used by the chosen outline are ignored (and not validated).
struct ApertureGeometry {
  // Grid span D [m] (the n x n grid spans exactly D; for kCircular it is also the outer diameter) and the
  // central obstruction (obstruction diameter / D in [0, 1)), PupilGeometry's meaning.
  PupilGeometry pupil;
  // Outer shape: disk or hexagonal segments.
  ApertureOutline outline = ApertureOutline::kCircular;
  // Segment layout, used when outline == kHexSegments.
  SegmentGeometry segments;
  // Spider vanes (both outlines); count = 0 for none.
  SpiderGeometry spiders;

  // True when every used field is in range; otherwise false and, if `why` is non-null, a message naming the
  // bad field (e.g. "spiders.width_m = -0.1; allowed: ..."), its value and the allowed range.
  bool IsValid(std::string* why) const;
};

// Aperture transmission on the n x n pupil grid (see the top of this header): 1 inside, 0 outside, grey
// covered fractions on the edges when supersample > 1. Requires n >= 1, a valid geometry and 1 <= supersample
// <= 64. Throws InvalidArgument naming the bad argument or geometry field otherwise.
Image Aperture(Index n, const ApertureGeometry& geometry, int supersample = 1);

// Number of segments of a segmented layout: 1 + 3 R (R + 1), minus one without the central segment.
int SegmentCount(const SegmentGeometry& segments);
// Centres (x, y) [m] of the segments, in ring order (ring 0 first), as a 2 x count matrix (row 0: x, row 1:
// y).
Eigen::Matrix2Xd SegmentCentres(const SegmentGeometry& segments);
// Distance from the pupil centre to the farthest segment corner [m]: the radius of the circumscribed circle
// of the segmented primary. The grid diameter D must be at least twice this.
double SegmentedOuterRadius(const SegmentGeometry& segments);

// Resamples a transmission mask onto the n x n pupil grid. `mask` (rows x cols, any size >= 1, values finite
// in [0, 1]) is taken to span the same square D x D as the grid, each input pixel a constant-valued
// rectangle; output pixel (i, k) is the exact area-weighted mean of the input over its footprint:
//     out = R_y * mask * R_x^T,   R(i, j) = n * |[i/n, (i+1)/n) ∩ [j/m, (j+1)/m)|   (unit span),
// so sum(out) / n^2 = sum(mask) / (rows * cols) (the transmitted area is conserved exactly) and edges come
// out grey. With the input's size equal to n the mask is returned unchanged; an integer down-sampling factor
// averages blocks. Throws InvalidArgument for n < 1, an empty mask or values outside [0, 1] or non-finite.
Image ResampleMask(const Image& mask, Index n);

}  // namespace aosr
