// The exact transfer of the linear reconstructors: what a slanted-edge MTF (core/slanted_edge.hpp) of their
// output must read, computed from the model instead of measured.
//
// ## The estimators as linear operators
//
// For a known model and a fixed λ, Tikhonov's estimate is linear in the frames: x̂ = R y. Noise-free,
// y = A x, so x̂ = R A x. On the periodic model (core/forward_model.hpp) each LR bin u couples the r² aliased HR
// frequencies f_k = u + k∘m through the N x r² matrix A(u), and with per-frame weights W = diag(w_i)
// (tikhonov.hpp (1)-(2)) the estimate of the bin is
//
//     X̂(f_·) = R(u) X(f_·),     R(u) = G(u)⁻¹ A(u)ᴴ W A(u),     G(u) = A(u)ᴴ W A(u) + (λ/r²) P(u),      (1)
//
// P = diag |Γ̂(f_k)|² the prior's symbol. (Where G(u) is singular, as at λ = 0 with N < r², the minimum-norm
// solution is the estimator and R(u) is the pseudo-inverse's projection; computed by SVD.) R(u) is r² x r²:
//   * its diagonal T(f_k) = R_kk(u) is the response at HR frequency f to an input at f: the *transfer*;
//   * its off-diagonal R_kk'(u) is aliasing: an input at f_k' puts a response at f_k = f_k' + (k − k')∘m, its
//     frequency moved by a multiple of the camera's sampling frequency 1/r cycles per HR pixel.
// T is a function of the HR frequency alone (each HR bin belongs to exactly one (u, k)). Its value does not
// depend on how λ was chosen (GCV or given) nor on the solution path (Fourier or CG): the minimiser of
// tikhonov.hpp (1) is unique, so only the λ used, the prior and the weights enter.
//
// The target-PSF output (target_psf.hpp) is the same kind of operator, Q(u) A(u) with Q = T (AᴴA + κI)⁻¹Aᴴ and
// the DC row normalised; its diagonal is the effective PSF's transfer, so the exact curve is |DTFT| of the
// effective PSF (the PSF extension of `aosr reconstruct -m linear`'s file): KernelTransferCurve.
//
// ## What a slanted edge reads (why the diagonal)
//
// An edge x(p) = E(n·p) (unit normal n, edge direction t ⊥ n) has its spectrum on the line ℓ = {s n}. The output
// on ℓ is
//
//     X̂(s n) = T(s n) X(s n)  +  Σ_{j≠0} R(s n, s n − j/r) X(s n − j/r),
//
// and the aliased terms would need s n − j/r on ℓ, i.e. the shift j/r (a multiple of the camera's sampling
// frequency per axis) parallel to n: for an edge slanted off the axes it is not (j/r · t ≠ 0). The aliased output
// lies on the parallel lines ℓ + j/r instead: in the image, ripples along the edge of period 1/|j/r · t| (at r = 2
// and 5°, 1/(0.5 sin 5°) ≈ 23 HR px, one phase cycle of the camera's pixels). The ESF bins pixels by their
// distance to the edge over many rows, which averages such ripples out (a residual of the order of 1/(the number
// of their periods along the ROI)). So the edge reads the in-band transfer |T(s n)|, not the aliased power,
// times the transfer of the edge object itself: for an edge area-sampled on the HR grid (scene/objects.hpp
// SlantedEdgeTarget, and any sky integrated over HR pixels) the HR pixel box sinc(s n_x) sinc(s n_y)
// (sinc(z) = sin πz/(πz)); normalised at s = 0 as the edge method normalises. That product is the curve here
// (TransferCurveOptions::hr_pixel_box, normalise_dc). A method with strong aliasing can thus read a high MTF
// while its image of a sinusoid is contaminated by aliases: TransferCurve::alias reports, per frequency, the
// RMS response that an input at f sends to the other r² − 1 frequencies of its bin (the column norm of R off its
// diagonal), on the same scale as the curve.
//
// Along a direction the curve follows the edge's normal (SetDirectionFromEdge: the edge read by
// MeasureSlantedEdgeMtf); T and the alias response are exact on the HR FFT grid (spacing 1/M cycles per HR
// pixel) and interpolated bilinearly (complex T, then the modulus) between its points. A radial average is
// the mean over 180 directions in [0°, 180°) of the modulus at each radius (Hermitian symmetry covers the rest),
// for radii up to the HR Nyquist 0.5.
//
// Tested (tests/solvers/linear_transfer_test.cpp, _physics_test.cpp): T and the alias response against the
// estimator's own output for a sinusoid on the grid (1e-10); the slanted-edge MTF of noise-free Tikhonov and
// target-PSF reconstructions of edge scenes (r = 2 with N = 4 and 2, r = 4 with N = 4; λ = 1e-3 and 3e-2) against
// these curves: worst gap 0.0015 up to the HR Nyquist (issue 33's target: 0.03).
//
// Read such edges with SlantedEdgeOptions::smooth_tails = false. The tail smoothing assumes a monotone LSF tail
// (optics); a reconstruction's LSF rings where T falls steeply, and smoothing the ringing away moved the measured
// curves of the same Tikhonov cases by up to 0.07 (r = 2) and 0.16 (r = 4) from the exact ones. On noisy
// reconstructions the choice is noise against this bias.
//
// TV and MAP have no such curve: their response depends on the signal (contrast, noise); for them the
// slanted-edge curve at the scene's contrast and noise is the answer.
//
// API rules: inputs and options are validated first (InvalidArgument names the function, field and value);
// nothing here returns NaN.
#pragma once

