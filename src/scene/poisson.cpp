#include "aosr/scene/poisson.hpp"

#include <array>
#include <cmath>

namespace aosr {
namespace {

constexpr double kHalfLogTwoPi = 0.91893853320467274178;  // ½ ln(2π)
constexpr int kTableSize = 32;

// δ(k) = ln k! − (k ln k − k + ½ ln(2πk)) for 1 <= k < kTableSize, from exact sums of logs.
const std::array<double, kTableSize>& StirlingRemainderTable() {
  static const std::array<double, kTableSize> table = [] {
    std::array<double, kTableSize> t{};
    double log_factorial = 0;
    t[0] = 0;  // unused: k = 0 is handled separately
    for (int k = 1; k < kTableSize; ++k) {
      log_factorial += std::log(static_cast<double>(k));
      const double kd = k;
      t[k] = log_factorial - (kd * std::log(kd) - kd + 0.5 * std::log(kd) + kHalfLogTwoPi);
    }
    return t;
  }();
  return table;
}

double StirlingRemainder(double k) {
  if (k < kTableSize) return StirlingRemainderTable()[static_cast<int>(k)];
  const double inv = 1.0 / k, inv2 = inv * inv;
  return inv * (1.0 / 12 - inv2 * (1.0 / 360 - inv2 * (1.0 / 1260)));
}

}  // namespace

double PoissonLogPmf(double k, double mean) {
  if (k == 0) return -mean;
  const double d = (k - mean) / mean;
  // (1 + d) ln(1 + d) − d, with log1p for accuracy near d = 0.
  const double deviance = (1.0 + d) * std::log1p(d) - d;
  return -mean * deviance - 0.5 * std::log(k) - kHalfLogTwoPi - StirlingRemainder(k);
}

double PoissonGenerator::Uniform() {
  ++uniform_draws_;
  constexpr double kInv53 = 1.0 / 9007199254740992.0;  // 2^-53
  return (static_cast<double>(engine_() >> 11) + 0.5) * kInv53;
}

double PoissonGenerator::Next(double mean) {
  if (mean <= 0) return 0.0;
  return mean < kRejectionThreshold ? Inversion(mean) : Ptrs(mean);
}

double PoissonGenerator::Inversion(double mean) {
  // 1/k by table: the search's dependent chain is then multiply-add only (a division per step doubled the
  // cost at mean ~5).
  static const std::array<double, kInversionMaxK + 1> inverse = [] {
    std::array<double, kInversionMaxK + 1> t{};
    for (int k = 1; k <= kInversionMaxK; ++k) t[k] = 1.0 / k;
    return t;
  }();
  const double u = Uniform();
  if (mean != inversion_mean_) {  // e^(−λ) of the last mean: flat regions repeat it
    inversion_mean_ = mean;
    inversion_exp_ = std::exp(-mean);
  }
  double p = inversion_exp_;
  double cdf = p;
  int k = 0;
  // The guard only matters if rounding leaves the summed cdf just below u ~ 1 - 2^-54 (p(k) has underflowed
  // to 0 long before k = kInversionMaxK for mean < 10).
  while (u > cdf && k < kInversionMaxK) {
    ++k;
    p *= mean * inverse[k];
    cdf += p;
  }
  return k;
}

double PoissonGenerator::Ptrs(double mean) {
  // The set-up depends on the mean only; flat regions (sky, flat fields) repeat it pixel after pixel.
  if (mean != ptrs_mean_) {
    ptrs_mean_ = mean;
    ptrs_b_ = 0.931 + 2.53 * std::sqrt(mean);
    ptrs_a_ = -0.059 + 0.02483 * ptrs_b_;
    ptrs_inv_alpha_ = 1.1239 + 1.1328 / (ptrs_b_ - 3.4);
    ptrs_v_r_ = 0.9277 - 3.6224 / (ptrs_b_ - 2.0);
  }
  const double a = ptrs_a_, b = ptrs_b_, inv_alpha = ptrs_inv_alpha_, v_r = ptrs_v_r_;
  for (;;) {
    const double u = Uniform() - 0.5;  // (−½, ½)
    const double v = Uniform();        // (0, 1)
    const double us = 0.5 - std::fabs(u);
    const double k = std::floor((2.0 * a / us + b) * u + mean + 0.43);
    if (us >= 0.07 && v <= v_r) return k;
    if (k < 0 || (us < 0.013 && v > us)) continue;
    if (std::log(v * inv_alpha / (a / (us * us) + b)) <= PoissonLogPmf(k, mean)) return k;
  }
}

}  // namespace aosr
