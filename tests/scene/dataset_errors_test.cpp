// Datasets: every bad manifest, file and output folder gets an error naming the manifest field or path.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <filesystem>

#include "../io/temp_dir.hpp"
#include "aosr/io/config.hpp"
#include "aosr/io/fits.hpp"
#include "aosr/scene/dataset.hpp"
#include "dataset_fixture.hpp"
#include "support/testing.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

namespace fs = std::filesystem;
using test::ErrorOf;
using testing_io::TempDir;
using ::testing::AllOf;
using ::testing::HasSubstr;

// A folder with a written simulation, whose manifest each test edits into a broken one.
class DatasetErrorsTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new TempDir;
    test::SimulateInto(dir_->File("scene.json"), test::SmallDatasetScene(), dir_->File("sim"));
    manifest_ = new nlohmann::json(ReadJsonFile(dir_->File("sim/manifest.json")));
  }
  static void TearDownTestSuite() {
    delete manifest_;
    delete dir_;
  }
  // Writes `m` as sim/<name> (next to the simulation's files) and returns LoadDataset's error.
  template <typename E = InvalidArgument>
  static std::string LoadError(const nlohmann::json& m) {
    test::WriteJson(dir_->File("sim/broken.json"), m);
    return ErrorOf<E>([&] { LoadDataset(dir_->File("sim/broken.json")); });
  }
  static TempDir* dir_;
  static nlohmann::json* manifest_;
};
TempDir* DatasetErrorsTest::dir_ = nullptr;
nlohmann::json* DatasetErrorsTest::manifest_ = nullptr;

TEST_F(DatasetErrorsTest, BadWcsNamesTheManifestAndTheKeyword) {
  nlohmann::json m = *manifest_;
  m["wcs"] = {{"CTYPE1", "RA---SIN"}, {"CTYPE2", "DEC--SIN"}, {"CRPIX1", 1.0}, {"CRPIX2", 1.0},
              {"CRVAL1", 0.0},        {"CRVAL2", 0.0},        {"CDELT1", -1e-5}, {"CDELT2", 1e-5}};
  EXPECT_THAT(LoadError(m), AllOf(HasSubstr("broken.json: wcs: WcsFromHeader: invalid CTYPE1 = 'RA---SIN'"),
                                  HasSubstr("only the gnomonic TAN projection is supported")));
  m["wcs"] = {{"CTYPE1", "RA---TAN"}, {"CTYPE2", "DEC--TAN"}, {"CRPIX1", 1.0}, {"CRPIX2", 1.0},
              {"CRVAL1", 0.0},        {"CRVAL2", 0.0},        {"CD1_1", -1e-5}, {"CD2_2", 1e-5}, {"A_ORDER", 2}};
  EXPECT_THAT(LoadError(m), HasSubstr("A_ORDER = (present); allowed: no SIP distortion"));
  m["wcs"] = "RA---TAN";
  EXPECT_THAT(LoadError(m), HasSubstr("broken.json: wcs = \"RA---TAN\"; allowed: an object of FITS WCS keywords"));
  m["wcs"] = {{"NAXIS", 2}};
  EXPECT_THAT(LoadError(m), HasSubstr("wcs.NAXIS"));
  // A frames file whose own header WCS is unsupported: the file, the keyword, and the way out.
  FitsData frames = ReadFits(dir_->File("sim/frames.fits"));
  frames.header.Set("CTYPE1", "RA---TAN-SIP");
  WriteFitsCube(dir_->File("sim/sip_frames.fits"), frames.planes, frames.header, FitsType::kFloat64);
  m = *manifest_;
  m["frames"] = "sip_frames.fits";
  EXPECT_THAT(LoadError(m), AllOf(HasSubstr("sip_frames.fits (frames of"), HasSubstr("-SIP is not supported"),
                                  HasSubstr("\"wcs\" section replaces it")));
  m["wcs"] = nullptr;
  test::WriteJson(dir_->File("sim/broken.json"), m);
  EXPECT_FALSE(LoadDataset(dir_->File("sim/broken.json")).wcs);
}

