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

#include <limits>
#include <string>
#include <vector>

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
// beside the raw scores, the SUB-PIXEL OFFSET d = (dy, dx) of the estimate against the truth IN THE SCORED
// REGION is measured and the scores are recomputed on the estimate moved back by it.
//
// Model. The estimate is the truth moved by d on the periodic grid, estimate ≈ S_d truth with
//     (S_d x)(y, x) = x(y − dy, x − dx)   (a Fourier/sinc shift: +dx moves the scene toward +x, image.hpp).
//
// Whole-image offset (MeasureImageOffset): d maximises the circular cross-correlation
//     c(d) = Σ_p (S_d truth)(p) · estimate(p) = (1/RC) Re Σ_k E(k) T*(k) exp(+2πi (k_y dy/R + k_x dx/C)),
// which, S_d being unitary, is the least-squares d over the whole periodic image. Found as Guizar-Sicairos,
// Thurman & Fienup, "Efficient subpixel image registration algorithms", Opt. Lett. 33, 156 (2008): the
// whole-pixel peak of c by one inverse FFT, then c evaluated by matrix-multiply DFTs on a 1/20-px grid over
// ±1.2 px around it and on a 1/1000-px grid over ±0.06 px around that. The grid step bounds the error at
// 0.0005 px; on band-limited periodic images the offset is recovered to ~0.001 px (tested to 0.01). Cost
// ~(R + C)·R·C·0.2 complex multiply-adds: ~60 ms for 512 × 512. It is right for images that are periodic
// (the registration of frames against a periodic model, solvers/registration.hpp), and wrong for scoring a
// crop or a ring: the wrap-around step of a non-periodic truth and the border a reconstructor cannot
// reproduce enter c(d) and pull d (issue 31 measured 0.3 HR px in x on a design symmetric in x and y, and an
// "aligned" PSNR 0.85–1.09 dB below the raw one).
//
// Offset in a region (MeasureImageOffsetInWindow; what the aligned scores use), in two steps:
//  1. Start: the peak of the cross-correlation (the search above) of the APODISED images
//       a = w · (truth − μ_w(truth)),   b = w · (estimate − μ_w(estimate)),   μ_w(x) = Σ w x / Σ w,
//     with w ≥ 0 a window that is 0 outside the region and rises smoothly from its edges (ScoreWindow: a Tukey
//     taper, ½(1 − cos(π δ/τ)) at distance δ inside the edge, 1 beyond τ). The windowed images vanish smoothly at
//     the region's edge, so neither the periodic wrap nor what lies outside the region (the border, other rings)
//     enters; the weighted means are removed so that the window's own autocorrelation does not make the peak.
//     This peak is still pulled toward 0 by the window's overlap Σ w(p) w(p + d), the more so the smoother the
//     images (0.29 px of 1.73 on the smooth test scene), so it only starts:
//  2. Least squares in the region: d minimises J(d) = Σ_p v(p) ((S_{−d} estimate)(p) − truth(p))², v the region's
//     scored pixels (1 in the crop or ring, 0 elsewhere; MeasureImageOffsetInWindow uses v = w), by Gauss-Newton
//     (the derivative of S_{−d} e is S_{−d} ∇e, exact in Fourier space) from the peak and from d = 0, keeping the
//     lower J. This is the offset that best aligns the estimate where it is scored: no border and no wrap enters J
//     except through the Fourier shift of the estimate itself, which is what the aligned score sees too. On the
//     band-limited and on the smooth non-periodic test scenes it recovers known shifts to 0.01 px (tested).
// Cost: 3 inverse FFTs per Gauss-Newton step (typically 3-6 steps per start), plus the correlation's 3 FFTs and
// matrix DFTs: ~0.1-0.2 s per region at 512².
//
// Aligned scores (CompareImagesAligned, CompareImagesInRings): PSNR, SSIM and RMSE of S_{−d} estimate against
// the truth, on the same region and with the same dynamic range L as the raw ones, where d is the offset
// measured in that region (the crop, or the ring inside the crop). GUARANTEE: the aligned scores are never below
// the raw ones: the measured offset is APPLIED only when it raises neither the region's MSE nor lowers its SSIM;
// otherwise the reported offset is 0, the aligned scores equal the raw ones bit for bit, `offset_applied` is false
// and `measured_offset` still holds what was measured (0 when the region's truth or estimate has no structure).
// J(d) <= J(0) by construction (Gauss-Newton from 0 only accepts steps that lower J), so the MSE test fails only
// by the FFTs' rounding, when the best offset is ~0; SSIM, a different score, can disagree with the least-squares
// offset. So "aligned" is the better of "as it is" and "moved back by the offset measured where it is scored".

