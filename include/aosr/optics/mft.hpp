// Matrix Fourier transform (MFT): the exact 2-D DFT of a sampled pupil-plane field evaluated on an arbitrary
// focal-plane grid (any pitch, any size), as two dense matrix products (R. Soummer, L. Pueyo, A.
// Sivaramakrishnan, R. J. Vanderbei, "Fast computation of Lyot-style coronagraph propagation", Opt. Express
// 15, 15935 (2007)).
//
// Maths. Pupil coordinates u are in units of the telescope diameter D, focal-plane angles alpha in units of
// lambda/D, so the Fraunhofer kernel is exp(-2 pi i u.alpha) whatever the wavelength. The input is an n_y x
// n_x field whose pixel pitch is 1/span (span = number of input pixels across D), with pupil.hpp's centring:
//     u_y(k) = (k - (n_y - 1)/2) / span,          u_x(l) = (l - (n_x - 1)/2) / span.
// The output has rows x cols samples at pitch s (pixel_scale_lod, in lambda/D) with image.hpp's
// centred-kernel rule: the optical axis is output pixel (rows/2, cols/2) (integer division), so
//     alpha_y(p) = (p - rows/2) s,               alpha_x(q) = (q - cols/2) s,
//     out(p, q)  = (1/span^2) sum_{k,l} E(k, l) exp(-2 pi i (u_y(k) alpha_y(p) + u_x(l) alpha_x(q)))
//                = (1/span^2) [W_y E W_x^T](p, q),
//     W_y(p, k)  = exp(-2 pi i alpha_y(p) u_y(k)),   W_x(q, l) = exp(-2 pi i alpha_x(q) u_x(l)).
// The separable kernel is what makes this two matrix products: O(rows n_y n_x + rows n_x cols) (or the other
// order, whichever is cheaper) instead of O(rows cols n_y n_x); W_y and W_x are built once per plan.
//
// Normalisation. The factor 1/span^2 = (pixel area in D^2 units) makes out(alpha) the Riemann sum of the
// continuous Fourier transform  E^(alpha) = integral E(u) exp(-2 pi i u.alpha) d^2u  (u in D, alpha in
// lambda/D). Parseval then reads
//     sum_{p,q} |out(p, q)|^2 s^2  ->  integral |E^|^2 d^2alpha = integral |E|^2 d^2u
//                                   =  sum_{k,l} |E(k,l)|^2 / span^2,
// the pupil energy in units of D^2 (pi/4 for a clear unit-amplitude disk). The sum over the output equals
// the pupil energy exactly (to rounding) when the output covers one full period of the sampled field's
// transform, rows s = cols s = span, with s <= 1 (the discrete Parseval identity); on a finite window it is
// the energy falling inside the window. (|out| is periodic with period span lambda/D along each axis, like
// any transform of a sampled field.) Unlike an FFT, pitch and window are free: no zero padding to reach a
// fine pitch, and no need to compute a whole period when only a small window around the core is wanted.
//
// Sign convention: a field E = exp(+2 pi i t.u) (a tilted wavefront) gives |out|^2 peaked at alpha = +t, i.e.
// toward larger output row/column index.
//
// Thread safety: a plan is immutable after construction; Apply/ApplyAdjoint may run concurrently.
#pragma once

#include <Eigen/Core>
#include <string>

#include "aosr/core/image.hpp"

namespace aosr {

struct MftGeometry {
  // Shape (n_y x n_x) of the input field; both >= 1.
  Shape input;
  // Number of input pixels across the pupil diameter D (> 0): the input pitch is D / span. For a pupil from
  // pupil.hpp (an n x n grid spanning D) this is n; a field zero-padded to a larger grid keeps span = n.
  double pupil_span_px = 0.0;
  // Shape (rows x cols) of the output; both >= 1. The optical axis is pixel (rows/2, cols/2).
  Shape output;
  // Output pitch s in lambda/D (> 0). s = pixel_scale_rad * D / lambda. Nyquist sampling of the PSF is
  // s = 0.5; flux is conserved over an infinite grid for s <= 1.
  double pixel_scale_lod = 0.0;

  // True when all fields are in range; otherwise false and `why` (if non-null) names the bad field.
  bool IsValid(std::string* why) const;
};

// A precomputed MFT (the two DFT matrices) for one geometry; apply it to many fields.
class MatrixFourierTransform {
 public:
  // Throws InvalidArgument (naming the field) when the geometry is invalid.
  explicit MatrixFourierTransform(const MftGeometry& geometry);

  // out = (1/span^2) W_y E W_x^T for an input of shape geometry().input; output shape geometry().output.
  ComplexImage Apply(const ComplexImage& field) const;
  // The exact adjoint: E' = (1/span^2) W_y^H out W_x^* (conjugate transposes), for gradients through the PSF.
  ComplexImage ApplyAdjoint(const ComplexImage& image) const;

  const MftGeometry& geometry() const { return geometry_; }

 private:
  MftGeometry geometry_;
  Eigen::MatrixXcd w_y_;    // rows x n_y
  Eigen::MatrixXcd w_x_t_;  // n_x x cols (W_x transposed)
  double scale_ = 1.0;      // 1 / span^2
  bool rows_first_ = true;  // evaluate (W_y E) W_x^T (true) or W_y (E W_x^T) (false), whichever is cheaper
};

// One-shot MFT of `pupil_field` (span = pupil_span_px input pixels across D) onto an `output` grid of pitch
// `pixel_scale_lod` lambda/D. Builds a plan each call; keep a MatrixFourierTransform for repeated use.
ComplexImage Mft(const ComplexImage& pupil_field, double pupil_span_px, double pixel_scale_lod, Shape output);

}  // namespace aosr
