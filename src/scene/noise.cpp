#include "aosr/scene/noise.hpp"

#include <cmath>
#include <random>

#include "aosr/core/error.hpp"

namespace aosr {

double NoiseSigmaFromPeakFraction(const ImageStack& frames, double fraction) {
  CheckArgument(std::isfinite(fraction) && fraction >= 0, "NoiseSigmaFromPeakFraction", "fraction", fraction,
                "finite and >= 0");
  CheckArgument(!frames.empty(), "NoiseSigmaFromPeakFraction", "frames", "empty", "at least one frame");
  double peak = 0;
  for (const Image& f : frames) peak = std::max(peak, f.maxCoeff());
  return fraction * peak;
}

void AddGaussianNoise(ImageStack* frames, double sigma, std::uint64_t seed) {
  CheckArgument(std::isfinite(sigma) && sigma >= 0, "AddGaussianNoise", "sigma", sigma, "finite and >= 0");
  CheckArgument(frames != nullptr, "AddGaussianNoise", "frames", "null", "a frame stack");
  if (sigma == 0) return;
  std::mt19937_64 rng(seed);
  // Uniform in (0, 1]: avoids log(0).
  auto uniform = [&rng] { return (double(rng() >> 11) + 1.0) * (1.0 / 9007199254740992.0); };
  for (Image& f : *frames)
    for (Index i = 0; i < f.size(); i += 2) {
      const double rad = sigma * std::sqrt(-2.0 * std::log(uniform()));
      const double ang = 2.0 * M_PI * uniform();
      f.data()[i] += rad * std::cos(ang);
      if (i + 1 < f.size()) f.data()[i + 1] += rad * std::sin(ang);
    }
}

}  // namespace aosr
