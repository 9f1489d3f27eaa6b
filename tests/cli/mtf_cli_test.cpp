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


// Several outputs of a noise-free edge dataset on one plot and in one table: the Tikhonov and linear outputs'
// edges against their exact transfer (solvers/linear_transfer.hpp) within issue 33's 0.03 up to the HR Nyquist,
// TV marked signal-dependent, the truth measured only; the table's columns and the plot.
TEST_F(MtfCliTest, SeveralOutputsWithTheExactTransfer) {
  const nlohmann::json scene = {{"name", "edge"},
                                {"telescope", "paper-8m"},
                                {"frames", 4},
                                {"r", 2},
                                {"detector", {{"frame_px", 128}, {"noise", "none"}}},
                                {"objects", nlohmann::json::array({{{"type", "slanted-edge"}, {"angle_deg", 5.0},
                                                                    {"low", 0.1}, {"high", 1.0}}})}};
  std::ofstream(Path("scene.json")) << scene.dump(2);
  ASSERT_EQ(RunCli("simulate " + Path("scene.json") + " -o " + Path("data")).status, 0);
  for (const char* m : {"tikhonov", "linear", "tv"}) {
    const CliRun rec = RunCli("reconstruct " + Path("data") + " -m " + m + " -o " + Path(std::string(m) + ".fits") +
                              (std::string(m) == "tv" ? " --iterations 30" : ""));
    ASSERT_EQ(rec.status, 0) << rec.out;
  }
  const std::string images = Path("data/truth.fits") + " " + Path("tikhonov.fits") + " " + Path("linear.fits") + " " +
                             Path("tv.fits");
  // The region avoids the trustworthy border (16 camera px): the frames were rendered without wrap-around.
  const CliRun r = RunCli("mtf " + images + " --manifest " + Path("data") + " --roi 64,32,128,192 --no-smooth-tails --json -o " +
                          Path("mtf.png") + " --table " + Path("mtf.csv"));
  ASSERT_EQ(r.status, 0) << r.out;
  const nlohmann::json j = nlohmann::json::parse(r.out);
  ASSERT_EQ(j["outputs"].size(), 4u);
  EXPECT_EQ(j["outputs"][0]["label"], "truth");
  EXPECT_EQ(j["outputs"][0]["exact"]["status"], "measured only");
  EXPECT_EQ(j["outputs"][3]["exact"]["status"], "signal-dependent");
  for (int i : {1, 2}) {
    const nlohmann::json& o = j["outputs"][i];
    ASSERT_EQ(o["exact"]["status"], "exact") << o["label"];
    const std::vector<double> f = o["curve"]["frequency"], m = o["curve"]["mtf"], e = o["exact"]["curve"]["mtf"];
    ASSERT_EQ(f.back(), 0.5);  // several images: up to the HR Nyquist
    ASSERT_EQ(e.size(), m.size());
    double worst = 0;
    for (std::size_t k = 0; k < m.size(); ++k) worst = std::max(worst, std::abs(m[k] - e[k]));
    EXPECT_LT(worst, 0.03) << o["label"];
    EXPECT_EQ(o["nyquist"]["r"].get<int>(), 2);
  }
  EXPECT_TRUE(fs::exists(Path("mtf.png")));
  std::ifstream csv(Path("mtf.csv"));
  std::string header;
  std::getline(csv, header);
  EXPECT_EQ(header, "frequency_cycles_per_px,truth edge,tikhonov edge,linear edge,tv edge,tikhonov exact,linear exact");
  int rows = 0;
  for (std::string line; std::getline(csv, line);) ++rows;
  EXPECT_EQ(rows, 51);
  // Without the dataset, Tikhonov's exact curve is unavailable (its model is not in the file); the text says so.
  const CliRun text = RunCli("mtf " + Path("tikhonov.fits") + " " + Path("tv.fits") + " --roi 64,32,128,192");
  ASSERT_EQ(text.status, 0) << text.out;
  EXPECT_THAT(text.out, HasSubstr("tikhonov: MTF50"));
  EXPECT_THAT(text.out, HasSubstr("exact curve unavailable: needs the dataset's model (--manifest)"));
  EXPECT_THAT(text.out, HasSubstr("tv: MTF50"));
  EXPECT_THAT(text.out, HasSubstr("signal-dependent"));
  // One linear output alone: its exact line from the PSF extension.
  const CliRun one = RunCli("mtf " + Path("linear.fits") + " --roi 64,32,128,192 --no-smooth-tails");
  ASSERT_EQ(one.status, 0) << one.out;
  EXPECT_THAT(one.out, HasSubstr("exact transfer (linear): MTF50"));
  // Errors: dataset options without a dataset, the fitted prior, no usable edge in any image.
  const CliRun w = RunCli("mtf " + Path("tikhonov.fits") + " --weights mask");
  EXPECT_EQ(w.status, 1);
  EXPECT_THAT(w.out, HasSubstr("--weights"));
  const CliRun p = RunCli("mtf " + Path("tikhonov.fits") + " --manifest " + Path("data") + " --prior fitted");
  EXPECT_EQ(p.status, 1);
  EXPECT_THAT(p.out, HasSubstr("--prior"));
  Image flat = Image::Constant(64, 64, 1.0);
  aosr::WriteFits(Path("flat.fits"), flat);
  const CliRun none = RunCli("mtf " + Path("flat.fits") + " " + Path("flat.fits"));
  EXPECT_EQ(none.status, 1);
  EXPECT_THAT(none.out, HasSubstr("no image has a usable edge"));
}


