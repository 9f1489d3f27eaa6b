#include "aosr/scene/planet.hpp"

#include <algorithm>
#include <cmath>
#include <vector>

#include "aosr/ao/random.hpp"
#include "aosr/core/error.hpp"
#include "aosr/core/memory.hpp"
#include "object_random.hpp"

namespace aosr {
namespace {

constexpr std::uint64_t kPlanetStream = 4;  // dead leaves use 3, galaxies 2, star fields 0 and 1
constexpr double kDeg = kPi / 180.0;
constexpr double kMaxRadius = 1e5;
constexpr int kMaxSupersample = 16;
constexpr int kMaxTextureSide = 65536;
constexpr int kMaxBands = 1000;
constexpr int kMaxSpots = 100000;
constexpr double kMaxSpotContrast = 1e6;
constexpr double kMaxWobble = 45.0;
constexpr int kWobbleWaves = 3;  // undulations of the band boundaries around the body

// x reduced to [0, period). fmod keeps the sign of x; the final guard catches -tiny + period rounding to
// period.
double Wrap(double x, double period) {
  double r = std::fmod(x, period);
  if (r < 0.0) r += period;
  return r >= period ? 0.0 : r;
}

// The disc geometry of planet.hpp with its trigonometry evaluated once: maps a point to (φ, λ, μ).
struct DiscGeometry {
  double cy, cx, inv_r;
  double cos_p, sin_p;      // pole position angle
  double cos_b, sin_b;      // sub-observer latitude
  double central_meridian;  // λ_c(t), degrees

  DiscGeometry(Shape hr, const PlanetOptions& o, double time_s)
      : cy(std::isnan(o.centre_y) ? 0.5 * double(hr.rows - 1) : o.centre_y),
        cx(std::isnan(o.centre_x) ? 0.5 * double(hr.cols - 1) : o.centre_x),
        inv_r(1.0 / o.radius_px),
        cos_p(std::cos(o.pole_angle_deg * kDeg)),
        sin_p(std::sin(o.pole_angle_deg * kDeg)),
        cos_b(std::cos(o.sub_observer_latitude_deg * kDeg)),
        sin_b(std::sin(o.sub_observer_latitude_deg * kDeg)),
        central_meridian(PlanetCentralMeridianDeg(o, time_s)) {}

  // Fills (lat, lon, mu) in degrees / degrees / [0, 1] for normalised disc coordinates (dx, dy) with
  // dx² + dy² = rho2 < 1. lon is not reduced to [0, 360) (the texture lookup wraps it).
  void Surface(double dx, double dy, double rho2, double* lat, double* lon, double* mu) const {
    const double zeta = std::sqrt(1.0 - rho2);
    const double xi = dx * cos_p + dy * sin_p;
    const double eta = dx * sin_p - dy * cos_p;
    const double sin_lat = std::clamp(eta * cos_b + zeta * sin_b, -1.0, 1.0);
    *lat = std::asin(sin_lat) / kDeg;
    *lon = central_meridian + std::atan2(xi, zeta * cos_b - eta * sin_b) / kDeg;
    *mu = zeta;
  }
};

// Bilinear lookup in an equirectangular map (layout of planet.hpp): pixel centres at latitude
// 90 − (i + 1/2) Δφ and longitude (j + 1/2) Δλ; wraps in longitude, clamps in latitude.
class TextureSampler {
 public:
  explicit TextureSampler(const Image& texture)
      : t_(texture),
        rows_(texture.rows()),
        cols_(texture.cols()),
        rows_per_deg_(double(texture.rows()) / 180.0),
        cols_per_deg_(double(texture.cols()) / 360.0) {}

