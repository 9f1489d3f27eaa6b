#include "aosr/scene/detector.hpp"

#include <algorithm>
#include <cmath>
#include <optional>

#include "aosr/core/error.hpp"
#include "aosr/core/operators.hpp"
#include "aosr/scene/poisson.hpp"

namespace aosr {
namespace {


bool FiniteNonNegative(double v) { return std::isfinite(v) && v >= 0; }

// The weighted box of the fill factor (detector.hpp). Separable: HR pixel (i, j) carries w[i % r] w[j % r].
class FillFactorOp final : public LinearOperator {
 public:
  FillFactorOp(Shape hr, int r, double fill, std::vector<double> w)
      : LinearOperator(hr.size() / (Index(r) * r), hr.size(),
                       "PixelResponse(r=" + std::to_string(r) + ", fill=" + ToString(fill) + ")"),
        hr_(hr),
        r_(r),
        col_w_(hr.cols),
        w_(std::move(w)) {
    for (Index j = 0; j < hr.cols; ++j) col_w_[j] = w_[j % r];
  }

 private:
  void ApplyImpl(ConstRef x, Ref y) const override {
    const Index lr_cols = hr_.cols / r_;
    y.setZero();
    for (Index i = 0; i < hr_.rows; ++i) {
      const double wi = w_[i % r_];
      if (wi == 0) continue;
      const double* row = x.data() + i * hr_.cols;
      double* out = y.data() + (i / r_) * lr_cols;
      for (Index j = 0; j < hr_.cols; ++j) out[j / r_] += wi * col_w_[j] * row[j];
    }
  }
  void ApplyAdjointImpl(ConstRef y, Ref x) const override {
    const Index lr_cols = hr_.cols / r_;
    for (Index i = 0; i < hr_.rows; ++i) {
      const double wi = w_[i % r_];
      const double* in = y.data() + (i / r_) * lr_cols;
      double* row = x.data() + i * hr_.cols;
      for (Index j = 0; j < hr_.cols; ++j) row[j] = wi * col_w_[j] * in[j / r_];
    }
  }
  Shape hr_;
  Index r_;
  std::vector<double> col_w_;
  std::vector<double> w_;
};

}  // namespace

// ---------------------------------------------------------------------------------------------------------
// Options

bool DetectorOptions::IsValid(std::string* why) const {
  if (!(std::isfinite(gain_e_per_adu) && gain_e_per_adu > 0))
    return Fail(why, "gain_e_per_adu must be finite and > 0, got " + ToString(gain_e_per_adu));
  if (!std::isfinite(bias_adu)) return Fail(why, "bias_adu must be finite, got " + ToString(bias_adu));
  if (!(std::isfinite(exposure_time_s) && exposure_time_s > 0))
    return Fail(why, "exposure_time_s must be finite and > 0, got " + ToString(exposure_time_s));
  if (noise_model != NoiseModel::kPhysical && noise_model != NoiseModel::kPeakFraction)
    return Fail(why, "noise_model must be kPhysical or kPeakFraction");
  if (!FiniteNonNegative(read_noise_e))
    return Fail(why, "read_noise_e must be finite and >= 0, got " + ToString(read_noise_e));
  if (!FiniteNonNegative(peak_noise_fraction))
    return Fail(why, "peak_noise_fraction must be finite and >= 0, got " + ToString(peak_noise_fraction));
  if (!FiniteNonNegative(background_e_per_s))
    return Fail(why, "background_e_per_s must be finite and >= 0, got " + ToString(background_e_per_s));
  if (!FiniteNonNegative(dark_current_e_per_s))
    return Fail(why, "dark_current_e_per_s must be finite and >= 0, got " + ToString(dark_current_e_per_s));
  if (!(std::isfinite(saturation_adu) && saturation_adu > 0))
    return Fail(why, "saturation_adu must be finite and > 0, got " + ToString(saturation_adu));
  if (enable_saturation && !(saturation_adu > bias_adu))
    return Fail(why, "saturation_adu must exceed bias_adu = " + ToString(bias_adu) +
                         " when saturation is "
                         "enabled, got " +
                         ToString(saturation_adu));
  if (!(fill_factor > 0 && fill_factor <= 1))
    return Fail(why, "fill_factor must be in (0, 1], got " + ToString(fill_factor));
  if (bad_pixel_mask.size() > 0 && !(bad_pixel_mask == 0 || bad_pixel_mask == 1).all())
    return Fail(why, "bad_pixel_mask must hold only 0 (bad) and 1 (good)");
  if (enable_bad_pixels && bad_pixel_mask.size() == 0)
    return Fail(why, "bad_pixel_mask must be non-empty when enable_bad_pixels is set");
  return true;
}

// ---------------------------------------------------------------------------------------------------------
// Free functions

std::vector<double> FillFactorWeights(int r, double fill_factor) {
  CheckArgument(r >= 1, "FillFactorWeights", "r", r, ">= 1");
  CheckArgument(fill_factor > 0 && fill_factor <= 1, "FillFactorWeights", "fill_factor", fill_factor,
                "(0, 1]");
  const double lo = 0.5 * r * (1.0 - fill_factor), hi = 0.5 * r * (1.0 + fill_factor);
  std::vector<double> w(r);
  for (int a = 0; a < r; ++a) w[a] = std::max(0.0, std::min<double>(a + 1, hi) - std::max<double>(a, lo));
  return w;
}

OperatorPtr PixelResponse(Shape hr, int r, double fill_factor) {
  CheckArgument(fill_factor > 0 && fill_factor <= 1, "PixelResponse", "fill_factor", fill_factor, "(0, 1]");
  if (fill_factor == 1.0) return Decimate(hr, r);  // the forward model's own box
  CheckArgument(r >= 1, "PixelResponse", "r", r, ">= 1");
  CheckArgument(hr.rows > 0 && hr.cols > 0 && hr.rows % r == 0 && hr.cols % r == 0, "PixelResponse", "hr",
                ToString(hr), "positive multiples of r = " + std::to_string(r));
  return std::make_shared<FillFactorOp>(hr, r, fill_factor, FillFactorWeights(r, fill_factor));
}

double PeakFractionSigma(const ImageStack& frames, double fraction) {
  CheckArgument(FiniteNonNegative(fraction), "PeakFractionSigma", "fraction", fraction, "finite and >= 0");
  CheckArgument(!frames.empty(), "PeakFractionSigma", "frames", "empty", "at least one frame");
  double peak = 0;
  for (const Image& f : frames)
    if (f.size() > 0) peak = std::max(peak, f.maxCoeff());
  return fraction * peak;
}

std::int64_t AddNormalNoise(Image* image, double sigma, NormalGenerator* rng) {
  CheckArgument(FiniteNonNegative(sigma), "AddNormalNoise", "sigma", sigma, "finite and >= 0");
  CheckArgument(image != nullptr && rng != nullptr, "AddNormalNoise", "image/rng", "null", "non-null");
  if (sigma == 0) return 0;
  double* p = image->data();
  for (Index i = 0; i < image->size(); ++i) p[i] += sigma * rng->Next();
  return image->size();
}

Image RandomBadPixelMask(Shape s, double fraction, std::uint64_t seed) {
  CheckArgument(s.rows >= 0 && s.cols >= 0, "RandomBadPixelMask", "s", ToString(s), "non-negative sides");
  CheckArgument(fraction >= 0 && fraction <= 1, "RandomBadPixelMask", "fraction", fraction, "[0, 1]");
  PoissonGenerator rng(seed);  // only its uniform stream
  Image mask(s.rows, s.cols);
  for (Index i = 0; i < mask.size(); ++i) mask.data()[i] = rng.Uniform() < fraction ? 0.0 : 1.0;
  return mask;
}

// ---------------------------------------------------------------------------------------------------------
// Detector

Detector::Detector(DetectorOptions options) : options_(std::move(options)) {
  std::string why;
  if (!options_.IsValid(&why)) throw InvalidArgument("Detector: " + why);
}

std::vector<std::string> Detector::Plan() const {
  const DetectorOptions& o = options_;
  std::vector<std::string> plan;
  if (o.enable_background && o.background_e_per_s > 0)
    plan.push_back("background " + ToString(o.background_e_per_s) + " e-/px/s x " +
                   ToString(o.exposure_time_s) + " s");
  if (o.enable_dark_current && o.dark_current_e_per_s > 0)
    plan.push_back("dark current " + ToString(o.dark_current_e_per_s) + " e-/px/s x " +
                   ToString(o.exposure_time_s) + " s");
  if (o.noise_model == NoiseModel::kPhysical) {
    if (o.enable_photon_noise) plan.push_back("photon noise (Poisson: inversion below 10 e-, PTRS above)");
    if (o.enable_read_noise && o.read_noise_e > 0)
      plan.push_back("read noise " + ToString(o.read_noise_e) + " e- RMS");
  } else if (o.peak_noise_fraction > 0) {
    plan.push_back("Gaussian noise at " + ToString(100 * o.peak_noise_fraction) + "% of the peak");
  }
  plan.push_back("gain " + ToString(o.gain_e_per_adu) + " e-/ADU, bias " + ToString(o.bias_adu) + " ADU");
  if (o.enable_quantization) plan.push_back("quantisation to whole ADU");
  if (o.enable_saturation) plan.push_back("saturation at " + ToString(o.saturation_adu) + " ADU");
  if (o.enable_bad_pixels)
    plan.push_back("bad pixels: " + ToString(Index((o.bad_pixel_mask == 0).count())) + " read the bias");
  return plan;
}

namespace {

// Per-pixel inverse variance of the recorded ADU at expected electrons λ (detector.hpp, "Weights").
class WeightModel {
 public:
  WeightModel(const DetectorOptions& o, double peak_sigma_e) {
    g2_ = o.gain_e_per_adu * o.gain_e_per_adu;
    quant_ = o.enable_quantization ? 1.0 / 12.0 : 0.0;
    if (o.noise_model == NoiseModel::kPeakFraction) {
      base_e2_ = peak_sigma_e * peak_sigma_e;
    } else {
      photon_ = o.enable_photon_noise ? 1.0 : 0.0;
      base_e2_ = o.enable_read_noise ? o.read_noise_e * o.read_noise_e : 0.0;
    }
    any_noise_ = photon_ > 0 || base_e2_ > 0 || quant_ > 0;
  }
  double operator()(double lambda) const {
    if (!any_noise_) return 1.0;  // uniform weights
    double var_e2 = photon_ * std::max(lambda, 0.0) + base_e2_;
    if (var_e2 == 0 && quant_ == 0) var_e2 = 1.0;  // Poisson-only pixel expecting nothing: one electron²
    return 1.0 / (var_e2 / g2_ + quant_);
  }

