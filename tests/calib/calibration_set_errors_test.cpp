// Bad calibration input gives a clear error naming the problem (or is masked), never a crash in Ceres.
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <limits>

#include "aosr/calib/calibrate.hpp"
#include "aosr/calib/calibration_file.hpp"
#include "aosr/calib/calibration_set.hpp"
#include "aosr/calib/linearity.hpp"
#include "aosr/calib/modal_fit.hpp"
#include "aosr/core/memory.hpp"
#include "aosr/io/fits.hpp"
#include "aosr/optics/zernike.hpp"
#include "support/testing.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

using ::testing::AllOf;
using ::testing::HasSubstr;
using test::ErrorOf;
namespace fs = std::filesystem;

SyntheticCalibrationOptions Small() {
  SyntheticCalibrationOptions o;
  o.window = {16, 16};
  o.modes = {4, 5};
  o.amplitudes_m = {30e-9, 60e-9};
  o.static_modes = {4};
  o.static_m = {10e-9};
  return o;
}

TEST(CalibrationSetErrors, MismatchedImageSizes) {
  CalibrationSet set = SynthesizeCalibrationSet(Small());
  set.frames[2].adu = Image::Ones(16, 18);
  EXPECT_THAT(ErrorOf([&] { ValidateCalibrationSet(&set); }), HasSubstr("frames[2] shape = 16x18"));
  EXPECT_THAT(ErrorOf([&] { Calibrate(set); }), HasSubstr("all frames must match"));
}

TEST(CalibrationSetErrors, ModeMissingItsReference) {
  CalibrationSet set = SynthesizeCalibrationSet(Small());
  std::vector<CalibrationFrame> kept;
  for (CalibrationFrame& f : set.frames)
    if (!(f.reference && f.mode == 1)) kept.push_back(f);
  set.frames = kept;
  EXPECT_THAT(ErrorOf([&] { ValidateCalibrationSet(&set); }), HasSubstr("mode Z5 = no reference (flat) frame"));
}

TEST(CalibrationSetErrors, AmplitudesAllZero) {
  CalibrationSet set = SynthesizeCalibrationSet(Small());
  for (CalibrationFrame& f : set.frames)
    if (f.mode == 0) f.amplitude_m = 0.0;
  EXPECT_THAT(ErrorOf([&] { ValidateCalibrationSet(&set); }), HasSubstr("mode Z4 = amplitudes all zero"));
  // The fit itself refuses too (before Ceres).
  const Image& y = set.frames[0].adu;
  std::vector<ModalFitImage> images = {{&y, nullptr, 0.0}};
  EXPECT_THAT(ErrorOf([&] { FitModalImages(set.optics, Zernike(4, 64), images, {}, {}); }),
              HasSubstr("every commanded amplitude is 0"));
}

TEST(CalibrationSetErrors, NanPixelsAreMaskedAndAllNanFramesRefused) {
  CalibrationSet set = SynthesizeCalibrationSet(Small());
  set.frames[1].adu(3, 4) = std::numeric_limits<double>::quiet_NaN();
  set.frames[1].adu(8, 8) = std::numeric_limits<double>::infinity();
  ValidateCalibrationSet(&set);
  EXPECT_EQ(set.masked_pixels, 2);
  EXPECT_EQ(set.frames[1].valid(3, 4), 0.0);
  EXPECT_EQ(set.frames[1].adu(3, 4), 0.0);
  CalibrateOptions co;
  co.per_amplitude = false;
  co.fit.reweight_passes = 0;
  const CalibrationResult r = Calibrate(set, co);
  for (const ModeCalibration& m : r.modes) EXPECT_TRUE(std::isfinite(m.final_fit.gain));
  set.frames[1].adu.setConstant(std::numeric_limits<double>::quiet_NaN());
  EXPECT_THAT(ErrorOf([&] { ValidateCalibrationSet(&set); }), HasSubstr("0 valid pixels"));
  // Unmasked NaN handed straight to the fit is refused before Ceres.
  Image y = set.frames[2].adu;
  y(0, 0) = std::numeric_limits<double>::quiet_NaN();
  std::vector<ModalFitImage> images = {{&y, nullptr, 30e-9}};
  EXPECT_THAT(ErrorOf([&] { FitModalImages(set.optics, Zernike(4, 64), images, {}, {}); }),
              HasSubstr("non-finite unmasked pixels"));
}

