// Private to the library (not installed): the per-bin Fourier engine of tikhonov.hpp and the λ searches, shared
// by the Fourier path and the conjugate-gradient path (whose preconditioner is this engine's inverse), and used
// by design/design_empirical.cpp (objective B's preconditioner) and the tests.
#pragma once

#include <Eigen/Dense>
#include <chrono>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "aosr/core/forward_model.hpp"
#include "aosr/solvers/tikhonov.hpp"

namespace aosr::tikhonov_internal {

// |Γ̂|² on the full HR spectrum of grid `hr` (validated options).
Image PriorSymbolImage(const TikhonovOptions& options, Shape hr);

// Everything about a periodic model and a Fourier-diagonal prior that depends on neither λ nor the data:
// the N x r² systems A(u), the prior P(u) and the ranks. λ below is always the λ' of the *unweighted*
// objective ||y − Ax||² + λ'||Γx||² (tikhonov.hpp, (2) with w = λ'/r²).
class FourierSystem {
 public:
  FourierSystem(const MultiFrameModel& model, const Image& prior_symbol, double rank_tolerance,
                TikhonovBinSolver solver);

  // Data spectra (frames on the model's LR grid, finite).
  void SetData(const ImageStack& frames);

  struct Fit {
    double residual2 = 0;  // ||y − A x_λ||² (spatial units, Parseval-normalised)
    double dof = 0;  // n − tr H_λ = Σ_u (N − tr(A G⁻¹ Aᴴ)), residual degrees of freedom (only if asked)
    Index woodbury_bins = 0;
    // EvaluateSpectral with want_prior: η = ||Γ x_λ||² (spatial units) and dη/dλ (for the L-curve).
    double prior2 = 0;
    double dprior2 = 0;
  };
  Fit Evaluate(double lambda, bool want_trace) const;
  // The same residual and trace from one decomposition per bin (SetSpectralMethod), made on first use after SetData:
  // with
  // B(u) = A(u) P(u)^(-1/2) = U diag(s) Vᴴ and c = |Uᴴ Y(u)|², w = λ/r²,
  //   ||Y − A X||² = Σ_k (w / (s_k² + w))² c_k + ||(I − UUᴴ) Y||²,   N − tr H = Σ_k w / (s_k² + w) + (N − q),
  // q = min(N, r²): O(q) per bin and λ instead of a solve, so a λ rule may evaluate as often as it likes
  // (tikhonov.hpp, "λ rules"). Bins whose prior vanishes somewhere (the DC bin of the gradient and Laplacian
  // priors) are solved directly at each λ.
  // want_prior adds η = ||Γx||² = (1/(m² r²)) Σ_u Σ_k s_k² c_k/(s_k² + w)² and its derivative by λ,
  // dη/dλ = −(2/(m² r⁴)) Σ_u Σ_k s_k² c_k/(s_k² + w)³ (direct bins: −2 Re (Px)ᴴ G⁻¹ (Px) per bin).
  Fit EvaluateSpectral(double lambda, bool want_prior = false) const;
  // How EvaluateSpectral's per-bin decomposition is made. kEigen (default): the eigen-decomposition of the
  // whitened Gram matrix B Bᴴ (q x q, q = min(N, r²), after a Householder QR of B when N > r² so that the part of
  // Y no λ fits is a sum of squares), its small eigenvalues refined by Rayleigh-Ritz on B itself (tikhonov.cpp
  // says why that is as accurate as an SVD of B). kSvd: the SVD of B (the reference the tests compare with).
  // Setting it discards a decomposition already made.
  enum class SpectralMethod { kEigen, kSvd };
  void SetSpectralMethod(SpectralMethod method) {
    spectral_method_ = method;
    spectral_.reset();
  }
  Image Solve(double lambda, Fit* fit = nullptr) const;

  // G(u)⁻¹ for every bin (pseudo-inverse where singular; *proper = false then).
  std::vector<Eigen::MatrixXcd> Inverses(double lambda, bool* proper, Index* woodbury_bins) const;

  const MultiFrameModel& model() const { return model_; }
  double lambda0() const { return lambda0_; }  // Σ tr AᴴA / Σ tr P
  Index bins() const { return nb_; }
  Index deficient_bins() const { return deficient_; }
  Index unconstrained() const { return unconstrained_; }