TEST_F(DatasetErrorsTest, MissingManifestOrFile) {
  TempDir empty;
  EXPECT_THAT(ErrorOf<IoError>([&] { LoadDataset(empty.path().string()); }),
              AllOf(HasSubstr(empty.path().string()), HasSubstr("no manifest.json")));
  EXPECT_THAT(ErrorOf<IoError>([&] { LoadDataset(empty.File("nope.json")); }), HasSubstr("nope.json"));
  nlohmann::json m = *manifest_;
  m["frames"] = "missing_frames.fits";
  EXPECT_THAT(LoadError(m), AllOf(HasSubstr("broken.json: frames"), HasSubstr("missing_frames.fits"), HasSubstr("no such file")));
  m = *manifest_;
  m["weights"] = "";
  EXPECT_THAT(LoadError(m), HasSubstr("weights = \"\""));
  // A file that exists but is not FITS: the reader's IoError names it.
  test::WriteJson(dir_->File("sim/not_fits.fits"), {{"a", 1}});
  m = *manifest_;
  m["truth"] = "not_fits.fits";
  EXPECT_THAT(LoadError<IoError>(m), HasSubstr("not_fits.fits"));
}

TEST_F(DatasetErrorsTest, UnknownOrMalformedManifestFields) {
  nlohmann::json m = *manifest_;
  m["framez"] = "frames.fits";
  EXPECT_THAT(LoadError(m), AllOf(HasSubstr("framez"), HasSubstr("unknown field")));
  m = *manifest_;
  m["format"] = "fits-list";
  EXPECT_THAT(LoadError(m), AllOf(HasSubstr("format = \"fits-list\""), HasSubstr("aosr-manifest")));
  m = *manifest_;
  m["version"] = 2;
  EXPECT_THAT(LoadError(m), HasSubstr("version = 2"));
  m = *manifest_;
  m.erase("psfs");
  EXPECT_THAT(LoadError(m), AllOf(HasSubstr("psfs = (missing)"), HasSubstr("exactly one of psfs")));
  m = *manifest_;
  m["scene"] = "../scene.json";
  EXPECT_THAT(LoadError(m), HasSubstr("both psfs and scene"));
  m = *manifest_;
  m["gain_e_per_adu"] = 0;
  EXPECT_THAT(LoadError(m), HasSubstr("gain_e_per_adu = 0"));
  m = *manifest_;
  m["offsets"][0]["shift_px"] = {1.0};
  EXPECT_THAT(LoadError(m), HasSubstr("offsets[0].shift_px"));
  m = *manifest_;
  m["offsets"].erase(1);
  EXPECT_THAT(LoadError(m), AllOf(HasSubstr("offsets = 1 entries"), HasSubstr("one per frame (2)")));
  m = *manifest_;
  m["stars"][0]["y_px"] = 99.0;  // disagrees with y_hr_px
  EXPECT_THAT(LoadError(m), HasSubstr("stars[0].y_px"));
  m = *manifest_;
  m["pixel_scale"]["hr_mas"] = 1.0;
  EXPECT_THAT(LoadError(m), HasSubstr("pixel_scale.hr_mas = 1"));
  m = *manifest_;
  m["frame_shape"] = {32, 33};
  EXPECT_THAT(LoadError(m), HasSubstr("frame_shape = 32x33"));
}

