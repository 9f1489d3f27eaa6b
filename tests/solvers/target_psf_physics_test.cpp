// Target-PSF linear reconstruction: every noise figure it reports against a Monte-Carlo over noise
// realisations pushed through the same estimator (seeds fixed; tolerances are a few standard errors).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <random>

#include "aosr/core/operators.hpp"
#include "aosr/scene/preset_psf.hpp"
#include "aosr/scene/telescope.hpp"
#include "aosr/solvers/target_psf.hpp"
#include "solvers/tikhonov_fixture.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

std::shared_ptr<const MultiFrameModel> Model(Shape hr) {
  return std::make_shared<MultiFrameModel>(
      test::RasterModel(hr, 2, {{0, 0}, {0, 1}, {1, 0}, {1, 1}, {0.5, 0.5}}, 0.9));
}

TargetPsfOptions Options() {
  TargetPsfOptions o;
  o.kind = TargetPsfKind::kGaussian;
  o.fwhm_hr_px = 3.0;
  return o;
}

// Monte-Carlo statistics of the estimator applied to pure noise: per-pixel variance and the lag covariance
// averaged over pixels.
struct MonteCarlo {
  Image var, var_se;  // per pixel, and the standard error of each value
  double mean_var = 0, mean_var_se = 0;
  Image xi;           // (2R+1)² centred, averaged over pixels
};

MonteCarlo RunMonteCarlo(const ReconstructionProblem& base, const TargetPsfOptions& o, const std::vector<Image>& pixel_sigma,
               int trials, std::uint64_t seed, int radius) {
  const Shape hr = base.model->hr_shape();
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> n01;
  Image s2 = Image::Zero(hr.rows, hr.cols), s4 = Image::Zero(hr.rows, hr.cols);
  Image xi = Image::Zero(2 * radius + 1, 2 * radius + 1);
  std::vector<double> means;
  TargetPsfOptions q = o;
  q.compute_noise = false;
  for (int t = 0; t < trials; ++t) {
    ReconstructionProblem p = base;
    for (std::size_t i = 0; i < p.frames.size(); ++i)
      for (Index k = 0; k < p.frames[i].size(); ++k) p.frames[i].data()[k] = pixel_sigma[i].data()[k] * n01(rng);
    const Image x = ReconstructTargetPsf(p, q).image;
    s2 += x.square();
    s4 += x.square().square();
    means.push_back(x.square().mean());
    for (int dy = -radius; dy <= radius; ++dy)
      for (int dx = -radius; dx <= radius; ++dx) {
        double acc = 0;
        for (Index y = 0; y < hr.rows; ++y)
          for (Index xx = 0; xx < hr.cols; ++xx)
            acc += x(y, xx) * x((y + dy + hr.rows) % hr.rows, (xx + dx + hr.cols) % hr.cols);
        xi(dy + radius, dx + radius) += acc / double(hr.size());
      }
  }
  MonteCarlo mc;
  const double k = trials;
  mc.var = s2 / k;
  mc.var_se = ((s4 / k - mc.var.square()).max(0.0) / (k - 1)).sqrt();
  mc.xi = xi / k;
  for (double m : means) mc.mean_var += m / k;
  double m2 = 0;
  for (double m : means) m2 += (m - mc.mean_var) * (m - mc.mean_var);
  mc.mean_var_se = std::sqrt(m2 / (k - 1) / k);
  return mc;
}

TEST(TargetPsfPhysicsTest, ExactNoiseMapAndCorrelationMatchMonteCarlo) {
  const Shape hr{32, 32};
  ReconstructionProblem p;
  p.model = Model(hr);
  p.frames = p.model->Render(Image::Zero(32, 32));
  // Uniform weight 4 and σ = 1.4 for a weight-1 pixel: every frame pixel has σ 0.7.
  for (int i = 0; i < 5; ++i) p.weights.push_back(Image::Constant(16, 16, 4.0));
  TargetPsfOptions o = Options();
  o.noise_sigma = 1.4;
  o.correlation_radius = 2;
  const TargetPsfResult r = ReconstructTargetPsf(p, o);
  ASSERT_EQ(r.summary.method, "target-psf-fourier");
  const MonteCarlo mc = RunMonteCarlo(p, o, std::vector<Image>(5, Image::Constant(16, 16, 0.7)), 400, 11, 2);
  // Per sub-pixel phase (the map is periodic with period r = 2): pool the Monte-Carlo over that phase.
  for (int py = 0; py < 2; ++py)
    for (int px = 0; px < 2; ++px) {
      double sum = 0;
      int count = 0;
      for (Index y = py; y < 32; y += 2)
        for (Index x = px; x < 32; x += 2) {
          sum += mc.var(y, x);
          ++count;
          EXPECT_DOUBLE_EQ(r.noise_std(y, x), r.noise_std(py, px));
        }
      const double predicted = r.noise_std(py, px) * r.noise_std(py, px);
      EXPECT_NEAR(sum / count, predicted, 0.04 * predicted) << "phase " << py << ", " << px;
    }
  // ξ(Δ): lag 0 is the mean variance; the neighbours carry the correlation the target PSF leaves.
  const double xi0 = r.noise_correlation(2, 2);
  EXPECT_NEAR(xi0, r.summary.noise_rms * r.summary.noise_rms, 1e-12 * xi0);
  for (int dy = 0; dy <= 2; ++dy)
    for (int dx = 0; dx <= 2; ++dx)
      EXPECT_NEAR(mc.xi(2 + dy, 2 + dx), r.noise_correlation(2 + dy, 2 + dx), 0.04 * xi0) << dy << ", " << dx;
  EXPECT_GT(r.noise_correlation(2, 3), 0.3 * xi0);  // the target's smoothing correlates neighbours
}

