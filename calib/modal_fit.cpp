#include "aosr/calib/modal_fit.hpp"

#include <ceres/ceres.h>
#include <Eigen/SVD>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <limits>
#include <numeric>

#include "aosr/core/error.hpp"
#include "aosr/optics/pupil.hpp"
#include "aosr/optics/zernike.hpp"
#include "aosr/solvers/ceres_termination.hpp"

namespace aosr {
namespace {


double Sinc(double x) { return std::abs(x) < 1e-12 ? 1.0 : std::sin(kPi * x) / (kPi * x); }

double Median(std::vector<double> v) {
  if (v.empty()) return 0.0;
  const std::size_t mid = v.size() / 2;
  std::nth_element(v.begin(), v.begin() + mid, v.end());
  return v[mid];
}

}  // namespace

bool CalibrationOptics::IsValid(std::string* why) const {
  auto fail = [why](const std::string& m) {
    if (why) *why = m;
    return false;
  };
  if (!(std::isfinite(wavelength_m) && wavelength_m > 0)) return fail("wavelength_m = " + ToString(wavelength_m) + "; allowed: > 0");
  if (!(std::isfinite(pixel_lambda_over_d) && pixel_lambda_over_d > 0))
    return fail("pixel_lambda_over_d = " + ToString(pixel_lambda_over_d) + "; allowed: > 0");
  if (!(std::isfinite(obstruction) && obstruction >= 0 && obstruction < 1))
    return fail("obstruction = " + ToString(obstruction) + "; allowed: in [0, 1)");
  if (pupil_px < 16 || pupil_px > 512) return fail("pupil_px = " + ToString(pupil_px) + "; allowed: in [16, 512]");
  return true;
}

bool ModalFitOptions::IsValid(std::string* why) const {
  auto fail = [why](const std::string& m) {
    if (why) *why = m;
    return false;
  };
  if (static_max_noll != 0 && (static_max_noll < 3 || static_max_noll > 37))
    return fail("static_max_noll = " + ToString(static_max_noll) + "; allowed: 0 or 3..37");
  if (!(std::isfinite(source_sigma_px) && source_sigma_px >= 0))
    return fail("source_sigma_px = " + ToString(source_sigma_px) + "; allowed: >= 0");
  if (!(std::isfinite(huber_threshold) && huber_threshold >= 0))
    return fail("huber_threshold = " + ToString(huber_threshold) + "; allowed: >= 0 (0: least squares)");
  if (reweight_passes < 0 || reweight_passes > 5) return fail("reweight_passes = " + ToString(reweight_passes) + "; allowed: 0..5");
  if (max_iterations < 1) return fail("max_iterations = " + ToString(max_iterations) + "; allowed: >= 1");
  for (auto [name, v] : {std::pair<const char*, double>{"function_tolerance", function_tolerance},
                         {"parameter_tolerance", parameter_tolerance},
                         {"gradient_tolerance", gradient_tolerance}})
    if (!(std::isfinite(v) && v >= 0 && v < 1)) return fail(std::string(name) + " = " + ToString(v) + "; allowed: in [0, 1)");
  if (padding_px < 0 || padding_px > 256) return fail("padding_px = " + ToString(padding_px) + "; allowed: 0..256");
  if (oversampling < 0 || oversampling > 8) return fail("oversampling = " + ToString(oversampling) + "; allowed: 0..8 (0: automatic)");
  return true;
}

// ---------------------------------------------------------------------------------------------------------
// ModalImageModel

ModalImageModel::ModalImageModel(const CalibrationOptics& optics, const Image& mode_shape,
                                 std::vector<int> static_modes, Shape window, int padding_px, int oversampling)
    : optics_(optics), static_modes_(std::move(static_modes)), window_(window) {
  const char* fn = "ModalImageModel";
  std::string why;
  if (!optics.IsValid(&why)) throw InvalidArgument(std::string(fn) + ": invalid optics: " + why);
  const Index n = optics.pupil_px;
  CheckArgument(mode_shape.rows() == n && mode_shape.cols() == n, fn, "mode_shape",
                ToString(ShapeOf(mode_shape)), "the pupil grid " + ToString(Shape{n, n}));
  CheckArgument(AllFinite(mode_shape), fn, "mode_shape", "non-finite values", "finite values");
  for (int k : static_modes_) CheckArgument(k >= 4 && k <= 200, fn, "static mode", k, "Noll index in 4..200 (tip/tilt is the position)");
  CheckArgument(window.rows >= 8 && window.cols >= 8 && window.rows <= 1024 && window.cols <= 1024, fn, "window",
                ToString(window), "both sides in [8, 1024]");
  CheckArgument(padding_px >= 0 && padding_px <= 256, fn, "padding_px", padding_px, "0..256");
  CheckArgument(oversampling >= 0 && oversampling <= 8, fn, "oversampling", oversampling, "0..8 (0: automatic)");
  const double s = optics.pixel_lambda_over_d;
  q_ = oversampling > 0 ? oversampling : std::max(1, int(std::ceil(s / 0.45 - 1e-12)));
  CheckArgument(s / q_ < 0.5, fn, "oversampling", q_,
                "a value with pixel_lambda_over_d / oversampling < 0.5 (the fine grid must sample the PSF above "
                "Nyquist); 0 chooses one");
  fine_ = {(window.rows + 2 * padding_px) * q_, (window.cols + 2 * padding_px) * q_};
  amplitude_ = CircularPupil(n, PupilGeometry{1.0, optics.obstruction}, 1);
  mode_shape_ = mode_shape;
  for (int k : static_modes_) static_shapes_.push_back(Zernike(k, n, optics.obstruction));
  u_x_.resize(n, n);
  u_y_.resize(n, n);
  for (Index i = 0; i < n; ++i)
    for (Index k = 0; k < n; ++k) {
      u_x_(i, k) = 0.5 * NormalisedPupilPosition(k, n);
      u_y_(i, k) = 0.5 * NormalisedPupilPosition(i, n);
    }
  const double s_f = s / q_;
  intensity_scale_ = s_f * s_f * double(n) * double(n) / amplitude_.square().sum();
  MftGeometry g;
  g.input = {n, n};
  g.pupil_span_px = double(n);
  g.output = fine_;
  g.pixel_scale_lod = s_f;
  mft_ = std::make_shared<MatrixFourierTransform>(g);
}

double ModalImageModel::RadiansPerMetre() const { return 2 * kPi / optics_.wavelength_m; }

void ModalImageModel::AxisKernel(Index out, Index fine, double variance_px2, Eigen::MatrixXd* k,
                                 Eigen::MatrixXd* dk) const {
  const double q = q_;
  const double f_c = optics_.pixel_lambda_over_d / q;  // PSF cutoff in cycles per fine sample
  std::vector<double> h(fine), dh(fine);
  for (Index t = 0; t < fine; ++t) {
    const double f = double(t <= fine / 2 ? t : t - fine) / double(fine);
    const double af = std::abs(f);
    double taper = 1.0;
    if (af > f_c) {
      const double c = std::cos(0.5 * kPi * std::min(1.0, (af - f_c) / (0.5 - f_c)));
      taper = c * c;
    }
    const double g2 = 2 * kPi * kPi * q * q * f * f;
    h[t] = Sinc(q * f) * std::exp(-g2 * variance_px2) * taper;
    dh[t] = -g2 * h[t];
  }
  // k(d) = (1/L) Σ_t H(f_t) cos(2π f_t d), d = 0..L−1 (periodic).
  std::vector<double> kv(fine, 0.0), dkv(fine, 0.0);
  for (Index d = 0; d < fine; ++d) {
    double acc = 0, dacc = 0;
    for (Index t = 0; t < fine; ++t) {
      const double c = std::cos(2 * kPi * double((t * d) % fine) / double(fine));
      acc += h[t] * c;
      dacc += dh[t] * c;
    }
    kv[d] = acc / double(fine);
    dkv[d] = dacc / double(fine);
  }
  const Index centre = fine / 2, half = out / 2;
  k->resize(out, fine);
  if (dk) dk->resize(out, fine);
  for (Index p = 0; p < out; ++p) {
    const Index c = centre + (p - half) * q_;
    for (Index j = 0; j < fine; ++j) {
      const Index d = (((c - j) % fine) + fine) % fine;
      (*k)(p, j) = kv[d];
      if (dk) (*dk)(p, j) = dkv[d];
    }
  }
}

Image ModalImageModel::Render(const ModalImageParameters& p) const {
  return RenderWithDerivatives(p, Request{}, nullptr);
}

Image ModalImageModel::RenderWithDerivatives(const ModalImageParameters& p, const Request& req, Derivatives* d) const {
  const char* fn = "ModalImageModel::Render";
  CheckArgument(p.static_m.size() == static_shapes_.size() || p.static_m.empty(), fn, "static_m size",
                p.static_m.size(), "the model's static mode count " + ToString(static_shapes_.size()) + " (or 0)");
  CheckArgument(std::isfinite(p.source_sigma_px) && p.source_sigma_px >= 0, fn, "source_sigma_px", p.source_sigma_px, ">= 0");
  CheckArgument(std::isfinite(p.amplitude_m) && std::isfinite(p.dx_px) && std::isfinite(p.dy_px) &&
                    std::isfinite(p.flux) && std::isfinite(p.background),
                fn, "parameters", "non-finite", "finite values");
  const double rpm = RadiansPerMetre();
  const double s = optics_.pixel_lambda_over_d;
  Image phase = (rpm * p.amplitude_m) * mode_shape_ + (2 * kPi * s) * (p.dx_px * u_x_ + p.dy_px * u_y_);
  for (std::size_t k = 0; k < p.static_m.size(); ++k) phase += (rpm * p.static_m[k]) * static_shapes_[k];
  const Index n = optics_.pupil_px;
  ComplexImage field(n, n);
  for (Index i = 0; i < field.size(); ++i)
    field.data()[i] = amplitude_.data()[i] * Complex(std::cos(phase.data()[i]), std::sin(phase.data()[i]));
  const ComplexImage e_hat = mft_->Apply(field);
  const Image intensity = intensity_scale_ * e_hat.abs2();
  const double v = p.source_sigma_px * p.source_sigma_px;
  Eigen::MatrixXd ky, kx, dky, dkx;
  AxisKernel(window_.rows, fine_.rows, v, &ky, req.variance ? &dky : nullptr);
  AxisKernel(window_.cols, fine_.cols, v, &kx, req.variance ? &dkx : nullptr);
  const double q2 = double(q_) * double(q_);
  auto blur = [&](const Image& img) -> Image {
    Image out = (ky * img.matrix() * kx.transpose()).array();
    return out;
  };
  const Image unit = q2 * blur(intensity);  // image of unit flux
  const Image model = p.flux * unit + p.background;
  if (!d) return model;
  // ∂I/∂θ for a phase derivative image P: 2 scale Re(conj(Ê) MFT(i E P)).
  auto d_phase = [&](const Image& pd) -> Image {
    ComplexImage f2(n, n);
    for (Index i = 0; i < f2.size(); ++i) f2.data()[i] = Complex(0, 1) * field.data()[i] * pd.data()[i];
    const ComplexImage de = mft_->Apply(f2);
    const Image di = (2 * intensity_scale_) * (e_hat.conjugate() * de).real();
    return Image(p.flux * q2 * blur(di));
  };
  *d = Derivatives{};
  if (req.amplitude) d->d_amplitude_rad = d_phase(mode_shape_);
  if (req.position) {
    d->d_dx = d_phase(Image((2 * kPi * s) * u_x_));
    d->d_dy = d_phase(Image((2 * kPi * s) * u_y_));
  }
  if (req.static_terms)
    for (const Image& z : static_shapes_) d->d_static_rad.push_back(d_phase(z));
  if (req.variance)
    d->d_variance = (p.flux * q2) * (dky * intensity.matrix() * kx.transpose() + ky * intensity.matrix() * dkx.transpose()).array();
  if (req.flux) d->d_flux = unit;
  return model;
}

// ---------------------------------------------------------------------------------------------------------
// The fit

namespace {

// Parameter block layout of one image's residual block.
struct Layout {
  bool has_static = false;
  int n_static = 0;
  // indices of the blocks in the parameter list
  int gain = 0, position = 1, statics = -1, variance = -1, photometry = -1;
};

struct ImageData {
  Image y;        // ADU (masked pixels set to 0)
  Image sqrt_w;   // √(1/Var), 0 where masked
  double commanded_rad = 0;  // a_i in radians of RMS phase
  double f0 = 1;             // flux unit
  double b_unit = 1;         // background unit
};

class ImageCost : public ceres::CostFunction {
 public:
  ImageCost(const ModalImageModel* model, const ImageData* data, Layout layout, double huber)
      : model_(model), data_(data), layout_(layout), huber_(huber) {
    set_num_residuals(int(data->y.size()));
    auto* sizes = mutable_parameter_block_sizes();
    sizes->push_back(1);
    sizes->push_back(2);
    if (layout.has_static) sizes->push_back(layout.n_static);
    sizes->push_back(1);
    sizes->push_back(2);
  }

