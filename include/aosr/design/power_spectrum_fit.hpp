// The object power spectrum of training images, for objective A's Wiener variant (design_objective.hpp) and
// the power-spectrum prior of the Tikhonov/Wiener reconstructor (tikhonov.hpp).
//
// ## What is estimated
//
// The design and the Wiener reconstructor model the object as a stationary random field on the periodic
// M x M HR grid whose DFT coefficients are independent with
//     s(f) = E|X(f)|² / M²     (X the unnormalised DFT, f in cycles per HR pixel, bin (0,0) = zero frequency),
// so that (Parseval) the mean of s over the M² bins is the expected variance per HR pixel. Units: s is in
// (flux per HR pixel)², the pixels of a training image are taken to *be* HR pixels (resample first, e.g.
// with image_object.hpp, if a file's pixel is not θ_hr), and frequencies are in cycles per HR pixel.
//
// ## Periodogram (Welch 1967, IEEE Trans. Audio Electroacoust. 15, 70)
//
// Each of the K training images (any sizes >= M x M) is, in this order,
//   1. rescaled (explicitly, never silently): kNone keeps its units; kPeak multiplies it so that its maximum
//      pixel equals scale_value; kMean so that its mean equals scale_value (s scales as the factor squared);
//   2. mean-subtracted (its own mean);
//   3. cut into M x M patches at a step of patch_step pixels along each axis (the last patch of a row or
//      column is moved flush with the image's edge, so every pixel is used; an image of exactly M x M is one
//      patch);
//   4. per patch p: the window-weighted mean c = Σ w x / Σ w is removed (so the windowed patch has no DC
//      component and the window does not smear the mean level into the lowest frequencies), then
//          P_p(f) = |DFT(w · (x − c))(f)|² / Σ w²,
//      the division by Σ w² (M² for the rectangular window, (3M/8)² for Hann) restoring the power the window
//      removes;
// and the periodogram is the plain average of P_p over all patches of all images. Windows:
//   kRectangular  w = 1. Exact Parseval: with one patch, mean_f P(f) = the variance of the mean-removed
//                 patch. Unbiased only for a periodic patch: a real image's edges leak power ∝ |f|⁻², which
//                 swamps spectra steeper than that.
//   kHann         w(j) = sin²(π (j + ½) / M) per axis (separable; no zero samples). Side lobes fall as |f|⁻⁶,
//                 so spectra up to |f|⁻⁵ are measured. For a field whose spectrum is sampled on the grid the
//                 expected periodogram is exactly s smoothed by the separable kernel [1/6, 2/3, 1/6] (|Ŵ|²
//                 normalised); the fit models this smoothing (below). Default, with patch_step M/2 (50%
//                 overlap, the usual Welch choice: nearly independent estimates from twice the patches).
// With several patches, mean_f P(f) is the mean of the patches' (windowed) variances: it leaves out the
// variance of the patch means, i.e. power below 1/M that the M-grid cannot represent anyway.
//
// ## Parametric fit
//
// The isotropic model
//     s(f) = a / (f0² + |f|²)^(β/2)  +  w            (a > 0, f0 > 0, w >= 0 the optional white floor)
// is fitted by weighted least squares in log space on annuli of the grid: annulus b holds the bins with
// round(M|f|) = b and f_min <= |f| <= f_max. Its residual is
//     ρ_b = sqrt(n_b) (ln P̄_b − ln m̄_b),   P̄_b = mean of the periodogram over the annulus,
//                                            m̄_b = mean of (κ ⊛ s_θ) over the annulus,
// with n_b the annulus' bin count (ln P̄_b has variance ∝ 1/n_b) and κ the window's smoothing kernel (δ for
// kRectangular, [1/6, 2/3, 1/6]² for kHann, applied circularly). The default f_min = 2/M for Hann (1/M for
// rectangular) skips the bins the mean removal of step 4 touches (|k| <= √2). Parameters θ = (ln a, ln f0,
// β, ln w): a grid search over f0 with (ln a, β) solved linearly at each f0 starts Levenberg-Marquardt
// (a small dense Gauss-Newton with damping; ~4 parameters). Reported: a, f0, β, w, the residual RMS
// sqrt(Σ ρ_b² / Σ n_b) (the typical log misfit, so 0.05 ≈ 5%), annuli, patches and iterations.
//
// The fitted model sampled on the M x M grid (`spectrum`) is what the design uses: smooth, with no
// periodogram noise; `periodogram` is the raw average (0 at f = 0 by step 4; the model's s(0) = a/f0^β + w
// is the fit's extrapolation). Tested (power_spectrum_fit_physics_test.cpp states the measured values): a, f0,
// β recovered from Gaussian random fields drawn with that spectrum (β within 0.013, f0 3.4%, a 1.3% over 20
// seeds of 900 patches); white noise gives a flat periodogram at σ²; Parseval; dead leaves give β = 2.0 below
// 1/r_min and 3.4 above (the natural-image range |f|^-(2..3)). A flat spectrum does not determine β and f0
// separately (β -> 0, or f0 beyond the band): the fitted *spectrum* is then flat, the parameters arbitrary.
//
// ## The matching Tikhonov / Wiener prior
//
// tikhonov.hpp's kPowerSpectrum prior is parameterised compatibly: S(f) = (1 + |f|²/f₀²)^(−β/2) with the same
// |f| (cycles per HR pixel), and the Bayesian reading E|X(f)|²/M² = (σ²/λ) S(f). Since
//     a / (f0² + |f|²)^(β/2) = (a / f0^β) · (1 + |f|²/f0²)^(−β/2),
// the fitted spectrum (w = 0) is exactly that prior with spectrum_corner = f0, spectrum_slope = β and
//     λ = σ² f0^β / a          (σ: noise per LR pixel, in the object's flux units; the Wiener choice).
// Then DesignObjective's Wiener-consistent s = (σ²/λ)/P(f) (empty object_power_spectrum) *is* the fitted
// model. With a floor w > 0, or f0 > 0.5, or β outside [0, 8] (tikhonov's ranges), the parametric form
// cannot express it and WienerPriorOptions samples the model on the caller's HR grid instead:
// object_power_spectrum = s/s(0), λ = σ²/s(0) (tied to that grid).
//
// API rules: every entry point validates its options and inputs first and throws InvalidArgument naming the
// function and the argument or field (an image by its index: "images[2]"); LoadTrainingImages throws IoError
// naming the path for an unreadable file. Results are deterministic; nothing here is threaded.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "aosr/core/image.hpp"
#include "aosr/solvers/power_spectrum_model.hpp"
#include "aosr/solvers/tikhonov.hpp"

