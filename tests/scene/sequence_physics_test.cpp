// Physics oracles for the simulator's sequences (scene_spec.hpp, SequenceSpec; issue 34 item 1): a static sky
// repeats the cycle bit for bit, a moving star's centroid and a variable star's flux follow their laws, a moving
// extended component is its own truth shifted, a planet repeats after its period, the closed loop runs once
// through all exposures, and the dataset carries the phases, times and per-exposure truth to disk and back.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <nlohmann/json.hpp>

#include "../io/temp_dir.hpp"
#include "aosr/scene/dataset.hpp"
#include "aosr/io/fits.hpp"
#include "aosr/io/image_io.hpp"
#include "aosr/scene/dataset_memory.hpp"
#include "aosr/scene/pipeline.hpp"
#include "aosr/scene/planet.hpp"
#include "dataset_fixture.hpp"
#include "support/testing.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

using testing_io::TempDir;

// N = 4 phases of a raster, 32² camera frames at r = 2, no noise; frame time 1 s / 4 = 0.25 s. `objects` is a JSON
// array: one object goes in as json::array({object}), since a braced single json is a copy to clang, an array to GCC.
nlohmann::json Scene(nlohmann::json objects) {
  return {{"name", "sequence"},
          {"telescope", "paper-8m"},
          {"frames", 4},
          {"r", 2},
          {"seed", 3},
          {"offsets", {{"type", "raster"}}},
          {"detector", {{"frame_px", 32}, {"noise", "none"}, {"saturation", false}}},
          {"objects", std::move(objects)}};
}

double MaxAbs(const Image& a) { return a.abs().maxCoeff(); }

// First moments (y, x) of an image, in its pixels.
std::array<double, 2> Centroid(const Image& img) {
  double s = 0, y = 0, x = 0;
  for (Index i = 0; i < img.rows(); ++i)
    for (Index j = 0; j < img.cols(); ++j) s += img(i, j), y += i * img(i, j), x += j * img(i, j);
  return {y / s, x / s};
}

// A static sky: the sequence's exposure j is the single cycle's frame j mod N, bit for bit (the same offset,
// the same PSF, the same object), at M exposure times t0 + jΔ + T/2; nothing per exposure is computed beyond
// the N distinct PSFs.
TEST(SequencePhysics, StaticSkyRepeatsTheCycleBitForBit) {
  nlohmann::json j = Scene({{{"type", "usaf"}, {"flux", {{"total_e", 1e6}}}}});
  const Simulation cycle = ScenePipeline(ParseScene(j, "<test>")).Run();
  j["sequence"] = {{"frames", 10}, {"frame_interval_s", 0.4}, {"start_s", 2.0}};
  const SceneSpec spec = ParseScene(j, "<test>");
  const Simulation seq = ScenePipeline(spec).Run();
  ASSERT_EQ(seq.expected_e.size(), 10u);
  ASSERT_EQ(seq.frames.size(), 10u);
  EXPECT_EQ(seq.counters.psfs_computed, 4);
  EXPECT_TRUE(seq.truth_frames.empty());  // nothing changes
  EXPECT_EQ(MaxAbs(seq.truth - cycle.truth), 0.0);
  for (int i = 0; i < 10; ++i) {
    EXPECT_EQ(MaxAbs(seq.expected_e[i] - cycle.expected_e[i % 4]), 0.0) << "exposure " << i;
    EXPECT_DOUBLE_EQ(seq.times_s[i], 2.0 + 0.4 * i + 0.125) << "mid-exposure time";
  }
  EXPECT_TRUE(cycle.times_s.empty());
}

