// Isotropic total-variation (TV) super-resolution, solved by ADMM with an exact Fourier x-update.
//
//     x̂ = argmin_x  ½ Σ_i ||W_i^½ (y_i − A_i x)||²  +  μ TV(x)   [+ ι(x ≥ 0)],
//
//     TV(x) = Σ_p ||(∇x)_p||₂ = Σ_p sqrt((D_y x)_p² + (D_x x)_p²),
//
// with A_i = D_r ∘ H_i the shared forward model (core/forward_model.hpp), W_i the per-pixel inverse-variance
// weights of the ReconstructionProblem (problem.hpp: weight 0 masks a pixel, which may then hold NaN), and ∇
// the periodic forward-difference gradient of core/operators.hpp (Gradient(hr, Boundary::kPeriodic)), the
// same boundary the Fourier model assumes. Unlike Tikhonov's ||∇x||², the TV prior charges an edge by its
// height, not its height squared, so piecewise-constant objects keep sharp edges; the price is an iterative
// solve.
//
// Splitting (ADMM, Boyd, Parikh, Chu, Peleato & Eckstein 2011, "Distributed optimization and statistical
// learning via the alternating direction method of multipliers", Found. Trends Mach. Learn. 3(1), §3).
// Introduce z = ∇x (2 values per pixel) and, with positivity, v = x; with the scaled duals u (for z) and
// s (for v), one penalty ρ > 0 and over-relaxation α (Boyd §3.4.3; α = 1 is plain ADMM), an iteration is
//
//   x ← argmin ½||y − Ax||²_W + ρ/2 ||∇x − z + u||² + ρ/2 ||x − v + s||²,  i.e. the linear system
//         (AᵀWA + ρ ∇ᵀ∇ + ρ_v I) x = AᵀW y + ρ ∇ᵀ(z − u) + ρ_v (v − s),   ρ_v = ρ with positivity, else 0;
//   ĝ ← α ∇x + (1 − α) z,                         v̂ ← α x + (1 − α) v;
//   z_p ← max(0, 1 − (μ/ρ) / ||ĝ_p + u_p||) (ĝ_p + u_p)   (isotropic shrinkage: the prox of (μ/ρ)||·||₂);
//   v ← max(0, v̂ + s);
//   u ← u + ĝ − z,                                 s ← s + v̂ − v.
//
// The x-update. With uniform weights (W = w I, problem.HasUniformWeights()) the system is block-diagonal
// in Fourier space like Tikhonov's (tikhonov.hpp): for each LR bin u, with A(u) the N x r² aliased system
// and P(u) = diag(4 sin²(π f_y/M_y) + 4 sin²(π f_x/M_x)) the symbol of ∇ᵀ∇ on the r² aliased HR bins,
//
//     (r² w A(u)ᴴA(u) + ρ P(u) + ρ_v I) X(f_·) = B(f_·),   B = DFT of the right-hand side,
//
// solved exactly by fourier_normal_system.hpp (Woodbury N x N form where N < r², factorised once per value of
// ρ), so an iteration costs two HR FFTs, m² small solves and one pixel-wise pass: the z- and v-updates with
// their duals, the next right-hand side (AᵀWy included) and every residual and stopping sum are formed in a
// single sweep over the image (total_variation.cpp), the array traffic that bounds this memory-bound step.
// With masked or varying weights (the normal case for measured and photon-noise data) the default splits the
// data term off (x_update kFourierSplit): ω = Ax is a further ADMM variable with a fixed penalty ρ_ω (the mean
// positive weight) and scaled dual t, so the x-update keeps the Fourier-exact system above at weight ρ_ω and
// the weights enter only a per-pixel update:
//
//   x ← (ρ_ω AᵀA + ρ∇ᵀ∇ + ρ_v I)⁻¹ (ρ_ω Aᵀ(ω − t) + ρ∇ᵀ(z − u) + ρ_v(v − s)),
//   â ← α Ax + (1 − α) ω,   ω ← (W∘y + ρ_ω(â + t)) / (W + ρ_ω),   t ← t + â − ω
//
// (Almeida & Figueiredo 2013, IEEE TIP 22(8), 3074). Ax comes out of the same per-bin solve, so an iteration
// costs the two HR FFTs plus 2N LR FFTs (each r² times smaller). kConjugateGradient instead solves the unsplit
// system (AᵀWA + ρ∇ᵀ∇ + ρ_v I) by unpreconditioned CG, warm-started: 4N HR FFTs per CG step and tens of steps
// per x-update; it is kept as the reference the split path is tested against.
//
// Convergence in practice (measured, 64x64 HR, r = 2 and 3, μ near its PSNR-best value): 300–400
// iterations to the default ε_rel = 1e-4, 1500–2000 to 1e-6, ADMM's usual slow linear tail. Small μ with
// noise-free data, or μ far above the noise level, converge more slowly (thousands to 1e-5). Time per
// iteration on one core of the 2-core development machine (reconstruct_bench's TV rows, N = 4, CPU time):
// about 1 ms at 256² (r = 2), 4 ms at 512² (r = 4), 20 ms at 1024² (r = 8) for the exact update.
//
// Stopping rule (Boyd §3.3.1), with K = [∇; I] (the I row only with positivity), ζ = (z, v); with the split
// data block its residuals join, scaled by ρ_ω/ρ into the gradient block's units, and its part of the dual
// residual is bounded by ρ_ω ||A||₂ ||ω − ω_prev|| (so the rule can only stop late, never early):
//     primal residual  r = ||K x − ζ||,            ε_pri  = √p ε_abs + ε_rel max(||K x||, ||ζ||),
//     dual residual    d = ρ ||Kᵀ(ζ − ζ_prev)||,   ε_dual = √n ε_abs + ε_rel ρ ||Kᵀ (u, s)||,
// p = number of constraint rows (2n, or 3n with positivity), n = HR pixels. Converged when r ≤ ε_pri and
// d ≤ ε_dual; optionally also when the relative change of x falls below change_tolerance.
// Adaptive ρ (residual balancing, Boyd §3.4.1, on the residuals normalised by their tolerances as in
// Wohlberg 2017, arXiv:1704.06209, so the balance is scale-free): when r/ε_pri exceeds `rho_balance` times
// d/ε_dual, ρ grows by `rho_factor` (and u, s shrink by it, keeping the unscaled duals ρu, ρs); in the
// opposite case ρ shrinks. The Fourier factors are then recomputed (cheap: m² small Cholesky). The
// number of changes is capped so that the classical fixed-ρ convergence guarantee applies in the end.
//
// API rules (for every function below):
//  * Images are on the model's HR grid, row-major (image.hpp); frames and weights follow problem.hpp.
//  * Bad arguments throw InvalidArgument naming the function and the argument (options: the field).
//  * Non-convergence is reported in the summary (Termination::kMaxIterations), not thrown. A non-finite
//    iterate ends the solve with Termination::kFailed and returns the last finite iterate: NaN is never
//    returned.
//  * No wall-time promise is made or tested; the summary records the time taken.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "aosr/core/forward_model.hpp"
#include "aosr/core/progress.hpp"
#include "aosr/solvers/fourier_normal_system.hpp"
#include "aosr/solvers/problem.hpp"
#include "aosr/solvers/summary.hpp"

