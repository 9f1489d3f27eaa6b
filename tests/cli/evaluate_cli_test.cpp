// End-to-end checks of `aosr evaluate` through the real executable: metrics against hand-computed values.
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>

#include "aosr/core/metrics.hpp"
#include "aosr/io/fits.hpp"
#include "support/testing.hpp"

namespace {

namespace fs = std::filesystem;
using aosr::Image;
using aosr::test::CliRun;
using aosr::test::RunCli;
using ::testing::HasSubstr;

class EvaluateCliTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("aosr_evaluate_cli_" + std::to_string(getpid()) + "_" +
                                        ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  std::string Path(const std::string& name) const { return (dir_ / name).string(); }
  fs::path dir_;
};

// estimate = truth + c everywhere: RMSE = c and PSNR = 20 log10(L / c) with L = max − min of the truth.
TEST_F(EvaluateCliTest, ConstantOffsetGivesTheExactRmseAndPsnr) {
  Image truth(32, 40);
  for (int y = 0; y < 32; ++y)
    for (int x = 0; x < 40; ++x) truth(y, x) = std::sin(0.3 * y) * std::cos(0.2 * x) * 50 + 60;
  const double c = 0.5;
  aosr::WriteFits(Path("truth.fits"), truth);
  aosr::WriteFits(Path("estimate.fits"), Image(truth + c));
  const CliRun r = RunCli("evaluate --truth " + Path("truth.fits") + " --estimate " + Path("estimate.fits") + " --json");
  ASSERT_EQ(r.status, 0) << r.out;
  const nlohmann::json j = nlohmann::json::parse(r.out);
  // Files hold floats: the offset survives to ~1e-5 relative.
  EXPECT_NEAR(j["rmse"].get<double>(), c, 1e-5);
  const double range = truth.maxCoeff() - truth.minCoeff();
  EXPECT_NEAR(j["psnr_db"].get<double>(), 20 * std::log10(range / c), 1e-3);
  EXPECT_GT(j["ssim"].get<double>(), 0.99);
  EXPECT_EQ(j["crop_px"].get<int>(), 0);
  const CliRun text = RunCli("evaluate --truth " + Path("truth.fits") + " --estimate " + Path("estimate.fits") + " --crop 4");
  ASSERT_EQ(text.status, 0) << text.out;
  EXPECT_THAT(text.out, HasSubstr("PSNR"));
  EXPECT_THAT(text.out, HasSubstr("crop 4 px"));
}

// A linear-method output keeps the frames' sky: with --subtract-sky auto (the default) an estimate whose METHOD is
// linear is scored after removing its median level above the truth's (truth + c scores as the truth: RMSE ~ 0,
// sky_subtracted = c); without the keyword, or with --subtract-sky no, the sky counts (RMSE = c); yes forces it.
TEST_F(EvaluateCliTest, SubtractSkyRemovesTheLinearOutputsSkyLevel) {
  Image truth(32, 40);
  for (int y = 0; y < 32; ++y)
    for (int x = 0; x < 40; ++x) truth(y, x) = std::sin(0.3 * y) * std::cos(0.2 * x) * 50 + 60;
  const double c = 7.25;
  aosr::FitsHeader linear;
  linear.Set("METHOD", std::string("linear"), "reconstruction method");
  aosr::WriteFits(Path("truth.fits"), truth);
  aosr::WriteFits(Path("linear.fits"), Image(truth + c), linear);
  aosr::WriteFits(Path("plain.fits"), Image(truth + c));
  auto run = [&](const std::string& estimate, const std::string& extra) {
    const CliRun r = RunCli("evaluate --truth " + Path("truth.fits") + " --estimate " + Path(estimate) + " --json " + extra);
    EXPECT_EQ(r.status, 0) << r.out;
    return nlohmann::json::parse(r.out);
  };
  const nlohmann::json a = run("linear.fits", "");
  EXPECT_NEAR(a["sky_subtracted"].get<double>(), c, 1e-5);
  EXPECT_LT(a["rmse"].get<double>(), 1e-5);
  const nlohmann::json n = run("linear.fits", "--subtract-sky no");
  EXPECT_FALSE(n.contains("sky_subtracted"));
  EXPECT_NEAR(n["rmse"].get<double>(), c, 1e-5);
  const nlohmann::json p = run("plain.fits", "");
  EXPECT_FALSE(p.contains("sky_subtracted"));
  EXPECT_NEAR(p["rmse"].get<double>(), c, 1e-5);
  const nlohmann::json y = run("plain.fits", "--subtract-sky yes");
  EXPECT_NEAR(y["sky_subtracted"].get<double>(), c, 1e-5);
  const CliRun bad = RunCli("evaluate --truth " + Path("truth.fits") + " --estimate " + Path("plain.fits") + " --subtract-sky maybe");
  EXPECT_NE(bad.status, 0);
  EXPECT_THAT(bad.out, HasSubstr("--subtract-sky"));
}

// An estimate moved by a known sub-pixel offset: --json reports the offset (HR px; mas from the truth's PIXSCALE)
// and the aligned scores; an unmoved estimate has offset 0 and aligned = raw.
TEST_F(EvaluateCliTest, ReportsTheOffsetAndTheAlignedScores) {
  // Three Gaussian blobs (sigma 3 px: band-limited to e^-44 at Nyquist, ~0 at the edges, so periodic).
  Image truth(48, 48);
  const double blobs[3][3] = {{15, 20, 100}, {30, 12, 60}, {26, 33, 80}};  // y, x, height
  for (int y = 0; y < 48; ++y)
    for (int x = 0; x < 48; ++x) {
      truth(y, x) = 10;
      for (const auto& b : blobs) truth(y, x) += b[2] * std::exp(-((y - b[0]) * (y - b[0]) + (x - b[1]) * (x - b[1])) / 18.0);
    }
  aosr::FitsHeader h;
  h.Set("PIXSCALE", 13.75, "[mas] HR pixel pitch");
  aosr::WriteFits(Path("truth.fits"), truth, h, aosr::FitsType::kFloat64);
  aosr::WriteFits(Path("moved.fits"), aosr::FourierShiftImage(truth, 0.3, -0.45), {}, aosr::FitsType::kFloat64);
  CliRun r = RunCli("evaluate --truth " + Path("truth.fits") + " --estimate " + Path("moved.fits") + " --json");
  ASSERT_EQ(r.status, 0) << r.out;
  nlohmann::json j = nlohmann::json::parse(r.out);
  EXPECT_NEAR(j["offset_hr_px"]["dy"].get<double>(), 0.3, 0.01);
  EXPECT_NEAR(j["offset_hr_px"]["dx"].get<double>(), -0.45, 0.01);
  EXPECT_NEAR(j["offset_mas"]["dy"].get<double>(), 0.3 * 13.75, 0.01 * 13.75);
  EXPECT_NEAR(j["offset_mas"]["dx"].get<double>(), -0.45 * 13.75, 0.01 * 13.75);
  EXPECT_GT(j["aligned"]["psnr_db"].get<double>(), 50.0);
  EXPECT_LT(j["psnr_db"].get<double>(), 40.0);  // measured 34.0
  EXPECT_GT(j["aligned"]["ssim"].get<double>(), j["ssim"].get<double>());
  const CliRun text = RunCli("evaluate --truth " + Path("truth.fits") + " --estimate " + Path("moved.fits"));
  ASSERT_EQ(text.status, 0) << text.out;
  EXPECT_THAT(text.out, HasSubstr("aligned (offset dy, dx = +0.300, -0.450 HR px = +4.1"));
  EXPECT_THAT(text.out, HasSubstr(" mas): PSNR "));
  // Unmoved, and a truth without PIXSCALE: offset 0, no mas.
  aosr::WriteFits(Path("plain.fits"), truth, {}, aosr::FitsType::kFloat64);
  r = RunCli("evaluate --truth " + Path("plain.fits") + " --estimate " + Path("plain.fits") + " --json");
  ASSERT_EQ(r.status, 0) << r.out;
  j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j["offset_hr_px"]["dy"].get<double>(), 0.0);
  EXPECT_EQ(j["offset_hr_px"]["dx"].get<double>(), 0.0);
  EXPECT_TRUE(j["offset_mas"].is_null());
  EXPECT_TRUE(j["aligned"]["psnr_db"].is_null() || j["aligned"]["psnr_db"] == j["psnr_db"]);
}

