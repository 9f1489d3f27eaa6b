// What parsing a scene derives: the shipped scenes, raster offsets, design files, magnitudes, the PSF window
// and the seeds (scene_spec.hpp; the file format is data/scenes/README.md).
#include "aosr/scene/scene_spec.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <set>
#include <string>
#include <vector>

#include "../io/temp_dir.hpp"
#include "aosr/ao/random.hpp"
#include "aosr/core/error.hpp"
#include "aosr/io/config.hpp"
#include "aosr/scene/photometry.hpp"
#include "aosr/scene/raster.hpp"
#include "aosr/scene/telescope.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

namespace fs = std::filesystem;
using Json = nlohmann::json;

constexpr double kArcsec = M_PI / 180.0 / 3600.0;

Json BaseScene() {
  return Json{{"name", "base"},
              {"telescope", "paper-8m"},
              {"frames", 4},
              {"r", 2},
              {"detector", {{"frame_px", 32}}},
              {"objects", Json::array({Json{{"type", "usaf"}}})}};
}

void WriteJson(const std::string& path, const Json& j) {
  std::ofstream out(path);
  out << j.dump(2);
}

std::vector<fs::path> ShippedScenes() {
  std::vector<fs::path> out;
  for (const auto& e : fs::directory_iterator(fs::path(DataDirectory()) / "scenes"))
    if (e.path().extension() == ".json") out.push_back(e.path());
  std::sort(out.begin(), out.end());
  return out;
}

// ---- The shipped scenes ------------------------------------------------------------------------------------

TEST(SceneSpecTest, EveryShippedSceneParses) {
  const std::vector<fs::path> scenes = ShippedScenes();
  std::set<std::string> names;
  for (const fs::path& p : scenes) {
    SCOPED_TRACE(p.string());
    SceneSpec s;
    ASSERT_NO_THROW(s = LoadScene(p.string()));
    EXPECT_EQ(s.name, p.stem().string()) << "a scene's name is its file name";
    EXPECT_EQ(int(s.offsets.frames.size()), s.frames);
    EXPECT_FALSE(s.objects.empty());
    EXPECT_LE(s.HrPixelLambdaOverD(), 1.0 + 1e-12);
    EXPECT_EQ(s.psf_size_px % 2, 0);
    names.insert(s.name);
  }
  for (const char* expected :
       {"demo", "paper-sim-r2", "paper-sim-r4", "paper-sim-r8", "paper-bench", "crowded-stars", "galaxy-field"})
    EXPECT_TRUE(names.count(expected)) << expected << ".json is missing from " << DataDirectory() << "/scenes";
}

// The paper's simulation: the same sky, atmosphere, loop and offsets at every r; only the sampling changes.
TEST(SceneSpecTest, PaperSimulationScenesDifferOnlyInR) {
  const std::string dir = DataDirectory() + "/scenes/";
  const SceneSpec r2 = LoadScene(dir + "paper-sim-r2.json");
  for (int r : {2, 4, 8}) {
    SCOPED_TRACE("r = " + std::to_string(r));
    const SceneSpec s = LoadScene(dir + "paper-sim-r" + std::to_string(r) + ".json");
    EXPECT_EQ(s.r, r);
    EXPECT_EQ(s.frames, 4);
    EXPECT_EQ(s.telescope.name, "paper-8m");
    EXPECT_EQ(s.ao.mode, AoSpec::Mode::kClosedLoop);
    EXPECT_EQ(s.ao.sensor, SensorKind::kDiffractive);
    EXPECT_EQ(s.ao.seed, r2.ao.seed);
    EXPECT_EQ(s.ao.psf_every_steps, r2.ao.psf_every_steps);
    EXPECT_EQ(s.frame, r2.frame);
    EXPECT_EQ(s.detector.noise_model, NoiseModel::kPeakFraction);
    EXPECT_DOUBLE_EQ(s.detector.peak_noise_fraction, 0.01);
    EXPECT_FALSE(s.detector.enable_saturation);
    ASSERT_EQ(s.objects.size(), 1u);
    EXPECT_EQ(s.objects[0].kind, ObjectSpec::Kind::kUsaf);
    for (int i = 0; i < 4; ++i) EXPECT_EQ(s.offsets.frames[i], r2.offsets.frames[i]) << "frame " << i;
    // The default window, 32 lambda/D, at HR pixels of 1/r lambda/D.
    EXPECT_EQ(s.psf_size_px, 32 * r);
  }
}

