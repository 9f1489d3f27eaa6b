#include "aosr/scene/galaxy.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "aosr/ao/random.hpp"
#include "aosr/core/error.hpp"
#include "object_random.hpp"

namespace aosr {
namespace {

constexpr double kMinN = 0.2;  // exclusive
constexpr double kMaxN = 20.0;
constexpr double kCutFraction = 1e-12;  // light beyond the rendered isophote
constexpr int kMaxGalaxies = 100000;
constexpr std::uint64_t kGalaxyStream = 2;
constexpr int kMaxIterations = 100000;
constexpr double kEps = 1e-16;
constexpr double kTiny = 1e-300;


bool ValidN(double n) { return std::isfinite(n) && n > kMinN && n <= kMaxN; }

void CheckN(const std::string& function, double n) {
  CheckArgument(ValidN(n), function, "n", n, "(0.2, 20]");
}

// x^a e^-x / Γ(a), the common prefactor of the series and the continued fraction.
double GammaPrefactor(double a, double x) { return std::exp(-x + a * std::log(x) - std::lgamma(a)); }

// P(a, x) by its power series  e^-x x^a / Γ(a) Σ_k x^k / (a (a+1) ... (a+k)), for x < a + 1.
double GammaPSeries(double a, double x) {
  double term = 1.0 / a, sum = term, ap = a;
  for (int k = 0; k < kMaxIterations; ++k) {
    ap += 1.0;
    term *= x / ap;
    sum += term;
    if (std::abs(term) < std::abs(sum) * kEps) break;
  }
  return sum * GammaPrefactor(a, x);
}

// Q(a, x) by Legendre's continued fraction
//   Q = e^-x x^a / Γ(a) · 1/(x+1-a- 1(1-a)/(x+3-a- 2(2-a)/(x+5-a- ...))),  for x >= a + 1,
// evaluated with the modified Lentz method.
double GammaQContinuedFraction(double a, double x) {
  double b = x + 1.0 - a;
  double c = 1.0 / kTiny, d = 1.0 / b, h = d;
  for (int i = 1; i < kMaxIterations; ++i) {
    const double an = -i * (i - a);
    b += 2.0;
    d = an * d + b;
    if (std::abs(d) < kTiny) d = kTiny;
    c = b + an / c;
    if (std::abs(c) < kTiny) c = kTiny;
    d = 1.0 / d;
    const double delta = d * c;
    h *= delta;
    if (std::abs(delta - 1.0) < kEps) break;
  }
  return h * GammaPrefactor(a, x);
}

double GammaP(double a, double x) {
  if (x <= 0.0) return 0.0;
  if (x < a + 1.0) return GammaPSeries(a, x);
  return 1.0 - GammaQContinuedFraction(a, x);
}

double GammaQ(double a, double x) {
  if (x <= 0.0) return 1.0;
  if (x < a + 1.0) return 1.0 - GammaPSeries(a, x);
  return GammaQContinuedFraction(a, x);
}

double BnExpansion(double n) {
  return 2.0 * n - 1.0 / 3.0 + 4.0 / (405.0 * n) + 46.0 / (25515.0 * n * n) +
         131.0 / (1148175.0 * n * n * n) - 2194697.0 / (30690717750.0 * n * n * n * n);
}

// Root of P(a, b) = 1/2 (the median of Gamma(a)), which lies in (0, a): safeguarded Newton from `guess`.
double GammaMedian(double a, double guess) {
  double lo = 0.0, hi = a;
  double b = (guess > lo && guess < hi) ? guess : 0.5 * (lo + hi);
  for (int it = 0; it < 200; ++it) {
    const double f = GammaP(a, b) - 0.5;
    if (f == 0.0) return b;
    if (f > 0.0)
      hi = b;
    else
      lo = b;
    const double slope = std::exp(-b + (a - 1.0) * std::log(b) - std::lgamma(a));  // dP/db
    double next = b - f / slope;
    if (!(next > lo && next < hi)) next = 0.5 * (lo + hi);
    if (std::abs(next - b) <= 1e-15 * b || hi - lo <= 1e-15 * hi) return next;
    b = next;
  }
  return b;
}

// x with Q(a, x) = q (q small): bracket by doubling, then bisection.
double GammaUpperQuantile(double a, double q) {
  double lo = 0.0, hi = a + 10.0;
  while (GammaQ(a, hi) > q && hi < 1e6) {
    lo = hi;
    hi *= 2.0;
  }
  for (int it = 0; it < 200 && hi - lo > 1e-12 * hi; ++it) {
    const double mid = 0.5 * (lo + hi);
    (GammaQ(a, mid) > q ? lo : hi) = mid;
  }
  return hi;
}

void CheckGalaxy(const std::string& function, const std::string& name, const SersicGalaxy& g) {
  std::string why;
  if (!g.IsValid(&why)) throw InvalidArgument(function + ": invalid " + name + ": " + why);
}

// The profile with every constant precomputed.
class Profile {
 public:
  explicit Profile(const SersicGalaxy& g)
      : yc_(g.y),
        xc_(g.x),
        cos_(std::cos(g.position_angle_rad)),
        sin_(std::sin(g.position_angle_rad)),
        inv_q2_(1.0 / (g.axis_ratio * g.axis_ratio)),
        inv_re2_(1.0 / (g.half_light_radius_px * g.half_light_radius_px)),
        half_inv_n_(0.5 / g.n),
        b_(SersicBn(g.n)),
        peak_(g.EffectiveIntensity() * std::exp(b_)) {}