  double operator()(double lat_deg, double lon_deg) const {
    // Continuous row coordinate (row i centred at i), clamped to the first and last rows' centres.
    const double r = std::clamp((90.0 - lat_deg) * rows_per_deg_ - 0.5, 0.0, double(rows_ - 1));
    Index r0 = std::min<Index>(static_cast<Index>(r), std::max<Index>(rows_ - 2, 0));
    const Index r1 = std::min<Index>(r0 + 1, rows_ - 1);
    const double fr = r - double(r0);
    // Continuous column coordinate, wrapped to [0, cols).
    const double c = Wrap(lon_deg * cols_per_deg_ - 0.5, double(cols_));
    Index c0 = static_cast<Index>(c);
    if (c0 >= cols_) c0 = cols_ - 1;  // rounding of c just below cols
    const Index c1 = c0 + 1 == cols_ ? 0 : c0 + 1;
    const double fc = c - double(c0);
    const double top = (1.0 - fc) * t_(r0, c0) + fc * t_(r0, c1);
    const double bottom = (1.0 - fc) * t_(r1, c0) + fc * t_(r1, c1);
    return (1.0 - fr) * top + fr * bottom;
  }

 private:
  const Image& t_;
  Index rows_, cols_;
  double rows_per_deg_, cols_per_deg_;
};

void CheckPlanetOptions(const std::string& fn, const PlanetOptions& options) {
  std::string why;
  if (!options.IsValid(&why)) throw InvalidArgument(fn + ": invalid options: " + why);
}

void CheckTime(const std::string& fn, double time_s) {
  CheckArgument(std::isfinite(time_s), fn, "time_s", time_s, "a finite time in seconds");
}

void CheckField(const std::string& fn, Shape hr) {
  CheckArgument(hr.rows >= 1 && hr.cols >= 1, fn, "hr", ToString(hr), "rows and cols >= 1");
}

}  // namespace

bool PlanetOptions::IsValid(std::string* why) const {
  if (std::isinf(centre_y) || std::isinf(centre_x))
    return Fail(why, "centre = (" + ToString(centre_y) + ", " + ToString(centre_x) +
                         ") (must be finite, or NaN for the field centre)");
  if (!(radius_px > 0.0 && radius_px <= kMaxRadius))
    return Fail(why, "radius_px = " + ToString(radius_px) + " (must be in (0, 100000])");
  if (!std::isfinite(rotation_period_s))
    return Fail(why, "rotation_period_s = " + ToString(rotation_period_s) +
                         " (must be finite; 0: no rotation, < 0: retrograde)");
  if (!(pole_angle_deg >= -360.0 && pole_angle_deg <= 360.0))
    return Fail(why, "pole_angle_deg = " + ToString(pole_angle_deg) + " (must be in [-360, 360])");
  if (!(sub_observer_latitude_deg >= -90.0 && sub_observer_latitude_deg <= 90.0))
    return Fail(why, "sub_observer_latitude_deg = " + ToString(sub_observer_latitude_deg) +
                         " (must be in [-90, 90])");
  if (!std::isfinite(longitude0_deg))
    return Fail(why, "longitude0_deg = " + ToString(longitude0_deg) + " (must be finite)");
  if (!(limb_darkening >= 0.0 && limb_darkening <= 1.0))
    return Fail(why, "limb_darkening = " + ToString(limb_darkening) + " (must be in [0, 1])");
  if (supersample < 1 || supersample > kMaxSupersample)
    return Fail(why, "supersample = " + std::to_string(supersample) + " (must be in [1, 16])");
  return true;
}

double PlanetCentralMeridianDeg(const PlanetOptions& options, double time_s) {
  const std::string fn = "PlanetCentralMeridianDeg";
  CheckPlanetOptions(fn, options);
  CheckTime(fn, time_s);
  // The phase is reduced before scaling to degrees so that t = k T gives exactly longitude0 (periodic bytes).
  const double phase = options.rotation_period_s == 0.0 ? 0.0 : Wrap(time_s / options.rotation_period_s, 1.0);
  return Wrap(options.longitude0_deg - 360.0 * phase, 360.0);
}

PlanetSurfacePoint PlanetSurfaceAt(Shape hr, const PlanetOptions& options, double y, double x,
                                   double time_s) {
  const std::string fn = "PlanetSurfaceAt";
  CheckField(fn, hr);
  CheckPlanetOptions(fn, options);
  CheckArgument(std::isfinite(y), fn, "y", y, "a finite HR pixel coordinate");
  CheckArgument(std::isfinite(x), fn, "x", x, "a finite HR pixel coordinate");
  CheckTime(fn, time_s);
  const DiscGeometry g(hr, options, time_s);
  const double dx = (x - g.cx) * g.inv_r, dy = (y - g.cy) * g.inv_r;
  const double rho2 = dx * dx + dy * dy;
  PlanetSurfacePoint p;
  if (!(rho2 < 1.0)) return p;
  p.on_disc = true;
  g.Surface(dx, dy, rho2, &p.latitude_deg, &p.longitude_deg, &p.mu);
  p.longitude_deg = Wrap(p.longitude_deg, 360.0);
  return p;
}

Image RenderPlanet(Shape hr, const PlanetOptions& options, const Image& texture, double time_s) {
  const std::string fn = "RenderPlanet";
  CheckField(fn, hr);
  CheckPlanetOptions(fn, options);
  CheckArgument(texture.size() > 0, fn, "texture", ToString(ShapeOf(texture)), "a non-empty map");
  CheckArgument(AllFinite(texture), fn, "texture", "a map with non-finite values", "finite values >= 0");
  CheckArgument(texture.minCoeff() >= 0.0, fn, "texture",
                "a map with minimum " + ToString(texture.minCoeff()), "finite values >= 0");
  CheckTime(fn, time_s);

  Image image = Image::Zero(hr.rows, hr.cols);
  const DiscGeometry g(hr, options, time_s);
  const TextureSampler sample(texture);
  const double radius = options.radius_px;
  const double u = options.limb_darkening;
  const int s = options.supersample;

  // Pixels whose footprint [y - 1/2, y + 1/2) can meet the disc: the bounding box widened by half a pixel,
  // clipped to the field. Computed in double first so that a far-off centre cannot overflow Index.
  const auto lower = [](double a, Index n) {
    return static_cast<Index>(std::clamp(std::floor(a - 0.5), 0.0, double(n)));
  };
  const auto upper = [](double b, Index n) {
    return static_cast<Index>(std::clamp(std::ceil(b + 0.5), -1.0, double(n - 1)));
  };
  const Index y0 = lower(g.cy - radius, hr.rows), y1 = upper(g.cy + radius, hr.rows);
  const Index x0 = lower(g.cx - radius, hr.cols), x1 = upper(g.cx + radius, hr.cols);
  if (y0 > y1 || x0 > x1) return image;

  // Sub-sample offsets from the pixel centre, symmetric about 0 so that a disc centred on a pixel centre or
  // corner gives a mirror-symmetric image.
  std::vector<double> offset(s);
  for (int k = 0; k < s; ++k) offset[k] = (k + 0.5) / s - 0.5;
  const double inv_samples = 1.0 / (double(s) * s);

  for (Index y = y0; y <= y1; ++y) {
    for (Index x = x0; x <= x1; ++x) {
      double sum = 0.0;
      for (int i = 0; i < s; ++i) {
        const double dy = (double(y) + offset[i] - g.cy) * g.inv_r;
        for (int j = 0; j < s; ++j) {
          const double dx = (double(x) + offset[j] - g.cx) * g.inv_r;
          const double rho2 = dx * dx + dy * dy;
          if (!(rho2 < 1.0)) continue;
          double lat, lon, mu;
          g.Surface(dx, dy, rho2, &lat, &lon, &mu);
          sum += sample(lat, lon) * (1.0 - u * (1.0 - mu));
        }
      }
      image(y, x) = sum * inv_samples;
    }
  }
  return image;
}

bool PlanetTextureOptions::IsValid(std::string* why) const {
  if (rows < 2 || rows > kMaxTextureSide)
    return Fail(why, "rows = " + std::to_string(rows) + " (must be in [2, 65536])");
  if (cols < 2 || cols > kMaxTextureSide)
    return Fail(why, "cols = " + std::to_string(cols) + " (must be in [2, 65536])");
  if (bands < 0 || bands > kMaxBands)
    return Fail(why, "bands = " + std::to_string(bands) + " (must be in [0, 1000])");
  if (!(band_contrast >= 0.0 && band_contrast < 1.0))
    return Fail(why, "band_contrast = " + ToString(band_contrast) + " (must be in [0, 1))");
  if (!(band_wobble_deg >= 0.0 && band_wobble_deg <= kMaxWobble))
    return Fail(why, "band_wobble_deg = " + ToString(band_wobble_deg) + " (must be in [0, 45])");
  if (spots < 0 || spots > kMaxSpots)
    return Fail(why, "spots = " + std::to_string(spots) + " (must be in [0, 100000])");
  if (!(spot_radius_deg > 0.0 && spot_radius_deg <= 90.0))
    return Fail(why, "spot_radius_deg = " + ToString(spot_radius_deg) + " (must be in (0, 90])");
  if (!(spot_contrast >= 0.0 && spot_contrast <= kMaxSpotContrast))
    return Fail(why, "spot_contrast = " + ToString(spot_contrast) + " (must be in [0, 1e6])");
  return true;
}

Image PlanetTexture(const PlanetTextureOptions& options, std::uint64_t seed) {
  const std::string fn = "PlanetTexture";
  std::string why;
  if (!options.IsValid(&why)) throw InvalidArgument(fn + ": invalid options: " + why);
  CheckMemory(8.0 * options.rows * options.cols,
              fn + ": a " + std::to_string(options.rows) + "x" + std::to_string(options.cols) + " map");

  const Index rows = options.rows, cols = options.cols;
  const double dlat = 180.0 / rows, dlon = 360.0 / cols;
  const auto latitude = [&](Index i) { return 90.0 - (double(i) + 0.5) * dlat; };
  const auto longitude = [&](Index j) { return (double(j) + 0.5) * dlon; };

  scene_internal::UniformGenerator rng(DeriveSeed(seed, kPlanetStream));
  // Drawn whether or not the bands wobble, so that spot positions do not depend on band_wobble_deg.
  const double psi = kTwoPi * rng.Next();

  // Bands, then their area-weighted mean over the map's pixels (cos φ: a pixel's share of the sphere).
  Image map(rows, cols);
  const double wave = 2.0 * kPi * options.bands / 180.0;  // radians of band phase per degree of latitude
  double weighted = 0.0, weights = 0.0;
  for (Index i = 0; i < rows; ++i) {
    const double lat = latitude(i), w = std::cos(lat * kDeg);
    for (Index j = 0; j < cols; ++j) {
      const double shifted =
          lat + options.band_wobble_deg * std::sin(kWobbleWaves * longitude(j) * kDeg + psi);
      map(i, j) = 1.0 + options.band_contrast * std::cos(wave * (shifted + 90.0));
      weighted += w * map(i, j);
    }
    weights += w * double(cols);
  }
  map /= weighted / weights;

  // Spots: g(d / r_s) = (1 − q²)², visited only on the rows within r_s (+ a row) of the spot's latitude.
  const double r_s = options.spot_radius_deg * kDeg;
  for (int k = 0; k < options.spots; ++k) {
    const double sin_lat_k = rng.Uniform(-1.0, 1.0);  // uniform on the sphere: sin φ uniform
    const double lon_k = rng.Uniform(0.0, 360.0);
    if (options.spot_contrast == 0.0) continue;
    const double lat_k = std::asin(sin_lat_k) / kDeg;
    const double cos_lat_k = std::cos(lat_k * kDeg);
    const double reach = options.spot_radius_deg + dlat;
    const Index i0 = std::max<Index>(0, static_cast<Index>(std::floor((90.0 - lat_k - reach) / dlat)));
    const Index i1 = std::min<Index>(rows - 1, static_cast<Index>(std::ceil((90.0 - lat_k + reach) / dlat)));
    for (Index i = i0; i <= i1; ++i) {
      const double lat = latitude(i) * kDeg;
      const double sin_lat = std::sin(lat), cos_lat = std::cos(lat);
      for (Index j = 0; j < cols; ++j) {
        const double cos_d = std::clamp(
            sin_lat * sin_lat_k + cos_lat * cos_lat_k * std::cos((longitude(j) - lon_k) * kDeg), -1.0, 1.0);
        const double q = std::acos(cos_d) / r_s;
        if (q >= 1.0) continue;
        const double b = 1.0 - q * q;
        map(i, j) += options.spot_contrast * b * b;
      }
    }
  }
  return map;
}

}  // namespace aosr