 private:
  // Bin i of the flat per-bin arrays, seen as Eigen matrices (no copy): A(u) column-major N x r², the data
  // Y(u) and the prior P(u) on the r² aliases.
  struct BinView {
    Eigen::Map<const Eigen::MatrixXcd> a;
    Eigen::Map<const Eigen::VectorXcd> y;
    Eigen::Map<const Eigen::VectorXd> prior;
    bool prior_positive;
    int rank;
  };
  BinView View(Index bin) const;
  struct BinSolution {
    Eigen::VectorXcd x;
    double residual2 = 0;
    double dof = 0;  // N − tr(A G⁻¹ Aᴴ)
    bool woodbury = false;
  };
  enum class Path { kWoodbury, kNormal, kMinimumNorm };
  Path Choose(Index bin, double w) const;
  BinSolution SolveBin(Index bin, double w, bool want_trace) const;
  // SolveBin's Woodbury or normal-equations path on caller scratch (max(r⁴, N² + N) values) without
  // allocation; false where the Cholesky fails (the caller falls back as SolveBin does).
  bool SolveBinInPlace(Index bin, double w, Path path, Complex* x, Complex* scratch) const;
  Eigen::MatrixXcd InverseBin(Index bin, double w, bool* proper, bool* woodbury) const;

  // EvaluateSpectral's per-bin decomposition (empty until first use; `direct` lists the bins solved directly).
  // Flat, a fixed stride of q_max = min(N, r²) values per bin; q[i] of them are used (fewer where columns of B
  // below its rounding were dropped; the rest are directions B does not reach, counted in N − q).
  struct Spectral {
    int q_max = 0;
    std::vector<double> s2;     // s_k² of bin i at i·q_max
    std::vector<double> c;      // |u_kᴴ Y|², likewise
    std::vector<double> perp;   // ||(I − UUᴴ) Y||² per bin
    std::vector<int> q;         // values used per bin
    std::vector<char> weight;   // 2 for one bin of a mirror pair (the other copies it), 1 if self-mirror, else 0
    std::vector<Index> direct;  // bins with a zero of the prior (solved at each λ)
    // The same values as one stream of terms (the counted bins' q values in bin order) for the λ loop:
    // s², weight·c and weight; and the λ-independent parts Σ weight·perp and Σ weight·(N − q).
    std::vector<double> term_s2, term_wc, term_weight;
    double fixed_residual = 0, fixed_dof = 0;
  };
  void MakeSpectral() const;
  void DecomposeBinSvd(Index bin, Spectral* sp) const;
  void DecomposeBinEigen(Index bin, Spectral* sp, std::vector<double>* scratch) const;
  SpectralMethod spectral_method_ = SpectralMethod::kEigen;
  // The bin of −u (LR frequencies), and whether `bin` is the one of its pair {u, −u} that is computed (the
  // other is its conjugate: real frames, real PSFs, an even prior).
  Index MirrorBin(Index bin) const;
  bool CanonicalBin(Index bin) const;
  mutable std::unique_ptr<Spectral> spectral_;

