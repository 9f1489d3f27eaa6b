// Datasets: a simulation written by WriteSimulation loads back exactly, and a hand-written "real data"
// manifest over the same frames (PSFs from an instrument scene) loads to the same data.
#include "aosr/scene/dataset.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <set>

#include "../io/temp_dir.hpp"
#include "aosr/io/config.hpp"
#include "aosr/io/fits.hpp"
#include "dataset_fixture.hpp"
#include "support/testing.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

namespace fs = std::filesystem;
using testing_io::TempDir;
using ::testing::ElementsAre;

double MaxAbsDiff(const Image& a, const Image& b) { return (a - b).abs().maxCoeff(); }

// One simulation shared by the tests (the suite never modifies it).
class DatasetTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new TempDir;
    written_ = new test::WrittenSimulation(
        test::SimulateInto(dir_->File("scene.json"), test::SmallDatasetScene(), dir_->File("sim")));
  }
  static void TearDownTestSuite() {
    delete written_;
    delete dir_;
  }
  static TempDir* dir_;
  static test::WrittenSimulation* written_;
};
TempDir* DatasetTest::dir_ = nullptr;
test::WrittenSimulation* DatasetTest::written_ = nullptr;

TEST_F(DatasetTest, WritesEveryFileAtomicallyAndNothingElse) {
  std::vector<std::string> names;
  for (const auto& e : fs::directory_iterator(dir_->File("sim"))) names.push_back(e.path().filename().string());
  std::sort(names.begin(), names.end());
  // No temporary files are left behind.
  EXPECT_THAT(names, ElementsAre("expected.fits", "frames.fits", "manifest.json", "psfs.fits", "truth.fits", "valid.fits",
                                 "weights.fits"));
  const FitsData frames = ReadFits(dir_->File("sim/frames.fits"));
  EXPECT_EQ(frames.header.GetString("ORIGIN"), std::string("aosr ") + AOSR_VERSION);
  EXPECT_EQ(frames.header.GetString("SCENE"), "dataset-test");
  EXPECT_EQ(frames.header.GetString("BUNIT"), "adu");
  EXPECT_EQ(frames.header.GetInt("SRFACTOR"), 2);
  EXPECT_DOUBLE_EQ(frames.header.GetDouble("GAIN"), 2.0);
  EXPECT_DOUBLE_EQ(frames.header.GetDouble("BIAS"), 100.0);
  EXPECT_DOUBLE_EQ(frames.header.GetDouble("EXPTIME"), 0.5);  // total 1 s over N = 2
  // The truth and PSFs are at HR sampling: half the camera pixel's mas.
  const FitsData truth = ReadFits(dir_->File("sim/truth.fits"));
  EXPECT_NEAR(truth.header.GetDouble("PIXSCALE"), frames.header.GetDouble("PIXSCALE") / 2, 1e-12);
  EXPECT_EQ(truth.header.GetString("BUNIT"), "electron");
}

TEST_F(DatasetTest, ManifestRecordsTheRunsProvenance) {
  const nlohmann::json m = ReadJsonFile(dir_->File("sim/manifest.json"));
  const Simulation& sim = written_->sim;
  EXPECT_EQ(m["format"], "aosr-manifest");
  EXPECT_EQ(m["version"], 1);
  EXPECT_EQ(m["software"], std::string("aosr ") + AOSR_VERSION);
  EXPECT_EQ(m["simulation"]["scene"]["name"], "dataset-test");
  EXPECT_EQ(m["simulation"]["scene"]["json"], test::SmallDatasetScene());  // the file as read
  EXPECT_EQ(m["simulation"]["seeds"]["scene"], 7);
  EXPECT_EQ(m["simulation"]["seeds"]["noise"], written_->scene.noise_seed);
  EXPECT_EQ(m["simulation"]["seeds"]["objects"].size(), 2u);
  ASSERT_EQ(m["simulation"]["exposures"].size(), 2u);
  EXPECT_DOUBLE_EQ(m["simulation"]["exposures"][1]["strehl"].get<double>(), sim.strehl[1]);
  EXPECT_DOUBLE_EQ(m["simulation"]["exposures"][1]["psf_window_fraction"].get<double>(), sim.psf_window_fraction[1]);
  EXPECT_FALSE(m["simulation"].contains("timings_s")) << "wall times would make the dataset irreproducible";
  EXPECT_EQ(m["noise"]["model"], "none");
  EXPECT_EQ(m["noise"]["frame_time_s"], 0.5);
  // paper-8m: camera pixel = lambda/D at 2.2 um on 8 m = 2.75e-7 rad = 56.72 mas; HR = half.
  EXPECT_NEAR(m["pixel_scale"]["camera_lambda_over_d"].get<double>(), 1.0, 1e-12);
  EXPECT_NEAR(m["pixel_scale"]["hr_mas"].get<double>(), 2.75e-7 / 2 * 180 / M_PI * 3600e3, 1e-9);
  // Catalogue stars: camera (10.25, 20.5) <-> HR ((c + 0.5) r - 0.5) = (21, 41.5).
  ASSERT_EQ(m["stars"].size(), 2u);
  EXPECT_DOUBLE_EQ(m["stars"][0]["y_hr_px"].get<double>(), 21.0);
  EXPECT_DOUBLE_EQ(m["stars"][0]["x_hr_px"].get<double>(), 41.5);
  EXPECT_DOUBLE_EQ(m["stars"][0]["y_px"].get<double>(), 10.25);
  EXPECT_DOUBLE_EQ(m["stars"][0]["flux_e"].get<double>(), 3000.0);
}