TEST(SceneSpecTest, BenchSceneUsesTheSmallestAllowedR) {
  const SceneSpec s = LoadScene(DataDirectory() + "/scenes/paper-bench.json");
  EXPECT_EQ(s.r, 4);
  // Camera pixel 70.32 um / 400 mm in units of 635 nm / 13.5 mm: 3.737 lambda/D.
  const double camera_lod = (70.32e-6 / 0.4) / (635e-9 / 0.0135);
  EXPECT_NEAR(s.HrPixelLambdaOverD(), camera_lod / 4, 1e-12);
  EXPECT_GT(camera_lod / 3, 1.0);  // r = 3 would undersample (see the errors test)
  EXPECT_EQ(s.ao.mode, AoSpec::Mode::kNone);
  EXPECT_EQ(s.detector.noise_model, NoiseModel::kPhysical);
  EXPECT_TRUE(s.detector.enable_photon_noise);
  EXPECT_TRUE(s.detector.enable_read_noise);
}

// ---- Offsets -----------------------------------------------------------------------------------------------

TEST(SceneSpecTest, RasterOffsetsAreTheClassicRasterInCameraPixels) {
  for (const auto& [n, r] : std::vector<std::pair<int, int>>{{1, 2}, {2, 2}, {4, 2}, {2, 4}, {4, 4}, {6, 2}, {9, 3}, {16, 4}}) {
    SCOPED_TRACE("N = " + std::to_string(n) + ", r = " + std::to_string(r));
    Json j = BaseScene();
    j["frames"] = n;
    j["r"] = r;
    j["offsets"] = {{"type", "raster"}};
    const SceneSpec s = ParseScene(j, "mem.json");
    EXPECT_EQ(s.offsets.kind, OffsetsSpec::Kind::kRaster);
    const std::vector<FrameOffset> raster = ClassicRaster(n, r);
    ASSERT_EQ(s.offsets.frames.size(), raster.size());
    for (std::size_t i = 0; i < raster.size(); ++i) {
      EXPECT_DOUBLE_EQ(s.offsets.frames[i].shift_y_px, raster[i].dy / r);
      EXPECT_DOUBLE_EQ(s.offsets.frames[i].shift_x_px, raster[i].dx / r);
      EXPECT_TRUE(s.offsets.frames[i].zernike.empty());
      EXPECT_TRUE(s.offsets.frames[i].actuators_m.empty());
    }
  }
}

// An independent oracle: N = 4 at r = 2 is the half-pixel raster, +-1/4 camera pixel about the centre, and
// N = 4 is the same 2 x 2 lattice of camera-pixel shifts at any r.
TEST(SceneSpecTest, FourFrameRasterIsQuarterPixelShiftsAtEveryR) {
  for (int r : {2, 4, 8}) {
    Json j = BaseScene();
    j["r"] = r;
    j["offsets"] = {{"type", "raster"}};
    const SceneSpec s = ParseScene(j, "mem.json");
    std::multiset<std::pair<double, double>> shifts;
    for (const DmOffset& o : s.offsets.frames) shifts.insert({o.shift_y_px, o.shift_x_px});
    const std::multiset<std::pair<double, double>> expected{{-0.25, -0.25}, {-0.25, 0.25}, {0.25, -0.25}, {0.25, 0.25}};
    EXPECT_EQ(shifts, expected) << "r = " << r;
  }
}

TEST(SceneSpecTest, NoOffsetsMeansZeroOffsetPerFrame) {
  const SceneSpec s = ParseScene(BaseScene(), "mem.json");
  EXPECT_EQ(s.offsets.kind, OffsetsSpec::Kind::kNone);
  ASSERT_EQ(s.offsets.frames.size(), 4u);
  for (const DmOffset& o : s.offsets.frames) EXPECT_TRUE(o.IsZero());
}

