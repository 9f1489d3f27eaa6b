// The calibration report image: one row per mode with the gain measured at each amplitude (error bars, the
// final gain as a line, the linear range shaded up to the onset), then, for the reference and each amplitude
// level (the positive poke), the measured frame above the modelled one on a common square-root stretch.
#pragma once

#include <string>

#include "aosr/calib/calibrate.hpp"
#include "aosr/calib/calibration_set.hpp"

namespace aosr {

// Writes the report as an 8-bit grayscale PNG (or TIFF by extension) atomically. InvalidArgument if the result
// does not belong to the set (mode or frame counts differ).
void WriteCalibrationReport(const std::string& path, const CalibrationSet& set, const CalibrationResult& result);

}  // namespace aosr
