#include "aosr/ao/random.hpp"

#include <cmath>

namespace aosr {

std::uint64_t DeriveSeed(std::uint64_t master_seed, std::uint64_t stream) {
  // Two SplitMix64 rounds: the first mixes the master seed, the second the stream index added to it, so
  // DeriveSeed(a, b) and DeriveSeed(b, a) differ.
  auto mix = [](std::uint64_t z) {
    z += 0x9E3779B97F4A7C15ULL;
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
    return z ^ (z >> 31);
  };
  return mix(mix(master_seed) + stream);
}

double NormalGenerator::Next() {
  if (has_spare_) {
    has_spare_ = false;
    return spare_;
  }
  constexpr double kTwoPi = 6.283185307179586476925;
  constexpr double kInv53 = 1.0 / 9007199254740992.0;                       // 2^-53
  const double u1 = (static_cast<double>(engine_() >> 11) + 1.0) * kInv53;  // (0, 1]
  const double u2 = static_cast<double>(engine_() >> 11) * kInv53;          // [0, 1)
  const double r = std::sqrt(-2.0 * std::log(u1));
  spare_ = r * std::sin(kTwoPi * u2);
  has_spare_ = true;
  return r * std::cos(kTwoPi * u2);
}

void NormalGenerator::Fill(double* out, std::int64_t count) {
  for (std::int64_t i = 0; i < count; ++i) out[i] = Next();
}

}  // namespace aosr
