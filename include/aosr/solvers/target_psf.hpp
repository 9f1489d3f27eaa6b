// Target-PSF linear reconstruction: the linear combination of the frames whose output has one chosen PSF
// everywhere, with its noise known. The idea is IMCOM's (Rowe, Hirata & Rhodes 2011, ApJ 741, 46): choose
// the linear estimator that trades *leakage* (how far the output's PSF is from the target) against *noise*;
// on the periodic model both are exact per Fourier bin, so the optimum is closed-form.
//
// The estimator. For LR frequency bin u the frames see the r² aliased HR frequencies through the N x r²
// matrix A(u) (core/forward_model.hpp), Y(u) = A(u) X + N(u). A linear estimate X̂ = Q(u) Y has expectation
// Q A X: its *effective PSF* is the r² x r² matrix Q A, whose diagonal is the shift-invariant transfer
// T_eff(f) and whose off-diagonal terms are aliasing (a response that depends on where a source sits within
// a camera pixel). With T = diag T(f_k) the target's transfer function, the leakage and noise of a bin are
//
//     L(u) = ||Q A − T||²_F,        noise(u) ∝ tr(Q Qᴴ)     (white frame noise, uniform weights),
//
// and minimising Σ_u noise + L/κ gives, bin by bin,
//
//     Q = T (AᴴA + κ I)⁻¹ Aᴴ,                                                                           (1)
//
// i.e. the target applied to a ridge estimate with ONE κ for all bins (the Lagrange multiplier of a global
// leakage bound; a per-bin κ would spend more noise for the same total leakage). With the eigen-decomposition
// AᴴA = Σ_j e_j v_j v_jᴴ and g_j = √e_j v_j (computed as Aᴴu_j from the smaller Gram matrix A Aᴴ when N ≤ r²),
// per HR frequency k of the bin:
//
//     T_eff,k = T_k Σ_j |g_kj|² / (e_j + κ)                                       (effective transfer)
//     ℓ_k     = |T_k|² (1 − Σ_j |g_kj|² (e_j + 2κ) / (e_j + κ)²)                  (leakage, row k of QA − T)
//     S_k     = |T_k|² Σ_j |g_kj|² / (e_j + κ)²                                   (noise power, ∝ σ²)
//     ℓ_min,k = |T_k|² (1 − Σ_{e_j > τ e_max} |g_kj|² / e_j)                      (κ → 0: unreachable part)
//
// The knob. U(κ) = Σ ℓ / Σ |T|² is the fraction of the target's power (equivalently, by Parseval, of
// ||ψ_target||²) that the output's PSF misses, IMCOM's U/C. It rises monotonically with κ from U_min (target
// power on directions the frames do not reach: N < r² leaves r² − N per bin, the pixel box's zeros on the alias
// lattice, f a non-zero multiple of the camera's sampling frequency, are invisible to any design, and modes with
// eigenvalue below τ = 1e-6 of the largest, near the optics' cut-off, would take a 1000-fold noise gain) to 1.
// TargetPsfOptions::leakage = ε sets κ by bisection on log κ so that U(κ) = U_min + ε, U counted with the modes
// below τ lost (the reported U is the true one, a little lower): the least noise for that leakage. τ keeps the
// choice stable: with the numerical rank (1e-18) instead, the bound chased the last per mille of the MTF, and a
// 0.8 % narrower model PSF moved κ 2.3x and the noise 29 % (paper-sim-r4, oracle vs nominal PSFs); now 3.7 %
// (solvers/target_psf.cpp, kReachFloor). The summary reports U, U_min, the per-frequency leakage ℓ (the FITS extension of the CLI) and
// the band: the largest radius |f| below which every HR frequency has ℓ ≤ 10⁻³ (the target is met there).
//
// Flux. The DC transfer of (1) is dc = e/(e + κ) < 1; the output is divided by it at every frequency, so the
// effective PSF sums to exactly 1 (a point source keeps its flux). With a 100 % fill-factor box pixel the DC
// bin sees no other HR frequency (B vanishes on the lattice), so this holds for a source at any sub-pixel
// position. Why every frequency and not the zero frequency alone: the filter must stay smooth there. Dividing
// only the DC bin made a jump of 1/dc − 1 at one frequency, which is a constant in space: the response to one
// pixel had a pedestal of ~1e-9 of its peak over the whole field (1e-4 of its L1 norm), a global coupling that
// no tile overlap captures (bench/results/kernel_reach.md). The factor is 1 + κ/e at DC (~1e-4 here), so the
// effective transfer elsewhere moves by that fraction; the noise and leakage reported include it.
//
// Noise. Frame pixels of weight w have variance σ²/w (σ = noise_sigma: 1 when the weights are inverse
// variances). On the Fourier path the output noise is exact: its power spectrum σ²/w₀ · S/r² (HR frequencies),
// its covariance averaged over position ξ(Δ) (noise_correlation, a small centred kernel; ξ(0) the mean
// variance), and the variance map, periodic with period r because aliasing makes the noise cyclostationary:
//
//     var(p) = σ²/(w₀ r⁴ m²) Σ_u Σ_j |Σ_k e^{2πi k·p/r} T_k g_kj / (e_j + κ)|²      (cf. tikhonov.hpp (6)).
//
// Weighted or masked data (the normal case for measured frames) take the conjugate-gradient path: the ridge
// part solves (AᵀWA + κ' I) y = AᵀW d (κ' = κ r² w̄, w̄ the mean positive weight; κ from the uniform-weight
// system with weight w̄, so U refers to that system), preconditioned by the exact Fourier inverse of
// (w̄ AᵀA + κ' I) (fourier_normal_system.hpp), then x̂ = T ⊛ y with the same DC normalisation. Its noise is
// estimated by probing: K noise realisations n ~ N(0, σ² W⁻¹) on the weighted pixels are pushed through the
// same estimator, var(p) ≈ (1/K) Σ x̂_n(p)², with its own per-pixel standard error (the spread of x̂_n(p)² over
// the probes / √K) and ξ(Δ) from the probes' autocorrelations. The effective PSF and leakage reported there
// are those of the uniform-weight system (the local PSF near masked pixels differs; the probes do not see it).
//
// API rules: options are validated (IsValid names the field) and the problem by its own rules; outcomes
// (an unreachable target, PCG not converging) are reported in the summary, never as exceptions; NaN is never
// returned.
#pragma once