  double operator()(double y, double x) const {
    const double dy = y - yc_, dx = x - xc_;
    const double u = dx * cos_ + dy * sin_, v = -dx * sin_ + dy * cos_;
    const double t = (u * u + v * v * inv_q2_) * inv_re2_;  // (R / R_e)²
    if (t == 0.0) return peak_;
    return peak_ * std::exp(-b_ * std::pow(t, half_inv_n_));  // I_e e^{b} e^{-b (R/Re)^{1/n}}
  }

 private:
  double yc_, xc_, cos_, sin_, inv_q2_, inv_re2_, half_inv_n_, b_, peak_;
};

// Adaptive cubature of the profile over squares (galaxy.hpp, "Rendering").
class PixelIntegrator {
 public:
  PixelIntegrator(const Profile& f, double total_flux, double field_area, const SersicRenderOptions& o)
      : f_(f),
        rtol_(o.relative_tolerance),
        floor_density_(total_flux / field_area),
        max_depth_(o.max_depth) {}

  // Integral over the pixel centred at (py, px).
  double Pixel(double py, double px) const {
    const double mid = f_(py, px);
    const double g = Gauss2(py - 0.5, px - 0.5, 1.0);
    if (Accept(g, mid, 1.0)) return g;
    return Refine(py - 0.5, px - 0.5, 1.0, g, 0);
  }

 private:
  bool Accept(double fine, double coarse, double area) const {
    return std::abs(fine - coarse) <= rtol_ * (std::abs(fine) + floor_density_ * area);
  }
  // 2x2 Gauss-Legendre rule on [y0, y0 + h] x [x0, x0 + h]: nodes at the centre ± h / (2 √3), weights h²/4.
  double Gauss2(double y0, double x0, double h) const {
    constexpr double kNode = 0.28867513459481288225;  // 1 / (2 √3)
    const double yc = y0 + 0.5 * h, xc = x0 + 0.5 * h, d = kNode * h;
    return 0.25 * h * h * (f_(yc - d, xc - d) + f_(yc - d, xc + d) + f_(yc + d, xc - d) + f_(yc + d, xc + d));
  }
  double Refine(double y0, double x0, double h, double coarse, int depth) const {
    const double k = 0.5 * h;
    const double q[4] = {Gauss2(y0, x0, k), Gauss2(y0, x0 + k, k), Gauss2(y0 + k, x0, k),
                         Gauss2(y0 + k, x0 + k, k)};
    const double fine = (q[0] + q[1]) + (q[2] + q[3]);
    if (depth >= max_depth_ || Accept(fine, coarse, h * h)) return fine;
    return (Refine(y0, x0, k, q[0], depth + 1) + Refine(y0, x0 + k, k, q[1], depth + 1)) +
           (Refine(y0 + k, x0, k, q[2], depth + 1) + Refine(y0 + k, x0 + k, k, q[3], depth + 1));
  }

