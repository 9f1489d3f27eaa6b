// The science detector: from the noiseless expected electrons of a frame to the recorded frame, its
// saturation and bad-pixel masks, and the inverse-variance weights the reconstructors need.
//
// ## Where this sits in the image model (DESIGN.md §1)
//
//     y_i = D_r( h_i ⊛ x ) + n_i
//
// The pixel integration D_r is the shared forward model's (core/forward_model.hpp, core Decimate): each
// camera pixel sums its r × r HR pixels. This file adds the two things the forward model leaves out:
//
//  * the fill factor F (PixelResponse): only a centred square of side F·(pixel pitch) of each pixel is
//    sensitive. On the HR grid that is a weighted box: along each axis HR pixel a ∈ {0..r−1} of the camera
//    pixel (spanning [a, a+1) in HR units, the camera pixel spanning [0, r)) gets the overlap length
//        w_a = | [a, a+1) ∩ [r/2 − F r/2, r/2 + F r/2) |        (0 ≤ w_a ≤ 1, Σ_a w_a = F r),
//    and HR pixel (a, b) weight w_a w_b, i.e. the exact sensitive area of the HR pixel if its flux is uniform
//    over it (the same assumption the box D_r makes). When F r is an integer of the same parity as r the
//    weights are exactly 0/1 (e.g. r = 4, F = ½: {0, 1, 1, 0}); otherwise edge HR pixels count partially.
//    A pixel then collects F² of a uniform field: light on the insensitive area is lost, not redistributed
//    (no microlenses). F = 1 returns the core Decimate operator itself. The operator is separable, so it is
//    still "box-filter then subsample" and the Fourier analysis of forward_model.hpp holds with the
//    per-axis transfer Σ_a w_a exp(2πi f a / M) in place of the plain box; MultiFrameModel does not take
//    this variant yet (compose PixelResponse with the frame's convolution instead).
//
//  * the noise n_i and the read-out (Detector), per camera pixel, in this order:
//        λ   = s + B t + D t                  expected electrons: signal s (the input), sky/thermal
//                                             background B and dark current D (e⁻ s⁻¹ pixel⁻¹) over the
//                                             frame time t
//        n   = Poisson(λ)                     photon (shot) noise; poisson.hpp, exact for every λ
//        n  += σ_r z,   z ~ N(0, 1)           read noise (σ_r electrons RMS)
//        ADU = n / g + bias                   gain g (e⁻ per ADU) and the electronic pedestal
//        ADU = round(ADU)                     optional ADC quantisation
//        ADU = min(ADU, S), flagged if ≥ S    saturation (full well or ADC range, whichever is lower)
//        ADU = bias on bad pixels             bad pixels read "dead" (zero signal), flagged
//    so, before clipping and without quantisation, E[ADU] = λ/g + bias and
//        Var[ADU] = λ/g² + (σ_r/g)² = (E[ADU] − bias)/g + (σ_r/g)²
//    ("variance = mean/gain + read²" with mean and read noise in ADU; quantisation adds 1/12 ADU²).
//    With every effect off the output is exactly s/g + bias, and all electrons are conserved.
//    Alternative noise model (NoiseModel::kPeakFraction, the paper's): photon and read noise are replaced by
//    additive Gaussian noise of σ = p · max over the sequence's frames of λ (the noiseless frames); the rest
//    of the chain is unchanged.
//
// ## Weights
//
// DetectorFrame::inverse_variance is 1 / Var[ADU] from the model at the *expected* λ (the oracle weights of a
// simulation), and 0 where the pixel is bad or saturated: a clipped value carries no usable likelihood and
// a dead pixel none at all. Two edge cases: with every noise source off the weights are 1 on valid pixels
// (uniform weighting; 1/0 would be meaningless); a valid pixel whose modelled variance is exactly 0 while
// other noise is on (Poisson only, λ = 0) gets the variance of one electron, 1/g² ADU², instead of infinite
// weight. InverseVarianceFromData estimates the same map from a recorded frame for real data.
//
// ## Why bad pixels read the bias
//
// A dead pixel reads the pedestal (no signal): finite, so a solver that multiplies data by weights is not
// poisoned by 0 · NaN = NaN (DESIGN.md §3: NaN is never returned silently). The masks say which pixels to
// ignore; a recorded value is never the only information.
//
// ## Randomness and cost
//
// Frame f of a sequence recorded with `seed` draws from its own streams, DeriveSeed(DeriveSeed(seed, f), 0)
// for Poisson and DeriveSeed(..., 1) for the normal deviates (ao/random.hpp), so frames are independent
// and a frame's noise does not depend on how many frames precede it or which effects the others enable.
// Every pixel draws (also bad ones), so masks do not shift the streams. All stages run in one fused pass
// over the pixels; a disabled effect is not computed (no generator is even constructed for disabled noise,
// and what remains is a loop-invariant, perfectly predicted branch); DetectorFrame counts the random draws
// so tests can prove it.
// Measured (detector_physics_test, one thread of a shared 2-core VM): 10⁶ pixels of Poisson + read noise
// take 55–70 ms into a reused DetectorFrame, of which ~21 ms are NormalGenerator's Box-Muller deviates and
// 16–40 ms the Poisson deviates (λ = 0.5 .. 5000); frames are independent streams, so a caller may record
// them on parallel threads with identical results.
//
// Errors: aosr::InvalidArgument naming the function and field (DetectorOptions::IsValid names the field).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "aosr/ao/random.hpp"
#include "aosr/core/image.hpp"
#include "aosr/core/linear_operator.hpp"

