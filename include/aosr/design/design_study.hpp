// One phase-design study as `aosr design` runs it: the scene's design model, objective A (expected Tikhonov/Wiener
// MSE, design_objective.hpp, optionally with an object spectrum fitted to training images) or B (mean MAP loss over
// training scenes, design_empirical.hpp), OptimizeDesign from the raster and perturbed starts, the check on a fresh
// sample, the expected gain over the raster with its uncertainty and the advice (DesignGain: the raster is kept
// unless the design gains at least min_gain_db, significantly), and the design file (design_file.hpp).
// The CLI (src/cli/design_command.cpp) and the Python aosr.design() both call RunDesignStudy, so a design made
// from either is the same file, bit for bit.
#pragma once

#include <cstdint>
#include <functional>
#include <limits>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "aosr/design/design_file.hpp"
#include "aosr/design/design_optimizer.hpp"
#include "aosr/scene/scene_spec.hpp"

namespace aosr {

// The options of `aosr design` (its --help says what each does); defaults are the CLI's.
struct DesignStudyOptions {
  std::string param = "zernike";  // raster (evaluate only) | tiptilt | zernike | actuators
  int modes = 20;                 // Zernike modes per exposure
  double rms_max_nm = 0.0;        // bound on each offset's pupil RMS [nm]; 0: none
  double strehl_min = 0.0;        // lower bound on each offset's Strehl; 0: none
  int starts = 3;
  int realisations = 2;           // AO PSF realisations averaged
  int screens = 4;                // residual screens per exposure and realisation
  double lambda = 1e-2;           // objective A: Tikhonov lambda of the reconstructor
  std::string prior = "gradient";  // objective A: reconstructor prior
  int iterations = 100;           // L-BFGS iterations per start
  int threads = 2;
  std::uint64_t seed = 1;
  std::string objective = "A";    // A | B
  std::string loss = "l1";        // B: l1 | l2
  int training_scenes = 3;        // B: dead-leaves training scenes
  std::vector<std::string> training;  // training images (A: fitted spectrum, Wiener design; B: training scenes)
  double training_zoom = 1.0;     // B: source pixels per HR pixel of the --training crops
  double noise_sigma = 0.04;      // B, and A with training: noise sigma per LR pixel at peak 1
  int validation_realisations = 4;  // fresh-sample check; 0: none
  double map_lambda = -1.0;       // B: MAP lambda; < 0: automatic (1/sigma for the TV prior, 1 for tikhonov)
  double epsilon = 1e-3;          // B: Charbonnier epsilon
  std::string map_prior = "charbonnier-tv";  // B: charbonnier-tv | tikhonov
  // Progress and cancellation of the optimisation (DesignOptimizerOptions::progress_callback, stage "design").
  // After a cancellation the best design so far is kept and the fresh-sample check is skipped (the summary's
  // termination says "cancelled"). Not a CLI option (the CLI stops on Ctrl-C); Python's aosr.design uses it.
  ProgressCallback progress;
  double min_gain_db = 0.2;       // the smallest expected gain [dB] for which the design is advised (and kept)
  // Objective A's check judges the design on a sky this many times finer than the HR grid (1 .. 16;
  // design_continuous_sky.hpp): what a real, continuous sky gets. 1: on the HR grid's own sky, as objective A
  // optimises (where the HR pixel is coarser than λ/2D that overstates a design's gain, up to 2x in J band).
  int sky_oversampling = 4;
};

// The expected gain of a design over the classic raster and the advice that follows.
//
// gain = 10 log10(J_raster / J_design) [dB], J the objective's mean over the check sample. For objective A J
// is the expected MSE per HR pixel of the Tikhonov/Wiener reconstruction, so the gain is the expected PSNR
// gain of that reconstructor. Its uncertainty is the standard error of the per-realisation gains
// g_k = 10 log10(J_raster,k / J_design,k) over the V fresh AO realisations (sd(g_k) / sqrt(V), paired: the
// raster and the design see the same residual screens); 0 when the frames follow the nominal model
// (realisations = 0: J is exact), unknown (NaN, JSON null) for one pooled sample (objective B, V = 1, or no
// check). The advice is "design" when gain >= threshold_db and gain > 2 standard errors (when known), else
// "raster": keep the classic raster; the study then returns the raster.
struct DesignGain {
  double db = 0.0;
  double stderr_db = 0.0;
  std::vector<double> per_realisation_db;
  int realisations = 0;            // V (1: the nominal model or a pooled sample)
  double objective_raster = 0.0;   // mean J of the exact classic raster over the check sample
  double objective_design = 0.0;   // mean J of the optimised design
  std::string basis;               // what J and the sample were, in words
  double threshold_db = 0.2;
  std::string advice = "raster";   // "design" | "raster"
  std::string reason;              // one sentence: why
  // Objective A checked on a finer sky (DesignStudyOptions::sky_oversampling s > 1): db and stderr_db are that
  // sky's, and the same sample's gain on the HR grid's own sky (what the optimiser saw) is hr_sky_db +-
  // hr_sky_stderr_db. s = 1: no such check (NaN).
  int sky_oversampling = 1;
  double hr_sky_db = std::numeric_limits<double>::quiet_NaN();
  double hr_sky_stderr_db = std::numeric_limits<double>::quiet_NaN();

  // Sets db, stderr_db, per_realisation_db, realisations and the means from paired samples (> 0, finite).
  void FromPairs(const std::vector<double>& raster, const std::vector<double>& design, bool exact);
  // Sets advice and reason from db, stderr_db and threshold_db.
  void Decide();
  // "+1.23 +- 0.04 dB (basis): use the design".
  std::string BriefReport() const;
  nlohmann::json ToJson() const;
};

struct DesignStudy {
  DesignResult result;                     // the design kept (the raster unless the advice is "design")
  DesignGain gain;                         // its expected gain over the raster and the advice
  std::vector<DesignFrameReport> reports;  // per exposure: RMS, Strehl
  nlohmann::json file;                     // the design file (WriteDesignFile writes it)
  nlohmann::json summary;                  // what `aosr design --json` prints, without total_seconds/output
  // For the CLI's text report.
  std::string method;           // the objective's method() name
  std::string last_evaluation;  // objective B: its last evaluation's BriefReport; else empty
  int realisations = 0;         // the objective's realisations
  bool ao = false;              // the design model has an AO residual
  Index grid = 0;               // the design model's HR grid side
};

// Runs the study. InvalidArgument (naming the option) for a bad option; `progress`, when set, gets one line per
// stage. Calibration (designed offsets -> DM commands) is the caller's: calib/calibration_file.hpp.
DesignStudy RunDesignStudy(const SceneSpec& scene, const DesignStudyOptions& options,
                           const std::function<void(const std::string&)>& progress = {});

}  // namespace aosr
