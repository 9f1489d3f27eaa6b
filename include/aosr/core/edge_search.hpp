// Finding straight edges for the slanted-edge MTF (slanted_edge.hpp) when no region is given: on a test chart
// (the USAF bars, a knife edge), on a reconstruction of one, or on a measured frame.
//
// ## The method
//
// 1. Gradients by the Sobel operator; an edge pixel is one whose gradient magnitude is at least `threshold` of
//    the image's strong gradients (the 99.9th percentile of the magnitudes, so that one hot pixel does not set
//    the scale) and a local maximum across the edge (non-maximum suppression along the row for an edge nearer
//    the column direction, along the column otherwise).
// 2. Edge pixels of one orientation (nearer vertical or nearer horizontal) and one polarity (dark to bright
//    toward +x, or toward −x) are linked into 8-connected chains; a chain becomes a candidate when a straight
//    line fits it (RMS residual <= 0.75 px), it has about one pixel per row along it (no branches: corners and
//    crossings are dropped) and spans at least min_length_px.
// 3. Each candidate gets a region for MeasureSlantedEdgeMtf: its rows, less a tenth at each end (the corners of
//    a bar), and across the edge as far as the nearest other strong gradient allows on both sides in every row
//    (at most max_half_width_px, and 2 px short of the next edge pixel, whose blur it keeps out). An edge with
//    less than 5 px clear on a side is listed but not measured (the measurement needs the edge >= 5 px from the
//    region's sides, and a level on each side to read). Candidates with room come first, longest first.
//
// MeasureSlantedEdgeMtfAuto tries the whole image first (a frame holding one edge, as the slanted-edge scene
// object renders), then each candidate in order, and returns the first that the measurement accepts, with the
// region used. When none does it throws InvalidArgument saying what was found and why each was refused. Edges
// along an axis are the common case there: the USAF bars of an untilted chart lie within a few hundredths of a
// degree of the columns and rows, and an e-SFR needs the edge to cross at least one pixel of phase (a tilt of
// 2-10° on a chart, as test benches mount it; scene objects `usaf` with `rotation_deg`, or `slanted-edge`).
//
// API rules: options are validated (IsValid names the field); InvalidArgument for an empty or non-finite image.
#pragma once

#include <string>
#include <vector>

#include "aosr/core/image.hpp"
#include "aosr/core/slanted_edge.hpp"

namespace aosr {

struct EdgeSearchOptions {
  // Edge pixels: gradient magnitude >= threshold x the 99.9th percentile of the magnitudes, in (0, 1).
  double threshold = 0.3;
  // Shortest chain kept, pixels along the edge, >= 8 (the measurement's own minimum is 20).
  int min_length_px = 20;
  // The region's half-width across the edge, at most this, [6, 1000]. Default 32 (the ESF over ±32 px).
  int max_half_width_px = 32;
  // Candidates returned, longest first, [1, 1000].
  int max_candidates = 50;

  bool IsValid(std::string* why) const;
};

struct EdgeCandidate {
  PixelRoi roi;           // the region to measure it in
  bool vertical = true;   // nearer the column direction (x varies across it)
  double angle_deg = 0;   // signed, from the nearer axis (the measurement's convention: tan = px across per px along)
  Index length_px = 0;    // pixels along the edge (before the ends are trimmed)
  double fit_rms_px = 0;  // RMS residual of the chain about its line
  double contrast = 0;    // |mean level at +half-width/2 − at −half-width/2| across the edge, image units
  Index clear_px = 0;     // px clear of the next edge on the nearer side (the region's half-width); under 5 the
                          // edge is not measured (the bars of a chart too small for the sampling)
};

// The straight edges of an image (step 1-3 above), longest first.
std::vector<EdgeCandidate> FindStraightEdges(const Image& image, const EdgeSearchOptions& options = {});

struct AutoEdgeMtf {
  SlantedEdgeMtf mtf;
  PixelRoi roi;             // the region measured (the whole image: 0, 0, cols, rows)
  bool whole_image = false; // the whole image held one measurable edge
  int candidate = -1;       // else the index of the candidate used
  std::vector<EdgeCandidate> candidates;
  std::vector<std::string> refused;  // why each candidate tried before it was refused, in order
};

// The slanted-edge MTF of an image with no region given: the whole image, else the first candidate edge that
// measures (options.roi is ignored; the other options apply to every attempt).
AutoEdgeMtf MeasureSlantedEdgeMtfAuto(const Image& image, const SlantedEdgeOptions& options,
                                      const EdgeSearchOptions& search = {});

}  // namespace aosr
