// End-to-end checks of `aosr simulate` through the real executable.
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>

#include "support/testing.hpp"

namespace AOSR_TEST_NS {

namespace fs = std::filesystem;
using aosr::test::CliRun;
using aosr::test::RunCli;
using ::testing::AllOf;
using ::testing::HasSubstr;

// A scratch folder holding a small scene file (paper-8m without turbulence, 32-px frames, r = 2, N = 2,
// raster offsets, no noise), removed at the end of the test.
class SimulateCliTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("aosr_simulate_cli_" + std::to_string(getpid()) + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    WriteScene(Scene());
  }
  void TearDown() override { fs::remove_all(dir_); }

  static nlohmann::json Scene() {
    return {{"name", "cli-test"},
            {"telescope", "paper-8m"},
            {"frames", 2},
            {"r", 2},
            {"offsets", {{"type", "raster"}}},
            {"detector", {{"frame_px", 32}, {"noise", "none"}, {"saturation", false}}},
            {"objects", nlohmann::json::array({{{"type", "demo"}, {"flux", {{"peak_e", 100.0}}}}})}};
  }
  void WriteScene(const nlohmann::json& j) const { std::ofstream(ScenePath()) << j.dump(2); }
  std::string ScenePath() const { return (dir_ / "scene.json").string(); }
  std::size_t Entries() const { return std::distance(fs::directory_iterator(dir_), fs::directory_iterator()); }

  fs::path dir_;
};

TEST_F(SimulateCliTest, PlanListsTheStagesAndRunsNothing) {
  CliRun r = RunCli("simulate " + ScenePath() + " --plan");
  ASSERT_EQ(r.status, 0) << r.out;
  for (const char* stage : {"object", "dm-offsets", "psf", "convolution", "pixel-integration", "detector", "total estimate"})
    EXPECT_THAT(r.out, HasSubstr(stage));
  EXPECT_THAT(r.out, ::testing::Not(HasSubstr("ao-loop")));  // not enabled by the scene
  r = RunCli("simulate " + ScenePath() + " --plan --json");
  ASSERT_EQ(r.status, 0) << r.out;
  const nlohmann::json j = nlohmann::json::parse(r.out);
  std::vector<std::string> names;
  for (const auto& s : j["stages"]) names.push_back(s["name"]);
  EXPECT_THAT(names, ::testing::ElementsAre("object", "dm-offsets", "psf", "convolution", "pixel-integration", "detector"));
  EXPECT_EQ(j["hr_shape"], nlohmann::json({64, 64}));
  EXPECT_EQ(Entries(), 1u);  // only the scene: nothing was written
  // --plan computes nothing, so it takes no output folder.
  r = RunCli("simulate " + ScenePath() + " --plan -o " + (dir_ / "out").string());
  EXPECT_NE(r.status, 0);
  EXPECT_THAT(r.out, HasSubstr("--plan"));
  EXPECT_FALSE(fs::exists(dir_ / "out"));
}

TEST_F(SimulateCliTest, OutputFolderGetsTheWholeDataset) {
  const fs::path out = dir_ / "out" / "run1";  // parents are created
  const CliRun r = RunCli("simulate " + ScenePath() + " -o " + out.string());
  ASSERT_EQ(r.status, 0) << r.out;
  EXPECT_THAT(r.out, AllOf(HasSubstr("scene cli-test"), HasSubstr("convolution"), HasSubstr("Strehl"),
                           HasSubstr((out / "manifest.json").string())));
  for (const char* f : {"frames.fits", "valid.fits", "weights.fits", "truth.fits", "psfs.fits", "expected.fits",
                        "manifest.json"})
    EXPECT_TRUE(fs::exists(out / f)) << f;
  std::ifstream in(out / "manifest.json");
  const nlohmann::json m = nlohmann::json::parse(in);
  EXPECT_EQ(m["format"], "aosr-manifest");
  EXPECT_EQ(m["simulation"]["scene"]["json"], Scene());
}

TEST_F(SimulateCliTest, JsonSummaryParses) {
  const CliRun r = RunCli("simulate " + ScenePath() + " --json --set detector.frame_px=40");
  ASSERT_EQ(r.status, 0) << r.out;
  const nlohmann::json j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j["scene"], "cli-test");
  EXPECT_EQ(j["frame_shape"], nlohmann::json({40, 40}));  // --set applied
  EXPECT_EQ(j["strehl"].size(), 2u);
  EXPECT_FALSE(j["timings"].empty());
  EXPECT_TRUE(j["output"].is_null());
  EXPECT_EQ(Entries(), 1u);
}

