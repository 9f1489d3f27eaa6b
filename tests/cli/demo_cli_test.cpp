// End-to-end checks of `aosr demo` through the real executable.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <map>
#include <nlohmann/json.hpp>

#include <cmath>
#include <string>
#include <vector>

#include "aosr/io/image_io.hpp"
#include "support/testing.hpp"

namespace AOSR_TEST_NS {

using aosr::Index;
using aosr::test::CliRun;
using aosr::test::RunCli;

// Issue 24: every family of methods is in the demo, each row with its scores, time and iterations.
TEST(DemoCliTest, EveryMethodIsReportedWithItsFields) {
  const CliRun r = RunCli("demo --json");
  ASSERT_EQ(r.status, 0) << r.out;
  const nlohmann::json j = nlohmann::json::parse(r.out);
  std::vector<std::string> names;
  for (const auto& m : j["methods"]) {
    names.push_back(m["method"]);
    for (const char* f : {"label", "psnr_db", "ssim", "rmse", "seconds", "iterations", "termination", "in_montage", "note"})
      EXPECT_TRUE(m.contains(f)) << m["method"] << " lacks " << f;
    EXPECT_TRUE(std::isfinite(m["psnr_db"].get<double>())) << m;
    EXPECT_GE(m["seconds"].get<double>(), 0.0) << m;
  }
  EXPECT_EQ(names, (std::vector<std::string>{"bicubic", "drizzle", "tikhonov", "linear", "tv", "map"})) << r.out;
  for (const char* f : {"scene", "tikhonov", "tv", "linear_against_truth_through_psf", "total_seconds"})
    EXPECT_TRUE(j.contains(f)) << f;
  EXPECT_GT(j["tv"]["mu"].get<double>(), 0.0);
  EXPECT_FALSE(j.contains("montage"));  // nothing written without -o
}

// Issue 33: the resolving power on the demo's USAF target per method, beside PSNR. One frame cannot resolve past
// the camera's Nyquist (0.5 cycles per camera pixel; measured: bicubic and Drizzle 0.43), the multi-frame
// reconstructions can (measured: Tikhonov and TV 0.76, MAP 0.68, linear 0.54), and none past the truth's own
// finest representable element (0.96).
TEST(DemoCliTest, ResolvingPowerOnTheUsafTargetPerMethod) {
  const CliRun r = RunCli("demo --json");
  ASSERT_EQ(r.status, 0) << r.out;
  const nlohmann::json j = nlohmann::json::parse(r.out);
  const double truth = j["usaf_truth"]["cycles_per_camera_px"].get<double>();
  std::map<std::string, double> f;
  for (const auto& m : j["methods"]) {
    ASSERT_TRUE(m["usaf"]["finest_element"].is_string()) << m;
    EXPECT_DOUBLE_EQ(m["usaf"]["threshold"].get<double>(), 0.153);
    f[m["method"]] = m["usaf"]["cycles_per_camera_px"].get<double>();
    EXPECT_LE(f[m["method"]], truth) << m;
    // The demo's camera pixel is lambda/D: both frequencies agree.
    EXPECT_NEAR(m["usaf"]["cycles_per_lambda_over_d"].get<double>(), f[m["method"]], 1e-9) << m;
  }
  EXPECT_LT(f["bicubic"], 0.5);
  EXPECT_LT(f["drizzle"], 0.5);
  for (const char* m : {"tikhonov", "tv", "map", "linear"}) EXPECT_GT(f[m], 0.5) << m;
  const CliRun text = RunCli("demo --no-map");
  ASSERT_EQ(text.status, 0) << text.out;
  EXPECT_THAT(text.out, ::testing::HasSubstr("USAF"));
  EXPECT_THAT(text.out, ::testing::HasSubstr("cyc/cpx"));
}

// The point of the demo: Tikhonov at least 3 dB above the single frame and Drizzle, and TV (the best
// reconstructor) at least 3 dB above Tikhonov (measured: bicubic 17.8, Drizzle 18.3, Tikhonov 25.4, TV 31.2 dB).
TEST(DemoCliTest, TvBeatsTikhonovWhichBeatsTheBaselinesByThreeDecibels) {
  const CliRun r = RunCli("demo --json --no-map");
  ASSERT_EQ(r.status, 0) << r.out;
  const nlohmann::json j = nlohmann::json::parse(r.out);
  std::map<std::string, double> psnr;
  for (const auto& m : j["methods"]) psnr[m["method"]] = m["psnr_db"];
  EXPECT_EQ(psnr.count("map"), 0u) << r.out;  // --no-map
  EXPECT_GE(psnr["tikhonov"], psnr["bicubic"] + 3.0) << r.out;
  EXPECT_GE(psnr["tikhonov"], psnr["drizzle"] + 3.0) << r.out;
  EXPECT_GE(psnr["tv"], psnr["tikhonov"] + 3.0) << r.out;
}

// Issue 16: the linear output with a target PSF has no high-frequency grain. SSIM against the truth above
// Drizzle's and Tikhonov's (whose grain costs it SSIM), and the truth seen through its PSF is reproduced.
TEST(DemoCliTest, LinearOutputIsGrainFreeAndMatchesTheTruthThroughItsPsf) {
  const CliRun r = RunCli("demo --json --no-map");
  ASSERT_EQ(r.status, 0) << r.out;
  const nlohmann::json j = nlohmann::json::parse(r.out);
  std::map<std::string, double> ssim;
  for (const auto& m : j["methods"]) ssim[m["method"]] = m["ssim"];
  ASSERT_TRUE(ssim.count("linear")) << r.out;
  EXPECT_GT(ssim["linear"], ssim["drizzle"]) << r.out;
  EXPECT_GT(ssim["linear"], ssim["tikhonov"] + 0.1) << r.out;
  EXPECT_GT(j["linear_against_truth_through_psf"]["psnr_db"].get<double>(), 35.0) << r.out;
}

// -o writes the FITS files and the labelled montage: one column per panel up to four, a row of whole images
// and a row of zoomed insets per four panels (truth, input frame, 5 methods: 7 panels -> 4 rows), white
// background, the orange inset boxes.
TEST(DemoCliTest, WritesEveryOutputAndALabelledMontage) {
  const auto dir = std::filesystem::temp_directory_path() / ("aosr_demo_cli_" + std::to_string(getpid()));
  const CliRun r = RunCli("demo --lr-size 32 --json -o " + dir.string());
  ASSERT_EQ(r.status, 0) << r.out;
  for (const char* f : {"truth.fits", "frames.fits", "psfs.fits", "bicubic.fits", "drizzle.fits", "tikhonov.fits",
                        "linear.fits", "tv.fits", "map.fits", "montage.png"})
    EXPECT_TRUE(std::filesystem::exists(dir / f)) << f;
  const nlohmann::json j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j["montage"].get<std::string>(), (dir / "montage.png").string());
  const aosr::RgbImage png = aosr::ReadRgbImage((dir / "montage.png").string());
  const int hr = 32 * 2;  // HR side of the panels
  EXPECT_GE(png.cols, 4 * hr);
  EXPECT_GE(png.rows, 4 * hr);
  Index orange = 0, white = 0;
  for (std::size_t k = 0; k + 2 < png.rgb.size(); k += 3) {
    const int red = png.rgb[k], green = png.rgb[k + 1], blue = png.rgb[k + 2];
    orange += red > 200 && green > 90 && green < 160 && blue < 60;
    white += red == 255 && green == 255 && blue == 255;
  }
  EXPECT_GT(orange, 7 * 4 * 20) << "the inset boxes (7 panels, 4 sides)";
  EXPECT_GT(white, png.rows * png.cols / 10) << "the figure's background and title bands";
  std::filesystem::remove_all(dir);
}

TEST(DemoCliTest, BadArgumentsGiveAClearErrorAndNonZeroExit) {
  using ::testing::HasSubstr;
  CliRun r = RunCli("demo --noise -1");
  EXPECT_EQ(r.status, 1);
  EXPECT_THAT(r.out, HasSubstr("--noise"));
  EXPECT_THAT(r.out, HasSubstr(">= 0"));
  r = RunCli("demo -r 12");
  EXPECT_EQ(r.status, 1);
  EXPECT_THAT(r.out, HasSubstr("--factor"));
  r = RunCli("demo -o /dev/null/x");
  EXPECT_EQ(r.status, 1);
  EXPECT_THAT(r.out, HasSubstr("/dev/null"));
  r = RunCli("no-such-command");
  EXPECT_EQ(r.status, 1);
}

}  // namespace