#include <cstdint>
#include <string>

#include "aosr/core/image.hpp"
#include "aosr/solvers/conjugate_gradient.hpp"
#include "aosr/solvers/problem.hpp"
#include "aosr/solvers/summary.hpp"

namespace aosr {

// kAuto: a Gaussian of FWHM max(FWHM of the mean model PSF, r HR pixels) (one camera pixel: finer targets put
// power on the pixel box's invisible lattice); kGaussian: a Gaussian of fwhm_hr_px; kImage: a given kernel.
enum class TargetPsfKind { kAuto, kGaussian, kImage };

struct TargetPsfOptions {
  TargetPsfKind kind = TargetPsfKind::kAuto;
  // kGaussian: FWHM in HR pixels, in [0.5, min(HR rows, cols) / 4].
  double fwhm_hr_px = 0.0;
  // kImage: the target PSF at HR sampling, centred at (K/2, K/2) as every kernel here, finite, positive sum
  // (renormalised to unit sum), no larger than the HR grid.
  Image image;
  // ε of the leakage bound U ≤ U_min + ε, in (0, 1). 1e-3: the effective PSF's error power is 0.1 % of the
  // target's, well below what PSF photometry notices, with noise close to its floor (it falls slowly as ε
  // grows; the bench's tradeoff rows show it).
  double leakage = 1e-3;
  // κ of (1) given (unit-weight Fourier units, > 0) instead of the leakage search: U is then reported, not
  // chosen (leakage_met says whether the bound holds). Tiling (tiling.hpp) gives every tile the κ chosen once.
  // 0 (the default): by the leakage bound.
  double kappa = 0.0;
  // With κ given: the largest mode energy e_max over the bins, which scales the reach floor (kReachFloor · e_max;
  // modes below it are what U_min counts as lost). Tiling gives every tile the representative problem's, so a
  // tile analyses each of its bins once, not twice (without it, a pass over every bin finds this problem's own
  // e_max before the solve). It changes only U_min and the unreachable count, never the estimate. 0: this
  // problem's own. Finite, >= 0, and > 0 only with kappa > 0.
  double e_max = 0.0;
  // σ of a pixel of weight 1 in frame units (noise variance σ²/w): 1 when the weights are inverse variances
  // (datasets' weights are). > 0.
  double noise_sigma = 1.0;
  // Compute the noise map, its correlation kernel and the noise RMS.
  bool compute_noise = true;
  // Weighted/masked path: noise probes (>= 2), their seed, and the PCG of the data solve (the probes stop at a
  // relative residual of max(cg.tolerance, 1e-6): their sampling error is far larger).
  int noise_probes = 32;
  std::uint64_t seed = 1;
  ConjugateGradientOptions cg = {1000, 1e-9};
  // Side of the effective-PSF image (even, >= 4); 0: 16 x the target FWHM, at least 32, capped by the HR grid
  // (the effective PSF has faint wings where T_eff falls short of T: a window too small cuts them off).
  // Half-width in HR pixels of the noise correlation kernel (>= 0); -1: 2r.
  int psf_size = 0;
  int correlation_radius = -1;