std::vector<DmOffset> SampleDesign() {
  std::vector<DmOffset> frames(4);
  frames[0].shift_y_px = 0.25;
  frames[0].shift_x_px = -0.125;
  frames[1].zernike = {{4, 35e-9}, {7, -12.5e-9}};
  frames[2].shift_x_px = 0.5;
  frames[2].actuators_m = {1e-9, -2.5e-9, 0.0, 40e-9};
  frames[3].zernike = {{2, 100e-9}};
  frames[3].actuators_m = {3e-9};
  return frames;
}

// A design written with DmOffsetToJson reads back as the same offsets (nm <-> m conversions included), both
// from a design file and inline in a scene.
TEST(SceneSpecTest, DesignFileRoundTripsThroughDmOffsetToJson) {
  testing_io::TempDir tmp;
  const std::vector<DmOffset> frames = SampleDesign();
  Json design = {{"name", "sample"}, {"design", {{"method", "hand-written"}, {"cost", 1.5}}}, {"comment", "test"}};
  design["frames"] = Json::array();
  for (const DmOffset& o : frames) design["frames"].push_back(DmOffsetToJson(o));
  fs::create_directories(tmp.path() / "designs");
  WriteJson(tmp.File("designs/sample.json"), design);

  const std::vector<DmOffset> loaded = LoadDesignFile(tmp.File("designs/sample.json"));
  ASSERT_EQ(loaded.size(), frames.size());
  for (std::size_t i = 0; i < frames.size(); ++i) {
    EXPECT_DOUBLE_EQ(loaded[i].shift_y_px, frames[i].shift_y_px);
    EXPECT_DOUBLE_EQ(loaded[i].shift_x_px, frames[i].shift_x_px);
    ASSERT_EQ(loaded[i].zernike.size(), frames[i].zernike.size());
    for (std::size_t k = 0; k < frames[i].zernike.size(); ++k) {
      EXPECT_EQ(loaded[i].zernike[k].noll, frames[i].zernike[k].noll);
      EXPECT_NEAR(loaded[i].zernike[k].rms_m, frames[i].zernike[k].rms_m, 1e-15 * std::abs(frames[i].zernike[k].rms_m));
    }
    ASSERT_EQ(loaded[i].actuators_m.size(), frames[i].actuators_m.size());
    for (std::size_t k = 0; k < frames[i].actuators_m.size(); ++k)
      EXPECT_NEAR(loaded[i].actuators_m[k], frames[i].actuators_m[k], 1e-15 * std::abs(frames[i].actuators_m[k]));
  }

  // The scene names the file relative to its own folder, not the working directory.
  Json j = BaseScene();
  j["offsets"] = {{"type", "design"}, {"file", "designs/sample.json"}};
  const SceneSpec from_file = ParseScene(j, tmp.File("scene.json"));
  EXPECT_EQ(from_file.offsets.kind, OffsetsSpec::Kind::kDesign);
  EXPECT_EQ(from_file.offsets.source, tmp.File("designs/sample.json"));
  j["offsets"] = {{"type", "design"}, {"frames", design["frames"]}};
  const SceneSpec inline_design = ParseScene(j, "mem.json");
  EXPECT_EQ(inline_design.offsets.source, "inline");
  for (std::size_t i = 0; i < frames.size(); ++i) {
    EXPECT_EQ(from_file.offsets.frames[i], loaded[i]);
    EXPECT_EQ(inline_design.offsets.frames[i], loaded[i]);
  }
  EXPECT_FALSE(loaded[1].IsZero());
}

TEST(SceneSpecTest, StaticAberrationsAreInMetres) {
  Json j = BaseScene();
  j["static_aberrations"] = Json::array({Json{{"noll", 4}, {"rms_nm", 30}}, Json{{"noll", 11}, {"rms_nm", -8}}});
  const SceneSpec s = ParseScene(j, "mem.json");
  ASSERT_EQ(s.static_aberrations.size(), 2u);
  EXPECT_EQ(s.static_aberrations[0].noll, 4);
  EXPECT_NEAR(s.static_aberrations[0].rms_m, 30e-9, 1e-22);
  EXPECT_NEAR(s.static_aberrations[1].rms_m, -8e-9, 1e-22);
}

// ---- Photometry --------------------------------------------------------------------------------------------

