// The slanted-edge MTF (ISO 12233 e-SFR) of an image, or of a region of it: how much contrast the image keeps
// at each spatial frequency, measured on a straight edge. It needs no truth, so it applies to simulated and
// measured images alike (the method of sfrmat3/sfrmat4 by P. Burns, MTF Mapper and Imatest; implemented here
// from the method, not from their code).
//
// ## The method
//
// 1. Orientation. In the region (ROI), the edge is taken as near-vertical when the summed |horizontal pixel
//    differences| exceed the summed |vertical| ones; otherwise the ROI is transposed and the edge is read as
//    near-horizontal. Below, "rows" run along the edge and x across it. The polarity s = ±1 makes the edge
//    rise toward +x (the mean of the right quarter of the columns minus the left quarter's).
// 2. Edge location, per row y: the derivative along the row, g(x) = s (I(y, x+1) − I(y, x−1)) / 2, weighted by a
//    Hamming window of half-width C/2 (C columns) centred on the current guess, and its centroid
//    x_e(y) = Σ x g w / Σ g w (sub-pixel). A least-squares line x_e(y) = a + b y is fitted; then, as sfrmat3/4 do,
//    the centroids are measured again with the window centred on the fitted line and the line is fitted again.
//    Edge angle θ = atan(b) from the column direction (reported in degrees, with the fit's RMS residual).
// 3. Edge-spread function (ESF). Every pixel is projected onto the edge normal: its signed distance
//        d = (x − a − b y) / sqrt(1 + b²)     [px, + toward the bright side]
//    and averaged into bins of Δ = 1/4 px (4× oversampling, bin k at d = kΔ), over the distances every row
//    of the ROI covers (|d| <= X: a symmetric range, X >= 5 px, capped by esf_half_width_px). The slant makes
//    the rows sample the edge at different sub-pixel phases; over rows spanning >= 1 px of phase
//    (R |b| / sqrt(1 + b²) >= 1 for R rows) every bin gets samples. Only the centred rows that span a whole
//    number of pixels of phase are binned (as sfrmat4 does), so that every phase counts equally. An isolated empty bin (both neighbours
//    filled, e.g. at a "critical" angle atan(p/q) where projected pixel centres fall on a lattice) is filled by
//    linear interpolation and counted; two empty bins in a row refuse the edge.
// 4. Line-spread function: LSF_k = (ESF_{k+1} − ESF_{k−1}) / (2Δ) (one-sided at the two ends), multiplied by
//    a window centred on the LSF peak (the LSF centroid within ±2 px of its maximum) and as long as the
//    ESF allows on the shorter side: Tukey (cosine tapers on the outer `tukey_taper` fraction, default 0.5) or
//    Hamming (ISO 12233's). The window trades noise against the bias of cutting the LSF's tails: on an Airy
//    pattern (tails ∝ 1/x²) a ±15 px window reads the MTF up to 0.03 high, ±50 px 0.01, ±96 px 0.003.
//    Before the window, the tails are smoothed (smooth_tails, default on): beyond T = 2h + 2 px from the ESF's
//    50 % point (h: the larger of its distances to the 5 % and 95 % points) each LSF bin becomes the mean of the
//    bins within ±min(4 px, (|d − d50| − T)/2). A smooth tail keeps its low-frequency content, which is all a
//    long-tailed LSF contributes beyond the core, and loses its bin-to-bin noise: at contrast-to-noise 100 on an
//    Airy edge read over ±96 px, the worst MTF50 error of 8 noise draws fell from 1.2 % to 0.6 %.
// 5. MTF: the DFT of the windowed LSF evaluated at any frequency f [cycles/px] (a direct sum, not an FFT grid),
//        MTF(f) = | Σ_k LSF_k w_k exp(−2πi f (d̄_k − c)) | / | Σ_k LSF_k w_k |    (normalised at f = 0),
//    with d̄_k the mean distance of bin k's samples (its centre kΔ when it was empty): with few rows per phase
//    cycle a bin's samples do not spread evenly over it (at 8°, 0.14 px of phase per row), and pairing each ESF
//    difference with where its samples lie keeps a pixel-box edge within 0.012 of its sinc up to 1 cycle/px
//    (0.023 with bin centres),
//    divided by two known transfer functions of the method itself:
//      * the central difference: sin(2πfΔ)/(2πfΔ) = sinc(2fΔ) (sinc(x) = sin(πx)/(πx)), as sfrmat's
//        derivative correction does for its own kernel;
//      * the bin average: a bin holds samples spread evenly over its Δ, so its mean is the ESF convolved with
//        a Δ-wide box: sinc(fΔ) (2.5 % at f = 0.5; the phase-coverage rule of step 3 makes "evenly" true).
//    Both are exact for the ideal ESF; the corrections amplify noise by ≤ 1/(sinc(2fΔ) sinc(fΔ)), 1.75 at
//    f = 1 cycle/px. The curve is reported for 0 <= f <= curve_max (default 1 cycle/px: twice the sampling's
//    Nyquist 0.5, which the 4× oversampled ESF resolves); nothing is evaluated past 1.5 cycles/px.
//
// What the curve is. Along the normal n, the LSF is the projection of the 2-D point response (optics × pixel
// box) and its DFT is the 2-D OTF on the line f·n (projection-slice theorem). So an edge at angle θ reads
// |OTF(f cosθ, f sinθ)|: for the pixel box that is sinc(f cosθ) sinc(f sinθ), not sinc(f) (0.3 % apart at
// f = 0.5, θ = 10°).
//
// Figures: MTF50 and MTF10, the lowest frequencies where the curve falls to 0.5 and 0.1 (found on a 1/200
// cycles/px grid from 0, then by bisection of the continuous DFT to 1e-7 cycles/px); NaN (with `reached`
// false) when the curve does not fall that low below 1.5 cycles/px. The MTF at the frequencies asked for,
// at the camera's Nyquist 1/(2r) cycles per HR pixel for an HR image at super-resolution factor r, and at
// the optical cut-off D/λ = pixel_lambda_over_d cycles per pixel (a pixel of p λ/D).
//
// ## Refusals (aosr::InvalidArgument; the message says which and what would do)
// An image with no usable edge never gets a curve:
//  * "no edge": the region is flat, its outer quarters (across the edge) differ by less than a quarter of its
//    range, or its rows hold no single rising edge (the windowed derivative sums to
//    less than a quarter of the contrast in more than a tenth of the rows), or its ESF spans more than twice
//    the step between its ends (a bar or a line: it rises and falls back);
//  * "too short": fewer than min_edge_length_px rows along the edge, or fewer than 12 px across it;
//  * "too tilted": more than max_angle_deg (default 40°) from the nearer axis: at 45° rows and columns are
//    equally good readings and the projected pixel aperture changes;
//  * "too close to vertical/horizontal": the edge moves across less than one pixel over the rows, so the 4×
//    binning has empty phases (needs |tan θ| >= 1/R: 2.9° for 20 rows, 0.57° for 100); or two adjacent
//    bins are empty (a critical angle);
//  * "leaves the region": the edge comes within 5 px of the region's side in some row (or crosses it, so that
//    rows hold no edge);
//  * "clipped": a plateau of pixels at the region's maximum (minimum) value that starts within twice the ESF's
//    10-90 % rise of the edge and less than half as far from it as the plateau at the other extreme (or with
//    none there): a symmetric optical
//    response approaches both levels alike, a saturated detector stops at one. Pixels count as on a plateau
//    within 1e-6 of the region's range of its extreme, and a plateau needs max(4, 1 % of the pixels). Two
//    equally clipped extremes cannot be told from a noise-free edge and pass;
//  * "too noisy": contrast-to-noise ratio below min_contrast_to_noise (default 10), with the noise the
//    robust (1.4826 × median absolute) residual of the pixels about the ESF interpolated at their distance,
//    and the contrast the difference of the ESF's outer quarters (a residual below 1e-9 of the contrast is
//    rounding: noise 0, contrast-to-noise +infinity).
// Also refused: an ROI outside the image, non-finite pixels in it, invalid options (IsValid names the field).
//
// Accuracy (tests/core/slanted_edge_physics_test.cpp, analytic references, edges at 2°, 5° and 10°), max |ΔMTF|
// for 0 <= f <= 0.5 cycles/px and the worst MTF50 error:
//   Gaussian σ = 0.6, 1, 2 px (point-sampled, exp(−2π²σ²f²)), 100 rows × ±32 px, noise-free:   0.0004, 0.04 %
//   the same at contrast-to-noise 100 (σ = 0.6, 1 px), 800 rows × ±16 px:                      0.0032, 0.27 %
//   Airy × pixel box (OTF_circ(f/fc) sinc(f cos θ) sinc(f sin θ)), λ/D = 2 and 1.3 px,
//     200 rows × ±96 px, noise-free:                                                           0.0028, 0.33 %
//     1600 rows × ±96 px, contrast-to-noise 100:                                               0.0052, 0.40 %
//   a pixel-box edge alone (scene/objects.hpp SlantedEdgeTarget) at 3°, 5°, −8° over 160 rows: <= 0.012 up to
//     1 cycle/px (tests/scene/objects_test.cpp).
// The Airy cases' MTF50 reads 0.1-0.4 % high: the ±96 px window still cuts the LSF's 1/x² tails.
// The noisy cases need many rows: the MTF's noise grows with the ESF's length and falls as 1/sqrt(rows).
#pragma once