TEST_F(DatasetTest, RoundTripLoadsExactlyWhatWasSimulated) {
  const Simulation& sim = written_->sim;
  for (const std::string& where : {dir_->File("sim"), dir_->File("sim/manifest.json")}) {
    SCOPED_TRACE(where);
    const Dataset ds = LoadDataset(where);
    EXPECT_EQ(ds.r, 2);
    EXPECT_EQ(ds.frame, (Shape{32, 32}));
    EXPECT_EQ(ds.hr_frame, (Shape{64, 64}));
    ASSERT_EQ(ds.size(), 2);
    EXPECT_EQ(ds.gain_e_per_adu, 2.0);
    EXPECT_EQ(ds.bias_adu, 100.0);
    EXPECT_EQ(ds.trustworthy_border_px, sim.geometry.trustworthy_border_px);
    EXPECT_EQ(ds.psf_size(), sim.geometry.psf_size);
    EXPECT_NEAR(ds.camera_pixel_rad, 2.75e-7, 1e-20);
    EXPECT_EQ(ds.wavelength_m, 2.2e-6);
    ASSERT_TRUE(ds.weights.has_value());
    ASSERT_TRUE(ds.truth.has_value());
    EXPECT_EQ(MaxAbsDiff(*ds.truth, sim.truth), 0.0);  // float64 files: bit exact
    EXPECT_TRUE(fs::exists(ds.expected_file));
    const ImageStack electrons = ds.FramesElectrons();
    for (int i = 0; i < 2; ++i) {
      EXPECT_EQ(MaxAbsDiff(ds.frames[i], sim.frames[i].adu), 0.0);
      EXPECT_EQ(MaxAbsDiff(ds.valid[i], sim.frames[i].valid), 0.0);
      EXPECT_EQ(MaxAbsDiff((*ds.weights)[i], sim.frames[i].inverse_variance), 0.0);
      // Re-normalising a unit-sum kernel changes it by rounding only.
      EXPECT_LT(MaxAbsDiff(ds.psfs[i], sim.psfs[i]), 1e-15 * sim.psfs[i].maxCoeff() * 10);
      EXPECT_NEAR(ds.psfs[i].sum(), 1.0, 1e-12);
      // Noise "none": ADU = e/g + bias exactly, so (ADU - bias) g gives the noiseless electrons back.
      EXPECT_LT(MaxAbsDiff(electrons[i], sim.expected_e[i]), 1e-10 * sim.expected_e[i].maxCoeff());
      EXPECT_EQ(ds.offsets[i].shift_y_px, written_->scene.offsets.frames[i].shift_y_px);
      EXPECT_EQ(ds.offsets[i].shift_x_px, written_->scene.offsets.frames[i].shift_x_px);
    }
    // The raster really moved the two exposures (otherwise the offset check above proves nothing).
    EXPECT_NE(ds.offsets[0].shift_x_px, ds.offsets[1].shift_x_px);
    ASSERT_EQ(ds.stars.size(), sim.stars.size());
    for (std::size_t s = 0; s < ds.stars.size(); ++s) {
      EXPECT_DOUBLE_EQ(ds.stars[s].y, sim.stars[s].y);
      EXPECT_DOUBLE_EQ(ds.stars[s].x, sim.stars[s].x);
      EXPECT_DOUBLE_EQ(ds.stars[s].flux, sim.stars[s].flux);
    }
  }
}

