// The calibration set reader/writer, the linearity analysis, calibration.json and ApplyCalibration.
#include "aosr/calib/calibration_set.hpp"

#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "aosr/calib/calibrate.hpp"
#include "aosr/calib/calibration_file.hpp"
#include "aosr/calib/linearity.hpp"
#include "aosr/io/fits.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

namespace fs = std::filesystem;

class TempFolder {
 public:
  TempFolder() {
    path_ = fs::temp_directory_path() / ("aosr_calib_" + std::to_string(getpid()) + "_" +
                                         ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(path_);
    fs::create_directories(path_);
  }
  ~TempFolder() { fs::remove_all(path_); }
  std::string File(const std::string& n) const { return (path_ / n).string(); }
  const fs::path& path() const { return path_; }

 private:
  fs::path path_;
};

SyntheticCalibrationOptions Small() {
  SyntheticCalibrationOptions o;
  o.window = {16, 20};
  o.modes = {4, 7};
  o.gains = {0.9, 1.1};
  o.amplitudes_m = {30e-9, 60e-9};
  o.shared_references = 1;
  o.references_per_mode = 0;
  return o;
}

// The files `aosr calibrate` and aosr.calibrate refuse to overwrite: the manifest and every frame.
TEST(CalibrationSet, InputFilesAreTheManifestAndTheFrames) {
  TempFolder dir;
  EXPECT_TRUE(CalibrationSetInputFiles(SynthesizeCalibrationSet(Small())).empty());  // in memory
  WriteCalibrationSet(dir.path().string(), SynthesizeCalibrationSet(Small()));
  const CalibrationSet set = LoadCalibrationSet(dir.path().string());
  const std::vector<std::string> files = CalibrationSetInputFiles(set);
  ASSERT_EQ(files.size(), 1 + set.frames.size());
  EXPECT_EQ(fs::path(files[0]).filename(), kCalibrationSetFileName);
  for (const std::string& f : files) EXPECT_TRUE(fs::exists(f)) << f;
}

// Calibrate's progress (stage "calibrate", one step per mode) and cancellation: the modes not fitted say so.
TEST(CalibrationSet, CalibrateReportsModesAndCancels) {
  const CalibrationSet set = SynthesizeCalibrationSet(Small());
  CalibrateOptions o;
  o.threads = 1;
  o.fit.static_max_noll = 0;
  const CalibrationResult quiet = Calibrate(set, o);
  std::vector<Progress> seen;
  o.progress = [&seen](const Progress& q) {
    seen.push_back(q);
    return true;
  };
  const CalibrationResult watched = Calibrate(set, o);
  ASSERT_FALSE(seen.empty());
  EXPECT_EQ(seen.back().stage, "calibrate");
  EXPECT_EQ(seen.back().iteration, 2);
  EXPECT_EQ(seen.back().total, 2);
  EXPECT_FALSE(watched.cancelled);
  for (std::size_t m = 0; m < quiet.modes.size(); ++m)
    EXPECT_EQ(watched.modes[m].final_fit.gain, quiet.modes[m].final_fit.gain);
  o.progress = [](const Progress& q) { return q.iteration < 1; };  // stop after the first mode
  const CalibrationResult cut = Calibrate(set, o);
  EXPECT_TRUE(cut.cancelled);
  EXPECT_EQ(cut.modes[0].final_fit.gain, quiet.modes[0].final_fit.gain);
  EXPECT_EQ(cut.modes[1].final_fit.termination, Termination::kUserCancelled);
}

TEST(CalibrationSet, SynthesizedSetHasTheRequestedLayout) {
  const CalibrationSet set = SynthesizeCalibrationSet(Small());
  EXPECT_EQ(set.shape(), (Shape{16, 20}));
  ASSERT_EQ(set.modes.size(), 2u);
  EXPECT_EQ(set.modes[1].noll, 7);
  // 1 shared reference + 2 modes x 2 levels x (+, -).
  EXPECT_EQ(set.frames.size(), 9u);
  EXPECT_EQ(set.FramesOfMode(0).size(), 5u);  // its 4 pokes and the shared reference
  EXPECT_TRUE(set.frames[0].reference);
  EXPECT_EQ(set.frames[0].mode, -1);
  EXPECT_DOUBLE_EQ(set.truth["modes"][1]["gain"].get<double>(), 1.1);
  EXPECT_NEAR(set.optics.pixel_lambda_over_d, 0.3115, 1e-12);
  EXPECT_NEAR(set.optics.wavelength_m, 635e-9, 1e-15);  // the paper-bench preset
}

TEST(CalibrationSet, WriteThenLoadRoundTrips) {
  TempFolder dir;
  CalibrationSet set = SynthesizeCalibrationSet(Small());
  set.frames[3].valid(2, 2) = 0.0;  // a bad pixel goes to the shared mask
  WriteCalibrationSet(dir.path().string(), set);
  const CalibrationSet back = LoadCalibrationSet(dir.path().string());
  ASSERT_EQ(back.frames.size(), set.frames.size());
  ASSERT_EQ(back.modes.size(), set.modes.size());
  for (std::size_t i = 0; i < set.frames.size(); ++i) {
    EXPECT_EQ(back.frames[i].mode, set.frames[i].mode) << i;
    EXPECT_EQ(back.frames[i].reference, set.frames[i].reference) << i;
    EXPECT_NEAR(back.frames[i].amplitude_m, set.frames[i].amplitude_m, 1e-18) << i;
    EXPECT_EQ(back.frames[i].valid(2, 2), 0.0) << i;  // one mask for the whole set
    EXPECT_NEAR(back.frames[i].adu(5, 5), set.frames[i].adu(5, 5), 1e-9) << i;
  }
  EXPECT_EQ(back.noise.gain_e_per_adu, set.noise.gain_e_per_adu);
  EXPECT_EQ(back.truth["modes"][0]["mode"], 4);
}

// A hand-written manifest: dark subtraction, a PNG-free FITS set, a mode with its own reference and one using a
// shared reference, and pixel_rad instead of pixel_lambda_over_d.
TEST(CalibrationSet, HandWrittenManifestWithDark) {
  TempFolder dir;
  const Image dark = Image::Constant(12, 12, 100.0);
  WriteFits(dir.File("dark.fits"), dark);
  for (int i = 0; i < 4; ++i) {
    Image f = dark;
    f(6, 6) += 1000 + i;
    WriteFits(dir.File("f" + std::to_string(i) + ".fits"), f);
  }
  std::ofstream(dir.File(kCalibrationSetFileName)) << R"({
    "format": "aosr-calibration-set-v1", "telescope": "paper-bench", "pixel_rad": 1.465e-5,
    "detector": {"gain_e_per_adu": 2.0, "read_noise_e": 3.0}, "dark": "dark.fits",
    "frames": [
      {"file": "f0.fits", "reference": true},
      {"file": "f1.fits", "mode": 4, "amplitude_nm": 50},
      {"file": "f2.fits", "mode": 5, "amplitude_nm": -25.5},
      {"file": "f3.fits", "mode": 5, "reference": true}
    ]})";
  const CalibrationSet set = LoadCalibrationSet(dir.path().string());
  EXPECT_EQ(set.modes.size(), 2u);
  EXPECT_NEAR(set.optics.pixel_lambda_over_d, 1.465e-5 * 0.0135 / 635e-9, 1e-9);
  EXPECT_NEAR(set.frames[1].adu(6, 6), 1001.0, 1e-3);
  EXPECT_NEAR(set.frames[1].adu(0, 0), 0.0, 1e-6);
  EXPECT_NEAR(set.frames[2].amplitude_m, -25.5e-9, 1e-15);
  EXPECT_EQ(set.FramesOfMode(1), (std::vector<int>{0, 2, 3}));
  EXPECT_EQ(set.noise.read_noise_e, 3.0);
}