namespace aosr {

// PowerSpectrumModel and PowerSpectrumGrid live in solvers/power_spectrum_model.hpp (shared with the Wiener
// prior fitted to the frames, solvers/frame_power_spectrum.hpp).

// A periodic, real, stationary Gaussian random field on `shape` with spectrum s = model: x = IDFT(√s · DFT(n)),
// n white N(0, 1) (NormalGenerator, seed), so E|X(f)|²/(H W) = s(f) exactly at the grid's frequencies and the
// pixel variance is the mean of s over the grid. For tests and synthetic training sets. Both sides >= 2.
Image GaussianRandomField(Shape shape, const PowerSpectrumModel& model, std::uint64_t seed);

enum class SpectralWindow { kRectangular, kHann };
const char* ToString(SpectralWindow window);

// How training images in arbitrary units are brought to flux per HR pixel (step 1 above).
enum class TrainingScaling {
  kNone,  // the pixel values are already flux per HR pixel
  kPeak,  // each image is multiplied so that its maximum is scale_value (needs a positive maximum)
  kMean,  // each image is multiplied so that its mean is scale_value (needs a positive mean)
};
const char* ToString(TrainingScaling scaling);

struct PowerSpectrumFitOptions {
  // M: the patch side and the grid of the returned spectra, in [8, 4096]. For the design, its HR grid
  // (DesignOptics::grid). Default 64 (the paper system's design grid).
  Index grid = 64;
  // Default kHann (see top): real images are not periodic.
  SpectralWindow window = SpectralWindow::kHann;
  // Step between patch origins [HR px], in [0, 4096]; 0: M/2 for Hann (Welch's 50% overlap), M for
  // rectangular (tiles).
  Index patch_step = 0;
  // Step 1's rescaling and its target (finite, > 0; flux per HR pixel). Default: keep the units.
  TrainingScaling scaling = TrainingScaling::kNone;
  double scale_value = 1.0;
  // Fit the white floor w (true) or hold w = 0 (false, the default: the tikhonov-compatible form). A floor
  // absorbs noise or quantisation in the training images; it is not part of the object.
  bool fit_floor = false;
  // Frequencies fitted, cycles per HR pixel: min_frequency (0: automatic, 2/M for Hann, 1/M for rectangular;
  // else in (0, 0.5)) <= |f| <= max_frequency (in (min, 0.75]; default 0.5: the annuli the grid samples
  // completely). At least 5 annuli must remain.
  double min_frequency = 0.0;
  double max_frequency = 0.5;
  // Levenberg-Marquardt: iteration cap (>= 1) and the relative cost decrease below which it stops (in (0, 0.1)).
  int max_iterations = 200;
  double tolerance = 1e-12;

