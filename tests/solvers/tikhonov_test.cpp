#include "aosr/solvers/tikhonov.hpp"

#include <gtest/gtest.h>

#include <limits>
#include <random>

#include "aosr/core/fft.hpp"
#include "aosr/core/operators.hpp"
#include "aosr/solvers/conjugate_gradient.hpp"
#include "support/testing.hpp"

namespace aosr {
namespace {

Image Random(Shape s, std::uint64_t seed) { return aosr::test::RandomImage(s, seed); }

Image Gaussian(Index n, double sigma) {
  Image k(n, n);
  for (Index y = 0; y < n; ++y)
    for (Index x = 0; x < n; ++x) {
      const double dy = y - n / 2, dx = x - n / 2;
      k(y, x) = std::exp(-0.5 * (dy * dy + dx * dx) / (sigma * sigma));
    }
  return k / k.sum();
}

// N frames: one PSF, moved by the given HR-pixel offsets (the tip/tilt raster).
MultiFrameModel RasterModel(Shape hr, int r, const std::vector<std::pair<double, double>>& shifts, double sigma) {
  const ComplexImage h = TransferFunction(hr, Gaussian(11, sigma));
  std::vector<ComplexImage> otfs;
  for (auto [dy, dx] : shifts) otfs.push_back(h * ShiftTransfer(hr, dy, dx));
  return MultiFrameModel(hr, r, otfs);
}

// The Fourier solution must be the minimiser of the spatial objective: check it against CG on
// (AᵀA + λΓᵀΓ) x = Aᵀy built from the very same operators.
TEST(TikhonovTest, FourierSolveMatchesSpatialNormalEquations) {
  for (TikhonovPrior prior : {TikhonovPrior::kIdentity, TikhonovPrior::kGradient, TikhonovPrior::kLaplacian})
    for (int r : {2, 3}) {
      const Shape hr{6 * r, 8 * r};
      const MultiFrameModel m = RasterModel(hr, r, {{0, 0}, {0.5, 1}, {1.3, 0.2}}, 1.1);
      const ImageStack y = m.Render(Random(hr, 4).abs());
      TikhonovOptions opt;
      opt.prior = prior;
      opt.lambda = 0.05;
      const Image x_fourier = TikhonovFourier(m, y, opt);
      const OperatorPtr gamma = TikhonovPriorOperator(hr, prior);
      const OperatorPtr normal = Sum({Normal(m.Operator()), Scale(opt.lambda, Normal(gamma))});
      Vector x = Vector::Zero(hr.size());
      ConjugateGradientOptions cg;
      cg.max_iterations = 5000;
      cg.tolerance = 1e-13;
      const SolverSummary s = ConjugateGradient(*normal, m.Operator()->ApplyAdjoint(m.Flatten(y)), &x, cg);
      ASSERT_EQ(s.termination, Termination::kConverged) << s.BriefReport();
      const double rel = (AsVector(x_fourier) - x).norm() / x.norm();
      EXPECT_LT(rel, 1e-8) << ToString(prior) << " r=" << r;
    }
}

// Noise-free, N = r² raster, λ -> 0: exact recovery of an object band-limited to the frequencies the
// model can invert; the others are reported, not filled.
TEST(TikhonovTest, ExactRecoveryOfInvertibleBandWithCompleteRaster) {
  const int r = 2;
  const Shape hr{32, 40};
  const MultiFrameModel m = RasterModel(hr, r, {{0, 0}, {0, 1}, {1, 0}, {1, 1}}, 0.9);
  const Shape lr = m.lr_shape();
  // Zero the object's spectrum in every bin whose system is rank deficient.
  ComplexImage X = FftForward(Random(hr, 8).cast<Complex>());
  Index deficient = 0;
  for (Index uy = 0; uy < lr.rows; ++uy)
    for (Index ux = 0; ux < lr.cols; ++ux) {
      const auto sv = Eigen::JacobiSVD<Eigen::MatrixXcd>(m.AliasedSystem(uy, ux)).singularValues();
      if (sv.minCoeff() < 1e-9 * sv.maxCoeff()) {
        ++deficient;
        for (int ky = 0; ky < r; ++ky)
          for (int kx = 0; kx < r; ++kx) X(uy + ky * lr.rows, ux + kx * lr.cols) = 0;
      }
    }
  ASSERT_GT(deficient, 0) << "the pixel box must make some bins singular (its zeros on the alias lattice)";
  const Image x = FftInverse(X).real();
  TikhonovOptions opt;
  opt.lambda = 0.0;
  TikhonovSummary s;
  const Image xr = TikhonovFourier(m, m.Render(x), opt, &s);
  EXPECT_LT((xr - x).matrix().norm() / x.matrix().norm(), 1e-8);
  EXPECT_EQ(s.rank_deficient_bins, deficient);
  EXPECT_GT(s.unconstrained_frequencies, 0);
  EXPECT_LT(s.unconstrained_frequencies, hr.size() / 4);
}

// With N < r² every bin is rank deficient: the report must say so.
TEST(TikhonovTest, ReportsUnconstrainedFrequenciesWhenFramesAreTooFew) {
  const int r = 2;
  const Shape hr{16, 16};
  const MultiFrameModel m = RasterModel(hr, r, {{0, 0}, {1, 1}}, 1.0);
  TikhonovOptions opt;
  opt.lambda = 1e-3;
  TikhonovSummary s;
  const Image xr = TikhonovFourier(m, m.Render(Random(hr, 2).abs()), opt, &s);
  EXPECT_TRUE(AllFinite(xr));
  EXPECT_EQ(s.rank_deficient_bins, s.lr_bins);
  EXPECT_GE(s.unconstrained_frequencies, 2 * s.lr_bins);
}

}  // namespace
}  // namespace aosr

namespace aosr {
namespace {

// GCV needs no noise level, yet its λ should give an error close to the best λ on the same grid
// (an oracle that knows the truth). Smooth object, 2% white noise, N = r² raster.
TEST(TikhonovTest, GcvChoosesALambdaNearTheOracle) {
  const int r = 2;
  const Shape hr{64, 64};
  const MultiFrameModel m = RasterModel(hr, r, {{0, 0}, {0, 1}, {1, 0}, {1, 1}}, 1.0);
  Image x(hr.rows, hr.cols);
  for (Index y = 0; y < hr.rows; ++y)
    for (Index c = 0; c < hr.cols; ++c) x(y, c) = 1.0 + std::sin(0.3 * y) * std::cos(0.21 * c) + ((y / 9 + c / 7) % 2);
  ImageStack frames = m.Render(x);
  std::mt19937_64 rng(17);
  std::normal_distribution<double> noise(0.0, 0.02 * 4.0);
  for (Image& f : frames)
    for (Index i = 0; i < f.size(); ++i) f.data()[i] += noise(rng);
  TikhonovOptions gcv;
  gcv.lambda_rule = TikhonovLambdaRule::kGcv;
  TikhonovSummary s;
  const double err_gcv = (TikhonovFourier(m, frames, gcv, &s) - x).matrix().norm();
  double err_best = std::numeric_limits<double>::infinity();
  for (double t = -8; t <= 0; t += 0.25) {
    TikhonovOptions fixed;
    fixed.lambda = s.lambda * std::pow(10.0, t + 4);
    err_best = std::min(err_best, (TikhonovFourier(m, frames, fixed) - x).matrix().norm());
  }
  EXPECT_GT(s.gcv, 0);
  EXPECT_LT(err_gcv, 1.25 * err_best) << "GCV lambda " << s.lambda;
}

}  // namespace
}  // namespace aosr
