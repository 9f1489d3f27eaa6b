// The stars PSF (solvers/stars_psf.hpp) against the physics that made the data: a star field like
// data/scenes/crowded-stars.json (paper-8m, K band, the analytic long-exposure AO PSF in a 64 λ/D window, a 2 × 2
// raster, a 13 mag/arcsec² sky, photon and 5 e⁻ read noise, magnitudes 14-20, α = 1.75, blends allowed) on a
// 64² camera frame with 60 stars, simulated by the scene pipeline. The oracle is the PSFs the simulator
// convolved with. Measured at this seed (Release): RMS difference 0.97 % of the oracle's peak (target ≤ 2 %,
// issue 23); Tikhonov (GCV) with the stars PSFs within 0.3 dB of the oracle PSFs'. The same on the full
// crowded-stars scene (400 stars, 128²) is in README.md.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include "aosr/core/metrics.hpp"
#include "aosr/scene/dataset_memory.hpp"
#include "aosr/scene/pipeline.hpp"
#include "aosr/scene/scene_spec.hpp"
#include "aosr/solvers/dataset_problem.hpp"
#include "aosr/solvers/reconstruct.hpp"
#include "aosr/solvers/stars_psf.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

constexpr int kSeed = 7;

nlohmann::json StarScene(int frame_px, int count, bool noise) {
  nlohmann::json j = {
      {"name", "stars-psf-physics"},
      {"seed", kSeed},
      {"telescope", "paper-8m"},
      {"frames", 4},
      {"r", 2},
      {"ao", {{"mode", "analytic"}}},
      {"psf", {{"window_lambda_over_d", 64}}},
      {"offsets", {{"type", "raster"}}},
      {"photometry", {{"band", "K"}, {"throughput", 0.3}}},
      {"objects", {{{"type", "stars"}, {"count", count}, {"magnitude_range", {14, 20}}, {"alpha", 1.75},
                    {"min_separation_px", 0}}}},
      {"detector", {{"frame_px", frame_px}, {"total_exposure_s", 4.0}, {"saturation", false}}}};
  if (noise) {
    j["detector"]["sky_mag_per_arcsec2"] = 13.0;
    j["detector"]["noise"] = "physical";
    j["detector"]["read_noise_e"] = 5.0;
    j["detector"]["gain_e_per_adu"] = 2.0;
  } else {
    j["detector"]["noise"] = "none";
  }
  return j;
}

const Dataset& Field(bool noise) {
  static const Dataset noisy = [] {
    const SceneSpec scene = ParseScene(StarScene(64, 60, true), "<stars>");
    return DatasetFromSimulation(scene, ScenePipeline(scene).Run());
  }();
  static const Dataset clean = [] {
    const SceneSpec scene = ParseScene(StarScene(64, 60, false), "<stars>");
    return DatasetFromSimulation(scene, ScenePipeline(scene).Run());
  }();
  return noise ? noisy : clean;
}

// RMS difference over the estimate's window (both centred, the oracle cropped to it; each unit sum over its
// own window), relative to the oracle's peak.
// The first moment within 3 camera px (6 HR px) of the centre, about it: the stars PSF's centring convention.
FrameOffset CoreCentroid(const Image& k) {
  double s = 0, my = 0, mx = 0;
  for (Index y = 0; y < k.rows(); ++y)
    for (Index x = 0; x < k.cols(); ++x) {
      const double dy = double(y - k.rows() / 2), dx = double(x - k.cols() / 2);
      if (dy * dy + dx * dx > 36) continue;
      s += k(y, x);
      my += k(y, x) * dy;
      mx += k(y, x) * dx;
    }
  return {my / s, mx / s};
}

double RmsOverPeak(const Image& est, const Image& truth) {
  const Index k = std::min(est.rows(), truth.rows());
  const Image a = est.block(est.rows() / 2 - k / 2, est.cols() / 2 - k / 2, k, k);
  const Image b = truth.block(truth.rows() / 2 - k / 2, truth.cols() / 2 - k / 2, k, k);
  return std::sqrt((a - b).square().mean()) / b.maxCoeff();
}