  const Profile& f_;
  double rtol_;
  double floor_density_;
  int max_depth_;
};

void AddSersic(const SersicGalaxy& g, const SersicRenderOptions& options, Image* image) {
  if (g.flux == 0.0) return;
  const Index rows = image->rows(), cols = image->cols();
  const Profile profile(g);
  const PixelIntegrator integrator(profile, g.flux, static_cast<double>(rows) * static_cast<double>(cols),
                                   options);
  // Bounding box of the isophote enclosing 1 - kCutFraction of the light, plus a pixel's half-diagonal.
  const double b = SersicBn(g.n);
  const double x_cut = GammaUpperQuantile(2.0 * g.n, kCutFraction);
  const double r_cut = g.half_light_radius_px * std::pow(x_cut / b, g.n);
  const double a_ax = r_cut + 1.0, b_ax = g.axis_ratio * r_cut + 1.0;
  const double c = std::cos(g.position_angle_rad), s = std::sin(g.position_angle_rad);
  const double half_x = std::sqrt(a_ax * a_ax * c * c + b_ax * b_ax * s * s);
  const double half_y = std::sqrt(a_ax * a_ax * s * s + b_ax * b_ax * c * c);
  const auto clamp_index = [](double v, Index n) {
    return static_cast<Index>(std::max(0.0, std::min(static_cast<double>(n - 1), v)));
  };
  if (g.y + half_y < -0.5 || g.y - half_y > rows - 0.5 || g.x + half_x < -0.5 || g.x - half_x > cols - 0.5)
    return;
  const Index y0 = clamp_index(std::floor(g.y - half_y), rows),
              y1 = clamp_index(std::ceil(g.y + half_y), rows);
  const Index x0 = clamp_index(std::floor(g.x - half_x), cols),
              x1 = clamp_index(std::ceil(g.x + half_x), cols);
  for (Index y = y0; y <= y1; ++y)
    for (Index x = x0; x <= x1; ++x)
      (*image)(y, x) += integrator.Pixel(static_cast<double>(y), static_cast<double>(x));
}

}  // namespace

double RegularisedGammaP(double a, double x) {
  CheckArgument(std::isfinite(a) && a > 0.0, "RegularisedGammaP", "a", a, "finite and > 0");
  CheckArgument(!std::isnan(x) && x >= 0.0, "RegularisedGammaP", "x", x, ">= 0");
  if (std::isinf(x)) return 1.0;
  return GammaP(a, x);
}

double SersicBn(double n) {
  CheckN("SersicBn", n);
  return GammaMedian(2.0 * n, BnExpansion(n));
}

double SersicBnCiottiBertin(double n) {
  CheckN("SersicBnCiottiBertin", n);
  return BnExpansion(n);
}

double SersicEnclosedFraction(double n, double radius_over_re) {
  CheckN("SersicEnclosedFraction", n);
  CheckArgument(!std::isnan(radius_over_re) && radius_over_re >= 0.0, "SersicEnclosedFraction",
                "radius_over_re", radius_over_re, ">= 0");
  if (std::isinf(radius_over_re)) return 1.0;
  return GammaP(2.0 * n, SersicBn(n) * std::pow(radius_over_re, 1.0 / n));
}

bool SersicGalaxy::IsValid(std::string* why) const {
  if (!std::isfinite(y) || !std::isfinite(x))
    return Fail(why, "centre (y, x) = (" + ToString(y) + ", " + ToString(x) + ") (must be finite)");
  if (!std::isfinite(flux) || flux < 0.0)
    return Fail(why, "flux = " + ToString(flux) + " (must be finite and >= 0)");
  if (!ValidN(n)) return Fail(why, "n = " + ToString(n) + " (must be in (0.2, 20])");
  if (!std::isfinite(half_light_radius_px) || half_light_radius_px <= 0.0)
    return Fail(why,
                "half_light_radius_px = " + ToString(half_light_radius_px) + " (must be finite and > 0)");
  if (!std::isfinite(axis_ratio) || axis_ratio <= 0.0 || axis_ratio > 1.0)
    return Fail(why, "axis_ratio = " + ToString(axis_ratio) + " (must be in (0, 1])");
  if (!std::isfinite(position_angle_rad))
    return Fail(why, "position_angle_rad = " + ToString(position_angle_rad) + " (must be finite)");
  return true;
}

double SersicGalaxy::EffectiveIntensity() const {
  CheckGalaxy("SersicGalaxy::EffectiveIntensity", "galaxy", *this);
  const double b = SersicBn(n);
  const double log_norm =
      std::log(2.0 * M_PI * n * axis_ratio * half_light_radius_px * half_light_radius_px) + b -
      2.0 * n * std::log(b) + std::lgamma(2.0 * n);
  return flux * std::exp(-log_norm);
}

double SersicGalaxy::Intensity(double py, double px) const {
  CheckGalaxy("SersicGalaxy::Intensity", "galaxy", *this);
  CheckArgument(std::isfinite(py) && std::isfinite(px), "SersicGalaxy::Intensity", "(y, x)",
                ToString(py) + ", " + ToString(px), "finite");
  return Profile(*this)(py, px);
}

bool SersicRenderOptions::IsValid(std::string* why) const {
  if (!std::isfinite(relative_tolerance) || relative_tolerance < 1e-12 || relative_tolerance > 1e-2)
    return Fail(why, "relative_tolerance = " + ToString(relative_tolerance) + " (must be in [1e-12, 1e-2])");
  if (max_depth < 0 || max_depth > 40)
    return Fail(why, "max_depth = " + std::to_string(max_depth) + " (must be in [0, 40])");
  return true;
}

namespace {

void CheckRender(const std::string& fn, Shape hr, const SersicRenderOptions& options) {
  CheckArgument(hr.rows >= 1 && hr.cols >= 1, fn, "hr", ToString(hr), "rows and cols >= 1");
  std::string why;
  if (!options.IsValid(&why)) throw InvalidArgument(fn + ": invalid options: " + why);
}

}  // namespace

Image RenderSersic(Shape hr, const SersicGalaxy& galaxy, const SersicRenderOptions& options) {
  CheckRender("RenderSersic", hr, options);
  CheckGalaxy("RenderSersic", "galaxy", galaxy);
  Image image = Image::Zero(hr.rows, hr.cols);
  AddSersic(galaxy, options, &image);
  return image;
}

Image RenderGalaxies(Shape hr, const std::vector<SersicGalaxy>& galaxies,
                     const SersicRenderOptions& options) {
  CheckRender("RenderGalaxies", hr, options);
  for (std::size_t k = 0; k < galaxies.size(); ++k)
    CheckGalaxy("RenderGalaxies", "galaxies[" + std::to_string(k) + "]", galaxies[k]);
  Image image = Image::Zero(hr.rows, hr.cols);
  for (const SersicGalaxy& g : galaxies) AddSersic(g, options, &image);
  return image;
}

bool GalaxyFieldOptions::IsValid(std::string* why) const {
  if (count < 0 || count > kMaxGalaxies)
    return Fail(why, "count = " + std::to_string(count) + " (must be in [0, 100000])");
  if (!ValidN(n_min)) return Fail(why, "n_min = " + ToString(n_min) + " (must be in (0.2, 20])");
  if (!ValidN(n_max) || n_max < n_min)
    return Fail(why,
                "n_max = " + ToString(n_max) + " (must be in [n_min, 20], n_min = " + ToString(n_min) + ")");
  if (!std::isfinite(re_min_px) || re_min_px <= 0.0)
    return Fail(why, "re_min_px = " + ToString(re_min_px) + " (must be finite and > 0)");
  if (!std::isfinite(re_max_px) || re_max_px < re_min_px)
    return Fail(why, "re_max_px = " + ToString(re_max_px) +
                         " (must be finite and >= re_min_px = " + ToString(re_min_px) + ")");
  if (!std::isfinite(q_min) || q_min <= 0.0 || q_min > 1.0)
    return Fail(why, "q_min = " + ToString(q_min) + " (must be in (0, 1])");
  if (!std::isfinite(q_max) || q_max < q_min || q_max > 1.0)
    return Fail(why,
                "q_max = " + ToString(q_max) + " (must be in [q_min, 1], q_min = " + ToString(q_min) + ")");
  std::string flux_why;
  if (!flux.IsValid(&flux_why)) return Fail(why, "flux." + flux_why);
  if (!std::isfinite(margin_px) || margin_px < 0.0)
    return Fail(why, "margin_px = " + ToString(margin_px) + " (must be finite and >= 0)");
  return true;
}

std::vector<SersicGalaxy> GalaxyField(Shape hr, const GalaxyFieldOptions& options, std::uint64_t seed) {
  const std::string fn = "GalaxyField";
  CheckArgument(hr.rows >= 1 && hr.cols >= 1, fn, "hr", ToString(hr), "rows and cols >= 1");
  std::string why;
  if (!options.IsValid(&why)) throw InvalidArgument(fn + ": invalid options: " + why);
  const double m = options.margin_px;
  CheckArgument(2.0 * m < static_cast<double>(std::min(hr.rows, hr.cols)), fn, "options.margin_px", m,
                "< half the smaller side of hr = " + ToString(hr));
  scene_internal::UniformGenerator rng(DeriveSeed(seed, kGalaxyStream));
  std::vector<SersicGalaxy> galaxies;
  galaxies.reserve(options.count);
  const double log_re_min = std::log(options.re_min_px), log_re_max = std::log(options.re_max_px);
  for (int k = 0; k < options.count; ++k) {
    SersicGalaxy g;  // seven draws per galaxy, always in this order
    g.y = rng.Uniform(-0.5 + m, hr.rows - 0.5 - m);
    g.x = rng.Uniform(-0.5 + m, hr.cols - 0.5 - m);
    g.n = rng.Uniform(options.n_min, options.n_max);
    g.half_light_radius_px = std::exp(rng.Uniform(log_re_min, log_re_max));
    g.axis_ratio = rng.Uniform(options.q_min, options.q_max);
    g.position_angle_rad = rng.Uniform(0.0, M_PI);
    g.flux = scene_internal::PowerLawQuantile(rng.Next(), options.flux.alpha, options.flux.flux_min,
                                              options.flux.flux_max);
    galaxies.push_back(g);
  }
  return galaxies;
}

}  // namespace aosr
