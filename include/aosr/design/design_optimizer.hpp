// Phase design, part 3: minimising an objective (a DesignCriterion, design_psf.hpp: objective A of
// design_objective.hpp or objective B of design_empirical.hpp) over a parameterisation (design_parameterisation.hpp) with Ceres' GradientProblemSolver (L-BFGS, Wolfe
// line search), from several starts.
//
//     θ* = argmin_θ J(w(θ)),     w(θ) = the N DM offsets of parameters θ (bounds built in, so unconstrained).
//
// Starts: start 0 is the classic raster itself (its θ; for actuators a DM fit of it), starts 1 .. K−1 the
// raster plus Gaussian perturbations of start_spread × ParameterScale() per parameter (seeded). Each start runs
// L-BFGS on z = θ / ParameterScale() (so the first line-search step is O(1) in every unit). The best start wins;
// L-BFGS with a Wolfe line search only accepts decreasing steps, so the result is never worse on J than
// start 0, and the returned design is the raster itself if no start improved on it (the summary says so).
// The kRaster kind has no parameters: the raster is evaluated, not optimised.
//
// Outcomes are data: DesignSummary reports J at the raster, at the start and at the end, iterations, evaluations,
// time and Ceres' termination; non-convergence within max_iterations is kMaxIterations, not an exception. An
// evaluation that throws NumericalError (objective B: a MAP or adjoint solve missed its tolerance) is a failed
// step for Ceres (its line search contracts), never a value.
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "aosr/core/progress.hpp"
#include "aosr/design/design_parameterisation.hpp"
#include "aosr/design/design_psf.hpp"
#include "aosr/solvers/summary.hpp"

namespace aosr {

struct DesignOptimizerOptions {
  // Starts K in [1, 64]. Default 3: the raster and two perturbed copies (designs with N < r² or mismatch have
  // several local minima; more starts buy robustness at K times the cost).
  int starts = 3;
  // Perturbation of starts 1.. in units of ParameterScale() (a quarter-pixel tilt), >= 0. Default 0.5.
  double start_spread = 0.5;
  // L-BFGS iterations per start (>= 1; Ceres' default 50 is often short of convergence here). Default 100.
  int max_iterations = 100;
  // Ceres stopping rules: relative change of J, gradient max-norm relative to the start's, and relative
  // step; each in (0, 1). Defaults 1e-10, 1e-6, 1e-9 (J carries a design-independent part, the prior
  // variance of the frequencies beyond the optical cutoff, so its relative changes are small).
  double function_tolerance = 1e-10;
  double gradient_tolerance = 1e-6;
  double parameter_tolerance = 1e-9;
  int lbfgs_memory = 10;  // [1, 100]
  std::uint64_t seed = 1;
  // Called with one line per start and per iteration (e.g. to print progress on a terminal); may be empty.
  std::function<void(const std::string&)> progress;
  // Progress and cancellation (core/progress.hpp): stage "design", one report per L-BFGS iteration
  // (rate-limited; iteration counted over all starts, of total starts × max_iterations, value J). Returning
  // false ends the current start at its current point and runs no further start; the best design so far is
  // returned with Termination::kUserCancelled. Empty (the default): no cost.
  ProgressCallback progress_callback;

  bool IsValid(std::string* why) const;
};

struct DesignSummary : SolverSummary {
  // Inherited: method ("design-lbfgs" or "design-raster"), termination (of the best start), message,
  // iterations (summed over starts), final_cost (= final_objective), seconds.
  std::string parameterisation;
  int parameters = 0;
  double raster_objective = 0.0;   // J of the exact classic raster (tip/tilt)
  double initial_objective = 0.0;  // J at start 0 (the raster in this parameterisation)
  double final_objective = 0.0;    // J of the returned design
  double invisible_floor = 0.0;    // DesignCriterion::invisible_floor(): the part of J no design changes (NaN:
                                   // none known, objective B)
  std::string objective = "expected-mse";  // DesignCriterion::method()
  std::vector<double> start_objectives;  // final J of every start
  int best_start = 0;
  int evaluations = 0;             // objective (+gradient) evaluations over all starts
  bool improved = false;           // the returned design is better than start 0

  // "zernike (380 parameters): J 1.234e-2 -> 1.001e-2 (-18.9 % vs raster) in 3 starts, 212 iterations,
  // 240 evaluations, 41.2 s; best start 0 (converged)".
  // include_time = false leaves out the wall time (for files that must be byte-reproducible).
  std::string FullReport(bool include_time = true) const;
};

struct DesignResult {
  Vector parameters;                 // θ (empty for kRaster)
  std::vector<Vector> coefficients;  // per exposure (parameterisation.hpp)
  std::vector<DmOffset> offsets;     // per exposure, as a scene reads them
  std::vector<Image> opds;           // per exposure, n x n [m]
  DesignSummary summary;
};

// Minimises J over `parameterisation` (whose frame count must match the objective's, and pupil grid its
// optics'). Validates first; throws InvalidArgument naming the argument or option.
DesignResult OptimizeDesign(const DesignCriterion& objective, const DesignParameterisation& parameterisation,
                            const DesignOptimizerOptions& options);

}  // namespace aosr