// A star moving at v and a star varying as 1 + a sin(2πt/P), each in its half of the frame, both on HR pixel
// centres at every exposure (v = 4 camera px / s moves 2 HR px per 0.25 s exposure; a fractional position's
// band-limited point spreads Dirichlet tails that the crop and the clip at 0 cut, ~1e-3 px): between two
// exposures of one phase (the same PSF and DM shift) the first star's frame centroid moves by v Δt camera
// pixels, and the second's flux scales by its light curve's ratio, to rounding. The truth deposits the moving
// star at its position at each exposure's mid-time.
TEST(SequencePhysics, MovingAndVariableStarsFollowTheirLaws) {
  const double vy = 4.0, vx = -4.0;  // camera px / s
  nlohmann::json j = Scene({{{"type", "stars"},
                             {"catalogue", {{{"y_px", 4.25}, {"x_px", 11.75}, {"flux_e", 5e4}}}},
                             {"variation", {{"velocity_px_per_s", {vy, vx}}}}},
                            {{"type", "stars"},
                             {"catalogue", {{{"y_px", 15.25}, {"x_px", 23.75}, {"flux_e", 4e4}}}},
                             {"variation", {{"light_curve", {{"kind", "sine"}, {"period_s", 1.7}, {"amplitude", 0.6}, {"phase_deg", 30}}}}}}});
  j["psf"] = {{"size_px", 16}};  // 8 camera pixels: the two stars' light stays apart and inside the frame
  j["sequence"] = {{"frames", 8}};
  const SceneSpec spec = ParseScene(j, "<test>");
  const Simulation sim = ScenePipeline(spec).Run();
  ASSERT_EQ(sim.truth_frames.size(), 8u);
  EXPECT_TRUE(sim.stars.empty()) << "changing stars are not a static catalogue";
  auto left = [&](int i) { return Image(sim.expected_e[i].leftCols(16)); };
  auto right = [&](int i) { return Image(sim.expected_e[i].rightCols(16)); };
  const ObjectVariation& curve = spec.objects[1].variation;
  for (int i = 4; i < 8; ++i) {
    const int q = i % 4;
    const double dt = sim.times_s[i] - sim.times_s[q];
    const auto c = Centroid(left(i)), c0 = Centroid(left(q));
    EXPECT_NEAR(c[0] - c0[0], vy * dt, 1e-9) << "exposure " << i;
    EXPECT_NEAR(c[1] - c0[1], vx * dt, 1e-9) << "exposure " << i;
    const double ratio = curve.FluxFactor(sim.times_s[i]) / curve.FluxFactor(sim.times_s[q]);
    EXPECT_NEAR(right(i).sum() / right(q).sum(), ratio, 1e-12) << "exposure " << i;
    EXPECT_NEAR(right(i).sum(), 4e4 * curve.FluxFactor(sim.times_s[i]), 1e-9 * 4e4) << "all its light, scaled";
  }
  for (int i = 0; i < 8; ++i) {
    const auto c = Centroid(sim.truth_frames[i].leftCols(32));
    EXPECT_NEAR(c[0], (4.25 + vy * sim.times_s[i] + 0.5) * 2 - 0.5, 1e-9);
    EXPECT_NEAR(c[1], (11.75 + vx * sim.times_s[i] + 0.5) * 2 - 0.5, 1e-9);
  }
  double mean = 0;
  for (const Image& t : sim.truth_frames) mean += t.sum() / 8;
  EXPECT_NEAR(sim.truth.sum(), mean, 1e-9 * mean) << "the truth is the sequence's mean";
}