TEST(Linearity, AcceptsConsistentLevelsAndFlagsTheFirstDeviation) {
  std::vector<AmplitudeGain> levels = {{20e-9, 1.00, 0.01}, {40e-9, 1.01, 0.005}, {60e-9, 0.995, 0.004},
                                       {80e-9, 0.90, 0.004}, {100e-9, 0.80, 0.004}};
  const LinearityReport r = AnalyseLinearity(levels);
  EXPECT_EQ(r.verdict, "saturates");
  EXPECT_DOUBLE_EQ(r.linear_max_m, 60e-9);
  EXPECT_DOUBLE_EQ(r.onset_m, 80e-9);
  EXPECT_NEAR(r.reference_gain, 1.0, 0.01);
  EXPECT_GT(r.fit_reduced_chi2, 10.0);
  // Within tolerance but statistically significant: still linear (both conditions are needed).
  const LinearityReport small = AnalyseLinearity({{20e-9, 1.0, 1e-4}, {40e-9, 1.02, 1e-4}});
  EXPECT_EQ(small.verdict, "linear");
  // Applied amplitude folding back.
  const LinearityReport wrap = AnalyseLinearity({{20e-9, 1.0, 0.01}, {40e-9, 1.0, 0.01}, {60e-9, 0.6, 0.01}});
  EXPECT_EQ(wrap.verdict, "wraps");
  const LinearityReport up = AnalyseLinearity({{20e-9, 1.0, 0.01}, {40e-9, 1.2, 0.01}});
  EXPECT_EQ(up.verdict, "superlinear");
}

