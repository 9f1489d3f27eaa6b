#include "aosr/solvers/tikhonov.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <limits>
#include <random>

#include "aosr/core/fft.hpp"
#include "aosr/core/parallel.hpp"
#include "aosr/core/operators.hpp"
#include "aosr/solvers/conjugate_gradient.hpp"
#include "aosr/solvers/problem.hpp"
#include "solvers/tikhonov_fixture.hpp"
#include "solvers/tikhonov_internal.hpp"  // the library's solvers/ folder (tests/CMakeLists.txt)
#include "support/testing.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

Image Random(Shape s, std::uint64_t seed) { return aosr::test::RandomImage(s, seed); }

using test::RasterModel;
using ::testing::HasSubstr;
using ::testing::Not;

// A test model: r, the frames' shifts (HR px) and the prior (the gradient prior unless given).
struct ModelCase {
  int r;
  std::vector<std::pair<double, double>> shifts;
  TikhonovPrior prior = TikhonovPrior::kGradient;
};

// The Fourier solution must be the minimiser of the spatial objective: check it against CG on
// (AᵀA + λΓᵀΓ) x = Aᵀy built from the very same operators.
TEST(TikhonovTest, FourierSolveMatchesSpatialNormalEquations) {
  for (TikhonovPrior prior : {TikhonovPrior::kIdentity, TikhonovPrior::kGradient, TikhonovPrior::kLaplacian,
                              TikhonovPrior::kPowerSpectrum})
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
  EXPECT_TRUE(s.unconstrained_counted) << "at lambda = 0 the minimum-norm solve makes the ranks: they are reported";
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
  opt.count_unconstrained = true;
  TikhonovSummary s;
  const Image frames_x = Random(hr, 2).abs();
  const Image xr = TikhonovFourier(m, m.Render(frames_x), opt, &s);
  EXPECT_TRUE(AllFinite(xr));
  EXPECT_TRUE(s.unconstrained_counted);
  EXPECT_EQ(s.rank_deficient_bins, s.lr_bins);
  EXPECT_GE(s.unconstrained_frequencies, 2 * s.lr_bins);
  EXPECT_THAT(s.message, HasSubstr("HR frequencies unconstrained by the data"));
  // Not asked for (the default) at λ > 0: not counted, and the summary says so; the image is the same bits.
  opt.count_unconstrained = false;
  TikhonovSummary quiet;
  const Image xq = TikhonovFourier(m, m.Render(frames_x), opt, &quiet);
  EXPECT_FALSE(quiet.unconstrained_counted);
  EXPECT_EQ(quiet.rank_deficient_bins, -1);
  EXPECT_EQ(quiet.unconstrained_frequencies, -1);
  EXPECT_THAT(quiet.message, Not(HasSubstr("unconstrained")));
  EXPECT_TRUE((xq == xr).all());
}

// The ranks made on request agree with each bin's JacobiSVD against the same floor (rank_tolerance x the largest
// singular value of all bins), for N < r², N = r² and N > r², with a prior that vanishes at the DC alias (whose
// bin a λ > 0 solve ranks by itself) and one that does not; and the counts are the same bits on 1, 2 and 3 threads.
TEST(TikhonovTest, RanksOnRequestAgreeWithTheSvdCounts) {
  using Case = ModelCase;
  const std::vector<Case> cases = {
      {2, {{0, 0}, {0.5, 0.5}}, TikhonovPrior::kGradient},
      {2, {{0, 0}, {0, 1}, {1, 0}, {1, 1}}, TikhonovPrior::kIdentity},
      {3, {{0, 0}, {0.4, 1.1}, {1.3, 0.2}, {2.1, 2.2}, {0.7, 1.9}, {1.6, 0.8}, {2.5, 1.4}, {0.2, 2.6}, {1.1, 1.7},
           {2.8, 0.5}, {0.9, 0.1}},
       TikhonovPrior::kLaplacian}};
  for (const Case& c : cases) {
    const Shape hr{12 * c.r, 8 * c.r};
    const MultiFrameModel m = RasterModel(hr, c.r, c.shifts, 0.9);
    const Shape lr = m.lr_shape();
    TikhonovOptions opt;
    opt.prior = c.prior;
    // The oracle: every bin's singular values by JacobiSVD, the floor from the largest of all.
    std::vector<Eigen::VectorXd> sv;
    double sv_max = 0;
    for (Index uy = 0; uy < lr.rows; ++uy)
      for (Index ux = 0; ux < lr.cols; ++ux) {
        sv.push_back(Eigen::JacobiSVD<Eigen::MatrixXcd>(m.AliasedSystem(uy, ux)).singularValues());
        sv_max = std::max(sv_max, sv.back().maxCoeff());
      }
    Index deficient = 0, unconstrained = 0;
    for (const Eigen::VectorXd& s : sv) {
      const Index rank = (s.array() > opt.rank_tolerance * sv_max).count();
      if (rank < c.r * c.r) ++deficient, unconstrained += c.r * c.r - rank;
    }
    ASSERT_GT(deficient, 0) << "r = " << c.r << ": the case must have rank-deficient bins";
    const ImageStack frames = m.Render(Random(hr, 5).abs());
    std::vector<Index> counts;
    for (int threads : {1, 2, 3}) {
      SetDefaultThreads(threads);
      tikhonov_internal::FourierSystem sys(m, tikhonov_internal::PriorSymbolImage(opt, hr), opt.rank_tolerance,
                                           TikhonovBinSolver::kAuto);
      sys.SetData(frames);
      sys.Solve(1e-3);  // a λ > 0 solve ranks at most the bins whose prior vanishes
      EXPECT_FALSE(sys.ranks_made());
      counts.push_back(sys.deficient_bins());
      counts.push_back(sys.unconstrained());
      EXPECT_TRUE(sys.ranks_made());
    }
    SetDefaultThreads(1);
    EXPECT_EQ(counts[0], deficient) << "r = " << c.r << ", N = " << c.shifts.size();
    EXPECT_EQ(counts[1], unconstrained) << "r = " << c.r << ", N = " << c.shifts.size();
    for (std::size_t k = 2; k < counts.size(); ++k) EXPECT_EQ(counts[k], counts[k % 2]);
  }
}

}  // namespace
}  // namespace aosr