namespace aosr {

// How the ADMM x-update system is solved ("execution is not maths": both give the same iterates up to
// the CG tolerance).
enum class TotalVariationXUpdate {
  kAuto,               // kFourier when problem.HasUniformWeights(), else kFourierSplit
  kFourier,            // exact per-frequency solve; InvalidArgument unless weights are uniform
  kFourierSplit,       // data term split off (ω = Ax), exact per-frequency x-update; any weights
  kConjugateGradient,  // matrix-free CG on (AᵀWA + ρ∇ᵀ∇ + ρ_v I), warm-started; any weights
};
const char* ToString(TotalVariationXUpdate x_update);

struct TotalVariationOptions {
  // TV weight μ >= 0, in the objective's units: (weight x frame units²) per object unit (an edge of
  // height h costs μ·h per HR pixel of its length). With inverse-variance weights (w = 1/σ²) the data
  // term counts misfits in noise units and μ is per object unit. There is no universal value; scan a
  // decade grid. Measured (total_variation_physics_test.cpp: unit weights, N = r² = 4, blocks with edges of
  // 0.4–1): the PSNR-best μ was ≈ 10σ² for frame noise σ = 0.05 and 0.1, i.e. μ ≈ 10 with w = 1/σ².
  // 0 leaves the (generally non-unique) least-squares problem. Default 1e-2: unit weights and frames of
  // order 1 with a few percent of noise, the regime of the tests.
  double mu = 1e-2;

