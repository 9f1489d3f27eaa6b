// Physics oracles for the Tikhonov/Wiener reconstructor: the posterior standard deviation map against the
// empirical spread of x̂ − x over 200 draws of object and noise, and the Wiener error against the trace of
// the posterior covariance.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>

#include "aosr/core/fft.hpp"
#include "aosr/solvers/tikhonov.hpp"
#include "solvers/tikhonov_internal.hpp"
#include "solvers/tikhonov_fixture.hpp"
#include "support/testing.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

// What the std map is. C = σ²(AᵀWA + λΓᵀΓ)⁻¹ is the covariance of x − x̂ when the object is drawn from the
// prior *and* the noise is drawn: the Bayesian error. Over noise alone (object fixed) x̂ has the smaller
// covariance σ²Q⁻¹AᵀWAQ⁻¹ (Q = AᵀWA + λΓᵀΓ), missing the bias term σ²Q⁻¹λΓᵀΓQ⁻¹; the two agree only
// as λ → 0. So the oracle draws both, from a proper Gaussian prior (the power-spectrum prior, sampled
// exactly through the FFT), and reports the noise-only spread beside it.
//
// Setting: 32x32 camera, r = 2, N = 3 < r² frames (Woodbury bins; sub-pixel phases sampled unequally),
// uniform weight 4 (noise σ/2 per pixel, testing the weight convention), Wiener λ = σ²/s².
struct WienerSetup {
  Shape hr{64, 64};
  int r = 2;
  double sigma = 0.05;  // noise σ of a weight-1 pixel
  double weight = 4.0;  // every pixel: variance σ²/4
  double s = 1.0;       // object amplitude: per-pixel power spectrum s²·S(f)
  TikhonovOptions options;
  std::shared_ptr<const MultiFrameModel> model;
  Image sqrt_s;  // √S on the full HR spectrum

  WienerSetup() {
    model = std::make_shared<const MultiFrameModel>(
        test::RasterModel(hr, r, {{0, 0}, {0.5, 1.0}, {1.0, 0.25}}, 1.0));
    options.prior = TikhonovPrior::kPowerSpectrum;
    options.spectrum_slope = 2.0;
    options.spectrum_corner = 0.05;
    // Wiener: the prior x ~ N(0, (σ²/λ)(ΓᵀΓ)⁻¹) has per-pixel spectrum (σ²/λ) S, so λ = σ²/s².
    options.lambda = sigma * sigma / (s * s);
    options.compute_std = true;
    options.noise_sigma = sigma;
    sqrt_s = Image(hr.rows, hr.cols);
    for (Index fy = 0; fy < hr.rows; ++fy)
      for (Index fx = 0; fx < hr.cols; ++fx)
        sqrt_s(fy, fx) = std::sqrt(1.0 / TikhonovPriorSymbol(options, hr, fy, fx));
  }

  // An object from the prior: s · IFFT(FFT(white) · √S), covariance s² S as a circulant.
  Image DrawObject(std::uint64_t seed) const {
    const ComplexImage w = FftForward(test::RandomImage(hr, seed).cast<Complex>());
    return s * FftInverse(w * sqrt_s.cast<Complex>()).real();
  }

  ReconstructionProblem Problem(const Image& x, std::uint64_t seed) const {
    ReconstructionProblem p;
    p.model = model;
    p.frames = test::AddNoise(model->Render(x), sigma / std::sqrt(weight), seed);
    p.weights = ImageStack(model->frames(), Image::Constant(hr.rows / r, hr.cols / r, weight));
    return p;
  }
};