  bool Evaluate(double const* const* x, double* residuals, double** jacobians) const override {
    const double rpm = model_->RadiansPerMetre();
    ModalImageParameters p;
    p.amplitude_m = x[layout_.gain][0] * data_->commanded_rad / rpm;
    p.dy_px = x[layout_.position][0];
    p.dx_px = x[layout_.position][1];
    if (layout_.has_static)
      for (int k = 0; k < layout_.n_static; ++k) p.static_m.push_back(x[layout_.statics][k] / rpm);
    const double v = std::max(0.0, x[layout_.variance][0]);
    p.source_sigma_px = std::sqrt(v);
    p.flux = data_->f0 * x[layout_.photometry][0];
    p.background = data_->b_unit * x[layout_.photometry][1];
    for (double val : {p.amplitude_m, p.dy_px, p.dx_px, v, p.flux, p.background})
      if (!std::isfinite(val)) return false;
    for (double c : p.static_m)
      if (!std::isfinite(c)) return false;
    ModalImageModel::Request req;
    const bool want = jacobians != nullptr;
    if (want) {
      req.amplitude = jacobians[layout_.gain] != nullptr && data_->commanded_rad != 0.0;
      req.position = jacobians[layout_.position] != nullptr;
      req.static_terms = layout_.has_static && jacobians[layout_.statics] != nullptr;
      req.variance = jacobians[layout_.variance] != nullptr;
      req.flux = jacobians[layout_.photometry] != nullptr;
    }
    ModalImageModel::Derivatives d;
    Image m;
    try {
      m = model_->RenderWithDerivatives(p, req, want ? &d : nullptr);
    } catch (const Error&) {
      return false;
    }
    const Index np = m.size();
    std::vector<double> chain(np);
    for (Index i = 0; i < np; ++i) {
      const double sw = data_->sqrt_w.data()[i];
      const double r = sw * (m.data()[i] - data_->y.data()[i]);
      if (!std::isfinite(r)) return false;
      double rt = r, dr = 1.0;
      if (huber_ > 0 && std::abs(r) > huber_) {
        const double t = std::sqrt(2 * huber_ * std::abs(r) - huber_ * huber_);
        rt = r > 0 ? t : -t;
        dr = huber_ / t;
      }
      residuals[i] = rt;
      chain[i] = dr * sw;
    }
    if (!want) return true;
    auto fill = [&](double* jac, int cols, int col, const Image* dm, double factor) {
      if (!jac) return;
      for (Index i = 0; i < np; ++i) jac[i * cols + col] = dm ? chain[i] * factor * dm->data()[i] : chain[i] * factor;
    };
    if (jacobians[layout_.gain]) {
      if (data_->commanded_rad != 0.0) fill(jacobians[layout_.gain], 1, 0, &d.d_amplitude_rad, data_->commanded_rad);
      else std::fill(jacobians[layout_.gain], jacobians[layout_.gain] + np, 0.0);
    }
    if (jacobians[layout_.position]) {
      fill(jacobians[layout_.position], 2, 0, &d.d_dy, 1.0);
      fill(jacobians[layout_.position], 2, 1, &d.d_dx, 1.0);
    }
    if (layout_.has_static && jacobians[layout_.statics])
      for (int k = 0; k < layout_.n_static; ++k) fill(jacobians[layout_.statics], layout_.n_static, k, &d.d_static_rad[k], 1.0);
    if (jacobians[layout_.variance]) fill(jacobians[layout_.variance], 1, 0, &d.d_variance, 1.0);
    if (jacobians[layout_.photometry]) {
      fill(jacobians[layout_.photometry], 2, 0, &d.d_flux, data_->f0);
      fill(jacobians[layout_.photometry], 2, 1, nullptr, data_->b_unit);
    }
    return true;
  }

