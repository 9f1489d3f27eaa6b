// Reproducibility as a promise (issue 14; DESIGN.md §4): every computing command, run twice on the same
// inputs and seed, writes the same output bytes, once with 1 thread and once with 2. Each output file is
// compared byte for byte: a product file carries no wall time, host or thread count.
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <iterator>
#include <nlohmann/json.hpp>
#include <string>

#include "support/testing.hpp"

namespace AOSR_TEST_NS {

namespace fs = std::filesystem;
using aosr::test::CliRun;
using aosr::test::RunCli;

std::string Bytes(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

class ReproducibilityCliTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("aosr_repro_cli_" + std::to_string(getpid()) + "_" +
                                        ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  std::string Path(const std::string& name) const { return (dir_ / name).string(); }

  // Runs `args` (which must contain the placeholder @OUT@ for its output) with --threads 1 into OUT1 and
  // --threads 2 into OUT2, then compares every file the two runs wrote.
  void ExpectSameBytes(const std::string& args, const std::string& out1, const std::string& out2,
                       const std::string& thread_flag = "--threads") {
    auto with = [&](const std::string& out, int threads) {
      std::string a = args;
      a.replace(a.find("@OUT@"), 5, out);
      return a + " " + thread_flag + " " + std::to_string(threads);
    };
    const CliRun r1 = RunCli(with(out1, 1));
    ASSERT_EQ(r1.status, 0) << with(out1, 1) << "\n" << r1.out;
    const CliRun r2 = RunCli(with(out2, 2));
    ASSERT_EQ(r2.status, 0) << with(out2, 2) << "\n" << r2.out;
    std::vector<std::pair<fs::path, fs::path>> files;
    if (fs::is_directory(out1)) {
      for (const auto& e : fs::recursive_directory_iterator(out1))
        if (e.is_regular_file()) files.push_back({e.path(), fs::path(out2) / fs::relative(e.path(), out1)});
    } else {
      files.push_back({out1, out2});
      for (const char* side : {"_std.fits", "_weight.fits"}) {  // companion outputs, where the method writes them
        const std::string stem1 = out1.substr(0, out1.size() - 5), stem2 = out2.substr(0, out2.size() - 5);
        if (fs::exists(stem1 + side)) files.push_back({stem1 + side, stem2 + side});
      }
    }
    ASSERT_FALSE(files.empty()) << args;
    for (const auto& [a, b] : files) {
      ASSERT_TRUE(fs::exists(b)) << b;
      EXPECT_TRUE(Bytes(a) == Bytes(b)) << a << " and " << b << " differ (" << args << ")";
    }
  }

  fs::path dir_;
};

// A small crowded field with photon and read noise, sky, saturation and bad pixels (so every reconstructor
// sees non-uniform inverse-variance weights and masks), analytic AO PSFs, HR 128² (the blocked FFT path).
void WriteScene(const std::string& path) {
  std::ifstream in(std::string(AOSR_SOURCE_DIR) + "/data/scenes/crowded-stars.json");
  nlohmann::json scene = nlohmann::json::parse(in);
  scene["detector"]["frame_px"] = 64;
  scene["objects"][0]["count"] = 60;
  scene["psf"]["window_lambda_over_d"] = 32;
  std::ofstream(path) << scene.dump(2);
}

TEST_F(ReproducibilityCliTest, SimulateAndEveryReconstructorWriteTheSameBytes) {
  WriteScene(Path("scene.json"));
  ExpectSameBytes("simulate " + Path("scene.json") + " -o @OUT@", Path("sim1"), Path("sim2"));
  if (HasFailure()) return;
  for (const std::string m : {"shift-add", "shift-add-median", "drizzle", "tikhonov", "tv", "map"}) {
    SCOPED_TRACE(m);
    std::string extra = m == "tv" || m == "map" ? " --iterations 15" : "";
    if (m == "tikhonov") extra = " --std --noise-sigma 10 --lambda-rule discrepancy";
    ExpectSameBytes("reconstruct " + Path("sim1") + " -m " + m + extra + " -o @OUT@", Path(m + "1.fits"),
                    Path(m + "2.fits"));
  }
}

TEST_F(ReproducibilityCliTest, DesignWritesTheSameBytes) {
  const nlohmann::json scene = {{"name", "repro-design"},
                                {"telescope", "paper-8m"},
                                {"frames", 3},
                                {"r", 2},
                                {"ao", {{"mode", "analytic"}}},
                                {"offsets", {{"type", "raster"}}},
                                {"detector", {{"frame_px", 32}, {"noise", "none"}, {"saturation", false}}},
                                {"objects", nlohmann::json::array({{{"type", "demo"}, {"flux", {{"peak_e", 100.0}}}}})}};
  std::ofstream(Path("scene.json")) << scene.dump(2);
  ExpectSameBytes("design " + Path("scene.json") +
                      " --param zernike --modes 4 --realisations 1 --starts 2 --iterations 3 "
                      "--validation-realisations 1 -o @OUT@",
                  Path("design1.json"), Path("design2.json"));
}

TEST_F(ReproducibilityCliTest, CalibrateWritesTheSameBytes) {
  const nlohmann::json spec = {
      {"telescope", "paper-bench"},
      {"calibration",
       {{"window_px", {24, 24}}, {"modes", {4, 6}}, {"gains", {0.85, 1.2}}, {"amplitudes_nm", {30, 60}},
        {"static_nm", {{"4", 15}}}, {"seed", 3}}}};
  std::ofstream(Path("spec.json")) << spec.dump(2);
  ExpectSameBytes("calibrate --synthesize " + Path("spec.json") + " -o @OUT@", Path("set1"), Path("set2"));
  if (HasFailure()) return;
  ExpectSameBytes("calibrate " + Path("set1") + " -o @OUT@", Path("cal1"), Path("cal2"));
}

}  // namespace
