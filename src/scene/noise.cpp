#include "aosr/scene/noise.hpp"

#include <cmath>

#include "aosr/ao/random.hpp"
#include "aosr/core/error.hpp"
#include "aosr/scene/detector.hpp"

namespace aosr {

// Both functions are the detector model's peak-fraction noise (detector.hpp, NoiseModel::kPeakFraction),
// kept under their original names for the demo.

double NoiseSigmaFromPeakFraction(const ImageStack& frames, double fraction) {
  CheckArgument(std::isfinite(fraction) && fraction >= 0, "NoiseSigmaFromPeakFraction", "fraction", fraction,
                "finite and >= 0");
  CheckArgument(!frames.empty(), "NoiseSigmaFromPeakFraction", "frames", "empty", "at least one frame");
  return PeakFractionSigma(frames, fraction);
}

void AddGaussianNoise(ImageStack* frames, double sigma, std::uint64_t seed) {
  CheckArgument(std::isfinite(sigma) && sigma >= 0, "AddGaussianNoise", "sigma", sigma, "finite and >= 0");
  CheckArgument(frames != nullptr, "AddGaussianNoise", "frames", "null", "a frame stack");
  if (sigma == 0) return;
  // One stream over the frames in order, as before.
  NormalGenerator rng(seed);
  for (Image& f : *frames) AddNormalNoise(&f, sigma, &rng);
}

}  // namespace aosr
