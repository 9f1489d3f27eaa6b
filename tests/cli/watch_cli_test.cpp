// End-to-end checks of `aosr watch` through the real executable: a writer thread of this test plays the camera
// (frames at 50 per second, one written in place in two parts), the command stops after --frames files and its
// JSON summary, log and quick-look are checked against the library's streaming engine fed the same frames;
// SIGTERM stops it cleanly with its summary; bad options and folders are refused before anything is written.
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>
#include <thread>
#include <vector>

#include "aosr/io/fits.hpp"
#include "aosr/scene/dataset.hpp"
#include "aosr/solvers/video_stream.hpp"
#include "support/testing.hpp"
#include "support/video_sequence.hpp"

namespace AOSR_TEST_NS {

namespace fs = std::filesystem;
using aosr::Image;
using aosr::test::CliRun;
using aosr::test::RunCli;
using aosr::test::RunShell;
using ::testing::HasSubstr;

class WatchCliTest : public ::testing::Test {
 protected:
  void SetUp() override {
    root_ = fs::temp_directory_path() / ("aosr_watch_cli_" + std::to_string(getpid()));
    fs::remove_all(root_);
    fs::create_directories(root_ / "camera");
    aosr::test::WriteVideoDataset(root_ / "model", {0, 1, 2, 3}, aosr::test::VideoPsfs(), nullptr);
  }
  void TearDown() override { fs::remove_all(root_); }
  std::string P(const std::string& name) const { return (root_ / name).string(); }
  static nlohmann::json Json(const CliRun& r) {
    const std::size_t brace = r.out.find('{');
    return brace == std::string::npos ? nlohmann::json() : nlohmann::json::parse(r.out.substr(brace));
  }
  // Waits until `path` exists (the command made its log: it is watching), up to 30 s.
  static bool WaitFor(const fs::path& path) {
    for (int i = 0; i < 3000 && !fs::exists(path); ++i) std::this_thread::sleep_for(std::chrono::milliseconds(10));
    return fs::exists(path);
  }
  fs::path root_;
};

TEST_F(WatchCliTest, ReconstructsFramesAsTheCameraWritesThem) {
  CliRun run;
  aosr::test::JoiningThread watch([&] {
    run = RunCli("watch " + P("camera") + " --model " + P("model") + " -o " + P("out") +
                 " --lambda 3e-3 --time-key TSEC --frames 10 --idle-timeout 30 --json");
  });
  ASSERT_TRUE(WaitFor(root_ / "out" / "watch.jsonl"));
  for (int j = 0; j < 10; ++j) {
    const std::string path = P("camera/frame" + std::to_string(j) + ".fits");
    if (j == 6)
      aosr::test::WriteLiveFrameInTwoParts(path, P("staging.fits"), j, j % 4, 0.02 * j, 0.03);
    else
      aosr::test::WriteLiveFrame(path, j, j % 4, 0.02 * j);
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  watch.Join();
  ASSERT_EQ(run.status, 0) << run.out;
  const nlohmann::json j = Json(run);
  EXPECT_EQ(j["files"], 10);
  EXPECT_EQ(j["used"], 10);
  EXPECT_EQ(j["outputs"], 7);
  EXPECT_EQ(j["stopped_by"], "frames");
  // Latencies: the first written output apart, then percentiles of the others (none when a slow machine, e.g.
  // under the sanitizers, superseded all but the last).
  EXPECT_GT(j["first_latency_ms"].get<double>(), 0.0);
  if (j["written"].get<int>() > 1) {
    EXPECT_GT(j["latency_ms"]["p50"].get<double>(), 0.0);
  }
  // One log line per file, complete JSON each.
  std::ifstream log(P("out/watch.jsonl"));
  std::vector<nlohmann::json> lines;
  for (std::string line; std::getline(log, line);) lines.push_back(nlohmann::json::parse(line));
  ASSERT_EQ(lines.size(), 10u);
  EXPECT_EQ(lines[3]["output"], 0);
  EXPECT_EQ(lines[9]["output"], 6);
  EXPECT_EQ(lines[9]["written"], 6);  // the last output is always put in place
  EXPECT_GT(lines[9]["latency_ms"].get<double>(), 0.0);
  EXPECT_EQ(j["written"].get<int>() + j["superseded"].get<int>(), 7);
  // The quick-look is the library engine's last output for the same frames.
  const aosr::Dataset model = aosr::LoadDataset(P("model"));
  aosr::VideoOptions vo;
  vo.reconstruct.tikhonov.lambda_rule = aosr::TikhonovLambdaRule::kFixed;
  vo.reconstruct.tikhonov.lambda = 3e-3;
  vo.reconstruct.tikhonov.noise_sigma = 1.0;
  aosr::DatasetVideo ref(model, vo);
  Image last;
  for (int f = 0; f < 10; ++f)
    if (auto o = ref.PushFrame(f % 4, f, 0.02 * f, Image(aosr::test::VideoFrameE(f) / aosr::test::kVideoGain + aosr::test::kVideoBias)))
      last = o->image;
  const aosr::FitsData q = aosr::ReadFits(P("out/quicklook.fits"));
  ASSERT_EQ(q.planes.size(), 1u);
  EXPECT_LT((q.planes[0] - last).abs().maxCoeff(), 1e-6 * last.abs().maxCoeff());
  EXPECT_EQ(q.header.GetString("CTYPE2"), "DEC--TAN");
  EXPECT_TRUE(fs::exists(P("out/quicklook.png")));
}

TEST_F(WatchCliTest, SigtermStopsWithItsSummary) {
  const CliRun r = RunShell(std::string(AOSR_CLI_PATH) + " watch " + P("camera") + " --model " + P("model") + " -o " +
                            P("out") + " --json & p=$!; sleep 1; kill -TERM $p; wait $p");
  ASSERT_EQ(r.status, 0) << r.out;
  EXPECT_EQ(Json(r)["stopped_by"], "signal");
  EXPECT_EQ(Json(r)["files"], 0);
}

TEST_F(WatchCliTest, BadInputIsRefusedBeforeAnythingIsWritten) {
  CliRun r = RunCli("watch " + P("camera") + " --model " + P("model") + " -o " + P("camera"));
  EXPECT_EQ(r.status, 1);
  EXPECT_THAT(r.out, HasSubstr("other than the watched one"));
  r = RunCli("watch " + P("nowhere") + " --model " + P("model") + " -o " + P("out"));
  EXPECT_EQ(r.status, 1);
  EXPECT_THAT(r.out, HasSubstr("nowhere"));
  r = RunCli("watch " + P("camera") + " --model " + P("model") + " -o " + P("out") + " --phase-key 'dm phase'");
  EXPECT_EQ(r.status, 1);
  EXPECT_THAT(r.out, HasSubstr("phase_key"));
  r = RunCli("watch " + P("camera") + " -o " + P("out"));
  EXPECT_EQ(r.status, 1);
  EXPECT_THAT(r.out, HasSubstr("--model"));
  EXPECT_FALSE(fs::exists(P("out")));
  // An earlier quick-look is kept unless --force.
  fs::create_directories(P("out"));
  std::ofstream(P("out/quicklook.fits")) << "earlier";
  r = RunCli("watch " + P("camera") + " --model " + P("model") + " -o " + P("out") + " --idle-timeout 0.1");
  EXPECT_EQ(r.status, 1);
  EXPECT_THAT(r.out, HasSubstr("--force"));
  EXPECT_FALSE(fs::exists(P("out/watch.jsonl")));
  r = RunCli("watch " + P("camera") + " --model " + P("model") + " -o " + P("out") + " --idle-timeout 0.1 --force --json");
  EXPECT_EQ(r.status, 0) << r.out;
  EXPECT_EQ(Json(r)["stopped_by"], "idle");
}

}  // namespace AOSR_TEST_NS
