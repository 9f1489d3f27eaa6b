// End-to-end checks of `aosr tradeoff` through the real executable, on the demo scene simulated at a small
// size.
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <nlohmann/json.hpp>
#include <string>
#include <utility>

#include "support/testing.hpp"

namespace AOSR_TEST_NS {

namespace fs = std::filesystem;
using aosr::test::CliRun;
using aosr::test::RunCli;
using ::testing::HasSubstr;
using ::testing::Not;

// A PNG's (width, height) from its IHDR chunk (bytes 16-23, big-endian), without decoding it in this process:
// the test only needs the size, and decoding is tested in tests/io/plot_test.cpp. (GCC 12's LSan crashed at exit
// on OpenImageIO's dynamic TLS here, in this process and in the aosr it runs; scripts/sanitize.sh's
// intercept_tls_get_addr=0 says why and is what fixes it.)
std::pair<unsigned, unsigned> PngSize(const fs::path& p) {
  std::ifstream f(p, std::ios::binary);
  unsigned char h[24] = {};
  if (!f.read(reinterpret_cast<char*>(h), sizeof h)) return {0, 0};
  if (std::string(reinterpret_cast<char*>(h) + 1, 3) != "PNG" || std::string(reinterpret_cast<char*>(h) + 12, 4) != "IHDR")
    return {0, 0};
  const auto be32 = [&](int o) {
    return (unsigned(h[o]) << 24) | (unsigned(h[o + 1]) << 16) | (unsigned(h[o + 2]) << 8) | unsigned(h[o + 3]);
  };
  return {be32(16), be32(20)};
}

std::string ReadText(const fs::path& p) {
  std::ifstream in(p);
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

// One dataset for the suite: data/scenes/demo.json at 64x64 camera pixels (r = 2, N = 4), plus a copy of its
// manifest without the truth. Every run narrows --methods / --iterations to stay within a few seconds.
class TradeoffCliTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = fs::temp_directory_path() / ("aosr_tradeoff_cli_" + std::to_string(getpid()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    status_ = RunCli("simulate " + std::string(AOSR_SOURCE_DIR) +
                     "/data/scenes/demo.json --set detector.frame_px=64 -o " + Data());
    if (status_.status == 0) {
      nlohmann::json m = nlohmann::json::parse(ReadText(dir_ / "data" / "manifest.json"));
      m.erase("truth");
      std::ofstream(dir_ / "data" / "no_truth.json") << m.dump(2);
    }
  }
  static void TearDownTestSuite() { fs::remove_all(dir_); }
  void SetUp() override { ASSERT_EQ(status_.status, 0) << status_.out; }

  static std::string Data() { return (dir_ / "data").string(); }
  static std::string Out(const std::string& name) { return (dir_ / name).string(); }

  static fs::path dir_;
  static CliRun status_;
};
fs::path TradeoffCliTest::dir_;
CliRun TradeoffCliTest::status_;

constexpr const char* kQuick =
    " --methods shift-add,drizzle,tikhonov,tv --iterations 10,5 --lambda-factors 0.1,10 --threads 1";

TEST_F(TradeoffCliTest, WritesTableJsonAndPictureWithARowPerMethodAndKnob) {
  const CliRun r = RunCli("tradeoff " + Data() + " -o " + Out("with_truth") + kQuick);
  ASSERT_EQ(r.status, 0) << r.out;
  const fs::path out = Out("with_truth");
  ASSERT_TRUE(fs::exists(out / "tradeoff.md"));
  ASSERT_TRUE(fs::exists(out / "tradeoff.json"));
  ASSERT_TRUE(fs::exists(out / "tradeoff.png"));

  const nlohmann::json j = nlohmann::json::parse(ReadText(out / "tradeoff.json"));
  EXPECT_TRUE(j["has_truth"].get<bool>());
  EXPECT_GT(j["metric_crop_px"].get<int>(), 0);  // the trustworthy border, as the bench crops
  // shift-add 1, drizzle 1, tikhonov 3 (x0.1, GCV, x10, in increasing lambda), tv 2 (caps 5, 10, sorted).
  ASSERT_EQ(j["rows"].size(), 7u) << j.dump(2);
  std::map<std::string, int> per_method;
  for (const auto& row : j["rows"]) {
    per_method[row["method"].get<std::string>()]++;
    ASSERT_TRUE(row["psnr_db"].is_number()) << row.dump();
    EXPECT_TRUE(std::isfinite(row["psnr_db"].get<double>())) << row.dump();
    EXPECT_GT(row["ssim"].get<double>(), 0.0) << row.dump();
    EXPECT_GT(row["misfit"].get<double>(), 0.0) << row.dump();
    EXPECT_NE(row["termination"], "failed") << row.dump();
    EXPECT_GE(row["seconds"].get<double>(), 0.0);
  }
  EXPECT_EQ(per_method,
            (std::map<std::string, int>{{"shift-add", 1}, {"drizzle", 1}, {"tikhonov", 3}, {"tv", 2}}));
  const auto& rows = j["rows"];
  EXPECT_DOUBLE_EQ(rows[2]["lambda_factor"].get<double>(), 0.1);
  EXPECT_DOUBLE_EQ(rows[3]["lambda_factor"].get<double>(), 1.0);
  EXPECT_DOUBLE_EQ(rows[4]["lambda_factor"].get<double>(), 10.0);
  EXPECT_NEAR(rows[4]["regularisation"].get<double>(), 10 * rows[3]["regularisation"].get<double>(),
              1e-9 * rows[4]["regularisation"].get<double>());
  EXPECT_EQ(rows[5]["iteration_cap"], 5);
  EXPECT_EQ(rows[6]["iteration_cap"], 10);
  EXPECT_TRUE(rows[2]["change"].is_null());  // first of its sweep
  EXPECT_GT(rows[3]["change"].get<double>(), 0.0);
  EXPECT_GT(rows[6]["change"].get<double>(), 0.0);
  EXPECT_TRUE(rows[0]["objective"].is_null());  // shift-and-add minimises nothing

  const std::string md = ReadText(out / "tradeoff.md");
  EXPECT_THAT(md, HasSubstr("| method | knob | iterations | termination | time [s] | PSNR [dB] | SSIM | aligned PSNR [dB] | "
                            "aligned SSIM | offset [HR px] |"));
  EXPECT_THAT(md, HasSubstr("tradeoff " + Data() + " -o " + Out("with_truth")));  // the command line
  EXPECT_THAT(md, HasSubstr("![accuracy against time](tradeoff.png)"));

  const std::pair<unsigned, unsigned> png = PngSize(out / "tradeoff.png");
  EXPECT_EQ(png.first, 2u * 720u);  // width: two panels, PSNR and SSIM
  EXPECT_EQ(png.second, 460u);
}

TEST_F(TradeoffCliTest, LinearRowsTradeResolutionForNoiseAndAreScoredThroughTheirOwnPsf) {
  const CliRun t = RunCli("tradeoff " + Data() + " -o " + Out("linear") +
                          " --methods linear --target-factors 1.5,0.8 --threads 1 --json");
  ASSERT_EQ(t.status, 0) << t.out;
  const nlohmann::json j = nlohmann::json::parse(t.out);
  ASSERT_EQ(j["rows"].size(), 3u) << j.dump(2);
  const auto& rows = j["rows"];
  // In increasing target width: 0.8, 1 (automatic), 1.5.
  EXPECT_DOUBLE_EQ(rows[1]["target_factor"].get<double>(), 1.0);
  EXPECT_NEAR(rows[0]["target_fwhm_hr_px"].get<double>(), 0.8 * rows[1]["target_fwhm_hr_px"].get<double>(), 1e-9);
  EXPECT_NEAR(rows[2]["target_fwhm_hr_px"].get<double>(), 1.5 * rows[1]["target_fwhm_hr_px"].get<double>(), 1e-9);
  // A wider target: less noise, a wider effective PSF.
  EXPECT_LT(rows[2]["noise_rms"].get<double>(), rows[1]["noise_rms"].get<double>());
  EXPECT_GT(rows[2]["effective_fwhm_hr_px"].get<double>(), rows[1]["effective_fwhm_hr_px"].get<double>());
  for (const auto& row : rows) EXPECT_GE(row["leakage"].get<double>(), 0.0);
  // The automatic row's score is `aosr reconstruct -m linear`'s against the truth through its PSF.
  const CliRun r = RunCli("reconstruct " + Data() + " -m linear -o " + Out("linear/lin.fits") + " --threads 1 --json");
  ASSERT_EQ(r.status, 0) << r.out;
  const nlohmann::json k = nlohmann::json::parse(r.out);
  EXPECT_NEAR(rows[1]["psnr_db"].get<double>(), k["against_truth_through_psf"]["psnr_db"].get<double>(), 1e-9);
  const std::string md = ReadText(fs::path(Out("linear")) / "tradeoff.md");
  EXPECT_THAT(md, HasSubstr("effective FWHM"));
}

TEST_F(TradeoffCliTest, PsnrAgreesWithReconstruct) {
  const CliRun t =
      RunCli("tradeoff " + Data() + " -o " + Out("agree") + " --methods tikhonov --lambda-factors 10 --json");
  ASSERT_EQ(t.status, 0) << t.out;
  const nlohmann::json j = nlohmann::json::parse(t.out);
  const CliRun r = RunCli("reconstruct " + Data() + " -m tikhonov -o " + Out("agree/tik.fits") + " --json");
  ASSERT_EQ(r.status, 0) << r.out;
  const nlohmann::json k = nlohmann::json::parse(r.out);
  ASSERT_EQ(j["rows"].size(), 2u);
  EXPECT_EQ(j["metric_crop_px"], k["against_truth"]["crop_px"]);
  EXPECT_DOUBLE_EQ(j["rows"][0]["psnr_db"].get<double>(), k["against_truth"]["psnr_db"].get<double>());
  EXPECT_DOUBLE_EQ(j["rows"][0]["ssim"].get<double>(), k["against_truth"]["ssim"].get<double>());
  EXPECT_EQ(j["rows"][0]["aligned"]["psnr_db"], k["against_truth"]["aligned"]["psnr_db"]);
  EXPECT_EQ(j["rows"][0]["offset_hr_px"], k["against_truth"]["offset_hr_px"]);
  EXPECT_EQ(j["rows"][0]["offset_mas"], k["against_truth"]["offset_mas"]);
}

TEST_F(TradeoffCliTest, RefusesToOverwriteUnlessForced) {
  const std::string cmd = "tradeoff " + Data() + " -o " + Out("again") + " --methods shift-add --threads 1";
  ASSERT_EQ(RunCli(cmd).status, 0);
  const std::string before = ReadText(fs::path(Out("again")) / "tradeoff.json");
  const CliRun second = RunCli(cmd);
  EXPECT_EQ(second.status, 1) << second.out;
  EXPECT_THAT(second.out, HasSubstr("tradeoff.md: exists; pass --force to overwrite it"));
  EXPECT_EQ(ReadText(fs::path(Out("again")) / "tradeoff.json"), before);
  const CliRun forced = RunCli(cmd + " --force");
  EXPECT_EQ(forced.status, 0) << forced.out;
}

TEST_F(TradeoffCliTest, WritesBesideTheDatasetWithoutTouchingIt) {
  const std::string manifest = ReadText(dir_ / "data" / "manifest.json");
  const auto frames_time = fs::last_write_time(dir_ / "data" / "frames.fits");
  const CliRun r = RunCli("tradeoff " + Data() + " -o " + Data() + " --methods shift-add --threads 1");
  ASSERT_EQ(r.status, 0) << r.out;
  EXPECT_TRUE(fs::exists(dir_ / "data" / "tradeoff.png"));
  EXPECT_EQ(ReadText(dir_ / "data" / "manifest.json"), manifest);
  EXPECT_EQ(fs::last_write_time(dir_ / "data" / "frames.fits"), frames_time);
  for (const char* f : {"tradeoff.md", "tradeoff.json", "tradeoff.png"}) fs::remove(dir_ / "data" / f);
}

TEST_F(TradeoffCliTest, WithoutATruthPlotsTheMisfitAndTheChange) {
  const CliRun r =
      RunCli("tradeoff " + (dir_ / "data" / "no_truth.json").string() + " -o " + Out("no_truth") +
             " --methods shift-add,tikhonov,map --iterations 5,10 --lambda-factors 0.1 --threads 1");
  ASSERT_EQ(r.status, 0) << r.out;
  const fs::path out = Out("no_truth");
  const nlohmann::json j = nlohmann::json::parse(ReadText(out / "tradeoff.json"));
  EXPECT_FALSE(j["has_truth"].get<bool>());
  ASSERT_EQ(j["rows"].size(), 5u) << j.dump(2);
  for (const auto& row : j["rows"]) {
    EXPECT_TRUE(row["psnr_db"].is_null()) << row.dump();
    EXPECT_TRUE(row["ssim"].is_null()) << row.dump();
    EXPECT_GT(row["misfit"].get<double>(), 0.0) << row.dump();
  }
  EXPECT_GT(j["rows"][4]["change"].get<double>(), 0.0);  // map cap 10 against cap 5
  const std::string md = ReadText(out / "tradeoff.md");
  EXPECT_THAT(md, HasSubstr("no truth in the dataset"));
  EXPECT_THAT(md, Not(HasSubstr("PSNR [dB]")));
  EXPECT_THAT(md, HasSubstr("| objective | misfit | change |"));
  EXPECT_EQ(PngSize(out / "tradeoff.png").first, 2u * 720u);
}

TEST_F(TradeoffCliTest, BadInputGetsAClearError) {
  CliRun r = RunCli("tradeoff " + Out("no_such_dataset") + " -o " + Out("bad1"));
  EXPECT_EQ(r.status, 1) << r.out;
  EXPECT_THAT(r.out, HasSubstr("no_such_dataset"));
  EXPECT_FALSE(fs::exists(Out("bad1")));  // nothing created for a dataset that cannot be read

  r = RunCli("tradeoff " + Data() + " -o " + Out("bad2") + " --methods tikhonov,wiener");
  EXPECT_EQ(r.status, 1) << r.out;
  EXPECT_THAT(r.out, HasSubstr("--methods"));
  EXPECT_THAT(r.out, HasSubstr("wiener"));

  r = RunCli("tradeoff " + Data() + " -o " + Out("bad3") + " --lambda-factors 0.1,-2");
  EXPECT_EQ(r.status, 1) << r.out;
  EXPECT_THAT(r.out, HasSubstr("--lambda-factors"));

  r = RunCli("tradeoff " + Data() + " -o " + Out("bad3b") + " --methods linear --target-factors 1");
  EXPECT_EQ(r.status, 1) << r.out;
  EXPECT_THAT(r.out, HasSubstr("--target-factors"));

  r = RunCli("tradeoff " + Data() + " -o " + Out("bad4") + " --iterations 0");
  EXPECT_EQ(r.status, 1) << r.out;
  EXPECT_THAT(r.out, HasSubstr("--iterations"));

  std::ofstream(Out("a_file")) << "x";
  r = RunCli("tradeoff " + Data() + " -o " + Out("a_file"));
  EXPECT_EQ(r.status, 1) << r.out;
  EXPECT_THAT(r.out, HasSubstr("not a directory"));
}

// --progress: every stage of every run on stderr, stdout only the JSON; quiet without it (stderr a file).
TEST_F(TradeoffCliTest, ProgressGoesToStderrOnlyWhenAsked) {
  const fs::path err = dir_ / "stderr.txt";
  const auto run = [&](const std::string& extra) {
    return aosr::test::RunShell(
        "(" + std::string(AOSR_CLI_PATH) + " tradeoff " + Data() + " -o " + Out("progress") +
        " --force --methods tv,map --iterations 4 --threads 1 --json " + extra + " 2> " + err.string() + ")");
  };
  CliRun r = run("--progress");
  ASSERT_EQ(r.status, 0) << r.out << ReadText(err);
  EXPECT_NO_THROW((void)nlohmann::json::parse(r.out)) << r.out;
  const std::string progress = ReadText(err);
  for (const char* line : {"[aosr] pilot 0/1", "[aosr] tv 4/4", "[aosr] map 4/4"})
    EXPECT_THAT(progress, HasSubstr(line)) << progress;
  EXPECT_THAT(r.out, Not(HasSubstr("[aosr]")));

  r = run("");
  ASSERT_EQ(r.status, 0) << r.out;
  EXPECT_EQ(ReadText(err), "");
}

}  // namespace
