// Phase design, part 2: objective A, the closed-form expected reconstruction MSE of the linear (Tikhonov /
// Wiener) reconstructor, as a function of the N DM offsets w_dm,i, with its analytic gradient. No Ceres here:
// design_optimizer.hpp minimises it (as a DesignCriterion). The PSFs and the pull-back from the transfer
// functions to the DM offsets are design_psf.hpp's, shared with objective B (design_empirical.hpp).
//
// ## The model (DESIGN.md §1, forward_model.hpp, tikhonov.hpp)
//
// The design works on a periodic HR grid of M x M pixels (M = the scene's PSF window, a multiple of r;
// m = M / r LR pixels), large enough to hold the PSF: the expected MSE is a mean over frequencies, so M sets
// only how finely the frequency axis is sampled. Exposure i's PSF at HR pitch θ_hr is
//     p_i = |MFT(A exp(i 2π (w_dm,i + w_static) / λ))|²   on the M x M window (psf.hpp),   h_i = p_i / Σ p_i,
// and its transfer function H_i = DFT(h_i) (unit sum: H_i(0) = 1). Per LR bin u the aliased system is
//     A(u)_{ik} = (1/r²) B(f_k) H_i(f_k),   f_k = u + k∘m,  k ∈ {0..r−1}²      (N x r², B the pixel box).
//
// Nominal and true systems. The reconstructor uses the *nominal* A0(u): the long-exposure OTF of the analytic
// AO model (analytic_ao.hpp), H0_i(f) = H_diff,i(f) · T(f), T(f) = exp(−D_res(λ f / θ_hr) / 2) (D_res: the
// residual structure function at pupil separation ρ = λ f, interpolated bilinearly on its lattice; T(0) = 1).
// Without AO, H0_i = H_diff,i. The frames are made by the *realised* systems A_ρ(u): for each of R
// realisations ρ (fixed for the whole optimisation: a sample-average approximation), exposure i's PSF is the
// average of L short-exposure PSFs through residual phase screens ψ_{ρ,i,l} drawn from the analytic model's
// residual PSD (FFT screens on its K n x K n grid, cropped to the pupil):
//     p_{ρ,i} = Σ_l |MFT(A exp(i 2π (w_dm,i + w_static + ψ_{ρ,i,l}) / λ))|².
// With R = 0 the frames are made by the nominal model (A = A0: the idealised case).
//
// ## Objective A
//
// Object prior: X(f) independent, E|X(f)|² = M² s(f); either s = object_power_spectrum (a spectrum fitted to
// training images) or the Wiener-consistent s = (σ²/λ) / P(f), P = |Γ̂|² the reconstructor's prior symbol
// (tikhonov.hpp). Noise: white, σ² per LR pixel. The reconstructor, per bin (tikhonov.hpp (2)),
//     R(u) = G⁻¹ A0ᴴ,   G = A0ᴴA0 + w P,   w = λ / r²,
// gives X̂ − X = (R A − I) X + R N, so the expected squared error of a bin, in units where Parseval reads
// Σ_p |x_p|² = (1/M²) Σ_f |X(f)|², is M² e(u) with
//     e(u) = tr(F S Fᴴ) + (σ²/r²) tr(R Rᴴ),   F = R A − I,   S = diag s(f_k),
// and the expected MSE per HR pixel, averaged over realisations, is
//     J = (1/M²) Σ_u (1/R) Σ_ρ e_ρ(u) = (1/r²) mean_u mean_ρ e_ρ(u).                                   (A)
// Check: with A = A0 and the Wiener s, e(u) = (σ²/r²) tr G⁻¹ and J is the mean posterior variance
// tr C / M² of tikhonov.hpp (6) (tested against TikhonovSummary::mean_posterior_variance). Components with
// s = ∞ (P(f) = 0: the mean level under a gradient prior) are left out: unit-sum PSFs pass the mean exactly
// in every system, so F has no component there when P(0) = 0.
//
// ## Gradient (Wirtinger: for real J of complex Z, Γ_Z = ∂J/∂Re Z + i ∂J/∂Im Z, dJ = Re tr(Γ_Zᴴ dZ))
//
//     Γ_A  = 2 Rᴴ F S,                                  (true system; per realisation, weight 1/R)
//     Γ_R  = 2 (F S Aᴴ + (σ²/r²) R),   Z = G⁻¹ Γ_R,
//     Γ_A0 = (I − A0 R) Zᴴ − A0 Z Rᴴ,                   (through R = G⁻¹A0ᴴ and G)
// (with A = A0 the two add). Then Γ_H(f_k) = conj(B(f_k)/r²) Γ_A[i,k] for every HR frequency (each belongs to
// exactly one bin), and DesignPsfModel::PullBack (design_psf.hpp) does the rest: Γ_Hdiff = T Γ_H0; through
// the DFT, ∂J/∂h = M² Re IDFT(Γ_H) (shifted back to the centred window); through the normalisation, ∂J/∂p = (∂J/∂h − ⟨∂J/∂h, h⟩) / Σp; through p = |Y|², Y = MFT(E),
// Γ_E = 2 MFT^H(∂J/∂p ⊙ Y) (mft.hpp's exact adjoint); and through E = A exp(i k w), k = 2π/λ,
//     ∂J/∂w = k Im(Γ_E conj(E)),
// summed over the L screens and every realisation. design_parameterisation.hpp continues to θ. Taylor tests
// check each parameterisation through the whole chain (remainder falls 4x per halving of h).
//
// Cost per evaluation with gradient: N (1 + R L) field propagations and as many adjoints (on the paper's
// system the periodic path: Q x Q FFTs, Q = 256 at r = 2, 512 at r = 4; else MFTs of the n-pixel pupil onto
// M x M), N (1 + R) FFT pairs of M x M for the OTFs and their adjoints (one per PSF, not per screen), and m²
// small solves of r² x r². Measured (bench/results/design.md, one thread, loaded machine): paper system r = 2
// 48 ms for R = 0 and 0.12 s for R = 2, L = 4 (2.4x its FFT floor); r = 4 0.2 s and 1.0 s.
//
// API rules: constructors validate their inputs and options (InvalidArgument naming the field); Evaluate
// validates the OPDs. Immutable after construction; Evaluate is const and thread-safe.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "aosr/core/forward_model.hpp"
#include "aosr/core/image.hpp"
#include "aosr/design/design_psf.hpp"
#include "aosr/solvers/tikhonov.hpp"

