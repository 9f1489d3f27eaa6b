#include "aosr/ao/shack_hartmann.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>
#include <utility>

#include "aosr/core/error.hpp"
#include "aosr/optics/pupil.hpp"
#include "aosr/core/fft.hpp"
#include "fast_trig.hpp"
#include "poisson.hpp"

namespace aosr {
namespace {



// Validates the pupil arguments shared by the operator and the sensor; returns p = n / M.
Index CheckGeometry(const Image& amplitude, double diameter_m, const ShackHartmannOptions& o,
                    const char* fn) {
  std::string why;
  if (!o.IsValid(&why)) throw InvalidArgument(std::string(fn) + ": invalid options." + why);
  CheckPupilAmplitude(amplitude, diameter_m, fn);
  const Index n = amplitude.rows();
  const int m = o.subapertures_across;
  CheckArgument(
      n % m == 0 && n / m >= 2, fn, "options.subapertures_across", m,
      "a divisor of the pupil grid size n = " + std::to_string(n) + " with n / M >= 2 pixels per lenslet");
  return n / m;
}

}  // namespace

bool ShackHartmannOptions::IsValid(std::string* why) const {
  if (subapertures_across < 1 || subapertures_across > 1000) {
    return Fail(why, "subapertures_across = " + ToString(subapertures_across) + "; allowed: 1 .. 1000");
  }
  if (!(valid_threshold > 0.0 && valid_threshold <= 1.0)) {
    return Fail(why, "valid_threshold = " + ToString(valid_threshold) +
                         "; allowed: (0, 1] (fraction of the lenslet's area that is lit)");
  }
  if (mode != ShackHartmannMode::kGeometric && mode != ShackHartmannMode::kDiffractive) {
    return Fail(why, "mode = " + ToString(static_cast<int>(mode)) + "; allowed: kGeometric or kDiffractive");
  }
  if (!(std::isfinite(wavelength_m) && wavelength_m > 0.0)) {
    return Fail(why, "wavelength_m = " + ToString(wavelength_m) + "; allowed: > 0 and finite [m]");
  }
  if (!(pixel_scale_lod > 0.0 && pixel_scale_lod <= 1.0)) {
    return Fail(why, "pixel_scale_lod = " + ToString(pixel_scale_lod) + "; allowed: (0, 1] [lambda_wfs / d]");
  }
  if (field_of_view_px != 0 && (field_of_view_px < 2 || field_of_view_px > 4096)) {
    return Fail(why, "field_of_view_px = " + ToString(field_of_view_px) +
                         "; allowed: 0 (one full period) or 2 .. 4096 [pixels]");
  }
  if (spot_transform != SpotTransform::kAuto && spot_transform != SpotTransform::kFft &&
      spot_transform != SpotTransform::kMft) {
    return Fail(why, "spot_transform = " + ToString(static_cast<int>(spot_transform)) +
                         "; allowed: kAuto, kFft or kMft");
  }
  if (!(threshold_fraction >= 0.0 && threshold_fraction < 1.0)) {
    return Fail(why, "threshold_fraction = " + ToString(threshold_fraction) +
                         "; allowed: [0, 1) (fraction of the spot maximum)");
  }
  const ShackHartmannNoise& n = noise;
  if (!std::isfinite(n.guide_star_magnitude)) {
    return Fail(why,
                "noise.guide_star_magnitude = " + ToString(n.guide_star_magnitude) + "; allowed: finite");
  }
  if (!(std::isfinite(n.zero_point_photons_per_s_m2) && n.zero_point_photons_per_s_m2 > 0.0)) {
    return Fail(why, "noise.zero_point_photons_per_s_m2 = " + ToString(n.zero_point_photons_per_s_m2) +
                         "; allowed: > 0 and finite [photons s^-1 m^-2]");
  }
  if (!(n.throughput > 0.0 && n.throughput <= 1.0)) {
    return Fail(why, "noise.throughput = " + ToString(n.throughput) + "; allowed: (0, 1]");
  }
  if (!(std::isfinite(n.frame_time_s) && n.frame_time_s > 0.0)) {
    return Fail(why, "noise.frame_time_s = " + ToString(n.frame_time_s) + "; allowed: > 0 and finite [s]");
  }
  if (!(std::isfinite(n.read_noise_e) && n.read_noise_e >= 0.0)) {
    return Fail(why, "noise.read_noise_e = " + ToString(n.read_noise_e) + "; allowed: >= 0 and finite [e-]");
  }
  if (!(std::isfinite(n.geometric_noise_rad) && n.geometric_noise_rad >= 0.0)) {
    return Fail(why, "noise.geometric_noise_rad = " + ToString(n.geometric_noise_rad) +
                         "; allowed: >= 0 and finite [rad]");
  }
  if (mode == ShackHartmannMode::kGeometric && n.photon_noise) {
    return Fail(why,
                "noise.photon_noise = true; allowed: false in geometric mode (no spots are simulated; "
                "use noise.geometric_noise_rad)");
  }
  if (mode == ShackHartmannMode::kGeometric && n.read_noise_e > 0.0) {
    return Fail(why, "noise.read_noise_e = " + ToString(n.read_noise_e) +
                         "; allowed: 0 in geometric mode (use noise.geometric_noise_rad)");
  }
  if (mode == ShackHartmannMode::kDiffractive && n.geometric_noise_rad > 0.0) {
    return Fail(why, "noise.geometric_noise_rad = " + ToString(n.geometric_noise_rad) +
                         "; allowed: 0 in diffractive mode (use photon_noise and read_noise_e)");
  }
  return true;
}

// ---------------------------------------------------------------------------------------------------------
// GeometricSlopeOperator

namespace {

Index CountValid(const Image& amplitude, double diameter_m, const ShackHartmannOptions& o) {
  const Index p = CheckGeometry(amplitude, diameter_m, o, "GeometricSlopeOperator");
  const int m = o.subapertures_across;
  Index count = 0;
  for (int a = 0; a < m; ++a) {
    for (int b = 0; b < m; ++b) {
      const auto block = amplitude.block(a * p, b * p, p, p);
      const double fraction = block.sum() / static_cast<double>(p * p);
      const double sx = (block.leftCols(p - 1) * block.rightCols(p - 1)).sum();
      const double sy = (block.topRows(p - 1) * block.bottomRows(p - 1)).sum();
      if (fraction >= o.valid_threshold - 1e-12 && sx > 0.0 && sy > 0.0) ++count;
    }
  }
  CheckArgument(count > 0, "GeometricSlopeOperator", "amplitude", "no valid lenslet",
                "at least one lenslet lit to options.valid_threshold = " + ToString(o.valid_threshold));
  return count;
}

}  // namespace

GeometricSlopeOperator::GeometricSlopeOperator(const Image& amplitude, double diameter_m,
                                               const ShackHartmannOptions& options)
    : LinearOperator(2 * CountValid(amplitude, diameter_m, options), amplitude.size(),
                     "GeometricShackHartmann(" + std::to_string(options.subapertures_across) + "x" +
                         std::to_string(options.subapertures_across) + ")") {
  const Index n = amplitude.rows();
  const int m = options.subapertures_across;
  subapertures_across_ = m;
  p_ = n / m;
  const Index p = p_;
  const double dx = diameter_m / static_cast<double>(n);
  valid_mask_ = Image::Zero(m, m);
  illumination_ = Image::Zero(m, m);
  start_.push_back(0);
  Image kx(p, p), ky(p, p);
  for (int a = 0; a < m; ++a) {
    for (int b = 0; b < m; ++b) {
      const auto block = amplitude.block(a * p, b * p, p, p);
      const double fraction = block.sum() / static_cast<double>(p * p);
      illumination_(a, b) = fraction;
      const double sx = (block.leftCols(p - 1) * block.rightCols(p - 1)).sum();
      const double sy = (block.topRows(p - 1) * block.bottomRows(p - 1)).sum();
      if (!(fraction >= options.valid_threshold - 1e-12 && sx > 0.0 && sy > 0.0)) continue;
      valid_mask_(a, b) = 1.0;
      valid_.push_back(static_cast<Index>(a) * m + b);
      // s_x = sum_pairs A A' (w' - w) / dx / sum A A': pixel (i, k+1) gets +c, pixel (i, k) gets -c.
      kx.setZero();
      ky.setZero();
      for (Index i = 0; i < p; ++i) {
        for (Index k = 0; k + 1 < p; ++k) {
          const double cx = block(i, k) * block(i, k + 1) / (sx * dx);
          kx(i, k + 1) += cx;
          kx(i, k) -= cx;
          const double cy = block(k, i) * block(k + 1, i) / (sy * dx);
          ky(k + 1, i) += cy;
          ky(k, i) -= cy;
        }
      }
      for (Index i = 0; i < p; ++i) {
        for (Index k = 0; k < p; ++k) {
          if (kx(i, k) == 0.0 && ky(i, k) == 0.0) continue;
          pixel_.push_back((a * p + i) * n + (b * p + k));
          weight_x_.push_back(kx(i, k));
          weight_y_.push_back(ky(i, k));
        }
      }
      start_.push_back(static_cast<Index>(pixel_.size()));
    }
  }
}

void GeometricSlopeOperator::ApplyImpl(ConstRef x, Ref y) const {
  const Index nv = n_valid();
  for (Index v = 0; v < nv; ++v) {
    double sx = 0.0, sy = 0.0;
    for (Index e = start_[v]; e < start_[v + 1]; ++e) {
      const double w = x[pixel_[e]];
      sx += weight_x_[e] * w;
      sy += weight_y_[e] * w;
    }
    y[v] = sx;
    y[nv + v] = sy;
  }
}

void GeometricSlopeOperator::ApplyAdjointImpl(ConstRef y, Ref x) const {
  x.setZero();
  const Index nv = n_valid();
  for (Index v = 0; v < nv; ++v) {
    const double sx = y[v], sy = y[nv + v];
    for (Index e = start_[v]; e < start_[v + 1]; ++e) x[pixel_[e]] += weight_x_[e] * sx + weight_y_[e] * sy;
  }
}

// ---------------------------------------------------------------------------------------------------------
// ShackHartmann

namespace {

std::shared_ptr<const GeometricSlopeOperator> BuildGeometric(const Image& amplitude, double diameter_m,
                                                             const ShackHartmannOptions& options) {
  CheckGeometry(amplitude, diameter_m, options, "ShackHartmann");
  return std::make_shared<const GeometricSlopeOperator>(amplitude, diameter_m, options);
}

}  // namespace

ShackHartmann::ShackHartmann(const Image& amplitude, double diameter_m, const ShackHartmannOptions& options)
    : ShackHartmann(BuildGeometric(amplitude, diameter_m, options), amplitude, diameter_m, options) {}

ShackHartmann::ShackHartmann(std::shared_ptr<const GeometricSlopeOperator> geometric, const Image& amplitude,
                             double diameter_m, const ShackHartmannOptions& options)
    : WavefrontSensor(amplitude.rows(), geometric->rows()),
      options_(options),
      diameter_m_(diameter_m),
      geometric_(std::move(geometric)),
      poisson_engine_(DeriveSeed(options.noise.seed, 0)),
      normal_(DeriveSeed(options.noise.seed, 1)) {
  const char* fn = "ShackHartmann";
  const Index n = amplitude.rows();
  const Index p = geometric_->pixels_per_subaperture();
  const Index nv = geometric_->n_valid();
  const int msub = options.subapertures_across;
  const double dx = diameter_m / static_cast<double>(n);
  const ShackHartmannNoise& noise = options.noise;
  const double photon_rate = noise.zero_point_photons_per_s_m2 *
                             std::pow(10.0, -0.4 * noise.guide_star_magnitude) * noise.throughput *
                             noise.frame_time_s;  // photo-electrons per m^2 per frame
  photons_.resize(nv);
  std::vector<double> energy(nv);
  for (Index v = 0; v < nv; ++v) {
    const Index a = geometric_->valid_indices()[v] / msub, b = geometric_->valid_indices()[v] % msub;
    energy[v] = amplitude.block(a * p, b * p, p, p).square().sum();
    photons_[v] = photon_rate * energy[v] * dx * dx;
  }

  if (options.mode == ShackHartmannMode::kDiffractive) {
    const double s = options.pixel_scale_lod;
    const double q_real = static_cast<double>(p) / s;
    const double q_round = std::round(q_real);
    const bool q_integer = std::abs(q_real - q_round) <= 1e-9 * q_real;
    m_ = options.field_of_view_px == 0 ? static_cast<Index>(std::floor(q_real + 1e-9))
                                       : static_cast<Index>(options.field_of_view_px);
    CheckArgument(m_ >= 2 && static_cast<double>(m_) * s <= static_cast<double>(p) * (1.0 + 1e-12), fn,
                  "options.field_of_view_px", options.field_of_view_px,
                  "a window of 2 .. p / pixel_scale_lod = " + ToString(q_real) +
                      " pixels (one period of the lenslet's " + std::to_string(p) + "-pixel field)");
    if (options.spot_transform == SpotTransform::kFft) {
      CheckArgument(
          q_integer, fn, "options.pixel_scale_lod", s,
          "with spot_transform = kFft: p / pixel_scale_lod an integer (p = " + std::to_string(p) + ")");
    }
    use_fft_ = options.spot_transform != SpotTransform::kMft && q_integer;
    q_ = use_fft_ ? static_cast<Index>(q_round) : p;
    const Index side = q_;  // field buffer side: q (zero-padded FFT input) or p (MFT input)
    if (!use_fft_) {
      MftGeometry g;
      g.input = {p, p};
      g.pupil_span_px = static_cast<double>(p);
      g.output = {m_, m_};
      g.pixel_scale_lod = s;
      mft_ = std::make_unique<MatrixFourierTransform>(g);
    }
    // The optical axis on the window's centre ((m - 1)/2, (m - 1)/2): a pixel corner for even m (header
    // "Sampling"). Both transforms put it on pixel (m/2, m/2), so the field gets the tilt that moves the spot
    // by delta = (m - 1)/2 - floor(m/2) pixels (-1/2 for even m, 0 for odd): a ramp exp(2 pi i t u) with
    // t = delta s [lambda/d] and u = (j - (p - 1)/2) / p [d] per axis moves the spot by +t (mft.hpp's and
    // the FFT path's sign). Constant phases drop out of |E^|^2.
    const double delta = 0.5 * static_cast<double>(m_ - 1) - static_cast<double>(m_ / 2);
    const double ramp_per_px = kTwoPi * delta * s / static_cast<double>(p);
    fields_.assign(nv, ComplexImage::Zero(side, side));
    lit_start_.push_back(0);
    norm_.resize(nv);
    for (Index v = 0; v < nv; ++v) {
      const Index a = geometric_->valid_indices()[v] / msub, b = geometric_->valid_indices()[v] % msub;
      for (Index i = 0; i < p; ++i) {
        for (Index k = 0; k < p; ++k) {
          const double amp = amplitude(a * p + i, b * p + k);
          if (amp <= 0.0) continue;
          lit_pupil_.push_back((a * p + i) * n + (b * p + k));
          lit_local_.push_back(i * side + k);
          lit_amp_.push_back(amp);
          lit_ramp_.push_back(ramp_per_px * (static_cast<double>(i + k) - static_cast<double>(p - 1)));
        }
      }
      lit_start_.push_back(static_cast<Index>(lit_pupil_.size()));
      // Photons per unit |spectrum|^2: FFT N / (q^2 sum A^2); MFT N s^2 p^2 / sum A^2 (identical, header).
      norm_[v] = use_fft_ ? photons_[v] / (static_cast<double>(q_ * q_) * energy[v])
                          : photons_[v] * s * s * static_cast<double>(p * p) / energy[v];
    }
    window_x_.resize(m_ * m_);
    window_y_.resize(m_ * m_);
    if (use_fft_) window_bin_.resize(m_ * m_);
    for (Index y = 0; y < m_; ++y) {
      for (Index x = 0; x < m_; ++x) {
        const Index t = y * m_ + x;
        window_x_[t] = static_cast<double>(x) - 0.5 * static_cast<double>(m_ - 1);
        window_y_[t] = static_cast<double>(y) - 0.5 * static_cast<double>(m_ - 1);
        if (use_fft_) {
          const Index fy = ((y - m_ / 2) % q_ + q_) % q_, fx = ((x - m_ / 2) % q_ + q_) % q_;
          window_bin_[t] = fy * q_ + fx;
        }
      }
    }
    spots_ = Image::Zero(nv, m_ * m_);
    phase_.assign(lit_pupil_.size(), 0.0);
    cos_.assign(lit_pupil_.size(), 0.0);
    sin_.assign(lit_pupil_.size(), 0.0);
  }
  CalibrateReference();
}

ShackHartmann::~ShackHartmann() = default;

double ShackHartmann::spot_pixel_scale_rad() const {
  return options_.pixel_scale_lod * options_.wavelength_m / subaperture_m();
}

std::string ShackHartmann::Describe() const {
  std::ostringstream os;
  const int m = options_.subapertures_across;
  os << "Shack-Hartmann " << m << "x" << m << " (" << n_valid() << " valid, " << pixels_per_subaperture()
     << " px/lenslet), ";
  if (options_.mode == ShackHartmannMode::kGeometric) {
    os << "geometric";
  } else {
    os << "diffractive at " << options_.wavelength_m * 1e9 << " nm: spots " << m_ << "x" << m_ << " px at "
       << options_.pixel_scale_lod << " lambda/d ("
       << (use_fft_ ? "FFT " + std::to_string(q_) + "x" + std::to_string(q_) : std::string("MFT"))
       << "), CoG threshold " << options_.threshold_fraction;
    if (options_.noise.photon_noise)
      os << ", photon noise (mag " << options_.noise.guide_star_magnitude << ")";
    if (options_.noise.read_noise_e > 0.0) os << ", read noise " << options_.noise.read_noise_e << " e-";
  }
  return os.str();
}

Image ShackHartmann::LastSpot(Index v) const {
  CheckArgument(options_.mode == ShackHartmannMode::kDiffractive, "ShackHartmann::LastSpot", "mode",
                "kGeometric", "kDiffractive (geometric mode forms no spots)");
  CheckArgument(v >= 0 && v < n_valid(), "ShackHartmann::LastSpot", "v", v,
                "0 .. " + std::to_string(n_valid() - 1));
  Image spot(m_, m_);
  for (Index t = 0; t < m_ * m_; ++t) spot.data()[t] = spots_(v, t);
  return spot;
}

void ShackHartmann::MeasureRaw(const Image& opd_m, bool noisy, Eigen::Ref<Vector> raw) {
  if (options_.mode == ShackHartmannMode::kDiffractive) {
    MeasureDiffractive(opd_m, noisy, raw);
    return;
  }
  geometric_->Apply(Eigen::Map<const Vector>(opd_m.data(), opd_m.size()), raw);
  const double sigma = options_.noise.geometric_noise_rad;
  if (noisy && sigma > 0.0) {
    for (Index i = 0; i < raw.size(); ++i) raw[i] += sigma * normal_.Next();
  }
}

void ShackHartmann::MeasureDiffractive(const Image& opd_m, bool noisy, Eigen::Ref<Vector> raw) {
  const Index nv = n_valid();
  const Index m2 = m_ * m_;
  const double wavenumber = kTwoPi / options_.wavelength_m;
  const double pixel_rad = spot_pixel_scale_rad();
  const bool photon = noisy && options_.noise.photon_noise;
  const double read = noisy ? options_.noise.read_noise_e : 0.0;
  const double threshold = options_.threshold_fraction;
  const double* w = opd_m.data();
  // The phases of every lit pixel at once (a vectorised sin/cos), then each lenslet's field.
  const long lit = static_cast<long>(lit_pupil_.size());
  for (long j = 0; j < lit; ++j) phase_[j] = wavenumber * w[lit_pupil_[j]] + lit_ramp_[j];
  internal::SinCosBatch(phase_.data(), lit, cos_.data(), sin_.data());
  for (Index v = 0; v < nv; ++v) {
    Complex* field = fields_[v].data();
    for (Index j = lit_start_[v]; j < lit_start_[v + 1]; ++j) {
      field[lit_local_[j]] = Complex(lit_amp_[j] * cos_[j], lit_amp_[j] * sin_[j]);
    }
    double* spot = &spots_(v, 0);
    const double norm = norm_[v];
    if (use_fft_) {
      FftForwardInto(fields_[v], &spectrum_);
      const Complex* x = spectrum_.data();
      for (Index t = 0; t < m2; ++t) spot[t] = norm * std::norm(x[window_bin_[t]]);
    } else {
      const ComplexImage out = mft_->Apply(fields_[v]);
      const Complex* x = out.data();
      for (Index t = 0; t < m2; ++t) spot[t] = norm * std::norm(x[t]);
    }
    if (photon) {
      for (Index t = 0; t < m2; ++t) spot[t] = internal::PoissonDeviate(poisson_engine_, spot[t]);
    }
    if (read > 0.0) {
      for (Index t = 0; t < m2; ++t) spot[t] += read * normal_.Next();
    }
    double cut = 0.0;
    if (threshold > 0.0) cut = threshold * *std::max_element(spot, spot + m2);
    double sum = 0.0, sx = 0.0, sy = 0.0;
    for (Index t = 0; t < m2; ++t) {
      const double i = spot[t] - cut;
      if (i <= 0.0) continue;
      sum += i;
      sx += i * window_x_[t];
      sy += i * window_y_[t];
    }
    if (!std::isfinite(sum)) {  // a non-finite OPD: let the caller's check report it
      raw[v] = raw[nv + v] = std::numeric_limits<double>::quiet_NaN();
      continue;
    }
    raw[v] = sum > 0.0 ? sx / sum * pixel_rad : 0.0;
    raw[nv + v] = sum > 0.0 ? sy / sum * pixel_rad : 0.0;
  }
}

}  // namespace aosr