TEST(CalibrationSetErrors, FitArgumentsAndOptions) {
  const CalibrationSet set = SynthesizeCalibrationSet(Small());
  const Image& y = set.frames[2].adu;
  Image other = Image::Ones(16, 20);
  std::vector<ModalFitImage> images = {{&y, nullptr, 30e-9}, {&other, nullptr, 60e-9}};
  EXPECT_THAT(ErrorOf([&] { FitModalImages(set.optics, Zernike(4, 64), images, {}, {}); }),
              HasSubstr("images[1] shape = 16x20"));
  images.pop_back();
  EXPECT_THAT(ErrorOf([&] { FitModalImages(set.optics, Zernike(4, 32), images, {}, {}); }), HasSubstr("mode_shape"));
  ModalFitOptions bad;
  bad.huber_threshold = -1;
  EXPECT_THAT(ErrorOf([&] { FitModalImages(set.optics, Zernike(4, 64), images, {}, bad); }), HasSubstr("huber_threshold"));
  NoiseModelParameters noise;
  noise.gain_e_per_adu = 0;
  EXPECT_THAT(ErrorOf([&] { FitModalImages(set.optics, Zernike(4, 64), images, noise, {}); }), HasSubstr("gain_e_per_adu"));
  Image flat = Image::Zero(16, 16);
  std::vector<ModalFitImage> dark = {{&flat, nullptr, 30e-9}};
  EXPECT_THAT(ErrorOf([&] { FitModalImages(set.optics, Zernike(4, 64), dark, {}, {}); }), HasSubstr("no signal"));
  CalibrateOptions co;
  co.threads = 0;
  EXPECT_THAT(ErrorOf([&] { Calibrate(set, co); }), HasSubstr("threads"));
  EXPECT_THAT(ErrorOf([] { AnalyseLinearity({}); }), HasSubstr("levels"));
  SyntheticCalibrationOptions so = Small();
  so.gains = {1.0};
  EXPECT_THAT(ErrorOf([&] { SynthesizeCalibrationSet(so); }), HasSubstr("gains"));
  // Actuator-pattern modes: a name clashing with another, a pattern of the wrong length for the DM, no modes.
  so = Small();
  so.patterns = {CalibrationMode{0, "p", {1.0}}, CalibrationMode{0, "p", {1.0}}};
  EXPECT_THAT(ErrorOf([&] { SynthesizeCalibrationSet(so); }), HasSubstr("distinct names"));
  so.patterns.pop_back();
  EXPECT_THAT(ErrorOf([&] { SynthesizeCalibrationSet(so); }), HasSubstr("actuator pattern size"));
  so.patterns.clear();
  so.modes.clear();
  EXPECT_THAT(ErrorOf([&] { SynthesizeCalibrationSet(so); }), HasSubstr("at least one"));
  // Every field within its range, the set past the memory limit: refused before any frame is rendered.
  so = Small();
  so.window = {1024, 1024};
  so.references_per_mode = 1000;
  SetMemoryLimitBytes(1024.0 * 1024 * 1024);
  const std::string memory = ErrorOf<ResourceError>([&] { SynthesizeCalibrationSet(so); });
  SetMemoryLimitBytes(0);
  EXPECT_THAT(memory, HasSubstr("frames of 1024x1024 pixels needs about"));
  EXPECT_THAT(memory, HasSubstr("more than the limit of 1 GiB"));
}

class ManifestErrors : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("aosr_calib_errors_" + std::to_string(getpid()) + "_" +
                                        ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    WriteCalibrationSet(dir_.string(), SynthesizeCalibrationSet(Small()));
    manifest_ = nlohmann::json::parse(std::ifstream(dir_ / kCalibrationSetFileName));
  }
  void TearDown() override { fs::remove_all(dir_); }
  std::string Rewrite() {
    std::ofstream(dir_ / kCalibrationSetFileName) << manifest_.dump(2);
    return ErrorOf<Error>([&] { LoadCalibrationSet(dir_.string()); });
  }
  fs::path dir_;
  nlohmann::json manifest_;
};

