// The multi-frame image-formation model shared by the simulator and every reconstructor.
//
//     y_i = D_r( h_i ⊛ x ),   i = 0 .. N-1                            (DESIGN.md §1, noise excluded)
//
//  x    object on the HR grid (hr_shape), flux per HR pixel.
//  h_i  exposure i's PSF at HR sampling, applied by periodic convolution through its transfer function
//       H_i (half spectrum, see fft.hpp). A sub-pixel pointing offset is part of h_i.
//  D_r  the camera: each LR pixel sums its r x r HR pixels (see image.hpp for the pixel layout).
//
// Fourier structure. Write M = hr_shape, m = lr_shape = M / r. D_r is "box-filter then subsample":
// D_r z = S_r (b ⊛ z) with b the r x r box anchored so that (b ⊛ z)[n] = Σ_{k∈{0..r-1}²} z[n+k], whose
// transfer function is B(f) = Π_axes Σ_{k=0}^{r-1} exp(+2πi f_a k / M_a). Subsampling folds the HR
// spectrum, so each LR frequency u couples the r² HR frequencies f = u + k∘m (k ∈ {0..r-1}²):
//
//     Y_i(u) = (1/r²) Σ_k B(u + k∘m) H_i(u + k∘m) X(u + k∘m).
//
// AliasedSystem(u) returns that N x r² matrix; Fourier-domain solvers build on it. B vanishes on the
// alias lattice (f_a a non-zero multiple of m_a), so those HR frequencies are invisible to any design.
//
// A PSF that changes across the field (WithPsfField; core/psf_field.hpp, DESIGN.md §1 "Wide fields"). The
// same model extended: with node k's PSFs h_{i,k} and interpolation weights w_k,
//
//     y_i = D_r Σ_k H_{i,k} (w_k ⊙ x),
//
// built from the same primitives (Σ_k (node k's model) ∘ Mask(w_k)), so its adjoint is exact by construction.
// Operator(), FrameOperator(i) and Render are then the space-variant ones. The Fourier structure (otf,
// Otf, AliasedSystem) stays that of the model WithPsfField was called on, an isoplanatic approximation (the
// PSFs at the field's centre, typically): what a Fourier preconditioner or a λ rule may use, never a solve
// that claims exactness. space_variant() tells the solvers which they have; those that need the Fourier
// structure to be exact refuse a space-variant model or take their operator path.
#pragma once

#include <Eigen/Dense>
#include <vector>
#include <memory>

#include "aosr/core/linear_operator.hpp"
#include "aosr/core/psf_field.hpp"

namespace aosr {

// A frame's pointing offset in HR pixels (+dx moves the scene toward +x). Designed tip/tilt offsets are
// carried by the PSFs; this records them for the methods that register frames instead of modelling them.
struct FrameOffset {
  double dy = 0.0;
  double dx = 0.0;
};

class MultiFrameModel {
 public:
  // `otfs[i]` is frame i's half-spectrum transfer function on the HR grid (hr.rows x hr.cols/2+1).
  // r >= 1 must divide both HR sides. Throws InvalidArgument on any inconsistency.
  MultiFrameModel(Shape hr, int r, std::vector<ComplexImage> otfs);
  // From centred PSF kernels at HR sampling (each must fit in the HR grid; not renormalised).
  static MultiFrameModel FromKernels(Shape hr, int r, const ImageStack& centred_psfs);

  Shape hr_shape() const { return hr_; }
  Shape lr_shape() const { return {hr_.rows / r_, hr_.cols / r_}; }
  int r() const { return r_; }
  int frames() const { return static_cast<int>(otfs_.size()); }
  const ComplexImage& otf(int i) const { return *otfs_.at(i); }

  // D_r ∘ H_i, and the stack over frames (rows = N · lr size, cols = hr size).
  const OperatorPtr& FrameOperator(int i) const { return frame_ops_.at(i); }
  const OperatorPtr& Operator() const { return op_; }

  // Noise-free frames of an object on the HR grid.
  ImageStack Render(const Image& x) const;
  // Frames <-> the stacked vector Operator() works on. Checks the count and shape of frames.
  Vector Flatten(const ImageStack& frames) const;
  ImageStack Unflatten(const Vector& y) const;

  // The pixel transfer function B(f) at full-spectrum HR frequency bin (fy, fx).
  Complex PixelTransfer(Index fy, Index fx) const;
  // The N x r² matrix of the LR frequency bin (uy, ux), columns ordered k = ky * r + kx for the HR bins
  // (uy + ky·m_rows, ux + kx·m_cols).
  Eigen::MatrixXcd AliasedSystem(Index uy, Index ux) const;
  // Full-spectrum H_i at HR bin (fy, fx), from the stored half spectrum by Hermitian symmetry.
  Complex Otf(int i, Index fy, Index fx) const;

  // This model with the space-variant operator of `grid` and node_psfs[k][i] (node k, frame i; centred kernels
  // at HR sampling, each fitting the HR grid), see the top of the file. The grid must cover this model's HR
  // grid and give this model's frame count at every node. InvalidArgument otherwise.
  MultiFrameModel WithPsfField(const PsfFieldGrid& grid, const std::vector<ImageStack>& node_psfs) const;
  bool space_variant() const { return !field_grid_.empty(); }
  // The isoplanatic model of the same transfer functions (this model without WithPsfField's operator).
  MultiFrameModel Isoplanatic() const;
  const PsfFieldGrid& field_grid() const { return field_grid_; }

 private:
  Shape hr_;
  int r_;
  std::vector<std::shared_ptr<const ComplexImage>> otfs_;  // Hermitian, shared with frame_ops_
  std::vector<OperatorPtr> frame_ops_;
  OperatorPtr op_;
  std::vector<Complex> box_y_, box_x_;  // 1-D pixel transfer per axis
  PsfFieldGrid field_grid_;             // space-variant models only (WithPsfField)
};

}  // namespace aosr
