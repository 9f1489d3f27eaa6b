// Regularised maximum-a-posteriori (MAP) super-resolution, solved by L-BFGS (Ceres GradientProblem).
//
//     x̂ = argmin_x  F(x) = L(y | A x) + λ R(x),          A = MultiFrameModel::Operator()  (problem.hpp)
//
// The gradient is exact and matrix-free: ∇F = Aᵀ ∂L/∂(Ax) + λ ∇R, with A and Aᵀ applied by FFTs through the
// one shared forward model (no automatic differentiation over images). Every term below is ≥ 0, so Ceres'
// relative function tolerance is meaningful.
//
// Likelihoods (w = problem weights; a pixel of weight 0 is masked and never read; b = background):
//   kGaussian  weighted least squares          L = ½ Σ w (y − A x − b)²
//              ∂L/∂(Ax) = −w (y − A x − b).  w is an inverse variance (frame units⁻²).
//   kPoisson   shifted Poisson with read noise (Snyder, Hammoud & White 1993, JOSA A 10, 1014): in electrons,
//              y + σ² ~ Poisson(μ), μ = A x + b + σ² (σ = read_noise), whose negative log-likelihood is
//              Σ [μ − c log μ], c = max(y + σ², 0). We add the x-independent Σ [c log c − c], so that
//                                              L = Σ_{w>0} [μ − c − c log(μ/c)]     (μ − c where c = 0)
//              is half the Poisson deviance: ≥ 0, zero where μ = c, ≈ ½ Σ (y − Ax − b)² / μ at high counts.
//              ∂L/∂(Ax) = 1 − c/μ.  Weights only mask (w > 0 counts with weight 1): the noise model
//              supplies the variance. It needs μ > 0 on every unmasked pixel; positivity guarantees that
//              for non-negative PSFs because b + σ² > 0 is required. Without positivity the solver backs off
//              (line search) from steps that leave the domain, and a warm start outside it is an error;
//              but a pixel with c = 0 (y <= −σ²: zero counts without read noise, or a deep negative read-
//              noise excursion) pulls μ toward 0 with constant force, the infimum then lies on the domain's
//              boundary, and the solve typically ends kFailed in the line search. Use positivity.
//
// Priors R (∇ = periodic forward differences [D_y; D_x], core/operators.hpp, as the model is periodic;
// g_p = (∇x)_p is the gradient vector at pixel p, t_p = |g_p|):
//   kTikhonov       R = ½ ||Γ x||²,  Γ from tikhonov.hpp (identity, gradient or Laplacian); ∇R = ΓᵀΓ x.
//   kCharbonnierTv  R = Σ_p (sqrt(t_p² + ε²) − ε)          (→ total variation as ε → 0; smooth for ε > 0)
//                   ∇R = ∇ᵀ (g / sqrt(t² + ε²)).
//   kHuberTv        R = Σ_p ρ_δ(t_p),  ρ_δ(t) = t²/(2δ) for t ≤ δ,  t − δ/2 for t > δ
//                   ∇R = ∇ᵀ (g / max(t, δ)).  Quadratic (Tikhonov-like, curvature 1/δ) below δ, total
//                   variation above; ρ is C¹ with a Lipschitz gradient. This is the classical Huber function
//                   divided by δ, so that both TV priors have unit slope for large gradients and one λ means
//                   the same in both: ε and δ play the same role (the gradient magnitude below which the
//                   prior smooths rather than preserves edges), in flux per HR pixel.
//
// λ convention. With kGaussian, b = 0, kTikhonov and no positivity, F(x) = ½ [Σ w (y − Ax)² + λ ||Γx||²],
// one half of tikhonov.hpp's objective with the same weights (TikhonovFourier: unit weights). The same λ
// therefore gives the same minimiser (tested against TikhonovFourier to 1e-5 relative; measured 1e-7).
// R is in flux² for kTikhonov and in flux (per HR pixel, summed) for the TV priors, so λ values do not
// carry over between them.
//
// Positivity by reparameterisation (Ceres 2.1's GradientProblemSolver has no bounds). With kSoftplus the
// solver works on z ∈ ℝⁿ and
//
//     x = s · softplus(z / s) = s · log(1 + exp(z / s)),     ∂F/∂z_p = σ(z_p / s) · ∂F/∂x_p,
//
// σ(t) = 1 / (1 + e^{−t}) the logistic function (the chain rule is applied pixel-wise to the x-gradient).
// Why softplus: it is a smooth bijection ℝ → (0, ∞), so it adds no stationary points (x = z² makes z = 0
// stationary for every pixel and doubles every minimum); and it is the identity (up to e^{−z/s}) for
// x ≫ s, so bright pixels see the unconstrained curvature, where x = exp(z) rescales the Hessian by x² and
// freezes faint pixels relative to bright ones over an astronomical dynamic range. Only pixels with x ≲ s
// are compressed. s does not move the minimiser (x → 0 is approached as z → −∞ for any s); it sets where
// the compression starts. Cost: a pixel whose constrained optimum is 0 is approached as s·e^{z/s}, slowly.
//
// Conventions written once: images are flux per HR pixel on model->hr_shape(); frames in frame units
// (electrons for kPoisson); non-convergence is reported in the summary, not thrown; bad input throws
// InvalidArgument naming the argument before Ceres is called (Ceres aborts on misuse).
#pragma once

