// Fuzz target: calibration-set manifests (calib/calibration_set.hpp LoadCalibrationSet: manifest, frames,
// dark, mask, validation), then one step past loading: each mode's frame list, the first mode's shape on the
// pupil grid (what the fit builds first), and the calibration.json a fit of the set would write
// (CalibrationToJson with an empty result: it copies the set's provenance and its "truth").
//
// Companion files, written once into the scratch folder's set/: a small synthetic set (SynthesizeCalibrationSet:
// paper-bench, 16x16 frames, Z2 and Z4 at +-50 nm, one reference each), whose calibration-set.json is the
// corpus seed; plus other frames a mutated manifest may name: frame.png (16x16), small.fits (8x8), cube.fits
// (2 planes), nan.fits (all NaN), dark.fits and mask.fits (16x16).
//
// With AOSR_FUZZ_WRITE_COMPANIONS=DIR set, the set is also written to DIR (that is how the seed was made).
#include <cstdint>
#include <cstdlib>
#include <limits>
#include <string>

#include "aosr/calib/calibrate.hpp"
#include "aosr/calib/calibration_file.hpp"
#include "aosr/calib/calibration_set.hpp"
#include "aosr/io/fits.hpp"
#include "aosr/io/image_io.hpp"
#include "fuzz_common.hpp"

namespace {

void WriteCompanions(const std::string& dir) {
  aosr::SyntheticCalibrationOptions o;
  o.window = {16, 16};
  o.pupil_px = 32;
  o.modes = {2, 4};
  o.gains = {0.9, 1.1};
  o.amplitudes_m = {50e-9};
  o.static_modes = {4};
  o.static_m = {10e-9};
  o.seed = 7;
  aosr::WriteCalibrationSet(dir, aosr::SynthesizeCalibrationSet(o));
  aosr::Image img(16, 16);
  for (aosr::Index y = 0; y < 16; ++y)
    for (aosr::Index x = 0; x < 16; ++x) img(y, x) = double((x * 3 + y * 5) % 17) / 16.0;
  aosr::WriteViewImage(dir + "/frame.png", img);
  aosr::WriteFits(dir + "/small.fits", aosr::Image::Ones(8, 8));
  aosr::WriteFitsCube(dir + "/cube.fits", {img, img});
  aosr::WriteFits(dir + "/nan.fits", aosr::Image::Constant(16, 16, std::numeric_limits<double>::quiet_NaN()));
  aosr::WriteFits(dir + "/dark.fits", aosr::Image::Constant(16, 16, 3.0));
  aosr::Image mask = aosr::Image::Ones(16, 16);
  mask(0, 0) = 0.0;
  aosr::WriteFits(dir + "/mask.fits", mask);
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static const std::string dir = [] {
    const std::string d = aosr::fuzz::ScratchDir() + "/set";
    WriteCompanions(d);
    if (const char* out = std::getenv("AOSR_FUZZ_WRITE_COMPANIONS")) WriteCompanions(out);
    return d;
  }();
  aosr::fuzz::WriteScratch(std::string("set/") + aosr::kCalibrationSetFileName, data, size);
  aosr::fuzz::ExpectAosrErrors([&] {
    const aosr::CalibrationSet set = aosr::LoadCalibrationSet(dir);
    for (int m = 0; m < int(set.modes.size()); ++m) (void)set.FramesOfMode(m);
    if (!set.modes.empty()) (void)set.ModeShape(0);
    (void)aosr::CalibrationToJson(set, aosr::CalibrationResult{}).dump();
  });
  return 0;
}
