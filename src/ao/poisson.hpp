// Internal: portable Poisson deviates for the detector noise of the wavefront sensors.
//
// std::poisson_distribution's algorithm is implementation-defined, so a seed would give different noise on
// libstdc++, libc++ and MSVC; here uniforms come from the top 53 bits of std::mt19937_64 (fully specified)
// and the deviates from two published algorithms:
//  * mean < 12: Knuth's multiplication method (D. E. Knuth, TAOCP vol. 2, 3.4.1): the count of uniforms
//    whose running product stays above exp(-mean); O(mean) uniforms.
//  * mean >= 12: Hörmann's transformed rejection with squeeze, PTRS (W. Hörmann, Insurance: Mathematics and
//    Economics 12, 39-45 (1993)), with the paper's constants; ~1.1 uniform pairs per deviate.
#pragma once

#include <cmath>
#include <cstdint>
#include <random>

namespace aosr {
namespace internal {

inline double Uniform01(std::mt19937_64& engine) {  // [0, 1)
  return static_cast<double>(engine() >> 11) * (1.0 / 9007199254740992.0);
}

inline double PoissonDeviate(std::mt19937_64& engine, double mean) {
  if (!(mean > 0.0)) return 0.0;
  if (mean < 12.0) {
    const double limit = std::exp(-mean);
    double product = 1.0 - Uniform01(engine);  // (0, 1]
    double k = 0.0;
    while (product > limit) {
      k += 1.0;
      product *= 1.0 - Uniform01(engine);
    }
    return k;
  }
  const double sq = std::sqrt(mean);
  const double log_mean = std::log(mean);
  const double b = 0.931 + 2.53 * sq;
  const double a = -0.059 + 0.02483 * b;
  const double inv_alpha = 1.1239 + 1.1328 / (b - 3.4);
  const double v_r = 0.9277 - 3.6224 / (b - 2.0);
  for (;;) {
    const double u = Uniform01(engine) - 0.5;
    const double v = Uniform01(engine);
    const double us = 0.5 - std::abs(u);
    const double k = std::floor((2.0 * a / us + b) * u + mean + 0.43);
    if (us >= 0.07 && v <= v_r) return k;
    if (k < 0.0 || (us < 0.013 && v > us)) continue;
    if (std::log(v) + std::log(inv_alpha) - std::log(a / (us * us) + b) <=
        -mean + k * log_mean - std::lgamma(k + 1.0)) {
      return k;
    }
  }
}

}  // namespace internal
}  // namespace aosr