#include <limits>
#include <string>
#include <vector>

#include "aosr/core/image.hpp"

namespace aosr {

// A rectangle of pixels: columns x0 .. x0 + width − 1, rows y0 .. y0 + height − 1. width or height 0 means "to
// the image's last column / row".
struct PixelRoi {
  Index x0 = 0;
  Index y0 = 0;
  Index width = 0;
  Index height = 0;
};

enum class LsfWindow { kTukey, kHamming };

// The ESF's oversampling: bins of 1/4 px (ISO 12233).
inline constexpr int kEsfOversampling = 4;
// The highest frequency anything is evaluated at [cycles/px]: 3/4 of the oversampled Nyquist (2 cycles/px),
// where the method's corrections (top of file) stay below 4.5.
inline constexpr double kMaxMtfFrequency = 1.5;

struct SlantedEdgeOptions {
  // The region holding one edge, in the image's pixels. Default: the whole image.
  PixelRoi roi;
  // The LSF window (step 4). Tukey by default: its flat middle keeps more of a long-tailed LSF than Hamming's
  // (an Airy edge read through a ±15 px Hamming window is 0.044 high, Tukey 0.030).
  LsfWindow window = LsfWindow::kTukey;
  // Tukey's cosine-tapered fraction of each half, (0, 1]; 1 is the Hann window. Default 0.5.
  double tukey_taper = 0.5;
  // Smooth the LSF's tails before the DFT (step 4): far from the edge a running mean whose half-width grows with
  // the distance (up to 4 px) removes the tails' high-frequency noise and keeps their low-frequency content,
  // which is what a long-tailed LSF contributes. Default true; false: the plain ISO 12233 estimate.
  bool smooth_tails = true;
  // Cap on the ESF's half-length X [px], 0 (default) or >= 5: 0 uses all the region gives. A shorter ESF cuts
  // noise (its variance grows with the window's length) but also the LSF's tails.
  double esf_half_width_px = 0.0;
  // Edge length (rows along the edge) below which the edge is refused as too short, [8, 1e6]. Default 20.
  int min_edge_length_px = 20;
  // Largest angle from the nearer axis [deg], (0, 45]. Default 40.
  double max_angle_deg = 40.0;
  // Smallest contrast-to-noise ratio accepted, >= 0 (0 accepts any). Default 10: below it the MTF's noise
  // at Nyquist is several hundredths even on a few hundred rows.
  double min_contrast_to_noise = 10.0;
  // The reported curve: frequencies 0, step, 2 step, ... <= curve_max [cycles/px]. curve_max in
  // (0, kMaxMtfFrequency], default 1; curve_step in (0, curve_max], default 0.01.
  double curve_max = 1.0;
  double curve_step = 0.01;
  // Further frequencies to report the MTF at [cycles/px], each in [0, kMaxMtfFrequency].
  std::vector<double> frequencies;
  // Super-resolution factor of an HR image, 0 (default: not given) or in [1, 64]: the MTF at the camera's
  // Nyquist 1/(2r) cycles per HR pixel is reported.
  int r = 0;
  // The pixel's size in λ/D, 0 (default: not given) or in (0, kMaxMtfFrequency]: the MTF at the optical
  // cut-off D/λ = pixel_lambda_over_d cycles/px is reported.
  double pixel_lambda_over_d = 0.0;