#include <string>

#include "aosr/core/progress.hpp"
#include "aosr/solvers/problem.hpp"
#include "aosr/solvers/summary.hpp"
#include "aosr/solvers/tikhonov.hpp"

namespace aosr {

enum class MapLikelihood { kGaussian, kPoisson };
enum class MapPrior { kTikhonov, kCharbonnierTv, kHuberTv };
enum class MapPositivity { kNone, kSoftplus };
// Preconditioning of L-BFGS by a change of variables z = C u, C = M^(-1/2) a Fourier multiplier, M(f) the
// Fourier diagonal of the objective's curvature at the start (see MapOptions::preconditioner).
enum class MapPreconditioner { kNone, kFourier };

const char* ToString(MapLikelihood l);
const char* ToString(MapPrior p);
const char* ToString(MapPositivity p);
// "gaussian" | "poisson";  "tikhonov" | "charbonnier-tv" | "huber-tv";  "none" | "softplus".
// InvalidArgument otherwise.
MapLikelihood ParseMapLikelihood(const std::string& name);
MapPrior ParseMapPrior(const std::string& name);
MapPositivity ParseMapPositivity(const std::string& name);

struct MapOptions {
  // --- The objective -------------------------------------------------------------------------------------
  MapLikelihood likelihood = MapLikelihood::kGaussian;
  // Read-noise RMS σ_r in electrons, >= 0. Used by kPoisson only (the Gaussian weights carry the variance).
  double read_noise = 0.0;
  // Background b added to every modelled LR pixel (frame units, electrons for kPoisson), >= 0. 0 suits
  // background-subtracted frames. kPoisson needs b + read_noise² > 0 (the log needs a floor: for a
  // photon-counting detector with neither, set read_noise to e.g. 0.1 e⁻).
  double background = 0.0;

  // Default: Charbonnier TV, the edge-preserving prior that is the reason to run MAP after Tikhonov.
  MapPrior prior = MapPrior::kCharbonnierTv;
  // Γ of kTikhonov (ignored by the TV priors). Default: gradient, as in TikhonovOptions.
  TikhonovPrior tikhonov_operator = TikhonovPrior::kGradient;
  // Regularisation weight λ >= 0 (finite), in units of the likelihood per unit of R (see the λ convention
  // above). 0 gives the (positivity-constrained) maximum-likelihood estimate.
  double lambda = 1e-2;
  // kCharbonnierTv smoothing ε > 0 and kHuberTv threshold δ > 0, in flux per HR pixel (units of the image
  // gradient). Gradients well above ε/δ are treated as edges (TV), well below as smooth (quadratic). Take
  // them below the edge heights to preserve and near the noise in the gradient. The defaults suit images of
  // order-unity flux per HR pixel; scale them with the flux.
  double epsilon = 1e-2;
  double delta = 1e-2;

