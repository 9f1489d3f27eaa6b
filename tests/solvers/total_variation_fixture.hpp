// Shared test data of the TV solver tests (unit and physics): Gaussian-PSF rasters, a piecewise-constant
// object and noisy problems with fixed seeds.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <memory>
#include <random>
#include <utility>
#include <vector>

#include "aosr/core/forward_model.hpp"
#include "aosr/core/operators.hpp"
#include "aosr/solvers/problem.hpp"
#include "solvers/tikhonov_fixture.hpp"  // test::GaussianKernel

namespace aosr::tv_test {


// N frames: one Gaussian PSF moved by the given HR-pixel offsets (a tip/tilt raster).
inline std::shared_ptr<const MultiFrameModel> RasterModel(
    Shape hr, int r, const std::vector<std::pair<double, double>>& shifts, double sigma) {
  const ComplexImage h = TransferFunction(hr, test::GaussianKernel(11, sigma));
  std::vector<ComplexImage> otfs;
  for (auto [dy, dx] : shifts) otfs.push_back(h * ShiftTransfer(hr, dy, dx));
  return std::make_shared<const MultiFrameModel>(hr, r, otfs);
}

// Piecewise-constant: two rectangles and a disc on a pedestal.
inline Image Blocks(Shape s) {
  Image x = Image::Constant(s.rows, s.cols, 0.2);
  for (Index y = 0; y < s.rows; ++y)
    for (Index c = 0; c < s.cols; ++c) {
      if (y >= s.rows / 8 && y < s.rows / 2 && c >= s.cols / 8 && c < s.cols / 2) x(y, c) = 1.0;
      if (y >= s.rows / 3 && y < 5 * s.rows / 6 && c >= 5 * s.cols / 8 && c < 7 * s.cols / 8) x(y, c) = 0.6;
      const double dy = y - 0.7 * s.rows, dx = c - 0.3 * s.cols;
      if (dy * dy + dx * dx < std::pow(s.rows / 7.0, 2)) x(y, c) = 0.0;
    }
  return x;
}

inline ReconstructionProblem NoisyProblem(std::shared_ptr<const MultiFrameModel> model, const Image& truth,
                                          double sigma, std::uint64_t seed) {
  ReconstructionProblem p;
  p.model = model;
  p.frames = model->Render(truth);
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> noise(0.0, sigma);
  for (Image& f : p.frames)
    for (Index i = 0; i < f.size(); ++i) f.data()[i] += noise(rng);
  return p;
}

inline double RelativeDifference(const Image& a, const Image& b) {
  return (a - b).matrix().norm() / std::max(a.matrix().norm(), b.matrix().norm());
}

// 32x32 HR, r = 2, a complete 2x2 raster with a Gaussian PSF, blocks + 2% noise: the small problem most
// tests use (about 0.1 ms per ADMM iteration).
inline ReconstructionProblem SmallProblem(std::uint64_t seed = 1) {
  const Shape hr{32, 32};
  return NoisyProblem(RasterModel(hr, 2, {{0, 0}, {0, 1}, {1, 0}, {1, 1}}, 1.0), Blocks(hr), 0.08, seed);
}

}  // namespace aosr::tv_test
