// The compiled pipeline: which stages a scene enables, and proof that disabled effects cost nothing.
#include "aosr/scene/pipeline.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include "aosr/core/fft.hpp"
#include "aosr/ao/phase_screen.hpp"
#include "support/testing.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

// A small, cheap scene: paper-8m optics without turbulence, 32-px frames, r = 2, no noise.
nlohmann::json BaseScene() {
  return {{"name", "test"},
          {"telescope", "paper-8m"},
          {"frames", 4},
          {"r", 2},
          {"detector", {{"frame_px", 32}, {"noise", "none"}, {"saturation", false}}},
          {"objects", nlohmann::json::array({{{"type", "demo"}, {"flux", {{"peak_e", 100.0}}}}})}};
}

std::vector<std::string> StageNames(const ScenePipeline& p) {
  std::vector<std::string> names;
  for (const PipelineStage& s : p.stages()) names.push_back(s.name);
  return names;
}

TEST(ScenePipeline, MinimalSceneHasOnlyTheCoreStages) {
  const ScenePipeline p(ParseScene(BaseScene(), "<test>"));
  EXPECT_THAT(StageNames(p), ::testing::ElementsAre("object", "psf", "convolution", "pixel-integration", "detector"));
}

TEST(ScenePipeline, EachEffectAddsItsStage) {
  nlohmann::json j = BaseScene();
  j["objects"] = nlohmann::json::array({{{"type", "stars"}, {"count", 5}, {"flux_range_e", {10.0, 100.0}}}});
  j["static_aberrations"] = nlohmann::json::array({{{"noll", 4}, {"rms_nm", 30.0}}});
  j["offsets"] = {{"type", "raster"}};
  j["ao"] = {{"mode", "analytic"}};
  const ScenePipeline p(ParseScene(j, "<test>"));
  EXPECT_THAT(StageNames(p), ::testing::ElementsAre("object", "static-aberrations", "dm-offsets", "psf", "point-sources",
                                                    "pixel-integration", "detector"));
  j["ao"] = {{"mode", "closed-loop"}, {"sensor", "ideal"}, {"time_per_frame_s", 0.01}, {"settling_s", 0.0}};
  j["objects"].push_back({{"type", "demo"}});
  const ScenePipeline q(ParseScene(j, "<test>"));
  EXPECT_THAT(StageNames(q), ::testing::ElementsAre("object", "static-aberrations", "dm-offsets", "ao-loop", "psf", "nominal-psf",
                                                    "convolution", "point-sources", "pixel-integration", "detector"));
}

TEST(ScenePipeline, CompilingComputesNothing) {
  nlohmann::json j = BaseScene();
  j["ao"] = {{"mode", "analytic"}};
  j["offsets"] = {{"type", "raster"}};
  const std::uint64_t ffts = FftExecutionCount();
  const std::uint64_t screens = PhaseScreensGenerated();
  const ScenePipeline p(ParseScene(j, "<test>"));
  EXPECT_EQ(FftExecutionCount(), ffts);
  EXPECT_EQ(PhaseScreensGenerated(), screens);
  EXPECT_NE(p.PlanReport().find("analytic AO PSF"), std::string::npos) << p.PlanReport();
}

TEST(ScenePipeline, StaticPsfIsComputedOnceAndNothingDisabledRuns) {
  const ScenePipeline p(ParseScene(BaseScene(), "<test>"));
  const Simulation sim = p.Run();
  EXPECT_EQ(sim.counters.psfs_computed, 1);     // no offsets: one PSF shared by the 4 exposures
  EXPECT_EQ(sim.counters.frame_transforms, 1);  // and one convolution
  EXPECT_EQ(sim.counters.phase_screens, 0u);    // no atmosphere: no phase screen is ever generated
  EXPECT_EQ(sim.counters.loop_steps, 0);
  EXPECT_EQ(sim.counters.noise_draws, 0);       // noise "none": no random number drawn
  ASSERT_EQ(sim.frames.size(), 4u);
  for (const DetectorFrame& f : sim.frames) EXPECT_EQ((f.adu - sim.frames[0].adu).abs().maxCoeff(), 0.0);
  EXPECT_THAT(sim.distinct_psf, ::testing::ElementsAre(0, 0, 0, 0));
}