TEST_F(DatasetErrorsTest, WrongCubeShapes) {
  const ImageStack three(3, Image::Ones(32, 32));
  WriteFitsCube(dir_->File("sim/three.fits"), three);
  nlohmann::json m = *manifest_;
  m["valid"] = "three.fits";
  EXPECT_THAT(LoadError(m), AllOf(HasSubstr("valid = a 3 x 32x32 cube"), HasSubstr("2 x 32x32")));
  m = *manifest_;
  m["psfs"] = "three.fits";  // three planes for two frames
  EXPECT_THAT(LoadError(m), AllOf(HasSubstr("psfs = 3 x 32x32"), HasSubstr("K even")));
  WriteFitsCube(dir_->File("sim/odd.fits"), ImageStack(2, Image::Ones(5, 5)));
  m = *manifest_;
  m["psfs"] = "odd.fits";
  EXPECT_THAT(LoadError(m), AllOf(HasSubstr("psfs = 2 x 5x5"), HasSubstr("K even")));
  WriteFitsCube(dir_->File("sim/zero.fits"), ImageStack(2, Image::Zero(4, 4)));
  m = *manifest_;
  m["psfs"] = "zero.fits";
  m.erase("psf_size_px");
  EXPECT_THAT(LoadError(m), AllOf(HasSubstr("psfs = plane 0 with sum 0"), HasSubstr("sum > 0")));
  m = *manifest_;
  m["truth"] = "frames.fits";  // a camera cube where one HR image belongs
  EXPECT_THAT(LoadError(m), AllOf(HasSubstr("truth = a 2 x 32x32 cube"), HasSubstr("1 x 64x64")));
  WriteFitsCube(dir_->File("sim/halves.fits"), ImageStack(2, Image::Constant(32, 32, 0.5)));
  m = *manifest_;
  m["valid"] = "halves.fits";
  EXPECT_THAT(LoadError(m), HasSubstr("values other than 0 and 1"));
  // Frames that do not match the instrument scene.
  m = {{"format", "aosr-manifest"}, {"version", 1}, {"frames", "three.fits"}, {"scene", "../scene.json"}};
  EXPECT_THAT(LoadError(m), AllOf(HasSubstr("frames = 3 x 32x32"), HasSubstr("the scene's frames x frame_px = 2 x 32x32")));
  m["frames"] = "frames.fits";
  m["offsets"] = nlohmann::json::array();
  EXPECT_THAT(LoadError(m), HasSubstr("offsets = (given with scene)"));
}

// psf_field: its cube must hold grid nodes x frames planes of the PSFs' shape, each with light; its grid and
// interpolation are checked.
TEST_F(DatasetErrorsTest, BadPsfFieldSections) {
  const int k = int((*manifest_)["psf_size_px"].get<long long>());
  WriteFitsCube(dir_->File("sim/field3.fits"), ImageStack(3, Image::Ones(k, k)));
  WriteFitsCube(dir_->File("sim/field8.fits"), ImageStack(8, Image::Ones(k, k)));
  nlohmann::json m = *manifest_;
  m["psf_field"] = {{"psfs", "field3.fits"}, {"grid", {2, 2}}};
  EXPECT_THAT(LoadError(m), AllOf(HasSubstr("psf_field.psfs = 3 x"), HasSubstr("8 planes (4 nodes x 2 frames")));
  m["psf_field"] = {{"psfs", "field8.fits"}, {"grid", {2, 65}}};
  EXPECT_THAT(LoadError(m), AllOf(HasSubstr("psf_field.grid"), HasSubstr("1..64 nodes")));
  m["psf_field"] = {{"psfs", "field8.fits"}, {"grid", {2, 2}}, {"interpolation", "cubic"}};
  EXPECT_THAT(LoadError(m), AllOf(HasSubstr("psf_field.interpolation"), HasSubstr("bilinear")));
  m["psf_field"] = {{"psfs", "field8.fits"}, {"grid", {2, 2}}, {"spacing", 3}};
  EXPECT_THAT(LoadError(m), HasSubstr("psf_field.spacing"));
  m["psf_field"] = {{"grid", {2, 2}}};
  EXPECT_THAT(LoadError(m), HasSubstr("psf_field.psfs"));
  ImageStack dark(8, Image::Ones(k, k));
  dark[5].setZero();
  WriteFitsCube(dir_->File("sim/field_dark.fits"), dark);
  m["psf_field"] = {{"psfs", "field_dark.fits"}, {"grid", {2, 2}}};
  EXPECT_THAT(LoadError(m), AllOf(HasSubstr("psf_field.psfs = plane 5 with sum 0"), HasSubstr("sum > 0")));
  m["psf_field"] = {{"psfs", "field8.fits"}, {"grid", {2, 2}}};
  EXPECT_EQ(ErrorOf([&] {
              test::WriteJson(dir_->File("sim/ok.json"), m);
              LoadDataset(dir_->File("sim/ok.json"));
            }),
            "no exception");
}

