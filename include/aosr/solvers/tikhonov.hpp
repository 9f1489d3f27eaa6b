// Tikhonov (regularised least-squares, Wiener) super-resolution.
//
//     x̂ = argmin_x  Σ_i Σ_p w_i[p] (y_i − D_r(h_i ⊛ x))[p]²  +  λ ||Γ x||²                        (1)
//
// with the data, weights and model of a ReconstructionProblem (problem.hpp). Weights are *relative*
// inverse variances: pixel p of frame i has noise variance σ²/w_i[p], σ = TikhonovOptions::noise_sigma
// (so with no weights every pixel has variance σ²). Two exact solution paths share this one objective:
//
// 1. Fourier (periodic boundaries, uniform weights w_i[p] = w₀). The model is block-diagonal in Fourier space
//    (forward_model.hpp): each of the m_y·m_x LR frequency bins u couples the r² aliased HR bins
//    f_k = u + k∘m through the N x r² matrix A(u). With P(u) = diag(|Γ̂(f_k)|²), λ' = λ/w₀ and w = λ'/r²,
//    Parseval turns (1) into one small Hermitian system per bin,
//
//        G(u) X(f_·) = A(u)ᴴ Y(u),     G(u) = A(u)ᴴ A(u) + w P(u).                                   (2)
//
//    (The 1/r² is the ratio of the LR and HR Parseval factors.) This is exact: N+1 FFTs and m² solves.
//    *Woodbury.* G is r² x r² but has rank-N data part. When N < r², w > 0 and P(u) > 0, the push-through
//    identity gives the same solution from an N x N system, the Wiener filter in data space:
//
//        X = P⁻¹Aᴴ K⁻¹ Y,   K = A P⁻¹ Aᴴ + w I_N,   Y − A X = w K⁻¹ Y,   tr(A G⁻¹ Aᴴ) = N − w tr K⁻¹,  (3)
//        G⁻¹ = (P⁻¹ − P⁻¹Aᴴ K⁻¹ A P⁻¹) / w,
//
//    O(N r⁴ + N³) per bin instead of O(r⁶). It agrees with (2) to rounding (tested to 1e-10), and it gives
//    GCV's n − tr H = Σ_u w tr K⁻¹ without the cancellation of N − tr(AG⁻¹Aᴴ) at small λ.
//    *Singular bins.* Where G(u) is singular (λ = 0 and A(u) rank deficient, or a prior null space the
//    data do not see) the minimum-norm solution of the stacked system [A; √w P^½] is returned (SVD, with
//    singular values below rank_tolerance × the largest of all bins dropped) and the summary counts the HR
//    frequencies the data leave unconstrained: they are reported, not filled (at λ = 0 always, otherwise on
//    request: TikhonovOptions::count_unconstrained). At λ > 0 a bin whose prior vanishes at some aliases is
//    solved by (2) when the data see those aliases (their columns of A(u) have full column rank against that
//    floor), else by the minimum-norm path.
//
// 2. Conjugate gradients (anything that breaks periodicity: non-uniform weights, masked pixels, zero-padded
//    boundaries). Solves the normal equations of (1),
//
//        (AᵀWA + λ ΓᵀΓ) x = AᵀW y,                                                                  (4)
//
//    matrix-free with the same operators, preconditioned by the *exact* Fourier inverse of the uniform-
//    weight problem (w̄AᵀA + λΓᵀΓ)⁻¹, w̄ the mean of the positive weights (applied by real FFTs and per-bin
//    solves of FourierNormalSystem: the Woodbury form of (3) where N < r², which keeps an N x N factor per bin
//    instead of G(u)⁻¹, 32 fewer HR arrays at r = 4). With uniform weights it is exact and PCG stops after one iteration. With
//    masked pixels M⁻¹N = I − M⁻¹Aᵀ(w̄ − W)A differs from I on a subspace no larger than the masked pixels,
//    and weights within [a, b]·w̄ keep its eigenvalues within [a, b] where the data dominate, whatever the
//    conditioning of the blur: measured on 64x64 HR, r = 2, N = 3, λ = 1e-3,
//    15 iterations instead of 397 with 2% of the pixels masked, 44 instead of 414 with 10% masked and
//    weights in 0.5..1.5 (tikhonov_cg_test.cpp).
//    *Zero-padded boundaries* (boundary = kZeroPadded): the object is reconstructed on an HR grid padded by
//    `padding` camera pixels on every side and the frames see only its central window: y_i = C D_r(h_i ⊛ x)
//    (padded_model.hpp). Since the crop C is aligned with camera pixels this is the periodic model on the
//    padded grid with weight 0 on the padded LR pixels, i.e. (4) on the padded grid, preconditioned by the
//    padded grid's Fourier inverse. Sources outside the field that spill light into it are then modelled
//    instead of wrapping around. Here the preconditioner helps little (measured: 458 iterations instead of
//    564 for padding 2, λ = 1e-2): every padded LR pixel is unobserved, and the slow modes are objects in
//    the pad that only the prior constrains (eigenvalues λ|Γ̂|²/(|A|² + λ|Γ̂|²) of M⁻¹N, the spread of N's
//    own). Keep the padding near the PSF's extent (the default) and expect more iterations at small λ.
//    *Huge λ.* Where λ γ_min exceeds 1e8 · w_max N r² (γ_min the smallest positive prior symbol) the prior
//    outweighs the data beyond double precision's reach and (4) cannot be solved by iteration; there the CG
//    path returns the closed-form expansion x = z₀ + (u₁ + z₁)/λ + O(λ⁻²) (null-space fit plus first-order
//    term; tikhonov_cg.cpp), which is exact to rounding at any λ up to the largest double.
//
// Priors Γ (periodic on the grid solved on, so Fourier-diagonal; |f|² in cycles per HR pixel squared,
// f_a = SignedFrequency(k_a, M_a) / M_a):
//   kIdentity       Γ = I                      |Γ̂|² = 1
//   kGradient       Γ = forward differences    |Γ̂|² = 4 sin²(π f_y) + 4 sin²(π f_x)
//   kLaplacian      Γ = ∇ᵀ∇ (5-point)          |Γ̂|² = (4 sin²(π f_y) + 4 sin²(π f_x))²
//   kPowerSpectrum  Γ = S^(−½) ⊛               |Γ̂|² = 1 / S(f),  S a stationary object power spectrum:
//                   either given (object_power_spectrum) or S(f) = (1 + |f|²/f₀²)^(−β/2), normalised to
//                   S(0) = 1 (β = spectrum_slope, f₀ = spectrum_corner; β = 0 is the identity prior).
//   kFitted         kPowerSpectrum with S fitted to the frames themselves (frame_power_spectrum.hpp): the
//                   periodogram of the frames against the forward model E P̄(u) = r² Σ_k T_k(u) s(f_k) + v
//                   (T the frames' mean |A(u)|², v the white noise floor), s(f) = s(0)(1 + |f|²/f₀²)^(−β/2)
//                   by Levenberg-Marquardt over the frequencies the data constrain. No training images, so
//                   legitimate on measured data. Masked pixels are filled with their frame's weighted mean
//                   for the fit; the noise floor is held at σ²·mean(1/w) when noise_sigma > 0 (σ known),
//                   else fitted. The fitted β, f₀, s(0) and v are in the summary.
//
// Bayesian reading (Wiener). With Gaussian noise of variance σ²/w and the prior x ~ N(0, (σ²/λ)(ΓᵀΓ)⁻¹),
// i.e. for kPowerSpectrum a stationary object with E|X̂(f)|² / M² = (σ²/λ)·S(f) (M² = M_y·M_x HR pixels,
// unnormalised DFT), (1) gives the posterior mean and the posterior covariance is
//
//     C = σ² (AᵀWA + λ ΓᵀΓ)⁻¹.                                                                      (5)
//
// So λ = σ²/s² is the Wiener choice for an object of power spectrum s²·S(f). On the Fourier path the
// diagonal of C, the posterior standard deviation map, is closed-form. Shifting the object by r HR pixels
// (one camera pixel) shifts every frame by one LR pixel and changes neither the data term nor the prior,
// so C commutes with such shifts and its diagonal is periodic with period r in each axis: every camera
// pixel has the same r x r pattern of uncertainty (sub-pixel phases the frames sample badly are worse).
// In Fourier terms, with 𝔽 the unnormalised HR DFT and m² = m_y·m_x LR pixels, AᵀA + λ'ΓᵀΓ =
// (1/m²) 𝔽ᴴ diag_u G(u) 𝔽 (Parseval, as for (2)), hence
// (AᵀA + λ'ΓᵀΓ)⁻¹ = (1/(r² M²)) 𝔽ᴴ diag_u G(u)⁻¹ 𝔽, and its diagonal at HR pixel p picks up the phases
// exp(2πi (f_k − f_k')·p / M) = exp(2πi (k − k')·p / r), which depend on p mod r only:
//
//     C_pp = (σ²/w₀) · (1/r⁴) · φ(p)ᴴ Ḡ φ(p),   Ḡ = (1/m²) Σ_u G(u)⁻¹,   φ_k(p) = exp(−2πi k·p / r),   (6)
//
// the average of the per-bin r² x r² inverses, modulated by the HR phase within one r x r cell. (Check:
// A = 0, Γ = I gives G = (λ'/r²) I and C_pp = σ²/λ.) Its sum Σ_p C_pp = tr C is the expected squared error
// of the estimate over objects drawn from the prior (the Wiener MSE). Note that C is the spread of x̂ − x
// over object *and* noise; over noise alone x̂ varies less (σ²Q⁻¹AᵀWAQ⁻¹, Q = AᵀWA + λΓᵀΓ), the two
// agreeing only as λ → 0. Where some G(u) is singular the posterior is improper (infinite variance along
// an unseen direction) and no map is returned. Tested against a dense inverse (1e-10) and against 200
// draws of object and noise (each sub-pixel phase within 0.3%, tikhonov_physics_test.cpp).
//
// λ rules:
//   kFixed        λ as given.
//   kGcv          generalised cross-validation (Golub, Heath & Wahba 1979, Technometrics 21, 215): minimises
//                 GCV(λ) = n · ||y − A x_λ||² / (n − tr H_λ)²; needs no noise level. Each value is a sum over
//                 the singular values of the whitened bins B(u) = A(u) P(u)^(−½) (one decomposition per bin for
//                 the whole search, then O(min(N, r²)) per bin and λ; a bin whose prior vanishes at z aliases the
//                 data see is first reduced to the N − z dimensions outside those aliases' columns; the
//                 decomposition is a Householder bidiagonalisation of B and implicit QR sweeps, applied to the
//                 data alone, as accurate as an SVD of B: tested against one to 1e-10 in the GCV curve), so the
//                 search is a log grid (gcv_decades x
//                 gcv_steps_per_decade) to find the basin and a golden-section search on log λ between the
//                 best point's neighbours to 1e-4 decades: a continuous minimiser, not a grid point. Needs a
//                 Fourier-exact problem (uniform weights, periodic boundary: tr H exactly, per bin; a CG
//                 solve then uses that λ); otherwise it is an InvalidArgument. A minimum at either end of the
//                 grid is a bound, not a GCV minimiser, and the summary's message says so (seen with a point
//                 source 10²–10⁶ times the rest of the scene: GCV then runs to the smallest λ).
//   kDiscrepancy  Morozov's discrepancy principle: λ such that the weighted residual equals the expected
//                 noise,  Σ_i Σ_p w_i[p] (y_i − A_i x_λ)[p]² = τ · σ² · n_w,  n_w the number of weighted
//                 pixels (N·m² without weights), τ = discrepancy_factor. The residual grows monotonically
//                 with λ, so the root is bracketed on a log scale and refined by the Illinois method. τ = 1
//                 is the classical rule; since the residual of an estimate with p effective parameters
//                 is about (n − p)σ², τ = 1 over-smooths, more so when N is small relative to r² (measured,
//                 N = 5, r = 2, 5% noise: λ 10x the oracle's, error 9% above the oracle's).
//   kLcurve       Hansen's L-curve (Hansen 1992, SIAM Review 34, 561; Hansen & O'Leary 1993, SIAM J. Sci.
//                 Comput. 14, 1487): λ at the maximum curvature of the curve (ln ρ(λ), ln η(λ)), ρ = ||y − A x_λ||²,
//                 η = ||Γ x_λ||². For an exact minimiser dρ/dλ = −λ dη/dλ, so the curvature needs only ρ, η and
//                 η' = dη/dλ (the second derivatives cancel):
//                     κ = [1/(ρη) + λη'(1/(ρη²) + λ/(ρ²η))] / (|η'| (λ²/ρ² + 1/η²)^(3/2)),
//                 and each is a sum over the whitened bins' singular values, η = Σ s²c/(s²+w)², η' ∝ −2Σ s²c/(s²+w)³
//                 (one decomposition per bin, as GCV). Needs no noise level. The corner is the positive local maximum of
//                 κ at the largest λ on the grid t = log10(λ/λ₀) in [−gcv_decades, gcv_decades/2], refined by
//                 golden section: maxima at smaller λ are where the curve comes to rest at the least-squares end
//                 (residual and norm both saturate; a short arc with a large κ), not the L's corner (Hansen
//                 2001 restricts the curve for the same reason). Same Fourier-exact requirement as kGcv.
//   kUpre         the unbiased predictive risk estimator (Mallows' C_L, Mallows 1973, Technometrics 15, 661;
//                 Vogel 2002, "Computational Methods for Inverse Problems", §7.1; for Gaussian noise it is
//                 Stein's SURE, Stein 1981, Ann. Stat. 9, 1135, of the prediction A x_λ): minimises
//                     U(λ) = ||y − A x_λ||² + 2 σ_p² tr H_λ − n σ_p²,   σ_p² = noise_sigma² / w₀,
//                 an unbiased estimate of the predictive risk E||A(x_λ − x)||². Needs noise_sigma > 0 (1 for
//                 inverse-variance weights). Same grid, refinement and Fourier-exact requirement as kGcv.
//   kWiener       λ = σ² / s(0), the Wiener choice for the kFitted prior's spectrum s = s(0)·S (see the Bayesian
//                 reading above): no search. σ = noise_sigma when > 0, else from the fitted noise floor,
//                 σ² = v / mean(1/w). Needs prior kFitted; works on both paths (weights and masks included).
//   For weighted or masked data, ReconstructOptions (reconstruct.hpp) chooses λ for kGcv, kLcurve and kUpre on
//   the unweighted frames and scales it by the mean weight; ReconstructTikhonov itself refuses them there.
//
// API rules: every entry point validates its options (IsValid names the field) and its inputs before
// computing and throws InvalidArgument naming the argument; outcomes (λ chosen, iterations, unmet
// discrepancy, unconstrained frequencies) are reported in TikhonovSummary, never as exceptions; NaN is
// never returned.
#pragma once

