// Physics oracles for the Tikhonov/Wiener reconstructor: the posterior standard deviation map against the
// empirical spread of x̂ − x over 200 draws of object and noise, and the Wiener error against the trace of
// the posterior covariance.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>

#include "aosr/core/fft.hpp"
#include "aosr/solvers/tikhonov.hpp"
#include "solvers/tikhonov_fixture.hpp"
#include "support/testing.hpp"

namespace aosr {
namespace {

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

}  // namespace
}  // namespace aosr
