// Shared by tiling_test.cpp and tiling_slow_test.cpp: a scene with edges, texture and stars, and fixed options.
#pragma once

#include <cmath>

#include "aosr/solvers/reconstruct.hpp"
#include "aosr/solvers/tiling.hpp"
#include "solvers/tikhonov_fixture.hpp"
#include "support/testing.hpp"

namespace aosr::test {

// Blocks, a smooth ramp and a few point sources on a sky: edges, texture and stars for every method.
inline Image Object(Shape s) {
  Image x = Image::Constant(s.rows, s.cols, 0.1);
  x.block(s.rows / 5, s.cols / 6, s.rows / 3, s.cols / 4) += 1.0;
  x.block(s.rows / 2, s.cols / 2, s.rows / 4, s.cols / 3) += 0.6;
  for (Index y = 0; y < s.rows; ++y)
    for (Index x0 = 0; x0 < s.cols; ++x0) x(y, x0) += 0.2 * std::sin(0.07 * double(y)) * std::cos(0.05 * double(x0));
  // The stars at the same fractions of any grid (at (20, 150), (131, 33) and (95, 97) on 192²).
  auto at = [](Index n, Index k) { return n * k / 192; };
  x(at(s.rows, 20), at(s.cols, 150)) += 4.0;
  x(at(s.rows, 131), at(s.cols, 33)) += 3.0;
  x(at(s.rows, 95), at(s.cols, 97)) += 2.0;
  return x;
}

// N = r² = 4 frames through one Gaussian PSF (σ = 1.5 HR px) moved by whole HR pixels (a compact kernel: the
// tiles cut nothing of it), frames with N(0, σ_n²) noise.
struct Scene {
  std::shared_ptr<const MultiFrameModel> model;
  Image truth;
  ReconstructionProblem problem;
};

inline Scene MakeScene(Shape hr = {192, 192}, int r = 2, double noise = 0.01) {
  Scene s;
  s.model = std::make_shared<const MultiFrameModel>(
      test::RasterModel(hr, r, {{0, 0}, {0, 1}, {1, 0}, {1, 1}}, 1.5));
  s.truth = Object(hr);
  s.problem.model = s.model;
  s.problem.frames = test::AddNoise(s.model->Render(s.truth), noise, 11);
  s.problem.offsets = {{0, 0}, {0, 1}, {1, 0}, {1, 1}};
  return s;
}

inline double MaxAbs(const Image& a) { return a.abs().maxCoeff(); }

inline ReconstructOptions Fixed(ReconstructionMethod m) {
  ReconstructOptions o;
  o.method = m;
  o.tikhonov.lambda_rule = TikhonovLambdaRule::kFixed;
  o.tikhonov.lambda = 1e-3;
  o.linear.noise_sigma = 0.01;
  return o;
}

}  // namespace aosr::test