// Pools x̂ − x over 200 realisations (object from the prior and noise): its per-pixel variance must be the
// std map squared. The map is periodic with period r, so pixels of one phase (p mod r) are pooled: 200 x 1024
// samples per phase. Asserted: each phase's RMS error within 5% of the map, and the per-pixel empirical std
// (200 samples each, ±5% sampling error) within 5% of the map for the median pixel.
TEST(TikhonovPhysicsTest, PosteriorStdMatchesTheSpreadOf200Realisations) {
  SCOPED_TRACE("seeds: objects 1000..1199, noise 5000..5199");
  const WienerSetup su;
  const int runs = 200;
  Image sum2 = Image::Zero(su.hr.rows, su.hr.cols), noise2 = sum2;
  Image predicted;
  TikhonovOptions no_std = su.options;
  no_std.compute_std = false;
  for (int k = 0; k < runs; ++k) {
    const Image x = su.DrawObject(1000 + k);
    const TikhonovResult res = ReconstructTikhonov(su.Problem(x, 5000 + k), su.options);
    ASSERT_TRUE(res.summary.std_computed) << res.summary.message;
    if (k == 0) {
      predicted = res.posterior_std;
      EXPECT_GT(res.summary.woodbury_bins, 0);
    }
    sum2 += (res.image - x).square();
    // x̂ is linear: its noise-only fluctuation is the reconstruction of the noise alone.
    noise2 +=
        ReconstructTikhonov(su.Problem(Image::Zero(su.hr.rows, su.hr.cols), 5000 + k), no_std).image.square();
  }
  const Image empirical = (sum2 / runs).sqrt();
  const int r = su.r;
  double worst_phase = 0;
  for (int py = 0; py < r; ++py)
    for (int px = 0; px < r; ++px) {
      double e2 = 0, n2 = 0;
      Index count = 0;
      for (Index y = py; y < su.hr.rows; y += r)
        for (Index x = px; x < su.hr.cols; x += r)
          e2 += sum2(y, x) / runs, n2 += noise2(y, x) / runs, ++count;
      const double ratio = std::sqrt(e2 / double(count)) / predicted(py, px);
      const double noise_only = std::sqrt(n2 / double(count));
      worst_phase = std::max(worst_phase, std::abs(ratio - 1));
      std::printf(
          "phase (%d,%d): posterior std %.5f, empirical RMS of x^-x %.5f (ratio %.4f); noise-only spread "
          "%.5f\n",
          py, px, predicted(py, px), predicted(py, px) * ratio, ratio, noise_only);
      EXPECT_LT(noise_only, predicted(py, px));  // the estimator's noise covariance misses the prior's share
    }
  std::vector<double> dev;
  for (Index i = 0; i < empirical.size(); ++i)
    dev.push_back(std::abs(empirical.data()[i] / predicted.data()[i] - 1));
  std::nth_element(dev.begin(), dev.begin() + dev.size() / 2, dev.end());
  const double median = dev[dev.size() / 2];
  std::printf("worst phase |ratio-1| = %.4f; per-pixel median |ratio-1| = %.4f (sampling alone: ~0.034)\n",
              worst_phase, median);
  EXPECT_LT(worst_phase, 0.05);
  EXPECT_LT(median, 0.05);
  // The phases differ: N = 3 frames sample the four sub-pixel phases unequally.
  EXPECT_GT(predicted.block(0, 0, r, r).maxCoeff() / predicted.block(0, 0, r, r).minCoeff(), 1.01);
}

// Wiener optimality: for objects drawn from the prior, the mean squared error of the posterior mean is
// tr C / M² — summary.mean_posterior_variance — and a mis-set λ (x10 either way) does worse.
TEST(TikhonovPhysicsTest, WienerErrorIsTheTraceOfThePosteriorCovariance) {
  SCOPED_TRACE("seeds: objects 7000..7059, noise 9000..9059");
  const WienerSetup su;
  const int runs = 60;
  double mse = 0, mse_low = 0, mse_high = 0, predicted = 0;
  TikhonovOptions low = su.options, high = su.options;
  low.lambda /= 10;
  high.lambda *= 10;
  low.compute_std = high.compute_std = false;
  for (int k = 0; k < runs; ++k) {
    const Image x = su.DrawObject(7000 + k);
    const ReconstructionProblem p = su.Problem(x, 9000 + k);
    const TikhonovResult res = ReconstructTikhonov(p, su.options);
    predicted = res.summary.mean_posterior_variance;
    mse += (res.image - x).square().mean() / runs;
    mse_low += (ReconstructTikhonov(p, low).image - x).square().mean() / runs;
    mse_high += (ReconstructTikhonov(p, high).image - x).square().mean() / runs;
  }
  std::printf("MSE per HR pixel: %.5g (tr C / M^2 = %.5g, ratio %.4f); lambda/10: %.5g, lambda*10: %.5g\n",
              mse, predicted, mse / predicted, mse_low, mse_high);
  EXPECT_NEAR(mse / predicted, 1.0, 0.03);
  EXPECT_GT(mse_low, mse);
  EXPECT_GT(mse_high, mse);
}

