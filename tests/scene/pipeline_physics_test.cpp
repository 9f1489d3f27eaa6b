// Physics oracles for the simulator: with the effects off the frames are the analytic D_r(h_i * x), flux
// is conserved through every noiseless stage, the point-source path equals the FFT path, and a flat field's
// frame statistics follow the detector model.
#include <gtest/gtest.h>

#include <cstdio>
#include <fstream>
#include <nlohmann/json.hpp>

#include "aosr/core/operators.hpp"
#include "aosr/io/fits.hpp"
#include "aosr/scene/pipeline.hpp"
#include "aosr/scene/point_sources.hpp"
#include "../io/temp_dir.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

nlohmann::json Scene(nlohmann::json objects, int frame_px = 32) {
  return {{"name", "physics"},
          {"telescope", "paper-8m"},
          {"frames", 4},
          {"r", 2},
          {"offsets", {{"type", "raster"}}},
          {"detector", {{"frame_px", frame_px}, {"noise", "none"}, {"saturation", false}}},
          {"objects", std::move(objects)}};
}

Image Decimated(const Image& hr, int r) {
  const Shape lr{hr.rows() / r, hr.cols() / r};
  return ToImage(Decimate(ShapeOf(hr), r)->Apply(AsVector(hr)), lr);
}

// No atmosphere, no noise: each frame is D_r of the linear (zero-padded) convolution of the object with the
// exposure's windowed PSF, the analytic model, to rounding.
TEST(PipelinePhysics, NoAtmosphereNoNoiseFramesAreDrOfTheConvolution) {
  nlohmann::json j = Scene({{{"type", "usaf"}, {"flux", {{"total_e", 1e6}}}}});
  j["static_aberrations"] = nlohmann::json::array({{{"noll", 7}, {"rms_nm", 40.0}}});
  const Simulation sim = ScenePipeline(ParseScene(j, "<test>")).Run();
  const Shape hr = sim.geometry.hr_frame;
  for (int i = 0; i < 4; ++i) {
    const Image conv = ToImage(LinearConvolution(hr, sim.psfs[i])->Apply(AsVector(sim.truth)), hr);
    const Image expected = Decimated(conv, 2);
    const double peak = expected.abs().maxCoeff();
    EXPECT_LT((sim.expected_e[i] - expected).abs().maxCoeff(), 1e-12 * peak) << "frame " << i;
    EXPECT_LT((sim.frames[i].adu - expected).abs().maxCoeff(), 1e-12 * peak) << "gain 1, bias 0";
  }
}

// A compact object far from the frame edges keeps all its light: object -> convolution -> crop -> D_r ->
// read-out (gain and bias undone) conserve the total to 1e-10.
TEST(PipelinePhysics, FluxIsConservedThroughEveryNoiselessStage) {
  nlohmann::json j = Scene({{{"type", "galaxies"}, {"count", 3}, {"half_light_radius_px", {0.3, 0.6}}, {"sersic_n_range", {0.5, 1.0}},
                             {"margin_px", 24.0}, {"flux", {{"total_e", 5e4}}}},
                            {{"type", "stars"}, {"catalogue", {{{"y_px", 31.25}, {"x_px", 32.75}, {"flux_e", 2e3}}}}}},
                           64);
  j["ao"] = {{"mode", "analytic"}};
  j["detector"]["gain_e_per_adu"] = 2.5;
  j["detector"]["bias_adu"] = 100.0;
  const ScenePipeline p(ParseScene(j, "<test>"));
  const Simulation sim = p.Run();
  const double truth_total = 5e4 + 2e3;
  EXPECT_NEAR(sim.truth.sum(), truth_total, 1e-10 * truth_total);
  for (int i = 0; i < 4; ++i) {
    // Exponential-or-steeper galaxies (n <= 1) of R_e <= 1.2 HR px hold < 1e-20 of their light beyond the
    // 48-HR-px margin, and the star sits on an HR pixel centre (a fractional position's band-limited point
    // would spread Dirichlet tails over the whole padded grid, some of which the crop removes).
    EXPECT_NEAR(sim.expected_e[i].sum(), truth_total, 1e-10 * truth_total) << "frame " << i;
    const double read_out = ((sim.frames[i].adu.array() - 100.0) * 2.5).sum();
    EXPECT_NEAR(read_out, truth_total, 1e-10 * truth_total) << "frame " << i;
  }
}