// A simulated star field: evaluating the truth against itself gives zero photometric and astrometric error.
TEST_F(EvaluateCliTest, StarFieldTruthAgainstItselfHasNoStarErrors) {
  const nlohmann::json scene = {
      {"name", "evaluate-stars"},
      {"telescope", "paper-8m"},
      {"frames", 2},
      {"r", 2},
      {"offsets", {{"type", "raster"}}},
      {"detector", {{"frame_px", 64}, {"noise", "none"}, {"saturation", false}}},
      {"objects", nlohmann::json::array({{{"type", "stars"}, {"count", 12}, {"margin_px", 4},
                                          {"flux_range_e", {1e3, 1e5}}}})}};
  std::ofstream(Path("scene.json")) << scene.dump(2);
  CliRun r = RunCli("simulate " + Path("scene.json") + " -o " + Path("out"));
  ASSERT_EQ(r.status, 0) << r.out;
  const nlohmann::json manifest = nlohmann::json::parse(std::ifstream(Path("out/manifest.json")));
  ASSERT_TRUE(manifest.contains("truth")) << manifest.dump(2);
  const std::string truth = Path("out/" + manifest["truth"].get<std::string>());
  r = RunCli("evaluate --manifest " + Path("out") + " --estimate " + truth + " --stars 5 --json");
  ASSERT_EQ(r.status, 0) << r.out;
  const nlohmann::json j = nlohmann::json::parse(r.out);
  ASSERT_TRUE(j.contains("stars")) << r.out;
  EXPECT_GT(j["stars"]["measured"].get<int>(), 0);
  EXPECT_LT(j["stars"]["median_abs_flux_error"].get<double>(), 1e-6);
  EXPECT_LT(j["stars"]["rms_position_error_hr_px"].get<double>(), 1e-6);
  EXPECT_EQ(j["crop_px"].get<int>(), manifest["trustworthy_border_px"].get<int>() * 2);  // camera px × r
}