// The λ rules that search (tikhonov.hpp: kLcurve, kUpre) on a problem with a known object and noise: 64x64 HR,
// r = 2, N = 3, gradient prior, a smooth random object (the WienerSetup's draw), σ = 0.05 per pixel.
struct RuleSetup {
  WienerSetup w;
  Image x;
  ReconstructionProblem p;
  RuleSetup() {
    w.weight = 1.0;
    x = w.DrawObject(7);
    p.model = w.model;
    p.frames = test::AddNoise(w.model->Render(x), w.sigma, 8);
  }
  std::unique_ptr<tikhonov_internal::FourierSystem> System(const TikhonovOptions& o) const {
    auto sys = std::make_unique<tikhonov_internal::FourierSystem>(
        *w.model, tikhonov_internal::PriorSymbolImage(o, w.model->hr_shape()), o.rank_tolerance, o.bin_solver);
    sys->SetData(p.frames);
    return sys;
  }
};

// UPRE is an unbiased estimate of the predictive risk ||A(x_λ − x)||² (Vogel 2002, §7.1): its minimiser must
// agree with the true risk's minimiser, found on a fine grid (0.02 decades) against the known object, for
// several noise draws. Asserted: within 0.25 decades; the risk at UPRE's λ within 5 % of the smallest.
TEST(TikhonovPhysicsTest, UpreMinimiserAgreesWithTheTruePredictiveRisk) {
  RuleSetup s;
  const ImageStack clean = s.w.model->Render(s.x);
  for (std::uint64_t seed : {31, 32, 33}) {
    ReconstructionProblem p = s.p;
    p.frames = test::AddNoise(clean, s.w.sigma, seed);
    TikhonovOptions o;
    o.lambda_rule = TikhonovLambdaRule::kUpre;
    o.noise_sigma = s.w.sigma;
    const TikhonovResult upre = ReconstructTikhonov(p, o);
    auto risk = [&](double lambda) {
      TikhonovOptions f;
      f.lambda = lambda;
      const ImageStack pred = s.w.model->Render(ReconstructTikhonov(p, f).image);
      double r = 0;
      for (int i = 0; i < int(pred.size()); ++i) r += (pred[i] - clean[i]).square().sum();
      return r;
    };
    double best = 1e300, best_lambda = 0;
    for (double t = -2; t <= 2.0001; t += 0.02) {
      const double lam = upre.summary.lambda * std::pow(10.0, t);
      const double r = risk(lam);
      if (r < best) best = r, best_lambda = lam;
    }
    SCOPED_TRACE("seed " + std::to_string(seed) + ": " + upre.summary.message);
    std::printf("seed %d: UPRE lambda %.4g, risk minimiser %.4g (risk ratio %.4f)\n", int(seed),
                upre.summary.lambda, best_lambda, risk(upre.summary.lambda) / best);
    EXPECT_NEAR(std::log10(upre.summary.lambda / best_lambda), 0.0, 0.25);
    EXPECT_LT(risk(upre.summary.lambda), 1.05 * best);
    EXPECT_GT(upre.summary.upre, 0.0);
  }
}