 private:
  double g2_ = 1, quant_ = 0, photon_ = 0, base_e2_ = 0;
  bool any_noise_ = false;
};

}  // namespace

void Detector::CheckFrame(const Image& expected_e, const char* function) const {
  CheckArgument(expected_e.size() > 0, function, "expected_e", ToString(ShapeOf(expected_e)),
                "a non-empty image");
  CheckArgument(AllFinite(expected_e), function, "expected_e", "non-finite values", "finite values");
  const double peak = expected_e.maxCoeff(), low = expected_e.minCoeff();
  CheckArgument(low >= -1e-6 * std::max(1.0, peak), function, "expected_e", low,
                "expected electrons >= 0 (down to -1e-6 * max(1, peak) for FFT rounding)");
  if (options_.enable_bad_pixels && ShapeOf(options_.bad_pixel_mask) != ShapeOf(expected_e))
    throw InvalidArgument(function, "bad_pixel_mask", ToString(ShapeOf(options_.bad_pixel_mask)),
                          "the frame's shape " + ToString(ShapeOf(expected_e)));
}

double Detector::OffsetElectrons() const {
  double offset = 0;
  if (options_.enable_background) offset += options_.background_e_per_s * options_.exposure_time_s;
  if (options_.enable_dark_current) offset += options_.dark_current_e_per_s * options_.exposure_time_s;
  return offset;
}

Image Detector::ExpectedElectrons(const Image& expected_e) const {
  CheckFrame(expected_e, "Detector");
  const double offset = OffsetElectrons();
  Image lambda = expected_e.max(0.0);
  if (offset > 0) lambda += offset;
  return lambda;
}

Image Detector::MeanAdu(const Image& expected_e) const {
  return ExpectedElectrons(expected_e) / options_.gain_e_per_adu + options_.bias_adu;
}

Image Detector::VarianceAdu(const Image& expected_e, double peak_sigma_e) const {
  CheckArgument(FiniteNonNegative(peak_sigma_e), "Detector::VarianceAdu", "peak_sigma_e", peak_sigma_e,
                "finite and >= 0");
  const DetectorOptions& o = options_;
  const Image lambda = ExpectedElectrons(expected_e);
  const double g2 = o.gain_e_per_adu * o.gain_e_per_adu;
  const double quant = o.enable_quantization ? 1.0 / 12.0 : 0.0;
  if (o.noise_model == NoiseModel::kPeakFraction)
    return Image::Constant(lambda.rows(), lambda.cols(), peak_sigma_e * peak_sigma_e / g2 + quant);
  const double read2 = o.enable_read_noise ? o.read_noise_e * o.read_noise_e : 0.0;
  const double photon = o.enable_photon_noise ? 1.0 : 0.0;
  return (photon * lambda + read2) / g2 + quant;
}

Image Detector::InverseVarianceFromData(const Image& adu, const Image& valid, double peak_sigma_e) const {
  CheckArgument(ShapeOf(adu) == ShapeOf(valid), "Detector::InverseVarianceFromData", "valid",
                ToString(ShapeOf(valid)), "the frame's shape " + ToString(ShapeOf(adu)));
  CheckArgument(FiniteNonNegative(peak_sigma_e), "Detector::InverseVarianceFromData", "peak_sigma_e",
                peak_sigma_e, "finite and >= 0");
  const WeightModel weight(options_, peak_sigma_e);
  Image w(adu.rows(), adu.cols());
  for (Index i = 0; i < w.size(); ++i)
    w.data()[i] =
        valid.data()[i] == 0 ? 0.0 : weight((adu.data()[i] - options_.bias_adu) * options_.gain_e_per_adu);
  return w;
}

// One pass over the pixels doing every enabled stage (detector.hpp). The flags are loop-invariant branches;
// the random generators exist only when their effect is on.
void Detector::RecordChecked(const Image& expected_e, double peak_sigma_e, std::uint64_t seed,
                             std::uint64_t frame, DetectorFrame* out) const {
  const DetectorOptions& o = options_;
  const Index rows = expected_e.rows(), cols = expected_e.cols(), n = expected_e.size();
  out->adu.resize(rows, cols);
  out->saturated.resize(rows, cols);
  out->valid.resize(rows, cols);
  out->inverse_variance.resize(rows, cols);
  out->noise_sigma_e = o.noise_model == NoiseModel::kPeakFraction ? peak_sigma_e : 0.0;
  out->uniform_draws = out->normal_draws = 0;

  const bool physical = o.noise_model == NoiseModel::kPhysical;
  const bool photon = physical && o.enable_photon_noise;
  const double normal_sigma =
      physical ? (o.enable_read_noise ? o.read_noise_e : 0.0) : peak_sigma_e;  // electrons RMS
  const std::uint64_t frame_seed = DeriveSeed(seed, frame);
  std::optional<PoissonGenerator> poisson;
  std::optional<NormalGenerator> normal;
  if (photon) poisson.emplace(DeriveSeed(frame_seed, 0));
  if (normal_sigma > 0) normal.emplace(DeriveSeed(frame_seed, 1));

  const double offset = OffsetElectrons();
  const double gain = o.gain_e_per_adu, bias = o.bias_adu, saturation = o.saturation_adu;
  const bool clip = o.enable_saturation, quantize = o.enable_quantization, bad = o.enable_bad_pixels;
  const WeightModel weight(o, peak_sigma_e);
  const double* s = expected_e.data();
  const double* mask = bad ? o.bad_pixel_mask.data() : nullptr;
  double *adu = out->adu.data(), *sat = out->saturated.data(), *valid = out->valid.data(),
         *w = out->inverse_variance.data();
  for (Index i = 0; i < n; ++i) {
    const double lambda = std::max(s[i], 0.0) + offset;  // FFT rounding below 0 counts as 0
    double e = photon ? poisson->Next(lambda) : lambda;
    if (normal) e += normal_sigma * normal->Next();
    double a = e / gain + bias;
    if (quantize) a = std::floor(a + 0.5);
    double saturated = 0;
    if (clip && a >= saturation) {
      a = saturation;
      saturated = 1;
    }
    double ok = 1 - saturated;
    if (bad && mask[i] == 0) {  // dead: reads the bias; reported as bad, not as clipped
      a = bias;
      ok = 0;
      saturated = 0;
    }
    adu[i] = a;
    sat[i] = saturated;
    valid[i] = ok;
    w[i] = ok == 0 ? 0.0 : weight(lambda);
  }
  if (poisson) out->uniform_draws = poisson->uniform_draws();
  if (normal) out->normal_draws = n;
}

double Detector::PeakSigma(const Image& expected_e) const {
  if (options_.noise_model != NoiseModel::kPeakFraction) return 0.0;
  return options_.peak_noise_fraction * (std::max(expected_e.maxCoeff(), 0.0) + OffsetElectrons());
}

void Detector::Record(const Image& expected_e, std::uint64_t seed, std::uint64_t frame,
                      DetectorFrame* out) const {
  CheckArgument(out != nullptr, "Detector::Record", "out", "null", "a DetectorFrame");
  CheckFrame(expected_e, "Detector::Record");
  RecordChecked(expected_e, PeakSigma(expected_e), seed, frame, out);
}

DetectorFrame Detector::Record(const Image& expected_e, std::uint64_t seed, std::uint64_t frame) const {
  DetectorFrame out;
  Record(expected_e, seed, frame, &out);
  return out;
}

std::vector<DetectorFrame> Detector::RecordSequence(const ImageStack& expected_e, std::uint64_t seed) const {
  CheckArgument(!expected_e.empty(), "Detector::RecordSequence", "expected_e", "empty", "at least one frame");
  double sigma = 0;
  for (const Image& f : expected_e) {
    if (ShapeOf(f) != ShapeOf(expected_e.front()))
      throw InvalidArgument("Detector::RecordSequence", "expected_e", ToString(ShapeOf(f)),
                            "every frame of shape " + ToString(ShapeOf(expected_e.front())));
    CheckFrame(f, "Detector::RecordSequence");
    sigma = std::max(sigma, PeakSigma(f));  // the paper's σ: p · max over all frames
  }
  std::vector<DetectorFrame> out(expected_e.size());
  for (std::size_t i = 0; i < expected_e.size(); ++i) RecordChecked(expected_e[i], sigma, seed, i, &out[i]);
  return out;
}

OperatorPtr Detector::PixelResponse(Shape hr, int r) const {
  return aosr::PixelResponse(hr, r, options_.fill_factor);
}

}  // namespace aosr