TEST(TargetPsfPhysicsTest, ProbedNoiseOfWeightedDataMatchesMonteCarloWithinItsErrorBars) {
  const Shape hr{32, 32};
  ReconstructionProblem p;
  p.model = Model(hr);
  p.frames = p.model->Render(Image::Zero(32, 32));
  std::vector<Image> sigma;
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> u(0.5, 2.0);
  for (int i = 0; i < 5; ++i) {
    Image w(16, 16);
    for (Index k = 0; k < w.size(); ++k) w.data()[k] = u(rng);
    if (i == 1) w.block(4, 4, 3, 3) = 0;  // a bad-pixel patch
    p.weights.push_back(w);
    sigma.push_back((w > 0).select(w.max(1e-300).rsqrt(), 0.0));  // inverse-variance weights, σ = 1
  }
  TargetPsfOptions o = Options();
  o.noise_probes = 64;
  o.seed = 3;
  o.correlation_radius = 1;
  const TargetPsfResult r = ReconstructTargetPsf(p, o);
  ASSERT_EQ(r.summary.method, "target-psf-cg");
  ASSERT_EQ(r.summary.noise_probes, 64);
  const MonteCarlo mc = RunMonteCarlo(p, o, sigma, 200, 17, 1);
  // The global RMS, within the combined standard error.
  const double mc_rms = std::sqrt(mc.mean_var);
  const double mc_rms_se = mc.mean_var_se / (2 * mc_rms);
  EXPECT_NEAR(r.summary.noise_rms, mc_rms, 4 * std::hypot(r.summary.noise_rms_error, mc_rms_se));
  // Per pixel: the reported standard errors are honest if the z-scores of the two independent estimates
  // have unit variance.
  double z2 = 0;
  for (Index k = 0; k < hr.size(); ++k) {
    const double vp = r.noise_std.data()[k] * r.noise_std.data()[k];
    const double vp_se = 2 * r.noise_std.data()[k] * r.noise_std_error.data()[k];
    const double z = (vp - mc.var.data()[k]) / std::hypot(vp_se, mc.var_se.data()[k]);
    z2 += z * z;
  }
  z2 /= double(hr.size());
  EXPECT_GT(z2, 0.6);
  EXPECT_LT(z2, 1.5);
  // The map sees the bad-pixel patch: noisier there than on average.
  EXPECT_GT(r.noise_std.block(8, 8, 6, 6).mean(), r.noise_std.mean());
  // Lag covariance from the probes.
  EXPECT_NEAR(r.noise_correlation(1, 2), mc.xi(1, 2), 0.1 * mc.xi(1, 1));
}

// The auto target's noise must follow the model smoothly (issue 31: with the leakage bound held to the modes near
// the optics' cut-off, a 0.8 % narrower model PSF moved κ 2.3x and the noise 29 % on paper-sim-r4). Two models of the
// same telescope at r = 4, N = 4 on the classic raster, whose PSFs differ as a model and the truth do: paper-8m's
// analytic AO PSF on axis, and the same blurred by a Gaussian of σ = 0.45 HR px (the auto target 2.2 % broader, as
// jitter or a slightly worse seeing would make it). The exact noise of the auto-target output (uniform weights,
// Fourier path) must change smoothly with the target: measured −7.5 % and κ x1.15; with the numerical-rank floor
// (1e-18) instead of the reach floor (solvers/target_psf.cpp) −27 % and κ x2.2.
TEST(TargetPsfPhysicsTest, AutoTargetNoiseFollowsASmallModelChangeSmoothly) {
  const TelescopePreset preset = LoadTelescopePreset("paper-8m");
  const Shape hr{128, 128};
  PresetPsfOptions po;
  po.mode = "analytic";
  po.r = 4;
  po.size = 128;
  const Image psf = ComputePresetPsf(preset, po).psf;
  auto model_with = [&](double blur) {
    ComplexImage h = TransferFunction(hr, psf / psf.sum());
    if (blur > 0) h *= TransferFunction(hr, test::GaussianKernel(11, blur));
    std::vector<ComplexImage> otfs;
    for (auto [dy, dx] : std::vector<std::pair<double, double>>{{-1, -1}, {-1, 1}, {1, -1}, {1, 1}})
      otfs.push_back(h * ShiftTransfer(hr, dy, dx));
    return std::make_shared<const MultiFrameModel>(hr, 4, otfs);
  };
  TargetPsfOptions o;  // auto target, leakage 1e-3
  auto run = [&](std::shared_ptr<const MultiFrameModel> m) {
    ReconstructionProblem p;
    p.model = m;
    p.frames = ImageStack(4, Image::Zero(32, 32));
    return ReconstructTargetPsf(p, o).summary;
  };
  const TargetPsfSummary a = run(model_with(0)), b = run(model_with(0.45));
  std::printf("model: target %.3f, kappa %.3g, noise %.4g; blurred: target %.3f, kappa %.3g, noise %.4g\n",
              a.target_fwhm_hr_px, a.kappa, a.noise_rms, b.target_fwhm_hr_px, b.kappa, b.noise_rms);
  ASSERT_TRUE(a.leakage_met && b.leakage_met);
  const double fwhm_change = std::abs(b.target_fwhm_hr_px / a.target_fwhm_hr_px - 1);
  EXPECT_GT(fwhm_change, 0.01);  // the models do differ, by a little
  EXPECT_LT(fwhm_change, 0.04);
  EXPECT_LT(std::abs(std::log(b.noise_rms / a.noise_rms)), 0.12) << "noise " << a.noise_rms << " vs " << b.noise_rms;
  EXPECT_LT(std::abs(std::log(b.kappa / a.kappa)), std::log(1.5)) << "kappa " << a.kappa << " vs " << b.kappa;
}

}  // namespace
}  // namespace aosr