 private:
  const ModalImageModel* model_;
  const ImageData* data_;
  Layout layout_;
  double huber_;
};

Image VarianceFrom(const Image& signal, const NoiseModelParameters& noise) {
  const double g = noise.gain_e_per_adu, rn = noise.read_noise_e / g;
  return (signal.max(0.0) / g + rn * rn).max(1.0 / (g * g));
}

}  // namespace

ModalFitResult FitModalImages(const CalibrationOptics& optics, const Image& mode_shape,
                              const std::vector<ModalFitImage>& images, const NoiseModelParameters& noise,
                              const ModalFitOptions& options, const ModalFitStart& start) {
  const auto t0 = std::chrono::steady_clock::now();
  const char* fn = "FitModalImages";
  std::string why;
  if (!options.IsValid(&why)) throw InvalidArgument(std::string(fn) + ": invalid options: " + why);
  if (!optics.IsValid(&why)) throw InvalidArgument(std::string(fn) + ": invalid optics: " + why);
  CheckArgument(!images.empty(), fn, "images", "none", "at least one image");
  CheckArgument(std::isfinite(noise.gain_e_per_adu) && noise.gain_e_per_adu > 0, fn, "noise.gain_e_per_adu",
                noise.gain_e_per_adu, "> 0");
  CheckArgument(std::isfinite(noise.read_noise_e) && noise.read_noise_e >= 0, fn, "noise.read_noise_e", noise.read_noise_e, ">= 0");
  CheckArgument(std::isfinite(start.gain) && start.gain != 0, fn, "start.gain", start.gain, "finite and non-zero");
  const Shape window = images[0].adu ? ShapeOf(*images[0].adu) : Shape{};
  bool any_poke = false;
  for (std::size_t i = 0; i < images.size(); ++i) {
    const ModalFitImage& im = images[i];
    const std::string which = "images[" + std::to_string(i) + "]";
    CheckArgument(im.adu != nullptr, fn, which, "null", "an image");
    CheckArgument(ShapeOf(*im.adu) == window, fn, which + " shape", ToString(ShapeOf(*im.adu)),
                  "the first image's shape " + ToString(window) + " (all images of a fit share one window)");
    CheckArgument(!im.valid || ShapeOf(*im.valid) == window, fn, which + " valid mask shape",
                  im.valid ? ToString(ShapeOf(*im.valid)) : "", "the image's shape " + ToString(window));
    CheckArgument(std::isfinite(im.commanded_m), fn, which + " commanded amplitude", im.commanded_m, "finite");
    Index bad = 0, used = 0;
    for (Index p = 0; p < window.size(); ++p) {
      if (im.valid && im.valid->data()[p] == 0.0) continue;
      ++used;
      if (!std::isfinite(im.adu->data()[p])) ++bad;
    }
    CheckArgument(bad == 0, fn, which, std::to_string(bad) + " non-finite unmasked pixels",
                  "finite values where valid (mask NaN pixels with the valid map)");
    CheckArgument(used >= 16, fn, which, std::to_string(used) + " valid pixels", "at least 16 valid pixels");
    any_poke = any_poke || im.commanded_m != 0.0;
  }
  CheckArgument(any_poke, fn, "images", "every commanded amplitude is 0",
                "at least one image with a non-zero commanded amplitude (the gain is undetermined otherwise)");

  std::vector<int> static_modes;
  if (options.static_max_noll >= 4)
    for (int k = 4; k <= options.static_max_noll; ++k) static_modes.push_back(k);
  CheckArgument(start.static_m.empty() || start.static_m.size() == static_modes.size(), fn, "start.static_m size",
                start.static_m.size(), "0 or " + ToString(static_modes.size()));
  const ModalImageModel model(optics, mode_shape, static_modes, window, options.padding_px, options.oversampling);
  const double rpm = model.RadiansPerMetre();
  const int n_img = int(images.size());

  // Data, start values.
  std::vector<ImageData> data(n_img);
  std::vector<double> b0(n_img), f0(n_img);
  for (int i = 0; i < n_img; ++i) {
    const Image& y = *images[i].adu;
    std::vector<double> border;
    for (Index r = 0; r < window.rows; ++r)
      for (Index c = 0; c < window.cols; ++c) {
        if (images[i].valid && (*images[i].valid)(r, c) == 0.0) continue;
        if (r < 2 || c < 2 || r >= window.rows - 2 || c >= window.cols - 2) border.push_back(y(r, c));
      }
    b0[i] = Median(border);
    double sum = 0;
    for (Index p = 0; p < window.size(); ++p)
      if (!images[i].valid || images[i].valid->data()[p] != 0.0) sum += y.data()[p] - b0[i];
    CheckArgument(sum > 0, fn, "images[" + std::to_string(i) + "]", "no signal above the background (sum " + ToString(sum) + ")",
                  "an image of the source");
    f0[i] = sum;
    data[i].y = y;
    data[i].commanded_rad = images[i].commanded_m * rpm;
    data[i].f0 = sum;
    data[i].b_unit = std::sqrt(VarianceFrom(Image::Constant(1, 1, b0[i]), noise)(0, 0));
    for (Index p = 0; p < window.size(); ++p)
      if (images[i].valid && images[i].valid->data()[p] == 0.0) data[i].y.data()[p] = 0.0;
  }
  double dy0 = start.dy_px, dx0 = start.dx_px;
  if (!start.position_given) {
    // Centroid of the frame with the smallest |amplitude| (a reference when there is one), over its bright core.
    int best = 0;
    for (int i = 1; i < n_img; ++i)
      if (std::abs(images[i].commanded_m) < std::abs(images[best].commanded_m)) best = i;
    const Image& y = data[best].y;
    const Image sig = (y - b0[best]).max(0.0);
    double peak = 0;
    for (Index p = 0; p < sig.size(); ++p)
      if (!images[best].valid || images[best].valid->data()[p] != 0.0) peak = std::max(peak, sig.data()[p]);
    double sw = 0, sy = 0, sx = 0;
    for (Index r = 0; r < window.rows; ++r)
      for (Index c = 0; c < window.cols; ++c) {
        if (images[best].valid && (*images[best].valid)(r, c) == 0.0) continue;
        const double w = sig(r, c) >= 0.2 * peak ? sig(r, c) : 0.0;
        sw += w, sy += w * r, sx += w * c;
      }
    if (sw > 0) dy0 = sy / sw - double(window.rows / 2), dx0 = sx / sw - double(window.cols / 2);
  }

  // Parameters.
  double gain = start.gain;
  double position[2] = {dy0, dx0};
  std::vector<double> statics(static_modes.size(), 0.0);
  for (std::size_t k = 0; k < start.static_m.size(); ++k) statics[k] = start.static_m[k] * rpm;
  const double sigma0 = start.source_sigma_px >= 0 ? start.source_sigma_px : options.source_sigma_px;
  double variance = sigma0 * sigma0;
  std::vector<std::array<double, 2>> photometry(n_img);
  for (int i = 0; i < n_img; ++i) photometry[i] = {1.0, b0[i] / data[i].b_unit};
  Layout layout;
  layout.has_static = !static_modes.empty();
  layout.n_static = int(static_modes.size());
  int next = 2;
  if (layout.has_static) layout.statics = next++;
  layout.variance = next++;
  layout.photometry = next++;
  const bool fix_size = start.fix_source_size || !options.fit_source_size;

  ModalFitResult result;
  result.method = "modal-fit";
  result.static_modes = static_modes;
  std::vector<Image> models(n_img);
  auto render_all = [&]() {
    for (int i = 0; i < n_img; ++i) {
      ModalImageParameters p;
      p.amplitude_m = gain * images[i].commanded_m;
      p.dy_px = position[0], p.dx_px = position[1];
      for (double c : statics) p.static_m.push_back(c / rpm);
      p.source_sigma_px = std::sqrt(std::max(0.0, variance));
      p.flux = data[i].f0 * photometry[i][0];
      p.background = data[i].b_unit * photometry[i][1];
      models[i] = model.Render(p);
    }
  };

  std::unique_ptr<ceres::Problem> problem;
  ceres::Solver::Summary summary;
  int iterations = 0;
  for (int pass = 0; pass <= options.reweight_passes; ++pass) {
    for (int i = 0; i < n_img; ++i) {
      const Image var = VarianceFrom(pass == 0 ? data[i].y : models[i], noise);
      data[i].sqrt_w = var.rsqrt();
      if (images[i].valid)
        for (Index p = 0; p < window.size(); ++p)
          if (images[i].valid->data()[p] == 0.0) data[i].sqrt_w.data()[p] = 0.0;
    }
    ceres::Problem::Options po;
    problem = std::make_unique<ceres::Problem>(po);
    for (int i = 0; i < n_img; ++i) {
      std::vector<double*> blocks = {&gain, position};
      if (layout.has_static) blocks.push_back(statics.data());
      blocks.push_back(&variance);
      blocks.push_back(photometry[i].data());
      problem->AddResidualBlock(new ImageCost(&model, &data[i], layout, options.huber_threshold), nullptr, blocks);
    }
    problem->SetParameterLowerBound(&variance, 0, 0.0);
    if (start.fix_position) problem->SetParameterBlockConstant(position);
    if (layout.has_static && start.fix_static) problem->SetParameterBlockConstant(statics.data());
    if (fix_size) problem->SetParameterBlockConstant(&variance);
    ceres::Solver::Options so;
    so.linear_solver_type = ceres::DENSE_QR;
    so.max_num_iterations = options.max_iterations;
    so.function_tolerance = options.function_tolerance;
    so.parameter_tolerance = options.parameter_tolerance;
    so.gradient_tolerance = options.gradient_tolerance;
    so.num_threads = 1;
    so.logging_type = ceres::SILENT;
    so.minimizer_progress_to_stdout = false;
    ceres::Solve(so, problem.get(), &summary);
    iterations += int(summary.iterations.size()) - 1;
    render_all();
  }

  // Outcome, residuals and χ².
  result.iterations = iterations;
  result.termination = TerminationOf(summary.termination_type);
  result.message = summary.BriefReport();
  result.final_cost = summary.final_cost;
  bool finite = std::isfinite(gain) && std::isfinite(position[0]) && std::isfinite(position[1]) && std::isfinite(variance);
  for (double c : statics) finite = finite && std::isfinite(c);
  for (const Image& m : models) finite = finite && AllFinite(m);
  if (!finite) {
    result.termination = Termination::kFailed;
    result.message += "; non-finite parameters or model at the end of the solve";
  }
  Index n_valid = 0;
  double chi2 = 0;
  result.frame_residual_rms.assign(n_img, 0.0);
  for (int i = 0; i < n_img; ++i) {
    double acc = 0;
    Index cnt = 0;
    for (Index p = 0; p < window.size(); ++p) {
      const double sw = data[i].sqrt_w.data()[p];
      if (sw == 0.0) continue;
      const double r = sw * (models[i].data()[p] - data[i].y.data()[p]);
      acc += r * r;
      ++cnt;
    }
    chi2 += acc;
    n_valid += cnt;
    result.frame_residual_rms[i] = cnt ? std::sqrt(acc / double(cnt)) : 0.0;
  }
  int n_free = 2 * n_img + 1;
  if (!start.fix_position) n_free += 2;
  if (layout.has_static && !start.fix_static) n_free += layout.n_static;
  if (!fix_size) n_free += 1;
  result.chi2 = chi2;
  result.dof = std::max<Index>(1, n_valid - n_free);
  result.reduced_chi2 = chi2 / double(result.dof);
  result.covariance_scale = options.scale_covariance_by_chi2 ? std::max(1.0, result.reduced_chi2) : 1.0;

  result.gain = gain;
  result.dy_px = position[0], result.dx_px = position[1];
  for (double c : statics) result.static_m.push_back(c / rpm);
  result.static_sigma_m.assign(statics.size(), 0.0);
  result.source_sigma_px = std::sqrt(std::max(0.0, variance));
  for (int i = 0; i < n_img; ++i) {
    result.flux.push_back(data[i].f0 * photometry[i][0]);
    result.background.push_back(data[i].b_unit * photometry[i][1]);
  }
  result.model = models;

  // Covariance (the whole Jacobian, then the blocks we report): the pseudo-inverse of JᵀJ over every free
  // parameter, V diag(1/σ²) Vᵀ from the SVD J = U diag(σ) Vᵀ, refused as rank deficient when σ_min/σ_max <
  // 1e-7 (ceres::Covariance's DENSE_SVD rule with its default min_reciprocal_condition_number 1e-14). Computed
  // here rather than by ceres::Covariance, whose result varied in its last bits with the arrays' addresses
  // (run to run under ASLR; identical with ASLR off), so calibration.json was not the same bytes on repeat.
  if (result.termination != Termination::kFailed) {
    std::vector<double*> blocks = {&gain};
    int col_position = -1, col_static = -1, col_variance = -1;
    int cols = 1;
    if (!start.fix_position) col_position = cols, cols += 2, blocks.push_back(position);
    if (layout.has_static && !start.fix_static)
      col_static = cols, cols += layout.n_static, blocks.push_back(statics.data());
    if (!fix_size) col_variance = cols, cols += 1, blocks.push_back(&variance);
    for (int i = 0; i < n_img; ++i) cols += 2, blocks.push_back(photometry[i].data());
    ceres::Problem::EvaluateOptions eo;
    eo.parameter_blocks = blocks;
    eo.num_threads = 1;
    ceres::CRSMatrix crs;
    bool ok = problem->Evaluate(eo, nullptr, nullptr, nullptr, &crs) && crs.num_cols == cols;
    Eigen::MatrixXd cov;
    if (ok) {
      Eigen::MatrixXd jac = Eigen::MatrixXd::Zero(crs.num_rows, crs.num_cols);
      for (int row = 0; row < crs.num_rows; ++row)
        for (int k = crs.rows[row]; k < crs.rows[row + 1]; ++k) jac(row, crs.cols[k]) = crs.values[k];
      ok = jac.allFinite();
      if (ok) {
        const Eigen::JacobiSVD<Eigen::MatrixXd> svd(jac, Eigen::ComputeThinV);
        const Eigen::VectorXd& sv = svd.singularValues();
        ok = sv.size() == cols && sv(0) > 0 && sv(cols - 1) / sv(0) >= 1e-7;
        if (ok) cov = svd.matrixV() * sv.array().square().inverse().matrix().asDiagonal() * svd.matrixV().transpose();
      }
    }
    if (ok) {
      const double sc = result.covariance_scale;
      result.gain_sigma = std::sqrt(std::max(0.0, cov(0, 0) * sc));
      if (col_position >= 0) {
        result.dy_sigma_px = std::sqrt(std::max(0.0, cov(col_position, col_position) * sc));
        result.dx_sigma_px = std::sqrt(std::max(0.0, cov(col_position + 1, col_position + 1) * sc));
      }
      if (col_static >= 0)
        for (int k = 0; k < layout.n_static; ++k)
          result.static_sigma_m[k] = std::sqrt(std::max(0.0, cov(col_static + k, col_static + k) * sc)) / rpm;
      if (col_variance >= 0) {
        // σ = √v: dσ = dv / (2σ); at σ → 0 report √(std(v)) instead of an infinite slope.
        const double sv = std::sqrt(std::max(0.0, cov(col_variance, col_variance) * sc));
        result.source_sigma_sigma_px =
            result.source_sigma_px > 0 ? std::min(sv / (2 * result.source_sigma_px), std::sqrt(sv)) : std::sqrt(sv);
      }
    } else {
      result.termination = Termination::kFailed;
      result.message += "; covariance failed (the Jacobian is rank deficient: a parameter is not constrained by "
                        "these images)";
    }
  }
  result.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return result;
}

}  // namespace aosr