  // Constrain x >= 0 (flux cannot be negative). Adds the v = x splitting; its two arrays join the
  // iteration's pixel pass. Off by default, like every other reconstructor in aosr.
  bool positivity = false;

  // Initial ADMM penalty ρ > 0 in the units of the data curvature (weight x frame²/object²), or 0
  // (the default) for the automatic value ρ₀ = tr(AᵀWA) / tr(∇ᵀ∇) = Σ_i Σ_p w_i[p] ||row of A_i||² / (4n):
  // the penalty at which the data and the splitting weigh alike in the x-update (for one unit-sum PSF,
  // N frames and unit weights ρ₀ = N ||b ⊛ h||² / (4 r²), b the r x r box). ρ changes the path, not the
  // optimum. ρ₀ ignores μ, while the fastest fixed ρ grows with it (measured ≈ 30–100 μ on the tests),
  // which is what adaptive_rho corrects.
  double rho = 0.0;

  // Residual balancing (see the top of this file). rho_balance (Boyd's μ, > 1) is the tolerated ratio of
  // the normalised residuals; rho_factor (Boyd's τ, > 1) the multiplicative step. At most
  // max_rho_updates changes are made (>= 0), so ρ is eventually fixed. Defaults 5, 2 and 50: Boyd's
  // τ = 2, and a balance tighter than his 10, which on the test problems (64x64 blocks, r = 2 and 3,
  // with and without positivity) took up to 20% fewer iterations to reach ε_rel = 1e-6, never more;
  // 2–3 made ρ oscillate and sometimes exhaust the updates far from a good value.
  bool adaptive_rho = true;
  double rho_balance = 5.0;
  double rho_factor = 2.0;
  int max_rho_updates = 50;

  // Over-relaxation α in [1, 1.9] (Boyd §3.4.3). 1 is plain ADMM. Default 1.6: it saved 15–35% of
  // the iterations on the same test problems, at no cost per iteration.
  double relaxation = 1.6;

  // Stopping rule: absolute tolerance ε_abs >= 0 in object units per constraint entry (it matters only
  // when the solution is ≈ 0, where a relative rule cannot be met), relative tolerance ε_rel in (0, 1).
  // The default ε_rel = 1e-4 (Boyd's suggestion) gave images within 1–3e-4 (relative L2) and objectives
  // within 1e-4 of the ε_rel = 1e-7 optimum on the test problems; use 1e-6 or below to compare optima.
  double absolute_tolerance = 1e-12;
  double relative_tolerance = 1e-4;
  // If > 0, also stop when ||x_k − x_{k−1}|| <= change_tolerance ||x_k||. Off (0) by default: a small
  // step is a weak certificate for ADMM, whose iterates can creep; the residual rule is the honest one.
  double change_tolerance = 0.0;
  // Iteration limit (>= 1); reaching it is Termination::kMaxIterations, with the current estimate.
  int max_iterations = 1000;

  // x-update path, and the CG controls when CG is used: relative residual tolerance in (0, 1) per
  // x-update (tight, because inexact x-updates put a floor under the ADMM residuals) and the per-update
  // CG iteration limit (>= 1). Warm starts make most updates take a handful of steps.
  TotalVariationXUpdate x_update = TotalVariationXUpdate::kAuto;
  double cg_tolerance = 1e-10;
  int cg_max_iterations = 200;

  // Record per-iteration residuals, tolerances, ρ and objective in the summary. The objective costs N
  // extra forward-model applications per iteration, so this is off by default.
  bool record_history = false;

  // Called after ADMM iterations (core/progress.hpp: at most every 0.2 s, always the first and the last) with
  // stage "tv", total = max_iterations and value = primal residual / its tolerance ("primal/tol", <= 1 once
  // the primal part of the stopping rule is met). Returning false stops after that iteration with
  // Termination::kUserCancelled and the current estimate. Empty (the default): not called, no cost; a
  // callback that returns true leaves the result bit-identical.
  ProgressCallback progress;