TEST_F(EvaluateCliTest, BadInputNamesTheProblem) {
  Image a = Image::Zero(8, 8), b = Image::Zero(8, 10);
  a(2, 3) = 1;
  aosr::WriteFits(Path("a.fits"), a);
  aosr::WriteFits(Path("b.fits"), b);
  CliRun r = RunCli("evaluate --truth " + Path("a.fits") + " --estimate " + Path("b.fits"));
  EXPECT_EQ(r.status, 1);
  EXPECT_THAT(r.out, HasSubstr("--estimate"));
  EXPECT_THAT(r.out, HasSubstr("shape"));
  r = RunCli("evaluate --estimate " + Path("b.fits"));
  EXPECT_EQ(r.status, 1);
  EXPECT_THAT(r.out, HasSubstr("--truth/--manifest"));
  r = RunCli("evaluate --truth " + Path("missing.fits") + " --estimate " + Path("a.fits"));
  EXPECT_EQ(r.status, 1);
  EXPECT_THAT(r.out, HasSubstr("missing.fits"));
  r = RunCli("evaluate --truth " + Path("a.fits") + " --estimate " + Path("a.fits") + " --crop 4");
  EXPECT_EQ(r.status, 1);
  EXPECT_THAT(r.out, HasSubstr("--crop"));
}

// --usaf: the resolving power on the scene's USAF target (scene/usaf_contrast.hpp). The noise-free truth resolves
// its representable elements with transfer 1; a flat image resolves none. No --truth is needed.
TEST_F(EvaluateCliTest, UsafResolvingPowerOfTheTruth) {
  const nlohmann::json scene = {{"name", "usaf"},
                                {"telescope", "paper-8m"},
                                {"frames", 1},
                                {"r", 2},
                                {"detector", {{"frame_px", 64}, {"noise", "none"}}},
                                {"objects", nlohmann::json::array({{{"type", "usaf"}}})}};
  std::ofstream(Path("scene.json")) << scene.dump(2);
  const CliRun sim = RunCli("simulate " + Path("scene.json") + " -o " + Path("data"));
  ASSERT_EQ(sim.status, 0) << sim.out;
  const CliRun r = RunCli("evaluate --estimate " + Path("data/truth.fits") + " --usaf " + Path("scene.json") + " --json");
  ASSERT_EQ(r.status, 0) << r.out;
  const nlohmann::json j = nlohmann::json::parse(r.out);
  ASSERT_FALSE(j["usaf"]["finest"].is_null()) << r.out;
  EXPECT_GT(j["usaf"]["elements"].size(), 10u);
  for (const auto& e : j["usaf"]["elements"])  // bars of 1 px or more: the truth's own contrast is well above 0
    if (e["bar_width_hr_px"].get<double>() >= 1.0) {
      EXPECT_NEAR(e["transfer"].get<double>(), 1.0, 1e-6);
    }
  EXPECT_DOUBLE_EQ(j["usaf"]["finest"]["cycles_per_camera_px"].get<double>(),
                   2 * j["usaf"]["finest"]["cycles_per_hr_px"].get<double>());
  aosr::WriteFits(Path("flat.fits"), Image::Constant(128, 128, 1.0));
  const CliRun flat = RunCli("evaluate --estimate " + Path("flat.fits") + " --usaf " + Path("scene.json"));
  ASSERT_EQ(flat.status, 0) << flat.out;
  EXPECT_THAT(flat.out, HasSubstr("finest resolved element: none"));
  const CliRun wrong = RunCli("evaluate --estimate " + Path("flat.fits") + " --usaf " + Path("data/manifest.json"));
  EXPECT_EQ(wrong.status, 1) << wrong.out;
}

}  // namespace
