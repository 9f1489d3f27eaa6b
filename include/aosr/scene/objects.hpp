// Test objects ("truths") on the high-resolution (HR) grid: a 1951 USAF resolution target, a slanted edge,
// point sources, and the demo truth that combines them.
//
// Coordinates (image.hpp): continuous HR pixel coordinates (y, x), pixel (y, x) centred at integers and
// covering [y - 1/2, y + 1/2) x [x - 1/2, x + 1/2). Values are flux per HR pixel.
//
// ## The 1951 USAF target (MIL-STD-150A geometry)
//
// Element e (1..6) of group g has a spatial frequency of
//
//     f(g, e) = 2^(g + (e - 1)/6)   line pairs per mm          (so each group doubles f, each element ×2^(1/6)),
//
// one line pair being one bar plus one equal gap. Hence the bar width is w = 1 / (2 f) mm, the gap between
// bars is w, and each bar is 5w long. An element is three vertical bars (long along y: they measure
// resolution along x) and three horizontal bars (long along x: resolution along y); each triplet fills a
// 5w x 5w square (3 bars + 2 gaps).
//
// Layout (ours; the real chart's spiral of group pairs is not reproduced), in target millimetres with the
// origin at the top-left corner of the target's bounding box:
//   * element (g, e) occupies a 5w tall x 12w wide box: the vertical-bar triplet on the left (bars at
//     x = 0, 2w, 4w), a 2w gap, then the horizontal-bar triplet on the right (x from 7w to 12w, bars at
//     y = 0, 2w, 4w);
//   * the six elements of a group form a column, element 1 on top, left-aligned, with a gap of 2w(g, e)
//     below element e; the column is 12 w(g, 1) wide;
//   * the groups' columns run left to right from first_group (coarsest) to last_group (finest), top-aligned,
//     with a gap of 3 w(g, 1) after the column of group g.
// Each column is half as wide and tall as the one before it, so the target is roughly square and its
// lower-right part is empty (DemoObject puts point sources there). For groups -2..1 the bounding box is
// 61.9 mm tall x 55.5 mm wide. The bounding box is centred on the field centre ((rows-1)/2, (cols-1)/2) and
// scaled by pixels_per_mm; bars falling outside the field are clipped.
//
// Rendering is anti-aliased by area coverage: a pixel's value is background + (bar_value - background) x
// (the fraction of the pixel's area covered by bars). Bars are axis-aligned rectangles, so the coverage of
// one bar is the product of two 1-D interval overlaps and is computed exactly; this is the box-filtered
// (pixel-integrated) image, the limit of s x s supersampling as s -> infinity, and makes the rendered flux
// equal the bars' area to rounding. Bars never overlap, so coverages add.
//
// Sampling note: at pixels_per_mm = p an element is representable on the HR grid (Nyquist: bar width >= 1 px)
// when w p >= 1, i.e. f <= p/2 lp/mm. Elements beyond that alias on the HR grid itself and are the
// "unresolvable even in principle" reference; elements between the camera's Nyquist (bar width r px) and the
// HR one are what super-resolution is meant to recover.
//
// Errors: aosr::InvalidArgument naming the function and the argument.
#pragma once

#include <limits>
#include <string>
#include <vector>

#include "aosr/core/image.hpp"

namespace aosr {

// Spatial frequency of USAF element (group, element) in line pairs per mm: 2^(group + (element - 1)/6).
// element must be in 1..6; group in [-10, 12] (the real charts span -2..9).
double UsafFrequency(int group, int element);

// Bar width of element (group, element) in mm: 1 / (2 UsafFrequency(group, element)).
double UsafBarWidthMm(int group, int element);

struct UsafOptions {
  // Groups rendered, inclusive, coarsest first. Need first_group <= last_group, both in [-10, 12].
  // Default -2..1: a 14x span of frequency (0.25 to 3.56 lp/mm), enough to bracket the camera and HR
  // Nyquist limits of a super-resolution factor up to ~4 at the default scale.
  int first_group = -2;
  int last_group = 1;
  // HR pixels per target mm, > 0 and finite. Default 8: the finest default element (group 1, element 6,
  // w = 0.140 mm) has 1.12 px bars, just above the HR grid's Nyquist limit, and the default target's bounding
  // box is 495 x 444 px.
  double pixels_per_mm = 8.0;
  // Value of the uncovered field and of fully covered bar pixels (flux per HR pixel), finite.
  double background = 0.0;
  double bar_value = 1.0;
  // 0 (default): exact area coverage (see top of file). s >= 1: the classical alternative, the average of
  // s x s point samples at the sub-pixel centres (s = 1 is aliased point sampling); its coverage error is
  // below 2/s per pixel. Kept to compare against, not because it is better. Must be in [0, 64].
  int supersample = 0;
  // The chart turned about the field's centre by this angle [deg], in [-45, 45], positive from +x toward +y
  // (clockwise on a display with y down). Default 0. A test bench tilts its chart by a few degrees so that
  // the bars' edges can be read by the slanted-edge MTF (core/slanted_edge.hpp, core/edge_search.hpp). A turned
  // chart is rendered with exact area coverage of each turned bar (needs supersample 0); UsafBars and
  // UsafElements stay in the chart's own, untilted placement, and the contrast reading (usaf_contrast.hpp)
  // refuses a turned chart.
  double rotation_deg = 0.0;