  // False, with `why` naming the offending field, when any field is outside its documented range.
  bool IsValid(std::string* why) const;
};

struct TotalVariationSummary : SolverSummary {
  // SolverSummary: method "tv"; final_cost = ½ Σ w (y − Ax̂)² + μ TV(x̂) at the returned x̂ (the positivity
  // indicator is 0 there: the returned x̂ is clipped to x̂ >= 0 when positivity is on);
  // frame_residual_rms from WeightedDataMisfit.
  double mu = 0.0;
  double data_misfit = 0.0;      // ½ Σ_i Σ_p w_i[p] (y_i − A_i x̂)²[p]
  double total_variation = 0.0;  // TV(x̂)
  // The last iteration's ADMM residuals and their tolerances (see the stopping rule above).
  double primal_residual = 0.0;
  double dual_residual = 0.0;
  double primal_tolerance = 0.0;
  double dual_tolerance = 0.0;
  double initial_rho = 0.0;  // ρ at the first iteration (given or automatic)
  double final_rho = 0.0;    // ρ at the last iteration
  int rho_updates = 0;       // number of ρ changes made by residual balancing
  TotalVariationXUpdate x_update = TotalVariationXUpdate::kFourier;  // the path actually used
  Index singular_bins = 0;  // Fourier path: bins whose x-update matrix was singular (pseudo-inverse used)
  int cg_iterations = 0;    // CG path: total CG steps over all x-updates
  int cg_unconverged = 0;   // CG path: x-updates that stopped at cg_max_iterations
  // With options.record_history: one entry per ADMM iteration.
  std::vector<double> history_primal, history_dual, history_primal_tolerance, history_dual_tolerance,
      history_rho, history_cost;
};

// TV(x) = Σ_p ||(∇x)_p||₂ with periodic forward differences.
double IsotropicTotalVariation(const Image& x);

// The TV objective ½ Σ_i ||W_i^½ (y_i − A_i x)||² + μ TV(x) at x (on the model's HR grid; the positivity
// indicator is not included). Validates the problem; mu >= 0.
double TotalVariationObjective(const ReconstructionProblem& problem, const Image& x, double mu);

// ADMM's whole state at the end of a run, to start another run on a nearby problem where it stopped: the next
// window of a video stream (video_stream.hpp), whose solution and duals differ from this one's by the frames'
// changes. Starting the duals there too, not only x, is what lets a few iterations per window stay close to the
// converged solution (bench/results/video.md measures both).
struct TotalVariationState {
  Image x;       // the last iterate, before the positivity clip
  Vector z, u;   // the gradient split (2 x HR pixels, ∂y then ∂x) and its scaled dual
  Vector v, s;   // the positivity split and its scaled dual (empty without positivity)
  double rho = 0;  // ρ at the end (the scaled duals are for this ρ); 0: no state
  bool empty() const { return !(rho > 0); }
  // The uniform-weight x-update's factorised system (FourierNormalSystem) and what it was built for: a next run on
  // the same model object with the same data weight and ρ reuses it instead of building it again. A run may
  // refactorise it, and copies of a state share it: do not run two copies at the same time (clear `cache` first).
  struct Cache {
    std::shared_ptr<const MultiFrameModel> model;
    double weight = 0, rho = 0, rho_v = 0;
    std::shared_ptr<FourierNormalSystem> system;
  } cache;
};

// Solves the problem above by ADMM. `initial` (optional) warm-starts x (HR shape, finite); otherwise
// x starts at 0. The splitting variables start consistent with it (z = ∇x, v = max(x, 0)) and the duals
// at 0. Returns x̂ (>= 0 when options.positivity).
// `state` (optional, in and out): if it holds a state (not empty) of the same HR shape and positivity setting,
// the run starts from it instead (x, z, u, v, s and its ρ, which then replaces options.rho; `initial` is not read);
// a state that does not fit is refused. On return it holds the run's final state, or is empty if the run failed.
Image TotalVariationAdmm(const ReconstructionProblem& problem, const TotalVariationOptions& options = {},
                         TotalVariationSummary* summary = nullptr, const Image* initial = nullptr,
                         TotalVariationState* state = nullptr);

}  // namespace aosr