// The scene field sky_oversampling through --set: the plan and the summary say it, the outputs stay on the HR
// grid, and a bad value is named.
TEST_F(SimulateCliTest, SkyOversamplingIsASceneField) {
  CliRun r = RunCli("simulate " + ScenePath() + " --json --set sky_oversampling=3");
  ASSERT_EQ(r.status, 0) << r.out;
  const nlohmann::json j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j["sky_oversampling"], 3);
  EXPECT_EQ(j["hr_shape"], nlohmann::json({64, 64}));
  r = RunCli("simulate " + ScenePath() + " --plan --set sky_oversampling=3");
  ASSERT_EQ(r.status, 0) << r.out;
  EXPECT_THAT(r.out, AllOf(HasSubstr("sky_oversampling 3"), HasSubstr("192x192")));
  r = RunCli("simulate " + ScenePath() + " --plan --set sky_oversampling=0");
  EXPECT_EQ(r.status, 1);
  EXPECT_THAT(r.out, HasSubstr("sky_oversampling"));
}

TEST_F(SimulateCliTest, BadSceneOrOutputExitsOneNamingTheProblem) {
  nlohmann::json bad = Scene();
  bad["r"] = 0;
  WriteScene(bad);
  CliRun r = RunCli("simulate " + ScenePath() + " -o " + (dir_ / "out").string());
  EXPECT_EQ(r.status, 1) << r.out;
  EXPECT_THAT(r.out, AllOf(HasSubstr("scene.json: r = 0"), HasSubstr("allowed")));
  EXPECT_FALSE(fs::exists(dir_ / "out"));  // the scene is checked before anything is made
  bad = Scene();
  bad["detector"]["nosie"] = "none";
  WriteScene(bad);
  r = RunCli("simulate " + ScenePath());
  EXPECT_EQ(r.status, 1) << r.out;
  EXPECT_THAT(r.out, AllOf(HasSubstr("detector.nosie"), HasSubstr("unknown field")));
  WriteScene(Scene());
  r = RunCli("simulate " + ScenePath() + " --set r=40");
  EXPECT_EQ(r.status, 1) << r.out;
  EXPECT_THAT(r.out, HasSubstr("r = 40"));
  r = RunCli("simulate " + ScenePath() + " --set =3");
  EXPECT_EQ(r.status, 1) << r.out;
  EXPECT_THAT(r.out, HasSubstr("--set"));
  r = RunCli("simulate " + (dir_ / "missing.json").string());
  EXPECT_EQ(r.status, 1) << r.out;
  EXPECT_THAT(r.out, HasSubstr("missing.json"));
  // The output folder is checked before the simulation runs.
  r = RunCli("simulate " + ScenePath() + " -o /dev/null/out");
  EXPECT_EQ(r.status, 1) << r.out;
  EXPECT_THAT(r.out, HasSubstr("/dev/null/out"));
  // Writing the dataset over the scene file itself is refused.
  fs::rename(ScenePath(), dir_ / "manifest.json");
  r = RunCli("simulate " + (dir_ / "manifest.json").string() + " -o " + dir_.string());
  EXPECT_EQ(r.status, 1) << r.out;
  EXPECT_THAT(r.out, HasSubstr("never overwrites an input"));
  EXPECT_EQ(Entries(), 1u);
}

// Memory bounds (core/memory.hpp) through the real executable: a scene that cannot fit is refused with the
// memory it would need, under the machine's limit, an explicit --memory-limit, and `ulimit -v`; a scene that
// fits runs under `ulimit -v` (the budget is what the limit leaves, not the limit itself); and the plan's
// estimate is of the order of what a run really holds.
// `ulimit` needs a shell of its own: the script runs under sh -c.
CliRun RunShell(const std::string& script) { return aosr::test::RunShell("sh -c '" + script + "'"); }

TEST_F(SimulateCliTest, MemoryBoundsRefuseWhatCannotFitAndSayHowMuch) {
  CliRun r = RunCli("simulate " + ScenePath() + " --set frames=1024 --set r=4 --set detector.frame_px=4096");
  EXPECT_EQ(r.status, 1) << r.out;
  EXPECT_THAT(r.out, AllOf(HasSubstr("simulating 1024 frames of 4096x4096 at r = 4"), HasSubstr("TiB of memory"),
                           HasSubstr("more than the limit")));
  r = RunCli("simulate " + ScenePath() + " --memory-limit 1M");
  EXPECT_EQ(r.status, 1) << r.out;
  EXPECT_THAT(r.out, HasSubstr("more than the limit of 1 MiB (set for this run)"));
  r = RunCli("simulate " + ScenePath() + " --memory-limit lots");
  EXPECT_EQ(r.status, 1) << r.out;
  EXPECT_THAT(r.out, HasSubstr("--memory-limit: \"lots\" is not a memory size"));
  EXPECT_EQ(Entries(), 1u);
}

