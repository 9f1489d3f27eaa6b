// One entry point for every reconstructor, so the CLI, the benchmarks and the phase-design evaluation run
// a method by name with the same options and get the same kind of result.
//
//   method            what runs                                          second map (aux)
//   shift-add         ShiftAndAdd (mean), masks honoured                 —
//   shift-add-median  ShiftAndAdd (median)                               —
//   drizzle           Drizzle (drizzle.hpp)                              weight map W
//   tikhonov          ReconstructTikhonov (tikhonov.hpp)                 posterior std (when computable)
//   linear            ReconstructTargetPsf (target_psf.hpp): one chosen  noise std (exact, or probed for
//                     output PSF, known noise                            weighted data)
//   tv                TotalVariationAdmm (total_variation.hpp)           —
//   map               MapReconstruct (map.hpp), warm-started by Tikhonov —
//
// Automatic regularisation for tv and map (ReconstructOptions::auto_regularisation, on by default). There is
// no universal TV weight; this rule follows how the objective scales. Divide ½Σw(y − Ax)² + μTV(x) by the
// noise variance ρ² in weight units and measure the object in units of the pixel noise σ_n = ρ/√w̄ (w̄ the
// mean positive weight): the data term becomes a sum of squared noise-unit residuals and the TV weight
// μ' = μ/(ρ√w̄). The rule keeps μ' fixed,
//
//     μ = k · ρ · √w̄,   ρ² = Σ w (y − A x̂_T)² / n_w  (x̂_T: the GCV Tikhonov estimate),   k = 0.5,
//
// (ρ ≈ 1 with true inverse-variance weights, ρ = σ with unit weights). k from measurements: the PSNR-best μ
// of total_variation_physics_test (unit weights, blocks, σ = 0.05 and 0.1) gives k = 0.5 and 1; the demo
// scene (σ = 1% of the peak, inverse-variance weights) k = 0.26–0.5 (PSNR within 0.5 dB of its best over
// k = 0.1–1.5). MAP uses the same TV weight in its own convention (λ = 2μ: F = ½[data + λR]) with
// Charbonnier ε = 10⁻³ s, s = q₉₉.₅(x̂_T) − q₅₀(x̂_T) the object's contrast. A heuristic: scan μ for science.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "aosr/solvers/drizzle.hpp"
#include "aosr/solvers/map.hpp"
#include "aosr/solvers/problem.hpp"
#include "aosr/solvers/shift_and_add.hpp"
#include "aosr/solvers/target_psf.hpp"
#include "aosr/solvers/tikhonov.hpp"
#include "aosr/solvers/total_variation.hpp"

