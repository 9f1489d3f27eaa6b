// End-to-end checks of `aosr video` through the real executable: a small sequence dataset (10 frames cycling
// through 4 phases, a blob moving one HR pixel per frame) written by the test, the cube's shape, its TIMES
// extension and WCS, every plane against the batch reconstruction of its window (the library's and, for two
// windows, `aosr reconstruct` of a window dataset written independently), the video file read back through
// OpenCV, bad options and inputs refused before anything is written, and --force.
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <opencv2/videoio.hpp>
#include <string>
#include <vector>

#include "aosr/core/forward_model.hpp"
#include "aosr/core/metrics.hpp"
#include "aosr/io/fits.hpp"
#include "aosr/scene/dataset.hpp"
#include "aosr/solvers/dataset_problem.hpp"
#include "aosr/solvers/reconstruct.hpp"
#include "support/testing.hpp"
#include "support/video_sequence.hpp"

namespace AOSR_TEST_NS {

namespace fs = std::filesystem;
using aosr::Image;
using aosr::ImageStack;
using aosr::Index;
using aosr::test::CliRun;
using aosr::test::RunCli;
using ::testing::HasSubstr;

using aosr::test::kVideoBias;
using aosr::test::kVideoDt;
using aosr::test::kVideoFrames;
using aosr::test::kVideoGain;
using aosr::test::kVideoHr;
using aosr::test::kVideoR;
using aosr::test::VideoFrameE;
using aosr::test::VideoManifest;
using aosr::test::VideoPsfs;
using aosr::test::WriteVideoDataset;

// The number of frames OpenCV reads back from a video file, and their size; -1 when it cannot open it.
int VideoFramesReadBack(const std::string& path, int* rows, int* cols) {
  cv::VideoCapture cap(path);
  if (!cap.isOpened()) return -1;
  int n = 0;
  cv::Mat f;
  while (cap.read(f) && !f.empty()) {
    *rows = f.rows;
    *cols = f.cols;
    ++n;
  }
  return n;
}

class VideoCliTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = fs::temp_directory_path() / ("aosr_video_cli_" + std::to_string(getpid()));
    fs::remove_all(dir_);
    std::vector<int> all;
    nlohmann::json slots = nlohmann::json::array(), times = nlohmann::json::array();
    for (int j = 0; j < kVideoFrames; ++j) {
      all.push_back(j);
      slots.push_back(j % 4);
      times.push_back(kVideoDt * j);
    }
    WriteVideoDataset(dir_ / "seq", all, VideoPsfs(), {{"slots", slots}, {"times_s", times}});
  }
  static void TearDownTestSuite() { fs::remove_all(dir_); }

  static std::string Seq() { return (dir_ / "seq").string(); }
  static std::string Out(const std::string& name) { return (dir_ / name).string(); }
  // The run's --json summary (stderr may precede it).
  static nlohmann::json Json(const CliRun& r) {
    const std::size_t brace = r.out.find('{');
    return brace == std::string::npos ? nlohmann::json() : nlohmann::json::parse(r.out.substr(brace));
  }

  // The batch reconstruction of frames `window` (time order) of the sequence, as `aosr reconstruct` makes it
  // from a dataset of those frames.
  static Image Batch(const std::vector<int>& window, aosr::ReconstructionMethod method, double lambda) {
    aosr::DatasetProblemOptions po;
    po.method = method;
    const aosr::DatasetProblem dp = aosr::ProblemFromDataset(aosr::SelectFrames(aosr::LoadDataset(Seq()), window), po);
    aosr::ReconstructOptions ro;
    ro.method = method;
    if (lambda >= 0) {
      ro.tikhonov.lambda_rule = aosr::TikhonovLambdaRule::kFixed;
      ro.tikhonov.lambda = lambda;
    }
    return aosr::Reconstruct(dp.problem, ro).image;
  }

  static fs::path dir_;
};
fs::path VideoCliTest::dir_;