  bool IsValid(std::string* why) const;
};

struct TargetPsfSummary : SolverSummary {
  // Inherited: method ("target-psf-fourier" | "target-psf-cg"), termination (kFailed if a solve failed;
  // kMaxIterations / kStagnated from PCG), iterations (PCG iterations of the data solve and the probes),
  // final_cost (0), frame_residual_rms (y − A (ridge estimate), per frame).
  std::string target;               // e.g. "gaussian FWHM 4.00 HR px (auto)"
  double target_fwhm_hr_px = 0;     // FWHM of the target (measured for an image target)
  double effective_fwhm_hr_px = 0;  // FWHM of the effective PSF
  double effective_psf_window_fraction = 1;  // sum of effective_psf: the part of the PSF inside its window
  double kappa = 0;                 // κ of (1), unit-weight Fourier units
  double e_max = 0;                 // the reach floor's scale: the largest mode energy over the bins (or the given)
  double leakage = 0;               // U at κ
  double leakage_unreachable = 0;   // U_min
  bool leakage_met = false;         // U ≤ U_min + ε (false only if κ hit its search floor)
  double leakage_max_in_band = 0;   // max ℓ inside the band (≤ 1e-3 by definition of the band)
  double band_cycles_per_hr_px = 0; // radius of the band where every ℓ ≤ 1e-3 (0.5√2 for the whole grid)
  Index unreachable_frequencies = 0;  // HR frequencies with ℓ_min > 1e-3
  double dc_transfer = 1;           // e/(e + κ) at zero frequency before the flux normalisation
  double noise_sigma = 0;           // σ used
  double noise_rms = 0;             // √(mean output variance), frame units per HR pixel (0 if not computed)
  double noise_rms_error = 0;       // probing: standard error of noise_rms; 0 on the exact path
  int noise_probes = 0;             // 0 on the exact path
  bool fourier_exact = false;       // uniform weights, periodic: everything above is exact
};

struct TargetPsfResult {
  Image image;              // x̂ on the HR grid, frame units per HR pixel, finite
  Image noise_std;          // √var(p), same grid (empty unless compute_noise)
  Image noise_std_error;    // probing: standard error of each noise_std value; empty on the exact path
  Image effective_psf;      // T_eff as a centred kernel, psf_size² (the whole PSF sums to 1; the window holds
                            // summary.effective_psf_window_fraction of it)
  Image target_psf;         // the target as a centred kernel of the same size
  Image noise_correlation;  // ξ(Δ), (2R+1)² centred on (R, R), frame units² (empty unless compute_noise)
  Image leakage_spectrum;   // ℓ on the HR frequency grid, zero frequency at (M_y/2, M_x/2)
  TargetPsfSummary summary;
};

TargetPsfResult ReconstructTargetPsf(const ReconstructionProblem& problem, const TargetPsfOptions& options);

// What ReconstructTargetPsf would choose, without the solve: κ (the leakage bound's, or the given one), e_max and
// the target's FWHM. Tiling fixes these once on the representative problem for every tile (tiling.hpp).
struct TargetPsfChoice {
  double kappa = 0;
  double e_max = 0;
  double target_fwhm_hr_px = 0;
};
TargetPsfChoice ChooseTargetPsf(const ReconstructionProblem& problem, const TargetPsfOptions& options);

// The unit-sum circular Gaussian of the given FWHM (HR pixels) as a centred size x size kernel, sampled as
// the continuous transfer exp(−2π²σ²|f|²) on the size x size DFT grid (so its DFT is exactly that
// transfer). size even, >= 2.
Image GaussianTargetKernel(double fwhm_px, Index size);

}  // namespace aosr