// The acceptance for real data: frames copied from the simulation, described by a hand-written
// manifest whose PSFs come from an instrument scene file, load to the same frames and PSFs.
TEST_F(DatasetTest, RealDataManifestWithAnInstrumentSceneLoadsTheSameData) {
  TempDir real;
  fs::copy_file(dir_->File("sim/frames.fits"), real.File("my_frames.fits"));
  test::WriteJson(real.File("instrument.json"), test::SmallDatasetScene());
  test::WriteJson(real.File("night.json"), {{"format", "aosr-manifest"},
                                            {"version", 1},
                                            {"comment", "frames of the dataset test, PSFs from the instrument file"},
                                            {"frames", "my_frames.fits"},
                                            {"scene", "instrument.json"}});
  const Dataset ds = LoadDataset(real.File("night.json"));
  const Dataset sim = LoadDataset(dir_->File("sim"));
  EXPECT_EQ(ds.r, sim.r);
  EXPECT_EQ(ds.frame, sim.frame);
  EXPECT_EQ(ds.gain_e_per_adu, sim.gain_e_per_adu);  // from the scene's detector
  EXPECT_EQ(ds.bias_adu, sim.bias_adu);
  EXPECT_EQ(ds.trustworthy_border_px, sim.trustworthy_border_px);
  EXPECT_EQ(ds.camera_pixel_rad, sim.camera_pixel_rad);
  EXPECT_FALSE(ds.weights.has_value());
  EXPECT_FALSE(ds.truth.has_value());
  ASSERT_EQ(ds.size(), sim.size());
  for (int i = 0; i < ds.size(); ++i) {
    EXPECT_EQ(MaxAbsDiff(ds.frames[i], sim.frames[i]), 0.0);
    EXPECT_EQ(ds.valid[i].minCoeff(), 1.0);
    EXPECT_LT(MaxAbsDiff(ds.psfs[i], sim.psfs[i]), 1e-14 * sim.psfs[i].maxCoeff());
    EXPECT_EQ(ds.offsets[i].shift_y_px, sim.offsets[i].shift_y_px);
    EXPECT_EQ(ds.offsets[i].shift_x_px, sim.offsets[i].shift_x_px);
  }
}

// Measured PSFs: one shared plane (not unit sum) is broadcast and normalised; NaN pixels of the frames
// (the FITS convention for bad ones) become invalid, read the bias and get weight 0.
TEST_F(DatasetTest, RealDataManifestWithMeasuredPsfsAndBadPixels) {
  TempDir real;
  const Dataset sim = LoadDataset(dir_->File("sim"));
  ImageStack frames = sim.frames;
  frames[1](3, 4) = std::nan("");
  WriteFitsCube(real.File("frames.fits"), frames, {}, FitsType::kFloat64);
  WriteFits(real.File("psf.fits"), Image(sim.psfs[0] * 5.0), {}, FitsType::kFloat64);
  WriteFitsCube(real.File("w.fits"), *sim.weights, {}, FitsType::kFloat64);
  test::WriteJson(real.File("manifest.json"), {{"format", "aosr-manifest"},
                                               {"version", 1},
                                               {"frames", "frames.fits"},
                                               {"psfs", real.File("psf.fits")},  // absolute paths are kept
                                               {"weights", "w.fits"},
                                               {"r", 2},
                                               {"gain_e_per_adu", 2.0},
                                               {"bias_adu", 100.0},
                                               {"stars", {{{"y_px", 10.25}, {"x_px", 20.5}, {"flux_e", 3000.0}}}}});
  const Dataset ds = LoadDataset(real.path().string());
  ASSERT_EQ(ds.size(), 2);
  for (int i = 0; i < 2; ++i) {
    EXPECT_NEAR(ds.psfs[i].sum(), 1.0, 1e-12);
    EXPECT_LT(MaxAbsDiff(ds.psfs[i], sim.psfs[0]), 1e-15);
    EXPECT_EQ(ds.offsets[i], DmOffset{});  // none given
  }
  EXPECT_EQ(ds.valid[1](3, 4), 0.0);
  EXPECT_EQ(ds.valid[1].sum(), 32 * 32 - 1);
  EXPECT_EQ(ds.frames[1](3, 4), 100.0);
  EXPECT_EQ((*ds.weights)[1](3, 4), 0.0);
  EXPECT_EQ(ds.FramesElectrons()[1](3, 4), 0.0);
  EXPECT_EQ(ds.trustworthy_border_px, (ds.psf_size() / 2 + 1) / 2);  // ceil(K / 2 / r)
  ASSERT_EQ(ds.stars.size(), 1u);
  EXPECT_DOUBLE_EQ(ds.stars[0].y, 21.0);  // camera -> HR
  EXPECT_DOUBLE_EQ(ds.stars[0].x, 41.5);
}

