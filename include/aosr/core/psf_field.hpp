// A PSF that changes across the field, sampled on a grid of field points and interpolated bilinearly between
// them (issue 31; the piecewise-linear "PSF interpolation" of Nagy & O'Leary 1998, in the unified notation of
// Denis, Thiébaut, Soulez et al., "Fast approximations of shift-variant blur", IJCV 2015). The simulator
// renders through it, and the reconstructors model it (tiles with local PSFs, solvers/tiling.hpp).
//
// Geometry (HR pixels of the frame, pixel centres at integer coordinates, image.hpp). The grid has ny x nx
// nodes, node (j, i) (index k = j·nx + i) at
//
//     y_j = j (H − 1) / (ny − 1),   x_i = i (W − 1) / (nx − 1)      (ny, nx >= 2: the first and last pixel
//                                                                   centres of the frame are nodes)
//     y_0 = (H − 1) / 2                                             (ny = 1: one row of nodes at the centre)
//
// for an H x W HR frame: nodes on the frame's edges, so no part of the frame is extrapolated.
//
// Interpolation. A source at (y, x) is seen through the PSF
//
//     h(y, x) = Σ_k w_k(y, x) h_k,   w_k(y, x) = tent(u − j) tent(v − i),   tent(t) = max(0, 1 − |t|),
//
// with u = y (ny − 1)/(H − 1) and v = x (nx − 1)/(W − 1) clamped to the grid (a source beyond the outer nodes
// takes the outer nodes' PSFs). The weights are ≥ 0 and sum to 1 at every position, so flux is conserved
// whatever the PSFs; at a node the PSF is the node's exactly; between nodes every pixel of the PSF moves
// linearly. Because the PSF belongs to the *source* (it is the light of a point at (y, x) that spreads), an
// image x is seen as
//
//     y = Σ_k h_k ⊛ (w_k ⊙ x)                                      (w_k the weight maps over the frame)
//
// which is the exact image of a sky of points each blurred by its own interpolated PSF: K convolutions
// instead of one. Linear interpolation's error against the true PSF between nodes is second order in the
// node spacing (the PSF's curvature in field position); bench/results/wide_field.md measures it against a
// denser grid.
#pragma once

#include <array>
#include <vector>

#include "aosr/core/image.hpp"

namespace aosr {

class PsfFieldGrid {
 public:
  PsfFieldGrid() = default;
  // A grid of ny x nx nodes (each 1..64) over an HR frame of `hr` (both sides >= 1; a side with 2 or more
  // nodes needs at least 2 pixels). InvalidArgument (naming `function`) otherwise.
  PsfFieldGrid(Shape hr, int ny, int nx, const char* function = "PsfFieldGrid");

  Shape hr_shape() const { return hr_; }
  int ny() const { return ny_; }
  int nx() const { return nx_; }
  int nodes() const { return ny_ * nx_; }
  bool empty() const { return nodes() == 0; }
  // Node k's position (y, x) in HR pixels of the frame.
  std::array<double, 2> Node(int k) const;
  // The node spacing (y, x) in HR pixels; 0 along an axis with one node.
  std::array<double, 2> Spacing() const;

  // The (node, weight) pairs of the position (y, x) in HR pixels: up to four, weights > 0 summing to 1.
  struct Weight {
    int node = 0;
    double weight = 0.0;
  };
  std::vector<Weight> Weights(double y, double x) const;
  // w_k over the whole frame at every pixel centre: on the HR grid (s = 1), or on a grid s times finer
  // (sky_oversampling), whose pixel (a, b) lies at HR coordinates ((a − (s−1)/2)/s, (b − (s−1)/2)/s).
  Image WeightMap(int k, int s = 1) const;
  // The PSF at (y, x): Σ_k w_k(y, x) psfs[k]; psfs holds one image per node, all of one shape.
  Image Interpolate(const ImageStack& psfs, double y, double x) const;

 private:
  double AxisCoordinate(double p, Index side, int n) const;
  Shape hr_{0, 0};
  int ny_ = 0, nx_ = 0;
};

}  // namespace aosr