namespace aosr {

struct DesignObjectiveOptions {
  // The reconstructor whose MSE is minimised: prior (and its spectrum parameters) and λ > 0 (the λ of
  // tikhonov.hpp (1) for unit weights; only the fixed rule). Default: tikhonov.hpp's gradient prior, 1e-2.
  TikhonovOptions reconstructor;
  // σ: noise standard deviation per LR pixel, > 0, in object units (flux per HR pixel). With the
  // Wiener-consistent prior J scales as σ² and the design does not depend on σ; default 1 (J in units of σ²).
  double noise_sigma = 1.0;
  // s(f) = E|X(f)|² / M² on the full M x M grid (unshifted, bin (0,0) = zero frequency), finite, >= 0 and
  // symmetric; empty: the Wiener-consistent s = (σ²/λ) / P(f).
  Image object_power_spectrum;
  // R: AO PSF realisations averaged (0: the frames follow the nominal model); each draws L = screens
  // residual screens per exposure. In [0, 64] and [1, 256]. Defaults 2 and 4: ~0.1 s per evaluation on the
  // paper's system (the realised PSFs are then partly speckled, as 0.1 s sub-exposures are).
  int realisations = 2;
  int screens = 4;
  std::uint64_t seed = 1;  // of the screens
  // Threads computing the PSFs and their adjoints (results do not depend on it), 1 .. 64. Default 1.
  int threads = 1;

  bool IsValid(std::string* why) const;
};

class DesignObjective : public DesignCriterion {
 public:
  // frames N >= 1. Throws InvalidArgument naming the bad argument, optics field or option.
  DesignObjective(const DesignOptics& optics, int frames, const DesignObjectiveOptions& options);

  // Evaluate(dm_opds, grad) (DesignCriterion): J of (A) for the DM offsets w_dm,i (N images, n x n, metres;
  // finite where the pupil transmits), and if `grad` is non-null ∂J/∂w_dm,i (N images n x n, zero outside
  // the pupil).

  // The systems behind J: the nominal model (H0, what the reconstructor uses) and one model per realisation
  // (the realised OTFs; none when R = 0), on the M x M grid.
  MultiFrameModel NominalModel(const std::vector<Image>& dm_opds) const;
  std::vector<MultiFrameModel> RealisedModels(const std::vector<Image>& dm_opds) const;

  // The object spectrum s(f) used (M x M; 0 where the Wiener s is infinite), the prior symbol P and
  // T(f) (all ones without AO).
  const Image& object_spectrum() const { return s_; }
  const Image& prior_symbol() const { return p_; }
  const Image& ao_factor() const { return psf_.ao_factor(); }
  // The part of J no design can change: (1/M²) Σ s(f) over the HR frequencies no exposure sees, beyond the
  // pupil's cutoff (|λ f| ≥ D) or on the pixel box's zeros (the alias lattice). J − floor is what the design
  // works on (approximately: the window lets a little light leak past the cutoff).
  double invisible_floor() const override { return floor_; }
  int frames() const override { return psf_.frames(); }
  int realisations() const override { return psf_.realisations(); }
  const char* method() const override { return "expected-mse"; }
  // True when the PSFs are the exact periodic ones (design_psf.hpp), false on the windowed MFT path.
  bool periodic() const { return psf_.periodic(); }
  const DesignOptics& optics() const override { return psf_.optics(); }
  const DesignObjectiveOptions& options() const { return options_; }
  const DesignPsfModel& psf_model() const { return psf_; }

 private:
  double EvaluateImpl(const std::vector<Image>& dm_opds, std::vector<Image>* grad) const override;

  DesignObjectiveOptions options_;
  DesignPsfModel psf_;
  Image s_, p_;
  double floor_ = 0;
};

// Objective (A) for given models: the nominal one the reconstructor uses and the true ones (empty: the
// nominal), with the same N, r and HR grid. object_power_spectrum as in DesignObjectiveOptions. This is the
// engine of DesignObjective::Evaluate; exposed for checks against Monte-Carlo reconstructions and the
// posterior covariance.
double ExpectedTikhonovMse(const MultiFrameModel& nominal, const std::vector<MultiFrameModel>& truths,
                           const TikhonovOptions& reconstructor, double noise_sigma,
                           const Image& object_power_spectrum = Image());

}  // namespace aosr