namespace aosr {

enum class NoiseModel {
  kPhysical,      // photon (Poisson) noise and read noise, each under its enable flag
  kPeakFraction,  // additive Gaussian, σ = peak_noise_fraction × max over the frames of λ (the paper's)
};

struct DetectorOptions {
  // --- Read-out conversion ------------------------------------------------------------------------------
  // Electrons per ADU, finite and > 0. Default 1: recorded values are electrons (plus bias), the easiest to
  // reason about; real near-IR arrays and CCDs run ~0.5–5 e⁻/ADU.
  double gain_e_per_adu = 1.0;
  // Electronic pedestal added to every pixel, ADU, finite. Default 0 so noiseless ADU = electrons/g; real
  // cameras use 100–1000 ADU to keep read noise above the ADC's zero (no lower clip is modelled here).
  double bias_adu = 0.0;
  // Integration time of one frame, seconds, finite and > 0. Only the background and dark current use it
  // (the signal arrives already in electrons per frame, see photometry.hpp). Default 1 s.
  double exposure_time_s = 1.0;

  // --- Noise ----------------------------------------------------------------------------------------------
  // Which noise model; see the top of the file. Default kPhysical.
  NoiseModel noise_model = NoiseModel::kPhysical;
  // kPhysical: Poisson photon noise on λ. Default on: it is the fundamental noise of the measurement.
  bool enable_photon_noise = true;
  // kPhysical: Gaussian read noise of read_noise_e. Default on.
  bool enable_read_noise = true;
  // Read noise in electrons RMS per read, finite and >= 0 (0 draws nothing). Default 5 e⁻: a near-IR
  // HgCdTe array with multiple (Fowler) sampling; CCDs ~3, sCMOS ~1.5, EMCCDs < 1.
  double read_noise_e = 5.0;
  // kPeakFraction: σ as a fraction p of the largest noiseless λ over the frames recorded together, finite
  // and >= 0 (0 draws nothing). Default 0.01, the 1% level of the paper's experiments.
  double peak_noise_fraction = 0.01;

  // --- Background and dark current ----------------------------------------------------------------------
  // Sky (and thermal) background, e⁻ s⁻¹ per camera pixel, finite and >= 0. From a sky surface brightness
  // use SkyBackgroundRate (photometry.hpp), which applies the pixel solid angle and the fill factor.
  // Default 0: the paper's scenes have no background.
  bool enable_background = true;
  double background_e_per_s = 0.0;
  // Dark current, e⁻ s⁻¹ per pixel, finite and >= 0. Default 0 (cooled IR arrays: ~0.01–0.1 e⁻/s).
  bool enable_dark_current = true;
  double dark_current_e_per_s = 0.0;

  // --- Saturation ------------------------------------------------------------------------------------------
  // Clip at saturation_adu and flag the pixels. Default on: a real frame cannot exceed its ADC range, and the
  // mask makes any clipping visible.
  bool enable_saturation = true;
  // Largest recorded value in ADU (including the bias), finite and > 0; when saturation is enabled it must
  // exceed bias_adu. Use the lower of the ADC range and full_well_e / gain + bias. Default 65535: a 16-bit
  // ADC.
  double saturation_adu = 65535.0;

  // --- ADC quantisation ------------------------------------------------------------------------------------
  // Round to whole ADU. Default off: it adds 1/12 ADU² of variance (negligible when read noise >> 1 ADU)
  // and makes noiseless output inexact; turn on to study the ADC itself.
  bool enable_quantization = false;

  // --- Bad pixels ----------------------------------------------------------------------------------------
  // Apply bad_pixel_mask: pixels where it is 0 read bias_adu (dead) and get weight 0. Default off.
  bool enable_bad_pixels = false;
  // Camera-shaped map, 1 = good, 0 = bad (no other values). Required (non-empty) when enable_bad_pixels;
  // its shape must equal the frames' (checked when recording). See RandomBadPixelMask.
  Image bad_pixel_mask;

  // --- Fill factor
  // ------------------------------------------------------------------------------------------ Sensitive
  // fraction of the pixel's *side* (linear; the sensitive area fraction is fill_factor²), in (0, 1]. Used by
  // Detector::PixelResponse on the HR grid (top of file). Default 1: the forward model's box
  // (back-illuminated and micro-lensed detectors are close to 1).
  double fill_factor = 1.0;