namespace aosr {

enum class ReconstructionMethod {
  kShiftAddMean,
  kShiftAddMedian,
  kDrizzle,
  kTikhonov,
  kLinear,
  kTotalVariation,
  kMap
};
const char* ToString(ReconstructionMethod m);
// Every method Reconstruct runs, in the order of the table above: the one list that ParseReconstructionMethod
// accepts (and names in its error), and that Python's aosr.methods() returns.
const std::vector<ReconstructionMethod>& ReconstructionMethods();
// "shift-add" | "shift-add-median" | "drizzle" | "tikhonov" | "linear" | "tv" | "map"; InvalidArgument otherwise.
ReconstructionMethod ParseReconstructionMethod(const std::string& name);

// The automatic rule's values for one problem: the pilot's λ (options.tikhonov's rule, scaled as for weighted
// data), the TV weight μ and the object's contrast s (map's ε = δ = 10⁻³ s).
struct AutomaticRegularisation {
  double pilot_lambda = 0.0;
  double mu = 0.0;
  double contrast = 1.0;
};

struct ReconstructOptions {
  ReconstructionMethod method = ReconstructionMethod::kTikhonov;
  DrizzleOptions drizzle;
  // Default GCV λ and the gradient prior. Measured against the PSNR-best λ on six held-out scenes
  // (bench/results/lambda_rules.md: demo, paper-sim r = 2 and 4, crowded-stars at fresh seeds) GCV and UPRE
  // lose the same (median ~0.01 dB, worst ~0.3 dB), the L-curve more (median ~0.2 dB), the discrepancy
  // principle most (~0.75 dB: it over-smooths); the fitted Wiener prior (kFitted + kWiener) is as good as GCV
  // but needs the noise level to be reliable. GCV is the one of the best that needs no noise level.
  TikhonovOptions tikhonov = [] {
    TikhonovOptions t;
    t.lambda_rule = TikhonovLambdaRule::kGcv;
    return t;
  }();
  TargetPsfOptions linear;
  TotalVariationOptions tv;
  MapOptions map;
  // tv and map: set μ (tv.mu) and λ, ε (map.lambda, map.epsilon) by the rule above, overriding the fields.
  bool auto_regularisation = true;
  // tv and map with auto_regularisation: when set, the rule's values are these instead of this problem's own
  // (the pilot still runs, at pilot_lambda, for its warm start). Tiling (tiling.hpp) sets them from one
  // representative problem so that every tile has the same weight. Empty (the default): this problem's.
  std::optional<AutomaticRegularisation> fixed_automatic;
  // One progress callback for every stage of the run (core/progress.hpp), so a caller sees which stage runs:
  // "pilot" (the GCV Tikhonov estimate behind tv's automatic μ and warm start, and map's warm start; reported
  // as iteration 0 of 1 when it starts and 1 of 1, value λ, when it ends), then "tv" or "map" (their solvers'
  // iterations). When set it replaces tv.progress and map.progress; when empty those are used as given.
  // Returning false cancels: during the pilot the run returns the pilot's Tikhonov estimate, later the
  // solver's current iterate, both with Termination::kUserCancelled. For tikhonov it replaces tikhonov.progress
  // (stages "tikhonov" and "tikhonov-cg", tikhonov.hpp). The other methods are direct and do not call it. Empty
  // (the default): no cost.
  ProgressCallback progress;
};

struct Reconstruction {
  Image image;           // HR estimate, flux per HR pixel (frame units), always finite
  Image aux;             // the method's second map (see the table), or empty
  std::string aux_name;  // "weight" | "posterior-std" | "noise-std" | ""
  SolverSummary summary;  // termination, message, iterations, final cost, seconds, per-frame residual RMS
  double regularisation = 0.0;  // λ (tikhonov, map) or μ (tv) used; 0 for the baselines
  double seconds_total = 0.0;   // including warm start and automatic regularisation
  // linear only: the output's effective PSF (centred, unit sum), the noise covariance kernel ξ(Δ), the
  // per-frequency leakage and the full summary (target_psf.hpp); empty / nullopt otherwise.
  Image effective_psf;
  Image noise_correlation;
  Image leakage_spectrum;
  std::optional<TargetPsfSummary> linear;
};

// The automatic rule's values (the pilot's λ, μ, contrast) for `problem`: one Tikhonov solve by
// options.tikhonov's λ rule.
AutomaticRegularisation ChooseAutomaticRegularisation(const ReconstructionProblem& problem,
                                                      const ReconstructOptions& options);

// The bytes a solve of `method` on an HR grid of `hr_pixels` with N frames holds at its peak, beyond its
// input: the model's transfer functions, the data's spectra and the method's work arrays (estimates of the
// large arrays, as core/memory.hpp's). Reconstruct checks it against the memory limit before it starts; the
// tile engine (tiling.hpp) sizes its tiles with it. Measured against peak RSS in
// bench/results/whole_detector.md.
double EstimateSolveBytes(ReconstructionMethod method, int frames, double hr_pixels, bool weighted);

// Validates the problem and options (InvalidArgument names the field); never returns NaN: a non-finite
// estimate is reported as Termination::kFailed with the image zeroed.
Reconstruction Reconstruct(const ReconstructionProblem& problem, const ReconstructOptions& options);

}  // namespace aosr
