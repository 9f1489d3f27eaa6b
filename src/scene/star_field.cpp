#include "aosr/scene/star_field.hpp"

#include <algorithm>
#include <cmath>
#include <unordered_map>

#include "aosr/ao/random.hpp"
#include "aosr/core/error.hpp"
#include "object_random.hpp"

namespace aosr {
namespace {

constexpr int kMaxStars = 10000000;
constexpr double kMaxAlpha = 5.0;
constexpr double kMaxPackingFraction = 0.4;
constexpr std::uint64_t kPositionStream = 0;
constexpr std::uint64_t kFluxStream = 1;


// ∫_1^ratio t^k dt, stable for k near -1.
double PowerIntegral(double k, double ratio) {
  const double lr = std::log(ratio);
  if (std::abs(k + 1.0) < 1e-12) return lr;
  return std::expm1((k + 1.0) * lr) / (k + 1.0);
}

void CheckLuminosity(const std::string& function, const LuminosityFunction& lf) {
  std::string why;
  if (!lf.IsValid(&why)) throw InvalidArgument(function + ": invalid luminosity: " + why);
}

// Hard-core random sequential addition on a cell grid of side s (a neighbour within s is in the 3x3 cells).
class HardCoreGrid {
 public:
  HardCoreGrid(double y0, double x0, double s) : y0_(y0), x0_(x0), s_(s) {}

  bool Free(double y, double x, const std::vector<PointSource>& stars) const {
    const long cy = Cell(y, y0_), cx = Cell(x, x0_);
    for (long dy = -1; dy <= 1; ++dy)
      for (long dx = -1; dx <= 1; ++dx) {
        auto it = cells_.find(Key(cy + dy, cx + dx));
        if (it == cells_.end()) continue;
        for (std::size_t k : it->second) {
          const double ey = stars[k].y - y, ex = stars[k].x - x;
          if (ey * ey + ex * ex < s_ * s_) return false;
        }
      }
    return true;
  }
  void Add(double y, double x, std::size_t index) {
    cells_[Key(Cell(y, y0_), Cell(x, x0_))].push_back(index);
  }