// An extended component moving by a whole number of HR pixels per exposure is its own first exposure shifted
// (the Fourier shift is exact there), with its flux kept while it stays inside the frame; at t = T/2 it has
// moved by v·T/2 from where the static scene puts it.
TEST(SequencePhysics, MovingExtendedComponentIsItsTruthShifted) {
  // 4 camera px / s at r = 2: 8 HR px / s, 2 HR px per 0.25 s exposure; t0 = 0.125 s: 1 HR px.
  nlohmann::json galaxies = {{"type", "galaxies"}, {"count", 4}, {"half_light_radius_px", {0.4, 0.8}},
                             {"sersic_n_range", {0.5, 1.0}}, {"margin_px", 10.0}, {"flux", {{"total_e", 1e5}}}};
  nlohmann::json j = Scene(nlohmann::json::array({galaxies}));
  const Simulation still = ScenePipeline(ParseScene(j, "<test>")).Run();
  galaxies["variation"] = {{"velocity_px_per_s", {0.0, 4.0}}};
  j = Scene(nlohmann::json::array({galaxies}));
  j["sequence"] = {{"frames", 6}};
  const Simulation sim = ScenePipeline(ParseScene(j, "<test>")).Run();
  ASSERT_EQ(sim.truth_frames.size(), 6u);
  const double peak = MaxAbs(still.truth);
  const Index cols = still.truth.cols();
  EXPECT_LT(MaxAbs(sim.truth_frames[0].rightCols(cols - 1) - still.truth.leftCols(cols - 1)), 1e-9 * peak);
  for (int i = 1; i < 6; ++i) {
    const Index d = 2 * i;
    EXPECT_LT(MaxAbs(sim.truth_frames[i].rightCols(cols - d) - sim.truth_frames[0].leftCols(cols - d)), 1e-9 * peak)
        << "exposure " << i;
    EXPECT_NEAR(sim.truth_frames[i].sum(), 1e5, 1e-6 * 1e5) << "exposure " << i;
  }
}

// What leaves the frame is gone: a star past the edge is neither deposited on the border of the truth nor brought
// back from the other side by the periodic grid, and an extended component moved farther than the frame is
// nothing (its padding is bounded by the frame, so a huge displacement costs no memory).
TEST(SequencePhysics, WhatLeavesTheFrameIsGone) {
  nlohmann::json j = Scene({{{"type", "stars"}, {"catalogue", {{{"y_px", 16.25}, {"x_px", 28.25}, {"flux_e", 1e4}}}},
                             {"variation", {{"velocity_px_per_s", {0.0, 8.0}}}}}});
  j["sequence"] = {{"frames", 8}};  // x = 28.25 + 8 t: off the frame (x > 31.5) from t = 0.41 s, exposure 2 on
  const Simulation sim = ScenePipeline(ParseScene(j, "<test>")).Run();
  for (int i = 0; i < 8; ++i) {
    const bool on = 28.25 + 8 * sim.times_s[i] <= 31.5;
    EXPECT_EQ(on, i < 2) << "exposure " << i;
    EXPECT_NEAR(sim.truth_frames[i].sum(), on ? 1e4 : 0.0, 1e-9 * 1e4) << "exposure " << i;
    if (!on) { EXPECT_EQ(sim.expected_e[i].abs().maxCoeff(), 0.0) << "exposure " << i << ": nothing comes back"; }
  }
  nlohmann::json edge = {{"type", "slanted-edge"}, {"variation", {{"velocity_px_per_s", {0.0, 100.0}}}}};
  j = Scene(nlohmann::json::array({edge}));
  j["sequence"] = {{"frames", 5}, {"frame_interval_s", 1e9}};
  const Simulation far = ScenePipeline(ParseScene(j, "<test>")).Run();
  EXPECT_GT(far.truth_frames[0].sum(), 0.0) << "exposure 0 (t = 0.125 s) has moved 12.5 camera px: still there";
  for (int i = 1; i < 5; ++i) EXPECT_EQ(far.truth_frames[i].abs().maxCoeff(), 0.0) << "exposure " << i << ": gone";
}

