#include "aosr/core/metrics.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>
#include <Eigen/Dense>
#include <utility>
#include <vector>

#include "aosr/core/error.hpp"
#include "aosr/core/fft.hpp"

namespace aosr {
namespace {

// The cropped region shared by every metric, after all argument checks.
struct Region {
  Image truth;
  Image estimate;
};

// Validates the common arguments and returns the cropped images. `min_side` is the smallest region side
// the caller can work with (1 for RMSE/PSNR, the SSIM window for SSIM).
Region CheckAndCrop(const char* function, const Image& truth, const Image& estimate,
                    const MetricOptions& opts, Index min_side) {
  std::string why;
  if (!opts.IsValid(&why)) throw InvalidArgument(std::string(function) + ": invalid opts: " + why);
  CheckArgument(truth.size() > 0, function, "truth", ToString(ShapeOf(truth)), "a non-empty image");
  CheckArgument(ShapeOf(estimate) == ShapeOf(truth), function, "estimate shape", ToString(ShapeOf(estimate)),
                "the truth's shape " + ToString(ShapeOf(truth)));
  CheckArgument(AllFinite(truth), function, "truth", "an image with NaN or Inf", "finite values only");
  CheckArgument(AllFinite(estimate), function, "estimate", "an image with NaN or Inf", "finite values only");
  const Index rows = truth.rows() - 2 * Index{opts.crop_px};
  const Index cols = truth.cols() - 2 * Index{opts.crop_px};
  CheckArgument(rows >= min_side && cols >= min_side, function, "opts.crop_px", opts.crop_px,
                "a crop leaving at least " + std::to_string(min_side) + "x" + std::to_string(min_side) +
                    " pixels of the " + ToString(ShapeOf(truth)) + " images" +
                    (min_side > 1 ? " (the SSIM window)" : ""));
  const Index c = opts.crop_px;
  return {truth.block(c, c, rows, cols), estimate.block(c, c, rows, cols)};
}

// The dynamic range L: opts.peak if given, otherwise the cropped truth's data range (must be > 0).
double DynamicRange(const char* function, const Image& cropped_truth, const MetricOptions& opts) {
  if (opts.peak > 0.0) return opts.peak;
  const double range = cropped_truth.maxCoeff() - cropped_truth.minCoeff();
  CheckArgument(range > 0.0, function, "opts.peak", "0 (derived from the truth's range, which is 0)",
                "> 0: the truth is constant over the cropped region, so state the dynamic range explicitly");
  return range;
}

double MeanSquaredError(const Region& r) { return (r.estimate - r.truth).square().mean(); }

// The normalised 1-D Gaussian taps g(k) ∝ exp(-(k - 5)² / (2 σ²)), k = 0..10. The 2-D window of Wang et
// al. is g gᵀ: normalising the 1-D taps normalises their outer product.
Vector SsimTaps() {
  Vector g(kSsimWindow);
  const int half = kSsimWindow / 2;
  for (int k = 0; k < kSsimWindow; ++k) {
    const double d = k - half;
    g(k) = std::exp(-d * d / (2.0 * kSsimSigma * kSsimSigma));
  }
  return g / g.sum();
}

// 'Valid' separable filtering: out(i, j) = Σ_{k,l} g(k) g(l) in(i + k, j + l), shape (R - 10) x (C - 10).
// The window is symmetric, so correlation and convolution coincide.
Image ValidFilter(const Image& in, const Vector& g) {
  const Index n = g.size();
  const Index out_rows = in.rows() - n + 1, out_cols = in.cols() - n + 1;
  Image along_x = Image::Zero(in.rows(), out_cols);
  for (Index k = 0; k < n; ++k) along_x += g(k) * in.middleCols(k, out_cols);
  Image out = Image::Zero(out_rows, out_cols);
  for (Index k = 0; k < n; ++k) out += g(k) * along_x.middleRows(k, out_rows);
  return out;
}

// The SSIM map of two cropped, validated images for dynamic range L.
Image SsimMapOfRegion(const Region& r, double dynamic_range) {
  const Vector g = SsimTaps();
  // Centre each image on its mean: μ is shift-equivariant and σ², σxy shift-invariant, so the moments of
  // the centred images give the same SSIM while Σ w x² - μ² no longer cancels a large offset.
  const double mean_x = r.truth.mean(), mean_y = r.estimate.mean();
  const Image xc = r.truth - mean_x;
  const Image yc = r.estimate - mean_y;
  const Image mu_xc = ValidFilter(xc, g);
  const Image mu_yc = ValidFilter(yc, g);
  const Image var_x = ValidFilter(xc.square(), g) - mu_xc.square();
  const Image var_y = ValidFilter(yc.square(), g) - mu_yc.square();
  const Image cov_xy = ValidFilter(xc * yc, g) - mu_xc * mu_yc;
  const Image mu_x = mu_xc + mean_x;
  const Image mu_y = mu_yc + mean_y;
  const double c1 = (kSsimK1 * dynamic_range) * (kSsimK1 * dynamic_range);
  const double c2 = (kSsimK2 * dynamic_range) * (kSsimK2 * dynamic_range);
  // Both denominators are >= C1 > 0 and >= C2 - (rounding) > 0, so the map is finite.
  return ((2.0 * mu_x * mu_y + c1) * (2.0 * cov_xy + c2)) /
         ((mu_x.square() + mu_y.square() + c1) * (var_x + var_y + c2));
}

}  // namespace

bool MetricOptions::IsValid(std::string* why) const {
  auto fail = [why](const std::string& message) {
    if (why != nullptr) *why = message;
    return false;
  };
  if (crop_px < 0) return fail("crop_px = " + std::to_string(crop_px) + " (must be >= 0)");
  if (!std::isfinite(peak) || peak < 0.0) return fail("peak = " + ToString(peak) + " (must be finite and >= 0)");
  return true;
}

double Rmse(const Image& truth, const Image& estimate, const MetricOptions& opts) {
  const Region r = CheckAndCrop("Rmse", truth, estimate, opts, 1);
  return std::sqrt(MeanSquaredError(r));
}

double Psnr(const Image& truth, const Image& estimate, const MetricOptions& opts) {
  const Region r = CheckAndCrop("Psnr", truth, estimate, opts, 1);
  const double peak = DynamicRange("Psnr", r.truth, opts);
  const double mse = MeanSquaredError(r);
  if (mse == 0.0) return std::numeric_limits<double>::infinity();
  return 10.0 * std::log10(peak * peak / mse);
}

Image SsimMap(const Image& truth, const Image& estimate, const MetricOptions& opts) {
  const Region r = CheckAndCrop("SsimMap", truth, estimate, opts, kSsimWindow);
  return SsimMapOfRegion(r, DynamicRange("SsimMap", r.truth, opts));
}

double Ssim(const Image& truth, const Image& estimate, const MetricOptions& opts) {
  const Region r = CheckAndCrop("Ssim", truth, estimate, opts, kSsimWindow);
  return SsimMapOfRegion(r, DynamicRange("Ssim", r.truth, opts)).mean();
}

ImageMetrics CompareImages(const Image& truth, const Image& estimate, const MetricOptions& opts) {
  const Region r = CheckAndCrop("CompareImages", truth, estimate, opts, kSsimWindow);
  const double peak = DynamicRange("CompareImages", r.truth, opts);
  const double mse = MeanSquaredError(r);
  ImageMetrics m;
  m.rmse = std::sqrt(mse);
  m.psnr = mse == 0.0 ? std::numeric_limits<double>::infinity() : 10.0 * std::log10(peak * peak / mse);
  m.ssim = SsimMapOfRegion(r, peak).mean();
  return m;
}

namespace {

constexpr double kTwoPiMetrics = 6.283185307179586476925286766559;

void CheckOffsetImages(const char* function, const Image& truth, const Image& estimate) {
  CheckArgument(truth.size() > 0, function, "truth", ToString(ShapeOf(truth)), "a non-empty image");
  CheckArgument(ShapeOf(estimate) == ShapeOf(truth), function, "estimate shape", ToString(ShapeOf(estimate)),
                "the truth's shape " + ToString(ShapeOf(truth)));
  CheckArgument(AllFinite(truth), function, "truth", "an image with NaN or Inf", "finite values only");
  CheckArgument(AllFinite(estimate), function, "estimate", "an image with NaN or Inf", "finite values only");
  CheckArgument(truth.maxCoeff() > truth.minCoeff(), function, "truth", "a constant image",
                "an image with structure (a constant has no correlation peak)");
  CheckArgument(estimate.maxCoeff() > estimate.minCoeff(), function, "estimate", "a constant image",
                "an image with structure (a constant has no correlation peak)");
}

// c(sy_j, sx_l) = Re Σ_k X(k) exp(+2πi (f_y sy_j / R + f_x sx_l / C)) on the (2h+1)² grid
// s = centre + (j − h) step: a matrix-multiply DFT (Guizar-Sicairos et al. 2008). Returns the best grid point.
ImageOffset RefinePeak(const ComplexImage& x, ImageOffset centre, double step, int h) {
  const Index rows = x.rows(), cols = x.cols(), n = 2 * h + 1;
  Eigen::MatrixXcd ey(n, rows), ex(cols, n);
  for (Index j = 0; j < n; ++j) {
    const double sy = centre.dy + static_cast<double>(j - h) * step;
    const double sx = centre.dx + static_cast<double>(j - h) * step;
    for (Index k = 0; k < rows; ++k) {
      const double a = kTwoPiMetrics * static_cast<double>(SignedFrequency(k, rows)) * sy / rows;
      ey(j, k) = Complex(std::cos(a), std::sin(a));
    }
    for (Index k = 0; k < cols; ++k) {
      const double a = kTwoPiMetrics * static_cast<double>(SignedFrequency(k, cols)) * sx / cols;
      ex(k, j) = Complex(std::cos(a), std::sin(a));
    }
  }
  const Eigen::MatrixXcd spectrum = x.matrix();
  const Eigen::MatrixXd c = (ey * spectrum * ex).real();
  Index by = 0, bx = 0;
  c.maxCoeff(&by, &bx);
  return {centre.dy + static_cast<double>(by - h) * step, centre.dx + static_cast<double>(bx - h) * step};
}

}  // namespace

namespace {

// The cross-power spectrum E T* of two real images (full, R x C), from their half spectra.
ComplexImage CrossSpectrum(const Image& estimate, const Image& truth) {
  return ExpandHalfSpectrum(FftR2C(estimate) * FftR2C(truth).conjugate(), estimate.cols());
}

// The d that maximises c(d) = (1/RC) Re Σ_k X(k) exp(+2πi (k_y dy/R + k_x dx/C)) for a cross-power spectrum
// X = E T*: the whole-pixel peak by one inverse FFT, then the two matrix-DFT refinements (see the header).
ImageOffset PeakOfCrossSpectrum(const ComplexImage& cross) {
  const Index rows = cross.rows(), cols = cross.cols();
  const Image coarse = FftInverse(cross).real();
  Index iy = 0, ix = 0;
  coarse.maxCoeff(&iy, &ix);
  ImageOffset d{static_cast<double>(SignedFrequency(iy, rows)), static_cast<double>(SignedFrequency(ix, cols))};
  d = RefinePeak(cross, d, 0.05, 24);   // ±1.2 px at 1/20 px
  d = RefinePeak(cross, d, 0.001, 60);  // ±0.06 px at 1/1000 px
  // A one-pixel-wide image axis has no sub-pixel information along it.
  if (rows == 1) d.dy = 0.0;
  if (cols == 1) d.dx = 0.0;
  return d;
}

// w · (x − μ_w(x)) with μ_w(x) = Σ w x / Σ w; nullopt when x has no structure under the window (its weighted
// standard deviation is below 1e-12 of its weighted mean's magnitude, or exactly 0).
std::optional<Image> Apodised(const Image& x, const Image& w, double sum_w) {
  const double mean = (w * x).sum() / sum_w;
  const Image centred = x - mean;
  const double variance = (w * centred.square()).sum() / sum_w;
  if (!(variance > 1e-24 * mean * mean)) return std::nullopt;
  return Image(w * centred);
}

// The even (half-sample symmetric) extension of x to 2R × 2C: ext(2R − 1 − y, x) = ext(y, x), the same along
// columns. It is periodic AND continuous where its grid wraps, so a Fourier shift of it does not ring from the
// step between a non-periodic image's opposite edges (what a shift of the image itself does).
Image MirrorExtend(const Image& x) {
  const Index rows = x.rows(), cols = x.cols();
  Image ext(2 * rows, 2 * cols);
  ext.topLeftCorner(rows, cols) = x;
  ext.topRightCorner(rows, cols) = x.rowwise().reverse();
  ext.bottomRows(rows) = ext.topRows(rows).colwise().reverse();
  return ext;
}

// The estimate moved back by d on its mirror extension, cropped to the image: S_{−d} e, and its derivatives
// ∂(S_{−d} e)/∂d = S_{−d} ∇e. The extension's half spectrum E is transformed once per estimate and shared by every
// region scored on it (the rings of CompareImagesInRings); each image is then one real inverse transform.
//
// The phase exp(+2πi f·d) is Hermitian except on the Nyquist row and column (f = +1/2 there for both members of a
// pair), so E·phase is not the spectrum of a real image. The real part of its complex inverse (what is meant) is the
// inverse of its Hermitian part H(k) = ½(X(k) + conj X(−k)); since E(−k) = conj E(k), H = E·Q with
// Q(k) = ½(q(k) + conj q(−k)) for the phase-and-derivative factor q, separable as q(k) = a(k_y)·c(k_x). So each
// stored bin gets E·½(a c + b d) with b, d the conjugated partners' factors, and c2r returns exactly that real part
// (equal to the complex inverse's real part up to rounding, at half its cost and without its complex buffers).
// A rectangle of an image: top-left corner (y, x) and shape.
struct Box {
  Index y = 0, x = 0, rows = 0, cols = 0;
};

// The smallest box holding every non-zero of w (w not all zero).
Box NonZeroBox(const Image& w) {
  Index y0 = w.rows(), y1 = -1, x0 = w.cols(), x1 = -1;
  for (Index y = 0; y < w.rows(); ++y)
    for (Index x = 0; x < w.cols(); ++x)
      if (w(y, x) != 0.0) {
        y0 = std::min(y0, y), y1 = std::max(y1, y);
        x0 = std::min(x0, x), x1 = std::max(x1, x);
      }
  if (y1 < 0) return Box{0, 0, w.rows(), w.cols()};
  return Box{y0, x0, y1 - y0 + 1, x1 - x0 + 1};
}

class MirrorShift {
 public:
  enum class Part { kValue, kDy, kDx };