// Stars at integer HR positions are plain deltas: the exact point-source path then equals the linear
// convolution of the delta image; at fractional positions it equals convolving the band-limited point image
// on the same padded grid by FFT (the acceptance's 1e-6 of peak; it is rounding).
TEST(PipelinePhysics, PointSourcePathEqualsFftPath) {
  nlohmann::json cat = nlohmann::json::array();
  for (int k = 0; k < 12; ++k)
    cat.push_back({{"y_px", 4.25 + 2.0 * k}, {"x_px", 27.75 - 2.0 * k}, {"flux_e", 100.0 * (k + 1)}});
  const ScenePipeline p(ParseScene(Scene({{{"type", "stars"}, {"catalogue", cat}}}), "<test>"));
  const Simulation sim = p.Run();
  const SceneGeometry& g = sim.geometry;
  ASSERT_EQ(sim.counters.object_transforms, 0);
  std::vector<PointSource> padded = sim.stars;
  for (PointSource& s : padded) s.y += double(g.pad_top), s.x += double(g.pad_left);
  const Image points = PointSourceImage(g.padded, padded);
  for (int i = 0; i < 4; ++i) {
    const Image conv = ToImage(PeriodicConvolutionFromKernel(g.padded, sim.psfs[i])->Apply(AsVector(points)), g.padded);
    const Image expected = Decimated(conv.block(g.pad_top, g.pad_left, g.hr_frame.rows, g.hr_frame.cols), 2);
    EXPECT_LT((sim.expected_e[i] - expected).abs().maxCoeff(), 1e-6 * expected.maxCoeff()) << "frame " << i;
  }
  // (y + 0.5) r - 0.5 with y = 4.25 + 2k, r = 2: 8 + 4k, integral. Those HR positions are exact deltas.
  nlohmann::json whole = nlohmann::json::array();
  for (int k = 0; k < 6; ++k) whole.push_back({{"y_px", 4.25 + 4.0 * k}, {"x_px", 10.25 + 3.0 * k}, {"flux_e", 50.0}});
  const Simulation w = ScenePipeline(ParseScene(Scene({{{"type", "stars"}, {"catalogue", whole}}}), "<test>")).Run();
  for (int i = 0; i < 4; ++i) {
    const Image conv = ToImage(LinearConvolution(g.hr_frame, w.psfs[i])->Apply(AsVector(w.truth)), g.hr_frame);
    EXPECT_LT((w.expected_e[i] - Decimated(conv, 2)).abs().maxCoeff(), 1e-10 * 50.0) << "frame " << i;
  }
}

// A flat field through the whole chain: away from the dark-sky border the frame has mean (expected) and
// variance mean/g + (read/g)^2 within 2% over ~10^6 pixels.
TEST(PipelinePhysics, FlatFieldVarianceFollowsTheDetectorModel) {
  testing_io::TempDir dir;
  const std::string flat = dir.File("flat.fits");
  WriteFits(flat, Image::Constant(16, 16, 1.0), FitsHeader(), FitsType::kFloat64);
  const int side = 1040;
  nlohmann::json j = Scene({{{"type", "image"}, {"path", flat}, {"flux", {{"peak_e", 800.0}}}}}, side);
  j["r"] = 1;
  j["frames"] = 1;
  j["offsets"] = {{"type", "none"}};
  j["psf"] = {{"size_px", 16}};
  j["detector"] = {{"frame_px", side}, {"noise", "physical"}, {"gain_e_per_adu", 2.0}, {"read_noise_e", 6.0},
                   {"bias_adu", 50.0}, {"saturation", false}};
  const Simulation sim = ScenePipeline(ParseScene(j, dir.File("scene.json"))).Run();
  const Index b = 20;  // beyond the 8-px border where the flat field meets the dark sky
  const Image adu = sim.frames[0].adu.block(b, b, side - 2 * b, side - 2 * b);
  const Image mean_e = sim.expected_e[0].block(b, b, side - 2 * b, side - 2 * b);
  ASSERT_LT(mean_e.maxCoeff() - mean_e.minCoeff(), 1e-9 * mean_e.maxCoeff()) << "the interior is flat";
  const double n = double(adu.size());
  const double mean = adu.mean();
  const double var = (adu.array() - mean).square().sum() / (n - 1);
  const double expected_mean = mean_e(0, 0) / 2.0 + 50.0;
  const double expected_var = (expected_mean - 50.0) / 2.0 + (6.0 / 2.0) * (6.0 / 2.0);
  EXPECT_NEAR(mean, expected_mean, 1e-3 * expected_mean);
  EXPECT_NEAR(var / expected_var, 1.0, 0.02) << "n = " << n;
}