TEST_F(DatasetErrorsTest, NeverWritesOverAnInput) {
  TempDir t;
  // The scene file is the folder's manifest.json: writing the dataset there would overwrite it.
  test::WriteJson(t.File("manifest.json"), test::SmallDatasetScene());
  const SceneSpec scene = LoadScene(t.File("manifest.json"));
  const ScenePipeline pipeline(scene);
  const Simulation sim = pipeline.Run();
  EXPECT_THAT(ErrorOf([&] { WriteSimulation(t.path().string(), scene, pipeline, sim); }),
              AllOf(HasSubstr("manifest.json"), HasSubstr("never overwrites an input")));
  EXPECT_EQ(ReadJsonFile(t.File("manifest.json")), test::SmallDatasetScene());  // untouched
  EXPECT_EQ(t.List().size(), 1u);                                              // nothing else written
  // The output folder is an existing file (the scene itself).
  EXPECT_THAT(ErrorOf<IoError>([&] { WriteSimulation(t.File("manifest.json"), scene, pipeline, sim); }),
              HasSubstr("not a folder"));
  // A simulation that does not belong to the scene.
  Simulation short_sim = sim;
  short_sim.frames.pop_back();
  EXPECT_THAT(ErrorOf([&] { WriteSimulation(t.File("out"), scene, pipeline, short_sim); }),
              AllOf(HasSubstr("WriteSimulation"), HasSubstr("N = 2")));
  EXPECT_FALSE(fs::exists(t.File("out")));
}


// A simulated sequence's per-exposure truth: a manifest naming a truth_frames cube of the wrong plane count or
// shape is refused with the field; PerPhase refuses a stack that is not one image per exposure.
TEST(DatasetSequenceErrorsTest, TruthFramesAndPerPhase) {
  TempDir dir;
  nlohmann::json j = test::SmallDatasetScene();  // N = 2
  j["sequence"] = {{"frames", 3}};
  j["objects"][1]["variation"] = {{"velocity_px_per_s", {1.0, 0.0}}};
  const test::WrittenSimulation w = test::SimulateInto(dir.File("scene.json"), j, dir.File("sim"));
  ASSERT_EQ(w.sim.truth_frames.size(), 3u);
  nlohmann::json m = ReadJsonFile(dir.File("sim/manifest.json"));
  WriteFitsCube(dir.File("sim/two.fits"), {w.sim.truth_frames[0], w.sim.truth_frames[1]}, FitsHeader{});
  m["truth_frames"] = "two.fits";
  test::WriteJson(dir.File("sim/manifest.json"), m);
  EXPECT_THAT(ErrorOf([&] { LoadDataset(dir.File("sim")); }),
              AllOf(HasSubstr("truth_frames"), HasSubstr("2 x"), HasSubstr("one HR image per frame")));
  WriteFitsCube(dir.File("sim/small.fits"), {Image::Zero(8, 8), Image::Zero(8, 8), Image::Zero(8, 8)}, FitsHeader{});
  m["truth_frames"] = "small.fits";
  test::WriteJson(dir.File("sim/manifest.json"), m);
  EXPECT_THAT(ErrorOf([&] { LoadDataset(dir.File("sim")); }), AllOf(HasSubstr("truth_frames"), HasSubstr("8x8")));
  EXPECT_THAT(ErrorOf([&] { PerPhase(w.scene, {w.sim.psfs[0]}); }),
              AllOf(HasSubstr("PerPhase"), HasSubstr("1 images"), HasSubstr("one per exposure of the scene (3)")));
  EXPECT_EQ(PerPhase(w.scene, w.sim.psfs).size(), 2u);
}

}  // namespace
}  // namespace aosr