TEST_F(SimulateCliTest, UnderUlimitTheBudgetIsWhatTheLimitLeaves) {
#if defined(AOSR_TEST_ASAN)
  GTEST_SKIP() << "AddressSanitizer reserves terabytes of address space: ulimit -v cannot apply";
#endif
  const std::string cli = AOSR_CLI_PATH;
  // 2 GiB of address space: the small scene runs; a 2048² frame at r = 4 (HR 8192²) would need ~10 GiB.
  CliRun r = RunShell("ulimit -v 2097152 && " + cli + " simulate " + ScenePath() + " --json --threads 2");
  EXPECT_EQ(r.status, 0) << r.out;
  r = RunShell("ulimit -v 2097152 && " + cli + " simulate " + ScenePath() + " --set r=4 --set detector.frame_px=2048");
  EXPECT_EQ(r.status, 1) << r.out;
  EXPECT_THAT(r.out, AllOf(HasSubstr("frames of 2048x2048 at r = 4"), HasSubstr("GiB of memory (estimate)"),
                           HasSubstr("what ulimit -v leaves this process")));
  EXPECT_THAT(r.out, ::testing::Not(HasSubstr("bad_alloc")));
}

TEST_F(SimulateCliTest, ThePeakMemoryEstimateIsOfTheOrderOfTheRun) {
  // The large arrays of a 256² frame at r = 4 (HR 1024²) dominate the process; the baseline (libraries, plans)
  // is measured on the 32² scene and taken off.
  CliRun r = RunCli("simulate " + ScenePath() + " --json --threads 1");
  ASSERT_EQ(r.status, 0) << r.out;
  const double base = nlohmann::json::parse(r.out)["peak_rss_bytes"];
  r = RunCli("simulate " + ScenePath() + " --json --threads 1 --set r=4 --set detector.frame_px=256 --set frames=4");
  ASSERT_EQ(r.status, 0) << r.out;
  const nlohmann::json j = nlohmann::json::parse(r.out);
  const double estimate = j["estimated_peak_bytes"], used = double(j["peak_rss_bytes"]) - base;
  EXPECT_GT(used, 0.0);
  EXPECT_GT(estimate, 0.5 * used) << "estimate " << estimate << " B, measured " << used << " B above the baseline";
  EXPECT_LT(estimate, 4.0 * used) << "estimate " << estimate << " B, measured " << used << " B above the baseline";
}

// --calibration: the simulated DM applies each commanded mode times its calibrated gain, so a raster made of
// Z2/Z3 shifts is applied at g times its size; the manifest records the applied offsets.
TEST_F(SimulateCliTest, CalibrationScalesWhatTheDmApplies) {
  std::ofstream(dir_ / "calibration.json")
      << nlohmann::json({{"format", "aosr-calibration-v1"},
                         {"modes", {{{"mode", 2}, {"gain", 0.5}}, {{"mode", 3}, {"gain", 0.8}}}}})
             .dump();
  const std::string out = (dir_ / "out").string();
  CliRun r = RunCli("simulate " + ScenePath() + " -o " + out + " --calibration " + (dir_ / "calibration.json").string());
  ASSERT_EQ(r.status, 0) << r.out;
  const nlohmann::json m = nlohmann::json::parse(std::ifstream(dir_ / "out" / "manifest.json"));
  const std::string plain = (dir_ / "plain").string();
  r = RunCli("simulate " + ScenePath() + " -o " + plain);
  ASSERT_EQ(r.status, 0) << r.out;
  const nlohmann::json p = nlohmann::json::parse(std::ifstream(dir_ / "plain" / "manifest.json"));
  ASSERT_EQ(m["offsets"].size(), 2u);
  for (int i = 0; i < 2; ++i) {
    const double py = p["offsets"][i]["shift_px"][0], px = p["offsets"][i]["shift_px"][1];
    EXPECT_NEAR(m["offsets"][i]["shift_px"][0].get<double>(), 0.8 * py, 1e-12);  // y shift: Z3
    EXPECT_NEAR(m["offsets"][i]["shift_px"][1].get<double>(), 0.5 * px, 1e-12);  // x shift: Z2
  }
  r = RunCli("simulate " + ScenePath() + " --calibration " + (dir_ / "nope.json").string());
  EXPECT_EQ(r.status, 1) << r.out;  // CLI11's own validation error, with the documented usage-error code
  EXPECT_THAT(r.out, HasSubstr("nope.json"));
}

}  // namespace
