// End-to-end checks of `aosr reconstruct` through the real executable, on a small simulated dataset.
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <nlohmann/json.hpp>
#include <string>

#include "aosr/io/fits.hpp"
#include "support/testing.hpp"

namespace AOSR_TEST_NS {

namespace fs = std::filesystem;
using aosr::test::CliRun;
using aosr::test::RunCli;
using ::testing::HasSubstr;
using ::testing::Not;

// One dataset for the whole suite: paper-8m without turbulence, 48-px frames, r = 2, N = 4 raster, 1% noise.
class ReconstructCliTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = fs::temp_directory_path() / ("aosr_reconstruct_cli_" + std::to_string(getpid()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    const nlohmann::json scene = {
        {"name", "reconstruct-cli"},
        {"telescope", "paper-8m"},
        {"frames", 4},
        {"r", 2},
        {"offsets", {{"type", "raster"}}},
        {"detector", {{"frame_px", 48}, {"noise", "peak-fraction"}, {"peak_noise_fraction", 0.01}, {"saturation", false}}},
        {"objects", nlohmann::json::array({{{"type", "usaf"}, {"flux", {{"peak_e", 1000.0}}}}})}};
    std::ofstream(dir_ / "scene.json") << scene.dump(2);
    status_ = RunCli("simulate " + (dir_ / "scene.json").string() + " -o " + (dir_ / "data").string());
  }
  static void TearDownTestSuite() { fs::remove_all(dir_); }
  void SetUp() override { ASSERT_EQ(status_.status, 0) << status_.out; }

  static nlohmann::json Run(const std::string& method, const std::string& extra = "") {
    const CliRun r = RunCli("reconstruct " + Data() + " -m " + method + " -o " + Out(method) + " --json " + extra);
    EXPECT_EQ(r.status, 0) << r.out;
    return r.status == 0 ? nlohmann::json::parse(r.out) : nlohmann::json();
  }
  static std::string Data() { return (dir_ / "data").string(); }
  static std::string Out(const std::string& m) { return (dir_ / (m + ".fits")).string(); }

  static fs::path dir_;
  static CliRun status_;
};
fs::path ReconstructCliTest::dir_;
CliRun ReconstructCliTest::status_;

TEST_F(ReconstructCliTest, EveryMethodWritesAnImageAndATruthfulSummary) {
  double psnr[4];
  int k = 0;
  for (const char* m : {"shift-add", "drizzle", "tikhonov", "tv"}) {
    const nlohmann::json j = Run(m);
    ASSERT_TRUE(j.contains("summary")) << m;
    EXPECT_EQ(j["method"], m);
    EXPECT_NE(j["summary"]["termination"], "failed") << j.dump(2);
    EXPECT_EQ(j["summary"]["frame_residual_rms"].size(), 4u) << m;
    const aosr::Image x = aosr::ReadFitsImage(Out(m));
    EXPECT_EQ(x.rows(), 96);
    EXPECT_TRUE(aosr::AllFinite(x));
    ASSERT_TRUE(j.contains("against_truth")) << j.dump(2);
    psnr[k++] = j["against_truth"]["psnr_db"].get<double>();
    // Beside the raw scores: the aligned ones and the offset, in HR px and mas (the dataset knows its scale).
    const nlohmann::json& t = j["against_truth"];
    ASSERT_TRUE(t.contains("aligned")) << t.dump(2);
    // Never below the raw ones: the offset is measured on the scored crop and applied only when it helps.
    EXPECT_GE(t["aligned"]["psnr_db"].get<double>(), t["psnr_db"].get<double>()) << m;
    EXPECT_GE(t["aligned"]["ssim"].get<double>(), t["ssim"].get<double>()) << m;
    EXPECT_LT(std::abs(t["offset_hr_px"]["dx"].get<double>()), 1.0) << m;
    ASSERT_TRUE(t["offset_mas"].is_object()) << t.dump(2);
    // One scale for both axes: mas_x hr_y = mas_y hr_x.
    EXPECT_NEAR(t["offset_mas"]["dx"].get<double>() * t["offset_hr_px"]["dy"].get<double>(),
                t["offset_mas"]["dy"].get<double>() * t["offset_hr_px"]["dx"].get<double>(), 1e-9) << m;
    // mas > HR px where an offset was applied (an HR pixel is more than a mas); none applied: both exactly 0.
    if (t["offset_applied"].get<bool>())
      EXPECT_GT(std::abs(t["offset_mas"]["dx"].get<double>()), std::abs(t["offset_hr_px"]["dx"].get<double>())) << m;
    else
      EXPECT_EQ(t["offset_mas"]["dx"].get<double>(), 0.0) << m;
  }
  EXPECT_TRUE(fs::exists(dir_ / "drizzle_weight.fits"));
  EXPECT_GT(psnr[2], psnr[1]);  // Tikhonov beats Drizzle
  EXPECT_GT(psnr[3], psnr[2]);  // TV beats Tikhonov on the bar target
}

// --fft-planner heuristic plans without the shipped FFTW wisdom: the same image to rounding (the plans differ,
// the maths does not); an unknown planner is refused with the allowed names.
TEST_F(ReconstructCliTest, FftPlannerHeuristicGivesTheSameImageToRounding) {
  for (const std::string planner : {"estimate", "heuristic"}) {
    const CliRun r = RunCli("reconstruct " + Data() + " -m tv --iterations 20 -o " + Out("tv-" + planner) +
                            " --fft-planner " + planner);
    ASSERT_EQ(r.status, 0) << r.out;
  }
  const aosr::Image a = aosr::ReadFitsImage(Out("tv-estimate")), b = aosr::ReadFitsImage(Out("tv-heuristic"));
  ASSERT_EQ(a.rows(), b.rows());
  EXPECT_LE((a - b).abs().maxCoeff(), 1e-6 * a.abs().maxCoeff());  // float32 output
  const CliRun bad = RunCli("reconstruct " + Data() + " -m tv -o " + Out("tv-bad") + " --fft-planner fastest");
  EXPECT_NE(bad.status, 0);  // CLI11 rejects the value (its own exit code)
  EXPECT_THAT(bad.out, HasSubstr("heuristic"));
  EXPECT_FALSE(fs::exists(Out("tv-bad")));
}

TEST_F(ReconstructCliTest, LinearWritesItsEffectivePsfNoiseAndLeakage) {
  // Uniform weights: the exact Fourier path, no probes.
  const nlohmann::json j = Run("linear", "--target-psf gaussian:3 --leakage 1e-3 --noise-sigma 10");
  ASSERT_TRUE(j.contains("linear")) << j.dump(2);
  EXPECT_EQ(j["summary"]["method"], "target-psf-fourier");
  EXPECT_EQ(j["linear"]["noise_probes"], 0);
  EXPECT_TRUE(j["linear"]["leakage_met"].get<bool>());
  EXPECT_NEAR(j["linear"]["target_fwhm_hr_px"].get<double>(), 3.0, 1e-12);
  EXPECT_GT(j["linear"]["noise_rms"].get<double>(), 0.0);
  EXPECT_EQ(aosr::FitsExtensionNames(Out("linear")), (std::vector<std::string>{"PSF", "NOISE_CORR", "LEAKAGE"}));
  const aosr::FitsData img = aosr::ReadFits(Out("linear"));
  EXPECT_NEAR(img.header.GetDouble("TGTFWHM"), 3.0, 1e-12);
  // The PSF extension holds the effective PSF in a window; PSFFRAC says how much of it lies inside.
  const aosr::FitsData psf = aosr::ReadFitsExtension(Out("linear"), "PSF");
  EXPECT_NEAR(psf.planes.at(0).sum(), img.header.GetDouble("PSFFRAC"), 1e-6);
  EXPECT_GT(img.header.GetDouble("PSFFRAC"), 0.99);
  EXPECT_TRUE(fs::exists(dir_ / "linear_std.fits"));
  ASSERT_TRUE(j.contains("against_truth_through_psf")) << j.dump(2);
  // The truth seen through the output's PSF is what a linear method estimates: much closer than the truth.
  EXPECT_GT(j["against_truth_through_psf"]["psnr_db"].get<double>(), j["against_truth"]["psnr_db"].get<double>() + 5);

  // Bad pixels make the weights non-uniform: the PCG path with noise probes.
  nlohmann::json scene = nlohmann::json::parse(std::ifstream(dir_ / "scene.json"));
  scene["detector"]["bad_pixels"] = {{"fraction", 0.02}};
  std::ofstream(dir_ / "scene_bad.json") << scene.dump(2);
  ASSERT_EQ(RunCli("simulate " + (dir_ / "scene_bad.json").string() + " -o " + (dir_ / "bad").string()).status, 0);
  const CliRun r = RunCli("reconstruct " + (dir_ / "bad").string() + " -m linear -o " +
                          (dir_ / "linear_bad.fits").string() + " --json --noise-probes 8");
  ASSERT_EQ(r.status, 0) << r.out;
  const nlohmann::json b = nlohmann::json::parse(r.out);
  EXPECT_EQ(b["summary"]["method"], "target-psf-cg");
  EXPECT_EQ(b["linear"]["noise_probes"], 8);
  EXPECT_GT(b["linear"]["noise_rms_error"].get<double>(), 0.0);
  EXPECT_GT(b["masked_pixels"].get<long long>(), 0);
}

TEST_F(ReconstructCliTest, LinearRejectsABadTargetPsf) {
  const std::string missing = (dir_ / "missing.fits").string();
  for (const std::string& bad : {std::string("gaussian:"), std::string("gaussian:0.1"), std::string("gaussian:3x"),
                                 std::string("moffat"), missing}) {
    const CliRun r = RunCli("reconstruct " + Data() + " -m linear -o " + Out("bad") + " --target-psf " + bad);
    EXPECT_NE(r.status, 0) << bad;
    EXPECT_THAT(r.out, HasSubstr(bad == missing ? "missing.fits" : "--target-psf")) << r.out;
    EXPECT_FALSE(fs::exists(Out("bad")));
  }
}

// Issue 24: `--weights auto` means source-independent background weights for the linear methods (here from the
// simulation's detector model: σ = 1 % of the peak, uniform, so the Fourier-exact path runs), the dataset's
// inverse variances for tv/map; the source-dependent ones stay available by name, with a warning.
TEST_F(ReconstructCliTest, DefaultWeightsAreSourceIndependentForLinearMethods) {
  for (const char* m : {"linear", "drizzle", "tikhonov"}) {
    const nlohmann::json j = Run(m);
    EXPECT_EQ(j["weights"], "background variances from the detector model (e-^-2)") << m;
    EXPECT_EQ(j["weights_option"], "auto");
    ASSERT_EQ(j["background_sigma_e"].size(), 4u) << j.dump(2);
    EXPECT_GT(j["background_sigma_e"][0].get<double>(), 0.0);
    EXPECT_FALSE(j.contains("warning")) << m;
  }
  EXPECT_EQ(Run("tv", "--iterations 5")["weights"], "dataset inverse variances (e-^-2)");
  EXPECT_EQ(Run("linear", "--weights background")["summary"]["method"], "target-psf-fourier");
  const nlohmann::json p = Run("linear", "--weights poisson");
  EXPECT_EQ(p["weights"], "dataset inverse variances (e-^-2)");
  EXPECT_THAT(p["warning"].get<std::string>(), HasSubstr("bias bright sources low"));
  const CliRun r = RunCli("reconstruct " + Data() + " -m drizzle -o " + Out("drizzle_poisson") + " --weights poisson");
  ASSERT_EQ(r.status, 0) << r.out;
  EXPECT_THAT(r.out, HasSubstr("warning: the dataset's inverse variances"));
  // A linear output is scored after subtracting its sky estimate (here ~0: the scene has no sky).
  const nlohmann::json l = Run("linear");
  ASSERT_TRUE(l.contains("sky_subtracted_e")) << l.dump(2);
  EXPECT_LT(std::abs(l["sky_subtracted_e"].get<double>()), 10.0);
}

// --target-psf diffraction: the telescope's Airy pattern at the dataset's wavelength (paper-8m, camera pixel
// λ/D, r = 2). Its FWHM as psf_metrics.hpp measures a pattern point-sampled at λ/(2D): 0.903 λ/D = 1.81 HR px
// (dataset_problem_test: 1.02 λ/D at λ/(8D), the same pattern).
TEST_F(ReconstructCliTest, LinearTakesTheDiffractionLimitedTarget) {
  const nlohmann::json j = Run("linear", "--target-psf diffraction");
  ASSERT_TRUE(j.contains("linear")) << j.dump(2);
  EXPECT_NEAR(j["linear"]["target_fwhm_hr_px"].get<double>(), 1.81, 0.02) << j.dump(2);
}

TEST_F(ReconstructCliTest, TikhonovWritesItsPosteriorStdMap) {
  const nlohmann::json j = Run("tikhonov", "--weights mask --std --noise-sigma 10");
  ASSERT_TRUE(j.contains("aux")) << j.dump(2);
  const aosr::Image s = aosr::ReadFitsImage(j["aux"]["path"].get<std::string>());
  EXPECT_GT(s.minCoeff(), 0.0);
  // Periodic with period r = 2 (tikhonov.hpp (6)).
  EXPECT_NEAR(s(10, 11), s(12, 13), 1e-5 * s(10, 11));
}

// The rank counts are made on request: the summary reports the unconstrained HR frequencies with
// --count-unconstrained and does not without it, the image being the same bits.
TEST_F(ReconstructCliTest, TikhonovCountsUnconstrainedFrequenciesOnRequest) {
  const nlohmann::json plain = Run("tikhonov", "--lambda 0.01");
  const aosr::Image a = aosr::ReadFitsImage(Out("tikhonov"));
  const nlohmann::json counted = Run("tikhonov", "--lambda 0.01 --count-unconstrained");
  const aosr::Image b = aosr::ReadFitsImage(Out("tikhonov"));
  EXPECT_THAT(counted["summary"]["message"].get<std::string>(), HasSubstr("HR frequencies unconstrained by the data"))
      << counted.dump(2);
  EXPECT_THAT(plain["summary"]["message"].get<std::string>(), Not(HasSubstr("unconstrained"))) << plain.dump(2);
  EXPECT_TRUE((a == b).all());
}

TEST_F(ReconstructCliTest, BadRequestsFailBeforeWritingAnything) {
  CliRun r = RunCli("reconstruct " + Data() + " -m wiener -o " + Out("x"));
  EXPECT_EQ(r.status, 1);
  EXPECT_THAT(r.out, HasSubstr("shift-add | shift-add-median | drizzle | tikhonov | linear | tv | map"));
  EXPECT_FALSE(fs::exists(Out("x")));
  // Never overwrite an input.
  r = RunCli("reconstruct " + Data() + " -m drizzle -o " + (dir_ / "data" / "frames.fits").string());
  EXPECT_EQ(r.status, 1);
  EXPECT_THAT(r.out, HasSubstr("input"));
  r = RunCli("reconstruct " + (dir_ / "nowhere").string() + " -o " + Out("y"));
  EXPECT_EQ(r.status, 1);
  EXPECT_THAT(r.out, HasSubstr("nowhere"));
  r = RunCli("reconstruct " + Data() + " -m drizzle --kernel round -o " + Out("z"));
  EXPECT_EQ(r.status, 1);
  EXPECT_THAT(r.out, HasSubstr("kernel"));
}

// --tile (solvers/tiling.hpp): 48-px frames in 2 x 2 tiles of 24 px. With a fixed λ the tiled image is the
// whole-grid one to a small fraction of its peak, the header and JSON say how it was
// tiled, 1 and 2 threads give the same bytes, and a bad tiling is refused before anything is written.
TEST_F(ReconstructCliTest, TileReconstructsByOverlappingTiles) {
  const nlohmann::json whole = Run("tikhonov", "--lambda 0.01");
  const aosr::Image w = aosr::ReadFitsImage(Out("tikhonov"));
  for (const char* threads : {"1", "2"}) {
    const CliRun r = RunCli("reconstruct " + Data() + " -m tikhonov --lambda 0.01 --tile 24 --tile-overlap 10 -o " +
                            Out(std::string("tiled") + threads) + " --json --threads " + threads);
    ASSERT_EQ(r.status, 0) << r.out;
    const nlohmann::json j = nlohmann::json::parse(r.out);
    ASSERT_TRUE(j.contains("tiling")) << j.dump(2);
    EXPECT_EQ(j["tiling"]["overlap"], 10);
    EXPECT_EQ(j["tiling"]["tiles"], nlohmann::json::array({2, 2}));
    EXPECT_THAT(j["summary"]["message"].get<std::string>(), HasSubstr("tiled: 2 x 2 tiles"));
  }
  const aosr::FitsData t1 = aosr::ReadFits(Out("tiled1")), t2 = aosr::ReadFits(Out("tiled2"));
  EXPECT_EQ(t1.header.GetInt("NTILES"), 4);
  const aosr::Image& t = t1.planes.at(0);
  // Measured 2.8e-4 of the peak (0.19 e on 668 e, on the tiles' inner edges): the periodic tiles' truncation at
  // overlap 10 (bench figures in solvers/tiling.hpp), far above the float32 rounding of the file.
  EXPECT_LT((t - w).abs().maxCoeff(), 1e-3 * w.abs().maxCoeff());
  EXPECT_TRUE((t == t2.planes.at(0)).all()) << "1 and 2 threads";
  // The automatic overlap (measured from Tikhonov's response at the GCV λ, capped by the field), GCV on the whole field.
  const nlohmann::json a = Run("tikhonov", "--tile 24");
  EXPECT_EQ(a["tiling"]["regularisation_source"], "whole field");
  EXPECT_THAT(a["tiling"]["overlap_rule"].get<std::string>(), HasSubstr("measured"));
  // Bad tilings: named, and nothing written.
  for (const std::string& bad : {std::string("--tile -3"), std::string("--tile 24 --tile-overlap 30"),
                                 std::string("--tile-overlap 4"), std::string("--tile 24 --tile-overlap -5"),
                                 std::string("--tile 24 --tile-tolerance 0")}) {
    const CliRun r = RunCli("reconstruct " + Data() + " -m tikhonov -o " + Out("bad") + " " + bad);
    EXPECT_EQ(r.status, 1) << bad << ": " << r.out;
    EXPECT_THAT(r.out, HasSubstr("tile")) << bad;
    EXPECT_FALSE(fs::exists(Out("bad"))) << bad;
  }
}

// --resume DIR: the finished tiles are kept; a rerun after losing some (a killed run never wrote them) solves
// only those and writes the same file, byte for byte.
TEST_F(ReconstructCliTest, ResumeGivesTheBytesOfAnUninterruptedRun) {
  auto bytes = [](const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  };
  const std::string dir = (dir_ / "tiles").string();
  const std::string cmd = "reconstruct " + Data() + " -m linear --tile 16 --json -o ";
  CliRun r = RunCli(cmd + Out("plain"));
  ASSERT_EQ(r.status, 0) << r.out;
  r = RunCli(cmd + Out("first") + " --resume " + dir);
  ASSERT_EQ(r.status, 0) << r.out;
  EXPECT_EQ(nlohmann::json::parse(r.out)["tiling"]["tiles_resumed"], 0);
  ASSERT_TRUE(fs::exists(fs::path(dir) / "tile_8.bin"));
  fs::remove(fs::path(dir) / "tile_0.bin");
  fs::remove(fs::path(dir) / "tile_4.bin");
  r = RunCli(cmd + Out("resumed") + " --resume " + dir);
  ASSERT_EQ(r.status, 0) << r.out;
  EXPECT_EQ(nlohmann::json::parse(r.out)["tiling"]["tiles_resumed"], 7);
  EXPECT_EQ(bytes(Out("resumed")), bytes(Out("plain")));
  EXPECT_EQ(bytes(Out("first")), bytes(Out("plain")));
  // The same folder with other options: refused, nothing written.
  r = RunCli(cmd + Out("other") + " --leakage 0.01 --resume " + dir);
  EXPECT_EQ(r.status, 1) << r.out;
  EXPECT_THAT(r.out, HasSubstr("another run"));
  EXPECT_FALSE(fs::exists(Out("other")));
  r = RunCli("reconstruct " + Data() + " -o " + Out("other") + " --resume " + dir);
  EXPECT_EQ(r.status, 1);
  EXPECT_THAT(r.out, HasSubstr("only with --tile"));
}

// The real thing behind the test above: the process killed by a signal while it solves its tiles (SIGKILL: no
// handler, no cleanup; SIGINT: the Ctrl-C path, which stops cleanly with status 130 and writes nothing). Each
// time the tiles it had finished are the ones a rerun with --resume takes over (none solved again), a tile it was
// writing when killed leaves no file under a tile's name (checkpoints are renamed into place), and the rerun's
// file has the bytes of an uninterrupted run. TV on 1 thread with tiles of 12 camera px (16 tiles, ~50 ms each),
// killed as soon as the first checkpoint appears, so the signal lands mid-run.
TEST_F(ReconstructCliTest, KilledOrInterruptedRunsResumeWithTheBytesOfAnUninterruptedRun) {
  auto bytes = [](const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  };
  const std::string cmd = "reconstruct " + Data() + " -m tv --tile 12 --threads 1 --json -o ";
  CliRun r = RunCli(cmd + Out("tv-plain"));
  ASSERT_EQ(r.status, 0) << r.out;
  ASSERT_EQ(nlohmann::json::parse(r.out)["tiling"]["tiles"], nlohmann::json::array({4, 4}));
  for (const std::string signal : {"KILL", "INT"}) {
    const fs::path dir = dir_ / ("tiles-" + signal);
    const std::string out = Out("tv-" + signal);
    // Start the run, wait for its first finished tile (or its end), send the signal, report the exit status.
    r = aosr::test::RunShell("(" + std::string(AOSR_CLI_PATH) + " " + cmd + out + " --resume " + dir.string() +
                             " > /dev/null 2> " + (dir_ / "err.txt").string() + " & p=$!; " +
                             "while kill -0 $p 2> /dev/null && ! ls " + dir.string() +
                             "/tile_*.bin > /dev/null 2>&1; do sleep 0.005; done; kill -" + signal +
                             " $p; wait $p; echo status=$?)");
    ASSERT_EQ(r.status, 0) << r.out;
    EXPECT_THAT(r.out, HasSubstr(signal == "KILL" ? "status=137" : "status=130")) << signal << ": " << r.out;
    EXPECT_FALSE(fs::exists(out)) << signal;
    if (signal == "INT") {
      std::ifstream err(dir_ / "err.txt");
      const std::string text((std::istreambuf_iterator<char>(err)), std::istreambuf_iterator<char>());
      EXPECT_THAT(text, HasSubstr("interrupted")) << text;
      EXPECT_THAT(text, HasSubstr("nothing written")) << text;
    }
    int finished = 0;
    for (const auto& e : fs::directory_iterator(dir)) {
      const std::string name = e.path().filename().string();
      if (name.rfind("tile_", 0) == 0 && e.path().extension() == ".bin") ++finished;
    }
    EXPECT_GE(finished, 1) << signal;
    EXPECT_LT(finished, 16) << signal << ": the signal came after the last tile";
    r = RunCli(cmd + out + " --resume " + dir.string());
    ASSERT_EQ(r.status, 0) << r.out;
    EXPECT_EQ(nlohmann::json::parse(r.out)["tiling"]["tiles_resumed"], finished) << signal;
    EXPECT_EQ(bytes(out), bytes(Out("tv-plain"))) << signal;
  }
}

// Progress (src/cli/progress_bar.hpp): --progress writes it to stderr, as whole lines when stderr is a file,
// and never to stdout (the JSON stays clean); without it, with stderr not a terminal (a file here), a
// successful run writes nothing to stderr.
TEST_F(ReconstructCliTest, ProgressGoesToStderrOnlyWhenAskedOrOnATerminal) {
  const fs::path err = dir_ / "stderr.txt";
  const auto run = [&](const std::string& extra) {
    // The subshell keeps stderr in the file (RunShell merges only the subshell's own stderr into stdout).
    return aosr::test::RunShell("(" + std::string(AOSR_CLI_PATH) + " reconstruct " + Data() + " -m tv -o " +
                                Out("tv-progress") + " --iterations 30 " + extra + " 2> " + err.string() +
                                ")");
  };
  const auto read = [](const fs::path& p) {
    std::ifstream in(p);
    return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  };
  CliRun r = run("--json --progress");
  ASSERT_EQ(r.status, 0) << r.out << read(err);
  EXPECT_NO_THROW((void)nlohmann::json::parse(r.out)) << r.out;
  EXPECT_THAT(r.out, Not(HasSubstr("[aosr]")));
  const std::string progress = read(err);
  EXPECT_THAT(progress, HasSubstr("[aosr] pilot 0/1"));
  EXPECT_THAT(progress, HasSubstr("[aosr] tv 1/30 ["));
  EXPECT_THAT(progress, HasSubstr("[aosr] tv 30/30 [####################] primal/tol "));
  EXPECT_THAT(progress, HasSubstr("elapsed"));
  EXPECT_THAT(progress, Not(HasSubstr("\r")));  // lines, not a redrawn line, in a file

  for (const char* quiet : {"--json", ""}) {
    r = run(quiet);
    ASSERT_EQ(r.status, 0) << r.out;
    EXPECT_EQ(read(err), "") << quiet;
    EXPECT_THAT(r.out, Not(HasSubstr("[aosr]")));
  }
}

// --offsets estimate: every method runs on the shifted model, and the summary lists per frame the commanded
// and estimated offsets in camera px (here the DM applies exactly the commanded raster: estimated ≈ commanded).
TEST_F(ReconstructCliTest, OffsetsEstimateReportsCommandedAndEstimatedPerFrame) {
  for (const char* m : {"tikhonov", "shift-add"}) {
    const nlohmann::json j = Run(m, "--offsets estimate");
    ASSERT_TRUE(j.contains("registration")) << j.dump(2);
    const nlohmann::json& f = j["registration"]["frames"];
    ASSERT_EQ(f.size(), 4u);
    for (const nlohmann::json& e : f) {
      for (int a = 0; a < 2; ++a)
        EXPECT_NEAR(e["estimated_camera_px"][a].get<double>(), e["commanded_camera_px"][a].get<double>(), 0.02) << e.dump();
      EXPECT_NEAR(std::abs(e["commanded_camera_px"][0].get<double>()), 0.25, 1e-12);
      EXPECT_GT(e["sigma_camera_px"].get<double>(), 0.0);
    }
    EXPECT_THAT(j["offsets"].get<std::string>(), HasSubstr("estimated from the frames"));
  }
  const CliRun text = RunCli("reconstruct " + Data() + " -m tikhonov --offsets estimate -o " + Out("reg"));
  ASSERT_EQ(text.status, 0) << text.out;
  EXPECT_THAT(text.out, AllOf(HasSubstr("registration ("), HasSubstr("frame 3: commanded (+0.2500, +0.2500)  estimated (")));
  const CliRun bad = RunCli("reconstruct " + Data() + " -m tikhonov --offsets estimate --registration-anchor x -o " + Out("reg"));
  EXPECT_NE(bad.status, 0);
  EXPECT_THAT(bad.out, HasSubstr("mean | frame0"));
}

// --model-psfs stars on data/scenes/crowded-stars.json shrunk to 48² camera px and 40 stars: the PSF from the
// frames' own stars, its report, the cube --stars-psf-out writes, a reconstruction close to the oracle PSFs'
// one, and the errors that name what is missing.
TEST(ReconstructCliStars, ModelPsfsFromTheStarsInTheFrames) {
  const fs::path dir = fs::temp_directory_path() / ("aosr_reconstruct_stars_" + std::to_string(getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  nlohmann::json scene;
  std::ifstream(std::string(AOSR_SOURCE_DIR) + "/data/scenes/crowded-stars.json") >> scene;
  scene["detector"]["frame_px"] = 48;
  scene["objects"][0]["count"] = 40;
  std::ofstream(dir / "scene.json") << scene.dump(2);
  ASSERT_EQ(RunCli("simulate " + (dir / "scene.json").string() + " -o " + (dir / "data").string()).status, 0);
  const std::string data = (dir / "data").string(), psf = (dir / "psf.fits").string();
  const CliRun r = RunCli("reconstruct " + data + " -m tikhonov --model-psfs stars --stars-psf-out " + psf + " -o " +
                          (dir / "s.fits").string() + " --json");
  ASSERT_EQ(r.status, 0) << r.out;
  const nlohmann::json j = nlohmann::json::parse(r.out);
  EXPECT_TRUE(j["model_psfs_replaced"].get<bool>());
  const nlohmann::json& s = j["stars_psf"];
  EXPECT_GE(s["stars_used"].get<int>(), 10);
  EXPECT_EQ(s["min_required"].get<int>(), 4);
  EXPECT_EQ(s["psf_size_hr_px"].get<int>(), 64);
  EXPECT_GT(s["chi2_per_dof"].get<double>(), 0.5);
  EXPECT_LT(s["chi2_per_dof"].get<double>(), 2.0);
  EXPECT_TRUE(s["cg_converged"].get<bool>());
  EXPECT_GE(s["cg_iterations_total"].get<int>(), s["cg_iterations_last"].get<int>());
  EXPECT_EQ(s["path"], psf);
  const aosr::FitsData cube = aosr::ReadFits(psf);
  ASSERT_EQ(cube.planes.size(), 4u);
  EXPECT_NEAR(cube.planes[0].sum(), 1.0, 1e-9);
  const CliRun o = RunCli("reconstruct " + data + " -m tikhonov -o " + (dir / "o.fits").string() + " --json");
  ASSERT_EQ(o.status, 0) << o.out;
  const double p_oracle = nlohmann::json::parse(o.out)["against_truth"]["psnr_db"].get<double>();
  EXPECT_GT(j["against_truth"]["psnr_db"].get<double>(), p_oracle - 0.5);
  // The text summary names the estimate.
  const CliRun text = RunCli("reconstruct " + data + " -m tikhonov --model-psfs stars -o " + (dir / "t.fits").string());
  EXPECT_THAT(text.out, HasSubstr("stars PSF: "));
  // What the frames lack, named; --stars-psf-out without stars.
  const CliRun none = RunCli("reconstruct " + data + " -m tikhonov --model-psfs stars --stars-threshold 1e5 -o " +
                             (dir / "n.fits").string());
  EXPECT_NE(none.status, 0);
  EXPECT_THAT(none.out, AllOf(HasSubstr("no point source above 100000 sigma"), HasSubstr("unsaturated point sources")));
  EXPECT_FALSE(fs::exists(dir / "n.fits"));
  const CliRun few = RunCli("reconstruct " + data + " -m tikhonov --model-psfs stars --stars-min 1000 -o " +
                            (dir / "f.fits").string());
  EXPECT_NE(few.status, 0);
  EXPECT_THAT(few.out, HasSubstr(">= 1000 = max(min_stars 1000"));
  const CliRun stray = RunCli("reconstruct " + data + " -m tikhonov --stars-psf-out " + psf + " -o " + (dir / "x.fits").string());
  EXPECT_NE(stray.status, 0);
  EXPECT_THAT(stray.out, HasSubstr("only with --model-psfs stars"));
  fs::remove_all(dir);
}

// --rings K: the summary's scores against the truth in K rings (as aosr evaluate --rings), each aligned on its own
// and never below its raw scores; a bad count or centre is refused before the reconstruction, naming the flag.
TEST_F(ReconstructCliTest, RingsReportTheScoresAcrossTheField) {
  // A centre inside the scored crop (HR px 32..63 of 96: the dataset's border): (30, 40) would leave room for one
  // ring of the SSIM window's width only.
  const nlohmann::json j = Run("tikhonov", "--rings 2 --ring-centre 40,44");
  ASSERT_TRUE(j["against_truth"].contains("rings")) << j.dump(2);
  const nlohmann::json& rings = j["against_truth"]["rings"];
  EXPECT_EQ(rings["count"].get<int>(), 2);
  EXPECT_EQ(rings["centre_hr_px"]["x"].get<double>(), 40.0);
  EXPECT_EQ(rings["centre_hr_px"]["y"].get<double>(), 44.0);
  for (const nlohmann::json& r : rings["rings"]) {
    EXPECT_GE(r["aligned"]["psnr_db"].get<double>(), r["psnr_db"].get<double>()) << r.dump();
    EXPECT_GE(r["aligned"]["ssim"].get<double>(), r["ssim"].get<double>()) << r.dump();
    EXPECT_GT(r["outer_arcsec"].get<double>(), r["inner_arcsec"].get<double>());
  }
  const CliRun text =
      RunCli("reconstruct " + Data() + " -m tikhonov -o " + Out("rings-text") + " --rings 2 --ring-centre 40,44");
  ASSERT_EQ(text.status, 0) << text.out;
  EXPECT_THAT(text.out, HasSubstr("2 rings about (x, y) = (40.00, 44.00) HR px"));
  for (const char* bad_text : {"--rings 40", "--rings 2 --ring-centre 200,3", "--ring-centre 3,3", "--rings 2 --ring-centre x"}) {
    const std::string bad = bad_text;
    const CliRun r = RunCli("reconstruct " + Data() + " -m tikhonov -o " + Out("rings-bad") + " " + bad);
    EXPECT_EQ(r.status, 1) << bad << "\n" << r.out;
    EXPECT_THAT(r.out, HasSubstr(bad.find("centre") != std::string::npos ? "--ring-centre" : "--rings")) << bad;
    EXPECT_FALSE(fs::exists(Out("rings-bad"))) << bad;
  }
}


// A dataset whose whole-grid reconstruction passes --memory-limit: reconstructed by tiles without a whole-grid
// model, the image written by rows into one FITS with the header and WCS of a whole-grid run, the same pixels
// as the tiled run that holds the whole grid, and the memory figures in the JSON. Too small a limit for even
// one tile: a clear error and no file.
TEST_F(ReconstructCliTest, MemoryLimitReconstructsByTilesWrittenByRows) {
  const std::string base = "reconstruct " + Data() + " -m tikhonov --lambda 0.01 --tile 24 --tile-overlap 10 --json "
                           "--threads 1 -o ";
  CliRun r = RunCli(base + Out("held"));
  ASSERT_EQ(r.status, 0) << r.out;
  const nlohmann::json held_json = nlohmann::json::parse(r.out);
  EXPECT_FALSE(held_json.contains("output_by_rows"));
  r = RunCli(base + Out("rows") + " --memory-limit 2M");
  ASSERT_EQ(r.status, 0) << r.out;
  const nlohmann::json j = nlohmann::json::parse(r.out);
  ASSERT_TRUE(j.contains("output_by_rows")) << j.dump(2);
  // Its frames were read by sections, never held: the masked pixels counted in bands are the held run's (the
  // counts of a masked field: DatasetWeightsTest.RuleDecidedBySectionsEqualsTheHeldFramesRule), and the truth the
  // manifest names is noted as not scored.
  EXPECT_EQ(j["masked_pixels"], held_json["masked_pixels"]);
  EXPECT_TRUE(j.contains("metrics_note")) << j.dump(2);
  EXPECT_GT(j["output_by_rows"]["whole_grid_bytes"].get<double>(), 2.0 * 1024 * 1024);
  EXPECT_THAT(j["summary"]["message"].get<std::string>(), HasSubstr("residuals are the tiles' over their cores"));
  const aosr::FitsData held = aosr::ReadFits(Out("held")), rows = aosr::ReadFits(Out("rows"));
  // The same tiles (the window models cut by one rule), blended by rows: equal to float32 rounding.
  const aosr::Image& a = held.planes.at(0);
  EXPECT_LT((rows.planes.at(0) - a).abs().maxCoeff(), 1e-6 * a.abs().maxCoeff());
  for (const char* key : {"NTILES", "TILE", "REGUL", "SRFACTOR", "BUNIT"}) EXPECT_TRUE(rows.header.Has(key)) << key;
  EXPECT_EQ(rows.header.GetDouble("REGUL"), held.header.GetDouble("REGUL"));
  // Automatic tiles under the limit, and a limit no tile fits. 2900K lies between the estimates of the smallest
  // tiling (2.67 MiB) and of the whole grid (2.95 MiB: 2N + 32 HR arrays for weighted Tikhonov, EstimateSolveBytes).
  r = RunCli("reconstruct " + Data() + " -m tikhonov --lambda 0.01 --json --threads 1 --memory-limit 2900K -o " +
             Out("auto"));
  ASSERT_EQ(r.status, 0) << r.out;
  EXPECT_GT(nlohmann::json::parse(r.out)["tiling"]["tile"].get<int>(), 0);
  r = RunCli("reconstruct " + Data() + " -m tikhonov --lambda 0.01 --memory-limit 300K -o " + Out("none"));
  EXPECT_EQ(r.status, 1) << r.out;
  EXPECT_THAT(r.out, HasSubstr("memory"));
  // The frames it names are the dataset's, though none is held (read by sections).
  EXPECT_THAT(r.out, HasSubstr(" " + std::to_string(held_json["frames"].get<int>()) + " frames")) << r.out;
  EXPECT_FALSE(fs::exists(Out("none")));
}

}  // namespace

namespace AOSR_TEST_NS {

// A scene with a psf_field: simulate writes the field's PSFs; reconstruct uses them by tiles (auto), says so in
// its JSON and FITS header, and does better than with the guide star's PSF (--psf-field none) 45 arcsec away;
// drizzle has no PSF to vary and refuses --psf-field tiles.
TEST(ReconstructCliPsfField, TilesWithLocalPsfsFromTheDatasetsField) {
  const fs::path dir = fs::temp_directory_path() / ("aosr_reconstruct_field_" + std::to_string(getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  const nlohmann::json scene = {
      {"name", "field-cli"},
      {"telescope", "paper-8m"},
      {"frames", 4},
      {"r", 2},
      {"ao", {{"mode", "analytic"}}},
      {"offsets", {{"type", "raster"}}},
      {"psf_field", {{"guide_star_arcsec", {-45.0, 0.0}}, {"grid", 2}}},
      {"detector", {{"frame_px", 48}, {"noise", "peak-fraction"}, {"peak_noise_fraction", 0.0005}, {"saturation", false}}},
      {"objects", {{{"type", "stars"}, {"count", 30}, {"flux_range_e", {2e4, 2e5}}, {"margin_px", 5.0}}}}};
  std::ofstream(dir / "scene.json") << scene.dump(2);
  const CliRun sim = RunCli("simulate " + (dir / "scene.json").string() + " -o " + (dir / "data").string());
  ASSERT_EQ(sim.status, 0) << sim.out;
  EXPECT_TRUE(fs::exists(dir / "data" / "field_psfs.fits"));
  const std::string data = (dir / "data").string();
  const CliRun f = RunCli("reconstruct " + data + " -m tikhonov -o " + (dir / "f.fits").string() + " --json");
  ASSERT_EQ(f.status, 0) << f.out;
  const nlohmann::json jf = nlohmann::json::parse(f.out);
  ASSERT_TRUE(jf.contains("psf_field"));
  EXPECT_EQ(jf["psf_field"]["model"], "tiles");
  EXPECT_EQ(jf["psf_field"]["grid"], nlohmann::json({2, 2}));
  EXPECT_EQ(jf["tiling"]["tile"], 24);  // half of 95 HR px = 23.75 camera px
  EXPECT_EQ(aosr::ReadFits((dir / "f.fits").string()).header.GetString("PSFFIELD"), "tiles 2x2");
  const CliRun n = RunCli("reconstruct " + data + " -m tikhonov --psf-field none -o " + (dir / "n.fits").string() + " --json");
  ASSERT_EQ(n.status, 0) << n.out;
  const nlohmann::json jn = nlohmann::json::parse(n.out);
  EXPECT_FALSE(jn.contains("psf_field"));
  EXPECT_GT(jf["against_truth"]["aligned"]["psnr_db"].get<double>(),
            jn["against_truth"]["aligned"]["psnr_db"].get<double>() + 1.0);
  const CliRun d = RunCli("reconstruct " + data + " -m drizzle --psf-field tiles -o " + (dir / "d.fits").string());
  EXPECT_NE(d.status, 0);
  EXPECT_THAT(d.out, HasSubstr("a method that models the PSF"));
  EXPECT_FALSE(fs::exists(dir / "d.fits"));
  fs::remove_all(dir);
}

}  // namespace AOSR_TEST_NS