  // True if every field is in range; otherwise false and, if why != nullptr, *why names the field.
  bool IsValid(std::string* why) const;
};

// The MTF at one frequency.
struct MtfPoint {
  double frequency = 0.0;  // cycles/px
  double mtf = 0.0;
};

// A frequency where the curve first falls to a level (MTF50, MTF10).
struct MtfCrossing {
  double level = 0.0;
  bool reached = false;  // false: the curve stays above `level` up to kMaxMtfFrequency; frequency is NaN
  double frequency = std::numeric_limits<double>::quiet_NaN();  // cycles/px
};

struct SlantedEdgeMtf {
  // The curve, cycles/px and MTF (1 at f = 0).
  std::vector<double> frequency;
  std::vector<double> mtf;
  MtfCrossing mtf50;
  MtfCrossing mtf10;
  std::vector<MtfPoint> at;        // at options.frequencies, in their order
  bool has_nyquist = false;        // options.r given
  MtfPoint nyquist;                // at 1/(2r)
  bool has_cutoff = false;         // options.pixel_lambda_over_d given
  MtfPoint cutoff;                 // at pixel_lambda_over_d

  // The edge, in the image's pixel coordinates.
  bool vertical = true;            // the edge runs along the columns (x varies across it); false: along rows
  double angle_deg = 0.0;          // from the nearer axis: the edge moves tan(angle) px across per px along
  double centre_y = 0.0;           // a point of the fitted edge line: the centre of the ROI's rows (columns)
  double centre_x = 0.0;
  double fit_rms_px = 0.0;         // RMS residual of the per-row edge locations about the line [px]
  Index edge_length_px = 0;        // rows (columns for a horizontal edge) along the edge
  Index rows_binned = 0;           // of them, the centred whole number of phase cycles binned (step 3)
  double low = 0.0;                // the ESF's dark and bright levels (its outer quarters), image units
  double high = 0.0;
  double noise_rms = 0.0;          // robust noise estimate, image units
  double contrast_to_noise = 0.0;  // (high − low) / noise_rms; +infinity for a noise-free image
  int empty_bins = 0;              // isolated empty ESF bins filled by interpolation

  // The ESF and LSF along the normal (+ toward the bright side), at distances d_k = k / 4 px; the LSF is
  // before the window. Image units and image units per px.
  std::vector<double> esf_distance;
  std::vector<double> esf;
  std::vector<double> lsf;

  // One line: "MTF50 0.187 cyc/px, MTF10 0.342 cyc/px, edge 5.0 deg, CNR 102".
  std::string BriefReport() const;
};

// The slanted-edge MTF of `image` in `options.roi` (see the top of the file). Errors: InvalidArgument for an
// ROI outside the image, non-finite pixels in it, invalid options, and an edge refused (top of file).
SlantedEdgeMtf MeasureSlantedEdgeMtf(const Image& image, const SlantedEdgeOptions& options = {});

}  // namespace aosr
