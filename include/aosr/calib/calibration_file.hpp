// calibration.json (format "aosr-calibration-v1"): the per-mode gains a calibration found, and their use.
//
// The file (field by field in data/calibration/README.md) holds, per mode, the gain g ± σ (applied / commanded
// power), the linear range and verdict, the per-amplitude gains and the fit quality; the static aberration
// combined over modes; and for synthetic sets the truth and each gain's pull (g − g_true)/σ.
//
// Using it. A design asks for an applied offset w = Σ_j b_j Z_j. A DM of gain g_j applies g_j × what it is
// commanded, so the command that applies the design is b_j / g_j:
//     ApplyCalibration(design) :  b_j -> b_j / g_j   for every calibrated Zernike term,
// and the tip/tilt image shift (made with Z2/Z3, scene_spec.hpp) likewise by 1/g_2 and 1/g_3. Terms of modes the
// calibration does not cover, and actuator commands, are left unchanged and listed in `notes`; so is a term whose
// commanded amplitude leaves the mode's measured linear range.
#pragma once

#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "aosr/calib/calibrate.hpp"
#include "aosr/scene/scene_spec.hpp"

namespace aosr {

inline constexpr const char* kCalibrationFormat = "aosr-calibration-v1";

// The calibration.json content as JSON (see data/calibration/README.md).
nlohmann::json CalibrationToJson(const CalibrationSet& set, const CalibrationResult& result);

// Writes `json` to `path` atomically (AtomicWrite).
void WriteCalibrationJson(const std::string& path, const nlohmann::json& json);

struct ModeGain {
  int noll = 0;              // 0 for an actuator pattern
  std::string name;
  double gain = 1.0, gain_sigma = 0.0;
  double linear_max_m = 0.0;  // 0: unknown
  std::string verdict;
};

struct Calibration {
  std::string source;
  std::vector<ModeGain> modes;
  // The calibrated gain of Zernike mode j, or null.
  const ModeGain* FindNoll(int j) const;
};

// Reads calibration.json. IoError for an unreadable file, InvalidArgument (file and field) for bad content,
// including a gain that is not finite and > 0.
Calibration LoadCalibration(const std::string& path);

// The command that applies `design` through a DM with the calibrated gains (top of the file). `notes` (may be
// null) receives one line per term left unscaled or outside its linear range.
DmOffset ApplyCalibration(const DmOffset& design, const Calibration& calibration, std::vector<std::string>* notes = nullptr);

// The inverse: the offset a DM with the calibrated gains applies for `command` (b_j -> g_j b_j, shifts by g_2,
// g_3). DmResponse(ApplyCalibration(d)) == d for every calibrated term. `aosr simulate --calibration` uses it
// to simulate the real DM; `aosr design --calibration` writes ApplyCalibration's commands.
DmOffset DmResponse(const DmOffset& command, const Calibration& calibration, std::vector<std::string>* notes = nullptr);

// A design file (design/design_file.hpp) whose frames become the commands that make a DM with the calibrated
// gains of `calibration_path` apply `designed` (the file's own offsets, one per frame): each frame is
// ApplyCalibration's command, and the designed frames, the file and the notes go to design.calibration for the
// record. What `aosr design --calibration` writes and aosr.design(calibration=...) returns. `notes` (may be null)
// receives ApplyCalibration's notes.
void ApplyCalibrationToDesignFile(const std::string& calibration_path, const std::vector<DmOffset>& designed,
                                  nlohmann::json* design_file, std::vector<std::string>* notes = nullptr);

}  // namespace aosr
