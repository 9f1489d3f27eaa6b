// Primitive linear operators on images (flattened row-major, see image.hpp).
//
// Each is exact to rounding and has an exact adjoint (checked by AdjointTest in the tests):
//   PeriodicConvolution  y = h ⊛ x with periodic boundaries, applied by r2c/c2r FFTs.
//                        Adjoint: correlation, i.e. the conjugate transfer function.
//                        Normal: one FFT pair with |H|^2.
//   LinearConvolution    zero-padded ("same"-size) convolution: x is zero outside its grid and the
//                        output keeps x's shape. Built as Crop ∘ PeriodicConvolution ∘ ZeroPad on a
//                        grid padded by the kernel's extent, so no wrap-around reaches the output.
//   Decimate             camera pixel integration: each output pixel is the *sum* of its r x r HR pixels
//                        (flux-conserving box response, DESIGN.md §1). Adjoint replicates.
//   Mask                 diagonal weighting y = w .* x (a 0/1 mask or per-pixel weights).
//   Gradient             forward differences [D_y x; D_x x] (2·n outputs). Periodic: wraps;
//                        Neumann: the difference across the last row/column is 0.
//   ZeroPad / Crop       embed an image in a larger zero grid at (top, left) / extract it; mutual adjoints.
#pragma once

#include "aosr/core/linear_operator.hpp"

namespace aosr {

enum class Boundary { kPeriodic, kNeumann };

// Periodic convolution on grid `s` by the transfer function `otf_half` (R x (C/2+1) half spectrum of a
// real kernel whose centre is at (0,0); see FftR2C). Throws on shape mismatch or non-finite values.
OperatorPtr PeriodicConvolution(Shape s, ComplexImage otf_half);
// Same, sharing a transfer function that is already Hermitian (HermitianProjection's result) and finite, as a
// MultiFrameModel keeps it: the operator holds no copy of its own.
OperatorPtr PeriodicConvolution(Shape s, std::shared_ptr<const ComplexImage> otf_half_hermitian);
// Same, from a centred kernel (centre at (p/2, q/2)) that fits in `s`.
OperatorPtr PeriodicConvolutionFromKernel(Shape s, const Image& centred_kernel);
// The half-spectrum transfer function of a centred kernel on grid `s`.
ComplexImage TransferFunction(Shape s, const Image& centred_kernel);

// Half-spectrum transfer function of a shift by (dy, dx) pixels (+dx toward +x): exp(-2πi(f·d/M)).
// Integer shifts are exact circular shifts; fractional ones are band-limited (sinc) interpolation, and
// at the Nyquist bin of an even axis the real part is what a real convolution can apply.
ComplexImage ShiftTransfer(Shape s, double dy, double dx);

// Zero-padded convolution of an image of shape `s` by a centred kernel; output shape `s`.
OperatorPtr LinearConvolution(Shape s, const Image& centred_kernel);

// Sum of r x r blocks: `hr` -> (hr.rows/r, hr.cols/r). r >= 1 must divide both sides.
OperatorPtr Decimate(Shape hr, int r);

// Diagonal weighting by `weights` (finite). A 0/1 image is a mask.
OperatorPtr Mask(const Image& weights);

// Forward-difference gradient; output is [D_y x; D_x x], each of shape s.
OperatorPtr Gradient(Shape s, Boundary boundary);

// Embed `inner` at offset (top, left) in a zero `outer` grid, and its adjoint.
OperatorPtr ZeroPad(Shape inner, Shape outer, Index top, Index left);
OperatorPtr Crop(Shape outer, Shape inner, Index top, Index left);

}  // namespace aosr
