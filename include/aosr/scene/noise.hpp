// Detector noise for the first scenes: additive white Gaussian noise at a stated level.
//
// The paper's convention (used by the demo) states the level as a fraction of the brightest noiseless
// pixel over all frames: sigma = fraction · max_i max(y_i). Photon and read noise, background,
// saturation and bad pixels belong to the full detector model of the scenes issue.
#pragma once

#include <cstdint>

#include "aosr/core/image.hpp"

namespace aosr {

// sigma = fraction · (largest pixel over all frames). fraction must be finite and >= 0.
double NoiseSigmaFromPeakFraction(const ImageStack& frames, double fraction);

// Adds N(0, sigma²) to every pixel of every frame, from a generator seeded with `seed` (deterministic
// across platforms for a given seed: std::mt19937_64 with a Box-Muller transform of our own, because
// std::normal_distribution's algorithm is implementation-defined). sigma must be finite and >= 0.
void AddGaussianNoise(ImageStack* frames, double sigma, std::uint64_t seed);

}  // namespace aosr