  // True if every field is in range; otherwise false and, if why != nullptr, *why names the field.
  bool IsValid(std::string* why) const;
};

// An axis-aligned rectangle in continuous HR pixel coordinates: [top, top + height) x [left, left + width).
struct PixelRect {
  double top = 0.0;
  double left = 0.0;
  double height = 0.0;
  double width = 0.0;
  double bottom() const { return top + height; }
  double right() const { return left + width; }
  double area() const { return height * width; }
};

// One bar of the target.
struct UsafBar {
  int group = 0;
  int element = 0;
  bool horizontal = false;  // true: long along x (resolves detail along y); false: long along y
  PixelRect rect;           // HR pixels; unclipped (may extend past the field)
};

// One element: its identification, frequency and bounding box (12w x 5w, see the layout above).
struct UsafElement {
  int group = 0;
  int element = 0;
  double frequency_lp_per_mm = 0.0;
  double bar_width_px = 0.0;  // w x pixels_per_mm
  PixelRect box;              // HR pixels; unclipped
};

// Size of the target's bounding box in mm (depends only on the groups).
struct UsafSize {
  double height_mm = 0.0;
  double width_mm = 0.0;
};
UsafSize UsafTargetSize(const UsafOptions& options);

// The six bars of every element, in the placement UsafTarget(shape, options) renders.
std::vector<UsafBar> UsafBars(Shape shape, const UsafOptions& options);
// Every element's bounding box, in the same placement; ordered by group then element.
std::vector<UsafElement> UsafElements(Shape shape, const UsafOptions& options);

// Renders the target on an HR grid of the given shape (both sides >= 1).
Image UsafTarget(Shape shape, const UsafOptions& options = {});

// A point source at continuous HR pixel coordinates (y, x) with total flux `flux` (any finite value).
struct PointSource {
  double y = 0.0;
  double x = 0.0;
  double flux = 0.0;
};

// Adds each source to *image, its flux split bilinearly over the four pixel centres around (y, x):
// with y0 = floor(y), fy = y - y0 (same for x), pixel (y0, x0) gets (1 - fy)(1 - fx) flux, (y0, x0 + 1) gets
// (1 - fy) fx flux, and so on. The weights sum to 1 (flux conserved) and their centroid is exactly (y, x).
// Every source must satisfy 0 <= y <= rows - 1 and 0 <= x <= cols - 1, so that no flux falls off the grid.
//
// This is a convenience for the demo truth, not a physical rendering: bilinear splitting is a triangle
// filter, so a source's image depends on its sub-pixel phase (a source at a pixel centre is one bright
// pixel, one at a corner is four quarter-bright ones) and is not band-limited. Exact rendering of an
// unresolved source goes through sub-pixel-shifted PSFs in the optics layer.
void AddPointSources(Image* image, const std::vector<PointSource>& sources);

// ## The slanted edge (a knife edge, as bench MTF targets have)
//
// A straight edge through the point (centre_y, centre_x) (HR pixels; NaN: the field centre ((rows − 1)/2,
// (cols − 1)/2)), turned by angle_deg from the column direction: moving one row toward +y moves the edge
// tan(angle) columns toward +x. Its unit normal, in (x, y), is n = (cos θ, −sin θ); the `high` side is the +n
// side (at 0° the right, at 90° the top rows). Values: low + (high − low) × the fraction of the pixel's area on
// the high side, computed exactly: over the pixel square the signed distance to the line is
// s + n_x u + n_y v with (u, v) uniform on [−1/2, 1/2]², whose distribution is the convolution of two boxes of
// widths |n_x| and |n_y| (a trapezoid), so the covered fraction is 1 − F(−s) with F the trapezoid's CDF,
// piecewise quadratic (no supersampling, no cancellation at axis-aligned angles). This is the box-filtered
// image of the half-plane: a slanted-edge MTF of it is the pixel box's, sinc(f cos θ) sinc(f sin θ)
// (core/slanted_edge.hpp).
struct SlantedEdgeTargetOptions {
  // Tilt from the column direction [deg], in [−180, 180]. Default 5 (ISO 12233 edges are ~5° off an axis).
  double angle_deg = 5.0;
  // A point of the edge [HR px]; NaN (default): the field centre. Finite values may lie off the field.
  double centre_y = std::numeric_limits<double>::quiet_NaN();
  double centre_x = std::numeric_limits<double>::quiet_NaN();
  // The levels of the two sides (flux per HR pixel), finite. Default 0 and 1.
  double low = 0.0;
  double high = 1.0;

  bool IsValid(std::string* why) const;
};

// Renders the slanted edge on an HR grid of the given shape (both sides >= 1).
Image SlantedEdgeTarget(Shape shape, const SlantedEdgeTargetOptions& options = {});

// The default demo truth on an HR grid of the given shape (both sides >= 64), deterministic:
//   * the USAF target, groups -2..1, background 0.05, bars 1.0, scaled so its bounding box fills 90% of the
//     field along its tighter dimension (pixels_per_mm = 0.9 min(rows / 61.9, cols / 55.5)), centred;
//   * five point sources in the empty lower-right part of the target's box (below group -1, right of group -2):
//     one isolated source (flux 0.9), a horizontal pair 6 px apart (0.6, 0.8) and a vertical pair 3 px apart
//     (0.5, 0.7): separations chosen in HR pixels so that they straddle typical camera pixel sizes.
// Values lie in [0.05, 1]: sources are at least 2 px apart along some axis, so their bilinear footprints
// never share a pixel, and they sit on the background, away from the bars.
Image DemoObject(Shape shape);

// The USAF options DemoObject renders with on `shape` (groups -2..1, background 0.05, bars 1, its scale).
UsafOptions DemoUsafOptions(Shape shape);

// The bounding box (HR pixels, unclipped) of the demo target's two finest groups (0 and 1): the bars whose
// widths straddle the camera's and the HR grid's resolution limits, what `aosr demo` zooms on.
PixelRect DemoFinestBars(Shape shape);

}  // namespace aosr
