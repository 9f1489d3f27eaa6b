// Small models shared by the Tikhonov tests: one Gaussian PSF moved by HR-pixel offsets (the tip/tilt
// raster of a dithered sequence).
#pragma once

#include <cmath>
#include <cstdint>
#include <random>
#include <utility>
#include <vector>

#include "aosr/core/forward_model.hpp"
#include "aosr/core/operators.hpp"

namespace aosr::test {

// A centred, unit-sum Gaussian kernel of side n.
inline Image GaussianKernel(Index n, double sigma) {
  Image k(n, n);
  for (Index y = 0; y < n; ++y)
    for (Index x = 0; x < n; ++x) {
      const double dy = double(y - n / 2), dx = double(x - n / 2);
      k(y, x) = std::exp(-0.5 * (dy * dy + dx * dx) / (sigma * sigma));
    }
  return k / k.sum();
}

// N frames: one Gaussian PSF of width sigma (HR pixels), moved by the given HR-pixel offsets.
inline MultiFrameModel RasterModel(Shape hr, int r, const std::vector<std::pair<double, double>>& shifts,
                                   double sigma) {
  const ComplexImage h = TransferFunction(hr, GaussianKernel(11, sigma));
  std::vector<ComplexImage> otfs;
  for (auto [dy, dx] : shifts) otfs.push_back(h * ShiftTransfer(hr, dy, dx));
  return MultiFrameModel(hr, r, otfs);
}

// Adds N(0, sigma²) noise to every pixel (fixed seed).
inline ImageStack AddNoise(ImageStack frames, double sigma, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> n01;
  for (Image& f : frames)
    for (Index i = 0; i < f.size(); ++i) f.data()[i] += sigma * n01(rng);
  return frames;
}

}  // namespace aosr::test