// Electrons per frame of a magnitude-m star: Phi0(K) 10^(-0.4 m) photons s^-1 m^-2, times the clear 8 m
// pupil's area, the throughput and the frame time T/N.
TEST(SceneSpecTest, MagnitudesConvertWithTheVegaZeroPoint) {
  Json j = BaseScene();
  j["photometry"] = {{"band", "K"}, {"throughput", 0.25}};
  j["detector"]["total_exposure_s"] = 8.0;  // 2 s per frame
  const SceneSpec s = ParseScene(j, "mem.json");
  EXPECT_DOUBLE_EQ(s.detector.exposure_time_s, 2.0);
  const double area = M_PI / 4 * 8.0 * 8.0;  // paper-8m has no central obstruction
  for (double m : {10.0, 15.0, 22.5}) {
    const double oracle = VegaBand("K").zero_point_photons * std::pow(10.0, -0.4 * m) * area * 0.25 * 2.0;
    EXPECT_NEAR(s.ElectronsPerFrameForMagnitude(m), oracle, 1e-12 * oracle) << "m = " << m;
    LightCollectorOptions c;
    c.diameter_m = 8.0;
    c.obstruction = 0.0;
    c.throughput = 0.25;
    EXPECT_NEAR(s.ElectronsPerFrameForMagnitude(m), ElectronsPerFrame(SourceFlux::Magnitude(m, "K"), c, {8.0, 4}),
                1e-12 * oracle);
  }
  // Five magnitudes are a factor 100.
  EXPECT_NEAR(s.ElectronsPerFrameForMagnitude(15.0) / s.ElectronsPerFrameForMagnitude(20.0), 100.0, 1e-10);
  // The book's hand check (photometry.hpp): K = 12 is 2.84e4 photons s^-1 m^-2.
  EXPECT_NEAR(s.ElectronsPerFrameForMagnitude(12.0) / (area * 0.25 * 2.0), 2.84e4, 0.01e4);
}

TEST(SceneSpecTest, ZeroPointMagnitudeGivesOneElectronPerSecond) {
  Json j = BaseScene();
  j["photometry"] = {{"zero_point_mag", 25.0}};
  j["detector"]["total_exposure_s"] = 12.0;  // 3 s per frame
  const SceneSpec s = ParseScene(j, "mem.json");
  EXPECT_NEAR(s.ElectronsPerFrameForMagnitude(25.0), 3.0, 1e-12);
  EXPECT_NEAR(s.ElectronsPerFrameForMagnitude(20.0), 300.0, 1e-9);  // 10^(-0.4 (20 - 25)) e-/s x 3 s
}

TEST(SceneSpecTest, StarMagnitudesBecomeElectronsPerFrame) {
  Json j = BaseScene();
  j["photometry"] = {{"band", "K"}};
  j["detector"]["total_exposure_s"] = 4.0;
  j["objects"] = Json::array(
      {Json{{"type", "stars"}, {"count", 50}, {"magnitude_range", {14, 21}}, {"alpha", 1.75}},
       Json{{"type", "stars"},
            {"catalogue", Json::array({Json{{"y_px", 3.5}, {"x_px", 20.25}, {"magnitude", 16}},
                                       Json{{"y_px", 30}, {"x_px", 1}, {"flux_e", 1234.5}}})}}});
  const SceneSpec s = ParseScene(j, "mem.json");
  const ObjectSpec& field = s.objects[0];
  EXPECT_TRUE(field.star_magnitudes);
  EXPECT_DOUBLE_EQ(field.stars.luminosity.flux_max, s.ElectronsPerFrameForMagnitude(14.0));  // bright end
  EXPECT_DOUBLE_EQ(field.stars.luminosity.flux_min, s.ElectronsPerFrameForMagnitude(21.0));
  EXPECT_DOUBLE_EQ(field.stars.luminosity.alpha, 1.75);
  EXPECT_EQ(field.stars.count, 50);
  EXPECT_EQ(field.flux.kind, FluxSpec::Kind::kNative);
  const ObjectSpec& cat = s.objects[1];
  ASSERT_EQ(cat.catalogue.size(), 2u);
  EXPECT_DOUBLE_EQ(cat.catalogue[0].y, 3.5);  // camera pixels, as written
  EXPECT_DOUBLE_EQ(cat.catalogue[0].x, 20.25);
  EXPECT_DOUBLE_EQ(cat.catalogue[0].flux, s.ElectronsPerFrameForMagnitude(16.0));
  EXPECT_DOUBLE_EQ(cat.catalogue[1].flux, 1234.5);
}

