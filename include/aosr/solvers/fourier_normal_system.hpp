// The normal system of a periodic multi-frame model plus a gradient and an identity penalty,
//
//     G x = (w AᵀA + a ∇ᵀ∇ + b I) x = rhs,      w > 0, a, b >= 0,
//
// solved exactly per LR frequency bin. A = the stacked D_r ∘ H_i of core/forward_model.hpp, ∇ the periodic
// forward-difference gradient. In Fourier space G is block-diagonal (DESIGN.md §1): for each LR bin u, with
// A(u) the N x r² aliased system and P(u) = diag(4 sin²(π f_y/M_y) + 4 sin²(π f_x/M_x)) the symbol of ∇ᵀ∇
// on its r² aliased HR bins,
//
//     G(u) = r² w A(u)ᴴA(u) + D(u),      D(u) = a P(u) + b I   (diagonal).
//
// Per-bin kernels. Factorize chooses per bin the cheaper exact form:
//  * Woodbury (N < r² and D(u) > 0): with B = √(r²w) A(u), K = I_N + B D⁻¹ Bᴴ (N x N, Cholesky),
//        G(u)⁻¹ v = D⁻¹ v − D⁻¹ Bᴴ K⁻¹ B D⁻¹ v,
//    about 2 N r² + N² complex multiply-adds per solve instead of r⁴ for the r² x r² Cholesky (r = 8, N = 4:
//    580 against 4096). The subtraction cancels where D is small beside the data (the lowest frequencies
//    without positivity): a bin whose amplification ||B||²_F / min D exceeds 1e6 (so at most ~1e-10 relative
//    error from the cancellation) uses the dense form instead.
//  * Dense: the r² x r² Cholesky of G(u) (a pivot below 1e-12 of its own diagonal entry: singular).
//  * Singular (a = b = 0 and A(u) rank-deficient, or the DC bin with every OTF zero there): the minimum-norm
//    solution by an eigen-decomposition pseudo-inverse, counted in singular_bins().
// The layout is flat (one array per quantity, bin-major), so nothing is allocated per bin, and the bins are
// solved on DefaultThreads() threads (core/parallel.hpp): each bin writes only its own spectrum entries,
// so the result does not depend on the thread count.
//
// The split data term. SolveWithData returns x = G⁻¹ (rhs + w Aᵀ v) for frames v and, from the same
// per-bin values, the model frames A x: the ADMM of total_variation.hpp with a split data term (weighted or
// masked data) needs exactly these, and forming them per bin costs N LR FFTs each way instead of the N HR
// FFTs of the spatial operators.
#pragma once

#include <Eigen/Dense>
#include <cstdlib>
#include <memory>
#include <mutex>
#include <vector>

#include "aosr/core/forward_model.hpp"
#include "aosr/core/operators.hpp"

namespace aosr {

class FourierNormalSystem {
 public:
  // Lays out √(r² w) A(u) for every bin. w must be finite and > 0.
  FourierNormalSystem(const MultiFrameModel& model, double data_weight);
  // (Re)factorises for the given a, b (finite, >= 0): per bin an N x N or r² x r² Cholesky (above).
  void Factorize(double gradient_weight, double identity_weight);
  // (Re)factorises with a general diagonal penalty: D(u) = `penalty` (an HR-shaped real, even symbol, finite and
  // >= 0) on the r² aliases of each bin, e.g. λ|Γ(f)|² of any Tikhonov prior (tikhonov_cg.cpp's preconditioner).
  // Only one bin of each mirror pair reads it: D(−f) = D(f) is assumed.
  void Factorize(const Image& penalty);
  // x = G⁻¹ rhs for an HR image rhs (finite). Requires a prior Factorize.
  Image Solve(const Image& rhs) const;
  // x = G⁻¹ (rhs + w Aᵀ v) for frames v (N frames of the LR shape, finite), and, if `ax` is not null, the
  // model frames A x. Requires a prior Factorize.
  void SolveWithData(const Image& rhs, const ImageStack& v, Image* x, ImageStack* ax) const;

  // Buffers that a caller keeps across solves, so that a solve allocates nothing (an ADMM iteration).
  struct Workspace {
    ComplexImage half, out;
    std::vector<ComplexImage> spectra, ax_half;
  };
  // The two solves above for an iterative caller: into *x (and *ax), resized only when their shapes
  // differ, with the caller's buffers, and without the finiteness checks of the inputs, which the caller
  // guarantees (total_variation.cpp checks ||rhs||² and its data once). Shapes are still checked.
  void SolveInto(const Image& rhs, Image* x, Workspace* ws) const;
  void SolveWithDataInto(const Image& rhs, const ImageStack& v, Image* x, ImageStack* ax, Workspace* ws) const;

  Index singular_bins() const { return singular_bins_; }
  Index woodbury_bins() const { return woodbury_bins_; }
  Index bins() const { return lr_.size(); }
  Shape hr_shape() const { return hr_; }
  // ||A||₂, the largest singular value of the stacked model (for unit data weight): max over bins of
  // r·σ_max(A(u)). Computed on the first call (an eigenvalue problem per bin; thread-safe), since only the
  // split data term needs it.
  double ModelNorm() const;

 private:
  // Factorize's two passes with D(u)_k = penalty(bin, k).
  template <class Penalty>
  void FactorizeWith(const Penalty& penalty);
  void SolveBins(const ComplexImage& half, const std::vector<ComplexImage>* v, ComplexImage* out,
                 std::vector<ComplexImage>* ax) const;
  void SolveBin(Index bin, Complex* v, Complex* work) const;

  Shape hr_, lr_;
  int r_ = 1, n_ = 0;
  double sqrt_s_ = 1;  // √(r² w)
  mutable std::once_flag model_norm_once_;
  mutable double model_norm_ = 0;
  bool factorized_ = false;
  Index singular_bins_ = 0, woodbury_bins_ = 0;
  struct FreeDeleter {
    void operator()(Complex* p) const { std::free(p); }
  };
  // Per bin, N x r² row-major: √(r² w) A(u); written only for the bins SolveBins solves (see the .cpp).
  std::unique_ptr<Complex[], FreeDeleter> b_;
  std::vector<double> symbol_;   // per bin, r² values of P(u)
  std::vector<double> dinv_;     // per bin, r² values of D(u)⁻¹ (Woodbury bins)
  std::vector<Complex> kfactor_;  // per bin, N x N Cholesky of K (row-major, 1/L_ii on the diagonal)
  std::vector<int> slot_;        // per bin: -1 Woodbury, else the index into dense_ / pseudo_
  std::vector<std::vector<Complex>> dense_;    // r² x r² Cholesky of G(u) (empty if singular)
  std::vector<Eigen::MatrixXcd> pseudo_;       // pseudo-inverse of a singular G(u) (empty otherwise)
};

// G⁻¹ of a factorised system as a LinearOperator on flattened HR images (self-adjoint; Solve per application). It
// shares `system`: refactorising the system changes the operator (callers make a new system while one is in use).
OperatorPtr NormalSystemInverse(std::shared_ptr<const FourierNormalSystem> system);

}  // namespace aosr