TEST(StarsPsfPhysics, NoisyStarFieldGivesTheOraclePsfWithinTwoPercentOfItsPeak) {
  const Dataset& d = Field(true);
  const StarsPsfResult s = EstimateStarsPsf(d);
  std::printf("seed %d: %s, %.2f s\n", kSeed, s.BriefReport().c_str(), s.seconds);
  ASSERT_EQ(int(s.psfs.size()), d.size());
  EXPECT_GE(s.used, 20);  // of 60 stars, the ones above 5 σ
  EXPECT_LT(s.chi2_per_dof, 3.0);
  EXPECT_TRUE(s.cg_converged) << s.BriefReport();
  for (int i = 0; i < d.size(); ++i) {
    const double e = RmsOverPeak(s.psfs[i], d.psfs[i]);
    std::printf("frame %d: RMS difference / oracle peak %.4f\n", i, e);
    EXPECT_LE(e, 0.02) << "frame " << i << ", seed " << kSeed;
    // The frame's offset is carried by its PSF: core centroids agree with the oracle's (HR px).
    const FrameOffset ce = CoreCentroid(s.psfs[i]), ct = CoreCentroid(d.psfs[i]);
    EXPECT_NEAR(ce.dy, ct.dy, 0.05);
    EXPECT_NEAR(ce.dx, ct.dx, 0.05);
  }
  // Positions and fluxes of the bright stars (> 1e4 e-) against the truth catalogue: measured within 0.02 HR
  // px and 3 % (the unit sum over the K window and the light of the oracle beyond it trade off in the fluxes).
  int matched = 0;
  for (const PointSource& e : s.stars) {
    if (e.flux < 1e4) continue;
    for (const PointSource& t : d.stars)
      if (std::hypot(e.y - t.y, e.x - t.x) < 0.1) {
        std::printf("star (%.3f, %.3f) flux %.0f: fitted (%.3f, %.3f) flux %.0f\n", t.y, t.x, t.flux, e.y, e.x, e.flux);
        EXPECT_NEAR(e.flux / t.flux, 1.0, 0.05) << "star at " << t.y << ", " << t.x;
        ++matched;
      }
  }
  EXPECT_GE(matched, 3);
}

TEST(StarsPsfPhysics, TikhonovWithTheStarsPsfIsCloseToTheOracle) {
  const Dataset& d = Field(true);
  DatasetProblemOptions oracle_o, stars_o;
  oracle_o.method = stars_o.method = ReconstructionMethod::kTikhonov;
  stars_o.stars_psfs = true;
  const DatasetProblem stars = ProblemFromDataset(d, stars_o);
  ASSERT_TRUE(stars.stars_psf.has_value());
  EXPECT_TRUE(stars.model_psfs_replaced);
  ReconstructOptions ro;
  ro.method = ReconstructionMethod::kTikhonov;
  const double p_oracle = Psnr(*d.truth, Reconstruct(ProblemFromDataset(d, oracle_o).problem, ro).image);
  const double p_stars = Psnr(*d.truth, Reconstruct(stars.problem, ro).image);
  std::printf("seed %d: Tikhonov PSNR oracle PSFs %.2f dB, stars PSFs %.2f dB\n", kSeed, p_oracle, p_stars);
  EXPECT_GT(p_stars, p_oracle - 0.3);
}

TEST(StarsPsfPhysics, KnownStarsOnNoiseFreeFramesRecoverThePsf) {
  // With the true catalogue and no noise the only error left is the model's: the truth's stars are split
  // bilinearly over HR pixels (objects.hpp) where the fit shifts them band-limited, and the oracle's light
  // beyond the K window. Measured 0.10 % of the peak.
  const Dataset& d = Field(false);
  StarsPsfOptions o;
  o.known_stars = d.stars;
  o.rounds = 1;
  const StarsPsfResult s = EstimateStarsPsf(d, o);
  for (int i = 0; i < d.size(); ++i) {
    const double e = RmsOverPeak(s.psfs[i], d.psfs[i]);
    std::printf("noise-free, known stars, frame %d: RMS difference / oracle peak %.5f\n", i, e);
    EXPECT_LE(e, 0.003);
  }
}

}  // namespace
}  // namespace aosr
