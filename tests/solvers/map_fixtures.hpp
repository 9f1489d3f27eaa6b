// Small problems shared by the MAP tests (map_test.cpp, map_physics_test.cpp, map_errors_test.cpp).
#pragma once

#include <cmath>
#include <memory>
#include <random>
#include <utility>
#include <vector>

#include "aosr/core/operators.hpp"
#include "aosr/solvers/problem.hpp"
#include "solvers/tikhonov_fixture.hpp"

namespace aosr::map_test {

using test::GaussianKernel;  // unit-sum, centred, sampled Gaussian PSF


// N frames: one Gaussian PSF moved by the given HR-pixel offsets (a tip/tilt raster).
inline std::shared_ptr<const MultiFrameModel> RasterModel(
    Shape hr, int r, const std::vector<std::pair<double, double>>& shifts, double sigma) {
  const ComplexImage h = TransferFunction(hr, GaussianKernel(11, sigma));
  std::vector<ComplexImage> otfs;
  for (auto [dy, dx] : shifts) otfs.push_back(h * ShiftTransfer(hr, dy, dx));
  return std::make_shared<const MultiFrameModel>(hr, r, otfs);
}

// The four-frame sub-pixel raster at r = 2 (offsets in HR pixels, not whole LR pixels).
inline std::shared_ptr<const MultiFrameModel> Raster4(Shape hr, double sigma = 1.0) {
  return RasterModel(hr, 2, {{0, 0}, {0, 1.1}, {0.9, 0}, {1.2, 0.8}}, sigma);
}

// A piecewise-constant object: level `sky` plus rectangles and a disc of heights ~ `amplitude`.
inline Image PiecewiseConstant(Shape s, double sky, double amplitude) {
  Image x = Image::Constant(s.rows, s.cols, sky);
  const double R = double(s.rows), C = double(s.cols);
  for (Index y = 0; y < s.rows; ++y)
    for (Index c = 0; c < s.cols; ++c) {
      const double fy = y / R, fx = c / C;
      if (fy > 0.15 && fy < 0.45 && fx > 0.1 && fx < 0.5) x(y, c) += amplitude;
      if (fy > 0.55 && fy < 0.85 && fx > 0.2 && fx < 0.35) x(y, c) += 0.6 * amplitude;
      const double dy = fy - 0.65, dx = fx - 0.7;
      if (dy * dy + dx * dx < 0.15 * 0.15) x(y, c) += 1.4 * amplitude;
    }
  return x;
}

// Frames of x plus N(0, sigma²) noise, fixed seed.
inline ImageStack NoisyFrames(const MultiFrameModel& m, const Image& x, double sigma, std::uint64_t seed) {
  ImageStack f = m.Render(x);
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> n(0.0, sigma);
  for (Image& im : f)
    for (Index i = 0; i < im.size(); ++i) im.data()[i] += n(rng);
  return f;
}

inline ReconstructionProblem MakeProblem(std::shared_ptr<const MultiFrameModel> m, ImageStack frames,
                                         ImageStack weights = {}) {
  ReconstructionProblem p;
  p.model = std::move(m);
  p.frames = std::move(frames);
  p.weights = std::move(weights);
  return p;
}

inline double Psnr(const Image& estimate, const Image& truth) {
  const double mse = (estimate - truth).square().mean();
  const double peak = truth.maxCoeff() - truth.minCoeff();
  return 10.0 * std::log10(peak * peak / mse);
}

inline double RelativeError(const Image& estimate, const Image& truth) {
  return (estimate - truth).matrix().norm() / truth.matrix().norm();
}

}  // namespace aosr::map_test
