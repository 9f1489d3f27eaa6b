// The accuracy/time trade-off of every reconstructor on one dataset: each method run through Reconstruct()
// (reconstruct.hpp) with the defaults of `aosr reconstruct`, over its knob. `aosr tradeoff` (which writes the table,
// the JSON and the picture) and Python's aosr.tradeoff both call RunTradeoffSweep.
//
// The knobs:
//   shift-add, shift-add-median, drizzle   one run (no knob)
//   tikhonov                               λ by GCV, then fixed λ = f · λ_GCV for each of lambda_factors
//                                          (the fixed runs skip the GCV search, so they are also its cost)
//   linear                                 the target-PSF output (target_psf.hpp), the science output: its
//                                          automatic target (leakage bound), then Gaussian targets of
//                                          FWHM f · FWHM_auto for each of target_factors: resolution bought
//                                          with noise and leakage. Scored against the truth seen through its
//                                          own effective PSF (what it estimates), with the target and
//                                          effective FWHM, the noise RMS and the leakage per row
//   tv, map                                one run per iteration cap, each from scratch (the Tikhonov pilot,
//                                          which also sets their weight, is part of every run's time)
// Per row: termination, iterations, wall seconds (Reconstruction::seconds_total: warm start and automatic
// weight included), and
//   with a truth     PSNR, SSIM, RMSE (core/metrics.hpp) on the truth cropped by the dataset's trustworthy
//                    border, crop = trustworthy_border_px · r HR px, exactly as bench/reconstruct_bench.cpp
//                    scores (so the numbers agree with the bench; the crop falls back to 0 when it would leave
//                    less than the 11 px SSIM window, as `aosr reconstruct` does), and the same after removing
//                    the global sub-pixel offset (scene/evaluation.hpp);
//   always           the method's own final objective (Summary::final_cost: not comparable across methods), the
//                    data misfit as the reduced χ² = Σ w (y − A x)² / n_w over the n_w weighted pixels (≈ 1
//                    when the residual is at the noise level with true inverse-variance weights; comparable
//                    across methods), and the relative change ‖x_k − x_{k−1}‖ / ‖x_k‖ from the previous row of
//                    the same method (previous cap, or next smaller λ or target).
// Weights as `aosr reconstruct --weights`: `auto` means background (source-independent) weights for the linear
// methods and the dataset's for tv and map (dataset_problem.hpp).
#pragma once

#include <functional>
#include <limits>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "aosr/core/progress.hpp"
#include "aosr/scene/dataset.hpp"
#include "aosr/solvers/dataset_problem.hpp"

namespace aosr {

// Every method the sweep knows, in its order.
inline const std::vector<std::string>& TradeoffMethods() {
  static const std::vector<std::string> all = {"shift-add", "shift-add-median", "drizzle", "tikhonov", "linear", "tv",
                                               "map"};
  return all;
}

struct TradeoffOptions {
  std::vector<std::string> methods;                              // empty: every method (TradeoffMethods)
  std::vector<int> iterations = {10, 30, 100, 300};              // tv, map: caps in 1 .. 1e6
  std::vector<double> lambda_factors = {0.01, 0.1, 10, 100};     // tikhonov: finite, > 0, not 1
  std::vector<double> target_factors = {0.9, 1.25, 1.5, 2.0};    // linear: in (0, 10], not 1
  DatasetWeights weights = DatasetWeights::kAuto;
};

// Checks the options; `name` gives each field's name in the caller's words (the CLI's "--lambda-factors", Python's
// "lambda_factors"). InvalidArgument naming the field.
void CheckTradeoffOptions(const TradeoffOptions& options, const std::function<std::string(const char* field)>& name,
                          const char* caller);

struct TradeoffRow {
  std::string method;
  std::string knob;             // human-readable knob setting, "-" for none
  double lambda_factor = std::numeric_limits<double>::quiet_NaN();  // tikhonov: λ / λ_GCV (1 for the GCV row)
  int iteration_cap = 0;        // tv, map
  double target_factor = std::numeric_limits<double>::quiet_NaN();  // linear: target FWHM / the automatic target's (1 for the automatic row)
  // linear: the target's and the effective PSF's FWHM [HR px], the output's noise RMS (frame units per HR
  // pixel) and its leakage U (target_psf.hpp).
  double target_fwhm = std::numeric_limits<double>::quiet_NaN(), effective_fwhm = std::numeric_limits<double>::quiet_NaN(), noise_rms = std::numeric_limits<double>::quiet_NaN(), leakage = std::numeric_limits<double>::quiet_NaN();
  int iterations = 0;
  std::string termination, message;
  double seconds = 0, regularisation = 0;
  double psnr = std::numeric_limits<double>::quiet_NaN(), ssim = std::numeric_limits<double>::quiet_NaN(), rmse = std::numeric_limits<double>::quiet_NaN();
  // After removing the global sub-pixel offset (scene/evaluation.hpp), and the offset [HR px, mas].
  double aligned_psnr = std::numeric_limits<double>::quiet_NaN(), aligned_ssim = std::numeric_limits<double>::quiet_NaN(), offset_dy = std::numeric_limits<double>::quiet_NaN(), offset_dx = std::numeric_limits<double>::quiet_NaN(), offset_dy_mas = std::numeric_limits<double>::quiet_NaN(),
         offset_dx_mas = std::numeric_limits<double>::quiet_NaN();
  double objective = std::numeric_limits<double>::quiet_NaN(), misfit = std::numeric_limits<double>::quiet_NaN(), change = std::numeric_limits<double>::quiet_NaN();
};


struct TradeoffSweep {
  std::vector<std::string> methods;  // run, in order
  std::vector<TradeoffRow> rows;
  std::string weights_source, weights_source_linear;  // the weights of tv/map and of the linear methods
  bool has_truth = false;
  int metric_crop_px = 0;                             // with a truth
  bool cancelled = false;  // `progress` cancelled a run: the sweep stopped after it (its row is the last)
};

// Runs the sweep on `dataset` (a loaded Dataset; options checked with the field names). `step`, when set, gets
// one line per run ("tikhonov λ = 0.1 × GCV = ..."); `progress` is handed to every Reconstruct, and a run it
// cancels is the sweep's last (`cancelled`).
TradeoffSweep RunTradeoffSweep(const Dataset& dataset, const TradeoffOptions& options,
                               const std::function<void(const std::string&)>& step = {},
                               const ProgressCallback& progress = {});

// A row as `aosr tradeoff --json` and aosr.tradeoff give it.
nlohmann::json TradeoffRowJson(const TradeoffRow& row);

}  // namespace aosr
