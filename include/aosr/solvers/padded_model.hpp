// The multi-frame model with zero-padded (non-periodic) boundaries.
//
// The periodic model (forward_model.hpp) wraps light that leaves one edge of the HR grid back in at the
// opposite edge. A real camera sees a window of an unbounded sky: light from just outside the field
// spills in, and nothing wraps. The padded model reconstructs x on an HR grid larger than the frames'
// footprint and crops:
//
//     y_i = C ( D_r ( h_i ⊛_P x ) ),    x on the padded HR grid P = r · L,
//
// with ⊛_P periodic convolution on P, D_r the camera's r x r pixel sums and C the crop of the frames'
// m-pixel window out of the padded L-pixel LR grid, at (top, left) = (padding, padding) camera pixels.
// The wrap-around of ⊛_P stays out of the window when the padding covers the PSF's extent. Because the
// window is aligned with camera pixels, C ∘ D_r = D_r ∘ C_hr, and the model is exactly the periodic model
// on P whose frames are observed only inside the window: a solver may treat it as the periodic model with
// weight 0 outside (EmbedFrames / EmbedWeights), which is how tikhonov.hpp's CG path uses it.
//
// Operator() is Stack_i(C ∘ D_r ∘ H_i): padded HR vector -> N frames of the window, flattened; its adjoint
// embeds each frame residual with zeros and sums the correlated images (adjoint-tested).
#pragma once

#include <memory>

#include "aosr/core/forward_model.hpp"
#include "aosr/core/linear_operator.hpp"

namespace aosr {

class PaddedModel {
 public:
  // From centred PSF kernels at HR sampling (image.hpp layout), each fitting in the padded grid. The
  // frames' HR footprint is frame_hr (r must divide it); padding >= 0 camera pixels on every side, the
  // padded LR side rounded up to NextFastFftSize (the extra goes to the bottom/right).
  static PaddedModel FromKernels(Shape frame_hr, int r, const ImageStack& centred_psfs, int padding);
  // From a periodic model: its kernels (the inverse transforms of its OTFs, with offsets taken in
  // (−M/2, M/2]) placed on the padded grid. Exact for kernels supported within half the original grid;
  // a kernel with wider support (e.g. the periodic sinc of a sub-pixel shift) is cut there.
  static PaddedModel FromPeriodicModel(const MultiFrameModel& model, int padding);
  // The padding (camera pixels, >= 1) that covers every frame's PSF: the smallest r·padding HR pixels
  // (Chebyshev radius about the kernel origin) holding all but `tail_fraction` of the kernel energy Σh_i²,
  // capped at half the larger LR side. Energy rather than Σ|h|: the band-limited (sinc) ringing of a
  // sub-pixel shift has a slowly decaying Σ|h| tail that would always hit the cap. tail_fraction in (0, 1).
  static int SuggestPadding(const MultiFrameModel& model, double tail_fraction = 1e-4);

  Shape frame_hr_shape() const { return {frame_lr_.rows * r(), frame_lr_.cols * r()}; }
  Shape frame_lr_shape() const { return frame_lr_; }
  Shape padded_hr_shape() const { return periodic_->hr_shape(); }
  Shape padded_lr_shape() const { return periodic_->lr_shape(); }
  int padding() const { return padding_; }  // camera pixels on the top and left
  int r() const { return periodic_->r(); }
  int frames() const { return periodic_->frames(); }

  // The periodic model on the padded grid (for Fourier preconditioners and per-bin systems).
  const MultiFrameModel& periodic() const { return *periodic_; }
  std::shared_ptr<const MultiFrameModel> periodic_ptr() const { return periodic_; }
  // Stack_i(C ∘ D_r ∘ H_i): padded_hr_shape -> N frames of frame_lr_shape.
  const OperatorPtr& Operator() const { return op_; }

  // Frames of the window for an object on the padded grid.
  ImageStack Render(const Image& padded_x) const;
  // Window frames -> padded LR frames (zero outside the window). Checks count and shapes.
  ImageStack EmbedFrames(const ImageStack& frames) const;
  // Window weights (empty: all 1) -> padded LR weights, 0 outside the window.
  ImageStack EmbedWeights(const ImageStack& weights) const;
  // The frames' HR footprint out of a padded object, and the reverse (zeros outside).
  Image CropObject(const Image& padded_x) const;
  Image EmbedObject(const Image& x) const;

 private:
  PaddedModel(Shape frame_lr, int padding, std::vector<ComplexImage> padded_otfs, int r, Shape padded_hr);

  Shape frame_lr_;
  int padding_ = 0;
  std::shared_ptr<const MultiFrameModel> periodic_;
  OperatorPtr op_;
};

}  // namespace aosr