// Run's progress callback (core/progress.hpp): steps after the object, each distinct PSF and each later stage;
// it changes nothing, and returning false stops the run with Simulation::cancelled.
TEST(ScenePipeline, ProgressReportsEveryStepAndCancels) {
  const ScenePipeline p(ParseScene(BaseScene(), "<test>"));
  const Simulation quiet = p.Run();
  std::vector<Progress> seen;
  const Simulation watched = p.Run([&seen](const Progress& q) {
    seen.push_back(q);
    return true;
  });
  ASSERT_GE(seen.size(), 2u);
  EXPECT_EQ(seen.front().stage, "simulate");
  EXPECT_EQ(seen.back().iteration, seen.back().total);
  EXPECT_EQ(seen.back().total, 4 + 1);  // object, 1 distinct PSF, convolution, pixels, detector
  EXPECT_FALSE(watched.cancelled);
  ASSERT_EQ(watched.frames.size(), quiet.frames.size());
  for (std::size_t i = 0; i < quiet.frames.size(); ++i)
    EXPECT_TRUE((watched.frames[i].adu == quiet.frames[i].adu).all());
  int calls = 0;
  const Simulation cut = p.Run([&calls](const Progress&) { return ++calls < 1; });
  EXPECT_TRUE(cut.cancelled);
  EXPECT_EQ(calls, 1);
  EXPECT_TRUE(cut.frames.empty());  // stopped after the object
}

TEST(ScenePipeline, AnalyticAoNeedsNoPhaseScreen) {
  nlohmann::json j = BaseScene();
  j["ao"] = {{"mode", "analytic"}};
  const Simulation sim = ScenePipeline(ParseScene(j, "<test>")).Run();
  EXPECT_EQ(sim.counters.phase_screens, 0u);
  EXPECT_LT(sim.strehl[0], 0.95);  // the AO residual is there
  EXPECT_GT(sim.strehl[0], 0.5);
}

TEST(ScenePipeline, ClosedLoopGeneratesScreensAndRunsTheLoop) {
  nlohmann::json j = BaseScene();
  j["frames"] = 2;
  j["ao"] = {{"mode", "closed-loop"}, {"sensor", "ideal"}, {"time_per_frame_s", 0.01}, {"settling_s", 0.005}};
  const Simulation sim = ScenePipeline(ParseScene(j, "<test>")).Run();
  EXPECT_GT(sim.counters.phase_screens, 0u);  // the counter sees the atmosphere when there is one
  // Two runs by default (ao.antithetic: the atmosphere and its negation), each 2 exposures of 8 + 4 frames.
  EXPECT_EQ(sim.counters.loop_steps, 2 * 2 * (8 + 4));
  EXPECT_EQ(sim.counters.psfs_computed, 2);  // each exposure its own stretch of turbulence
  j["ao"]["antithetic"] = false;
  EXPECT_EQ(ScenePipeline(ParseScene(j, "<test>")).Run().counters.loop_steps, 2 * (8 + 4));
}

