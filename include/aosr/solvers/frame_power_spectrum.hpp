// The object's power spectrum fitted to the frames themselves: the Wiener prior of tikhonov.hpp
// (TikhonovPrior::kFitted, λ rule kWiener) without training images, so it is legitimate on measured data.
//
// ## What the frames' periodogram measures
//
// With the model of forward_model.hpp, frame i's unnormalised LR DFT at LR bin u is
// Y_i(u) = Σ_k A_ik(u) X(f_k) + N_i(u), f_k = u + k∘m the r² HR frequencies aliased onto u (A(u) =
// MultiFrameModel::AliasedSystem). For a stationary object with s(f) = E|X(f)|²/M² (power_spectrum_model.hpp;
// M² HR pixels, m² LR pixels, M² = r² m²) and white noise of variance v per LR pixel, the frame-averaged
// periodogram P̄(u) = (1/N) Σ_i |Y_i(u)|² / m² has the expectation
//
//     E P̄(u) = r² Σ_k T_k(u) s(f_k)  +  v,      T_k(u) = (1/N) Σ_i |A_ik(u)|²,                          (1)
//
// the object's spectrum through the mean transfer |A|² of the frames (aliasing included: the r² HR
// frequencies of a bin are not separated, their sum is modelled), plus the white noise floor v. Rather
// than dividing by T (unstable where T is small, and impossible for the aliased sum) (1) is fitted as a
// forward model: the well-measured frequencies (large T s) fix the object's spectrum, the frequencies where
// T s has fallen below v fix the noise floor, and the ones in between weigh as their data say.
//
// ## The fit
//
// s(f) = a (f0² + |f|²)^(−β/2), i.e. s(0) (1 + |f|²/f0²)^(−β/2), the form of tikhonov.hpp's kPowerSpectrum
// prior. Each frame has its mean removed and (by default) a separable Hann window w applied, the periodogram
// being normalised by Σw²: its expectation is then (1) smoothed by the window's kernel [1/6, 2/3, 1/6] per
// axis, and the fit models that smoothing (as design/power_spectrum_fit.hpp does for training images);
// the window keeps the frames' edges (real objects are not periodic) from leaking power ∝ |u|⁻² into the
// spectrum. The LR bins are grouped in annuli of LR radius round(m|u|) >= min_radius (the DC bin and, with
// Hann, its neighbours carry the mean removal), and
//
//     ρ_b = √n_b (ln P̄_b − ln m̄_b)       (P̄_b, m̄_b: the periodogram and the smoothed model (1) averaged over annulus b)
//
// is minimised over θ = (ln a, ln f0, β, ln v) by Levenberg-Marquardt from the best point of a grid over
// (f0, β) with (a, v) solved linearly there. β is held in [0, 8] and f0 in [1/M, 0.5] cycles per HR pixel (the
// ranges the kPowerSpectrum prior accepts); v is fitted unless given (noise_variance > 0). Masked pixels should
// be filled (e.g. by the frame mean) before the fit: holes add white power.
//
// Tested (frame_power_spectrum_physics_test.cpp): frames simulated from Gaussian random fields of known β give
// β back within the stated tolerance and v within a few per cent.
//
// API rules as tikhonov.hpp: options and inputs are validated first (InvalidArgument names the field or
// argument); the outcome (iterations, convergence, residual) is in the result, never an exception.
#pragma once

#include <string>
#include <vector>

#include "aosr/core/forward_model.hpp"
#include "aosr/solvers/power_spectrum_model.hpp"

namespace aosr {

struct FramePowerSpectrumOptions {
  // Hann window on each frame (true, the default: measured frames are not periodic) or none (false: exact
  // for periodic frames, e.g. synthetic ones, and one LR bin more resolution at the lowest frequencies).
  bool hann_window = true;
  // Smallest LR radius fitted, in LR bins (round(m|u|), |u| in cycles per LR pixel x m), in 1..16. 0 (the
  // default): 2 with the Hann window (its kernel mixes the removed mean into radius 1), 1 without.
  int min_radius = 0;
  // White noise variance per LR pixel (frame units²): 0 (the default) fits it; > 0 holds it (a known noise).
  double noise_variance = 0.0;
  // Levenberg-Marquardt: iteration cap (1..1000) and the relative cost decrease at which it stops ((0, 0.1)).
  int max_iterations = 200;
  double tolerance = 1e-10;

  bool IsValid(std::string* why) const;
};

struct FramePowerSpectrumFit {
  PowerSpectrumModel model;     // the object's s(f) (floor 0), (frame units per HR pixel)²
  double noise_variance = 0.0;  // v of (1), per LR pixel (fitted, or the given one)
  bool noise_fitted = false;
  // The fitted floor reaches at least 1 % of the periodogram in some annulus: the frames see their noise. False
  // when the object's power stays far above the floor at every frequency (sharp PSF, bright object): v is
  // then not determined (the fit may drive it to ~0) and a Wiener λ from it is meaningless: give σ instead.
  bool noise_identified = true;
  // The annuli fitted: LR radius (cycles per LR pixel), periodogram P̄_b, smoothed model m̄_b, bins n_b.
  std::vector<double> annulus_frequency, annulus_power, annulus_model;
  std::vector<int> annulus_bins;
  double residual_rms = 0.0;  // sqrt(Σ n_b (ln P̄_b − ln m̄_b)² / Σ n_b): 0.05 is a typical 5 % misfit
  int iterations = 0;
  bool converged = false;
  std::string message;

  // s(0) = a / f0^β: the object's variance scale at zero frequency (the Wiener λ is σ²/s(0)).
  double ZeroFrequencyPower() const;
  // "beta 2.01, f0 0.0312 cyc/HR px, s(0) 4.1e+03, noise variance 0.0101 (fitted); residual 0.04 over 30 annuli,
  // 9 iterations (converged)".
  std::string BriefReport() const;
};

// Fits (1) to `frames` (on model.lr_shape(), finite, at least one). InvalidArgument for bad options, frame
// shapes or values, constant frames, or fewer than 4 annuli with power in the band (a grid too small).
FramePowerSpectrumFit FitFramePowerSpectrum(const MultiFrameModel& model, const ImageStack& frames,
                                            const FramePowerSpectrumOptions& options = {});

}  // namespace aosr