// The sub-pixel translation of `estimate` against `truth` [px, rows then cols]: estimate ≈ S_d truth.
struct ImageOffset {
  double dy = 0.0;  // rows [px], + toward larger row index
  double dx = 0.0;  // columns [px], + toward larger column index
};
// The whole periodic image's offset (above). Errors: as CompareImages' (shapes, empty, non-finite), and a
// truth or estimate with no structure (constant: no correlation peak).
ImageOffset MeasureImageOffset(const Image& truth, const Image& estimate);

// The offset in the region a window selects (above): `window` has the images' shape, values >= 0 and finite,
// and a positive sum. Errors: as MeasureImageOffset (shapes, empty, non-finite), a bad window, and a truth or
// estimate with no structure under the window (constant there: no correlation peak).
ImageOffset MeasureImageOffsetInWindow(const Image& truth, const Image& estimate, const Image& window);

// The apodisation window of a scored region, for MeasureImageOffsetInWindow: the rectangle of `shape` less
// `crop_px` at each border, optionally intersected with the annulus inner_px <= ρ < outer_px about
// (centre_y, centre_x) [px, pixel-centre convention], ρ the distance of a pixel centre from it. Inside the
// region w = T(δ_top) T(δ_bottom) T(δ_left) T(δ_right) T(δ_inner) T(δ_outer), each δ the distance [px] from the
// pixel centre to that edge (the rectangle's edges lie half a pixel outside its outermost pixel centres; an
// annulus with inner_px = 0 has no inner edge), T(δ) = ½(1 − cos(π min(δ/τ, 1))); 0 outside. Taper τ: an
// eighth of each side for the rectangle alone (a Tukey window with α = 0.25 along each axis), a quarter of the
// ring's width (outer − inner) on every edge of a ring (its own and the crop's, so an outer ring cut by the
// crop is not weighted down over an eighth of the image). inner_px < 0 means no ring.
// Errors: crop leaving nothing; non-finite or inverted ring radii.
struct ScoreRing {
  double centre_y = 0.0, centre_x = 0.0;  // [px]
  double inner_px = -1.0;                 // < 0: no ring (the whole crop)
  double outer_px = 0.0;                  // > inner_px
};
Image ScoreWindow(Shape shape, int crop_px, const ScoreRing& ring = {});

// S_d image on the periodic grid: out(y, x) = image(y − dy, x − dx), a Fourier (sinc) shift; the real part
// of the shifted spectrum (the Nyquist row/column of an even side is shifted as cos, which keeps the output
// real). A zero offset returns the image itself, bit for bit. Errors: empty image, non-finite image or offsets.
Image FourierShiftImage(const Image& image, double dy, double dx);

struct AlignedImageMetrics {
  ImageOffset offset;            // applied: the estimate was moved back by it [px]; 0 when not applied
  ImageOffset measured_offset;   // the least-squares offset in the scored region (0 when it has no structure)
  bool offset_applied = false;   // false: the shift would have lowered PSNR or SSIM (or no peak): aligned = raw
  ImageMetrics raw;              // CompareImages(truth, estimate)
  ImageMetrics aligned;          // CompareImages(truth, FourierShiftImage(estimate, −dy, −dx)), or raw
};
// Raw and aligned scores with the offset measured on the crop (see above; aligned >= raw always).
// Errors: as CompareImages.
AlignedImageMetrics CompareImagesAligned(const Image& truth, const Image& estimate,
                                         const MetricOptions& opts = {});