  bool IsValid(std::string* why) const;
};

struct PowerSpectrumFit {
  PowerSpectrumModel model;  // the fitted a, f0, β (and w)
  Image spectrum;            // the model on the M x M grid (PowerSpectrumGrid): what the design uses
  Image periodogram;         // the raw averaged periodogram, M x M, unshifted
  Index patches = 0;         // patches averaged (over all images)
  int images = 0;
  std::vector<double> scales;  // the factor each image was multiplied by in step 1 (1 for kNone)
  double mean_power = 0.0;   // mean of the periodogram over the grid: the mean windowed patch variance
  // The annuli fitted: centre frequency (cycles/HR px), mean periodogram P̄_b, mean fitted model m̄_b, bins n_b.
  std::vector<double> annulus_frequency, annulus_power, annulus_model;
  std::vector<int> annulus_bins;
  double residual_rms = 0.0;  // sqrt(Σ n_b (ln P̄_b − ln m̄_b)² / Σ n_b)
  int iterations = 0;         // Levenberg-Marquardt iterations
  bool converged = false;     // stopped by the tolerance, not the cap
  std::string message;

  // "a 1.02e+00, f0 0.0503, beta 2.98 (floor 0), residual 0.031 over 30 annuli, 1922 patches of 64x64 from
  // 2 images, 12 iterations (converged)".
  std::string BriefReport() const;
};

// The periodogram and the fit (see top). InvalidArgument for no images, an image smaller than M x M, a
// non-finite pixel, a constant image (zero variance after mean removal), a scaling target the image cannot
// meet (kPeak with max <= 0, kMean with mean <= 0), or fewer than 5 annuli with power in the band (annuli
// below 1e-12 of the largest annulus' power are rounding and left out; the message counts them).
PowerSpectrumFit FitPowerSpectrum(const std::vector<Image>& images, const PowerSpectrumFitOptions& options);

// The Tikhonov options whose kPowerSpectrum prior is the Wiener prior of `model` for noise σ per LR pixel
// (> 0, flux per HR pixel units; see top): parametric (spectrum_slope β, spectrum_corner f0, λ = σ² f0^β / a)
// when w = 0, f0 <= 0.5 and 0 <= β <= 8; otherwise object_power_spectrum = s/s(0) sampled on `hr` and λ =
// σ²/s(0). Fixed λ rule; every other field at its default.
TikhonovOptions WienerPriorOptions(const PowerSpectrumModel& model, double noise_sigma, Shape hr);

// Training images from files (io/image_io.hpp's ReadImage: FITS as stored, PNG/TIFF/JPEG as grayscale in
// [0, 1]), unscaled: FitPowerSpectrum's `scaling` states their units. IoError naming the path for an
// unreadable file; InvalidArgument naming the path for an empty list or a file with non-finite pixels.
std::vector<Image> LoadTrainingImages(const std::vector<std::string>& paths);

}  // namespace aosr