TEST(SceneSpecTest, FluxSpecKinds) {
  Json j = BaseScene();
  j["photometry"] = {{"band", "H"}};
  j["objects"] = Json::array({Json{{"type", "usaf"}}, Json{{"type", "usaf"}, {"flux", {{"total_e", 5e4}}}},
                              Json{{"type", "demo"}, {"flux", {{"peak_e", 900}}}},
                              Json{{"type", "dead-leaves"}, {"flux", {{"magnitude", 17.5}}}}});
  const SceneSpec s = ParseScene(j, "mem.json");
  EXPECT_EQ(s.objects[0].flux.kind, FluxSpec::Kind::kNative);
  EXPECT_EQ(s.objects[1].flux.kind, FluxSpec::Kind::kTotalElectrons);
  EXPECT_DOUBLE_EQ(s.objects[1].flux.value, 5e4);
  EXPECT_EQ(s.objects[2].flux.kind, FluxSpec::Kind::kPeakElectrons);
  EXPECT_DOUBLE_EQ(s.objects[2].flux.value, 900);
  EXPECT_EQ(s.objects[3].flux.kind, FluxSpec::Kind::kMagnitude);
  EXPECT_DOUBLE_EQ(s.objects[3].flux.value, 17.5);
}

// Sky of mu mag/arcsec^2 on a camera pixel of side theta: Phi(mu) A tau (theta/1")^2 e-/s.
TEST(SceneSpecTest, SkyBackgroundFromSurfaceBrightness) {
  Json j = BaseScene();
  j["photometry"] = {{"band", "K"}};
  j["detector"]["sky_mag_per_arcsec2"] = 13.0;
  SceneSpec s = ParseScene(j, "mem.json");
  const double pixel_arcsec = (2.2e-6 / 8.0) / kArcsec;  // lambda/D = 56.7 mas
  const double oracle = VegaBand("K").zero_point_photons * std::pow(10.0, -0.4 * 13.0) * (M_PI / 4 * 64.0) * 0.3 *
                        pixel_arcsec * pixel_arcsec;
  EXPECT_NEAR(s.detector.background_e_per_s, oracle, 1e-10 * oracle);
  EXPECT_TRUE(s.detector.enable_background);

  j["photometry"] = {{"zero_point_mag", 24.0}};
  s = ParseScene(j, "mem.json");
  EXPECT_NEAR(s.detector.background_e_per_s, std::pow(10.0, -0.4 * (13.0 - 24.0)) * pixel_arcsec * pixel_arcsec,
              1e-10 * s.detector.background_e_per_s);

  j = BaseScene();
  s = ParseScene(j, "mem.json");
  EXPECT_FALSE(s.detector.enable_background);
}

// ---- Geometry ----------------------------------------------------------------------------------------------

TEST(SceneSpecTest, DefaultPsfWindowIs32LambdaOverD) {
  Json j = BaseScene();
  EXPECT_EQ(ParseScene(j, "mem.json").psf_size_px, 64);  // paper-8m at r = 2: HR pixel lambda/(2D)
  j["r"] = 4;
  EXPECT_EQ(ParseScene(j, "mem.json").psf_size_px, 128);
  j["r"] = 2;
  j["psf"] = {{"window_lambda_over_d", 16.0}};
  EXPECT_EQ(ParseScene(j, "mem.json").psf_size_px, 32);
  j["psf"] = {{"size_px", 48}};
  EXPECT_EQ(ParseScene(j, "mem.json").psf_size_px, 48);
  // paper-bench at r = 4: HR pixels of 0.934 lambda/D, so the smallest even window of >= 32 lambda/D.
  j = BaseScene();
  j["telescope"] = "paper-bench";
  j["r"] = 4;
  const SceneSpec bench = ParseScene(j, "mem.json");
  EXPECT_GE(bench.psf_size_px * bench.HrPixelLambdaOverD(), 32.0);
  EXPECT_LT((bench.psf_size_px - 2) * bench.HrPixelLambdaOverD(), 32.0);
}

