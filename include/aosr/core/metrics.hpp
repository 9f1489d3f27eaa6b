// Full-reference image-quality metrics: how close a reconstruction `estimate` is to the known `truth`.
//
// All three metrics are computed on the same region: the images with `crop_px` pixels removed from each
// border (reconstructions are least trustworthy at the edges, where periodic or zero boundaries bite).
// Let x = truth and y = estimate on that region, n its pixel count, and L the dynamic range:
//
//   RMSE  = sqrt( (1/n) Σ (y - x)² )                       in the images' units.
//
//   PSNR  = 10 log10( L² / MSE ),   MSE = RMSE²             in dB.
//           L is MetricOptions::peak when given (> 0), otherwise the data range max(x) - min(x) of the
//           (cropped) truth. The convention matters: scikit-image's peak_signal_noise_ratio uses the dtype
//           range and MATLAB's psnr uses 1 for double images; state L when comparing numbers across tools.
//           Identical images (MSE = 0) give PSNR = +infinity (std::numeric_limits<double>::infinity()), a
//           documented result, never NaN.
//
//   SSIM  = the mean structural similarity of Wang, Bovik, Sheikh & Simoncelli, "Image quality assessment:
//           from error visibility to structural similarity", IEEE Trans. Image Process. 13(4):600-612
//           (2004), eq. (13) with the Gaussian window of their §III-C. For each window position,
//             μx = Σ w x,   σx² = Σ w (x - μx)²,   σxy = Σ w (x - μx)(y - μy)    (weights w, Σ w = 1)
//             SSIM(x,y) = (2 μx μy + C1)(2 σxy + C2) / ((μx² + μy² + C1)(σx² + σy² + C2)),
//             C1 = (K1 L)², C2 = (K2 L)²,  K1 = 0.01, K2 = 0.03,
//           with w(i,j) ∝ exp(-(i² + j²) / (2·1.5²)), i, j ∈ {-5..5} (11 x 11, normalised to unit sum; the
//           window is separable, so it is applied as two 1-D passes). The map is evaluated only where the
//           window fits inside the cropped images ('valid' region: x (C-10) positions) and SSIM is
//           its plain mean. The variances are population (weighted, biased) moments, not sample ones.
//           This is what Wang's reference ssim_index.m (2003) computes (filter2(window, ·, 'valid') with
//           fspecial('gaussian', 11, 1.5), mean2 of the map), and what scikit-image's
//           structural_similarity computes with gaussian_weights=True, sigma=1.5,
//           use_sample_covariance=False and an explicit data_range = L (its filter is truncated at
//           3.5 sigma, i.e. 11 taps, and it averages the map after cropping (11-1)/2 pixels per side, the
//           same valid region). Two differences to keep in mind: (1) with peak = 0 we take L from the
//           truth's range, whereas ssim_index.m assumes L = 255 and scikit-image requires data_range for
//           float images; (2) Wang's later ssim.m first downsamples images larger than 256 px by
//           round(min(R,C)/256), and MATLAB's toolbox ssim() filters 'same'-size with replicate padding;
//           we do neither.
//           SSIM is symmetric in x and y except through L (taken from the truth), and equals 1 iff x = y.
//
// Numerical note: σ² is computed as Σ w x² - μ² after subtracting each image's mean over the region
// (SSIM's σ terms are shift-invariant), so large offsets do not cancel catastrophically.
//
// Errors (aosr::InvalidArgument naming the function and argument): shapes differ; an image is empty; either
// image holds NaN or ±Inf; opts invalid (negative crop_px, negative or non-finite peak); the crop leaves an
// empty region (RMSE, PSNR) or a region smaller than the 11 x 11 SSIM window (SSIM, CompareImages); peak = 0
// and the cropped truth is constant, so no dynamic range can be derived (PSNR, SSIM: pass opts.peak).
#pragma once

#include <string>

#include "aosr/core/image.hpp"

namespace aosr {

// The SSIM window of Wang et al. (2004), exposed so tests and reports can state what was used.
inline constexpr int kSsimWindow = 11;       // side of the square Gaussian window, pixels
inline constexpr double kSsimSigma = 1.5;    // its standard deviation, pixels
inline constexpr double kSsimK1 = 0.01;      // C1 = (K1 L)²: stabilises the luminance term near μ = 0
inline constexpr double kSsimK2 = 0.03;      // C2 = (K2 L)²: stabilises the contrast term near σ = 0

struct MetricOptions {
  // Pixels ignored at each of the four borders, >= 0. Default 0: the whole image. Use it to keep
  // boundary artefacts of a reconstructor (wrap-around, zero padding) out of the score.
  int crop_px = 0;
  // Dynamic range L used by PSNR and SSIM, in image units, >= 0. Default 0 means "derive it": L =
  // max(truth) - min(truth) over the cropped truth. Give it explicitly (e.g. 1 for images normalised to
  // [0, 1]) when comparing against other tools or across truths with different ranges.
  double peak = 0.0;