TEST_F(VideoCliTest, SlidingTikhonovCubeTimesWcsAndEveryPlaneEqualTheBatch) {
  const CliRun r = RunCli("video " + Seq() + " -o " + Out("tik") + " -m tikhonov --lambda 3e-3 --json");
  ASSERT_EQ(r.status, 0) << r.out;
  const nlohmann::json j = Json(r);
  const int outputs = kVideoFrames - 4 + 1;  // one per frame once each phase has one
  EXPECT_EQ(j["outputs"], outputs) << r.out;
  EXPECT_EQ(j["frames_read"], kVideoFrames);
  EXPECT_EQ(j["paths"]["slot-filter"], outputs) << r.out;

  const aosr::FitsData cube = aosr::ReadFits(Out("tik") + "/video.fits");
  ASSERT_EQ(cube.planes.size(), std::size_t(outputs));
  for (const Image& p : cube.planes) {
    ASSERT_EQ(p.rows(), kVideoHr.rows);
    ASSERT_EQ(p.cols(), kVideoHr.cols);
  }
  const aosr::FitsHeader& h = cube.header;
  EXPECT_EQ(h.GetString("METHOD"), "tikhonov");
  EXPECT_EQ(h.GetString("WINDOW"), "sliding");
  EXPECT_EQ(h.GetInt("NPHASES"), 4);
  EXPECT_EQ(h.GetInt("NOUTPUT"), outputs);
  EXPECT_EQ(h.GetString("BUNIT"), "electron");
  // The HR grid's WCS: CD / r, CRPIX through the pixel-centre rule ((CRPIX - 1/2) r + 1/2; no DM shift here).
  EXPECT_EQ(h.GetString("CTYPE1"), "RA---TAN");
  EXPECT_NEAR(h.GetDouble("CD1_1"), -1e-5 / kVideoR, 1e-15);
  EXPECT_NEAR(h.GetDouble("CD2_2"), 1e-5 / kVideoR, 1e-15);
  EXPECT_NEAR(h.GetDouble("CRPIX1"), (10.5 - 0.5) * kVideoR + 0.5, 1e-9);
  EXPECT_NEAR(h.GetDouble("CRPIX2"), (12.5 - 0.5) * kVideoR + 0.5, 1e-9);
  EXPECT_NEAR(h.GetDouble("CRVAL1"), 150.1, 1e-9);
  EXPECT_NEAR(h.GetDouble("CRVAL2"), 2.2, 1e-9);

  // TIMES: row k = output k: time of its newest frame, of its oldest, first and last input frame.
  const aosr::FitsData t = aosr::ReadFitsExtension(Out("tik") + "/video.fits", "TIMES");
  ASSERT_EQ(t.planes.size(), 1u);
  ASSERT_EQ(t.planes[0].rows(), outputs);
  ASSERT_EQ(t.planes[0].cols(), 4);
  for (int k = 0; k < outputs; ++k) {
    EXPECT_NEAR(t.planes[0](k, 0), kVideoDt * (k + 3), 1e-12) << k;
    EXPECT_NEAR(t.planes[0](k, 1), kVideoDt * k, 1e-12) << k;
    EXPECT_EQ(t.planes[0](k, 2), k);
    EXPECT_EQ(t.planes[0](k, 3), k + 3);
  }
  EXPECT_NEAR(h.GetDouble("TSTART"), kVideoDt * 3, 1e-12);
  EXPECT_NEAR(h.GetDouble("TSTOP"), kVideoDt * (kVideoFrames - 1), 1e-12);

  // Every plane is the batch Tikhonov of its window (float32 in the file: 1e-6 of the peak).
  for (int k = 0; k < outputs; ++k) {
    const Image ref = Batch({k, k + 1, k + 2, k + 3}, aosr::ReconstructionMethod::kTikhonov, 3e-3);
    EXPECT_LT((cube.planes[std::size_t(k)] - ref).abs().maxCoeff(), 1e-6 * ref.abs().maxCoeff()) << "output " << k;
  }
  // The moving blob moves the outputs: consecutive planes differ (the test would pass a constant cube otherwise).
  EXPECT_GT((cube.planes[1] - cube.planes[0]).abs().maxCoeff(), 0.05 * cube.planes[0].abs().maxCoeff());

  // Two windows through `aosr reconstruct` on a dataset of their frames written independently (frames in time
  // order, each with its phase's PSF): the same image and the same WCS.
  const ImageStack psfs = VideoPsfs();
  for (int k : {0, outputs - 1}) {
    const std::vector<int> w = {k, k + 1, k + 2, k + 3};
    ImageStack wp;
    for (int f : w) wp.push_back(psfs[std::size_t(f % 4)]);
    const fs::path wd = dir_ / ("window" + std::to_string(k));
    WriteVideoDataset(wd, w, wp, nullptr);
    const std::string rec = (dir_ / ("window" + std::to_string(k) + ".fits")).string();
    const CliRun b = RunCli("reconstruct " + wd.string() + " -m tikhonov --lambda 3e-3 -o " + rec);
    ASSERT_EQ(b.status, 0) << b.out;
    const aosr::FitsData ref = aosr::ReadFits(rec);
    EXPECT_LT((cube.planes[std::size_t(k)] - ref.planes[0]).abs().maxCoeff(), 1e-6 * ref.planes[0].abs().maxCoeff())
        << "window " << k;
    for (const char* key : {"CRPIX1", "CRPIX2", "CRVAL1", "CRVAL2", "CD1_1", "CD2_2"})
      EXPECT_DOUBLE_EQ(h.GetDouble(key), ref.header.GetDouble(key)) << key;
  }

  // The video file: one frame per output, of the HR size.
  int rows = 0, cols = 0;
  const int n = VideoFramesReadBack(Out("tik") + "/video.avi", &rows, &cols);
  ASSERT_GE(n, 0) << "OpenCV cannot open " << Out("tik") << "/video.avi";
  EXPECT_EQ(n, outputs);
  EXPECT_EQ(rows, kVideoHr.rows);
  EXPECT_EQ(cols, kVideoHr.cols);
}