  // Default: none, so that the default objective is the convex one with the known Fourier oracle when the
  // prior is Tikhonov; astronomical images with sky near zero should use kSoftplus (kPoisson especially).
  MapPositivity positivity = MapPositivity::kNone;
  // Softplus scale s in flux per HR pixel (> 0), or 0 (default) for automatic: s = 0.01 x̄ with x̄ the mean
  // flux per HR pixel implied by the data, Σ_{w>0}(y − b) / (count · r²) (unit-sum PSFs), or 1 if x̄ ≤ 0.
  // Pixels below ~s are compressed (see above); the value does not move the minimiser.
  double softplus_scale = 0.0;

  // --- The solver (Ceres GradientProblemSolver, L-BFGS directions, Wolfe line search) ---------------------
  // Iteration limit, >= 1. Ceres' own default (50) is far too few for an image; an L-BFGS iteration costs
  // about 2(N+1) FFTs plus 1-2 more evaluations on average in the line search.
  int max_iterations = 500;
  // Stop when |ΔF| <= function_tolerance · F over an iteration (Ceres' rule; in [0, 1)).
  double function_tolerance = 1e-10;
  // Stop when max_p |∂F/∂z_p| <= gradient_tolerance · max_p |∂F/∂z_p| at the warm start, i.e. relative to
  // the initial gradient so that the rule does not depend on the flux units (Ceres' rule is absolute; we
  // scale it). In [0, 1).
  double gradient_tolerance = 1e-8;
  // Stop when |Δz| <= parameter_tolerance · (|z| + parameter_tolerance) (Ceres' rule; in [0, 1)).
  double parameter_tolerance = 1e-10;
  // L-BFGS memory (Ceres max_lbfgs_rank), in 1..1000. 20 is Ceres' default; more rarely pays on images.
  int lbfgs_memory = 20;
  // Oren's scaling of the initial inverse Hessian (Ceres use_approximate_eigenvalue_bfgs_scaling; Ceres'
  // default is off). On: without positivity (64 x 64 HR, Tikhonov and both TV priors) it changes the
  // iteration count by under 10% either way, but with softplus and a sharp TV prior (the low-count Poisson
  // test) the unscaled L-BFGS stalls (zero line-search step) at a cost 0.3% above the scaled run's minimum,
  // relative error 0.338 instead of 0.331.
  bool lbfgs_eigenvalue_scaling = true;
  // kFourier: L-BFGS runs on u with z = C u, C = M^(-1/2) applied by FFTs, where M(f) is the diagonal of the
  // objective's curvature in Fourier space at the warm start:
  //   M(f) = w̄ Σ_i |B(f) H_i(f)|² / r²  +  λ κ P(f)  (+ a floor of 1e-12 max M),
  // w̄ the mean positive weight (kPoisson: the mean of 1/max(c, 1)), P the symbol of the prior's ΓᵀΓ (∇ᵀ∇ for
  // the TV priors), κ = 1 for kTikhonov and, for the TV priors, the median over pixels of their curvature
  // φ'(t)/t at the warm start (1/sqrt(t² + ε²), 1/max(t, δ)). The objective and its minimiser are unchanged;
  // the problem L-BFGS sees is better scaled (the data term's curvature spans the OTF's dynamic range).
  // Costs 4 HR FFTs per evaluation. The iteration count and the tolerances then refer to u. Default kFourier:
  // measured on paper-sim-r4 (512², r = 4, N = 4, the automatic λ), it lowered F after 10 and 30 iterations
  // (PSNR 22.80 -> 23.03 dB and 23.73 -> 24.73 dB); κ scaled by 0.1 or 10 changed F at 30 iterations by < 0.2 %.
  MapPreconditioner preconditioner = MapPreconditioner::kFourier;

  // Called after L-BFGS iterations (a Ceres IterationCallback; core/progress.hpp: at most every 0.2 s, always
  // the first and the last) with stage "map", total = max_iterations and value = F ("cost"). Returning false
  // stops after that iteration with Termination::kUserCancelled and that iterate. Empty (the default): not
  // called, no cost; a callback that returns true leaves the result bit-identical. Callers that run solves
  // in parallel (design_empirical.hpp's objective B, one MAP per training pair) must leave it empty: it would
  // be called from several threads at once.
  ProgressCallback progress;