  explicit MirrorShift(const Image& estimate)
      : image_(ShapeOf(estimate)), ext_cols_(2 * estimate.cols()), spectrum_(FftR2C(MirrorExtend(estimate))) {}

  // S_{−d} e (Part::kValue) or one of its derivatives on `box` of the image (rows, cols of its top-left corner and
  // its shape). Not thread-safe: the transform's buffers are kept between calls (a fresh 2R x 2C array per call
  // cost more in page faults than the transform itself).
  Image Transform(ImageOffset d, Part part, const Box& box) const {
    const Index rows = spectrum_.rows(), half = spectrum_.cols(), cols = ext_cols_;
    // Per row: a(k) = py(k)·my(k) and b(k) = conj(a(−k)); per column the same with px, mx.
    ComplexVector a(rows), b(rows), c(half), e(half);
    auto factor = [](Index k, Index n, double shift, bool derivative) {
      const double f = static_cast<double>(SignedFrequency(k, n)) / static_cast<double>(n);
      const Complex phase(std::cos(kTwoPi * f * shift), std::sin(kTwoPi * f * shift));
      return derivative ? phase * Complex(0.0, kTwoPi * f) : phase;
    };
    for (Index k = 0; k < rows; ++k) {
      a(k) = factor(k, rows, d.dy, part == Part::kDy);
      b(k) = std::conj(factor((rows - k) % rows, rows, d.dy, part == Part::kDy));
    }
    for (Index l = 0; l < half; ++l) {
      c(l) = factor(l, cols, d.dx, part == Part::kDx);
      e(l) = std::conj(factor((cols - l) % cols, cols, d.dx, part == Part::kDx));
    }
    y_.resize(rows, half);
    for (Index k = 0; k < rows; ++k)
      for (Index l = 0; l < half; ++l) y_(k, l) = spectrum_(k, l) * (0.5 * (a(k) * c(l) + b(k) * e(l)));
    FftC2RInto(y_, cols, &out_);
    return out_.block(box.y, box.x, box.rows, box.cols);
  }