TEST(AppliedAmplitude, SaturatesAndFoldsBack) {
  EXPECT_DOUBLE_EQ(AppliedAmplitude(50e-9, 0.9, 0, 0.5), 45e-9);
  EXPECT_DOUBLE_EQ(AppliedAmplitude(-80e-9, 1.0, 60e-9, 0.5), -70e-9);
  EXPECT_DOUBLE_EQ(AppliedAmplitude(80e-9, 1.0, 60e-9, 1.5), 50e-9);
}

TEST(CalibrationFile, JsonRoundTripAndApplyCalibration) {
  TempFolder dir;
  const CalibrationSet set = SynthesizeCalibrationSet(Small());
  CalibrateOptions co;
  co.per_amplitude = true;
  const CalibrationResult r = Calibrate(set, co);
  const nlohmann::json j = CalibrationToJson(set, r);
  EXPECT_EQ(j["modes"].size(), 2u);
  EXPECT_TRUE(j["modes"][0].contains("pull"));
  EXPECT_TRUE(j["modes"][0].contains("per_amplitude"));
  WriteCalibrationJson(dir.File("calibration.json"), j);
  const Calibration c = LoadCalibration(dir.File("calibration.json"));
  ASSERT_NE(c.FindNoll(7), nullptr);
  EXPECT_DOUBLE_EQ(c.FindNoll(7)->gain, r.modes[1].final_fit.gain);
  EXPECT_EQ(c.FindNoll(5), nullptr);

  DmOffset design;
  design.zernike = {{4, 40e-9}, {7, -20e-9}, {5, 10e-9}};
  design.shift_x_px = 0.5;
  std::vector<std::string> notes;
  const DmOffset cmd = ApplyCalibration(design, c, &notes);
  EXPECT_DOUBLE_EQ(cmd.zernike[0].rms_m, 40e-9 / c.FindNoll(4)->gain);
  EXPECT_DOUBLE_EQ(cmd.zernike[1].rms_m, -20e-9 / c.FindNoll(7)->gain);
  EXPECT_DOUBLE_EQ(cmd.zernike[2].rms_m, 10e-9);  // not calibrated: unchanged, noted
  EXPECT_DOUBLE_EQ(cmd.shift_x_px, 0.5);           // Z2 not calibrated here
  ASSERT_EQ(notes.size(), 2u);
  EXPECT_NE(notes[0].find("shift_x_px"), std::string::npos);
  EXPECT_NE(notes[1].find("Z5"), std::string::npos);
  // The DM with the calibrated gains applies the design for those commands (aosr simulate --calibration).
  const DmOffset applied = DmResponse(cmd, c);
  for (std::size_t i = 0; i < design.zernike.size(); ++i)
    EXPECT_NEAR(applied.zernike[i].rms_m, design.zernike[i].rms_m, 1e-12 * std::abs(design.zernike[i].rms_m));
  EXPECT_DOUBLE_EQ(applied.shift_x_px, design.shift_x_px);
  EXPECT_DOUBLE_EQ(DmResponse(design, c).zernike[0].rms_m, 40e-9 * c.FindNoll(4)->gain);
}

}  // namespace
}  // namespace aosr
