#include "aosr/core/metrics.hpp"

#include <cmath>
#include <limits>

#include "aosr/core/error.hpp"

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

}  // namespace aosr