// A rotating planet: exposures one period apart see the same face (and, in the same phase, give the same
// frame), exposures in between do not; its flux normalisation holds at t = 0 and the limb-darkened disc's
// light is constant for a texture of bands only (rotation moves nothing then).
TEST(SequencePhysics, PlanetRepeatsAfterItsPeriod) {
  nlohmann::json planet = {{"type", "planet"}, {"radius_px", 9.0}, {"rotation_period_s", 1.0}, {"limb_darkening", 0.4},
                           {"pole_angle_deg", 20.0}, {"sub_observer_latitude_deg", 10.0},
                           {"texture", {{"spots", 6}, {"spot_radius_deg", 12.0}}}, {"flux", {{"total_e", 2e5}}}};
  nlohmann::json j = Scene(nlohmann::json::array({planet}));
  j["sequence"] = {{"frames", 8}};  // Δ = 0.25 s: exposure j + 4 is one period after j
  const Simulation sim = ScenePipeline(ParseScene(j, "<test>")).Run();
  ASSERT_EQ(sim.truth_frames.size(), 8u);
  const double peak = MaxAbs(sim.truth_frames[0]);
  for (int i = 0; i < 4; ++i) {
    EXPECT_LT(MaxAbs(sim.truth_frames[i + 4] - sim.truth_frames[i]), 1e-12 * peak) << "exposure " << i;
    EXPECT_LT(MaxAbs(sim.expected_e[i + 4] - sim.expected_e[i]), 1e-12 * MaxAbs(sim.expected_e[i])) << "exposure " << i;
  }
  EXPECT_GT(MaxAbs(sim.truth_frames[1] - sim.truth_frames[0]), 0.05 * peak) << "the spots move";
  planet["texture"] = {{"spots", 0}};
  j = Scene(nlohmann::json::array({planet}));
  j["sequence"] = {{"frames", 5}};
  const Simulation bands = ScenePipeline(ParseScene(j, "<test>")).Run();
  // Bands only: the same light at every rotation, the total_e its normalisation gave at t = 0.
  for (int i = 0; i < 5; ++i) EXPECT_NEAR(bands.truth_frames[i].sum(), 2e5, 1e-6 * 2e5) << "exposure " << i;
  // A planet that does not turn is a static component: the sequence's truth is the cycle's, with the same flux.
  planet["rotation_period_s"] = 0.0;
  j = Scene(nlohmann::json::array({planet}));
  const Simulation still = ScenePipeline(ParseScene(j, "<test>")).Run();
  EXPECT_NEAR(still.truth.sum(), 2e5, 1e-9 * 2e5);
  EXPECT_LT(MaxAbs(still.truth - bands.truth_frames[0]), 1e-9 * MaxAbs(still.truth)) << "the same face at every time";
}

// A planet's map from a file (texture_path, an equirectangular image): the truth is RenderPlanet of that map on
// the HR frame, at the camera-pixel geometry converted to HR pixels, in surface brightness per camera-pixel area.
TEST(SequencePhysics, PlanetMapFromAFile) {
  TempDir dir;
  Image map(18, 36);
  for (Index i = 0; i < map.rows(); ++i)
    for (Index k = 0; k < map.cols(); ++k) map(i, k) = 1.0 + 0.5 * std::sin(0.7 * double(k)) + 0.02 * double(i);
  WriteFits(dir.File("map.fits"), map);
  nlohmann::json j = Scene({{{"type", "planet"}, {"radius_px", 6.0}, {"centre_px", {15.0, 17.5}},
                             {"rotation_period_s", 2.0}, {"texture_path", dir.File("map.fits")}}});
  j["sequence"] = {{"frames", 4}};
  const Simulation sim = ScenePipeline(ParseScene(j, "<test>")).Run();
  PlanetOptions p;
  p.radius_px = 12.0;  // r = 2
  p.centre_y = 30.5, p.centre_x = 35.5;
  p.rotation_period_s = 2.0;
  const Image stored = ReadImage(dir.File("map.fits"));  // the map as the file holds it (float32)
  EXPECT_LT(MaxAbs(stored - map), 1e-6 * MaxAbs(map));
  for (int i = 0; i < 4; ++i) {
    const Image expected = RenderPlanet({64, 64}, p, stored, sim.times_s[i]) / 4.0;
    EXPECT_LT(MaxAbs(sim.truth_frames[i] - expected), 1e-12 * MaxAbs(expected)) << "exposure " << i;
  }
}