// A dataset loaded by sections (a job that solves one tile) holds no pixel; each section read from the files
// is exactly the held dataset's cut, bad pixels, mask and weights included.
TEST_F(DatasetTest, SectionsReadFromTheFilesEqualTheHeldPixels) {
  TempDir real;
  const Dataset sim = LoadDataset(dir_->File("sim"));
  ImageStack frames = sim.frames, valid = sim.valid;
  frames[1](3, 4) = std::nan("");
  frames[0](20, 30) = std::numeric_limits<double>::infinity();
  valid[0](7, 9) = 0;
  WriteFitsCube(real.File("frames.fits"), frames, {}, FitsType::kFloat64);
  WriteFitsCube(real.File("valid.fits"), valid, {}, FitsType::kFloat64);
  WriteFitsCube(real.File("w.fits"), *sim.weights, {}, FitsType::kFloat64);
  WriteFits(real.File("psf.fits"), sim.psfs[0], {}, FitsType::kFloat64);
  test::WriteJson(real.File("manifest.json"), {{"format", "aosr-manifest"}, {"version", 1}, {"frames", "frames.fits"},
                                               {"valid", "valid.fits"}, {"weights", "w.fits"}, {"psfs", "psf.fits"},
                                               {"r", 2}, {"gain_e_per_adu", 2.0}, {"bias_adu", 100.0}});
  const Dataset held = LoadDataset(real.path().string());
  const Dataset lazy = LoadDataset(real.path().string(), DatasetPixels::kSections);
  EXPECT_TRUE(lazy.frames.empty() && lazy.valid.empty() && !lazy.weights);
  ASSERT_TRUE(lazy.pixel_files.has_value());
  EXPECT_EQ(lazy.size(), 2);
  EXPECT_EQ(lazy.frame, held.frame);
  for (const auto& [y0, x0, rows, cols] : std::vector<std::array<Index, 4>>{{0, 0, 32, 32}, {2, 3, 5, 7}, {18, 25, 14, 7}}) {
    const DatasetSection a = ReadDatasetSection(lazy, y0, x0, rows, cols);
    const DatasetSection b = ReadDatasetSection(held, y0, x0, rows, cols);
    ASSERT_EQ(a.frames.size(), 2u);
    ASSERT_TRUE(a.weights && b.weights);
    for (int i = 0; i < 2; ++i) {
      EXPECT_TRUE((a.frames[i] == held.frames[i].block(y0, x0, rows, cols)).all()) << y0 << " " << x0;
      EXPECT_TRUE((a.frames[i] == b.frames[i]).all());
      EXPECT_TRUE((a.valid[i] == held.valid[i].block(y0, x0, rows, cols)).all());
      EXPECT_TRUE(((*a.weights)[i] == (*held.weights)[i].block(y0, x0, rows, cols)).all());
    }
  }
  const DatasetSection bad = ReadDatasetSection(lazy, 0, 0, 32, 32);
  EXPECT_EQ(bad.valid[1](3, 4), 0.0);  // NaN: invalid, read as the bias, weight 0
  EXPECT_EQ(bad.frames[1](3, 4), 100.0);
  EXPECT_EQ((*bad.weights)[1](3, 4), 0.0);
  EXPECT_EQ(bad.valid[0](20, 30), 0.0);  // Inf likewise
  EXPECT_EQ(bad.valid[0](7, 9), 0.0);    // the mask file's
  EXPECT_THROW(ReadDatasetSection(lazy, 30, 0, 5, 5), InvalidArgument);  // past the last row
  EXPECT_THROW(ReadDatasetSection(lazy, 0, -1, 5, 5), InvalidArgument);
  EXPECT_THROW(SelectFrames(lazy, {0}), InvalidArgument);  // needs the pixels held
  // A bad value is found in the section that holds it, naming the manifest.
  valid[1](30, 30) = 0.5;
  WriteFitsCube(real.File("valid.fits"), valid, {}, FitsType::kFloat64);
  EXPECT_NO_THROW(ReadDatasetSection(lazy, 0, 0, 16, 16));
  try {
    ReadDatasetSection(lazy, 16, 16, 16, 16);
    ADD_FAILURE() << "a mask value of 0.5 was accepted";
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("manifest.json: valid"), std::string::npos) << e.what();
  }
}

