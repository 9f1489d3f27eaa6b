// Objective A on a continuous sky (issue 33 item 6): the expected MSE of the Tikhonov/Wiener reconstructor when
// the sky is not a grid of HR pixels.
//
// ## Why
//
// Objective A (design_objective.hpp) takes the sky to *be* the M x M grid of HR pixels and the frames to be
// made by PSFs sampled at the HR pitch: the reconstructors' own model, exactly. Where the HR pixel is coarser
// than λ/2D the optics pass frequencies above the HR grid's Nyquist; on the discrete sky those alias in a way
// that depends on where each PSF sits against the HR grid, and a design that only moves the PSFs by half an
// HR pixel is then "worth" up to +1.9 dB (paper-sim-j-r2). A real sky has no HR grid: measured on images
// rendered from a sky 4x finer than the HR grid, about half of that gain goes (bench/results/design_regimes.md).
// This computes objective A for such a sky, in closed form, so that `aosr design` can say what a real sky gets.
//
// ## The model (edge-aligned pixels, as the simulator's sky_oversampling: scene_spec.hpp)
//
// The sky lives on a grid s times finer than the HR grid (s = sky_oversampling >= 1; s -> ∞ is the continuum):
// sM x sM fine pixels of pitch θ_hr / s, HR pixel k covering fine pixels [sk, sk + s), camera pixel j covering
// fine pixels [rsj, rsj + rs). Its spectrum, in HR units: E|X_f(g)|² = M² σ(ν_g), X_f the unnormalised DFT over
// the fine grid, ν_g = SignedFrequency(g, sM) / M in cycles per HR pixel; σ is a function of the continuous
// frequency (SkySpectrum), so as s grows the sky tends to a continuous field. The data of exposure i, per LR
// bin u of the m x m frame (m = M / r), from the (rs)² fine frequencies g_a = u + a∘m, a ∈ {0..rs−1}²:
//     y_i(u) = Σ_a A_f(u)_{ia} X_f(g_a) + n_i(u),   A_f(u)_{ia} = B_rs(g_a) H_i(ν_a) / (rs)²,
// (B_rs the camera box on the fine grid, H_i the exposure's true OTF at the continuous frequency ν_a, zero
// beyond the pupil's cutoff D/λ). The truth is the sky integrated over HR pixels; at HR frequency f_k,
// k ∈ {0..r−1}²,
//     X(f_k) = Σ_{a : a mod r = k} b_s(g_a) X_f(g_a),   b_s = B_s / s²   (the HR pixel's box, b_s(0) = 1).
// The reconstructor is objective A's, built on the nominal model at the HR pitch: R(u) = G⁻¹A0ᴴ,
// G = A0ᴴA0 + (λ/r²) P. The error X̂(f_k) − X(f_k) = Σ_a F_{ka} X_f(g_a) + (R n)_k with F = R A_f − C,
// C_{ka} = b_s(g_a) [a mod r = k], so per bin
//     e(u) = Σ_a σ(ν_a) ‖F_{:,a}‖² + (σ_n²/r²) ‖R‖²_F,        J = (1/M²) Σ_u mean_ρ e_ρ(u),          (A∞)
// the expected MSE per HR pixel of the reconstruction against the HR-pixel-integrated sky. With s = 1 and σ the
// HR spectrum, C = I, A_f = A and (A∞) is (A) exactly (tested). A fine frequency beyond the truth OTFs' band
// adds σ |b_s|² to its HR bin, whatever the design: the part of the sky no exposure sees. (A∞) converges as s
// grows, as 1/s² for a 1/|ν|² sky (b_s falls as 1/|ν| per axis): J at s = 4 is within 6 % of s = 16, and a gain
// between two designs, which both carry that unseen part, within 0.01 dB (tested; Monte-Carlo reconstructions
// of skies 4x finer than the HR grid match (A∞) within 0.4 %, where (A) is 78 % off).
//
// The true OTFs are needed at every frequency up to the cutoff θ_hr D / λ (cycles per HR pixel), which is above
// the HR grid's Nyquist (1/2) exactly where the question arises. The caller gives them as models on a grid t
// times finer than the HR grid (t = truth_oversampling, 1 or 2 since θ_hr <= λ/D: TruthOversamplingFor), i.e.
// PSFs sampled at θ_hr / t on a tM x tM window (DesignObjective on OversampledOptics); fine frequencies beyond
// that grid's band take H = 0. So the PSFs cost t² the HR ones, not s².
//
// ## Cost
//
// Per bin one r² x r² solve (as (A)) and (rs)² columns of N: m² (rs)² N r² flops per realisation, a few ms to
// 0.1 s on the paper's systems; the PSFs at θ_hr / t are the larger part when t = 2.
#pragma once

#include <functional>
#include <vector>

#include "aosr/core/forward_model.hpp"
#include "aosr/design/design_psf.hpp"
#include "aosr/solvers/power_spectrum_model.hpp"
#include "aosr/solvers/tikhonov.hpp"

namespace aosr {

// σ(ν_y, ν_x): the sky's spectrum E|X(ν)|² / M² at a continuous frequency (signed, cycles per HR pixel), in
// (flux per HR pixel)²; finite and >= 0, 0 for a component left out (the mean level under a gradient prior).
using SkySpectrum = std::function<double(double nu_y, double nu_x)>;

// The continuum form of the reconstructor's Wiener-consistent prior, σ = (σ_n²/λ) / P(ν): P = 1 (identity),
// (2π|ν|)² (gradient), (2π|ν|)⁴ (laplacian), (1 + |ν|²/f0²)^(β/2) (the parametric power-spectrum prior); P = 0
// (the mean, for the difference priors) is left out. The HR grid's own symbols (tikhonov.hpp) are their
// sampled, finite-difference forms. A power-spectrum prior given as a sampled spectrum has no continuum form:
// InvalidArgument.
SkySpectrum SkySpectrumOfPrior(const TikhonovOptions& reconstructor, double noise_sigma);
// σ(ν) = model(|ν|): a spectrum fitted to training images (power_spectrum_fit.hpp), continued beyond the HR
// band by its formula (the mean included, as objective A's Wiener variant includes it).
SkySpectrum SkySpectrumOfModel(const PowerSpectrumModel& model);

// The smallest t >= 1 whose grid (pitch θ_hr / t) holds the pupil's cutoff below its Nyquist:
// t >= 2 θ_hr D / λ. 1 when the HR pixel is at most λ/2D, else 2.
int TruthOversamplingFor(const DesignOptics& optics);
// The optics with the HR pitch divided by t, r and the grid multiplied by t (same pupil, same AO model, so a
// DesignObjective on them with the same seed draws the same residual screens). t in [1, 16].
DesignOptics OversampledOptics(const DesignOptics& optics, int t);

// (A∞) above. nominal: the reconstructor's model (HR grid M, r, N frames); truths: one model per realisation,
// each on the grid tM with r·t and N frames (t = truth_oversampling; non-empty); sky_oversampling s >= t, <= 64.
// reconstructor and noise_sigma as in ExpectedTikhonovMse. InvalidArgument naming the argument for
// inconsistent models or options, or a sky spectrum that is negative or not finite somewhere on the grid.
double ExpectedTikhonovMseOnContinuousSky(const MultiFrameModel& nominal, const std::vector<MultiFrameModel>& truths,
                                          int truth_oversampling, int sky_oversampling,
                                          const TikhonovOptions& reconstructor, double noise_sigma,
                                          const SkySpectrum& sky);

}  // namespace aosr