TEST(ScenePipeline, AntitheticPairCentresTheLongExposure) {
  // ao.antithetic (scene_spec.hpp): a stretch of one realisation leaves a random residual tilt; averaged with
  // the negated atmosphere's run it cancels (odd in the atmosphere for a noiseless, linear loop), so the PSF
  // of an exposure without offset is centred: first moments about the centre pixel (K/2, K/2) below 1e-9 HR
  // px (rounding) with the pair, above 1e-4 HR px (measured ~1e-3) with one realisation. The run of the
  // negated atmosphere is the first run's PSF inverted through the centre, so the pair's PSF is symmetric
  // under that inversion (to 1e-9 of its peak), and its Strehl is the realisation's (even in the atmosphere).
  nlohmann::json j = BaseScene();
  j["frames"] = 1;
  j["ao"] = {{"mode", "closed-loop"}, {"sensor", "geometric"}, {"time_per_frame_s", 0.02}, {"settling_s", 0.01},
             {"antithetic", false}};
  std::vector<double> strehl_one, strehl_pair;
  const Image one = ScenePipeline(ParseScene(j, "<test>")).ComputePsfs(nullptr, nullptr, &strehl_one).front();
  j["ao"]["antithetic"] = true;
  const Image pair = ScenePipeline(ParseScene(j, "<test>")).ComputePsfs(nullptr, nullptr, &strehl_pair).front();
  auto moment = [](const Image& k, int axis) {
    double m = 0.0;
    for (Index y = 0; y < k.rows(); ++y)
      for (Index x = 0; x < k.cols(); ++x) m += k(y, x) * double(axis == 0 ? y - k.rows() / 2 : x - k.cols() / 2);
    return m / k.sum();
  };
  // The window is even (K x K about K/2): its inversion through the centre maps pixel p to K - p, so compare
  // on the odd-sized interior [1, K).
  const Index k = pair.rows();
  const Image interior_one = one.block(1, 1, k - 1, k - 1), interior_pair = pair.block(1, 1, k - 1, k - 1);
  EXPECT_LT((interior_pair - interior_pair.reverse()).abs().maxCoeff(), 1e-9 * pair.maxCoeff());
  EXPECT_GT((interior_one - interior_one.reverse()).abs().maxCoeff(), 1e-4 * one.maxCoeff());
  for (int axis = 0; axis < 2; ++axis) {
    EXPECT_GT(std::abs(moment(interior_one, axis) - 0.0), 1e-4) << axis;
    EXPECT_LT(std::abs(moment(interior_pair, axis)), 1e-9) << axis;
  }
  EXPECT_GT(strehl_pair[0], 0.5);
  EXPECT_NEAR(strehl_pair[0], strehl_one[0], 1e-9);
}

TEST(ScenePipeline, DmGainChangesTheLoopButNotTheNominalModel) {
  // ao.dm_gain is a hardware error: the loop's PSFs change (same seed, same turbulence), the nominal model
  // (NominalPsfs, what the observer computes) is the same bytes as with a correct mirror.
  nlohmann::json j = BaseScene();
  j["frames"] = 2;
  j["ao"] = {{"mode", "closed-loop"}, {"sensor", "geometric"}, {"time_per_frame_s", 0.01}, {"settling_s", 0.005}};
  const SceneSpec exact = ParseScene(j, "<test>");
  j["ao"]["dm_gain"] = 1.1;
  const SceneSpec wrong = ParseScene(j, "<test>");
  const ImageStack a = ScenePipeline(exact).ComputePsfs(nullptr, nullptr, nullptr);
  const ImageStack b = ScenePipeline(wrong).ComputePsfs(nullptr, nullptr, nullptr);
  ASSERT_EQ(a.size(), 2u);
  ASSERT_EQ(b.size(), 2u);
  EXPECT_GT((a[0] - b[0]).abs().sum(), 1e-6);
  const ImageStack na = NominalPsfs(exact), nb = NominalPsfs(wrong);
  ASSERT_EQ(na.size(), 2u);
  ASSERT_EQ(nb.size(), 2u);
  for (int i = 0; i < 2; ++i) EXPECT_EQ((na[i] - nb[i]).abs().maxCoeff(), 0.0);
}

