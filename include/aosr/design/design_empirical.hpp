// Phase design, part 2b: objective B, the empirical one. The mean reconstruction loss of the MAP reconstructor
// (map.hpp) over K training scenes x R sampled AO PSF realisations, as a function of the N DM offsets, with its
// exact gradient by implicit differentiation of the MAP optimality condition. Slower than objective A
// (design_objective.hpp) and not a closed form: it judges a design by what the non-linear, edge-preserving
// reconstructor actually makes of it, in the loss of the paper (L1), so it confirms or refines A's optimum.
//
// ## The model
//
// The same periodic M x M HR grid, optics and PSFs as objective A (design_psf.hpp's DesignPsfModel: one PSF
// computation, one pull-back). Exposure i's nominal system A0_i = D_r ∘ H0_i (analytic-AO long exposure, what
// the reconstructor uses) and realised systems A_{ρ,i} = D_r ∘ H_{ρ,i} (what makes the frames; A_ρ = A0 when
// R = 0), D_r the r x r box sum, forward_model.hpp. Training scenes x_k (k = 0 .. K−1, M x M, flux per HR
// pixel) are given (DefaultTrainingScenes, TrainingScenesFromFiles). For every pair (k, ρ), P = K·max(R, 1)
// pairs in all, the frames are
//     y_{k,ρ} = A_ρ x_k + n_{k,ρ},    n_{k,ρ} ~ N(0, σ² I) per LR pixel, drawn once at construction (seeded),
// so that J below is a deterministic, smooth function of the design (a sample-average approximation).
//
// ## The reconstructor and the loss
//
//     x̂_{k,ρ} = argmin_x F(x) = ½ Σ_i ||y_i − A0_i x||² / σ² + λ R(x)            (map.hpp, weights 1/σ²)
//
// with R the Charbonnier TV prior (default; Σ_p sqrt(|∇x|_p² + ε²) − ε) or the Tikhonov prior ½||Γx||²,
// fixed λ and ε, Gaussian likelihood, and *no positivity*: the softplus map would make F non-convex in x
// (x̂ is then a minimiser of a reparameterised problem whose Hessian is not H below), and a pixel pinned at
// the boundary makes x̂ a non-smooth function of the design, while implicit differentiation needs x̂ to be a
// smooth function of w with an invertible Hessian. Without positivity F is strictly convex (the data term
// sees the mean: unit-sum PSFs pass f = 0; the prior is convex and strictly so off its null space), so x̂ is
// unique and smooth in w. The loss, averaged over the M² pixels and the P pairs:
//     J(w) = (1/P) Σ_{k,ρ} ℓ(x̂_{k,ρ}, x_k),   ℓ(x̂, x) = (1/M²) Σ_p φ(x̂_p − x_p),
//     φ(e) = e² (kL2)   or   φ(e) = sqrt(e² + η²) − η (kL1: Charbonnier-smoothed L1, → |e| as η → 0).
//
// ## The gradient (implicit differentiation; adjoint by CG)
//
// At x̂, g(x̂; w) = ∇_x F = A0ᵀ W (A0 x̂ − y) + λ ∇R(x̂) = 0, W = I/σ². Differentiating, H dx̂ = −∂g/∂w dw with
//     H = ∇²_x F(x̂) = A0ᵀ W A0 + λ ∇²R(x̂),
//     ∇²R = ΓᵀΓ (Tikhonov);  ∇²R = ∇ᵀ B ∇,  B_p = I/ρ_p − g_p g_pᵀ/ρ_p³,  g_p = (∇x̂)_p, ρ_p = sqrt(|g_p|² + ε²)
// (Charbonnier; B_p has eigenvalues 1/ρ_p and ε²/ρ_p³ > 0). H is symmetric positive definite (A0 sees the
// constants, ∇ᵀB∇ is positive on their complement), so with the adjoint v = H⁻¹ ∂ℓ/∂x̂ (conjugate gradients,
// the exact Hessian-vector product above),  dJ = −vᵀ (∂g/∂w) dw. With e = A0 x̂ − y the residual and
// y = A_ρ x + n:
//     −vᵀ dg = −⟨dA0 v, W e⟩ − ⟨W A0 v, dA0 x̂⟩ + ⟨W A0 v, dA_ρ x⟩.
// Each term is ⟨D_r(dH_i ⊙ U), z⟩ for an HR image u and an LR image z (Fourier: ⊙ acts on spectra). With the
// unnormalised DFT X = DFT(x) and Parseval, ⟨D_r IDFT(dH ⊙ U), z⟩ = (1/M²) Re Σ_f dH(f) U(f) conj(Z↑(f)),
// Z↑ = DFT(D_rᵀ z) (D_rᵀ replicates an LR pixel over its r x r block), so in the Wirtinger convention of
// design_psf.hpp (dJ = Re Σ conj(Γ_H) dH) each pair adds, for every exposure i,
//     Γ_{H0,i}   += −(1/(P M²)) [conj(V) DFT(D_rᵀ W e_i) + conj(X̂) DFT(D_rᵀ W (A0 v)_i)],
//     Γ_{H_ρ,i}  += +(1/(P M²)) conj(X_k) DFT(D_rᵀ W (A0 v)_i)          (to Γ_{H0,i} when R = 0),
// (v, x̂ here for ∂ℓ/∂x̂ without the 1/P, which is written out). DesignPsfModel::PullBack takes these to
// ∂J/∂w_i through T, the PSF normalisation, the MFT adjoint and the pupil phase. Taylor tests check the whole
// chain for every parameterisation, with and without PSF mismatch (design_empirical_test.cpp).
//
// ## Solving to a tolerance that does not depend on history
//
// The gradient formula holds at the exact minimiser; an inexact x̂ makes J and ∂J wrong to first order in
// ∇F(x̂). Each pair is therefore solved until ||∇F(x̂)||₂ <= map_tolerance · ||∇F(0)||₂, the reference
// ||∇F(0)|| = ||A0ᵀ W y|| being fixed by the data and the design, never by the starting point: from a cold
// start by MapReconstruct (Ceres L-BFGS, the project's MAP solver) and then Newton-CG steps with the exact
// Hessian above (inexact Newton, forcing term min(0.5, sqrt(||∇F||/||∇F(0)||)), backtracking line search),
// which reach 1e-12 in a few steps where L-BFGS stalls; from a warm start (warm_start = true: the x̂ of the
// same pair at the previous evaluation, a few Newton steps away for the small design steps of an optimiser)
// by Newton-CG directly, falling back to the cold path if Newton does not converge. Since F is strictly
// convex the minimiser is unique, so the history (which warm start) moves J only within the tolerance
// (tested: J at a design after visiting others equals a fresh objective's J to 1e-10 relative).
//
// Outcomes are data: EvaluateWithReport returns per pair the MAP and adjoint iterations, the final relative
// gradient of F and the adjoint's relative residual ||Hv − ∂ℓ/∂x̂|| / ||∂ℓ/∂x̂||. A pair whose MAP solve or
// adjoint solve missed its tolerance makes the evaluation not ok: the report says which and why, and the
// gradient is not written. Evaluate (DesignCriterion) throws NumericalError with that message instead, so
// a wrong gradient never reaches the optimiser silently (design_optimizer.hpp treats it as a failed step).
//
// Cost per evaluation (N frames, P pairs): the PSFs of objective A, plus per pair one MAP solve (a cold one:
// hundreds of L-BFGS iterations of 2N FFT pairs of M x M; a warm one: a few Newton steps of tens to hundreds
// of CG iterations) and one adjoint CG solve, each iteration one Hessian-vector product (2N FFTs of M x M plus
// the prior). Pairs run on `threads` threads. Measured on the paper's system (paper-sim-r2: M = 64, N = 4,
// r = 2, R = 2, one thread, defaults): a warm evaluation with gradient takes 0.8-2.3 s for K = 2 (4 pairs),
// 1.8 s for K = 3, 2.7 s for K = 4, the spread set by how far the optimiser stepped (Newton steps per pair);
// `aosr design ... --param tiptilt --objective B --training-scenes K --starts 1 --iterations 1 --threads 1`
// prints it as "last evaluation".
//
// API rules: constructors validate their inputs and options (InvalidArgument naming the field). Evaluate is
// const and thread-safe; it updates only the warm-start cache (under a lock), which changes J by no more than
// the tolerance.
#pragma once