#include <cstdint>
#include <string>

#include "aosr/core/forward_model.hpp"
#include "aosr/solvers/conjugate_gradient.hpp"
#include "aosr/solvers/frame_power_spectrum.hpp"
#include "aosr/solvers/problem.hpp"
#include "aosr/solvers/summary.hpp"

namespace aosr {

enum class TikhonovPrior { kIdentity, kGradient, kLaplacian, kPowerSpectrum, kFitted };
const char* ToString(TikhonovPrior p);
// Parses "identity" | "gradient" | "laplacian" | "power-spectrum" | "fitted"; InvalidArgument otherwise.
TikhonovPrior ParseTikhonovPrior(const std::string& name);

enum class TikhonovLambdaRule { kFixed, kGcv, kDiscrepancy, kLcurve, kUpre, kWiener };
const char* ToString(TikhonovLambdaRule rule);
// Parses "fixed" | "gcv" | "discrepancy" | "lcurve" | "upre" | "wiener"; InvalidArgument otherwise.
TikhonovLambdaRule ParseTikhonovLambdaRule(const std::string& name);

// How each Fourier bin is solved. kAuto: Woodbury (3) when N < r² and the bin allows it (w > 0, P > 0),
// else the normal equations (2). Forcing one is for tests and timing; a bin that does not allow Woodbury
// falls back to (2), and a singular bin always takes the minimum-norm SVD path.
enum class TikhonovBinSolver { kAuto, kNormalEquations, kWoodbury };

// kAuto: Fourier when the problem allows it (uniform weights, periodic boundary), else conjugate gradients.
// kFourier with a problem that does not allow it is an InvalidArgument; kConjugateGradient always iterates.
enum class TikhonovMethod { kAuto, kFourier, kConjugateGradient };

enum class TikhonovBoundary { kPeriodic, kZeroPadded };

struct TikhonovOptions {
  // --- prior -------------------------------------------------------------------------------------------
  TikhonovPrior prior = TikhonovPrior::kGradient;
  // kPowerSpectrum, parametric S(f) = (1 + |f|²/f₀²)^(−β/2): β = spectrum_slope in [0, 8] (natural images
  // have β ≈ 2, i.e. amplitude ∝ 1/|f|); f₀ = spectrum_corner in cycles per HR pixel, in (0, 0.5], where the
  // spectrum turns from flat to the power law (default: a period of 20 HR pixels).
  double spectrum_slope = 2.0;
  double spectrum_corner = 0.05;
  // kPowerSpectrum with a given spectrum: S on the full HR FFT grid of the model (hr rows x hr cols, bin
  // (0,0) = zero frequency, unshifted), finite, > 0 and symmetric S(−f) = S(f) (the spectrum of a real
  // object); its scale is absorbed by λ. Empty: the parametric form. Periodic boundary only (it is tied
  // to the model's grid).
  Image object_power_spectrum;
  // kFitted: how the spectrum is fitted to the frames (frame_power_spectrum.hpp). Its noise_variance is
  // overridden: σ²·mean(1/w) when noise_sigma > 0, else 0 (fitted).
  FramePowerSpectrumOptions spectrum_fit;