  const MultiFrameModel& model_;
  TikhonovBinSolver solver_;
  // The per-bin data, flat (one allocation per quantity, bin-major, a fixed stride per bin): built in one pass
  // over blocks of bins, on DefaultThreads() threads, each block writing only its own bins.
  int n_ = 0, rr_ = 0;              // N frames, r² aliases
  Index nb_ = 0;                    // LR bins
  std::vector<Complex> a_;          // A(u): bin i at i·N·r², column-major N x r²
  std::vector<Complex> y_;          // Y(u): bin i at i·N
  std::vector<double> prior_;       // P(u): bin i at i·r²
  std::vector<double> prior_inv_;   // 1/P(u) where P > 0, else 0
  std::vector<char> prior_positive_;
  std::vector<int> rank_;
  double sv_floor_ = 0;
  double lambda0_ = 1;
  Index deficient_ = 0, unconstrained_ = 0;
};

// x = scale · (AᵀA + λ'ΓᵀΓ)⁻¹ b as a self-adjoint LinearOperator on the HR grid: FFT, per-bin G⁻¹, inverse
// FFT ((1/r²) IFFT(G⁻¹ FFT b), see tikhonov.hpp).
OperatorPtr FourierInverseOperator(Shape hr, int r, std::vector<Eigen::MatrixXcd> inverses, double scale);

// diag (AᵀA + λ'ΓᵀΓ)⁻¹ on the HR grid from the per-bin inverses: (6) of tikhonov.hpp without σ²/w₀.
Image InverseDiagonal(Shape hr, int r, const std::vector<Eigen::MatrixXcd>& inverses);

// Discrepancy search: the λ where residual(λ) (nondecreasing) equals target, on t = log10(λ/λ₀) in
// [-16, 8], bracketed from t = -3 in steps of 2 decades, refined by the Illinois method.
struct LambdaSearch {
  double lambda = 0;
  double residual = 0;  // residual at that λ
  int evaluations = 0;
  bool met = false;
  // When not met: kFailed (the target is out of reach), kMaxIterations (evaluation limit), or kStagnated
  // (the bracket shrank to 1e-12 decades, the resolution of double precision, without the residual crossing
  // the target within tolerance: the residual is flat at rounding level or jumps there).
  Termination termination = Termination::kConverged;
  std::string note;
};
LambdaSearch DiscrepancySearch(const std::function<double(double)>& residual, double target, double lambda0,
                               double tolerance, int max_evaluations);

// GCV grid search on the engine (data set): returns λ' and the score. *edge (if non-null) is "" when the minimum
// is inside the grid, else a note for the summary: a minimum at either end is a bound, not a GCV minimiser.
double GcvSearch(const FourierSystem& sys, const TikhonovOptions& options, double* score, int* evaluations,
                 std::string* edge = nullptr);

// The minimum of f(t) over t = log10(λ/λ₀) as GcvSearch finds it: a grid of t in [−decades, 0] (steps_per_decade
// per decade), walking on upwards up to `decades` more while the minimum sits at the top, then golden-section
// search between the best point's neighbours to 1e-4 decades. edge: 0 inside, −1 at the bottom, +1 at the top.
struct LogGridMinimum {
  double t = 0;
  double value = 0;
  int evaluations = 0;
  int edge = 0;
};
LogGridMinimum MinimiseOnLogGrid(const std::function<double(double)>& f, double decades, int steps_per_decade);

// The L-curve curvature κ(λ) of tikhonov.hpp (kLcurve) from the spectral sums (−∞ where undefined), and the
// λ' of the corner: the positive local maximum of κ at the largest λ on the grid, refined by golden section
// (tikhonov.cpp says why not the global maximum); *edge "" or a note when there is no such corner.
double LcurveCurvature(const FourierSystem& sys, double lambda);
double LcurveSearch(const FourierSystem& sys, const TikhonovOptions& options, double* curvature, int* evaluations,
                    std::string* edge = nullptr);
// UPRE U(λ)/n = (||y − A x_λ||² + 2 v tr H_λ − n v) / n for noise variance v per pixel of the unweighted frames
// (tikhonov.hpp, kUpre), and the λ' of its minimum.
double Upre(const FourierSystem& sys, double lambda, double variance);
double UpreSearch(const FourierSystem& sys, const TikhonovOptions& options, double variance, double* score,
                  int* evaluations, std::string* edge = nullptr);

// Fills lambda, final_cost, weighted_residual, frame_residual_rms (WeightedDataMisfit of `solved`, the
// problem on the grid x lives on) and solved_hr_shape.
void FinishSummary(const ReconstructionProblem& solved, const Image& x, double lambda,
                   const TikhonovOptions& options, TikhonovSummary* s);
// "k of n HR frequencies unconstrained by the data (b rank-deficient bins)".
std::string BinReport(const FourierSystem& sys);
// The std map √(variance_scale · diag (AᵀA + λ'ΓᵀΓ)⁻¹); false (and nothing written) if the posterior is
// improper.
bool PosteriorStd(const FourierSystem& sys, double lambda_eff, double variance_scale, Image* std_map,
                  double* mean_variance);

// The entry behind ReconstructTikhonov/TikhonovFourier (errors name `function`), and the CG path
// (tikhonov_cg.cpp), called with validated options and problem.
TikhonovResult Reconstruct(const char* function, const ReconstructionProblem& problem,
                           const TikhonovOptions& options);
// prior kFitted: fits the spectrum to the problem's frames, resolves kWiener, and runs Reconstruct with the
// resulting kPowerSpectrum options; the fit is in the summary.
TikhonovResult FittedPrior(const char* function, const ReconstructionProblem& problem,
                           const TikhonovOptions& options, std::chrono::steady_clock::time_point start);
TikhonovResult ConjugateGradientPath(const char* function, const ReconstructionProblem& problem,
                                     const TikhonovOptions& options,
                                     std::chrono::steady_clock::time_point start);

}  // namespace aosr::tikhonov_internal
