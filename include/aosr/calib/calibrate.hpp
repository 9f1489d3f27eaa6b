// Calibrate a whole measurement set: for every poked mode, fit its gain (modal_fit.hpp) jointly over all its
// frames, then at each amplitude level separately, find the linear range (linearity.hpp), and refit jointly
// over the frames inside the linear range. The static aberration each mode's fit finds is combined over modes.
//
// Per mode (frames F = the mode's poked frames + its references + the shared references):
//  1. joint fit over F: g, position, static aberration, source size, per-frame flux/background;
//  2. per level |a_k|: the frames with |a| = |a_k|, fitting g and their flux/background only (position, static
//     aberration and source size held at the joint values) -> g_k ± σ_k;
//  3. AnalyseLinearity(g_k) -> linear range, onset, verdict;
//  4. if some level lies outside the linear range, the joint fit again over the references and the frames with
//     |a| <= the linear range (else the joint fit is final). The final fit's g ± σ is the mode's gain.
// The static aberration of the set is the inverse-variance weighted mean over modes of the final fits' c_k;
// its σ is that of the mean. Before combining, modes of odd azimuthal order m (tip/tilt, coma, trefoil: they do
// not break the twin-image symmetry, modal_fit.hpp) have their even-m static terms put on the branch of the
// even-m modes; the reported per-mode static terms are the aligned ones. A set with no even-m mode leaves the
// sign of the even-m static terms undetermined (the gains are not affected). (A single fit of every mode at once would share it exactly; per-mode fits are
// cheaper, parallel, and the spread across modes is itself a check.)
//
// Modes are independent and are fitted on `threads` threads (each fit single-threaded). Outcomes are data:
// a fit that fails or does not converge is reported in its ModalFitResult, not thrown.
#pragma once

#include <string>
#include <vector>

#include "aosr/calib/calibration_set.hpp"
#include "aosr/calib/linearity.hpp"
#include "aosr/calib/modal_fit.hpp"
#include "aosr/core/progress.hpp"

namespace aosr {

struct CalibrateOptions {
  ModalFitOptions fit;
  LinearityOptions linearity;
  // Threads over modes, in [1, 256]. Default 2 (the project's CI machines have two cores).
  int threads = 2;
  // Run the per-level fits and the linearity analysis (steps 2-4). Default on.
  bool per_amplitude = true;
  // Progress and cancellation (core/progress.hpp): stage "calibrate", iteration = modes done of `total` = the
  // set's modes, value the last mode's gain ("gain"). Reported from the calling thread (which fits modes too)
  // after each of its modes, so a report comes at least once per mode fit. Returning false stops handing out
  // modes: the modes in flight finish, the rest are left unfitted (Termination::kUserCancelled), and the
  // result says cancelled (no static aberration is combined). Empty (the default): no cost.
  ProgressCallback progress;

  bool IsValid(std::string* why) const;
};

struct ModeCalibration {
  int mode = 0;                      // index into the set's modes
  std::string name;                  // "Z4" or the pattern's name
  int noll = 0;                      // 0 for actuator patterns
  std::vector<int> frames;           // set frame indices of the joint fit (the order of joint.model)
  ModalFitResult joint;
  std::vector<int> final_frames;     // set frame indices of the final fit
  ModalFitResult final_fit;          // gain ± σ reported for the mode
  LinearityReport linearity;         // empty levels when per_amplitude is off
  bool refit = false;                // the final fit differs from the joint one
};

struct CalibrationResult {
  std::vector<ModeCalibration> modes;
  std::vector<int> static_modes;                 // Noll indices
  std::vector<double> static_m, static_sigma_m;  // combined over modes [m RMS OPD]
  double seconds = 0.0;
  int threads = 1;
  bool cancelled = false;  // CalibrateOptions::progress asked to stop: some modes are not fitted

  // One line per mode: gain ± σ, linear range, verdict, χ²/dof, termination.
  std::string BriefReport() const;
};

// Throws InvalidArgument for invalid options (before any fit); the set is validated again.
CalibrationResult Calibrate(const CalibrationSet& set, const CalibrateOptions& options = {});

}  // namespace aosr