TEST_F(ManifestErrors, EachBadFieldIsNamed) {
  EXPECT_EQ(ErrorOf<Error>([&] { LoadCalibrationSet(dir_.string()); }), "no exception");
  manifest_["frames"][1]["colour"] = "red";
  EXPECT_THAT(Rewrite(), HasSubstr("frames[1].colour"));
  manifest_["frames"][1].erase("colour");
  manifest_["frames"][1]["file"] = "frames/missing.fits";
  EXPECT_THAT(Rewrite(), HasSubstr("missing.fits"));
  manifest_["frames"][1]["file"] = "frames/001.fits";
  manifest_["frames"][2]["mode"] = "no-such-pattern";
  EXPECT_THAT(Rewrite(), HasSubstr("frames[2].mode"));
  manifest_["frames"][2]["mode"] = 4;
  manifest_["format"] = "something-else";
  EXPECT_THAT(Rewrite(), HasSubstr("format"));
  manifest_["format"] = kCalibrationSetFormat;
  manifest_["pixel_rad"] = 1e-5;
  EXPECT_THAT(Rewrite(), HasSubstr("exactly one of them"));
  manifest_.erase("pixel_rad");
  WriteFits((dir_ / "dark.fits").string(), Image(Image::Zero(10, 10)));
  manifest_["dark"] = "dark.fits";
  EXPECT_THAT(Rewrite(), HasSubstr("dark is 10x10"));
}

// Found by fuzz_calibration_set (fuzz/regressions/calibration_set/): a telescope or set path longer than the
// OS allows (NAME_MAX) made std::filesystem throw filesystem_error ("File name too long") out of the loader.
TEST_F(ManifestErrors, NamesTooLongForTheOsAreMissingFiles) {
  const std::string long_name(300, 'a');
  manifest_["telescope"] = long_name;
  EXPECT_THAT(Rewrite(), AllOf(HasSubstr("LoadTelescopePreset"), HasSubstr(long_name), HasSubstr("paper-bench")));
}

// Found by fuzz_calibration_set (fuzz/regressions/calibration_set/truth-*.json): CalibrationToJson read the set's
// free-form "truth" with get<int>() / get<double>(), so a manifest's truth of another shape, and a synthetic set's
// own truth for an actuator-pattern mode (named by string), threw nlohmann type_error out of `aosr calibrate`.
TEST_F(ManifestErrors, TruthOfAnyShapeIsProvenanceOnly) {
  for (const char* truth : {R"({"modes": [{"gain": 0.9, "mode": 4}, 18446744073709551615]})",
                            R"({"modes": [{"gain": {}, "mode": 4}]})", R"({"modes": [{"gain": 1.1, "mode": [4]}]})",
                            R"({"modes": 3})", R"({"modes": [{"mode": "poke", "gain": 1.0}]})"}) {
    manifest_["truth"] = nlohmann::json::parse(truth);
    EXPECT_EQ(Rewrite(), "no exception") << truth;
    const CalibrationSet set = LoadCalibrationSet(dir_.string());
    EXPECT_EQ(ErrorOf<Error>([&] { CalibrationToJson(set, CalibrationResult{}); }), "no exception") << truth;
  }
  SyntheticCalibrationOptions so = Small();
  so.modes = {4};
  so.gains = {1.0, 0.8};
  so.patterns = {CalibrationMode{0, "poke", std::vector<double>(101, 0.2)}};
  const CalibrationSet synthetic = SynthesizeCalibrationSet(so);
  EXPECT_EQ(ErrorOf<Error>([&] { CalibrationToJson(synthetic, CalibrationResult{}); }), "no exception");
}

TEST(CalibrationFileErrors, BadGainsAreRefused) {
  const fs::path p = fs::temp_directory_path() / ("aosr_calib_file_" + std::to_string(getpid()) + ".json");
  std::ofstream(p) << R"({"format": "aosr-calibration-v1", "modes": [{"mode": 4, "gain": -0.5}]})";
  EXPECT_THAT(ErrorOf([&] { LoadCalibration(p.string()); }), HasSubstr("modes[0].gain"));
  std::ofstream(p) << R"({"format": "aosr-calibration-v1", "modes": []})";
  EXPECT_THAT(ErrorOf([&] { LoadCalibration(p.string()); }), HasSubstr("modes"));
  fs::remove(p);
}

}  // namespace
}  // namespace aosr
