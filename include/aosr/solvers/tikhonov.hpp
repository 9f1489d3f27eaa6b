// Tikhonov (regularised least-squares) super-resolution, solved exactly in Fourier space.
//
//     x̂ = argmin_x  Σ_i ||y_i − D_r(h_i ⊛ x)||²  +  λ ||Γ x||²
//
// With periodic boundaries (forward_model.hpp) the problem separates over the m_y·m_x LR frequency bins
// u: each couples the r² aliased HR bins f_k = u + k∘m through the N x r² matrix A(u), and with
// P(u) = diag(|Γ̂(f_k)|²) Parseval gives, per bin,
//
//     (A(u)ᴴ A(u) + (λ / r²) P(u)) X(f_·) = A(u)ᴴ Y(u).
//
// (The λ/r² is the ratio of the HR and LR Parseval factors.) Each bin is an r² x r² Hermitian solve:
// exact, no iterations, O(m² r⁶) plus N+1 FFTs. Where the system is singular (λ = 0 and A(u) rank
// deficient, or a prior null space that the data do not see), the minimum-norm solution is returned and
// the summary counts the HR frequencies the data leave unconstrained: they are reported, not filled.
//
// Priors Γ (all periodic, so they are Fourier-diagonal):
//   kIdentity   Γ = I                      |Γ̂|² = 1
//   kGradient   Γ = forward differences    |Γ̂|² = 4 sin²(π f_y/M_y) + 4 sin²(π f_x/M_x)
//   kLaplacian  Γ = ∇ᵀ∇ (5-point)          |Γ̂|² = (4 sin²(π f_y/M_y) + 4 sin²(π f_x/M_x))²
#pragma once

#include <string>

#include "aosr/core/forward_model.hpp"
#include "aosr/solvers/summary.hpp"

namespace aosr {

enum class TikhonovPrior { kIdentity, kGradient, kLaplacian };
const char* ToString(TikhonovPrior p);
// Parses "identity" | "gradient" | "laplacian"; InvalidArgument otherwise.
TikhonovPrior ParseTikhonovPrior(const std::string& name);

// How λ is chosen: as given, or by generalised cross-validation (GCV; Golub, Heath & Wahba 1979,
// Technometrics 21, 215), which needs no noise estimate and is computed exactly per frequency bin.
enum class TikhonovLambdaRule { kFixed, kGcv };

struct TikhonovOptions {
  TikhonovPrior prior = TikhonovPrior::kGradient;
  TikhonovLambdaRule lambda_rule = TikhonovLambdaRule::kFixed;
  // Regularisation weight λ >= 0 for kFixed, in the units of the objective above (frame units squared
  // per prior unit squared). 0 gives the (minimum-norm) least-squares solution.
  double lambda = 1e-2;
  // kGcv searches λ = λ₀·10^t on a grid of t in [-gcv_decades, 0] with gcv_steps_per_decade points per
  // decade, where λ₀ = Σ_u tr(A(u)ᴴA(u)) / Σ_u tr P(u) is the scale at which data and prior weigh
  // alike. Each grid point costs one pass of per-bin solves. Defaults: 8 decades, 4 per decade.
  double gcv_decades = 8.0;
  int gcv_steps_per_decade = 4;
  // A singular value of A(u) below rank_tolerance × the largest singular value over all bins counts as
  // zero when reporting unconstrained frequencies. In (0, 1).
  double rank_tolerance = 1e-9;
  bool IsValid(std::string* why) const;
};

struct TikhonovSummary : SolverSummary {
  double lambda = 0.0;                  // the λ used (chosen by GCV or given)
  double gcv = 0.0;                     // GCV score at that λ (0 for kFixed)
  Index lr_bins = 0;                    // number of per-frequency systems solved
  Index rank_deficient_bins = 0;        // bins where rank A(u) < r²
  Index unconstrained_frequencies = 0;  // Σ_u (r² − rank A(u)): HR bins the data do not determine
};

// The regulariser Γ as an operator on the HR grid (for iterative solvers and tests).
OperatorPtr TikhonovPriorOperator(Shape hr, TikhonovPrior prior);
// |Γ̂(f)|² at full-spectrum HR bin (fy, fx).
double TikhonovPriorSymbol(TikhonovPrior prior, Shape hr, Index fy, Index fx);

// Solves the problem above. Frames must match model.lr_shape() and be finite.
Image TikhonovFourier(const MultiFrameModel& model, const ImageStack& frames, const TikhonovOptions& options,
                      TikhonovSummary* summary = nullptr);

}  // namespace aosr