  // True if every field is in range; otherwise false and, if why != nullptr, *why names the field.
  bool IsValid(std::string* why) const;
};

// A recorded frame and what a reconstructor needs to use it.
struct DetectorFrame {
  Image adu;                       // recorded values, ADU
  Image saturated;                 // 1 where the value was clipped at saturation_adu, else 0
  Image valid;                     // 1 usable, 0 bad or saturated
  Image inverse_variance;          // 1 / Var[ADU] from the model at the expected λ, ADU⁻²; 0 where !valid
  double noise_sigma_e = 0.0;      // kPeakFraction: the σ used, electrons; else 0
  std::int64_t uniform_draws = 0;  // random numbers consumed (Poisson uniforms) ...
  std::int64_t normal_draws = 0;   // ... and normal deviates: 0 when no noise is enabled
};

class Detector {
 public:
  // Validates `options` (InvalidArgument "Detector: <field> ...").
  explicit Detector(DetectorOptions options);

  const DetectorOptions& options() const { return options_; }

  // The enabled stages in order, one human-readable line each (e.g. "read noise 5 e- RMS").
  std::vector<std::string> Plan() const;

  // Records one frame from `expected_e`, the noiseless signal in electrons per pixel for this frame (after
  // D_r or PixelResponse), finite; negative values beyond FFT rounding (< −1e-6 · max(1, peak)) are rejected,
  // smaller ones count as 0. `frame` selects the random stream (see top of file). kPeakFraction takes σ from
  // this frame's peak; use RecordSequence for the paper's peak over all frames.
  DetectorFrame Record(const Image& expected_e, std::uint64_t seed, std::uint64_t frame = 0) const;
  // The same into `out`, reusing its buffers when the shape is unchanged (a sequence loop then allocates
  // nothing; first-touching four fresh 8 MB images per megapixel frame can cost more than the noise itself).
  void Record(const Image& expected_e, std::uint64_t seed, std::uint64_t frame, DetectorFrame* out) const;
  // Records frames 0..N−1 (frame i with stream i). All frames must share one shape.
  std::vector<DetectorFrame> RecordSequence(const ImageStack& expected_e, std::uint64_t seed) const;

  // Noiseless mean in ADU before clipping and bad pixels: λ/g + bias (no quantisation).
  Image MeanAdu(const Image& expected_e) const;
  // Model variance in ADU² at λ (see top of file); `peak_sigma_e` is kPeakFraction's σ (ignored otherwise).
  Image VarianceAdu(const Image& expected_e, double peak_sigma_e = 0.0) const;
  // Inverse-variance weights estimated from a recorded frame (real data): λ̂ = max(0, (ADU − bias) g), then
  // as the oracle map; 0 where `valid` is 0. kPeakFraction needs `peak_sigma_e`.
  Image InverseVarianceFromData(const Image& adu, const Image& valid, double peak_sigma_e = 0.0) const;

  // The detector's pixel response on the HR grid: core Decimate(hr, r) for fill_factor 1, else the weighted
  // box (top of file). hr sides must be multiples of r >= 1.
  OperatorPtr PixelResponse(Shape hr, int r) const;

 private:
  // Throws unless `expected_e` is a valid signal frame (finite, >= 0 up to rounding, mask-shaped).
  void CheckFrame(const Image& expected_e, const char* function) const;
  // Background + dark electrons per pixel per frame (those enabled).
  double OffsetElectrons() const;
  // λ = max(s, 0) + background + dark, validated.
  Image ExpectedElectrons(const Image& expected_e) const;
  // kPeakFraction's σ for one frame: peak_noise_fraction · max λ (0 for kPhysical).
  double PeakSigma(const Image& expected_e) const;
  // The fused per-pixel pipeline on a checked frame.
  void RecordChecked(const Image& expected_e, double peak_sigma_e, std::uint64_t seed, std::uint64_t frame,
                     DetectorFrame* out) const;

  DetectorOptions options_;
};

// The fill-factor operator of the top of the file, and its per-axis weights w_0..w_{r−1}.
OperatorPtr PixelResponse(Shape hr, int r, double fill_factor);
std::vector<double> FillFactorWeights(int r, double fill_factor);

// σ = fraction · (largest value over all frames); fraction finite and >= 0, at least one frame.
// (noise.hpp's NoiseSigmaFromPeakFraction is this.)
double PeakFractionSigma(const ImageStack& frames, double fraction);

// Adds sigma · N(0, 1) to every pixel in row-major order from `rng`; returns the deviates drawn (0 if
// sigma == 0). sigma finite and >= 0.
std::int64_t AddNormalNoise(Image* image, double sigma, NormalGenerator* rng);

// A bad-pixel mask (1 good, 0 bad) of shape `s` with each pixel bad independently with probability
// `fraction` in [0, 1], deterministic per seed.
Image RandomBadPixelMask(Shape s, double fraction, std::uint64_t seed);

}  // namespace aosr
