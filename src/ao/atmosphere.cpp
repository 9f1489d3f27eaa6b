#include "aosr/ao/atmosphere.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "aosr/ao/random.hpp"
#include "aosr/ao/von_karman.hpp"
#include "aosr/core/error.hpp"
#include "aosr/core/parallel.hpp"

namespace aosr {
namespace {


// cos/sin with round-off snapped to exact 0 and +-1, so that winds along the axes (theta = k pi/2) move the
// screen by exact whole pixels.
double Snap(double v) {
  if (std::abs(v) < 1e-12) return 0.0;
  if (std::abs(std::abs(v) - 1.0) < 1e-15) return v > 0.0 ? 1.0 : -1.0;
  return v;
}

}  // namespace

// Geometry of one layer in its screen's pixel coordinates (rows rho run against the wind, columns kappa
// across it). Pupil pixel (i, k) at (x, y) = (k - (n-1)/2, i - (n-1)/2) pixels from the pupil centre reads
//     rho   = rho0 + speed_px t - (x cos + y sin)        (absolute row of the infinite strip)
//     kappa = kappa0 - x sin + y cos.
struct Atmosphere::LayerState {
  double r0_m = 0.0;  // at r0_wavelength_m; +inf when inactive
  bool active = false;
  double cos_t = 1.0, sin_t = 0.0;
  double speed_px = 0.0;  // wind speed in pupil pixels per second
  double rho0 = 0.0, kappa0 = 0.0;
  std::unique_ptr<InfinitePhaseScreen> screen;
  std::vector<double> x_cos, x_sin;  // x_k cos, x_k sin for the columns of the pupil grid
  double altitude_m = 0.0;
  double margin_px = 0.0;  // M: extra pixels on every side for field directions (0 on axis only)
};

double FieldDirection::Norm() const { return std::hypot(x_rad, y_rad); }

bool AtmosphereOptions::IsValid(std::string* why) const {
  std::string msg;
  auto finite_positive = [](double v) { return std::isfinite(v) && v > 0.0; };
  if (!finite_positive(r0_m)) {
    msg = "r0_m = " + ToString(r0_m) + "; allowed: > 0 and finite [m]";
  } else if (!finite_positive(r0_wavelength_m)) {
    msg = "r0_wavelength_m = " + ToString(r0_wavelength_m) + "; allowed: > 0 and finite [m]";
  } else if (!finite_positive(L0_m)) {
    msg = "L0_m = " + ToString(L0_m) + "; allowed: > 0 and finite [m]";
  } else if (interpolation != Interpolation::kBilinear && interpolation != Interpolation::kCubic) {
    msg = "interpolation = " + ToString(static_cast<int>(interpolation)) + "; allowed: kBilinear, kCubic";
  } else if (!(std::isfinite(max_field_angle_rad) && max_field_angle_rad >= 0.0 &&
                 max_field_angle_rad <= 0.01)) {
    msg = "max_field_angle_rad = " + ToString(max_field_angle_rad) +
          "; allowed: [0, 0.01] [rad] (0.01 rad = 34 arcmin)";
  } else if (layers.empty()) {
    msg = "layers = (empty); allowed: at least one layer";
  } else {
    double sum = 0.0;
    for (std::size_t i = 0; i < layers.size() && msg.empty(); ++i) {
      const Layer& l = layers[i];
      const std::string name = "layers[" + std::to_string(i) + "].";
      if (!(std::isfinite(l.altitude_m) && l.altitude_m >= 0.0)) {
        msg = name + "altitude_m = " + ToString(l.altitude_m) + "; allowed: >= 0 and finite [m]";
      } else if (!(std::isfinite(l.cn2_fraction) && l.cn2_fraction >= 0.0 && l.cn2_fraction <= 1.0)) {
        msg = name + "cn2_fraction = " + ToString(l.cn2_fraction) + "; allowed: [0, 1]";
      } else if (!(std::isfinite(l.wind_speed_mps) && l.wind_speed_mps >= 0.0)) {
        msg = name + "wind_speed_mps = " + ToString(l.wind_speed_mps) + "; allowed: >= 0 and finite [m/s]";
      } else if (!std::isfinite(l.wind_direction_rad)) {
        msg = name + "wind_direction_rad = " + ToString(l.wind_direction_rad) + "; allowed: finite [rad]";
      }
      sum += l.cn2_fraction;
    }
    if (msg.empty() && !(std::abs(sum - 1.0) <= 1e-6)) {
      msg =
          "layers[*].cn2_fraction (sum) = " + ToString(sum) + "; allowed: fractions summing to 1 within 1e-6";
    }
  }
  if (msg.empty()) return true;
  if (why != nullptr) *why = msg;
  return false;
}

Atmosphere::Atmosphere(const AtmosphereOptions& options, Index pupil_n, double diameter_m)
    : options_(options), pupil_n_(pupil_n), diameter_m_(diameter_m) {
  std::string why;
  if (!options.IsValid(&why)) throw InvalidArgument("Atmosphere: invalid options." + why);
  CheckArgument(pupil_n >= 2 && pupil_n <= 1024, "Atmosphere", "pupil_n", pupil_n, "2 .. 1024 [pixels]");
  CheckArgument(std::isfinite(diameter_m) && diameter_m > 0.0, "Atmosphere", "diameter_m", diameter_m,
                "> 0 and finite [m]");
  const double dx = diameter_m / static_cast<double>(pupil_n);
  CheckArgument(options.L0_m <= 1e6 * dx, "Atmosphere", "options.L0_m", options.L0_m,
                "<= 1e6 pupil pixels (D/n) [m]");
  const double half_n = 0.5 * static_cast<double>(pupil_n - 1);
  for (std::size_t i = 0; i < options.layers.size(); ++i) {
    const Layer& l = options.layers[i];
    auto state = std::make_unique<LayerState>();
    state->active = l.cn2_fraction > 0.0;
    state->r0_m = state->active ? options.r0_m * std::pow(l.cn2_fraction, -0.6)
                                : std::numeric_limits<double>::infinity();
    state->cos_t = Snap(std::cos(l.wind_direction_rad));
    state->sin_t = Snap(std::sin(l.wind_direction_rad));
    state->speed_px = l.wind_speed_mps / dx;
    state->altitude_m = l.altitude_m;
    if (state->active && options.max_field_angle_rad > 0.0 && l.altitude_m > 0.0) {
      // Field directions: the footprint moves by up to h theta_max; one pixel more for rounding.
      state->margin_px = std::ceil(l.altitude_m * options.max_field_angle_rad / dx - 1e-9) + 1.0;
      CheckArgument(state->margin_px <= 1024.0, "Atmosphere", "options.max_field_angle_rad",
                    options.max_field_angle_rad,
                    "a field radius whose layer footprints move by at most 1024 pupil pixels (layer " +
                        std::to_string(i) + " at " + ToString(l.altitude_m) + " m would move by " +
                        ToString(l.altitude_m * options.max_field_angle_rad) + " m = " +
                        ToString(state->margin_px) + " pixels)");
    }
    if (state->active) {
      // Footprint half-extent h along and across the wind. The pupil centre sits at (rho0, kappa0) = (h + 3,
      // h + 3) at t = 0: 3 pixels of margin for the interpolation taps (floor - 1 .. floor + 2), and for a
      // wind along an axis (h = (n-1)/2) pupil pixel centres fall exactly on screen pixel centres, so such a
      // layer is read without interpolation whenever it has moved a whole number of pixels. The strip is
      // ceil(2h) + 6 columns wide; the window keeps 4 more rows than that, so calls may step back in time by
      // a few pixels of travel.
      // Field directions widen the strip and the window by the margin M on every side (0 on axis only: the
      // same screens, hence the same bytes, as without field directions).
      const double h = half_n * (std::abs(state->cos_t) + std::abs(state->sin_t));
      const Index margin = static_cast<Index>(state->margin_px);
      const Index size = static_cast<Index>(std::ceil(2.0 * h - 1e-9)) + 6 + 2 * margin;
      state->kappa0 = h + 3.0 + state->margin_px;
      state->rho0 = h + 3.0 + state->margin_px;
      InfinitePhaseScreenOptions so;
      so.width = size;
      so.length = size + 4;
      so.pixel_scale_m = dx;
      so.r0_m = state->r0_m;
      so.L0_m = options.L0_m;
      state->screen = std::make_unique<InfinitePhaseScreen>(so, DeriveSeed(options.seed, i));
      state->x_cos.resize(pupil_n);
      state->x_sin.resize(pupil_n);
      for (Index k = 0; k < pupil_n; ++k) {
        const double x = static_cast<double>(k) - half_n;
        state->x_cos[k] = x * state->cos_t;
        state->x_sin[k] = x * state->sin_t;
      }
    }
    layers_.push_back(std::move(state));
  }
}

Atmosphere::~Atmosphere() = default;
Atmosphere::Atmosphere(Atmosphere&&) noexcept = default;
Atmosphere& Atmosphere::operator=(Atmosphere&&) noexcept = default;

void Atmosphere::Prepare(LayerState& layer, double t_s, double row_shift_px, const char* function) {
  const double half_n = 0.5 * static_cast<double>(pupil_n_ - 1);
  const double h = half_n * (std::abs(layer.cos_t) + std::abs(layer.sin_t));
  // Absolute row of the footprint's centre (row_shift_px: a field direction's displacement along the rows).
  const double centre = layer.rho0 + layer.speed_px * t_s + row_shift_px;
  InfinitePhaseScreen& screen = *layer.screen;
  const Index length = screen.options().length;
  // Rows needed by the interpolation taps: floor(centre - h) - 1 .. floor(centre + h) + 2. The screen is
  // extruded as far as the widest field direction could need (the margin M ahead of the axis), whichever
  // direction asks: the rows held, and so the rounding of every read (Accumulate's base), are then a function
  // of time alone, and a direction's values do not depend on which directions were read before it (one loop
  // for many directions gives each the bytes of its own loop: closed_loop.hpp). On axis only, M = 0.
  const double ahead = std::floor(layer.rho0 + layer.speed_px * t_s + h + layer.margin_px) + 2.0;
  const double last_needed = std::max(ahead, std::floor(centre + h) + 2.0);
  const double have_last = static_cast<double>(screen.rows_extruded() + length - 1);
  if (last_needed > have_last) screen.Extrude(static_cast<Index>(last_needed - have_last));
  const double first_needed = std::floor(centre - h) - 1.0;
  CheckArgument(first_needed >= static_cast<double>(screen.rows_extruded()), function, "t_s", t_s,
                "a time whose screen rows are still held (the screens only keep a few pixels of wind travel "
                "behind the latest time requested)");
}

void Atmosphere::Accumulate(LayerState& layer, double t_s, double shift_x_px, double shift_y_px,
                            double* out) const {
  const Index n = pupil_n_;
  const double half_n = 0.5 * static_cast<double>(n - 1);
  const InfinitePhaseScreen& screen = *layer.screen;
  const Index w = screen.options().width;
  const double* data = screen.Row(0);
  const double scale = options_.r0_wavelength_m / (2.0 * kPi);  // rad at lambda_ref -> m
  // Window-relative row of the pupil centre; the difference of two large numbers is formed first so that
  // long runs keep full sub-pixel precision.
  // A field direction displaces the footprint by s = (shift_x, shift_y) pixels: reading phi(p + s) moves rho
  // by -(s_x cos + s_y sin) and kappa by -s_x sin + s_y cos (the geometry above). On axis both are 0 and
  // the sums below are the on-axis ones exactly.
  const double base = (layer.rho0 - static_cast<double>(screen.rows_extruded())) + layer.speed_px * t_s -
                      (shift_x_px * layer.cos_t + shift_y_px * layer.sin_t);
  const double kappa_c = layer.kappa0 - shift_x_px * layer.sin_t + shift_y_px * layer.cos_t;
  const double* xc = layer.x_cos.data();
  const double* xs = layer.x_sin.data();
  const bool cubic = options_.interpolation == AtmosphereOptions::Interpolation::kCubic;
  for (Index i = 0; i < n; ++i) {
    const double y = static_cast<double>(i) - half_n;
    const double rho_i = base - y * layer.sin_t;
    const double kappa_i = kappa_c + y * layer.cos_t;
    double* o = out + i * n;
    for (Index k = 0; k < n; ++k) {
      const double r = rho_i - xc[k];
      const double q = kappa_i - xs[k];
      const Index ri = static_cast<Index>(r);  // r, q >= 1 by construction: truncation is floor
      const Index qi = static_cast<Index>(q);
      const double fr = r - static_cast<double>(ri);
      const double fq = q - static_cast<double>(qi);
      const double* p = data + ri * w + qi;
      if (!cubic) {
        const double top = p[0] + fq * (p[1] - p[0]);
        const double bottom = p[w] + fq * (p[w + 1] - p[w]);
        o[k] += scale * (top + fr * (bottom - top));
      } else {
        // Keys (1981) cubic convolution, a = -1/2: weights of taps -1, 0, 1, 2 for fraction f; exactly
        // (0, 1, 0, 0) at f = 0.
        auto weights = [](double f, double* c) {
          const double f2 = f * f, f3 = f2 * f;
          c[0] = 0.5 * (-f3 + 2.0 * f2 - f);
          c[1] = 0.5 * (3.0 * f3 - 5.0 * f2 + 2.0);
          c[2] = 0.5 * (-3.0 * f3 + 4.0 * f2 + f);
          c[3] = 0.5 * (f3 - f2);
        };
        double cr[4], cq[4];
        weights(fr, cr);
        weights(fq, cq);
        double v = 0.0;
        for (int a = 0; a < 4; ++a) {
          const double* row = p + (a - 1) * w - 1;
          v += cr[a] * (cq[0] * row[0] + cq[1] * row[1] + cq[2] * row[2] + cq[3] * row[3]);
        }
        o[k] += scale * v;
      }
    }
  }
}

void Atmosphere::Opd(double t_s, Image* opd) {
  CheckArgument(opd != nullptr, "Atmosphere::Opd", "opd", "null", "an Image to write into");
  CheckArgument(std::isfinite(t_s) && t_s >= 0.0, "Atmosphere::Opd", "t_s", t_s, ">= 0 and finite [s]");
  for (auto& layer : layers_) {
    if (layer->active) Prepare(*layer, t_s, 0.0, "Atmosphere::Opd");
  }
  if (opd->rows() != pupil_n_ || opd->cols() != pupil_n_) opd->resize(pupil_n_, pupil_n_);
  opd->setZero();
  for (auto& layer : layers_) {
    if (layer->active) Accumulate(*layer, t_s, 0.0, 0.0, opd->data());
  }
  if (options_.antithetic) *opd = -*opd;
}

void Atmosphere::CheckFieldDirection(const FieldDirection& direction, const char* function) const {
  CheckArgument(std::isfinite(direction.x_rad) && std::isfinite(direction.y_rad), function, "direction",
                "(" + ToString(direction.x_rad) + ", " + ToString(direction.y_rad) + ") rad",
                "finite (x, y) [rad] from the guide star");
  const double angle = direction.Norm();
  if (angle <= options_.max_field_angle_rad * (1.0 + 1e-12)) return;
  for (std::size_t i = 0; i < layers_.size(); ++i) {
    const LayerState& l = *layers_[i];
    if (!l.active || l.altitude_m == 0.0) continue;  // a ground layer is the same in every direction
    constexpr double kArcsecPerRad = 180.0 * 3600.0 / kPi;
    throw InvalidArgument(
        function, "direction",
        "(" + ToString(direction.x_rad) + ", " + ToString(direction.y_rad) + ") rad, |theta| = " +
            ToString(angle) + " rad = " + ToString(angle * kArcsecPerRad) + " arcsec",
        "|theta| <= max_field_angle_rad = " + ToString(options_.max_field_angle_rad) + " rad = " +
            ToString(options_.max_field_angle_rad * kArcsecPerRad) +
            " arcsec: layer " + std::to_string(i) + " (" + ToString(l.altitude_m) + " m) would be read " +
            ToString(l.altitude_m * angle) + " m off axis, beyond its phase screen (build the atmosphere with "
            "AtmosphereOptions::max_field_angle_rad >= |theta|)");
  }
}

void Atmosphere::Opd(double t_s, const FieldDirection& direction, Image* opd) {
  if (direction.IsZero()) return Opd(t_s, opd);
  CheckArgument(opd != nullptr, "Atmosphere::Opd", "opd", "null", "an Image to write into");
  CheckArgument(std::isfinite(t_s) && t_s >= 0.0, "Atmosphere::Opd", "t_s", t_s, ">= 0 and finite [s]");
  CheckFieldDirection(direction, "Atmosphere::Opd");
  const double dx = diameter_m_ / static_cast<double>(pupil_n_);
  for (auto& layer : layers_) {
    if (!layer->active) continue;
    const double sx = layer->altitude_m * direction.x_rad / dx, sy = layer->altitude_m * direction.y_rad / dx;
    Prepare(*layer, t_s, -(sx * layer->cos_t + sy * layer->sin_t), "Atmosphere::Opd");
  }
  if (opd->rows() != pupil_n_ || opd->cols() != pupil_n_) opd->resize(pupil_n_, pupil_n_);
  opd->setZero();
  for (auto& layer : layers_) {
    if (!layer->active) continue;
    const double sx = layer->altitude_m * direction.x_rad / dx, sy = layer->altitude_m * direction.y_rad / dx;
    Accumulate(*layer, t_s, sx, sy, opd->data());
  }
  if (options_.antithetic) *opd = -*opd;
}

void Atmosphere::Opd(double t_s, const std::vector<FieldDirection>& directions, std::vector<Image>* opds) {
  const char* fn = "Atmosphere::Opd";
  CheckArgument(opds != nullptr, fn, "opds", "null", "a vector to write into");
  CheckArgument(std::isfinite(t_s) && t_s >= 0.0, fn, "t_s", t_s, ">= 0 and finite [s]");
  for (std::size_t k = 0; k < directions.size(); ++k)
    CheckFieldDirection(directions[k], ("Atmosphere::Opd (directions[" + std::to_string(k) + "])").c_str());
  const double dx = diameter_m_ / static_cast<double>(pupil_n_);
  auto shift = [&](const LayerState& layer, const FieldDirection& d, double* sx, double* sy) {
    *sx = d.IsZero() ? 0.0 : layer.altitude_m * d.x_rad / dx;
    *sy = d.IsZero() ? 0.0 : layer.altitude_m * d.y_rad / dx;
  };
  // Advance the screens (serially: Prepare may extrude); then every read is const (Accumulate).
  for (auto& layer : layers_) {
    if (!layer->active) continue;
    for (const FieldDirection& d : directions) {
      double sx, sy;
      shift(*layer, d, &sx, &sy);
      Prepare(*layer, t_s, -(sx * layer->cos_t + sy * layer->sin_t), fn);
    }
  }
  opds->resize(directions.size());
  ParallelFor(static_cast<Index>(directions.size()), [&](Index k) {
    Image& opd = (*opds)[static_cast<std::size_t>(k)];
    if (opd.rows() != pupil_n_ || opd.cols() != pupil_n_) opd.resize(pupil_n_, pupil_n_);
    opd.setZero();
    for (const auto& layer : layers_) {
      if (!layer->active) continue;
      double sx, sy;
      shift(*layer, directions[static_cast<std::size_t>(k)], &sx, &sy);
      Accumulate(*layer, t_s, sx, sy, opd.data());
    }
    if (options_.antithetic) opd = -opd;
  });
}

Image Atmosphere::Opd(double t_s, const FieldDirection& direction) {
  Image opd;
  Opd(t_s, direction, &opd);
  return opd;
}

Image Atmosphere::Opd(double t_s) {
  Image opd;
  Opd(t_s, &opd);
  return opd;
}

Image Atmosphere::LayerOpd(int layer, double t_s) {
  CheckArgument(layer >= 0 && layer < static_cast<int>(layers_.size()), "Atmosphere::LayerOpd", "layer",
                layer, "0 .. " + std::to_string(layers_.size() - 1));
  CheckArgument(std::isfinite(t_s) && t_s >= 0.0, "Atmosphere::LayerOpd", "t_s", t_s, ">= 0 and finite [s]");
  Image opd = Image::Zero(pupil_n_, pupil_n_);
  LayerState& state = *layers_[layer];
  if (state.active) {
    Prepare(state, t_s, 0.0, "Atmosphere::LayerOpd");
    Accumulate(state, t_s, 0.0, 0.0, opd.data());
  }
  if (options_.antithetic) opd = -opd;
  return opd;
}

double Atmosphere::LayerR0(int layer) const {
  CheckArgument(layer >= 0 && layer < static_cast<int>(layers_.size()), "Atmosphere::LayerR0", "layer", layer,
                "0 .. " + std::to_string(layers_.size() - 1));
  return layers_[layer]->r0_m;
}

double Atmosphere::R0At(double wavelength_m) const {
  CheckArgument(std::isfinite(wavelength_m) && wavelength_m > 0.0, "Atmosphere::R0At", "wavelength_m",
                wavelength_m, "> 0 and finite [m]");
  return ScaleR0(options_.r0_m, options_.r0_wavelength_m, wavelength_m);
}

}  // namespace aosr
