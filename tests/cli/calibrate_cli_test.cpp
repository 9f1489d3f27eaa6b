// End-to-end checks of `aosr calibrate` through the real executable: synthesize a small set, calibrate it,
// read calibration.json; bad input names the problem.
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>

#include "support/testing.hpp"

namespace AOSR_TEST_NS {

namespace fs = std::filesystem;
using aosr::test::CliRun;
using aosr::test::RunCli;
using ::testing::HasSubstr;

class CalibrateCliTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("aosr_calibrate_cli_" + std::to_string(getpid()) + "_" +
                                        ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    const nlohmann::json spec = {
        {"telescope", "paper-bench"},
        {"calibration",
         {{"window_px", {24, 24}}, {"modes", {4, 6}}, {"gains", {0.85, 1.2}}, {"amplitudes_nm", {30, 60, 90}},
          {"static_nm", {{"4", 15}, {"5", -10}}}, {"seed", 3}}}};
    std::ofstream(Path("spec.json")) << spec.dump(2);
  }
  void TearDown() override { fs::remove_all(dir_); }
  std::string Path(const std::string& name) const { return (dir_ / name).string(); }
  fs::path dir_;
};

TEST_F(CalibrateCliTest, SynthesizeThenCalibrateRecoversTheGains) {
  CliRun r = RunCli("calibrate --synthesize " + Path("spec.json") + " -o " + Path("set") + " --nonlinear-above 60");
  ASSERT_EQ(r.status, 0) << r.out;
  EXPECT_THAT(r.out, HasSubstr("14 frames"));  // 2 modes x (1 reference + 3 levels x 2 signs)
  ASSERT_TRUE(fs::exists(Path("set/calibration-set.json")));
  r = RunCli("calibrate " + Path("set") + " -o " + Path("out") + " --json --threads 2");
  ASSERT_EQ(r.status, 0) << r.out;
  const nlohmann::json j = nlohmann::json::parse(r.out);
  ASSERT_EQ(j["modes"].size(), 2u);
  for (const auto& m : j["modes"]) {
    const double truth = m["truth_gain"].get<double>();
    EXPECT_LT(std::abs(m["gain"].get<double>() - truth), 3 * m["gain_sigma"].get<double>()) << m.dump(2);
    EXPECT_EQ(m["verdict"], "saturates") << m.dump(2);
    EXPECT_NEAR(m["onset_nm"].get<double>(), 90.0, 1e-6);
  }
  const nlohmann::json file = nlohmann::json::parse(std::ifstream(Path("out/calibration.json")));
  EXPECT_EQ(file["format"], "aosr-calibration-v1");
  EXPECT_TRUE(fs::exists(Path("out/report.png")));
  EXPECT_GT(fs::file_size(Path("out/report.png")), 1000u);
  // Text output.
  r = RunCli("calibrate " + Path("set") + " -o " + Path("out2") + " --static-max-noll 0 --point-source");
  ASSERT_EQ(r.status, 0) << r.out;
  EXPECT_THAT(r.out, HasSubstr("Z6"));
  EXPECT_THAT(r.out, HasSubstr("saturates"));
}

TEST_F(CalibrateCliTest, BadInputNamesTheProblem) {
  CliRun r = RunCli("calibrate " + Path("nowhere") + " -o " + Path("out"));
  EXPECT_EQ(r.status, 1) << r.out;
  EXPECT_THAT(r.out, HasSubstr("nowhere"));
  r = RunCli("calibrate -o " + Path("out"));
  EXPECT_EQ(r.status, 1) << r.out;
  EXPECT_THAT(r.out, HasSubstr("SET"));
  r = RunCli("calibrate --synthesize no-such-preset -o " + Path("set"));
  EXPECT_EQ(r.status, 1) << r.out;
  EXPECT_THAT(r.out, HasSubstr("no-such-preset"));
  r = RunCli("calibrate --synthesize " + Path("spec.json") + " -o " + Path("set") + " --gains 1,2,3");
  EXPECT_EQ(r.status, 1) << r.out;
  EXPECT_THAT(r.out, HasSubstr("gains"));
  ASSERT_EQ(RunCli("calibrate --synthesize " + Path("spec.json") + " -o " + Path("set")).status, 0);
  r = RunCli("calibrate " + Path("set") + " -o " + Path("out") + " --seed 3");
  EXPECT_EQ(r.status, 1) << r.out;
  EXPECT_THAT(r.out, HasSubstr("only with --synthesize"));
  // Writing the outputs into the set folder is fine (different names); a frame of another size is not.
  std::ofstream(Path("set/calibration-set.json.bak")) << "";
  nlohmann::json m = nlohmann::json::parse(std::ifstream(Path("set/calibration-set.json")));
  m["frames"][0]["file"] = "../spec.json";
  std::ofstream(Path("set/calibration-set.json")) << m.dump();
  r = RunCli("calibrate " + Path("set") + " -o " + Path("out"));
  EXPECT_EQ(r.status, 1) << r.out;
  EXPECT_THAT(r.out, HasSubstr("spec.json"));
}

}  // namespace