// The L-curve: (1) the closed-form curvature κ(λ) agrees with the curvature of (ln ρ, ln η) by finite
// differences of the spectral sums; (2) the search's corner is the maximum of κ on a fine grid (0.01 decades)
// over ±1 decade around it to within that grid's resolution, and not itself a point of the coarse grid
// (continuous refinement); (3) the corner lies between the under- and over-smoothed ends: ρ and η strictly
// between their values at λ₀·10⁻⁸ and λ₀·10⁴. (This problem's curve also has a larger κ near λ₀·10⁻⁷, where
// it comes to rest at the least-squares end: measured κ 0.90 there against 0.49 at the corner near λ₀.)
TEST(TikhonovPhysicsTest, LcurveCornerIsTheContinuousMaximumOfTheCurvature) {
  RuleSetup s;
  TikhonovOptions o;
  o.lambda_rule = TikhonovLambdaRule::kLcurve;
  const auto sys = s.System(o);
  auto point = [&](double t) {
    const auto f = sys->EvaluateSpectral(sys->lambda0() * std::pow(10.0, t), true);
    return std::pair<double, double>(std::log(f.residual2), std::log(f.prior2));
  };
  // (1) Finite differences in t = log10 λ (the curvature does not depend on the parameterisation).
  for (double t : {-4.0, -2.5, -1.0, 0.5}) {
    const double h = 1e-3;
    const auto [a0, b0] = point(t);
    const auto [ap, bp] = point(t + h);
    const auto [am, bm] = point(t - h);
    const double a1 = (ap - am) / (2 * h), b1 = (bp - bm) / (2 * h);
    const double a2 = (ap - 2 * a0 + am) / (h * h), b2 = (bp - 2 * b0 + bm) / (h * h);
    const double k_fd = (a1 * b2 - a2 * b1) / std::pow(a1 * a1 + b1 * b1, 1.5);
    const double k = tikhonov_internal::LcurveCurvature(*sys, sys->lambda0() * std::pow(10.0, t));
    EXPECT_NEAR(k, k_fd, 1e-3 * std::max(1.0, std::abs(k_fd))) << "t = " << t;
  }
  // (2) The search against a fine grid.
  double kappa = 0;
  int evaluations = 0;
  std::string edge;
  const double lambda = tikhonov_internal::LcurveSearch(*sys, o, &kappa, &evaluations, &edge);
  EXPECT_EQ(edge, "");
  const double t_search = std::log10(lambda / sys->lambda0());
  double best = -1e300, best_t = 0;
  for (double t = t_search - 1; t <= t_search + 1; t += 0.01) {
    const double k = tikhonov_internal::LcurveCurvature(*sys, sys->lambda0() * std::pow(10.0, t));
    if (k > best) best = k, best_t = t;
  }
  std::printf("L-curve corner at t = %.4f (kappa %.4g); fine grid %.2f (kappa %.4g)\n", t_search, kappa, best_t,
              best);
  EXPECT_NEAR(t_search, best_t, 0.01);
  EXPECT_GT(t_search, -3.0);  // not the least-squares end
  EXPECT_GE(kappa, best * (1 - 1e-6));
  const double steps = t_search * o.gcv_steps_per_decade;
  EXPECT_GT(std::abs(steps - std::round(steps)), 1e-3);  // not a coarse-grid point
  // (3) Between the ends.
  const auto [a_lo, b_lo] = point(-8);
  const auto [a_c, b_c] = point(t_search);
  const auto [a_hi, b_hi] = point(4);
  EXPECT_LT(a_lo, a_c);
  EXPECT_LT(a_c, a_hi);
  EXPECT_GT(b_lo, b_c);
  EXPECT_GT(b_c, b_hi);
  // Through the public entry: the same λ, reported.
  const TikhonovResult r = ReconstructTikhonov(s.p, o);
  EXPECT_NEAR(r.summary.lambda / lambda, 1.0, 1e-9);
  EXPECT_NEAR(r.summary.lcurve_curvature, kappa, 1e-9 * std::abs(kappa));
  EXPECT_THAT(r.summary.message, ::testing::HasSubstr("L-curve"));
}

}  // namespace
}  // namespace aosr
