// `aosr mtf` through the real executable: the slanted-edge MTF of a FITS image (core/slanted_edge.hpp), its JSON,
// the plot, a refusal, and an edge from a scene's slanted-edge object through `aosr simulate`.
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>

#include "aosr/io/fits.hpp"
#include "core/slanted_edge_fixture.hpp"
#include "support/testing.hpp"

namespace AOSR_TEST_NS {

namespace fs = std::filesystem;
using aosr::Image;
using aosr::test::CliRun;
using aosr::test::RunCli;
using ::testing::HasSubstr;

class MtfCliTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("aosr_mtf_cli_" + std::to_string(getpid()) + "_" +
                                        ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  std::string Path(const std::string& name) const { return (dir_ / name).string(); }
  fs::path dir_;
};

// A Gaussian edge (σ = 1 px) inside a larger image: MTF50 = sqrt(ln 2 / (2π²)) / σ = 0.1874 cycles/px within 1 %,
// the Nyquist of r = 2 and the cut-off of a 0.4 λ/D pixel reported, and the PNG written.
TEST_F(MtfCliTest, GaussianEdgeInARegion) {
  Image img = Image::Zero(140, 120);
  img.block(10, 20, 120, 60) = aosr::test::GaussianEdge({120, 60}, 5.0, 1.0);
  aosr::WriteFits(Path("edge.fits"), img);
  const CliRun r = RunCli("mtf " + Path("edge.fits") + " --roi 20,10,60,120 --r 2 --pixel-lod 0.4 --freq 0.1,0.3 --json -o " +
                          Path("curve.png"));
  ASSERT_EQ(r.status, 0) << r.out;
  const nlohmann::json j = nlohmann::json::parse(r.out);
  const double f50 = std::sqrt(std::log(2.0) / (2 * M_PI * M_PI));
  EXPECT_NEAR(j["mtf50_cycles_per_px"].get<double>(), f50, 0.01 * f50);
  EXPECT_DOUBLE_EQ(j["nyquist"]["frequency"].get<double>(), 0.25);
  EXPECT_NEAR(j["nyquist"]["mtf"].get<double>(), aosr::test::GaussianMtf(1.0, 0.25), 0.02);
  EXPECT_DOUBLE_EQ(j["cutoff"]["frequency"].get<double>(), 0.4);
  ASSERT_EQ(j["at"].size(), 2u);
  EXPECT_NEAR(j["at"][0]["mtf"].get<double>(), aosr::test::GaussianMtf(1.0, 0.1), 0.02);
  EXPECT_EQ(j["edge"]["orientation"], "vertical");
  EXPECT_NEAR(j["edge"]["angle_deg"].get<double>(), 5.0, 0.05);
  EXPECT_EQ(j["curve"]["frequency"].size(), j["curve"]["mtf"].size());
  EXPECT_TRUE(fs::exists(Path("curve.png")));
  const CliRun text = RunCli("mtf " + Path("edge.fits") + " --roi 20,10,60,120");
  ASSERT_EQ(text.status, 0) << text.out;
  EXPECT_THAT(text.out, HasSubstr("MTF50 0.18"));
}

TEST_F(MtfCliTest, RefusalsSayWhy) {
  Image img = aosr::test::GaussianEdge({100, 50}, 5.0, 1.5);
  aosr::WriteFits(Path("clipped.fits"), Image(img.min(0.7)));
  const CliRun r = RunCli("mtf " + Path("clipped.fits"));
  EXPECT_EQ(r.status, 1) << r.out;
  EXPECT_THAT(r.out, HasSubstr("clipped (saturated)"));
  EXPECT_THAT(r.out, ::testing::Not(HasSubstr("MTF50")));
  aosr::WriteFits(Path("edge.fits"), img);
  const CliRun roi = RunCli("mtf " + Path("edge.fits") + " --roi 40,0,60,100");
  EXPECT_EQ(roi.status, 1) << roi.out;
  EXPECT_THAT(roi.out, HasSubstr("roi"));
  const CliRun count = RunCli("mtf " + Path("edge.fits") + " --roi 1,2,3");
  EXPECT_EQ(count.status, 1) << count.out;
}

// The scene's slanted-edge object, simulated without noise: the truth is the pixel box's edge (MTF
// sinc(f cos θ) sinc(f sin θ), MTF50 0.605 cycles/px at 5°), and `aosr mtf` reads r from the file's SRFACTOR.
TEST_F(MtfCliTest, SceneSlantedEdgeThroughSimulate) {
  const nlohmann::json scene = {{"name", "edge"},
                                {"telescope", "paper-8m"},
                                {"frames", 1},
                                {"r", 2},
                                {"detector", {{"frame_px", 48}, {"noise", "none"}}},
                                {"objects", nlohmann::json::array({{{"type", "slanted-edge"}, {"angle_deg", 5.0}}})}};
  std::ofstream(Path("scene.json")) << scene.dump(2);
  const CliRun sim = RunCli("simulate " + Path("scene.json") + " -o " + Path("data"));
  ASSERT_EQ(sim.status, 0) << sim.out;
  const CliRun r = RunCli("mtf " + Path("data/truth.fits") + " --json");
  ASSERT_EQ(r.status, 0) << r.out;
  const nlohmann::json j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j["nyquist"]["r"].get<int>(), 2);
  EXPECT_NEAR(j["mtf50_cycles_per_px"].get<double>(), 0.605, 0.006);
}

}  // namespace