TEST_F(VideoCliTest, CycleWindowLinearOnePlanePerCycleEqualsTheBatch) {
  const CliRun r = RunCli("video " + Seq() + " -o " + Out("lin") + " -m linear --window cycle --zoom 2 --json");
  ASSERT_EQ(r.status, 0) << r.out;
  EXPECT_EQ(Json(r)["outputs"], 2) << r.out;  // frames 0-3 and 4-7; 8 and 9 complete no cycle
  const aosr::FitsData cube = aosr::ReadFits(Out("lin") + "/video.fits");
  ASSERT_EQ(cube.planes.size(), 2u);
  EXPECT_EQ(cube.header.GetString("WINDOW"), "cycle");
  EXPECT_GT(cube.header.GetDouble("KAPPA"), 0.0);
  const aosr::FitsData t = aosr::ReadFitsExtension(Out("lin") + "/video.fits", "TIMES");
  EXPECT_EQ(t.planes[0](1, 2), 4);
  EXPECT_EQ(t.planes[0](1, 3), 7);
  for (int k = 0; k < 2; ++k) {
    const Image ref = Batch({4 * k, 4 * k + 1, 4 * k + 2, 4 * k + 3}, aosr::ReconstructionMethod::kLinear, -1);
    EXPECT_LT((cube.planes[std::size_t(k)] - ref).abs().maxCoeff(), 1e-6 * ref.abs().maxCoeff()) << "output " << k;
  }
  int rows = 0, cols = 0;
  EXPECT_EQ(VideoFramesReadBack(Out("lin") + "/video.avi", &rows, &cols), 2);
  EXPECT_EQ(rows, 2 * kVideoHr.rows);  // --zoom 2
  EXPECT_EQ(cols, 2 * kVideoHr.cols);
}

// A simulated sequence (a scene's "sequence": `aosr simulate` of data/scenes/video-planet.json, 8 exposures)
// carries the truth at every frame's time: `aosr video` scores each output against the truth at its newest frame
// (TIMES columns 5 and 6, the --json truth_scores) with the same numbers as aosr::CompareImages on the cube, and
// the manifest's phases and times drive the windows.
TEST_F(VideoCliTest, ASimulatedSequenceIsScoredAgainstTheTruthAtEachTime) {
  const std::string scene = std::string(AOSR_SOURCE_DIR) + "/data/scenes/video-planet.json";
  const CliRun sim = RunCli("simulate " + scene + " --set sequence.frames=8 -o " + Out("planet"));
  ASSERT_EQ(sim.status, 0) << sim.out;
  EXPECT_THAT(sim.out, HasSubstr("in a sequence of 8 exposures"));
  const CliRun r = RunCli("video " + Out("planet") + " -o " + Out("planet_video") + " --no-video --json");
  ASSERT_EQ(r.status, 0) << r.out;
  const nlohmann::json j = Json(r);
  ASSERT_EQ(j["outputs"], 5) << r.out;  // sliding: frames 3..7 complete a window of the 4 phases
  ASSERT_TRUE(j.contains("truth_scores")) << r.out;
  const std::vector<double> psnr = j["truth_scores"]["psnr_db"];
  ASSERT_EQ(psnr.size(), 5u);
  const aosr::Dataset d = aosr::LoadDataset(Out("planet"));
  ASSERT_EQ(d.truth_frames.size(), 8u);
  const aosr::FitsData cube = aosr::ReadFits(Out("planet_video") + "/video.fits");
  const aosr::FitsData t = aosr::ReadFitsExtension(Out("planet_video") + "/video.fits", "TIMES");
  ASSERT_EQ(t.planes[0].cols(), 6);
  aosr::MetricOptions mo;
  mo.crop_px = j["truth_scores"]["crop_px"];
  mo.peak = j["truth_scores"]["peak"];
  for (int k = 0; k < 5; ++k) {
    EXPECT_EQ(t.planes[0](k, 3), 3 + k);  // the newest frame
    EXPECT_DOUBLE_EQ(t.planes[0](k, 0), d.times_s[std::size_t(3 + k)]);
    // The cube is float32: the PSNR of its plane agrees to ~1e-6 dB.
    const double ref = aosr::CompareImages(d.truth_frames[std::size_t(3 + k)], cube.planes[std::size_t(k)], mo).psnr;
    EXPECT_NEAR(psnr[std::size_t(k)], ref, 1e-3) << "output " << k;
    EXPECT_DOUBLE_EQ(t.planes[0](k, 4), psnr[std::size_t(k)]);
    EXPECT_GT(psnr[std::size_t(k)], 20.0);  // a reconstruction, not noise
  }
}