  // --- λ -------------------------------------------------------------------------------------------------
  TikhonovLambdaRule lambda_rule = TikhonovLambdaRule::kFixed;
  // Regularisation weight λ >= 0 for kFixed, in the units of (1) (weight x frame units squared per prior
  // unit squared). 0 gives the (minimum-norm) least-squares solution.
  double lambda = 1e-2;
  // kGcv searches λ = λ₀·10^t on a grid of t in [-gcv_decades, 0] (walking on up to +gcv_decades while the
  // minimum sits at the top) with gcv_steps_per_decade points per
  // decade, where λ₀ = w₀ Σ_u tr(A(u)ᴴA(u)) / Σ_u tr P(u) is the scale at which data and prior weigh
  // alike. Each grid point costs one pass of per-bin solves. Defaults: 8 decades, 4 per decade. kLcurve and
  // kUpre search the same grid (and refine the same way).
  double gcv_decades = 8.0;
  int gcv_steps_per_decade = 4;
  // σ: noise standard deviation of a pixel of weight 1, in frame units; >= 0, and > 0 for kDiscrepancy, kUpre
  // and compute_std. kWiener and kFitted use it when > 0 (else the fitted noise floor). Not used otherwise.
  double noise_sigma = 0.0;
  // kDiscrepancy: τ in [0.1, 10] (target residual τσ²n_w); the root is accepted when the weighted residual
  // is within discrepancy_tolerance (relative, in (0, 0.1]) of the target, after at most
  // discrepancy_max_evaluations (>= 4) solves, each a Fourier pass or a full PCG solve. λ is searched in
  // λ₀·[1e-16, 1e8]; an unreachable target is reported (termination kFailed) with the nearest λ.
  double discrepancy_factor = 1.0;
  double discrepancy_tolerance = 1e-4;
  int discrepancy_max_evaluations = 60;

