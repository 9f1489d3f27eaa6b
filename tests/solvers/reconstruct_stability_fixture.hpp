// Small problems for the reconstructors' stability tests (reconstruct_stability_test.cpp): Gaussian-PSF
// rasters on tiny grids, objects with and without content on the pixel box's blind frequencies, and the
// reference errors a reconstruction must beat.
#pragma once

#include <cmath>
#include <cstdint>
#include <memory>
#include <random>
#include <utility>
#include <vector>

#include "aosr/core/fft.hpp"
#include "aosr/core/forward_model.hpp"
#include "aosr/core/operators.hpp"
#include "aosr/solvers/reconstruct.hpp"
#include "solvers/total_variation_fixture.hpp"  // Blocks, and test::GaussianKernel

namespace aosr::stability_test {

using Shift = std::pair<double, double>;  // (dy, dx) in HR pixels

inline const std::vector<ReconstructionMethod>& AllMethods() {
  static const std::vector<ReconstructionMethod> m = {
      ReconstructionMethod::kShiftAddMean, ReconstructionMethod::kShiftAddMedian, ReconstructionMethod::kDrizzle,
      ReconstructionMethod::kTikhonov,     ReconstructionMethod::kTotalVariation, ReconstructionMethod::kMap};
  return m;
}


// N frames of one Gaussian PSF (sigma HR px) moved by the given HR-pixel shifts: a tip/tilt dither.
inline std::shared_ptr<const MultiFrameModel> Model(Shape hr, int r, const std::vector<Shift>& shifts,
                                                    double sigma) {
  const ComplexImage h = TransferFunction(hr, test::GaussianKernel(11, sigma));  // grids of >= 11 HR px
  std::vector<ComplexImage> otfs;
  for (auto [dy, dx] : shifts) otfs.push_back(h * ShiftTransfer(hr, dy, dx));
  return std::make_shared<const MultiFrameModel>(hr, r, otfs);
}

// The complete r x r raster of whole-HR-pixel shifts (N = r²): every sub-pixel phase once.
inline std::vector<Shift> FullRaster(int r) {
  std::vector<Shift> s;
  for (int y = 0; y < r; ++y)
    for (int x = 0; x < r; ++x) s.push_back({double(y), double(x)});
  return s;
}

// The classic 2 x 2 raster at half a camera pixel (r/2 HR px): N = 4, so N < r² for r > 2.
inline std::vector<Shift> HalfPixelRaster(int r) {
  const double h = 0.5 * r;
  return {{0, 0}, {0, h}, {h, 0}, {h, h}};
}

// A smooth object of order-one flux per HR pixel: a pedestal, three Gaussian blobs and a ramp.
inline Image SmoothObject(Shape s) {
  Image x(s.rows, s.cols);
  const double R = double(s.rows), C = double(s.cols);
  for (Index y = 0; y < s.rows; ++y)
    for (Index c = 0; c < s.cols; ++c) {
      const auto blob = [&](double cy, double cx, double w, double a) {
        const double dy = (y - cy * R) / w, dx = (c - cx * C) / w;
        return a * std::exp(-0.5 * (dy * dy + dx * dx));
      };
      x(y, c) = 0.2 + 0.3 * double(c) / C + blob(0.3, 0.3, 2.5, 1.0) + blob(0.65, 0.6, 3.5, 0.7) +
                blob(0.4, 0.75, 1.5, 0.8);
    }
  return x;
}

// Piecewise-constant: two rectangles and a dark disc on a pedestal (edges for TV).
using tv_test::Blocks;

// HR frequencies where the pixel box B vanishes (forward_model.hpp): f_a a non-zero multiple of m_a on
// either axis. No dither and no PSF can make them visible.
inline bool BlindFrequency(Shape hr, int r, Index fy, Index fx) {
  const Index my = hr.rows / r, mx = hr.cols / r;
  return (fy % my == 0 && fy != 0) || (fx % mx == 0 && fx != 0);
}
inline Index BlindFrequencyCount(Shape hr, int r) {
  return Index(r - 1) * hr.cols + Index(r - 1) * hr.rows - Index(r - 1) * (r - 1);
}

// x with its content on the blind frequencies removed: the part of any object that a full-rank design can
// recover exactly (the rest is invisible to every design).
inline Image WithoutBlindFrequencies(const Image& x, int r) {
  const Shape s = ShapeOf(x);
  ComplexImage X = FftForward(x.cast<Complex>());
  for (Index fy = 0; fy < s.rows; ++fy)
    for (Index fx = 0; fx < s.cols; ++fx)
      if (BlindFrequency(s, r, fy, fx)) X(fy, fx) = 0;
  return FftInverse(X).real();
}

inline ImageStack AddNoise(ImageStack frames, double sigma, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> n01;
  for (Image& f : frames)
    for (Index i = 0; i < f.size(); ++i) f.data()[i] += sigma * n01(rng);
  return frames;
}

inline ReconstructionProblem MakeProblem(std::shared_ptr<const MultiFrameModel> model, ImageStack frames,
                                         const std::vector<Shift>& shifts, ImageStack weights = {}) {
  ReconstructionProblem p;
  p.model = std::move(model);
  p.frames = std::move(frames);
  p.weights = std::move(weights);
  for (auto [dy, dx] : shifts) p.offsets.push_back({dy, dx});
  return p;
}

inline double Norm(const Image& x) { return x.matrix().norm(); }
inline double RelativeError(const Image& estimate, const Image& truth) {
  return Norm(estimate - truth) / Norm(truth);
}
// The error of the flat image at the truth's mean: what the gradient prior alone returns (λ → ∞ keeps
// only the data's DC). Any reconstructor worth running must beat it.
inline double FlatError(const Image& truth) {
  return Norm(truth - Image::Constant(truth.rows(), truth.cols(), truth.mean())) / Norm(truth);
}

// Reconstruct() with one method and otherwise the given options.
inline Reconstruction RunMethod(const ReconstructionProblem& p, ReconstructionMethod m, ReconstructOptions o = {}) {
  o.method = m;
  return Reconstruct(p, o);
}

}  // namespace aosr::stability_test
