// One phase-design study as `aosr design` runs it: the scene's design model, objective A (expected Tikhonov/Wiener
// MSE, design_objective.hpp, optionally with an object spectrum fitted to training images) or B (mean MAP loss over
// training scenes, design_empirical.hpp), OptimizeDesign from the raster and perturbed starts, the check on a fresh
// sample that keeps the raster unless the design wins there too, and the design file (design_file.hpp).
// The CLI (src/cli/design_command.cpp) and the Python aosr.design() both call RunDesignStudy, so a design made
// from either is the same file, bit for bit.
#pragma once

#include <cstdint>
#include <functional>
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
};

struct DesignStudy {
  DesignResult result;                     // the design kept (the raster if it lost the fresh-sample check)
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