// sky_oversampling (pipeline.hpp): the frames come from a sky s times finer than the HR grid, the outputs stay on
// the HR grid. Flux is conserved through every noiseless stage as at s = 1 (the same compact scene as above),
// the truth is the HR grid's, the stars are in HR coordinates, and the PSFs are the HR-pitch PSFs ComputePsfs
// gives (every s-th sample of the fine ones, renormalised), to rounding.
TEST(PipelinePhysics, SkyOversamplingConservesFluxAndKeepsTheHrOutputs) {
  nlohmann::json j = Scene({{{"type", "galaxies"}, {"count", 3}, {"half_light_radius_px", {0.3, 0.6}}, {"sersic_n_range", {0.5, 1.0}},
                             {"margin_px", 24.0}, {"flux", {{"total_e", 5e4}}}},
                            {{"type", "stars"}, {"catalogue", {{{"y_px", 31.0625}, {"x_px", 32.9375}, {"flux_e", 2e3}}}}}},
                           64);
  j["ao"] = {{"mode", "analytic"}};
  // The star on a fine-grid pixel centre ((y + 0.5) r s - 0.5 = 252 and 267 at r s = 8), as above.
  j["sky_oversampling"] = 4;
  const ScenePipeline p(ParseScene(j, "<test>"));
  const Simulation sim = p.Run();
  ASSERT_EQ(sim.truth.rows(), 128);
  ASSERT_EQ(sim.geometry.hr_frame.rows, 128);
  const double truth_total = 5e4 + 2e3;
  EXPECT_NEAR(sim.truth.sum(), truth_total, 1e-10 * truth_total);
  for (int i = 0; i < 4; ++i) EXPECT_NEAR(sim.expected_e[i].sum(), truth_total, 1e-10 * truth_total) << "frame " << i;
  ASSERT_EQ(sim.stars.size(), 1u);
  EXPECT_NEAR(sim.stars[0].y, (31.0625 + 0.5) * 2 - 0.5, 1e-12);
  EXPECT_NEAR(sim.stars[0].x, (32.9375 + 0.5) * 2 - 0.5, 1e-12);
  const ImageStack hr_psfs = p.ComputePsfs(nullptr, nullptr, nullptr);
  ASSERT_EQ(sim.psfs.size(), hr_psfs.size());
  for (std::size_t i = 0; i < hr_psfs.size(); ++i) {
    ASSERT_EQ(sim.psfs[i].rows(), p.geometry().psf_size);
    EXPECT_LT((sim.psfs[i] - hr_psfs[i]).abs().maxCoeff(), 1e-9 * hr_psfs[i].maxCoeff()) << "exposure " << i;
  }
  // The plan says where the work is done.
  EXPECT_NE(p.PlanReport().find("sky_oversampling 4"), std::string::npos) << p.PlanReport();
}

// A peak normalisation means the same sky at every s: USAF's exact-area rendering integrated over HR pixels is
// the s = 1 truth (to rounding), peak_e included.
TEST(PipelinePhysics, SkyOversamplingKeepsTheTruthOfExactAreaObjects) {
  nlohmann::json j = Scene({{{"type", "usaf"}, {"flux", {{"peak_e", 1000.0}}}}});
  const Simulation one = ScenePipeline(ParseScene(j, "<test>")).Run();
  j["sky_oversampling"] = 3;
  const Simulation three = ScenePipeline(ParseScene(j, "<test>")).Run();
  EXPECT_LT((one.truth - three.truth).abs().maxCoeff(), 1e-9 * 1000.0);
  EXPECT_NEAR(three.truth.maxCoeff(), 1000.0, 1e-9 * 1000.0);
}

// Where the HR model is exact for a continuous sky, a fine sky changes nothing: a PSF band-limited at the HR
// grid (K band, HR pixel = camera pixel / 2 = lambda/2D: the OTF ends at the HR Nyquist frequency) and a sky
// smooth at the HR pitch (Gaussian galaxies, sigma ~ 5 HR px) give the s = 1 frames within 2e-4 of their
// peak (the PSF window's truncation and the galaxies' rendering tolerance; measured 7.2e-5). In J band (HR
// pixel 0.88 lambda/D) the HR grid aliases the PSF and the same smooth sky differs by more (measured 5.4e-4;
// asserted > 3e-4): the discretisation that sky_oversampling exists to measure (a sharp sky differs far more).
TEST(PipelinePhysics, SkyOversamplingAgreesWithTheHrGridWhereBothAreBandLimited) {
  nlohmann::json j = Scene({{{"type", "galaxies"}, {"count", 3}, {"half_light_radius_px", {2.5, 3.0}}, {"sersic_n_range", {0.5, 0.5}},
                             {"margin_px", 12.0}, {"flux", {{"total_e", 1e5}}}}},
                           48);
  j["ao"] = {{"mode", "analytic"}};
  auto frames = [&](const nlohmann::json& scene, int s) {
    nlohmann::json k = scene;
    k["sky_oversampling"] = s;
    return ScenePipeline(ParseScene(k, "<test>")).Run().expected_e;
  };
  auto worst = [](const ImageStack& a, const ImageStack& b) {
    double d = 0, peak = 0;
    for (std::size_t i = 0; i < a.size(); ++i) {
      d = std::max(d, (a[i] - b[i]).abs().maxCoeff());
      peak = std::max(peak, a[i].abs().maxCoeff());
    }
    return d / peak;
  };
  const double k_band = worst(frames(j, 1), frames(j, 4));
  EXPECT_LT(k_band, 2e-4);
  // The same telescope and camera observed in J: the K camera's pixel is 1.76 lambda/D at 1.25 um.
  nlohmann::json jj = j;
  std::ifstream preset(std::string(AOSR_SOURCE_DIR) + "/data/telescopes/paper-8m.json");
  jj["telescope"] = nlohmann::json::parse(preset);
  jj["telescope"]["science"] = {{"wavelength_m", 1.25e-6}, {"camera_pixel_lambda_over_d", 1.76}};
  const double j_band = worst(frames(jj, 1), frames(jj, 4));
  EXPECT_GT(j_band, 3e-4);
  std::printf("fine (s = 4) against HR-grid frames, max difference / peak: K %.3g, J %.3g\n", k_band, j_band);
}

}  // namespace
}  // namespace aosr