TEST_F(VideoCliTest, BadOptionsAndInputsAreRefusedBeforeAnythingIsWritten) {
  struct Case {
    std::string args, expect;
  };
  // A sequence whose slots do not match its frames.
  const fs::path bad = dir_ / "bad_slots";
  WriteVideoDataset(bad, {0, 1, 2, 3, 4}, VideoPsfs(), {{"slots", {0, 1, 2, 3}}});
  const std::vector<Case> cases = {
      {"-m drizzle", "tikhonov"},                           // not a streaming method (CLI11 names the choices)
      {"--window sometimes", "cycle"},                      // CLI11
      {"--lambda-rule wiener", "lambda_rule"},              // data-dependent filter, refused by the options
      {"--prior fitted", "fitted"},
      {"--target-psf moffat -m linear", "gaussian:"},
      {"--codec MJPEG", "four characters"},                 // VideoFileOptions
      {"--weights everything", "weights"},
  };
  for (const Case& c : cases) {
    const std::string out = Out("bad_out");
    const CliRun r = RunCli("video " + Seq() + " -o " + out + " " + c.args);
    EXPECT_NE(r.status, 0) << c.args;
    EXPECT_THAT(r.out, HasSubstr(c.expect)) << c.args;
    EXPECT_FALSE(fs::exists(out)) << c.args << ": the output folder was made";
  }
  const CliRun r = RunCli("video " + bad.string() + " -o " + Out("bad_out"));
  EXPECT_EQ(r.status, 1) << r.out;
  EXPECT_THAT(r.out, HasSubstr("slots"));
  EXPECT_THAT(r.out, HasSubstr("one per frame"));
  EXPECT_FALSE(fs::exists(Out("bad_out")));
  const CliRun missing = RunCli("video " + Out("no_such_dataset") + " -o " + Out("bad_out"));
  EXPECT_EQ(missing.status, 1) << missing.out;
  EXPECT_THAT(missing.out, HasSubstr("no_such_dataset"));
  EXPECT_FALSE(fs::exists(Out("bad_out")));
}

TEST_F(VideoCliTest, ExistingOutputsAreKeptWithoutForce) {
  const std::string out = Out("again");
  ASSERT_EQ(RunCli("video " + Seq() + " -o " + out + " --lambda 1e-2 --no-video").status, 0);
  const auto before = fs::last_write_time(out + "/video.fits");
  const Image first = aosr::ReadFits(out + "/video.fits").planes[0];
  const CliRun r = RunCli("video " + Seq() + " -o " + out + " --lambda 1e-1 --no-video");
  EXPECT_EQ(r.status, 1) << r.out;
  EXPECT_THAT(r.out, HasSubstr("exists; pass --force"));
  EXPECT_EQ(fs::last_write_time(out + "/video.fits"), before);
  EXPECT_TRUE((aosr::ReadFits(out + "/video.fits").planes[0] == first).all());
  const CliRun f = RunCli("video " + Seq() + " -o " + out + " --lambda 1e-1 --no-video --force");
  ASSERT_EQ(f.status, 0) << f.out;
  // A larger λ: a different (smoother) image replaced the first.
  EXPECT_GT((aosr::ReadFits(out + "/video.fits").planes[0] - first).abs().maxCoeff(), 1e-3 * first.abs().maxCoeff());
  EXPECT_FALSE(fs::exists(out + "/video.avi"));  // --no-video
}

}  // namespace AOSR_TEST_NS