TEST(SceneSpecTest, FrameAndHrGrid) {
  Json j = BaseScene();
  j["r"] = 3;
  j["detector"]["frame_px"] = {24, 40};
  const SceneSpec s = ParseScene(j, "mem.json");
  EXPECT_EQ(s.frame, (Shape{24, 40}));
  EXPECT_EQ(s.HrFrame(), (Shape{72, 120}));
  EXPECT_NEAR(s.HrPixelRad(), 2.2e-6 / 8.0 / 3, 1e-20);
  EXPECT_NEAR(s.HrPixelLambdaOverD(), 1.0 / 3, 1e-12);
}

// The sky is defined in camera pixels: changing r keeps every size and position of the objects.
TEST(SceneSpecTest, ObjectSizesAreCameraPixelsWhateverR) {
  Json j = BaseScene();
  j["detector"]["frame_px"] = 64;
  j["objects"] = Json::array(
      {Json{{"type", "galaxies"}, {"count", 3}, {"half_light_radius_px", {0.5, 3}}, {"margin_px", 4}},
       Json{{"type", "dead-leaves"}, {"radius_range_px", {0.25, 8}}},
       Json{{"type", "stars"}, {"count", 20}, {"min_separation_px", 1.5}, {"margin_px", 2}},
       Json{{"type", "stars"}, {"catalogue", Json::array({Json{{"y_px", 10.5}, {"x_px", 7.25}, {"flux_e", 10}}})}}});
  std::vector<SceneSpec> specs;
  for (int r : {2, 4}) {
    j["r"] = r;
    specs.push_back(ParseScene(j, "mem.json"));
  }
  const ObjectSpec* a = specs[0].objects.data();
  const ObjectSpec* b = specs[1].objects.data();
  EXPECT_DOUBLE_EQ(a[0].galaxies.re_min_px, 0.5);
  EXPECT_DOUBLE_EQ(b[0].galaxies.re_max_px, 3.0);
  EXPECT_DOUBLE_EQ(b[0].galaxies.margin_px, 4.0);
  EXPECT_DOUBLE_EQ(b[1].dead_leaves.r_min_px, 0.25);
  EXPECT_DOUBLE_EQ(b[1].dead_leaves.r_max_px, 8.0);
  EXPECT_DOUBLE_EQ(b[2].stars.min_separation_px, 1.5);
  EXPECT_DOUBLE_EQ(b[2].stars.margin_px, 2.0);
  EXPECT_DOUBLE_EQ(b[3].catalogue[0].y, a[3].catalogue[0].y);
  EXPECT_DOUBLE_EQ(b[3].catalogue[0].x, 7.25);
}

// The slanted edge: its fields, and its centre in camera pixels placed on the HR grid by the pipeline.
TEST(SceneSpecTest, SlantedEdgeObjectParses) {
  Json j = BaseScene();
  j["objects"] = Json::array({Json{{"type", "slanted-edge"}, {"angle_deg", 7.5}, {"low", 0.1}, {"high", 2.0},
                                   {"centre_px", {10.0, 12.0}}}});
  const SceneSpec s = ParseScene(j, "mem.json");
  ASSERT_EQ(s.objects.size(), 1u);
  EXPECT_EQ(s.objects[0].kind, ObjectSpec::Kind::kSlantedEdge);
  EXPECT_DOUBLE_EQ(s.objects[0].slanted_edge.angle_deg, 7.5);
  EXPECT_DOUBLE_EQ(s.objects[0].slanted_edge.low, 0.1);
  EXPECT_DOUBLE_EQ(s.objects[0].slanted_edge.high, 2.0);
  EXPECT_DOUBLE_EQ(s.objects[0].slanted_edge.centre_y, 10.0);
  EXPECT_DOUBLE_EQ(s.objects[0].slanted_edge.centre_x, 12.0);
  j["objects"][0]["angle_deg"] = 190;
  try {
    ParseScene(j, "mem.json");
    ADD_FAILURE() << "no exception";
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("objects[0].angle_deg = 190"), std::string::npos) << e.what();
  }
}

// ---- Detector ----------------------------------------------------------------------------------------------

