// Small synthetic star fields for the stars PSF tests: Gaussian stars on a sky, a 2 × 2 raster.
#pragma once

#include <cmath>
#include <random>
#include <utility>
#include <vector>

#include "aosr/core/forward_model.hpp"
#include "aosr/core/image.hpp"

namespace aosr::test {

struct StarFrames {
  ImageStack y, valid;
  std::vector<FrameOffset> offsets;
};

// 4 frames of 32² camera px (r = 2, a 2 × 2 raster of ±0.5 HR px) of Gaussian stars (σ = 1.2 HR px) at the
// given HR positions, flux `flux` e⁻, on a 100 e⁻ sky with Gaussian noise of variance 9 e⁻² + the signal (read and photon noise; seed 5). Pixels above
// `saturation` e⁻ are marked invalid. `fluxes`, when given, one per star instead of `flux`.
inline StarFrames MakeStarFrames(const std::vector<std::pair<double, double>>& stars, double flux,
                                 double saturation = 1e30, const std::vector<double>& fluxes = {}) {
  StarFrames f;
  std::mt19937_64 rng(5);
  std::normal_distribution<double> n01;
  const int r = 2, m = 32;
  for (auto [oy, ox] : std::vector<std::pair<double, double>>{{-0.5, -0.5}, {-0.5, 0.5}, {0.5, -0.5}, {0.5, 0.5}}) {
    Image hr = Image::Zero(m * r, m * r);
    for (std::size_t j = 0; j < stars.size(); ++j) {
      const auto [sy, sx] = stars[j];
      const double fj = fluxes.empty() ? flux : fluxes[j];
      for (Index y = 0; y < hr.rows(); ++y)
        for (Index x = 0; x < hr.cols(); ++x) {
          const double dy = double(y) - sy - oy, dx = double(x) - sx - ox;
          hr(y, x) += fj / (2 * M_PI * 1.44) * std::exp(-(dy * dy + dx * dx) / (2 * 1.44));
        }
    }
    Image y = Image::Zero(m, m), v = Image::Ones(m, m);
    for (Index a = 0; a < m; ++a)
      for (Index b = 0; b < m; ++b) {
        const double signal = hr.block(a * r, b * r, r, r).sum() + 100;
        y(a, b) = signal + std::sqrt(9 + signal) * n01(rng);
        if (y(a, b) > saturation) v(a, b) = 0;
      }
    f.y.push_back(y);
    f.valid.push_back(v);
    f.offsets.push_back({oy, ox});
  }
  return f;
}

}  // namespace aosr::test