// The closed loop runs once, continuously, through the M exposures: its first N exposures are the single
// cycle's (same seed, same atmosphere), the later ones are new stretches of turbulence (exposure j + N is not
// exposure j), every exposure runs its settling and its steps, and the nominal model stays one per phase.
TEST(SequencePhysics, ClosedLoopRunsOnceThroughTheSequence) {
  nlohmann::json j = Scene({{{"type", "usaf"}, {"flux", {{"total_e", 1e6}}}}});
  j["frames"] = 2;
  j["ao"] = {{"mode", "closed-loop"}, {"sensor", "ideal"}, {"time_per_frame_s", 0.01}, {"settling_s", 0.005}, {"antithetic", false}};
  const Simulation cycle = ScenePipeline(ParseScene(j, "<test>")).Run();
  j["sequence"] = {{"frames", 5}};
  const Simulation seq = ScenePipeline(ParseScene(j, "<test>")).Run();
  ASSERT_EQ(seq.psfs.size(), 5u);
  EXPECT_EQ(seq.counters.loop_steps, 5 * (8 + 4));
  EXPECT_EQ(seq.nominal_psfs.size(), 2u);
  for (int i = 0; i < 2; ++i) EXPECT_EQ(MaxAbs(seq.psfs[i] - cycle.psfs[i]), 0.0) << "exposure " << i;
  for (int i = 2; i < 5; ++i) {
    const double diff = (seq.psfs[i] - seq.psfs[i - 2]).abs().sum();
    EXPECT_GT(diff, 1e-4) << "exposure " << i << " is a new stretch of turbulence";
    EXPECT_LT(diff, 0.5) << "of the same AO system";
  }
}

// On disk and in memory: M frames, their phases j mod N and times, the per-exposure truth, and per-phase PSFs
// expanded to the frames; DatasetFromSimulation gives what LoadDataset reads, bit for bit.
TEST(SequencePhysics, DatasetCarriesPhasesTimesAndTruthPerFrame) {
  TempDir dir;
  nlohmann::json j = test::SmallDatasetScene();  // N = 2
  j["sequence"] = {{"frames", 5}, {"frame_interval_s", 0.6}};
  j["objects"][1]["variation"] = {{"velocity_px_per_s", {1.0, -2.0}},
                                  {"light_curve", {{"kind", "table"}, {"times_s", {0.0, 1.0, 3.0}}, {"factors", {1.0, 0.2, 1.5}}}}};
  const test::WrittenSimulation w = test::SimulateInto(dir.File("scene.json"), j, dir.File("sim"));
  const Dataset d = LoadDataset(dir.File("sim"));
  ASSERT_EQ(d.size(), 5);
  EXPECT_EQ(d.slot_count, 2);
  EXPECT_EQ(d.slots, (std::vector<int>{0, 1, 0, 1, 0}));
  ASSERT_EQ(d.times_s.size(), 5u);
  ASSERT_EQ(d.truth_frames.size(), 5u);
  for (int i = 0; i < 5; ++i) {
    EXPECT_DOUBLE_EQ(d.times_s[i], 0.6 * i + 0.25);
    EXPECT_EQ(MaxAbs(d.truth_frames[i] - w.sim.truth_frames[i]), 0.0);
    EXPECT_EQ(MaxAbs(d.psfs[i] - d.psfs[i % 2]), 0.0);
    EXPECT_TRUE(d.offsets[i] == w.scene.offsets.frames[i % 2]);
  }
  const Dataset m = DatasetFromSimulation(w.scene, w.sim);
  EXPECT_EQ(m.slots, d.slots);
  EXPECT_EQ(m.slot_count, d.slot_count);
  EXPECT_EQ(m.times_s, d.times_s);
  ASSERT_EQ(m.psfs.size(), 5u);
  ASSERT_EQ(m.truth_frames.size(), 5u);
  for (int i = 0; i < 5; ++i) {
    EXPECT_EQ(MaxAbs(m.psfs[i] - d.psfs[i]), 0.0);
    EXPECT_EQ(MaxAbs(m.frames[i] - d.frames[i]), 0.0);
    EXPECT_EQ(MaxAbs(m.truth_frames[i] - d.truth_frames[i]), 0.0);
  }
  // A window of the sequence keeps its frames' truth.
  const Dataset window = SelectFrames(d, {3, 4});
  ASSERT_EQ(window.truth_frames.size(), 2u);
  EXPECT_EQ(MaxAbs(window.truth_frames[1] - d.truth_frames[4]), 0.0);
}

}  // namespace AOSR_TEST_NS
}  // namespace aosr
