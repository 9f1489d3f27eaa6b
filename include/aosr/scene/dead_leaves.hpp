// The dead-leaves model: a synthetic natural-image texture of occluding discs, for evaluating reconstructions
// on content with edges at every scale (rather than on bar targets and stars only).
//
// ## Model (Matheron 1968; Lee, Mumford & Huang 2001, IJCV 41, 35; Gousseau & Roueff 2007, Multiscale Model.
// Simul. 6, 105)
//
// Discs ("leaves") fall one after another on the plane and each hides what lies under it. Their centres form
// a Poisson process, uniform on the plane; their radii are independent with the truncated power-law density
//
//     p(r) ∝ r^(-alpha),   r_min <= r <= r_max,
//
// and each carries an independent grey level, uniform on [grey_min, grey_max). The picture is the stationary
// state, reached when every point of the field is covered. alpha = 3 is the scale-invariant case (the number
// of discs of radius in [r, r + dr] per unit area scales as r^-3 dr, so a zoom by any factor within
// [r_min, r_max] leaves the statistics unchanged: Lee, Mumford & Huang 2001), the one whose radially averaged
// power spectrum follows the ~ f^-2 law of natural images (Field 1987; Ruderman 1994) between 1/r_max and
// 1/r_min, steepening toward f^-3 (isolated sharp edges) above 1/r_min. Gousseau & Roueff 2007 study the
// general alpha and the limits r_min -> 0, r_max -> ∞.
//
// ## Exact simulation on a window
//
// Drawing leaves *front to back* (the first drawn is on top) and letting each one paint only points that no
// earlier leaf covers gives exactly the stationary picture, and stops as soon as the window is covered (the
// "perfect simulation" of Kendall & Thönnes 1999). The window is the field [-1/2, rows - 1/2) x
// [-1/2, cols - 1/2) (HR pixel coordinates, image.hpp), of height H and width W. A leaf of radius r meets it
// iff its centre lies within distance r of the window. Among the Poisson leaves, those that meet the window
// have radii with density ∝ p(r) A(r), A(r) = HW + 2(H + W) r + π r² the area of the window dilated by the
// disc, and centres uniform on that dilated window. We propose r from p(r) (H + 2r)(W + 2r) (a mixture of
// three truncated power laws, r^-alpha, r^(1-alpha), r^(2-alpha), sampled exactly) and the centre uniformly
// on the window's bounding rectangle dilated by r, and reject proposals whose centre falls in a corner beyond
// distance r (acceptance >= π/4): the accepted leaves are exactly the window-meeting leaves of the stationary
// process, with no wasted draws even when r_max is much larger than the field.
//
// ## Pixels
//
// Each HR pixel is the mean of s x s point samples at its sub-pixel centres (supersample s): a box-filtered,
// anti-aliased image whose edge pixels hold the covered fractions to within O(1/s). The simulation runs on
// the s-times finer grid and stops when every sample is painted; tiles of 16 x 16 samples with an uncovered
// count let large late leaves skip covered regions, so the cost is about the number of leaves drawn (expected
// ~ (window area / mean leaf area) · ln(samples)) plus the samples painted once each.
//
// Determinism: one stream, DeriveSeed(seed, 3) (ao/random.hpp); five uniform deviates per proposal (mixture
// component, radius, centre y, centre x, grey).
//
// Errors: aosr::InvalidArgument naming the function and the argument or field.
#pragma once

#include <cstdint>
#include <string>

#include "aosr/core/image.hpp"

namespace aosr {

struct DeadLeavesOptions {
  // Radius range [HR px], finite, 0 < r_min_px < r_max_px <= 10^4. Default 1..64: edges down to the HR pixel
  // (the scale super-resolution is meant to recover) and objects up to a quarter of a 256-pixel field.
  double r_min_px = 1.0;
  double r_max_px = 64.0;
  // Exponent alpha of p(r) ∝ r^-alpha, finite, in [1, 6]. Default 3: scale invariance (see top of file).
  double radius_exponent = 3.0;
  // Grey levels, uniform on [grey_min, grey_max), finite, grey_min < grey_max. Default [0, 1).
  double grey_min = 0.0;
  double grey_max = 1.0;
  // Point samples per HR pixel side, in [1, 16]. Default 4: edge pixels within ~1/8 of their covered fraction
  // at 16 samples per pixel, for 16x the samples of point sampling.
  int supersample = 4;
  // Safety cap on the leaves drawn, >= 1. Default 10^8, far above the ~10^6 a 1024² field with r_min = 1
  // needs; if reached, the remaining holes get the mean grey (grey_min + grey_max)/2 and the summary reports
  // them.
  std::int64_t max_leaves = 100000000;

  // True if every field is in range; otherwise false and, if why != nullptr, *why names the field.
  bool IsValid(std::string* why) const;
};

// What a dead-leaves draw did.
struct DeadLeavesSummary {
  std::int64_t leaves_drawn = 0;       // leaves meeting the window, including fully hidden ones
  std::int64_t leaves_visible = 0;     // leaves that painted at least one sample
  std::int64_t samples = 0;            // rows · cols · supersample²
  std::int64_t uncovered_samples = 0;  // 0 unless max_leaves was reached
  bool complete() const { return uncovered_samples == 0; }
};

// A dead-leaves image on an HR grid of shape hr (both sides >= 1), deterministic per seed. If summary is not
// null it receives the statistics of the draw.
Image DeadLeaves(Shape hr, const DeadLeavesOptions& options, std::uint64_t seed,
                 DeadLeavesSummary* summary = nullptr);

}  // namespace aosr