// Issue 33: with no region, the edges are found on the bars of a turned USAF chart (data/scenes/usaf-tilted.json,
// 1 % noise); every output is read in the region found on the truth. There the linear output's edge agrees with
// its exact transfer within 0.03 up to the HR Nyquist; the Tikhonov output's ringing reaches past the ~16 px
// between bars, so only its MTF50 is held to its exact one (within 5 %; the curve is 0.07 off near 0.3 cycles/px,
// where the knife-edge scene's wide region above reads it within 0.03). The untilted chart is refused with the
// reason.
TEST_F(MtfCliTest, EdgesFoundOnATurnedChart) {
  const std::string scene = std::string(AOSR_SOURCE_DIR) + "/data/scenes/usaf-tilted.json";
  ASSERT_EQ(RunCli("simulate " + scene + " -o " + Path("data")).status, 0);
  for (const char* m : {"tikhonov", "linear"})
    ASSERT_EQ(RunCli("reconstruct " + Path("data") + " -m " + m + " -o " + Path(std::string(m) + ".fits")).status, 0);
  const CliRun r = RunCli("mtf " + Path("data/truth.fits") + " " + Path("tikhonov.fits") + " " + Path("linear.fits") +
                          " --manifest " + Path("data") + " --no-smooth-tails --json");
  ASSERT_EQ(r.status, 0) << r.out;
  const nlohmann::json j = nlohmann::json::parse(r.out);
  EXPECT_THAT(j["roi_source"].get<std::string>(), HasSubstr("found automatically in " + Path("data/truth.fits")));
  const nlohmann::json roi = j["outputs"][0]["roi"];
  for (int i : {1, 2}) {
    const nlohmann::json& o = j["outputs"][i];
    EXPECT_EQ(o["roi"], roi) << "every output in the same region";
    EXPECT_NEAR(std::abs(o["edge"]["angle_deg"].get<double>()), 5.0, 0.2);
    ASSERT_EQ(o["exact"]["status"], "exact") << o["label"];
    const std::vector<double> f = o["curve"]["frequency"], m = o["curve"]["mtf"], e = o["exact"]["curve"]["mtf"];
    if (o["label"] == "linear") {
      double worst = 0;
      for (std::size_t k = 0; k < m.size(); ++k) worst = std::max(worst, std::abs(m[k] - e[k]));
      EXPECT_LT(worst, 0.03) << o["label"];
    } else {
      double exact50 = 0;  // the exact curve's MTF50, interpolated linearly
      for (std::size_t k = 1; k < e.size() && exact50 == 0; ++k)
        if (e[k] <= 0.5) exact50 = f[k - 1] + (e[k - 1] - 0.5) / (e[k - 1] - e[k]) * (f[k] - f[k - 1]);
      ASSERT_GT(exact50, 0);
      EXPECT_NEAR(o["mtf50_cycles_per_px"].get<double>(), exact50, 0.05 * exact50) << o["label"];
    }
  }
  const CliRun text = RunCli("mtf " + Path("data/truth.fits"));
  ASSERT_EQ(text.status, 0) << text.out;
  EXPECT_THAT(text.out, HasSubstr("found automatically"));
  // The same chart untilted: edges found, along the axes, and the reason given.
  nlohmann::json flat = nlohmann::json::parse(std::ifstream(scene));
  flat["objects"][0].erase("rotation_deg");
  std::ofstream(Path("flat.json")) << flat.dump(2);
  ASSERT_EQ(RunCli("simulate " + Path("flat.json") + " -o " + Path("flat")).status, 0);
  const CliRun refused = RunCli("mtf " + Path("flat/truth.fits"));
  EXPECT_EQ(refused.status, 1);
  EXPECT_THAT(refused.out, HasSubstr("within 1 deg of an axis"));
}

}  // namespace
