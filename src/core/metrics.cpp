#include "aosr/core/metrics.hpp"

#include <cmath>
#include <limits>

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

ImageOffset MeasureImageOffset(const Image& truth, const Image& estimate) {
  CheckOffsetImages("MeasureImageOffset", truth, estimate);
  const Index rows = truth.rows(), cols = truth.cols();
  // Cross-power spectrum E T*: its inverse transform is c at whole-pixel shifts.
  const ComplexImage cross = FftForward(estimate.cast<Complex>()) * FftForward(truth.cast<Complex>()).conjugate();
  const Image coarse = FftInverse(cross).real();
  Index iy = 0, ix = 0;
  coarse.maxCoeff(&iy, &ix);
  ImageOffset d{static_cast<double>(SignedFrequency(iy, rows)), static_cast<double>(SignedFrequency(ix, cols))};
  // A one-pixel-wide image axis has no sub-pixel information along it.
  d = RefinePeak(cross, d, 0.05, 24);   // ±1.2 px at 1/20 px
  d = RefinePeak(cross, d, 0.001, 60);  // ±0.06 px at 1/1000 px
  if (rows == 1) d.dy = 0.0;
  if (cols == 1) d.dx = 0.0;
  return d;
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
  m.offset = MeasureImageOffset(truth, estimate);
  m.aligned = CompareImages(truth, FourierShiftImage(estimate, -m.offset.dy, -m.offset.dx), opts);
  return m;
}

}  // namespace aosr
