#include "aosr/design/design_parameterisation.hpp"

#include <cmath>

#include "aosr/core/error.hpp"
#include "aosr/optics/psf.hpp"
#include "aosr/optics/zernike.hpp"
#include "aosr/scene/raster.hpp"

namespace aosr {
namespace {

// g_ρ(t) = ρ tanh(t/ρ)/t and g'(t)/t, with series below x = t/ρ = 1e-3 (relative error < 1e-12).
double SquashFactor(double t, double rho) {
  const double x = t / rho;
  if (x < 1e-3) return 1.0 - x * x / 3.0 + 2.0 * x * x * x * x / 15.0;
  return std::tanh(x) / x;
}
double SquashSlopeOverT(double t, double rho) {
  const double x = t / rho;
  if (x < 1e-3) return (-2.0 / 3.0 + 8.0 * x * x / 15.0) / (rho * rho);
  const double th = std::tanh(x);
  return ((1.0 - th * th) - th / x) / (t * t);
}

// W-weighted projection of every column of `b` off span(basis columns): b − T (TᵀWT)⁻¹ TᵀW b.
Eigen::MatrixXd RemoveWeighted(const Eigen::MatrixXd& b, const Eigen::MatrixXd& t, const Eigen::VectorXd& w) {
  const Eigen::MatrixXd tw = t.transpose() * w.asDiagonal();
  const Eigen::MatrixXd coef = (tw * t).ldlt().solve(tw * b);
  return b - t * coef;
}

}  // namespace

const char* ToString(DesignParameterisationKind kind) {
  switch (kind) {
    case DesignParameterisationKind::kRaster:
      return "raster";
    case DesignParameterisationKind::kTipTilt:
      return "tiptilt";
    case DesignParameterisationKind::kZernike:
      return "zernike";
    case DesignParameterisationKind::kActuators:
      return "actuators";
  }
  return "unknown";
}

DesignParameterisationKind ParseDesignParameterisation(const std::string& name) {
  if (name == "raster") return DesignParameterisationKind::kRaster;
  if (name == "tiptilt") return DesignParameterisationKind::kTipTilt;
  if (name == "zernike") return DesignParameterisationKind::kZernike;
  if (name == "actuators") return DesignParameterisationKind::kActuators;
  throw InvalidArgument("ParseDesignParameterisation", "name", name, "raster, tiptilt, zernike or actuators");
}

bool DesignParameterisationOptions::IsValid(std::string* why) const {
  auto fail = [why](const std::string& m) {
    if (why) *why = m;
    return false;
  };
  if (zernike_modes < 2 || zernike_modes > 200)
    return fail("zernike_modes = " + std::to_string(zernike_modes) + "; allowed: 2 .. 200");
  if (!(std::isfinite(rms_max_m) && rms_max_m >= 0))
    return fail("rms_max_m = " + ToString(rms_max_m) + "; allowed: 0 (no bound) or > 0 and finite [m]");
  if (!(strehl_min >= 0 && strehl_min < 1))
    return fail("strehl_min = " + ToString(strehl_min) + "; allowed: [0, 1) (0: no bound)");
  return true;
}

DesignPupil DesignPupilFromScene(const SceneSpec& scene) {
  DesignPupil p;
  p.amplitude = scene.telescope.PupilAmplitude();
  p.diameter_m = scene.telescope.aperture.pupil.diameter_m;
  p.obstruction = scene.telescope.aperture.pupil.obstruction;
  p.wavelength_m = scene.telescope.science_wavelength_m;
  p.camera_pixel_rad = scene.CameraPixelRad();
  if (scene.telescope.ao)
    p.dm = std::make_shared<DeformableMirror>(scene.telescope.pupil_px, scene.telescope.aperture.pupil,
                                              scene.telescope.ao->dm);
  return p;
}

DesignParameterisation::DesignParameterisation(const DesignPupil& pupil, int frames, int r,
                                               const DesignParameterisationOptions& options)
    : options_(options), pupil_(pupil), frames_(frames), r_(r) {
  const char* fn = "DesignParameterisation";
  std::string why;
  if (!options.IsValid(&why)) throw InvalidArgument(std::string(fn) + ": options." + why);
  CheckArgument(frames >= 1, fn, "frames", frames, ">= 1");
  CheckArgument(r >= 1, fn, "r", r, ">= 1");
  n_ = pupil.amplitude.rows();
  CheckArgument(n_ >= 8 && pupil.amplitude.cols() == n_, fn, "pupil.amplitude shape", ToString(ShapeOf(pupil.amplitude)),
                "square n x n with n >= 8");
  CheckArgument(AllFinite(pupil.amplitude) && (pupil.amplitude >= 0).all() && pupil.amplitude.sum() > 0, fn,
                "pupil.amplitude", "negative, non-finite or all zero", "finite values >= 0, some > 0");
  CheckArgument(std::isfinite(pupil.diameter_m) && pupil.diameter_m > 0, fn, "pupil.diameter_m", pupil.diameter_m, "> 0");
  CheckArgument(pupil.obstruction >= 0 && pupil.obstruction < 1, fn, "pupil.obstruction", pupil.obstruction, "[0, 1)");
  CheckArgument(std::isfinite(pupil.wavelength_m) && pupil.wavelength_m > 0, fn, "pupil.wavelength_m",
                pupil.wavelength_m, "> 0 [m]");
  CheckArgument(std::isfinite(pupil.camera_pixel_rad) && pupil.camera_pixel_rad > 0, fn, "pupil.camera_pixel_rad",
                pupil.camera_pixel_rad, "> 0 [rad]");
  const Index pix = n_ * n_;
  shift_coefficient_ = TiltCoefficientForShift(pupil.camera_pixel_rad, pupil.diameter_m);
  auto column = [&](const Image& img) { return Eigen::Map<const Vector>(img.data(), pix); };
  switch (options.kind) {
    case DesignParameterisationKind::kRaster:
    case DesignParameterisationKind::kTipTilt:
      basis_.resize(pix, 2);
      basis_.col(0) = column(Image(shift_coefficient_ * Zernike(3, n_, pupil.obstruction)));
      basis_.col(1) = column(Image(shift_coefficient_ * Zernike(2, n_, pupil.obstruction)));
      break;
    case DesignParameterisationKind::kZernike:
      basis_.resize(pix, options.zernike_modes);
      for (int j = 0; j < options.zernike_modes; ++j) basis_.col(j) = column(Zernike(j + 2, n_, pupil.obstruction));
      break;
    case DesignParameterisationKind::kActuators: {
      if (!pupil.dm) throw InvalidArgument(fn, "pupil.dm", "null", "a deformable mirror for kind actuators");
      CheckArgument(pupil.dm->pupil_n() == n_, fn, "pupil.dm pupil_n", pupil.dm->pupil_n(),
                    "the pupil grid's n = " + std::to_string(n_));
      const Index a = pupil.dm->n_active();
      basis_.resize(pix, a);
      Vector e = Vector::Zero(a);
      for (Index k = 0; k < a; ++k) {
        e[k] = 1.0;
        basis_.col(k) = pupil.dm->Apply(e);
        e[k] = 0.0;
      }
      stroke_ = options.bound_stroke ? pupil.dm->options().stroke_m : 0.0;
      break;
    }
  }
  // Quadratic forms of the RMS (piston removed) and of the Strehl-costing part (piston, tip, tilt removed),
  // over the lit pixels only.
  std::vector<Index> lit;
  for (Index p = 0; p < pix; ++p)
    if (pupil.amplitude.data()[p] > 0) lit.push_back(p);
  const Index nl = Index(lit.size());
  Eigen::MatrixXd b(nl, basis_.cols()), t(nl, 3);
  Eigen::VectorXd w(nl);
  const Image z2 = Zernike(2, n_, pupil.obstruction), z3 = Zernike(3, n_, pupil.obstruction);
  for (Index k = 0; k < nl; ++k) {
    b.row(k) = basis_.row(lit[k]);
    w[k] = pupil.amplitude.data()[lit[k]];
    t(k, 0) = 1.0;
    t(k, 1) = z2.data()[lit[k]];
    t(k, 2) = z3.data()[lit[k]];
  }
  const double wsum = w.sum();
  const Eigen::MatrixXd bp = RemoveWeighted(b, t.leftCols(1), w);
  q_rms_ = bp.transpose() * w.asDiagonal() * bp / wsum;
  const Eigen::MatrixXd bs = RemoveWeighted(b, t, w);
  q_strehl_ = bs.transpose() * w.asDiagonal() * bs / wsum;
  rho_rms_ = options.rms_max_m;
  rho_strehl_ = options.strehl_min > 0
                    ? pupil.wavelength_m / (2.0 * M_PI) * std::sqrt(-std::log(options.strehl_min))
                    : 0.0;
  // The raster must be feasible: every design starts from it.
  for (const Vector& c : RasterCoefficients()) {
    const double t_rms = std::sqrt(std::max(0.0, c.dot(q_rms_ * c)));
    if (rho_rms_ > 0 && !(t_rms < rho_rms_))
      throw InvalidArgument(fn, "options.rms_max_m", ToString(rho_rms_),
                            "> the raster's own offset RMS " + ToString(t_rms) + " m (every design starts from it)");
  }
}

int DesignParameterisation::parameters() const {
  return options_.kind == DesignParameterisationKind::kRaster ? 0 : frames_ * int(basis_.cols());
}

Vector DesignParameterisation::Squash(const Vector& v) const {
  Vector c = v;
  if (stroke_ > 0) c = (v.array() / stroke_).tanh() * stroke_;
  if (rho_strehl_ > 0) c *= SquashFactor(std::sqrt(std::max(0.0, c.dot(q_strehl_ * c))), rho_strehl_);
  if (rho_rms_ > 0) c *= SquashFactor(std::sqrt(std::max(0.0, c.dot(q_rms_ * c))), rho_rms_);
  return c;
}

Vector DesignParameterisation::SquashPullBack(const Vector& v, const Vector& dc) const {
  // Forward pass keeping the intermediate coefficients.
  Vector c0 = v;
  if (stroke_ > 0) c0 = (v.array() / stroke_).tanh() * stroke_;
  Vector c1 = c0;
  double t1 = 0;
  if (rho_strehl_ > 0) {
    t1 = std::sqrt(std::max(0.0, c0.dot(q_strehl_ * c0)));
    c1 = c0 * SquashFactor(t1, rho_strehl_);
  }
  Vector d = dc;
  if (rho_rms_ > 0) {
    const double t2 = std::sqrt(std::max(0.0, c1.dot(q_rms_ * c1)));
    d = SquashFactor(t2, rho_rms_) * dc + SquashSlopeOverT(t2, rho_rms_) * c1.dot(dc) * (q_rms_ * c1);
  }
  if (rho_strehl_ > 0) d = SquashFactor(t1, rho_strehl_) * d + SquashSlopeOverT(t1, rho_strehl_) * c0.dot(d) * (q_strehl_ * c0);
  if (stroke_ > 0) {
    const Eigen::ArrayXd th = (v.array() / stroke_).tanh();
    d = (d.array() * (1.0 - th * th)).matrix();
  }
  return d;
}

std::vector<Vector> DesignParameterisation::Coefficients(const Vector& theta) const {
  if (options_.kind == DesignParameterisationKind::kRaster) return RasterCoefficients();
  CheckArgument(theta.size() == parameters(), "DesignParameterisation::Coefficients", "theta size", theta.size(),
                std::to_string(parameters()));
  const Index p = basis_.cols();
  std::vector<Vector> out;
  for (int i = 0; i < frames_; ++i) out.push_back(Squash(theta.segment(i * p, p)));
  return out;
}

std::vector<Image> DesignParameterisation::Opds(const Vector& theta) const {
  std::vector<Image> out;
  for (const Vector& c : Coefficients(theta)) out.push_back(ToImage(basis_ * c, {n_, n_}));
  return out;
}

Vector DesignParameterisation::PullBack(const Vector& theta, const std::vector<Image>& d_opd) const {
  const char* fn = "DesignParameterisation::PullBack";
  CheckArgument(int(d_opd.size()) == frames_, fn, "d_opd count", d_opd.size(), std::to_string(frames_));
  if (options_.kind == DesignParameterisationKind::kRaster) return Vector();
  CheckArgument(theta.size() == parameters(), fn, "theta size", theta.size(), std::to_string(parameters()));
  const Index p = basis_.cols();
  Vector g(theta.size());
  for (int i = 0; i < frames_; ++i) {
    CheckArgument(ShapeOf(d_opd[i]) == Shape{n_, n_}, fn, "d_opd shape", ToString(ShapeOf(d_opd[i])),
                  ToString(Shape{n_, n_}));
    const Vector dc = basis_.transpose() * AsVector(d_opd[i]);
    g.segment(i * p, p) = SquashPullBack(theta.segment(i * p, p), dc);
  }
  return g;
}

Vector DesignParameterisation::ToParameters(const std::vector<Vector>& coefficients) const {
  const char* fn = "DesignParameterisation::ToParameters";
  if (options_.kind == DesignParameterisationKind::kRaster) return Vector();
  CheckArgument(int(coefficients.size()) == frames_, fn, "coefficients count", coefficients.size(),
                std::to_string(frames_));
  const Index p = basis_.cols();
  Vector theta(frames_ * p);
  for (int i = 0; i < frames_; ++i) {
    Vector c = coefficients[i];
    CheckArgument(c.size() == p, fn, "coefficients size", c.size(), std::to_string(p));
    if (rho_rms_ > 0) {
      const double t = std::sqrt(std::max(0.0, c.dot(q_rms_ * c)));
      if (!(t < rho_rms_)) throw InvalidArgument(fn, "offset RMS", ToString(t), "< rms_max_m = " + ToString(rho_rms_));
      if (t > 0) c *= rho_rms_ * std::atanh(t / rho_rms_) / t;
    }
    if (rho_strehl_ > 0) {
      const double t = std::sqrt(std::max(0.0, c.dot(q_strehl_ * c)));
      if (!(t < rho_strehl_))
        throw InvalidArgument(fn, "offset non-tilt RMS", ToString(t), "< the Strehl bound's " + ToString(rho_strehl_) + " m");
      if (t > 0) c *= rho_strehl_ * std::atanh(t / rho_strehl_) / t;
    }
    if (stroke_ > 0) {
      if (!((c.array().abs() < stroke_).all()))
        throw InvalidArgument(fn, "command", ToString(c.cwiseAbs().maxCoeff()), "< stroke " + ToString(stroke_));
      c = (c.array() / stroke_).atanh().matrix() * stroke_;
    }
    theta.segment(i * p, p) = c;
  }
  return theta;
}

std::vector<Vector> DesignParameterisation::RasterCoefficients() const {
  std::vector<Vector> out;
  const std::vector<FrameOffset> raster = ClassicRaster(frames_, r_);
  std::unique_ptr<DmFitter> fitter;
  if (options_.kind == DesignParameterisationKind::kActuators) fitter = std::make_unique<DmFitter>(pupil_.dm, pupil_.amplitude);
  for (const FrameOffset& f : raster) {
    const double dy = f.dy / r_, dx = f.dx / r_;  // camera pixels
    Vector c = Vector::Zero(basis_.cols());
    switch (options_.kind) {
      case DesignParameterisationKind::kRaster:
      case DesignParameterisationKind::kTipTilt:
        c << dy, dx;
        break;
      case DesignParameterisationKind::kZernike:
        c[0] = dx * shift_coefficient_;  // Z2: x
        c[1] = dy * shift_coefficient_;  // Z3: y
        break;
      case DesignParameterisationKind::kActuators: {
        const Image opd = shift_coefficient_ * (dy * Zernike(3, n_, pupil_.obstruction) + dx * Zernike(2, n_, pupil_.obstruction));
        c = fitter->Fit(opd);
        // The fit's ripple may touch a tight bound: shrink into it (a raster start, not the raster exactly).
        double scale = 1.0;
        if (stroke_ > 0 && c.size()) scale = std::min(scale, 0.99 * stroke_ / std::max(1e-300, c.cwiseAbs().maxCoeff()));
        if (rho_strehl_ > 0) {
          const double t = std::sqrt(std::max(0.0, c.dot(q_strehl_ * c)));
          if (t > 0) scale = std::min(scale, 0.99 * rho_strehl_ / t);
        }
        c *= scale;
        break;
      }
    }
    out.push_back(c);
  }
  return out;
}

Vector DesignParameterisation::RasterParameters() const { return ToParameters(RasterCoefficients()); }

std::vector<Image> DesignParameterisation::RasterOpds() const {
  std::vector<Image> out;
  for (const FrameOffset& f : ClassicRaster(frames_, r_))
    out.push_back(shift_coefficient_ *
                  (f.dy / r_ * Zernike(3, n_, pupil_.obstruction) + f.dx / r_ * Zernike(2, n_, pupil_.obstruction)));
  return out;
}

double DesignParameterisation::ParameterScale() const {
  // A quarter camera pixel of shift, or its tilt coefficient: the raster's own scale.
  if (options_.kind == DesignParameterisationKind::kRaster || options_.kind == DesignParameterisationKind::kTipTilt)
    return 0.25;
  return 0.25 * shift_coefficient_;
}

std::vector<DmOffset> DesignParameterisation::Offsets(const Vector& theta) const {
  std::vector<DmOffset> out;
  for (const Vector& c : Coefficients(theta)) {
    DmOffset o;
    switch (options_.kind) {
      case DesignParameterisationKind::kRaster:
      case DesignParameterisationKind::kTipTilt:
        o.shift_y_px = c[0];
        o.shift_x_px = c[1];
        break;
      case DesignParameterisationKind::kZernike:
        o.shift_x_px = c[0] / shift_coefficient_;
        o.shift_y_px = c[1] / shift_coefficient_;
        for (Index j = 2; j < c.size(); ++j) o.zernike.push_back({int(j) + 2, c[j]});
        break;
      case DesignParameterisationKind::kActuators:
        o.actuators_m.assign(c.data(), c.data() + c.size());
        break;
    }
    out.push_back(o);
  }
  return out;
}

double DesignParameterisation::OpdRms(const Image& opd) const {
  const Image& a = pupil_.amplitude;
  const double w = a.sum();
  const double mean = (a * opd).sum() / w;
  return std::sqrt((a * (opd - mean).square()).sum() / w);
}

double DesignParameterisation::StrehlOf(const Image& opd) const {
  // Tip and tilt removed (the scene pipeline's convention: a designed shift is not a loss of quality).
  const Vector c = ProjectOntoZernike(opd, pupil_.amplitude, 3);
  const Image clean = opd - c[1] * Zernike(2, n_, pupil_.obstruction) - c[2] * Zernike(3, n_, pupil_.obstruction);
  return StrehlFromPupil(pupil_.amplitude, clean, pupil_.wavelength_m);
}

}  // namespace aosr
