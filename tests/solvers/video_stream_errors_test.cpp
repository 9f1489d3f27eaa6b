// Bad input to the streaming reconstruction (video_stream.hpp) and to a sequence manifest gets a clear error.
#include "aosr/solvers/video_stream.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "aosr/core/error.hpp"
#include "aosr/io/fits.hpp"
#include "solvers/tikhonov_fixture.hpp"
#include "support/testing.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

using ::testing::HasSubstr;
using test::ErrorOf;

std::shared_ptr<const MultiFrameModel> Model() {
  return std::make_shared<MultiFrameModel>(test::RasterModel({16, 16}, 2, {{0, 0}, {0, 1}, {1, 0}}, 1.0));
}

TEST(VideoStreamErrors, Options) {
  VideoOptions o;
  o.method = ReconstructionMethod::kDrizzle;
  EXPECT_THAT(ErrorOf([&] { VideoReconstructor(Model(), o); }), HasSubstr("method = drizzle; allowed: tikhonov | linear | tv"));
  o = {};
  o.tv_iterations = 0;
  EXPECT_THAT(ErrorOf([&] { VideoReconstructor(Model(), o); }), HasSubstr("tv_iterations = 0"));
  o = {};
  o.reconstruct.tikhonov.prior = TikhonovPrior::kFitted;
  EXPECT_THAT(ErrorOf([&] { VideoReconstructor(Model(), o); }), HasSubstr("data-dependent"));
  EXPECT_THAT(ErrorOf([&] { VideoReconstructor(nullptr, {}); }), HasSubstr("slot_model"));
  EXPECT_THAT(ErrorOf([] { ParseVideoWindow("tumbling"); }), HasSubstr("sliding | cycle"));
}

TEST(VideoStreamErrors, Push) {
  VideoReconstructor v(Model(), {});
  const Image f = Image::Zero(8, 8);
  EXPECT_THAT(ErrorOf([&] { v.Push(3, 0, 0.0, f); }), HasSubstr("slot = 3"));
  EXPECT_THAT(ErrorOf([&] { v.Push(0, 0, 0.0, Image::Zero(8, 9)); }), HasSubstr("the LR shape"));
  Image bad = f;
  bad(1, 1) = std::nan("");
  EXPECT_THAT(ErrorOf([&] { v.Push(0, 4, 0.0, bad); }), HasSubstr("frame 4"));
  Image w = Image::Ones(8, 8);
  w(1, 1) = 0;
  EXPECT_EQ(ErrorOf([&] { v.Push(0, 4, 0.0, bad, w); }), "no exception");  // a masked NaN is allowed
  w(2, 2) = -1;
  EXPECT_THAT(ErrorOf([&] { v.Push(0, 4, 0.0, f, w); }), HasSubstr(">= 0"));
  EXPECT_THAT(ErrorOf([&] { v.Push(0, 4, std::nan(""), f); }), HasSubstr("time_s"));
}

TEST(VideoStreamErrors, SequenceManifest) {
  const std::string dir =
      (std::filesystem::temp_directory_path() / ("aosr_video_err_" + std::to_string(::getpid()))).string();
  std::filesystem::create_directories(dir);
  WriteFitsCube(dir + "/frames.fits", ImageStack(5, Image::Ones(8, 8)));
  WriteFitsCube(dir + "/psfs.fits", ImageStack(2, Image::Ones(4, 4)));
  auto write = [&](const nlohmann::json& seq) {
    nlohmann::json m = {{"format", "aosr-manifest"}, {"version", 1}, {"frames", "frames.fits"},
                        {"psfs", "psfs.fits"},       {"r", 2},       {"gain_e_per_adu", 1.0},
                        {"bias_adu", 0.0},           {"sequence", seq}};
    std::ofstream(dir + "/manifest.json") << m.dump();
  };
  write({{"slots", {0, 1, 0, 1}}});
  EXPECT_THAT(ErrorOf([&] { LoadDataset(dir); }), HasSubstr("sequence.slots = 4 entries; allowed: one per frame (5"));
  write({{"slots", {0, 1, 0, 1, -1}}});
  EXPECT_THAT(ErrorOf([&] { LoadDataset(dir); }), HasSubstr("integers >= 0"));
  write({{"slots", {0, 1, 0, 1, 2}}});
  EXPECT_THAT(ErrorOf([&] { LoadDataset(dir); }), HasSubstr("psfs"));
  write({{"slots", {0, 1, 0, 1, 0}}, {"times_s", {0, 1, 2, 1.5, 3}}});
  EXPECT_THAT(ErrorOf([&] { LoadDataset(dir); }), HasSubstr("non-decreasing"));
  write({{"slots", {0, 1, 0, 1, 0}}, {"rate", 3}});
  EXPECT_THAT(ErrorOf([&] { LoadDataset(dir); }), HasSubstr("rate"));
  write({{"slots", {0, 1, 0, 1, 0}}});
  const Dataset d = LoadDataset(dir);
  EXPECT_THAT(ErrorOf([&] { SelectFrames(d, {0, 0}); }), HasSubstr("each frame once"));
  EXPECT_THAT(ErrorOf([&] { SelectFrames(d, {7}); }), HasSubstr("frames = 7"));
  EXPECT_THAT(ErrorOf([&] { DatasetVideo(d, {}, {}, 0.0); }), HasSubstr("frame_rate_hz"));
  DatasetProblemOptions po;
  po.offsets = DatasetOffsets::kEstimate;
  EXPECT_THAT(ErrorOf([&] { DatasetVideo(d, {}, po); }), HasSubstr("registration"));
  // A frame from outside (the live quick-look): the phase must exist and the frame have the model's shape.
  DatasetVideo live(d, {});
  EXPECT_THAT(ErrorOf([&] { live.PushFrame(2, 0, 0.0, Image::Ones(8, 8)); }), HasSubstr("slot = 2"));
  EXPECT_THAT(ErrorOf([&] { live.PushFrame(0, 0, 0.0, Image::Ones(4, 8)); }), HasSubstr("frame"));
  write({{"slots", {0, 0, 0, 0, 0}}});
  // Two PSF planes but slot 1 never appears: the video needs every phase.
  const Dataset one = LoadDataset(dir);
  EXPECT_THAT(ErrorOf([&] { DatasetVideo(one, {}); }), HasSubstr("no frame of slot 1"));
  std::filesystem::remove_all(dir);
}

}  // namespace AOSR_TEST_NS
}  // namespace aosr