#include <string>
#include <vector>

#include "aosr/core/forward_model.hpp"
#include "aosr/core/image.hpp"
#include "aosr/core/slanted_edge.hpp"
#include "aosr/solvers/problem.hpp"
#include "aosr/solvers/tikhonov.hpp"

namespace aosr {

// Tikhonov's response on the full HR FFT grid (hr rows x cols, bin (0, 0) the zero frequency, unshifted):
// `transfer` T(f) = R_kk(u) of (1), complex; `alias` the RMS of the off-diagonal column of R at f,
// sqrt(Σ_{k≠k'} |R_kk'(u)|²) for f = f_k'.
struct TransferGrid {
  ComplexImage transfer;
  Image alias;
};

// (1) for a model, per-frame weights (N values, each finite and > 0; empty: all 1), the prior of `prior`
// (its `prior` field and spectrum fields; not kFitted, whose spectrum the options do not hold: pass kPowerSpectrum
// with object_power_spectrum = PowerSpectrumGrid(summary.fitted_spectrum, hr) instead) and λ >= 0 (the
// units of tikhonov.hpp (1), i.e. those of the weights). Bins in parallel (deterministic).
TransferGrid TikhonovTransferGrid(const MultiFrameModel& model, const std::vector<double>& frame_weights,
                                  const TikhonovOptions& prior, double lambda);

struct TransferCurveOptions {
  // false (default): along the direction (direction_y, direction_x) in (f_y, f_x) (any non-zero finite vector,
  // normalised here; the default is the x axis). true: the radial average (top of file).
  bool radial = false;
  double direction_y = 0.0;
  double direction_x = 1.0;
  // Frequencies [cycles per HR px]: 0, step, ... <= curve_max. curve_max in (0, 1] (0.5 is the HR Nyquist; the
  // radial average stops there), curve_step in (0, curve_max]. Defaults 0.5 and 0.01. Or the list `frequencies`
  // (each in [0, curve_max]) when non-empty, e.g. the slanted-edge curve's own frequencies.
  double curve_max = 0.5;
  double curve_step = 0.01;
  std::vector<double> frequencies;
  // Multiply by the HR pixel box sinc(f_x) sinc(f_y): what an edge area-sampled on the HR grid carries, so that
  // the curve is the one a slanted edge of the output reads (top of file). Default true.
  bool hr_pixel_box = true;
  // Divide by |T(0)| (the edge method normalises at f = 0; Tikhonov's T(0) < 1 with an identity prior, the
  // target-PSF output's is 1). Default true.
  bool normalise_dc = true;

  bool IsValid(std::string* why) const;
};

// Sets options->direction_{y,x} to the normal of the edge MeasureSlantedEdgeMtf read (its angle and orientation)
// and options->radial = false.
void SetDirectionFromEdge(const SlantedEdgeMtf& edge, TransferCurveOptions* options);

struct TransferCurve {
  std::vector<double> frequency;  // cycles per HR px
  std::vector<double> mtf;        // |T|·(box), normalised as asked
  std::vector<double> alias;      // the alias response on the same scale (empty for a kernel: not known)
  double dc = 1.0;                // |T(0)| before normalisation
  bool radial = false;
  double direction_y = 0.0, direction_x = 1.0;  // the unit direction used (radial: unused)
};

// The curve of a TransferGrid (TikhonovTransferGrid).
TransferCurve GridTransferCurve(const TransferGrid& grid, const TransferCurveOptions& options = {});

// |DTFT| of a real kernel (the target-PSF output's effective PSF, centred, any size >= 1, finite, non-zero sum)
// along the direction or radially averaged: exact at every frequency (a direct sum, no grid).
TransferCurve KernelTransferCurve(const Image& kernel, const TransferCurveOptions& options = {});

// Tikhonov's curve for a problem (its model, and per-frame weights: each frame's mean weight over its pixels)
// and λ: `exact` is false when some frame's weights are not uniform (masked pixels, photon-noise weights), the
// estimator is then not shift-invariant and the curve is that of the per-frame mean weights. Also false for a
// zero-padded boundary (not seen here: the caller knows).
TransferCurve TikhonovTransferCurve(const ReconstructionProblem& problem, const TikhonovOptions& prior, double lambda,
                                    const TransferCurveOptions& options = {}, bool* exact = nullptr);

}  // namespace aosr