// What an output must never replace: the manifest and every file it names, resolved, from the folder, the
// manifest's path or the loaded dataset alike (the CLI's and aosr.distributed's rule). A manifest naming every
// kind of file (truth_frames, which the CLI's own copy of this list once left out, among them) gives them all.
TEST_F(DatasetTest, InputFilesAreTheManifestAndEveryFileItNames) {
  const std::string sim = dir_->File("sim");
  const auto canonical = [](const std::string& p) { return fs::weakly_canonical(p); };
  const std::set<fs::path> from_folder = DatasetInputFiles(sim);
  EXPECT_EQ(from_folder, DatasetInputFiles(sim + "/manifest.json"));
  EXPECT_EQ(from_folder, DatasetInputFiles(LoadDataset(sim, DatasetPixels::kSections)));
  for (const char* f : {"manifest.json", "frames.fits", "valid.fits", "weights.fits", "psfs.fits", "truth.fits",
                        "expected.fits"})
    EXPECT_EQ(from_folder.count(canonical(sim + "/" + f)), 1u) << f;
  EXPECT_EQ(from_folder.size(), 7u);

  const std::string other = dir_->File("every_key");
  fs::create_directories(other + "/sub");
  nlohmann::json m = {{"frames", "f.fits"},        {"valid", "sub/v.fits"},    {"weights", "w.fits"},
                      {"psfs", "p.fits"},          {"nominal_psfs", "n.fits"}, {"truth", "t.fits"},
                      {"truth_frames", "tf.fits"}, {"expected", "e.fits"},     {"scene", "../s.json"},
                      {"r", 2}};
  std::ofstream(other + "/manifest.json") << m.dump();
  const std::set<fs::path> all = DatasetInputFiles(other);
  EXPECT_EQ(all.size(), 10u);
  for (const char* f : {"manifest.json", "f.fits", "sub/v.fits", "w.fits", "p.fits", "n.fits", "t.fits", "tf.fits",
                        "e.fits", "../s.json"})
    EXPECT_EQ(all.count(canonical(other + "/" + f)), 1u) << f;
  // A manifest that cannot be read names nothing (LoadDataset reports it by name).
  std::ofstream(other + "/broken.json") << "{ not json";
  EXPECT_TRUE(DatasetInputFiles(other + "/broken.json").empty());
  EXPECT_TRUE(DatasetInputFiles(other + "/missing.json").empty());
}

TEST_F(DatasetTest, RewritingAFolderReplacesTheDataset) {
  TempDir t;
  nlohmann::json j = test::SmallDatasetScene();
  test::SimulateInto(t.File("a.json"), j, t.File("out"));
  j["objects"][0]["flux"]["peak_e"] = 1000.0;
  const test::WrittenSimulation second = test::SimulateInto(t.File("b.json"), j, t.File("out"));
  const Dataset ds = LoadDataset(t.File("out"));
  EXPECT_EQ(MaxAbsDiff(ds.frames[0], second.sim.frames[0].adu), 0.0);
  EXPECT_EQ(ds.manifest["simulation"]["scene"]["source"], t.File("b.json"));
  EXPECT_EQ(std::distance(fs::directory_iterator(t.File("out")), fs::directory_iterator()), 7);
}

}  // namespace
}  // namespace aosr