#include <cstdint>
#include <mutex>
#include <string>
#include <vector>

#include "aosr/core/image.hpp"
#include "aosr/design/design_psf.hpp"
#include "aosr/solvers/conjugate_gradient.hpp"
#include "aosr/solvers/map.hpp"
#include "aosr/solvers/summary.hpp"

namespace aosr {

enum class DesignLoss { kL2, kL1 };
const char* ToString(DesignLoss loss);
// "l2" | "l1"; InvalidArgument otherwise.
DesignLoss ParseDesignLoss(const std::string& name);

// K dead-leaves scenes (scene/dead_leaves.hpp) on `hr`: radii 1 .. side/4 HR pixels, grey levels in [0, 1),
// scene k seeded DeriveSeed(seed, k). count in 1 .. 64.
std::vector<Image> DefaultTrainingScenes(Shape hr, int count, std::uint64_t seed = 1);

// Training scenes from image files (io/image_io.hpp via scene/image_object.hpp): of each file the centred
// square window of zoom·M source pixels (the whole short side if the file is smaller), area-resampled onto
// M x M and scaled to a peak of 1 (negatives clipped). zoom > 0: 1 keeps the file's pixels as HR pixels (the
// fine detail a super-resolution design is about); larger zooms show more of the picture, coarser. IoError or
// InvalidArgument naming the path.
std::vector<Image> TrainingScenesFromFiles(const std::vector<std::string>& paths, Shape hr, double zoom = 1.0);

struct EmpiricalDesignOptions {
  // The K training scenes, each M x M (the design grid), finite; 1 .. 64 of them. Required.
  std::vector<Image> training_scenes;
  // σ per LR pixel, frame units (the frames sum r x r HR pixels of flux), > 0 and finite. Default 0.04: 1% of
  // the brightest LR pixel of a scene of peak 1 at r = 2 (the paper's noise, 1% of the peak).
  double noise_sigma = 0.04;
  std::uint64_t noise_seed = 1;  // of the noise draws n_{k,ρ} (pair p draws from DeriveSeed(noise_seed, p))
  // The MAP reconstructor: prior kCharbonnierTv (default) or kTikhonov (identity, gradient, Laplacian), λ >= 0,
  // ε > 0; likelihood kGaussian, positivity kNone and background 0 are required (see the top of the file).
  // map.max_iterations and its tolerances drive the cold-start L-BFGS. Defaults: λ = 1 (with the weights
  // 1/σ², reconstruct.hpp's automatic rule λ = 2μ = 2 · 0.5 · ρ √w̄ with ρ √w̄ ≈ 1) and ε = 1e-2 (1% of a
  // peak-1 scene: edges are TV, the noise quadratic); 300 L-BFGS iterations.
  MapOptions map = [] {
    MapOptions m;
    m.lambda = 1.0;
    m.epsilon = 1e-2;
    m.max_iterations = 300;
    return m;
  }();
  // The loss; η of kL1 in flux per HR pixel, > 0 (the loss is quadratic below η). Default L1 (the paper's) with
  // η = 1e-3, a tenth of a percent of a peak-1 scene.
  DesignLoss loss = DesignLoss::kL1;
  double loss_epsilon = 1e-3;
  // AO PSF realisations R (0: the frames follow the nominal model), screens per exposure L, their seed and
  // threads (over PSFs and over pairs; results do not depend on it): as objective A. Defaults 2, 4, 1, 1.
  int realisations = 2;
  int screens = 4;
  std::uint64_t seed = 1;
  int threads = 1;
  // MAP accuracy: ||∇F(x̂)|| <= map_tolerance ||∇F(0)||, in (0, 1e-3]. Default 1e-10 (J then to ~1e-10
  // relative; a Taylor test needs about that). Newton steps per solve, 1 .. 1000 (default 50), each a CG solve
  // of at most newton_cg_iterations iterations (>= 1, default 2000).
  double map_tolerance = 1e-10;
  int newton_iterations = 50;
  int newton_cg_iterations = 2000;
  // The adjoint solve H v = ∂ℓ/∂x̂: relative residual tolerance in (0, 1) and iteration cap. Default 1e-10, 5000.
  ConjugateGradientOptions adjoint = {5000, 1e-10};
  // Start each pair's MAP solve from its x̂ of the previous evaluation. Default true.
  bool warm_start = true;