  // False (and *why names the field, if why is non-null) unless every field is in its documented range.
  bool IsValid(std::string* why) const;
};

struct MapSummary : SolverSummary {
  // SolverSummary: method "map"; termination kConverged (Ceres CONVERGENCE), kMaxIterations (Ceres
  // NO_CONVERGENCE), kUserCancelled (options.progress returned false) or kFailed (Ceres FAILURE, a non-finite
  // cost or gradient anywhere — then the returned image is the lowest-cost finite iterate — or a non-finite
  // objective at the warm start, when Ceres is not run and the warm start is returned); message = Ceres'
  // BriefReport and its termination reason; final_cost = F at the returned image; frame_residual_rms over
  // each frame's unmasked pixels of y − Ax − b.
  double initial_cost = 0.0;           // F at the warm start (after the positivity floor, if any)
  double data_cost = 0.0;              // L(y | Ax) at the returned image
  double prior_cost = 0.0;             // λ R(x) at the returned image
  double softplus_scale = 0.0;         // s used (0 without positivity)
  Index warm_start_pixels_raised = 0;  // warm-start pixels below s·ln 2 started at x = s·ln 2 (z = 0)
  int cost_evaluations = 0;            // objective evaluations without gradient (Ceres line search)
  int gradient_evaluations = 0;        // objective evaluations with gradient
};

struct MapResult {
  Image image;  // the estimate on model->hr_shape(); always finite
  MapSummary summary;
};

// The objective in the solver's variables z (z = x without positivity), exposed for tests (Taylor test of
// the gradient) and for callers that want F itself. Immutable; Evaluate is thread-safe.
class MapObjective {
 public:
  struct Value {
    double total = 0.0;     // F = data + prior
    double data = 0.0;      // L(y | A x)
    double prior = 0.0;     // λ R(x)
    bool in_domain = true;  // false: kPoisson with μ = Ax + b + σ² <= 0 at an unmasked pixel
    bool finite = true;     // total (and the gradient, if requested) finite
    bool ok() const { return in_domain && finite; }
  };

  // Validates the problem and options (InvalidArgument naming the field otherwise) and keeps what it needs.
  MapObjective(const ReconstructionProblem& problem, const MapOptions& options);

  Index num_parameters() const { return hr_.size(); }
  Shape hr_shape() const { return hr_; }
  double softplus_scale() const { return scale_; }  // s, 0 without positivity

  // F(z) and, if gradient is non-null, ∇_z F (resized to num_parameters()). Outside the domain the value is
  // +∞ and the gradient is not computed.
  Value Evaluate(const Eigen::Ref<const Vector>& z, Vector* gradient = nullptr) const;
  // x(z) as an image.
  Image ToImage(const Eigen::Ref<const Vector>& z) const;
  // z(x). With positivity, pixels below s·ln 2 (including negative ones) map to z = 0 (x = s ln 2); their
  // number is written to *raised if non-null. x must be finite and of the HR shape.
  Vector ToParameters(const Image& x, Index* raised = nullptr) const;
  // Per-frame RMS of y − A x − b over each frame's unmasked pixels of `region` (problem.hpp; frame units; 0
  // for a fully masked frame).
  std::vector<double> FrameResidualRms(const Image& x, const LrRegion& region = {}) const;

 private:
  MapOptions options_;
  OperatorPtr a_;      // stacked forward model
  OperatorPtr gamma_;  // Γ (kTikhonov, non-identity) or ∇ (TV priors); null for the identity
  Shape hr_;
  int frames_ = 0;
  Shape lr_;
  Index lr_size_ = 0;
  Vector y_;            // stacked frames, masked pixels set to 0
  Vector w_;            // stacked weights (kPoisson: 0/1 mask)
  Vector c_;            // kPoisson: max(y + σ², 0) on unmasked pixels, else 0
  double scale_ = 0.0;  // softplus scale s
};

// Solves the MAP problem from `warm_start` (flux per HR pixel, HR shape, finite; e.g. the Tikhonov solution).
// An empty warm start (0 x 0) starts from the flat image x̄ (see softplus_scale), or 0 if x̄ ≤ 0.
// Throws InvalidArgument on invalid options, problem or warm start (and, for kPoisson without positivity,
// a warm start with Ax + b + σ² <= 0 on an unmasked pixel); never returns a non-finite image.
MapResult MapReconstruct(const ReconstructionProblem& problem, const MapOptions& options,
                         const Image& warm_start = Image());

}  // namespace aosr
