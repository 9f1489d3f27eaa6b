// Fuzz target: calibration files and calibration specs, the two small JSON files of calib/:
//  * calibration.json (calibration_file.hpp LoadCalibration), then one step past it: a design offset with a
//    shift and Zernike terms Z2..Z11 mapped through ApplyCalibration and DmResponse;
//  * synthetic-set specs (calibration_set.hpp LoadSyntheticCalibrationSpec, data/calibration/*.json), then the
//    options' IsValid (SynthesizeCalibrationSet itself renders frames: too slow for a fuzz loop).
// Both loaders see every input (each ignores the other's format with an aosr error).
#include <cstdint>
#include <string>
#include <vector>

#include "aosr/calib/calibration_file.hpp"
#include "aosr/calib/calibration_set.hpp"
#include "fuzz_common.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string path = aosr::fuzz::WriteScratch("calibration.json", data, size);
  aosr::fuzz::ExpectAosrErrors([&] {
    const aosr::Calibration calibration = aosr::LoadCalibration(path);
    aosr::DmOffset design;
    design.shift_y_px = 0.25;
    design.shift_x_px = -0.25;
    for (int j = 2; j <= 11; ++j) design.zernike.push_back({j, 20e-9 * (j % 3 == 0 ? -1 : 1)});
    std::vector<std::string> notes;
    const aosr::DmOffset command = aosr::ApplyCalibration(design, calibration, &notes);
    (void)aosr::DmResponse(command, calibration, &notes);
  });
  aosr::fuzz::ExpectAosrErrors([&] {
    const aosr::SyntheticCalibrationOptions options = aosr::LoadSyntheticCalibrationSpec(path);
    std::string why;
    (void)options.IsValid(&why);
  });
  return 0;
}