  bool IsValid(std::string* why) const;
};

// One (scene, realisation) pair of an evaluation.
struct EmpiricalPairReport {
  int scene = 0;
  int realisation = 0;        // 0 when R = 0
  bool warm_started = false;
  int lbfgs_iterations = 0;   // of MapReconstruct (0 if not run)
  int newton_steps = 0;
  int newton_cg_iterations = 0;
  double map_gradient = 0.0;  // ||∇F(x̂)|| / ||∇F(0)||
  bool map_converged = false;
  int adjoint_iterations = 0;
  double adjoint_residual = 0.0;  // ||H v − ∂ℓ/∂x̂|| / ||∂ℓ/∂x̂|| (0 without a gradient)
  bool adjoint_converged = true;
  double loss = 0.0;          // ℓ(x̂, x_k)
  std::string message;        // empty, or what went wrong
};

struct EmpiricalEvaluation {
  double objective = 0.0;  // J (the mean loss); meaningful only when ok
  bool ok = true;          // every MAP solve and adjoint solve met its tolerance
  std::string message;     // the first failure, or a one-line summary
  bool gradient = false;   // a gradient was asked for (and, if ok, written)
  std::vector<EmpiricalPairReport> pairs;
  double max_map_gradient = 0.0;
  double max_adjoint_residual = 0.0;
  double seconds = 0.0;
  // "J = 1.234e-2 over 6 pairs (warm 6), MAP |∇F| <= 3e-12 (newton 14, lbfgs 0), adjoint residual <= 8e-11
  // (412 CG iterations), 0.81 s".
  std::string BriefReport() const;
};

class EmpiricalDesignObjective : public DesignCriterion {
 public:
  // frames N >= 1. Throws InvalidArgument naming the bad argument, optics field or option.
  EmpiricalDesignObjective(const DesignOptics& optics, int frames, const EmpiricalDesignOptions& options);