// A noisy guide-star WFS reaches the nominal model through the analytic noise term (TelescopePreset::
// ToAnalyticAo measures it through the diffractive sensor): the noisy model's PSF is broader (lower peak),
// and photon-limited its noise variance is 10x at 2.5 magnitudes fainter. With the ideal or
// geometric sensor the truth's WFS is noiseless (only the diffractive one simulates photons), and the model is
// the noiseless one, byte for byte.
TEST(ScenePipeline, NominalModelCarriesTheGuideStarsWfsNoise) {
  nlohmann::json j = BaseScene();
  j["frames"] = 1;
  j["ao"] = {{"mode", "closed-loop"}, {"sensor", "diffractive"}, {"time_per_frame_s", 0.01}, {"settling_s", 0.005}};
  const SceneSpec quiet = ParseScene(j, "<test>");
  SceneSpec noisy = quiet;
  noisy.telescope.ao->wfs.photon_noise = true;
  noisy.telescope.ao->wfs.guide_star_magnitude = 8.0;
  SceneSpec fainter = noisy;
  fainter.telescope.ao->wfs.guide_star_magnitude = 10.5;
  const double s_noisy = noisy.telescope.ToAnalyticAo().wfs_noise_rad2;
  EXPECT_EQ(quiet.telescope.ToAnalyticAo().wfs_noise_rad2, 0.0);
  EXPECT_GT(s_noisy, 0.0);
  EXPECT_NEAR(fainter.telescope.ToAnalyticAo().wfs_noise_rad2 / s_noisy, 10.0, 1.5);
  const ImageStack q = NominalPsfs(quiet), n = NominalPsfs(noisy);
  ASSERT_EQ(q.size(), 1u);
  ASSERT_EQ(n.size(), 1u);
  EXPECT_LT(n[0].maxCoeff(), q[0].maxCoeff() * (1 - 1e-4));
  SceneSpec ideal = noisy;
  ideal.ao.sensor = SensorKind::kIdeal;
  SceneSpec ideal_quiet = quiet;
  ideal_quiet.ao.sensor = SensorKind::kIdeal;
  EXPECT_EQ((NominalPsfs(ideal)[0] - NominalPsfs(ideal_quiet)[0]).abs().maxCoeff(), 0.0);
}

TEST(ScenePipeline, StarsOnlySceneDoesNoObjectTransform) {
  nlohmann::json j = BaseScene();
  j["objects"] = nlohmann::json::array({{{"type", "stars"}, {"count", 20}, {"flux_range_e", {10.0, 1000.0}}}});
  j["offsets"] = {{"type", "raster"}};
  const Simulation sim = ScenePipeline(ParseScene(j, "<test>")).Run();
  EXPECT_EQ(sim.counters.object_transforms, 0);
  EXPECT_EQ(sim.counters.frame_transforms, 4);
  EXPECT_EQ(sim.stars.size(), 20u);
}

TEST(ScenePipeline, RasterGivesOnePsfPerExposureAndGeometryIsConsistent) {
  nlohmann::json j = BaseScene();
  j["offsets"] = {{"type", "raster"}};
  const ScenePipeline p(ParseScene(j, "<test>"));
  const SceneGeometry& g = p.geometry();
  EXPECT_EQ(g.hr_frame.rows, 64);
  EXPECT_EQ(g.psf_size, 64);  // 32 lambda/D at lambda/(2D) per HR pixel
  EXPECT_GE(g.padded.rows, g.hr_frame.rows + g.psf_size);
  EXPECT_EQ(g.trustworthy_border_px, 16);
  const Simulation sim = p.Run();
  EXPECT_EQ(sim.counters.psfs_computed, 4);
  EXPECT_THAT(sim.distinct_psf, ::testing::ElementsAre(0, 1, 2, 3));
  for (const Image& h : sim.psfs) EXPECT_NEAR(h.sum(), 1.0, 1e-12);
  for (double f : sim.psf_window_fraction) EXPECT_GT(f, 0.95);  // an unaberrated PSF keeps >95% in 32 lambda/D
}

TEST(ScenePipeline, NoiseStreamsAreIndependentOfOtherEffects) {
  nlohmann::json j = BaseScene();
  j["detector"] = {{"frame_px", 32}, {"noise", "physical"}, {"read_noise_e", 3.0}, {"saturation", false}};
  const Simulation a = ScenePipeline(ParseScene(j, "<test>")).Run();
  const Simulation b = ScenePipeline(ParseScene(j, "<test>")).Run();
  EXPECT_EQ((a.frames[1].adu - b.frames[1].adu).abs().maxCoeff(), 0.0);  // deterministic
  EXPECT_GT((a.frames[0].adu - a.frames[1].adu).abs().maxCoeff(), 0.0);  // frames draw their own noise
  j["seed"] = 7;
  const Simulation c = ScenePipeline(ParseScene(j, "<test>")).Run();
  EXPECT_GT((a.frames[0].adu - c.frames[0].adu).abs().maxCoeff(), 0.0);
}

}  // namespace
}  // namespace aosr
