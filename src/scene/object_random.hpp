// Internal to aosr_scene: the uniform deviates and power-law sampling shared by the object generators
// (star fields, galaxy fields, dead leaves). Not installed; public users see only the generators' seeds.
//
// Portability: as in ao/random.hpp, the bits come from std::mt19937_64 (whose output the C++ standard fixes)
// and the conversion to double is ours, so a seed gives the same objects with every standard library
// (std::uniform_real_distribution's algorithm is implementation-defined).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <random>

namespace aosr {
namespace scene_internal {

// Uniform deviates on [0, 1) from the top 53 bits of std::mt19937_64.
class UniformGenerator {
 public:
  explicit UniformGenerator(std::uint64_t seed) : engine_(seed) {}
  // u in [0, 1), a multiple of 2^-53.
  double Next() { return static_cast<double>(engine_() >> 11) * 0x1.0p-53; }
  // u in [lo, hi).
  double Uniform(double lo, double hi) { return lo + (hi - lo) * Next(); }

 private:
  std::mt19937_64 engine_;
};

// Inverse CDF of the truncated power law p(t) ∝ t^(-alpha) on [lo, hi] (0 < lo < hi), at u in [0, 1]:
//   alpha != 1:  t = [lo^(1-alpha) + u (hi^(1-alpha) - lo^(1-alpha))]^(1/(1-alpha))
//   alpha == 1:  t = lo (hi/lo)^u
// Evaluated in the scaled variable t/lo so that wide ranges keep full relative precision; the result is
// clamped to [lo, hi] against the last-bit rounding of pow.
inline double PowerLawQuantile(double u, double alpha, double lo, double hi) {
  const double ratio = hi / lo;
  double t;
  if (std::abs(alpha - 1.0) < 1e-12) {
    t = lo * std::pow(ratio, u);
  } else {
    const double e = 1.0 - alpha;
    // (t/lo)^e = 1 + u (ratio^e - 1); expm1/log1p keep precision when alpha is close to 1.
    const double span = std::expm1(e * std::log(ratio));
    t = lo * std::exp(std::log1p(u * span) / e);
  }
  return std::min(hi, std::max(lo, t));
}

// CDF of the same law at t in [lo, hi].
inline double PowerLawCdf(double t, double alpha, double lo, double hi) {
  if (t <= lo) return 0.0;
  if (t >= hi) return 1.0;
  if (std::abs(alpha - 1.0) < 1e-12) return std::log(t / lo) / std::log(hi / lo);
  const double e = 1.0 - alpha;
  return std::expm1(e * std::log(t / lo)) / std::expm1(e * std::log(hi / lo));
}

}  // namespace scene_internal
}  // namespace aosr