 private:
  long Cell(double t, double t0) const { return static_cast<long>(std::floor((t - t0) / s_)); }
  // Cell indices are negative left of (y0, x0), and shifting a negative signed value is undefined before
  // C++20: pack the two's-complement bits as unsigned.
  static std::uint64_t Key(long cy, long cx) {
    return (static_cast<std::uint64_t>(cy) << 32) ^ (static_cast<std::uint64_t>(cx) & 0xffffffffULL);
  }
  double y0_, x0_, s_;
  std::unordered_map<std::uint64_t, std::vector<std::size_t>> cells_;
};

}  // namespace

bool LuminosityFunction::IsValid(std::string* why) const {
  if (!std::isfinite(alpha) || alpha < 0.0 || alpha > kMaxAlpha)
    return Fail(why, "alpha = " + ToString(alpha) + " (must be finite and in [0, 5])");
  if (!std::isfinite(flux_min) || flux_min <= 0.0)
    return Fail(why, "flux_min = " + ToString(flux_min) + " (must be finite and > 0)");
  if (!std::isfinite(flux_max) || flux_max <= flux_min)
    return Fail(why, "flux_max = " + ToString(flux_max) +
                         " (must be finite and > flux_min = " + ToString(flux_min) + ")");
  return true;
}

double LuminosityFunction::Quantile(double u) const {
  CheckLuminosity("LuminosityFunction::Quantile", *this);
  CheckArgument(u >= 0.0 && u <= 1.0, "LuminosityFunction::Quantile", "u", u, "[0, 1]");
  return scene_internal::PowerLawQuantile(u, alpha, flux_min, flux_max);
}

double LuminosityFunction::Cdf(double f) const {
  CheckLuminosity("LuminosityFunction::Cdf", *this);
  CheckArgument(!std::isnan(f), "LuminosityFunction::Cdf", "f", f, "a number");
  return scene_internal::PowerLawCdf(f, alpha, flux_min, flux_max);
}

double LuminosityFunction::MeanFlux() const {
  CheckLuminosity("LuminosityFunction::MeanFlux", *this);
  const double ratio = flux_max / flux_min;
  return flux_min * PowerIntegral(1.0 - alpha, ratio) / PowerIntegral(-alpha, ratio);
}

bool StarFieldOptions::IsValid(std::string* why) const {
  if (count < 0 || count > kMaxStars)
    return Fail(why, "count = " + std::to_string(count) + " (must be in [0, 10000000])");
  std::string lf_why;
  if (!luminosity.IsValid(&lf_why)) return Fail(why, "luminosity." + lf_why);
  if (!std::isfinite(min_separation_px) || min_separation_px < 0.0)
    return Fail(why, "min_separation_px = " + ToString(min_separation_px) + " (must be finite and >= 0)");
  if (!std::isfinite(margin_px) || margin_px < 0.0)
    return Fail(why, "margin_px = " + ToString(margin_px) + " (must be finite and >= 0)");
  return true;
}

std::vector<PointSource> StarField(Shape hr, const StarFieldOptions& options, std::uint64_t seed) {
  const std::string fn = "StarField";
  CheckArgument(hr.rows >= 1 && hr.cols >= 1, fn, "hr", ToString(hr), "rows and cols >= 1");
  std::string why;
  if (!options.IsValid(&why)) throw InvalidArgument(fn + ": invalid options: " + why);
  const double m = options.margin_px;
  CheckArgument(2.0 * m < static_cast<double>(std::min(hr.rows, hr.cols)), fn, "options.margin_px", m,
                "< half the smaller side of hr = " + ToString(hr));
  // Available region: the field [-1/2, n - 1/2) shrunk by the margin.
  const double y0 = -0.5 + m, y1 = hr.rows - 0.5 - m;
  const double x0 = -0.5 + m, x1 = hr.cols - 0.5 - m;
  const double area = (y1 - y0) * (x1 - x0);
  const double s = options.min_separation_px;
  if (s > 0.0) {
    const double packing = options.count * M_PI * s * s / 4.0 / area;
    CheckArgument(packing <= kMaxPackingFraction, fn, "options.min_separation_px", s,
                  "a packing fraction count*pi*s^2/4/area <= 0.4 (here " + ToString(packing) +
                      " for count = " + std::to_string(options.count) + " on " + ToString(area) + " px^2)");
  }

  std::vector<PointSource> stars;
  stars.reserve(options.count);
  scene_internal::UniformGenerator position_rng(DeriveSeed(seed, kPositionStream));
  if (s == 0.0) {
    for (int k = 0; k < options.count; ++k) {
      const double y = position_rng.Uniform(y0, y1);
      const double x = position_rng.Uniform(x0, x1);
      stars.push_back({y, x, 0.0});
    }
  } else {
    HardCoreGrid grid(y0, x0, s);
    const long long budget = 1000LL * options.count + 10000;
    long long attempts = 0;
    while (static_cast<int>(stars.size()) < options.count && attempts < budget) {
      ++attempts;
      const double y = position_rng.Uniform(y0, y1);
      const double x = position_rng.Uniform(x0, x1);
      if (!grid.Free(y, x, stars)) continue;
      grid.Add(y, x, stars.size());
      stars.push_back({y, x, 0.0});
    }
    if (static_cast<int>(stars.size()) < options.count)
      throw Error(fn + ": placed only " + std::to_string(stars.size()) + " of " +
                  std::to_string(options.count) + " stars at min_separation_px = " + ToString(s) + " in " +
                  std::to_string(budget) + " attempts; lower count or min_separation_px");
  }
  return AssignFluxes(stars, options.luminosity, seed);
}

std::vector<PointSource> AssignFluxes(const std::vector<PointSource>& positions,
                                      const LuminosityFunction& luminosity, std::uint64_t seed) {
  CheckLuminosity("AssignFluxes", luminosity);
  for (std::size_t k = 0; k < positions.size(); ++k) {
    CheckArgument(std::isfinite(positions[k].y) && std::isfinite(positions[k].x), "AssignFluxes",
                  "positions[" + std::to_string(k) + "]",
                  ToString(positions[k].y) + ", " + ToString(positions[k].x), "finite coordinates");
  }
  std::vector<PointSource> out = positions;
  scene_internal::UniformGenerator flux_rng(DeriveSeed(seed, kFluxStream));
  for (PointSource& p : out) {
    p.flux = scene_internal::PowerLawQuantile(flux_rng.Next(), luminosity.alpha, luminosity.flux_min,
                                              luminosity.flux_max);
  }
  return out;
}

}  // namespace aosr