  // The estimate moved back by d for scoring; d = 0 is not moved (the caller keeps the image itself then).
  Image Shifted(ImageOffset d) const { return Transform(d, Part::kValue, Box{0, 0, image_.rows, image_.cols}); }

 private:
  Shape image_;
  Index ext_cols_;
  ComplexImage spectrum_;  // half spectrum of the mirror extension, 2R x (C + 1)
  mutable ComplexImage y_;
  mutable Image out_;
};

// The misfit of the region with the intensity nuisances fitted: J(d) = min_{g,b} Σ v (g·e_d + b − t)² (a weighted
// linear regression of t on e_d), with its g and b. A gain and a level are fitted so that the shift does not absorb
// a level or contrast difference: along a brightness gradient a shift changes the local level, and a plain
// least-squares shift would trade astrometry for photometry.
struct RegionFit {
  double j = 0.0, gain = 1.0, bias = 0.0;
};
RegionFit FitGainAndBias(const Image& e, const Image& truth, const Image& weights) {
  const double sw = weights.sum(), se = (weights * e).sum(), st = (weights * truth).sum();
  const double see = (weights * e.square()).sum(), set = (weights * e * truth).sum();
  const double det = sw * see - se * se;
  RegionFit f;
  if (det > 1e-12 * sw * see && det > 0.0) {
    f.gain = (sw * set - se * st) / det;
    f.bias = (st - f.gain * se) / sw;
  } else {  // a constant estimate in the region: only the level
    f.gain = 0.0;
    f.bias = st / sw;
  }
  f.j = (weights * (f.gain * e + f.bias - truth).square()).sum();
  return f;
}

// Gauss-Newton (variable projection) on J(d) from `start`: each step solves the 4x4 normal equations of (dy, dx, g,
// b) at the current fit, moves d only (capped at 0.5 px, halved up to 6 times until J decreases) and refits g and b
// exactly; stops when a step is below 1e-5 px or after 12 steps. J never increases. Returns d and J(d).
std::pair<ImageOffset, double> RefineShift(const MirrorShift& shift, const Image& full_truth,
                                           const Image& full_weights, ImageOffset start) {
  // J only sees the pixels with a weight: every image below is cut to their box.
  const Box box = NonZeroBox(full_weights);
  const Image truth = full_truth.block(box.y, box.x, box.rows, box.cols);
  const Image weights = full_weights.block(box.y, box.x, box.rows, box.cols);
  ImageOffset d = start;
  Image e = shift.Transform(d, MirrorShift::Part::kValue, box);
  RegionFit fit = FitGainAndBias(e, truth, weights);
  const Image ones = Image::Ones(box.rows, box.cols);
  for (int it = 0; it < 12; ++it) {
    // The Jacobian at d; a trial needs only its value (one transform), the derivatives only where it is accepted.
    const Image jy = fit.gain * shift.Transform(d, MirrorShift::Part::kDy, box);
    const Image jx = fit.gain * shift.Transform(d, MirrorShift::Part::kDx, box);
    const Image r = fit.gain * e + fit.bias - truth;
    const Image* cols[4] = {&jy, &jx, &e, &ones};
    Eigen::Matrix4d a;
    Eigen::Vector4d rhs;
    for (int i = 0; i < 4; ++i) {
      rhs(i) = -(weights * *cols[i] * r).sum();
      for (int k = 0; k <= i; ++k) a(i, k) = a(k, i) = (weights * *cols[i] * *cols[k]).sum();
    }
    if (!(a(0, 0) * a(1, 1) - a(0, 1) * a(0, 1) > 0.0)) break;  // no gradient in the region: nothing to align on
    const Eigen::Vector4d step = a.ldlt().solve(rhs);
    if (!step.allFinite()) break;
    double sy = step(0), sx = step(1);
    const double len = std::hypot(sy, sx);
    if (len > 0.5) sy *= 0.5 / len, sx *= 0.5 / len;
    bool accepted = false;
    for (int halving = 0; halving < 7 && !accepted; ++halving) {
      const ImageOffset trial{d.dy + sy, d.dx + sx};
      Image te = shift.Transform(trial, MirrorShift::Part::kValue, box);
      const RegionFit tf = FitGainAndBias(te, truth, weights);
      if (tf.j < fit.j) {
        d = trial;
        e = std::move(te);
        fit = tf;
        accepted = true;
      } else {
        sy *= 0.5;
        sx *= 0.5;
      }
    }
    if (!accepted || std::hypot(sy, sx) < 1e-5) break;
  }
  return {d, fit.j};
}

// The offset in a region (header): the peak of the cross-correlation of the images apodised by `window`, then the
// least-squares offset of the region itself, Σ v (S_{−d} e − t)² with weights v (the scored pixels), by
// Gauss-Newton from that peak and from 0, keeping the lower misfit. nullopt when the truth or the estimate has no
// structure under the window. Arguments already checked.
std::optional<ImageOffset> RegionOffset(const Image& truth, const Image& estimate, const MirrorShift& shift,
                                        const Image& window, const Image& weights) {
  const double sum_w = window.sum();
  const std::optional<Image> a = Apodised(truth, window, sum_w);
  const std::optional<Image> b = Apodised(estimate, window, sum_w);
  if (!a || !b) return std::nullopt;
  const ComplexImage cross = CrossSpectrum(*b, *a);
  const ImageOffset peak = PeakOfCrossSpectrum(cross);
  std::pair<ImageOffset, double> best = RefineShift(shift, truth, weights, ImageOffset{});
  if (peak.dy != 0.0 || peak.dx != 0.0) {
    const std::pair<ImageOffset, double> from_peak = RefineShift(shift, truth, weights, peak);
    if (from_peak.second < best.second) best = from_peak;
  }
  ImageOffset d = best.first;
  // A one-pixel-wide image axis has no sub-pixel information along it.
  if (truth.rows() == 1) d.dy = 0.0;
  if (truth.cols() == 1) d.dx = 0.0;
  return d;
}

}  // namespace

ImageOffset MeasureImageOffset(const Image& truth, const Image& estimate) {
  CheckOffsetImages("MeasureImageOffset", truth, estimate);
  // Cross-power spectrum E T*: its inverse transform is c at whole-pixel shifts.
  const ComplexImage cross = CrossSpectrum(estimate, truth);
  return PeakOfCrossSpectrum(cross);
}

ImageOffset MeasureImageOffsetInWindow(const Image& truth, const Image& estimate, const Image& window) {
  const char* f = "MeasureImageOffsetInWindow";
  CheckArgument(truth.size() > 0, f, "truth", ToString(ShapeOf(truth)), "a non-empty image");
  CheckArgument(ShapeOf(estimate) == ShapeOf(truth), f, "estimate shape", ToString(ShapeOf(estimate)),
                "the truth's shape " + ToString(ShapeOf(truth)));
  CheckArgument(ShapeOf(window) == ShapeOf(truth), f, "window shape", ToString(ShapeOf(window)),
                "the truth's shape " + ToString(ShapeOf(truth)));
  CheckArgument(AllFinite(truth), f, "truth", "an image with NaN or Inf", "finite values only");
  CheckArgument(AllFinite(estimate), f, "estimate", "an image with NaN or Inf", "finite values only");
  CheckArgument(AllFinite(window) && window.minCoeff() >= 0.0 && window.sum() > 0.0, f, "window",
                "values min " + ToString(window.minCoeff()) + ", sum " + ToString(window.sum()),
                "finite weights >= 0 with a positive sum (ScoreWindow)");
  const double sum_w = window.sum();
  CheckArgument(Apodised(truth, window, sum_w).has_value(), f, "truth", "constant under the window",
                "an image with structure in the windowed region (a constant has no correlation peak)");
  CheckArgument(Apodised(estimate, window, sum_w).has_value(), f, "estimate", "constant under the window",
                "an image with structure in the windowed region (a constant has no correlation peak)");
  return *RegionOffset(truth, estimate, MirrorShift(estimate), window, window);
}

Image ScoreWindow(Shape shape, int crop_px, const ScoreRing& ring) {
  const char* f = "ScoreWindow";
  const Index c = crop_px, rows = shape.rows - 2 * c, cols = shape.cols - 2 * c;
  CheckArgument(crop_px >= 0 && rows > 0 && cols > 0, f, "crop_px", crop_px,
                ">= 0 and leaving pixels of the " + ToString(shape) + " image");
  const bool has_ring = ring.inner_px >= 0.0;
  if (has_ring) {
    CheckArgument(std::isfinite(ring.centre_y) && std::isfinite(ring.centre_x), f, "ring centre",
                  ToString(ring.centre_y) + ", " + ToString(ring.centre_x), "finite [px]");
    CheckArgument(std::isfinite(ring.outer_px) && ring.outer_px > ring.inner_px, f, "ring outer_px", ring.outer_px,
                  "finite and > inner_px = " + ToString(ring.inner_px));
  }
  // Tukey taper: T(δ) = ½(1 − cos(π δ/τ)) for 0 < δ < τ, 0 at δ <= 0, 1 beyond τ.
  auto taper = [](double delta, double tau) {
    if (delta <= 0.0) return 0.0;
    if (delta >= tau) return 1.0;
    return 0.5 * (1.0 - std::cos(kPi * delta / tau));
  };
  const double ring_tau = has_ring ? 0.25 * (ring.outer_px - ring.inner_px) : 0.0;
  const double tau_y = has_ring ? ring_tau : rows / 8.0;
  const double tau_x = has_ring ? ring_tau : cols / 8.0;
  // The rectangle's edges lie half a pixel outside its outermost pixel centres.
  const double top = c - 0.5, bottom = double(shape.rows - c) - 0.5;
  const double left = c - 0.5, right = double(shape.cols - c) - 0.5;
  Image w = Image::Zero(shape.rows, shape.cols);
  for (Index y = c; y < shape.rows - c; ++y) {
    const double ty = taper(y - top, tau_y) * taper(bottom - y, tau_y);
    for (Index x = c; x < shape.cols - c; ++x) {
      double v = ty * taper(x - left, tau_x) * taper(right - x, tau_x);
      if (has_ring) {
        const double rho = std::hypot(y - ring.centre_y, x - ring.centre_x);
        if (rho < ring.inner_px || rho >= ring.outer_px) continue;
        v *= taper(ring.outer_px - rho, ring_tau);
        if (ring.inner_px > 0.0) v *= taper(rho - ring.inner_px, ring_tau);
      }
      w(y, x) = v;
    }
  }
  return w;
}

Image FourierShiftImage(const Image& image, double dy, double dx) {
  const char* f = "FourierShiftImage";
  CheckArgument(image.size() > 0, f, "image", ToString(ShapeOf(image)), "a non-empty image");
  CheckArgument(AllFinite(image), f, "image", "an image with NaN or Inf", "finite values only");
  CheckArgument(std::isfinite(dy), f, "dy", dy, "a finite offset [px]");
  CheckArgument(std::isfinite(dx), f, "dx", dx, "a finite offset [px]");
  if (dy == 0.0 && dx == 0.0) return image;  // exactly, not to the FFTs' rounding
  const Index rows = image.rows(), cols = image.cols();
  ComplexImage x = FftForward(image.cast<Complex>());
  for (Index k = 0; k < rows; ++k) {
    const double ay = -kTwoPiMetrics * static_cast<double>(SignedFrequency(k, rows)) * dy / rows;
    for (Index l = 0; l < cols; ++l) {
      const double a = ay - kTwoPiMetrics * static_cast<double>(SignedFrequency(l, cols)) * dx / cols;
      x(k, l) *= Complex(std::cos(a), std::sin(a));
    }
  }
  return FftInverse(x).real();
}

AlignedImageMetrics CompareImagesAligned(const Image& truth, const Image& estimate, const MetricOptions& opts) {
  AlignedImageMetrics m;
  m.raw = CompareImages(truth, estimate, opts);  // checks shapes, values and options first
  m.aligned = m.raw;
  Image scored = Image::Zero(truth.rows(), truth.cols());
  const Index c = opts.crop_px;
  scored.block(c, c, truth.rows() - 2 * c, truth.cols() - 2 * c).setOnes();
  const MirrorShift shift(estimate);
  const std::optional<ImageOffset> d =
      RegionOffset(truth, estimate, shift, ScoreWindow(ShapeOf(truth), opts.crop_px), scored);
  if (!d) return m;  // no structure on the crop: no peak, nothing to align
  m.measured_offset = *d;
  if (d->dy == 0.0 && d->dx == 0.0) {
    m.offset_applied = true;  // moved back by 0: the estimate itself
    return m;
  }
  // Applied only when it raises neither the crop's MSE nor lowers its SSIM (header: aligned >= raw).
  const ImageMetrics a = CompareImages(truth, shift.Shifted(*d), opts);
  if (a.rmse <= m.raw.rmse && a.ssim >= m.raw.ssim) {
    m.aligned = a;
    m.offset = *d;
    m.offset_applied = true;
  }
  return m;
}

bool RingOptions::IsValid(std::string* why) const {
  auto fail = [why](const std::string& message) {
    if (why != nullptr) *why = message;
    return false;
  };
  if (rings < 1) return fail("rings = " + std::to_string(rings) + " (must be >= 1)");
  if (std::isinf(centre_y) || std::isinf(centre_x))
    return fail("centre = (" + ToString(centre_y) + ", " + ToString(centre_x) +
                ") (must be finite [px], or NaN for the image centre)");
  return true;
}

namespace {

// Mean squared error and SSIM over one ring: `ring_of` holds each scored pixel's ring (or −1), `map` the SSIM
// map of the crop (element (i, j) centred on crop pixel (i + 5, j + 5)).
struct RingSums {
  std::vector<double> squared_error, ssim;
  std::vector<Index> pixels, positions;
};
RingSums SumRings(const Region& region, const Image& map, const Eigen::Array<int, Eigen::Dynamic, Eigen::Dynamic,
                                                                          Eigen::RowMajor>& ring_of, int rings) {
  RingSums s;
  s.squared_error.assign(std::size_t(rings), 0.0);
  s.ssim.assign(std::size_t(rings), 0.0);
  s.pixels.assign(std::size_t(rings), 0);
  s.positions.assign(std::size_t(rings), 0);
  for (Index y = 0; y < ring_of.rows(); ++y)
    for (Index x = 0; x < ring_of.cols(); ++x) {
      const int k = ring_of(y, x);
      const double e = region.estimate(y, x) - region.truth(y, x);
      s.squared_error[std::size_t(k)] += e * e;
      ++s.pixels[std::size_t(k)];
    }
  const int half = kSsimWindow / 2;
  for (Index i = 0; i < map.rows(); ++i)
    for (Index j = 0; j < map.cols(); ++j) {
      const int k = ring_of(i + half, j + half);
      s.ssim[std::size_t(k)] += map(i, j);
      ++s.positions[std::size_t(k)];
    }
  return s;
}

ImageMetrics RingScores(const RingSums& s, int k, double peak) {
  const std::size_t i = std::size_t(k);
  const double mse = s.squared_error[i] / double(s.pixels[i]);
  ImageMetrics m;
  m.rmse = std::sqrt(mse);
  m.psnr = mse == 0.0 ? std::numeric_limits<double>::infinity() : 10.0 * std::log10(peak * peak / mse);
  m.ssim = s.ssim[i] / double(s.positions[i]);
  return m;
}

}  // namespace

namespace {

// The rings' centre and radial span over the crop (header: geometry), and the largest K whose rings are at
// least kMinRingWidthPx wide (1 at least: one ring is the whole crop).
struct RingSpan {
  double centre_y = 0.0, centre_x = 0.0, rho_min = 0.0, rho_max = 0.0;
  int max_rings = 1;
};
RingSpan RingSpanOf(const char* f, Shape shape, int crop_px, const RingOptions& options) {
  const Index rows = shape.rows, cols = shape.cols, c = crop_px;
  RingSpan s;
  s.centre_y = std::isnan(options.centre_y) ? 0.5 * double(rows - 1) : options.centre_y;
  s.centre_x = std::isnan(options.centre_x) ? 0.5 * double(cols - 1) : options.centre_x;
  const double cy = s.centre_y, cx = s.centre_x;
  CheckArgument(cy >= -0.5 && cy <= rows - 0.5 && cx >= -0.5 && cx <= cols - 0.5, f, "centre (y, x)",
                "(" + ToString(cy) + ", " + ToString(cx) + ") px",
                "a point on the " + ToString(shape) + " image: -0.5 <= y <= " + ToString(rows - 0.5) +
                    ", -0.5 <= x <= " + ToString(cols - 0.5));
  // The crop's pixel centres span [c, rows − c − 1] × [c, cols − c − 1].
  const double y0 = double(c), y1 = double(rows - c - 1), x0 = double(c), x1 = double(cols - c - 1);
  s.rho_max = std::hypot(std::max(std::abs(cy - y0), std::abs(cy - y1)), std::max(std::abs(cx - x0), std::abs(cx - x1)));
  const bool inside = cy >= y0 - 0.5 && cy <= y1 + 0.5 && cx >= x0 - 0.5 && cx <= x1 + 0.5;
  s.rho_min = inside ? 0.0 : std::hypot(cy - std::clamp(cy, y0, y1), cx - std::clamp(cx, x0, x1));
  s.max_rings = std::max(1, int(std::floor((s.rho_max - s.rho_min) / kMinRingWidthPx)));
  return s;
}

}  // namespace

int MaxRings(Shape shape, int crop_px, const RingOptions& options) {
  const char* f = "MaxRings";
  CheckArgument(crop_px >= 0 && shape.rows - 2 * Index{crop_px} > 0 && shape.cols - 2 * Index{crop_px} > 0, f,
                "crop_px", crop_px, ">= 0 and leaving pixels of the " + ToString(shape) + " image");
  return RingSpanOf(f, shape, crop_px, options).max_rings;
}

RingMetrics CompareImagesInRings(const Image& truth, const Image& estimate, const RingOptions& ring_options,
                                 const MetricOptions& opts) {
  const char* f = "CompareImagesInRings";
  std::string why;
  if (!ring_options.IsValid(&why)) throw InvalidArgument(std::string(f) + ": invalid rings: " + why);
  const Region region = CheckAndCrop(f, truth, estimate, opts, kSsimWindow);
  RingMetrics out;
  out.peak = DynamicRange(f, region.truth, opts);
  const Index c = opts.crop_px;
  const RingSpan span = RingSpanOf(f, ShapeOf(truth), opts.crop_px, ring_options);
  out.centre_y = span.centre_y;
  out.centre_x = span.centre_x;
  const double cy = out.centre_y, cx = out.centre_x, rho_min = span.rho_min, rho_max = span.rho_max;
  const int k_rings = ring_options.rings;
  const double width = (rho_max - rho_min) / k_rings;
  CheckArgument(k_rings <= span.max_rings, f, "rings", k_rings,
                "1 .. " + std::to_string(span.max_rings) + " for this centre and crop: rings from " + ToString(rho_min) +
                    " to " + ToString(rho_max) + " px at least " + ToString(kMinRingWidthPx) +
                    " px wide (the SSIM window)");
  // Each scored pixel's ring.
  Eigen::Array<int, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> ring_of(region.truth.rows(), region.truth.cols());
  for (Index y = 0; y < ring_of.rows(); ++y)
    for (Index x = 0; x < ring_of.cols(); ++x) {
      const double rho = std::hypot(double(y + c) - cy, double(x + c) - cx);
      ring_of(y, x) = std::clamp(int(std::floor((rho - rho_min) / width)), 0, k_rings - 1);
    }
  const RingSums raw = SumRings(region, SsimMapOfRegion(region, out.peak), ring_of, k_rings);
  const MirrorShift shift(estimate);  // one transform of the estimate for every ring
  for (int k = 0; k < k_rings; ++k) {
    RingScore ring;
    ring.inner_px = rho_min + k * width;
    ring.outer_px = k + 1 == k_rings ? rho_max : rho_min + (k + 1) * width;
    ring.pixels = raw.pixels[std::size_t(k)];
    ring.ssim_positions = raw.positions[std::size_t(k)];
    ring.area_px = kPi * (ring.outer_px * ring.outer_px - ring.inner_px * ring.inner_px);
    CheckArgument(ring.pixels > 0 && ring.ssim_positions > 0, f, "rings", k_rings,
                  "fewer rings: ring " + std::to_string(k) + " (" + ToString(ring.inner_px) + " <= rho < " +
                      ToString(ring.outer_px) + " px) holds " + std::to_string(ring.pixels) + " scored pixels and " +
                      std::to_string(ring.ssim_positions) + " SSIM window centres");
    out.rings.push_back(ring);
  }
  for (int k = 0; k < k_rings; ++k) {
    RingScore& ring = out.rings[std::size_t(k)];
    AlignedImageMetrics& m = ring.scores;
    m.raw = RingScores(raw, k, out.peak);
    m.aligned = m.raw;
    // The ring's own window (the innermost ring about a centre inside the crop has inner_px = 0: a disc).
    const ScoreRing sr{cy, cx, ring.inner_px, ring.outer_px};
    Image in_ring = Image::Zero(truth.rows(), truth.cols());
    for (Index y = 0; y < ring_of.rows(); ++y)
      for (Index x = 0; x < ring_of.cols(); ++x)
        if (ring_of(y, x) == k) in_ring(y + c, x + c) = 1.0;
    const std::optional<ImageOffset> d =
        RegionOffset(truth, estimate, shift, ScoreWindow(ShapeOf(truth), opts.crop_px, sr), in_ring);
    if (!d) continue;
    m.measured_offset = *d;
    if (d->dy == 0.0 && d->dx == 0.0) {
      m.offset_applied = true;
      continue;
    }
    const Image moved = shift.Shifted(*d);
    const Region shifted{region.truth, moved.block(c, c, region.truth.rows(), region.truth.cols())};
    const ImageMetrics a = RingScores(SumRings(shifted, SsimMapOfRegion(shifted, out.peak), ring_of, k_rings), k, out.peak);
    if (a.rmse <= m.raw.rmse && a.ssim >= m.raw.ssim) {
      m.aligned = a;
      m.offset = *d;
      m.offset_applied = true;
    }
  }
  return out;
}

}  // namespace aosr