  // True if every field is in range; otherwise false and, if why != nullptr, *why names the field.
  bool IsValid(std::string* why) const;
};

// Root-mean-square error over the cropped region (see top of file). Units of the images.
double Rmse(const Image& truth, const Image& estimate, const MetricOptions& opts = {});

// Peak signal-to-noise ratio in dB, 10 log10(L² / MSE); +infinity for identical images.
double Psnr(const Image& truth, const Image& estimate, const MetricOptions& opts = {});

// Mean SSIM (Wang et al. 2004) over the valid window positions of the cropped images; in [-1, 1].
double Ssim(const Image& truth, const Image& estimate, const MetricOptions& opts = {});

// The SSIM map itself: one value per valid window position, shape (R' - 10) x (C' - 10) for a cropped
// region of R' x C'. Element (i, j) belongs to the window centred on cropped pixel (i + 5, j + 5), i.e. on
// pixel (i + 5 + crop_px, j + 5 + crop_px) of the inputs. Ssim() is this map's mean.
Image SsimMap(const Image& truth, const Image& estimate, const MetricOptions& opts = {});

// The three metrics at once, on the same region and with the same L.
struct ImageMetrics {
  double psnr = 0.0;  // dB (+infinity when estimate == truth)
  double ssim = 0.0;  // dimensionless, 1 for identical images
  double rmse = 0.0;  // image units
};
ImageMetrics CompareImages(const Image& truth, const Image& estimate, const MetricOptions& opts = {});

// ---------------------------------------------------------------------------------------------------------
// Scores that separate resolution from astrometry (DESIGN.md §4; the burst super-resolution convention).
//
// A reconstruction displaced by a fraction of a pixel loses many dB of PSNR though it resolves exactly as
// much: the offset is an astrometric error, not a loss of resolution, and the two are judged apart. So
// beside the raw scores, the GLOBAL SUB-PIXEL OFFSET d = (dy, dx) of the estimate against the truth is
// measured and the scores are recomputed on the estimate moved back by it.
//
// Offset. The estimate is modelled as the truth moved by d on the periodic grid, estimate ≈ S_d truth with
//     (S_d x)(y, x) = x(y − dy, x − dx)   (a Fourier/sinc shift: +dx moves the scene toward +x, image.hpp),
// and d is the translation that maximises the circular cross-correlation
//     c(d) = Σ_p (S_d truth)(p) · estimate(p) = (1/RC) Re Σ_k E(k) T*(k) exp(+2πi (k_y dy/R + k_x dx/C)),
// which, S_d being unitary, is the least-squares d: it minimises ‖estimate − S_d truth‖² over the whole
// (uncropped) periodic image. Found as Guizar-Sicairos, Thurman & Fienup, "Efficient subpixel image
// registration algorithms", Opt. Lett. 33, 156 (2008): the whole-pixel peak of c by one inverse FFT, then
// c evaluated by matrix-multiply DFTs on a 1/20-px grid over ±1.2 px around it and on a 1/1000-px grid over
// ±0.06 px around that. The grid step bounds the error at 0.0005 px; on band-limited images the offset is
// recovered to ~0.001 px (tested to 0.01). Cost ~(R + C)·R·C·0.2 complex multiply-adds: ~60 ms for
// 512 × 512. On images that are not band-limited (sharp edges on the HR grid) or not periodic the Fourier
// shift rings; the scores after it are then a lower bound on what a perfect alignment would give.
//
// Aligned scores: PSNR, SSIM and RMSE of S_{−d} estimate against the truth, on the same crop and with the same
// dynamic range L as the raw ones. Aligned ≥ raw up to the crop (c is maximised over the whole image).

// The sub-pixel translation of `estimate` against `truth` [px, rows then cols]: estimate ≈ S_d truth.
struct ImageOffset {
  double dy = 0.0;  // rows [px], + toward larger row index
  double dx = 0.0;  // columns [px], + toward larger column index
};
// Errors: as CompareImages' (shapes, empty, non-finite), and a truth or estimate with no structure (constant:
// no correlation peak).
ImageOffset MeasureImageOffset(const Image& truth, const Image& estimate);

// S_d image on the periodic grid: out(y, x) = image(y − dy, x − dx), a Fourier (sinc) shift; the real part
// of the shifted spectrum (the Nyquist row/column of an even side is shifted as cos, which keeps the output
// real). A zero offset returns the image itself, bit for bit. Errors: empty image, non-finite image or offsets.
Image FourierShiftImage(const Image& image, double dy, double dx);

struct AlignedImageMetrics {
  ImageOffset offset;    // of the estimate against the truth [px of the images' grid]
  ImageMetrics raw;      // CompareImages(truth, estimate)
  ImageMetrics aligned;  // CompareImages(truth, FourierShiftImage(estimate, −dy, −dx))
};
// Raw and aligned scores with the offset (see above). Errors: as CompareImages and MeasureImageOffset.
AlignedImageMetrics CompareImagesAligned(const Image& truth, const Image& estimate,
                                         const MetricOptions& opts = {});

}  // namespace aosr