  // Evaluate(dm_opds, grad) (DesignCriterion): J and ∂J/∂w_i; throws NumericalError (the report's message) when
  // a solve missed its tolerance. EvaluateWithReport never throws for that: it reports, and writes *grad (if
  // non-null) only when the evaluation is ok (otherwise grad is cleared).
  EmpiricalEvaluation EvaluateWithReport(const std::vector<Image>& dm_opds, std::vector<Image>* grad = nullptr) const;

  // The frames y_{k,ρ} of these offsets (pair p = k·max(R,1) + ρ; N frames each), and the systems.
  std::vector<ImageStack> Frames(const std::vector<Image>& dm_opds) const;
  MultiFrameModel NominalModel(const std::vector<Image>& dm_opds) const;
  std::vector<MultiFrameModel> RealisedModels(const std::vector<Image>& dm_opds) const;
  // x̂ of every pair at these offsets (solved as Evaluate does; the warm starts are used and updated).
  std::vector<Image> Reconstructions(const std::vector<Image>& dm_opds) const;

  // Forget the warm starts (the next evaluation solves from cold).
  void ResetWarmStarts() const;
  // The report of the last evaluation that finished.
  EmpiricalEvaluation last_evaluation() const;

  int frames() const override { return psf_.frames(); }
  int realisations() const override { return psf_.realisations(); }
  const DesignOptics& optics() const override { return psf_.optics(); }
  double invisible_floor() const override;  // NaN: a loss over scenes has no design-independent floor we know
  const char* method() const override { return "empirical-map-loss"; }
  int pairs() const { return int(noise_.size()); }
  const EmpiricalDesignOptions& options() const { return options_; }
  const DesignPsfModel& psf_model() const { return psf_; }

 private:
  double EvaluateImpl(const std::vector<Image>& dm_opds, std::vector<Image>* grad) const override;
  EmpiricalEvaluation Run(const std::vector<Image>& dm_opds, std::vector<Image>* grad,
                          std::vector<Image>* reconstructions) const;

  EmpiricalDesignOptions options_;
  DesignPsfModel psf_;
  std::vector<ComplexImage> scene_spectra_;  // DFT(x_k)
  std::vector<ImageStack> noise_;            // n_{k,ρ}, [pair][frame]
  mutable std::mutex mutex_;
  mutable std::vector<Image> warm_;          // x̂ of each pair at the last evaluation (empty: none)
  mutable EmpiricalEvaluation last_;
};

}  // namespace aosr