  // --- how ---------------------------------------------------------------------------------------------
  TikhonovMethod method = TikhonovMethod::kAuto;
  TikhonovBinSolver bin_solver = TikhonovBinSolver::kAuto;
  TikhonovBoundary boundary = TikhonovBoundary::kPeriodic;
  // kZeroPadded: camera pixels of padding on each side (>= 0; the padded LR side is then rounded up to an
  // FFT-friendly size, the extra on the bottom/right). -1: the PSFs' extent (PaddedModel::SuggestPadding).
  int padding = -1;
  // Conjugate-gradient path: stopping rule (relative residual of (4)) and iteration cap per solve, and
  // whether to precondition by the Fourier inverse (false only to measure what it buys). Default cap
  // 2000: masked problems need tens of iterations, zero-padded ones hundreds to thousands at small λ.
  ConjugateGradientOptions cg = {2000, 1e-10};
  bool precondition = true;
  // Compute the posterior standard deviation map (5)-(6) (needs noise_sigma > 0). Exact (closed form) when the
  // problem is Fourier-exact (uniform weights, periodic boundary). Otherwise (weights, masks, zero-padded
  // boundaries) estimated from std_samples exact draws of the posterior by perturbation-optimisation
  // (Papandreou & Yuille 2010; Orieux, Féron & Giovannelli 2012): x_s = Q⁻¹ σ (Aᵀ W^½ z₁ + √λ Γᵀ z₂),
  // z ~ N(0, I), Q = AᵀWA + λΓᵀΓ, has covariance exactly C = σ²Q⁻¹; each draw is one PCG solve. The map's
  // per-pixel standard error (from the spread of x_s² over the draws) comes with it. std_samples >= 2; the
  // draws are seeded by std_seed. With the large-λ expansion (see above) no map is made.
  bool compute_std = false;
  int std_samples = 32;
  std::uint64_t std_seed = 1;
  // A singular value of A(u) below rank_tolerance × the largest singular value over all bins counts as
  // zero when reporting unconstrained frequencies and in the minimum-norm path. In (0, 1).
  double rank_tolerance = 1e-9;
  // Count the HR frequencies the data leave unconstrained (summary.rank_deficient_bins,
  // unconstrained_frequencies and the message): the rank of every A(u) against that floor. Off by default
  // because the solve does not need them (at λ > 0 a bin whose prior is positive is solved without its rank)
  // and they are the costliest part of it where N ≈ r²: most bins then have singular values within a factor
  // 2-10 of the floor, whose rank takes singular values to an SVD's accuracy (measured at r = 4, N = 16: ~5x
  // the time of the rest of a λ-fixed solve; bench/results/tikhonov.md). Off, the counts are -1 and
  // summary.unconstrained_counted is false, except at λ = 0, where the minimum-norm solve makes every rank
  // and the counts are reported anyway.
  bool count_unconstrained = false;
  // Progress and cancellation (core/progress.hpp). The Fourier path is direct: stage "tikhonov" is reported
  // as iteration 0 of 1 when it starts and 1 of 1 (value λ) when it ends; a cancellation asked then has nothing
  // left to cut short (a caller such as Python's Ctrl-C handling acts on it after the return). The CG path
  // reports each PCG iteration of its solves and posterior draws as stage "tikhonov-cg"; returning false stops
  // it with the current iterate (no std map) and Termination::kUserCancelled. Empty (the default): no cost.
  ProgressCallback progress;