TEST(SceneSpecTest, NoiseModels) {
  Json j = BaseScene();
  SceneSpec s = ParseScene(j, "mem.json");  // default: physical, photon + 5 e- read noise
  EXPECT_EQ(s.detector.noise_model, NoiseModel::kPhysical);
  EXPECT_TRUE(s.detector.enable_photon_noise);
  EXPECT_TRUE(s.detector.enable_read_noise);
  EXPECT_DOUBLE_EQ(s.detector.read_noise_e, 5.0);
  EXPECT_TRUE(s.detector.enable_saturation);
  EXPECT_FALSE(s.detector.enable_bad_pixels);

  j["detector"]["read_noise_e"] = 0;
  j["detector"]["photon_noise"] = false;
  s = ParseScene(j, "mem.json");
  EXPECT_FALSE(s.detector.enable_read_noise);
  EXPECT_FALSE(s.detector.enable_photon_noise);

  j = BaseScene();
  j["detector"]["noise"] = "peak-fraction";
  j["detector"]["peak_noise_fraction"] = 0.02;
  s = ParseScene(j, "mem.json");
  EXPECT_EQ(s.detector.noise_model, NoiseModel::kPeakFraction);
  EXPECT_DOUBLE_EQ(s.detector.peak_noise_fraction, 0.02);
  EXPECT_FALSE(s.detector.enable_photon_noise);
  EXPECT_FALSE(s.detector.enable_read_noise);

  j["detector"] = {{"frame_px", 32}, {"noise", "none"}};
  s = ParseScene(j, "mem.json");
  EXPECT_EQ(s.detector.noise_model, NoiseModel::kPhysical);
  EXPECT_FALSE(s.detector.enable_photon_noise);
  EXPECT_FALSE(s.detector.enable_read_noise);
  EXPECT_DOUBLE_EQ(s.detector.peak_noise_fraction, 0.0);
}

TEST(SceneSpecTest, BadPixelMaps) {
  Json j = BaseScene();
  j["detector"]["bad_pixels"] = {{"fraction", 0.1}};
  SceneSpec s = ParseScene(j, "mem.json");
  EXPECT_TRUE(s.detector.enable_bad_pixels);
  ASSERT_EQ(ShapeOf(s.detector.bad_pixel_mask), (Shape{32, 32}));
  const double bad = 1.0 - s.detector.bad_pixel_mask.mean();
  EXPECT_GT(bad, 0.05);  // 1024 pixels at p = 0.1: sigma of the fraction ~0.0094
  EXPECT_LT(bad, 0.15);
  EXPECT_TRUE((s.detector.bad_pixel_mask.array() * (1 - s.detector.bad_pixel_mask.array()) == 0).all());
}

// ---- Paths, comments ---------------------------------------------------------------------------------------

TEST(SceneSpecTest, RelativePathsResolveAgainstTheSceneFolder) {
  testing_io::TempDir tmp;
  fs::create_directories(tmp.path() / "scenes" / "presets");
  Json tel = ReadJsonFile(DataDirectory() + "/telescopes/paper-8m.json");
  tel["name"] = "my-8m";
  WriteJson(tmp.File("scenes/presets/my-8m.json"), tel);
  Json j = BaseScene();
  j["telescope"] = "presets/my-8m.json";
  const SceneSpec s = ParseScene(j, tmp.File("scenes/scene.json"));
  EXPECT_EQ(s.telescope.name, "my-8m");
  EXPECT_EQ(s.source, tmp.File("scenes/scene.json"));
}

TEST(SceneSpecTest, InlineTelescope) {
  Json j = BaseScene();
  j["telescope"] = ReadJsonFile(DataDirectory() + "/telescopes/paper-8m.json");
  j["telescope"]["science"]["wavelength_m"] = 1.65e-6;  // H band on the same camera pixel in lambda/D
  const SceneSpec s = ParseScene(j, "mem.json");
  EXPECT_DOUBLE_EQ(s.telescope.science_wavelength_m, 1.65e-6);
  EXPECT_NEAR(s.CameraPixelRad(), 1.65e-6 / 8.0, 1e-20);
}

TEST(SceneSpecTest, DmGainIsAClosedLoopOptionDefaultingToOne) {
  Json j = BaseScene();
  j["ao"] = {{"mode", "closed-loop"}};
  EXPECT_EQ(ParseScene(j, "mem.json").ao.dm_gain, 1.0);
  j["ao"]["dm_gain"] = 1.1;
  EXPECT_EQ(ParseScene(j, "mem.json").ao.dm_gain, 1.1);
}

