// Detector noise for the first scenes: additive white Gaussian noise at a stated level.
//
// The paper's convention (used by the demo) states the level as a fraction of the brightest noiseless
// pixel over all frames: sigma = fraction · max_i max(y_i). These are thin wrappers over the full detector
// model (detector.hpp: photon and read noise, background, saturation, bad pixels, and this Gaussian model as
// NoiseModel::kPeakFraction), whose PeakFractionSigma and AddNormalNoise they call.
#pragma once

#include <cstdint>

#include "aosr/core/image.hpp"

namespace aosr {

// sigma = fraction · (largest pixel over all frames). fraction must be finite and >= 0.
double NoiseSigmaFromPeakFraction(const ImageStack& frames, double fraction);

// Adds N(0, sigma²) to every pixel of every frame, from one NormalGenerator (ao/random.hpp) seeded with
// `seed` and run over the frames in order (deterministic across platforms for a given seed: std::mt19937_64
// with a Box-Muller transform of our own, because std::normal_distribution's algorithm is
// implementation-defined). sigma must be finite and >= 0.
void AddGaussianNoise(ImageStack* frames, double sigma, std::uint64_t seed);

}  // namespace aosr
