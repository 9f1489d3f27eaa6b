// The data of one reconstruction, shared by every reconstructor (DESIGN.md §3: one forward model).
//
//     y_i = A_i x + n_i,   A_i = D_r ∘ H_i   (core/forward_model.hpp),   i = 0 .. N-1,
//
// with per-pixel inverse-variance weights w_i ≥ 0 (0: the pixel carries no information — bad, saturated,
// NaN/Inf in the data, or outside the trusted region). A weighted least-squares data term is
//
//     ½ Σ_i Σ_p w_i[p] (y_i[p] − (A_i x)[p])².
//
// Rules, written once for all solvers:
//  * frames and the model's LR shape agree; weights, when given, have the frames' shapes, are finite and ≥ 0;
//  * a frame pixel whose weight is 0 is never read (it may hold NaN or Inf);
//  * a weighted pixel must be finite (otherwise InvalidArgument naming frame and pixel: an unmasked NaN is
//    an error, not a silent hole);
//  * offsets (HR pixels, forward_model.hpp's FrameOffset) are what registration-based methods (shift-and-add,
//    Drizzle) use; model-based methods ignore them, the PSFs carry the offsets.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "aosr/core/forward_model.hpp"
#include "aosr/core/image.hpp"

namespace aosr {

// LR pixels [y0, y0 + rows) x [x0, x0 + cols), the same in every frame; rows = cols = 0: every pixel.
struct LrRegion {
  Index y0 = 0, x0 = 0, rows = 0, cols = 0;
  bool all() const { return rows == 0 && cols == 0; }
};

struct ReconstructionProblem {
  std::shared_ptr<const MultiFrameModel> model;  // required
  ImageStack frames;                             // N frames of model->lr_shape()
  ImageStack weights;                            // empty: every pixel weight 1; else N maps, finite, >= 0
  std::vector<FrameOffset> offsets;              // empty or N entries (HR pixels)
  // Where the summary's frame_residual_rms is measured (default: every pixel). A tile's core
  // (solvers/tiling.cpp): the tiled run then takes its cores' residuals from each solver's own final misfit
  // instead of rendering every tile once more. Costs and objectives always cover every pixel.
  LrRegion residual_region;

  int frame_count() const { return static_cast<int>(frames.size()); }
  // Throws InvalidArgument "<function>: <field> ..." unless the rules at the top of the file hold.
  void Validate(const std::string& function) const;
  // Weight of frame i (a map of ones when weights is empty).
  Image Weight(int i) const;
  // True when every weight is the same positive value (and no pixel is masked): the Fourier-domain solvers
  // are then exact; otherwise a weighted/masked path is needed.
  bool HasUniformWeights() const;
  // Frames with unweighted pixels set to 0 (safe to feed to FFT-based code).
  ImageStack CleanFrames() const;
};

// ½ Σ w (y − A x)² and, if `frame_rms` is non-null, the RMS of y_i − A_i x over each frame's weighted pixels
// of problem.residual_region (frame units). x is on model->hr_shape().
double WeightedDataMisfit(const ReconstructionProblem& problem, const Image& x, std::vector<double>* frame_rms = nullptr);

}  // namespace aosr