namespace aosr {
namespace AOSR_TEST_NS {

// A closed-loop simulation also writes the nominal model (the analytic-AO PSFs of the same offsets), which
// loads as Dataset::nominal_psfs: unit sum, the PSFs' shape, close to but not equal to the loop's draws.
TEST(DatasetClosedLoopTest, WritesAndLoadsTheNominalPsfs) {
  TempDir dir;
  nlohmann::json j = test::SmallDatasetScene();
  j["ao"] = {{"mode", "closed-loop"}, {"sensor", "geometric"}, {"time_per_frame_s", 0.02}, {"settling_s", 0.02}};
  j["objects"] = nlohmann::json::array({{{"type", "usaf"}, {"flux", {{"peak_e", 500.0}}}}});
  const test::WrittenSimulation w = test::SimulateInto(dir.File("scene.json"), j, dir.File("sim"));
  ASSERT_EQ(w.sim.nominal_psfs.size(), 2u);
  const ScenePipeline plan(w.scene);
  bool listed = false;
  for (const PipelineStage& s : plan.stages()) listed = listed || s.name == "nominal-psf";
  EXPECT_TRUE(listed);
  const Dataset d = LoadDataset(dir.File("sim"));
  ASSERT_EQ(d.nominal_psfs.size(), 2u);
  for (int i = 0; i < 2; ++i) {
    EXPECT_NEAR(d.nominal_psfs[i].sum(), 1.0, 1e-12);
    EXPECT_EQ(ShapeOf(d.nominal_psfs[i]), ShapeOf(d.psfs[i]));
    const double diff = (d.nominal_psfs[i] - d.psfs[i]).abs().sum();
    EXPECT_GT(diff, 1e-6);  // one loop draw is not the long-exposure model
    EXPECT_LT(diff, 1.0);   // but both are the same telescope's AO PSF
  }
  // Without a closed loop there is no nominal model beyond the PSFs themselves.
  EXPECT_TRUE(NominalPsfs(LoadScene(dir.File("scene.json"))).size() == 2u);
  j["ao"] = {{"mode", "none"}};
  test::WriteJson(dir.File("none.json"), j);
  EXPECT_TRUE(NominalPsfs(LoadScene(dir.File("none.json"))).empty());
}

}  // namespace
}  // namespace aosr

namespace aosr {
namespace AOSR_TEST_NS {

// A scene with a psf_field writes the PSFs of every field point (field_psfs.fits, node-major, with the nodes'
// positions and directions in the header) and the manifest's psf_field section, which loads back as
// Dataset::psf_field with the same numbers; with "scene" instead of PSFs, the scene's field gives it.
TEST(DatasetPsfFieldTest, WritesAndLoadsTheFieldGrid) {
  TempDir dir;
  nlohmann::json j = test::SmallDatasetScene();
  j["ao"] = {{"mode", "analytic"}};
  j["psf_field"] = {{"guide_star_arcsec", {-20.0, 5.0}}, {"grid", {2, 3}}};
  const test::WrittenSimulation w = test::SimulateInto(dir.File("scene.json"), j, dir.File("sim"));
  ASSERT_EQ(w.sim.field_psfs.size(), 6u);
  const Dataset d = LoadDataset(dir.File("sim"));
  ASSERT_TRUE(d.psf_field.has_value());
  EXPECT_EQ(d.psf_field->grid.ny(), 2);
  EXPECT_EQ(d.psf_field->grid.nx(), 3);
  EXPECT_EQ(d.psf_field->guide_star_x_arcsec, -20.0);
  EXPECT_EQ(d.psf_field->guide_star_y_arcsec, 5.0);
  ASSERT_EQ(d.psf_field->psfs.size(), 6u);
  for (int k = 0; k < 6; ++k)
    for (int i = 0; i < 2; ++i)
      EXPECT_LT((d.psf_field->psfs[k][i] - w.sim.field_psfs[k][i]).abs().maxCoeff(), 1e-15) << k << ", " << i;
  EXPECT_TRUE(d.psf_field->nominal_psfs.empty());
  const FitsData f = ReadFits(dir.File("sim/field_psfs.fits"));
  EXPECT_EQ(f.planes.size(), 12u);
  EXPECT_EQ(f.header.GetInt("FLDNX"), 3);
  EXPECT_DOUBLE_EQ(f.header.GetDouble("FX0002"), 63.0);
  EXPECT_NEAR(f.header.GetDouble("FTX0000"), w.sim.field_directions[0].x_rad * 180 * 3600 / M_PI, 1e-9);
  EXPECT_EQ(d.manifest.at("simulation").at("psf_field").at("nodes").size(), 6u);
  // The instrument-scene form: the same field PSFs, computed from the scene.
  nlohmann::json m = d.manifest;
  m.erase("psfs");
  m.erase("psf_field");
  m.erase("offsets");
  m["scene"] = "../scene.json";
  test::WriteJson(dir.File("sim/from_scene.json"), m);
  const Dataset s = LoadDataset(dir.File("sim/from_scene.json"));
  ASSERT_TRUE(s.psf_field.has_value());
  for (int k = 0; k < 6; ++k) EXPECT_LT((s.psf_field->psfs[k][1] - w.sim.field_psfs[k][1]).abs().maxCoeff(), 1e-15);
}

}  // namespace AOSR_TEST_NS
}  // namespace aosr