namespace aosr {
namespace AOSR_TEST_NS {

// GCV needs no noise level, yet its λ should give an error close to the best λ on the same grid
// (an oracle that knows the truth). Smooth object, 2% white noise, N = r² raster.
TEST(TikhonovTest, GcvChoosesALambdaNearTheOracle) {
  const int r = 2;
  const Shape hr{64, 64};
  const MultiFrameModel m = RasterModel(hr, r, {{0, 0}, {0, 1}, {1, 0}, {1, 1}}, 1.0);
  Image x(hr.rows, hr.cols);
  for (Index y = 0; y < hr.rows; ++y)
    for (Index c = 0; c < hr.cols; ++c)
      x(y, c) = 1.0 + std::sin(0.3 * y) * std::cos(0.21 * c) + ((y / 9 + c / 7) % 2);
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

namespace aosr {
namespace AOSR_TEST_NS {

using test::RasterModel;

std::shared_ptr<const MultiFrameModel> Shared(MultiFrameModel m) {
  return std::make_shared<const MultiFrameModel>(std::move(m));
}

// Woodbury (N x N per bin) and the normal equations (r² x r² per bin) are the same solve: agreement to
// rounding for every prior, for N < r² with r = 2 and 3, for the image, the GCV score and the std map.
TEST(TikhonovTest, WoodburyMatchesTheNormalEquations) {
  for (int r : {2, 3})
    for (TikhonovPrior prior : {TikhonovPrior::kIdentity, TikhonovPrior::kGradient, TikhonovPrior::kLaplacian,
                                TikhonovPrior::kPowerSpectrum}) {
      const Shape hr{8 * r, 10 * r};
      const MultiFrameModel m = RasterModel(hr, r, {{0, 0}, {0.5, 1.25}, {1.3, 0.2}}, 1.0);  // N = 3 < r²
      ReconstructionProblem p;
      p.model = Shared(m);
      p.frames = test::AddNoise(m.Render(test::RandomImage(hr, 3).abs()), 0.01, 5);
      TikhonovOptions direct;
      direct.prior = prior;
      direct.lambda_rule = TikhonovLambdaRule::kGcv;
      direct.bin_solver = TikhonovBinSolver::kNormalEquations;
      direct.compute_std = true;
      direct.noise_sigma = 0.01;
      TikhonovOptions woodbury = direct;
      woodbury.bin_solver = TikhonovBinSolver::kAuto;  // N < r²: Woodbury wherever the bin allows it
      const TikhonovResult a = ReconstructTikhonov(p, direct);
      const TikhonovResult b = ReconstructTikhonov(p, woodbury);
      EXPECT_EQ(a.summary.woodbury_bins, 0);
      // Every bin but the DC bin of the gradient/Laplacian (whose prior is 0 there) takes Woodbury.
      EXPECT_GE(b.summary.woodbury_bins, b.summary.lr_bins - 1) << ToString(prior);
      EXPECT_EQ(a.summary.lambda, b.summary.lambda) << ToString(prior) << " r=" << r;
      // GCV's denominator n − tr H is small at small λ when N < r² (the data are nearly interpolated). The
      // normal equations get it as N − ||L⁻¹Aᴴ||², losing ~1e-10 to cancellation (checked against long
      // double: ~1e-10 vs ~1e-13 for Woodbury's w·tr K⁻¹), hence the looser tolerance on the score.
      EXPECT_NEAR(a.summary.gcv, b.summary.gcv, 1e-8 * a.summary.gcv) << ToString(prior) << " r=" << r;
      // The two paths are different factorisations of bins whose condition grows as λ shrinks (the
      // Laplacian's |Γ̂|⁴ makes its GCV λ the smallest): measured agreement 1e-13..1.2e-10, hence 1e-9.
      EXPECT_LT((a.image - b.image).matrix().norm() / a.image.matrix().norm(), 1e-9)
          << ToString(prior) << " r=" << r;
      ASSERT_TRUE(a.summary.std_computed && b.summary.std_computed);
      EXPECT_LT((a.posterior_std - b.posterior_std).abs().maxCoeff() / a.posterior_std.maxCoeff(), 1e-10);
    }
}

// Each prior's symbol is what its operator does: ||Γx||² = (1/M²) Σ_f |Γ̂(f)|² |X(f)|² (Parseval).
TEST(TikhonovTest, PriorSymbolsAreTheOperatorsSpectra) {
  const Shape hr{12, 18};
  const Image x = test::RandomImage(hr, 21);
  const ComplexImage X = FftForward(x.cast<Complex>());
  TikhonovOptions given;
  given.prior = TikhonovPrior::kPowerSpectrum;
  given.object_power_spectrum = Image(hr.rows, hr.cols);
  for (Index fy = 0; fy < hr.rows; ++fy)
    for (Index fx = 0; fx < hr.cols; ++fx) {
      const double vy = double(SignedFrequency(fy, hr.rows)), vx = double(SignedFrequency(fx, hr.cols));
      given.object_power_spectrum(fy, fx) = 1.0 / (1.0 + vy * vy + 0.5 * vx * vx);  // symmetric in f
    }
  std::vector<TikhonovOptions> cases(5);
  cases[0].prior = TikhonovPrior::kIdentity;
  cases[1].prior = TikhonovPrior::kGradient;
  cases[2].prior = TikhonovPrior::kLaplacian;
  cases[3].prior = TikhonovPrior::kPowerSpectrum;
  cases[3].spectrum_slope = 3.0;
  cases[3].spectrum_corner = 0.1;
  cases[4] = given;
  for (const TikhonovOptions& o : cases) {
    double spectral = 0;
    for (Index fy = 0; fy < hr.rows; ++fy)
      for (Index fx = 0; fx < hr.cols; ++fx)
        spectral += TikhonovPriorSymbol(o, hr, fy, fx) * std::norm(X(fy, fx));
    spectral /= double(hr.size());
    const double spatial = TikhonovPriorOperator(hr, o)->Apply(AsVector(x)).squaredNorm();
    EXPECT_NEAR(spatial, spectral, 1e-11 * spectral) << ToString(o.prior);
  }
  // The parametric spectrum: S(0) = 1, the power law beyond the corner, β = 0 is the identity.
  TikhonovOptions ps;
  ps.prior = TikhonovPrior::kPowerSpectrum;
  ps.spectrum_slope = 2.0;
  ps.spectrum_corner = 1.0 / 12.0;
  EXPECT_DOUBLE_EQ(TikhonovPriorSymbol(ps, hr, 0, 0), 1.0);
  EXPECT_NEAR(TikhonovPriorSymbol(ps, hr, 1, 0), 2.0, 1e-12);  // |f| = f₀: (1 + 1)^(β/2)
  ps.spectrum_slope = 0.0;
  EXPECT_DOUBLE_EQ(TikhonovPriorSymbol(ps, hr, 5, 7), 1.0);
}

// Each prior acts as its maths says on the reconstruction: identity shrinks towards 0 (a large λ gives
// x ≈ Aᵀy/λ), the gradient and Laplacian leave the mean alone (a constant is in their null space, the DC
// of the data decides it), and a power-spectrum prior of slope 0 is the identity prior.
TEST(TikhonovTest, EachPriorActsAsItsNullSpaceSays) {
  const int r = 2;
  const Shape hr{16, 20};
  const MultiFrameModel m = RasterModel(hr, r, {{0, 0}, {0, 1}, {1, 0}, {1, 1}}, 1.0);
  const Image truth = 3.0 + test::RandomImage(hr, 9, false);
  const ImageStack y = m.Render(truth);
  TikhonovOptions o;
  o.lambda = 1e6;
  for (TikhonovPrior prior : {TikhonovPrior::kGradient, TikhonovPrior::kLaplacian}) {
    o.prior = prior;
    const Image x = TikhonovFourier(m, y, o);
    EXPECT_NEAR(x.mean(), truth.mean(), 1e-9) << ToString(prior);     // the flux is kept
    EXPECT_LT(x.maxCoeff() - x.minCoeff(), 1e-3) << ToString(prior);  // and only the flux
  }
  o.prior = TikhonovPrior::kIdentity;
  const Image x_id = TikhonovFourier(m, y, o);
  const Vector aty = m.Operator()->ApplyAdjoint(m.Flatten(y));
  EXPECT_LT((AsVector(x_id) - aty / o.lambda).norm() / (aty / o.lambda).norm(), 1e-4);
  o.lambda = 0.3;
  const Image a = TikhonovFourier(m, y, o);
  o.prior = TikhonovPrior::kPowerSpectrum;
  o.spectrum_slope = 0.0;
  const Image b = TikhonovFourier(m, y, o);
  EXPECT_LT((a - b).abs().maxCoeff(), 1e-12 * a.abs().maxCoeff());
}

// Uniform weights w₀ are a rescaling of the objective: the solution at λ is the unweighted one at λ/w₀.
TEST(TikhonovTest, UniformWeightsRescaleLambda) {
  const int r = 2;
  const Shape hr{16, 16};
  const MultiFrameModel m = RasterModel(hr, r, {{0, 0}, {0.5, 1}, {1, 0.3}}, 1.0);
  ReconstructionProblem p;
  p.model = Shared(m);
  p.frames = m.Render(test::RandomImage(hr, 2));
  p.weights = ImageStack(3, Image::Constant(8, 8, 4.0));
  TikhonovOptions o;
  o.lambda = 0.2;
  const TikhonovResult weighted = ReconstructTikhonov(p, o);
  EXPECT_EQ(weighted.summary.method, "tikhonov-fourier");
  o.lambda = 0.05;
  const Image plain = TikhonovFourier(m, p.frames, o);
  EXPECT_LT((weighted.image - plain).matrix().norm() / plain.matrix().norm(), 1e-12);
  EXPECT_DOUBLE_EQ(weighted.summary.lambda, 0.2);
}

// The discrepancy principle returns the λ at which Σ w (y − A x_λ)² = τ σ² n_w, and with τ = 1 that λ is a
// sensible one: its error within 1.5x of the best λ's for this truth (an oracle that knows it).
TEST(TikhonovTest, DiscrepancyLambdaHitsTheTargetResidual) {
  const int r = 2;
  const Shape hr{48, 48};
  const MultiFrameModel m = RasterModel(hr, r, {{0, 0}, {0, 1}, {1, 0}, {1, 1}, {0.5, 0.5}}, 1.0);
  Image x(hr.rows, hr.cols);
  for (Index yy = 0; yy < hr.rows; ++yy)
    for (Index c = 0; c < hr.cols; ++c)
      x(yy, c) = 1.0 + std::sin(0.3 * yy) * std::cos(0.21 * c) + ((yy / 9 + c / 7) % 2);
  const double sigma = 0.05;
  ReconstructionProblem p;
  p.model = Shared(m);
  p.frames = test::AddNoise(m.Render(x), sigma, 31);
  for (double tau : {1.0, 1.5}) {
    TikhonovOptions o;
    o.lambda_rule = TikhonovLambdaRule::kDiscrepancy;
    o.noise_sigma = sigma;
    o.discrepancy_factor = tau;
    const TikhonovResult res = ReconstructTikhonov(p, o);
    const double target = tau * sigma * sigma * 5 * 24 * 24;
    EXPECT_EQ(res.summary.termination, Termination::kConverged) << res.summary.BriefReport();
    EXPECT_DOUBLE_EQ(res.summary.discrepancy_target, target);
    EXPECT_NEAR(res.summary.weighted_residual, target, 1e-4 * target) << res.summary.BriefReport();
    // The same figure recomputed from the returned image through the spatial operator.
    const Vector resid = m.Operator()->Apply(AsVector(res.image)) - m.Flatten(p.frames);
    EXPECT_NEAR(resid.squaredNorm(), target, 1.01e-4 * target);
    EXPECT_LT(res.summary.lambda_evaluations, 20);
    // Against the oracle λ (the truth known) on a grid of quarter decades around it.
    double err_best = std::numeric_limits<double>::infinity(), lambda_best = 0;
    for (double t = -3; t <= 3; t += 0.25) {
      TikhonovOptions fixed;
      fixed.lambda = res.summary.lambda * std::pow(10.0, t);
      const double e = (TikhonovFourier(m, p.frames, fixed) - x).matrix().norm();
      if (e < err_best) err_best = e, lambda_best = fixed.lambda;
    }
    const double err = (res.image - x).matrix().norm();
    std::printf(
        "discrepancy tau=%.1f: lambda %.4g after %d evaluations, residual/target - 1 = %.2e; error %.4g "
        "vs oracle %.4g at lambda %.4g\n",
        tau, res.summary.lambda, res.summary.lambda_evaluations, resid.squaredNorm() / target - 1, err,
        err_best, lambda_best);
    if (tau == 1.0) {
      EXPECT_LT(err, 1.5 * err_best);
    }
  }
  // An unreachable target (σ far too large: even x = const leaves less residual) is reported, not thrown.
  TikhonovOptions o;
  o.lambda_rule = TikhonovLambdaRule::kDiscrepancy;
  o.noise_sigma = 100.0;
  const TikhonovResult res = ReconstructTikhonov(p, o);
  EXPECT_EQ(res.summary.termination, Termination::kFailed);
  EXPECT_NE(res.summary.message.find("not met"), std::string::npos) << res.summary.message;
  EXPECT_TRUE(AllFinite(res.image));
}

// The std map is exactly √diag(σ²(AᵀWA + λΓᵀΓ)⁻¹): check against a dense inverse of the spatial normal
// matrix on tiny grids (r = 2 and 3, N below and above r², uniform weight 2), and its period r.
TEST(TikhonovTest, PosteriorStdIsTheDiagonalOfTheDenseInverse) {
  using Case = ModelCase;
  const std::vector<Case> cases = {
      {2, {{0, 0}, {0.5, 1.3}}, TikhonovPrior::kGradient},
      {2, {{0, 0}, {0, 1}, {1, 0}, {1, 1}, {0.5, 0.2}}, TikhonovPrior::kIdentity},
      {3, {{0, 0}, {1.2, 0.4}, {2, 2.5}}, TikhonovPrior::kLaplacian},
      {3, {{0, 0}, {1.2, 0.4}, {2, 2.5}, {0.3, 1.7}}, TikhonovPrior::kPowerSpectrum}};
  for (const Case& c : cases) {
    const Shape hr{6 * c.r, 7 * c.r};
    const MultiFrameModel m = RasterModel(hr, c.r, c.shifts, 0.9);
    const double w0 = 2.0, sigma = 0.3, lambda = 0.07;
    ReconstructionProblem p;
    p.model = Shared(m);
    p.frames = m.Render(test::RandomImage(hr, 1));
    p.weights = ImageStack(c.shifts.size(), Image::Constant(6, 7, w0));
    TikhonovOptions o;
    o.prior = c.prior;
    o.lambda = lambda;
    o.compute_std = true;
    o.noise_sigma = sigma;
    const TikhonovResult res = ReconstructTikhonov(p, o);
    ASSERT_TRUE(res.summary.std_computed) << res.summary.message;
    // Dense Q = w₀AᵀA + λΓᵀΓ, column by column.
    const OperatorPtr q =
        Sum({Scale(w0, Normal(m.Operator())), Scale(lambda, Normal(TikhonovPriorOperator(hr, o)))});
    Eigen::MatrixXd dense(hr.size(), hr.size());
    for (Index j = 0; j < hr.size(); ++j) dense.col(j) = q->Apply(Vector::Unit(hr.size(), j));
    const Eigen::MatrixXd cov =
        sigma * sigma * dense.ldlt().solve(Eigen::MatrixXd::Identity(hr.size(), hr.size()));
    double worst = 0;
    for (Index j = 0; j < hr.size(); ++j) {
      const double s = res.posterior_std(j / hr.cols, j % hr.cols);
      worst = std::max(worst, std::abs(s * s - cov(j, j)) / cov(j, j));
    }
    EXPECT_LT(worst, 1e-10) << "r=" << c.r << " N=" << c.shifts.size() << " " << ToString(c.prior);
    EXPECT_NEAR(res.summary.mean_posterior_variance, cov.trace() / double(hr.size()), 1e-10 * cov.trace());
    // Period r: the dense diagonal itself repeats every camera pixel.
    for (Index j = 0; j < hr.size(); ++j) {
      const Index y = j / hr.cols, x = j % hr.cols;
      const Index j0 = (y % c.r) * hr.cols + (x % c.r);
      EXPECT_NEAR(cov(j, j), cov(j0, j0), 1e-10 * cov(j0, j0));
    }
  }
}

// λ = 0 with too few frames: the posterior is improper and no map is returned, said in the summary.
TEST(TikhonovTest, NoStdMapWhenThePosteriorIsImproper) {
  const Shape hr{16, 16};
  const MultiFrameModel m = RasterModel(hr, 2, {{0, 0}, {1, 1}}, 1.0);
  ReconstructionProblem p;
  p.model = Shared(m);
  p.frames = m.Render(test::RandomImage(hr, 2));
  TikhonovOptions o;
  o.lambda = 0;
  o.compute_std = true;
  o.noise_sigma = 1;
  const TikhonovResult res = ReconstructTikhonov(p, o);
  EXPECT_FALSE(res.summary.std_computed);
  EXPECT_EQ(res.posterior_std.size(), 0);
  EXPECT_NE(res.summary.message.find("improper"), std::string::npos) << res.summary.message;
}

// Frames of pure noise: the best estimate is the prior's (λ → ∞), so GCV's score keeps falling past the top of
// its initial grid. The search walks on upwards (gcv_decades more) instead of stopping at λ₀, and says the
// result is a bound.
TEST(TikhonovTest, GcvWalksUpwardsPastTheTopOfItsGrid) {
  const Shape hr{24, 24};
  const MultiFrameModel m = RasterModel(hr, 2, {{0, 0}, {1, 1}}, 1.0);
  ReconstructionProblem p;
  p.model = std::make_shared<const MultiFrameModel>(m);
  p.frames = test::AddNoise(m.Render(Image::Zero(24, 24)), 1.0, 3);
  TikhonovOptions o;
  o.lambda_rule = TikhonovLambdaRule::kGcv;
  o.gcv_decades = 2;
  o.gcv_steps_per_decade = 2;
  const TikhonovResult r = ReconstructTikhonov(p, o);
  EXPECT_GT(r.summary.lambda_evaluations, 5) << r.summary.message;  // more than the initial 5 grid points
  EXPECT_NE(r.summary.message.find("largest"), std::string::npos) << r.summary.message;
  EXPECT_TRUE(AllFinite(r.image));
}

}  // namespace
}  // namespace aosr

// ---- λ rules in closed form (issue 15): FourierSystem::EvaluateSpectral --------------------------------------

namespace aosr {
namespace AOSR_TEST_NS {

using tikhonov_internal::FourierSystem;
using tikhonov_internal::PriorSymbolImage;

// The prior's symbol image (built once per tile of a whole detector, the parametric spectrum's quarter mirrored)
// is the per-frequency symbol to the bit, on even and odd grids, for every prior and spectrum slope.
TEST(TikhonovTest, PriorSymbolImageIsThePerFrequencySymbolToTheBit) {
  for (const Shape hr : {Shape{12, 16}, Shape{13, 7}, Shape{1, 9}, Shape{10, 1}})
    for (TikhonovPrior prior : {TikhonovPrior::kIdentity, TikhonovPrior::kGradient, TikhonovPrior::kLaplacian,
                                TikhonovPrior::kPowerSpectrum, TikhonovPrior::kFitted})
      for (double slope : {2.0, 3.1}) {
        TikhonovOptions o;
        o.prior = prior;
        o.spectrum_slope = slope;
        o.spectrum_corner = 0.07;
        const Image p = PriorSymbolImage(o, hr);
        ASSERT_EQ(ShapeOf(p), hr);
        for (Index fy = 0; fy < hr.rows; ++fy)
          for (Index fx = 0; fx < hr.cols; ++fx)
            ASSERT_EQ(p(fy, fx), TikhonovPriorSymbol(o, hr, fy, fx))
                << ToString(prior) << ", slope " << slope << ", " << ToString(hr) << " at " << fy << ", " << fx;
      }
  // A measured spectrum need not be symmetric: it is read per frequency.
  TikhonovOptions o;
  o.prior = TikhonovPrior::kPowerSpectrum;
  o.object_power_spectrum = test::RandomImage({6, 5}, 3).abs() + 0.5;
  const Image p = PriorSymbolImage(o, {6, 5});
  for (Index fy = 0; fy < 6; ++fy)
    for (Index fx = 0; fx < 5; ++fx) EXPECT_EQ(p(fy, fx), 1.0 / o.object_power_spectrum(fy, fx));
}

// The spectral residual and trace (one SVD per bin, then sums over singular values) are the per-bin solves'
// to rounding, for every prior (the DC bin of the gradient/Laplacian is solved directly), for N < r², N = r²
// and N > r², over twelve decades of λ, and with rank-deficient bins (two identical frames).
TEST(TikhonovTest, SpectralEvaluationMatchesThePerBinSolves) {
  using Case = ModelCase;
  const std::vector<Case> cases = {{2, {{0, 0}, {0.5, 1.25}, {1.3, 0.2}}},                  // N = 3 < 4
                                   {2, {{0, 0}, {0, 1}, {1, 0}, {1, 1}}},                    // N = r²
                                   {2, {{0, 0}, {0, 1}, {1, 0}, {1, 1}, {0.5, 0.5}, {0.3, 1.7}}},  // N > r²
                                   {3, {{0, 0}, {0, 0}, {1.5, 0.5}}},                        // duplicate frames
                                   {4, {{0, 0}, {1.5, 2.5}}}};
  for (const Case& c : cases)
    for (TikhonovPrior prior : {TikhonovPrior::kIdentity, TikhonovPrior::kGradient, TikhonovPrior::kLaplacian,
                                TikhonovPrior::kPowerSpectrum}) {
      const Shape hr{6 * c.r, 8 * c.r};
      const MultiFrameModel m = RasterModel(hr, c.r, c.shifts, 1.0);
      TikhonovOptions o;
      o.prior = prior;
      FourierSystem sys(m, PriorSymbolImage(o, hr), o.rank_tolerance, TikhonovBinSolver::kAuto);
      sys.SetData(test::AddNoise(m.Render(test::RandomImage(hr, 9).abs()), 0.02, 4));
      for (double t = -8; t <= 4; t += 1) {
        const double lambda = sys.lambda0() * std::pow(10.0, t);
        const FourierSystem::Fit solved = sys.Evaluate(lambda, true), spectral = sys.EvaluateSpectral(lambda);
        const std::string what = std::string(ToString(prior)) + ", r = " + std::to_string(c.r) + ", N = " +
                                 std::to_string(c.shifts.size()) + ", log10(λ/λ0) = " + std::to_string(t);
        // Both forms lose the small singular values of the whitened bins to rounding at the scale of the
        // largest (ε s_max² absolutely, with s_max² ≳ λ₀), and each term w / (s² + w), like the solves' K⁻¹,
        // turns that into an error of about ε s_max² / w: measured at λ = 1e-8 λ₀ up to 1e-13 (λ₀/λ) per bin
        // in the trace (N < r², Laplacian and power-spectrum priors) and 7e-15 (λ₀/λ) relative in the residual
        // (Laplacian, r = 3 with two identical frames, whose rank-deficient bins make the solves' K nearly
        // singular). The tolerances are about 10x that; at λ >= λ₀ they are 1e-9 and 1e-8 relative.
        const double amplification = 1.0 / std::pow(10.0, std::min(t, 0.0));
        EXPECT_NEAR(spectral.residual2, solved.residual2, (1e-9 + 1e-13 * amplification) * solved.residual2 + 1e-14)
            << what;
        EXPECT_NEAR(spectral.dof, solved.dof, 1e-8 * solved.dof + 2e-12 * double(sys.bins()) * amplification) << what;
      }
    }
}

// The allocation-free per-bin kernels of FourierSystem::Solve (Woodbury N x N where N < r², normal equations
// otherwise, one bin per mirror pair) give the dense Eigen path's solution: x = G⁻¹ Aᵀy with G⁻¹ from
// Inverses (InverseBin, the old per-bin path), over twelve decades of λ including ill-conditioned bins, and
// the same residual as Evaluate. Also bit-identical for 1 and 2 threads.
TEST(TikhonovTest, FastBinKernelsAgreeWithTheDensePath) {
  using Case = ModelCase;
  const std::vector<Case> cases = {{2, {{0, 0}, {0.5, 1.25}, {1.3, 0.2}}},
                                   {2, {{0, 0}, {0, 1}, {1, 0}, {1, 1}, {0.5, 0.5}}},
                                   {3, {{0, 0}, {0, 0}, {1.5, 0.5}}},
                                   {4, {{0, 0}, {1.5, 2.5}}},
                                   {8, {{0, 0}, {2.5, 1.5}, {5.5, 4.5}, {1, 6}}}};
  for (const Case& c : cases)
    for (TikhonovPrior prior : {TikhonovPrior::kIdentity, TikhonovPrior::kGradient, TikhonovPrior::kPowerSpectrum}) {
      const Shape hr{c.r * (16 / c.r + 1), c.r * (24 / c.r + 1)};  // room for the PSF kernel
      const MultiFrameModel m = RasterModel(hr, c.r, c.shifts, 1.0);
      TikhonovOptions o;
      o.prior = prior;
      FourierSystem sys(m, PriorSymbolImage(o, hr), o.rank_tolerance, TikhonovBinSolver::kAuto);
      const ImageStack frames = test::AddNoise(m.Render(test::RandomImage(hr, 9).abs()), 0.02, 4);
      sys.SetData(frames);
      const Vector aty = m.Operator()->ApplyAdjoint(m.Flatten(frames));
      for (double t : {-8.0, -4.0, 0.0, 4.0}) {
        const double lambda = sys.lambda0() * std::pow(10.0, t);
        bool proper = true;
        const Vector reference =
            tikhonov_internal::FourierInverseOperator(hr, c.r, sys.Inverses(lambda, &proper, nullptr), 1.0)->Apply(aty);
        if (!proper) continue;  // a singular bin: the pseudo-inverse and the minimum-norm solve differ by design
        FourierSystem::Fit fit;
        const Image x = sys.Solve(lambda, &fit);
        const std::string what = std::string(ToString(prior)) + ", r = " + std::to_string(c.r) + ", N = " +
                                 std::to_string(c.shifts.size()) + ", log10(λ/λ0) = " + std::to_string(t);
        // The oracle is the normal equations (AᵀA + λΓᵀΓ) x = Aᵀy in the spatial operators: the fast kernels'
        // residual is at rounding level, and no worse than the dense path's (whose explicit inverse loses
        // digits at small λ: its error there is ~ε s_max² / w).
        const OperatorPtr normal = Sum({Normal(m.Operator()), Scale(lambda, Normal(TikhonovPriorOperator(hr, o)))});
        const double res = (normal->Apply(AsVector(x)) - aty).norm() / aty.norm();
        const double res_reference = (normal->Apply(reference) - aty).norm() / aty.norm();
        EXPECT_LT(res, std::max(1e-11, 2 * res_reference)) << what << " (dense path: " << res_reference << ")";
        if (t >= 0) {
          EXPECT_LT((AsVector(x) - reference).norm(), 1e-10 * reference.norm()) << what;
        }
        // The residual nearly cancels at tiny λ (the data are almost fitted): 1e-9 relative, 1e-7 at 1e-8 λ₀.
        EXPECT_NEAR(fit.residual2, sys.Evaluate(lambda, false).residual2,
                    (t >= -4 ? 1e-9 : 1e-7) * fit.residual2 + 1e-14) << what;
      }
    }
  const MultiFrameModel m = RasterModel({32, 48}, 4, {{0, 0}, {1.5, 2.5}, {0.5, 3}}, 1.0);
  TikhonovOptions o;
  FourierSystem sys(m, PriorSymbolImage(o, {32, 48}), o.rank_tolerance, TikhonovBinSolver::kAuto);
  sys.SetData(m.Render(test::RandomImage({32, 48}, 2)));
  const int saved = DefaultThreads();
  SetDefaultThreads(1);
  const Image one = sys.Solve(sys.lambda0() * 1e-3);
  SetDefaultThreads(2);
  const Image two = sys.Solve(sys.lambda0() * 1e-3);
  SetDefaultThreads(saved);
  EXPECT_TRUE((one == two).all());
}

// GCV's continuous search finds the minimum a fine grid finds: its score is no higher than the best of 2001
// points over ±1 decade around it, and its λ lies within one fine step (1e-3 decades) of the fine grid's best.
TEST(TikhonovTest, GcvContinuousOptimumAgreesWithAFineGrid) {
  for (TikhonovPrior prior : {TikhonovPrior::kIdentity, TikhonovPrior::kGradient, TikhonovPrior::kPowerSpectrum})
    for (int r : {2, 4}) {
      const Shape hr{16 * r, 16 * r};
      const MultiFrameModel m = RasterModel(hr, r, {{0, 0}, {0.5, 1.5}, {1.5, 0.5}, {1, 1}}, 1.2);
      ReconstructionProblem p;
      p.model = std::make_shared<const MultiFrameModel>(m);
      p.frames = test::AddNoise(m.Render(test::RandomImage(hr, 7).abs() + 1.0), 0.05, 8);
      TikhonovOptions o;
      o.prior = prior;
      o.lambda_rule = TikhonovLambdaRule::kGcv;
      const TikhonovResult res = ReconstructTikhonov(p, o);
      ASSERT_EQ(res.summary.message.find("bound"), std::string::npos) << res.summary.message;
      FourierSystem sys(m, PriorSymbolImage(o, hr), o.rank_tolerance, TikhonovBinSolver::kAuto);
      sys.SetData(p.frames);
      const double n = double(m.frames()) * double(sys.bins());
      auto gcv = [&](double lambda) {
        const FourierSystem::Fit f = sys.EvaluateSpectral(lambda);
        return n * f.residual2 / (f.dof * f.dof);
      };
      double best = std::numeric_limits<double>::infinity(), best_t = 0;
      for (int k = -1000; k <= 1000; ++k) {
        const double t = 1e-3 * k, g = gcv(res.summary.lambda * std::pow(10.0, t));
        if (g < best) best = g, best_t = t;
      }
      const std::string what = std::string(ToString(prior)) + ", r = " + std::to_string(r);
      EXPECT_LE(res.summary.gcv, best * (1 + 1e-12)) << what;
      EXPECT_LE(std::abs(best_t), 1e-3 + 1e-12) << what << ": the fine grid's best is " << best_t << " decades away";
      EXPECT_NEAR(gcv(res.summary.lambda), res.summary.gcv, 1e-12 * res.summary.gcv) << what;
    }
}

}  // namespace
}  // namespace aosr

// ---- issue 22: the λ search without a per-bin SVD ---------------------------------------------------------------

#include "solvers/bin_kernels.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

using tikhonov_internal::FourierSystem;
using tikhonov_internal::PriorSymbolImage;

// The allocation-free Hermitian eigen-solver of the per-bin passes: eigenvalues to a few ε ||M|| of Eigen's,
// orthonormal eigenvectors and M U = U diag(d) to rounding, at every size the bins use (1 .. 16), on random Gram
// matrices with a dominant column, with duplicate rows (singular) and the zero matrix.
TEST(TikhonovTest, HermitianEigenSolverIsExactToRounding) {
  std::mt19937_64 rng(5);
  std::normal_distribution<double> n01;
  for (int n : {1, 2, 3, 4, 8, 9, 16})
    for (int variant = 0; variant < 4; ++variant) {
      Eigen::MatrixXcd b(n, 2 * n + 1);
      for (Index i = 0; i < b.size(); ++i) b.data()[i] = Complex(n01(rng), n01(rng));
      if (variant == 1) b.col(0) *= 1e6;
      if (variant == 2 && n > 1) b.row(1) = b.row(0);
      if (variant == 3) b.setZero();
      const Eigen::MatrixXcd m = b * b.adjoint();
      std::vector<Complex> a(n * n), u(n * n);
      std::vector<double> d(n), work(3 * n * n + 2 * n);
      for (int i = 0; i < n; ++i)
        for (int j = 0; j < n; ++j) a[i * n + j] = m(i, j);
      ASSERT_TRUE(bins::HermitianEigen(a.data(), n, d.data(), u.data(), work.data()));
      const Eigen::Map<const Eigen::Matrix<Complex, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>> U(u.data(), n, n);
      const Eigen::Map<const Eigen::VectorXd> D(d.data(), n);
      const Eigen::VectorXd reference = Eigen::SelfAdjointEigenSolver<Eigen::MatrixXcd>(m).eigenvalues();
      const double scale = std::max(1.0, m.norm());
      const std::string what = "n = " + std::to_string(n) + ", variant " + std::to_string(variant);
      EXPECT_LT((D - reference).cwiseAbs().maxCoeff(), 1e-14 * scale) << what;
      EXPECT_LT((U.adjoint() * U - Eigen::MatrixXcd::Identity(n, n)).norm(), 1e-13) << what;
      EXPECT_LT((m * U - U * D.asDiagonal()).norm(), 1e-14 * scale) << what;
      for (int k = 1; k < n; ++k) EXPECT_LE(d[k - 1], d[k]) << what;
    }
}

// The λ rules' per-bin kernel (Householder bidiagonalisation and implicit QR sweeps, Uᴴy without U; the closed form
// of two rows; the LQ reduction first of a much wider matrix) against Eigen's JacobiSVD with the full U, at the
// shapes the bins use (p x k with p, k in 1 .. 16: wide, square and tall; and k = 64, r = 8's), on
// random matrices, with graded columns (σ from 1 down to ~1e-20, as aliases beyond the optical cutoff give), with a
// duplicate row (an exact zero σ), with one dominant column and the zero matrix: every σ within 1e-14 σ_max of the
// SVD's (an SVD's accuracy: absolute, so σ² to ~ε σ_max σ), the residual Σ (w/(σ² + w))² |uᴴy|² + perp and the trace
// Σ w/(σ² + w) within 1e-11 of the SVD's for w >= 1e-8 σ_max² (σ² errors of ε σ_max σ move w/(σ² + w) by at most
// ~ε σ_max/√w <= 1e4 ε there), and Σ |uᴴy|² + perp = ||y||² to rounding; two matrices at once give the same bits
// as each alone. Non-finite input is refused (alone, or beside a good matrix, which is not disturbed).
TEST(TikhonovTest, SingularSpectrumMatchesAnSvd) {
  std::mt19937_64 rng(11);
  std::normal_distribution<double> n01;
  int cases = 0;
  std::vector<std::pair<int, int>> shapes;  // a spread of p, k in 1 .. 16, and r = 8's wide ones (k = 64)
  for (int p = 1; p <= 16; ++p)
    for (int k = 1; k <= 16; ++k)
      if ((p + k) % 3 == 0 || p == k || p == 16 || k == 16 || p == 1 || k == 1) shapes.push_back({p, k});
  for (int p : {2, 3, 4, 8, 16}) shapes.push_back({p, 64});
  for (const auto& [p, k] : shapes)
    for (int variant = 0; variant < 5; ++variant) {
      Eigen::MatrixXcd x(p, k);
      for (Index i = 0; i < x.size(); ++i) x.data()[i] = Complex(n01(rng), n01(rng));
      if (variant == 1)
        for (int j = 0; j < k; ++j) x.col(j) *= std::pow(10.0, -20.0 * j / std::max(1, k - 1));
      if (variant == 2 && p > 1) x.row(p - 1) = x.row(0);
      if (variant == 3) x.col(0) *= 1e6;
      if (variant == 4) x.setZero();
      x *= 1e-3;  // not O(1): the kernel scales internally
      Eigen::VectorXcd y(p);
      for (int i = 0; i < p; ++i) y[i] = Complex(n01(rng), n01(rng));
      const int q = std::min(p, k);
      std::vector<Complex> xa(x.data(), x.data() + x.size()), ya(y.data(), y.data() + p), v(2 * std::max(p, k));
      std::vector<double> s2(q), c(q), work(2 * q);
      double perp = -1;
      // Two at once (SingularSpectra<2>, the bins' interleaved path), this one with a random other: the same bits.
      std::vector<Complex> x2(2 * xa.size()), yp(2 * p), v2(2 * v.size());
      std::vector<double> s2p(2 * q), cp(2 * q), work2(4 * q);
      double perp2[2] = {-1, -1};
      std::copy(xa.begin(), xa.end(), x2.begin());
      std::copy(ya.begin(), ya.end(), yp.begin());
      for (std::size_t i = xa.size(); i < x2.size(); ++i) x2[i] = Complex(n01(rng), n01(rng));
      for (int i = p; i < 2 * p; ++i) yp[i] = Complex(n01(rng), n01(rng));
      bins::SpectrumJob jobs[2];
      for (int l = 0; l < 2; ++l)
        jobs[l] = bins::SpectrumJob{&x2[l * xa.size()], &yp[l * p], &s2p[l * q], &cp[l * q], &perp2[l],
                                    &work2[2 * l * q], &v2[l * v.size()]};
      bins::SingularSpectra<2>(jobs, p, k, p);
      ASSERT_TRUE(bins::SingularSpectrum(xa.data(), p, k, p, ya.data(), s2.data(), c.data(), &perp, work.data(),
                                         v.data()));
      EXPECT_TRUE(jobs[0].ok && jobs[1].ok);
      for (int j = 0; j < q; ++j) {
        EXPECT_EQ(s2p[j], s2[j]);
        EXPECT_EQ(cp[j], c[j]);
      }
      EXPECT_EQ(perp2[0], perp);
      const Eigen::JacobiSVD<Eigen::MatrixXcd> svd(x, Eigen::ComputeFullU);
      const Eigen::VectorXd sv = svd.singularValues();  // descending
      const Eigen::VectorXcd uy = svd.matrixU().adjoint() * y;
      const double ref_perp = uy.tail(p - q).squaredNorm();
      const double smax = sv.size() ? sv[0] : 0.0;
      const std::string what = std::to_string(p) + " x " + std::to_string(k) + ", variant " + std::to_string(variant);
      for (int j = 0; j < q; ++j) {
        if (j > 0) {
          EXPECT_LE(s2[j - 1], s2[j]) << what;
        }
        EXPECT_LE(std::abs(std::sqrt(s2[j]) - sv[q - 1 - j]), 1e-14 * smax) << what << ", sigma " << j;
      }
      const double y2 = y.squaredNorm();
      double csum = perp;
      for (int j = 0; j < q; ++j) csum += c[j];
      EXPECT_NEAR(csum, y2, 1e-13 * y2) << what;
      EXPECT_NEAR(perp, ref_perp, 1e-13 * y2) << what;
      for (double t = -8; t <= 2; t += 0.5) {
        const double w = smax > 0 ? smax * smax * std::pow(10.0, t) : 1.0;
        double res = perp, dof = 0, ref_res = ref_perp, ref_dof = 0;
        for (int j = 0; j < q; ++j) {
          const double g = w / (s2[j] + w), gr = w / (sv[j] * sv[j] + w);
          res += g * g * c[j];
          dof += g;
          ref_res += gr * gr * std::norm(uy[j]);
          ref_dof += gr;
        }
        EXPECT_NEAR(res, ref_res, 1e-11 * y2) << what << ", log10(w/smax²) = " << t;
        EXPECT_NEAR(dof, ref_dof, 1e-11 * q) << what << ", log10(w/smax²) = " << t;
      }
      ++cases;
    }
  EXPECT_GT(cases, 500);
  std::vector<Complex> bad(4, Complex(1.0)), yb(2, Complex(1.0)), v(4);
  bad[3] = Complex(std::numeric_limits<double>::quiet_NaN(), 0.0);
  std::vector<double> s2(2), c(2), work(4);
  double perp = 0;
  EXPECT_FALSE(bins::SingularSpectrum(bad.data(), 2, 2, 2, yb.data(), s2.data(), c.data(), &perp, work.data(), v.data()));
  // ... also beside a good one, which is not disturbed.
  std::vector<Complex> pair_x = {Complex(1.0), Complex(0.0), Complex(0.0), Complex(2.0), 1.0, 1.0, 1.0,
                                 Complex(std::numeric_limits<double>::infinity(), 0.0)};
  std::vector<Complex> pair_y(4, Complex(1.0)), pair_v(8);
  std::vector<double> pair_s2(4), pair_c(4), pair_work(8);
  double pair_perp[2];
  bins::SpectrumJob jobs[2] = {
      bins::SpectrumJob{&pair_x[0], &pair_y[0], &pair_s2[0], &pair_c[0], &pair_perp[0], &pair_work[0], &pair_v[0]},
      bins::SpectrumJob{&pair_x[4], &pair_y[2], &pair_s2[2], &pair_c[2], &pair_perp[1], &pair_work[4], &pair_v[4]}};
  bins::SingularSpectra<2>(jobs, 2, 2, 2);
  EXPECT_TRUE(jobs[0].ok);
  EXPECT_FALSE(jobs[1].ok);
  EXPECT_NEAR(pair_s2[0], 1.0, 1e-15);  // diag(1, 2)
  EXPECT_NEAR(pair_s2[1], 4.0, 4e-15);
}

// The λ rules' per-bin decomposition by bidiagonalisation and QR sweeps (bins::SingularSpectrum, the default)
// against Eigen's JacobiSVD of the whitened bins: the GCV curve, its residual and its trace agree to 1e-10
// relative over twelve decades of λ, the GCV search picks the same λ (to 1e-9 decades:
// the curves agree far below the golden-section search's 1e-4-decade resolution) and so the same image, at
// r = 2, 4, 8 with N < r², N = r² and N > r², with a wide PSF (aliases beyond the optical cutoff: singular values
// 1e-10 .. 1e-20 of the largest in most bins, as in the shipped scenes) and with duplicate frames (rank-deficient
// bins).
TEST(TikhonovTest, SpectralBidiagonalPathMatchesTheSvdPath) {
  struct Case {
    int r;
    std::vector<std::pair<double, double>> shifts;
    double sigma;
  };
  const std::vector<Case> cases = {
      {2, {{0, 0}, {0.5, 1.25}, {1.3, 0.2}}, 2.5},                                     // N < r²
      {2, {{0, 0}, {0, 1}, {1, 0}, {1, 1}}, 1.0},                                      // N = r²
      {2, {{0, 0}, {0, 1}, {1, 0}, {1, 1}, {0.5, 0.5}, {0.3, 1.7}}, 2.5},              // N > r²
      {2, {{0, 0}, {0, 0}, {1.5, 0.5}}, 1.5},                                          // duplicate frames
      {4, {{0, 0}, {1.5, 2.5}, {3.2, 0.7}, {2.1, 3.3}}, 3.0},                          // N < r²
      {4, {{0, 0}, {0, 0}, {2.5, 1.5}}, 2.0},                                          // duplicates, N < r²
      {8, {{0, 0}, {2.5, 1.5}, {5.5, 4.5}, {1, 6}}, 4.0}};                             // N < r²
  std::vector<Case> all = cases;
  {
    Case square{4, {}, 2.0}, tall{4, {}, 2.0};  // N = r² and N > r² at r = 4
    for (int k = 0; k < 16; ++k) square.shifts.push_back({0.25 * k + 0.1 * (k % 3), 0.37 * k});
    tall.shifts = square.shifts;
    for (int k = 0; k < 4; ++k) tall.shifts.push_back({0.6 * k + 0.2, 1.1 * k});
    all.push_back(square);
    all.push_back(tall);
  }
  for (const Case& c : all)
    for (TikhonovPrior prior : {TikhonovPrior::kGradient, TikhonovPrior::kPowerSpectrum}) {
      const Shape hr{c.r * 6, c.r * 8};
      const MultiFrameModel m = RasterModel(hr, c.r, c.shifts, c.sigma);
      TikhonovOptions o;
      o.prior = prior;
      o.lambda_rule = TikhonovLambdaRule::kGcv;
      const ImageStack frames = test::AddNoise(m.Render(test::RandomImage(hr, 9).abs() + 0.5), 0.02, 4);
      FourierSystem eig(m, PriorSymbolImage(o, hr), o.rank_tolerance, TikhonovBinSolver::kAuto);
      FourierSystem svd(m, PriorSymbolImage(o, hr), o.rank_tolerance, TikhonovBinSolver::kAuto);
      svd.SetSpectralMethod(FourierSystem::SpectralMethod::kSvd);
      eig.SetData(frames);
      svd.SetData(frames);
      const std::string what = std::string(ToString(prior)) + ", r = " + std::to_string(c.r) + ", N = " +
                               std::to_string(c.shifts.size()) + ", sigma " + ToString(c.sigma);
      const double n_data = double(m.frames()) * double(eig.bins());
      for (double t = -8; t <= 4; t += 0.5) {
        const double lambda = eig.lambda0() * std::pow(10.0, t);
        const FourierSystem::Fit a = eig.EvaluateSpectral(lambda, true), b = svd.EvaluateSpectral(lambda, true);
        const double gcv_a = n_data * a.residual2 / (a.dof * a.dof), gcv_b = n_data * b.residual2 / (b.dof * b.dof);
        EXPECT_NEAR(gcv_a, gcv_b, 1e-10 * gcv_b) << what << ", log10(λ/λ0) = " << t;
        EXPECT_NEAR(a.residual2, b.residual2, 1e-10 * b.residual2) << what << ", log10(λ/λ0) = " << t;
        EXPECT_NEAR(a.dof, b.dof, 1e-10 * b.dof) << what << ", log10(λ/λ0) = " << t;
        EXPECT_NEAR(a.prior2, b.prior2, 1e-9 * b.prior2) << what << ", log10(λ/λ0) = " << t;
      }
      double score_a = 0, score_b = 0;
      int evals_a = 0, evals_b = 0;
      const double lambda_a = tikhonov_internal::GcvSearch(eig, o, &score_a, &evals_a);
      const double lambda_b = tikhonov_internal::GcvSearch(svd, o, &score_b, &evals_b);
      EXPECT_LE(std::abs(std::log10(lambda_a / lambda_b)), 1e-9) << what;
      EXPECT_NEAR(score_a, score_b, 1e-10 * score_b) << what;
      const Image xa = eig.Solve(lambda_a), xb = svd.Solve(lambda_b);
      EXPECT_LE((xa - xb).matrix().norm(), 1e-8 * xb.matrix().norm()) << what;
    }
}

// The flat engine on 1 and 2 threads gives the same bits (DESIGN.md §4): ranks, λ₀, the spectral sums of every
// λ rule (the terms stream and the per-bin path), the GCV λ and the solve, on a grid of several bin blocks and
// term blocks (96 x 96 LR bins), with N < r², N > r² and duplicate frames.
// The engine's lazily made parts give the same bits whichever pass makes them (the floor and λ₀ from their own pass,
// from the spectral decomposition's or from the solve's), and a whole reconstruction (GCV and λ fixed; Woodbury and
// normal-equation bins; a prior vanishing at DC, whose bin the solve defers and the decomposition reduces) is the same
// bits on 1, 2 and 3 threads.
TEST(TikhonovTest, LazyPartsAndReconstructionsAreBitIdenticalOnOneTwoAndThreeThreads) {
  using Case = ModelCase;
  const std::vector<Case> cases = {{2, {{0, 0}, {0.5, 1.25}, {1.3, 0.2}}, TikhonovPrior::kGradient},
                                   {4, {{0, 0}, {0.5, 1.25}, {1.3, 0.2}, {2.7, 3.1}}, TikhonovPrior::kLaplacian},
                                   {2, {{0, 0}, {0, 1}, {1, 0}, {1, 1}, {0.5, 0.5}}, TikhonovPrior::kPowerSpectrum}};
  const int saved = DefaultThreads();
  for (const Case& c : cases) {
    const Shape hr{40 * c.r, 48 * c.r};
    const std::string what = "r = " + std::to_string(c.r) + ", N = " + std::to_string(c.shifts.size());
    const auto model = std::make_shared<MultiFrameModel>(RasterModel(hr, c.r, c.shifts, 1.2));
    const ImageStack frames = test::AddNoise(model->Render(test::RandomImage(hr, 4).abs()), 0.02, 6);
    TikhonovOptions o;
    o.prior = c.prior;
    // λ₀ (and with it the floor) from EnsureFloor's pass, from the decomposition's and from the solve's.
    FourierSystem own(*model, PriorSymbolImage(o, hr), o.rank_tolerance, TikhonovBinSolver::kAuto);
    FourierSystem spectral(*model, PriorSymbolImage(o, hr), o.rank_tolerance, TikhonovBinSolver::kAuto);
    FourierSystem solved(*model, PriorSymbolImage(o, hr), o.rank_tolerance, TikhonovBinSolver::kAuto);
    for (FourierSystem* s : {&own, &spectral, &solved}) s->SetData(frames);
    const double lambda0 = own.lambda0();
    spectral.PrepareSpectral();
    solved.Solve(1e-2);
    EXPECT_EQ(spectral.lambda0(), lambda0) << what;
    EXPECT_EQ(solved.lambda0(), lambda0) << what;
    EXPECT_EQ(solved.deficient_bins(), own.deficient_bins()) << what;

    ReconstructionProblem p;
    p.model = model;
    p.frames = frames;
    std::vector<TikhonovResult> gcv, fixed;
    for (int threads : {1, 2, 3}) {
      SetDefaultThreads(threads);
      TikhonovOptions g = o;
      g.lambda_rule = TikhonovLambdaRule::kGcv;
      gcv.push_back(ReconstructTikhonov(p, g));
      TikhonovOptions f = o;
      f.lambda = gcv.front().summary.lambda;
      fixed.push_back(ReconstructTikhonov(p, f));
    }
    SetDefaultThreads(saved);
    for (std::size_t k = 1; k < gcv.size(); ++k) {
      EXPECT_TRUE((gcv[k].image == gcv[0].image).all()) << what << ", " << k + 1 << " threads";
      EXPECT_TRUE((fixed[k].image == fixed[0].image).all()) << what << ", " << k + 1 << " threads";
      EXPECT_EQ(gcv[k].summary.lambda, gcv[0].summary.lambda) << what;
      EXPECT_EQ(gcv[k].summary.gcv, gcv[0].summary.gcv) << what;
      EXPECT_EQ(gcv[k].summary.final_cost, gcv[0].summary.final_cost) << what;
      EXPECT_EQ(fixed[k].summary.final_cost, fixed[0].summary.final_cost) << what;
    }
    // λ fixed at GCV's λ is GCV's image.
    EXPECT_TRUE((fixed[0].image == gcv[0].image).all()) << what;
  }
}

TEST(TikhonovTest, FlatEngineIsBitIdenticalOnOneAndTwoThreads) {
  using Case = ModelCase;
  const std::vector<Case> cases = {{2, {{0, 0}, {0.5, 1.25}, {1.3, 0.2}}},
                                   {2, {{0, 0}, {0, 1}, {1, 0}, {1, 1}, {0.5, 0.5}, {0.3, 1.7}}},
                                   {2, {{0, 0}, {0, 0}, {1.5, 0.5}, {0.5, 1.5}}}};
  const int saved = DefaultThreads();
  for (const Case& c : cases) {
    const Shape hr{96 * c.r, 96 * c.r};
    const MultiFrameModel m = RasterModel(hr, c.r, c.shifts, 1.5);
    TikhonovOptions o;
    o.lambda_rule = TikhonovLambdaRule::kGcv;
    const ImageStack frames = test::AddNoise(m.Render(test::RandomImage(hr, 3).abs()), 0.02, 5);
    struct Run {
      Index deficient, unconstrained;
      double lambda0, lambda, score;
      FourierSystem::Fit fit, with_prior;
      Image x;
    };
    const auto run = [&](int threads) {
      SetDefaultThreads(threads);
      FourierSystem sys(m, PriorSymbolImage(o, hr), o.rank_tolerance, TikhonovBinSolver::kAuto);
      sys.SetData(frames);
      Run out;
      int evaluations = 0;
      out.deficient = sys.deficient_bins();
      out.unconstrained = sys.unconstrained();
      out.lambda0 = sys.lambda0();
      out.lambda = tikhonov_internal::GcvSearch(sys, o, &out.score, &evaluations);
      out.fit = sys.EvaluateSpectral(out.lambda);
      out.with_prior = sys.EvaluateSpectral(out.lambda, true);
      out.x = sys.Solve(out.lambda);
      return out;
    };
    const Run one = run(1), two = run(2);
    const std::string what = "r = " + std::to_string(c.r) + ", N = " + std::to_string(c.shifts.size());
    EXPECT_EQ(one.deficient, two.deficient) << what;
    EXPECT_EQ(one.unconstrained, two.unconstrained) << what;
    EXPECT_EQ(one.lambda0, two.lambda0) << what;
    EXPECT_EQ(one.lambda, two.lambda) << what;
    EXPECT_EQ(one.score, two.score) << what;
    EXPECT_EQ(one.fit.residual2, two.fit.residual2) << what;
    EXPECT_EQ(one.fit.dof, two.fit.dof) << what;
    EXPECT_EQ(one.with_prior.residual2, two.with_prior.residual2) << what;
    EXPECT_EQ(one.with_prior.prior2, two.with_prior.prior2) << what;
    EXPECT_EQ(one.with_prior.dprior2, two.with_prior.dprior2) << what;
    EXPECT_TRUE((one.x == two.x).all()) << what;
  }
  SetDefaultThreads(saved);
}

}  // namespace
}  // namespace aosr