  bool IsValid(std::string* why) const;
};

struct TikhonovSummary : SolverSummary {
  // Inherited: method ("tikhonov-fourier" | "tikhonov-cg"), termination (kFailed if the discrepancy target
  // is unreachable or PCG failed; kMaxIterations if PCG or the discrepancy search hit its cap; kStagnated if
  // either stopped at rounding level before its tolerance), iterations (PCG iterations summed over
  // every λ tried; 0 on the Fourier path), final_cost (objective (1) at x̂), frame_residual_rms (RMS of
  // y_i − A_i x̂ over each frame's weighted pixels, from WeightedDataMisfit).
  double lambda = 0.0;                  // the λ of (1) used (given, or chosen by the rule)
  double gcv = 0.0;                     // GCV score at that λ (0 unless kGcv)
  double discrepancy_target = 0.0;      // τσ²n_w (0 unless kDiscrepancy)
  double weighted_residual = 0.0;       // Σ w (y − A x̂)² = 2 · WeightedDataMisfit
  int lambda_evaluations = 0;           // λ values tried (solves or Fourier passes) by the rule
  Index lr_bins = 0;                    // number of per-frequency systems (of the grid solved on)
  // The rank counts, when counted (TikhonovOptions::count_unconstrained, or λ = 0); -1 otherwise.
  bool unconstrained_counted = false;
  Index rank_deficient_bins = -1;        // bins where rank A(u) < r²
  Index unconstrained_frequencies = -1;  // Σ_u (r² − rank A(u)): HR bins the data do not determine
  Index woodbury_bins = 0;              // bins of the final Fourier solve/preconditioner done by Woodbury (3)
  bool preconditioned = false;          // CG path: preconditioned by the Fourier inverse
  double preconditioner_weight = 0.0;   // w̄ of that preconditioner
  int final_solve_iterations = 0;       // CG path: iterations of the solve at the returned λ
  int padding = 0;                      // kZeroPadded: camera pixels added on the top and left
  Shape solved_hr_shape;                // the HR grid x was solved on (the padded grid for kZeroPadded)
  bool std_computed = false;            // the posterior std map is in the result
  int std_samples = 0;                  // posterior draws behind it (0: closed form)
  double mean_posterior_variance = 0.0; // tr C / M² (expected squared error per HR pixel), if computed
  double lcurve_curvature = 0.0;        // κ at λ (0 unless kLcurve)
  double upre = 0.0;                    // U(λ) / n, the predictive risk per pixel estimate (0 unless kUpre)
  // kFitted: the spectrum fitted to the frames (s(f), floor 0, (frame units per HR pixel)²) and the white noise
  // variance per LR pixel of the frames as given (fitted, or σ²·mean(1/w)); spectrum_fitted says they are set.
  bool spectrum_fitted = false;
  PowerSpectrumModel fitted_spectrum;
  double fitted_noise_variance = 0.0;
};

struct TikhonovResult {
  Image image;           // x̂ on problem.model->hr_shape() (the central window for kZeroPadded)
  Image posterior_std;   // √diag C of (5)-(6), same shape; empty unless summary.std_computed
  Image posterior_std_error;  // sampled maps: the standard error of each posterior_std value; else empty
  TikhonovSummary summary;
};

// The regulariser Γ as an operator on an HR grid (for iterative solvers and tests); ΓᵀΓ has the symbol
// below. The enum-only overloads use the default spectrum parameters for kPowerSpectrum. kFitted, whose spectrum
// ReconstructTikhonov fits to the frames, is here the parametric kPowerSpectrum form of the options' fields.
OperatorPtr TikhonovPriorOperator(Shape hr, const TikhonovOptions& options);
OperatorPtr TikhonovPriorOperator(Shape hr, TikhonovPrior prior);
// |Γ̂(f)|² at full-spectrum HR bin (fy, fx) of grid hr.
double TikhonovPriorSymbol(const TikhonovOptions& options, Shape hr, Index fy, Index fx);
double TikhonovPriorSymbol(TikhonovPrior prior, Shape hr, Index fy, Index fx);

// Solves (1) for a ReconstructionProblem, choosing the path as options.method says. Validates the problem
// (problem.hpp rules: a masked pixel may hold NaN) and the options first.
TikhonovResult ReconstructTikhonov(const ReconstructionProblem& problem, const TikhonovOptions& options);

// The Fourier path for unweighted frames (every pixel weight 1, periodic). Frames must match
// model.lr_shape() and be finite. options.method must not be kConjugateGradient and boundary must be
// kPeriodic; compute_std is ignored (use ReconstructTikhonov for the map).
Image TikhonovFourier(const MultiFrameModel& model, const ImageStack& frames, const TikhonovOptions& options,
                      TikhonovSummary* summary = nullptr);

}  // namespace aosr