// ---------------------------------------------------------------------------------------------------------
// Scores across the field: concentric rings about a centre (e.g. the guide star, where an AO system corrects
// best: the PSF, and so what a reconstruction recovers, changes with the distance from it).
//
// Geometry. The scored region is the crop (MetricOptions::crop_px). ρ(p) = |p − centre| for each pixel centre
// p; the rings split [ρ_min, ρ_max] into K equal widths w = (ρ_max − ρ_min)/K, ring k holding the pixels with
// ρ_min + k w <= ρ < ρ_min + (k+1) w (the last also ρ = ρ_max), where ρ_max is the largest ρ of a scored pixel
// (a corner of the crop) and ρ_min is 0 when the centre lies in the crop (within half a pixel of its pixel
// centres), else its distance to the crop's nearest pixel centre. Rings far from a centre near a corner are
// arcs cut by the crop: `pixels` says how many pixels each holds, beside `area_px`, the full annulus' area.
//
// Scores in ring k: MSE and PSNR over its pixels; SSIM the mean of SsimMap (of the whole crop) over the
// window positions whose centre pixel lies in the ring. Every ring uses the SAME dynamic range L (opts.peak,
// else the cropped truth's max − min), so rings compare with each other and with CompareImages. Each ring is
// aligned on its own: its offset is measured with ScoreWindow of that ring (so a field-varying PSF's local
// shift is separated from its local blur), with the guarantee above (aligned >= raw in every ring).
//
// Cost: per ring, about one MeasureImageOffset (two FFTs, the matrix DFTs) and one Fourier shift; ~0.1 s per
// ring at 512².
struct RingOptions {
  // Number of rings K, >= 1. Each ring must be at least kMinRingWidthPx wide.
  int rings = 4;
  // The centre [px of the images, pixel-centre convention: pixel (y, x) covers [y−½, y+½)]. NaN (default): the
  // image centre ((R−1)/2, (C−1)/2). Must lie on the image: −½ <= y <= R−½, −½ <= x <= C−½.
  double centre_y = std::numeric_limits<double>::quiet_NaN();
  double centre_x = std::numeric_limits<double>::quiet_NaN();
  // False, and the field in *why, if rings < 1 or a centre coordinate is ±Inf (NaN means "image centre").
  bool IsValid(std::string* why) const;
};
// The narrowest ring [px]: the SSIM window's side. A narrower ring's SSIM would mostly score its neighbours
// (each window reaches 5 px beyond its centre), and its alignment would rest on a sliver.
inline constexpr double kMinRingWidthPx = kSsimWindow;

struct RingScore {
  double inner_px = 0.0;  // ρ range [px] of the ring: inner <= ρ < outer
  double outer_px = 0.0;
  Index pixels = 0;          // scored pixels in the ring (inside the crop)
  Index ssim_positions = 0;  // SSIM window centres in the ring
  double area_px = 0.0;      // π (outer² − inner²): the full annulus, for comparison with `pixels`
  AlignedImageMetrics scores;  // raw and aligned in this ring, its own offset
};
struct RingMetrics {
  double centre_y = 0.0, centre_x = 0.0;  // the centre used [px]
  double peak = 0.0;                      // the dynamic range L used by every ring
  std::vector<RingScore> rings;           // innermost first
};
// The largest K CompareImagesInRings accepts for images of `shape`, this crop and centre (options.rings is not
// read), so that a caller can refuse a bad --rings before a long computation. Errors: crop leaving nothing, a
// centre off the image.
int MaxRings(Shape shape, int crop_px, const RingOptions& options);

// Errors (InvalidArgument naming the function and argument): as CompareImages (shapes, values, options);
// invalid ring options; a centre off the image; rings narrower than kMinRingWidthPx (the message gives the
// largest K allowed); a ring with no SSIM window position.
RingMetrics CompareImagesInRings(const Image& truth, const Image& estimate, const RingOptions& rings,
                                 const MetricOptions& opts = {});

}  // namespace aosr