TEST(SceneSpecTest, CommentKeysAreIgnoredAtEveryLevel) {
  Json j = BaseScene();
  j["comment"] = "top";
  j["comment_2"] = {{"anything", 1}};
  j["detector"]["comment_noise"] = "x";
  j["objects"][0]["comment"] = "y";
  j["objects"][0]["flux"] = {{"peak_e", 10}, {"comment", "z"}};
  j["ao"] = {{"mode", "none"}, {"comment", "static"}};
  j["offsets"] = {{"type", "raster"}, {"comment", "quarter pixels"}};
  j["psf"] = {{"comment", "default window"}};
  EXPECT_NO_THROW(ParseScene(j, "mem.json"));
}

// ---- Seeds -------------------------------------------------------------------------------------------------

SceneSpec SeededScene(std::uint64_t seed, const Json& extra_object = nullptr) {
  Json j = BaseScene();
  j["seed"] = seed;
  j["ao"] = {{"mode", "closed-loop"}};
  j["detector"]["bad_pixels"] = {{"fraction", 0.01}};
  j["objects"] = Json::array({Json{{"type", "stars"}, {"count", 5}}, Json{{"type", "galaxies"}, {"count", 2}},
                              Json{{"type", "dead-leaves"}}});
  if (!extra_object.is_null()) j["objects"].push_back(extra_object);
  return ParseScene(j, "mem.json");
}

std::vector<std::uint64_t> AllSeeds(const SceneSpec& s) {
  std::vector<std::uint64_t> seeds{s.ao.seed, s.noise_seed, s.bad_pixel_seed};
  for (const ObjectSpec& o : s.objects) seeds.push_back(o.seed);
  return seeds;
}

TEST(SceneSpecTest, SeedsDeriveDeterministicallyFromTheSceneSeed) {
  const std::vector<std::uint64_t> a = AllSeeds(SeededScene(42));
  EXPECT_EQ(a, AllSeeds(SeededScene(42))) << "same scene, same seeds";
  // Every effect and component has its own stream.
  EXPECT_EQ(std::set<std::uint64_t>(a.begin(), a.end()).size(), a.size());
  // Another scene seed changes every derived seed.
  const std::vector<std::uint64_t> b = AllSeeds(SeededScene(43));
  for (std::size_t i = 0; i < a.size(); ++i) EXPECT_NE(a[i], b[i]) << "seed " << i;
  // Seeds fit the parser's range for explicit seeds, [0, 2^62], so any derived seed can be written back.
  for (std::uint64_t s : a) EXPECT_LE(s, std::uint64_t(1) << 62);
  // Appending a component leaves the earlier ones, the noise and the atmosphere alone.
  const std::vector<std::uint64_t> c = AllSeeds(SeededScene(42, Json{{"type", "usaf"}}));
  ASSERT_EQ(c.size(), a.size() + 1);
  EXPECT_TRUE(std::equal(a.begin(), a.end(), c.begin()));
}

TEST(SceneSpecTest, ExplicitSeedsOverrideTheDerivedOnes) {
  Json j = BaseScene();
  j["seed"] = 42;
  j["ao"] = {{"mode", "analytic"}, {"seed", 7}};
  j["detector"]["noise_seed"] = 8;
  j["detector"]["bad_pixels"] = {{"fraction", 0.01}, {"seed", 9}};
  j["objects"] = Json::array({Json{{"type", "stars"}, {"count", 5}, {"seed", 12345}}, Json{{"type", "dead-leaves"}}});
  const SceneSpec s = ParseScene(j, "mem.json");
  EXPECT_EQ(s.ao.seed, 7u);
  EXPECT_EQ(s.noise_seed, 8u);
  EXPECT_EQ(s.bad_pixel_seed, 9u);
  EXPECT_EQ(s.objects[0].seed, 12345u);
  // The other component keeps its derived seed.
  j["objects"][0].erase("seed");
  EXPECT_EQ(ParseScene(j, "mem.json").objects[1].seed, s.objects[1].seed);
  EXPECT_NE(ParseScene(j, "mem.json").objects[0].seed, 12345u);
}

}  // namespace
}  // namespace aosr
