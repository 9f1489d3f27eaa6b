// Private to the library (not installed): the per-bin Fourier engine of tikhonov.hpp and the λ searches, shared
// by the Fourier path and the conjugate-gradient path, used by design/design_empirical.cpp (the prior symbol of
// objective B's preconditioner) and by the tests. Defined in tikhonov_prior.cpp (PriorSymbolImage),
// tikhonov_fourier_system.cpp (FourierSystem), tikhonov_spectral.cpp (FourierSystem's spectral decomposition for
// the λ rules), tikhonov_posterior.cpp (inverse operator, diagonal, PosteriorStd), tikhonov_lambda.cpp (λ
// searches), tikhonov.cpp (entry points, summary helpers) and tikhonov_cg.cpp (the CG path, preconditioned by
// fourier_normal_system.hpp's NormalSystemInverse).
#pragma once

#include <Eigen/Dense>
#include <chrono>
#include <functional>
#include <memory>
#include <mutex>
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
//
// Nothing of size N·r²·m² is stored: each bin's A(u) (N x r²) and P(u) are gathered from the model's OTFs and the
// prior symbol into per-thread scratch when a pass reaches the bin (the same values, bit for bit, a flat copy
// would hold), so a solve costs no allocation of the model's size. The rank floor (rank_tolerance x the largest
// singular value of all bins), λ₀ and the ranks are made on first use: a solve at λ > 0 with a positive prior
// needs none of them; the ranks (the counts deficient_bins() and unconstrained(), and λ = 0) need an SVD's
// accuracy in bins whose singular values straddle the floor, which is most bins at N ≈ r².
class FourierSystem {
 public:
  FourierSystem(const MultiFrameModel& model, Image prior_symbol, double rank_tolerance, TikhonovBinSolver solver);

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
  // (tikhonov.hpp, "λ rules"). Bins whose prior vanishes at aliases Z (the DC bin of the gradient and Laplacian
  // priors) are reduced to the complement of A(u)_Z's range where the data see that null space (MakeSpectral), with
  // N − tr H = Σ_k w/(s_k² + w) + (N − z − q); only where they do not are they solved directly at each λ.
  // want_prior adds η = ||Γx||² = (1/(m² r²)) Σ_u Σ_k s_k² c_k/(s_k² + w)² and its derivative by λ,
  // dη/dλ = −(2/(m² r⁴)) Σ_u Σ_k s_k² c_k/(s_k² + w)³ (direct bins: −2 Re (Px)ᴴ G⁻¹ (Px) per bin).
  Fit EvaluateSpectral(double lambda, bool want_prior = false) const;
  // How EvaluateSpectral's per-bin decomposition is made. kBidiagonal (default): the singular values of the
  // whitened B and the projections UᴴY from its Householder bidiagonalisation and implicit QR sweeps, the left
  // transformations applied to Y alone (bins::SingularSpectrum: an SVD's accuracy without forming U; where N > r²
  // the part of Y no λ fits is a sum of squares). kSvd: Eigen's JacobiSVD of B with the full U (the reference the
  // tests compare with). Setting it discards a decomposition already made.
  enum class SpectralMethod { kBidiagonal, kSvd };
  // Makes EvaluateSpectral's decomposition now (and, where not made yet, the floor and λ₀ from the same pass):
  // the λ rules call it before lambda0() so that one pass over the bins serves both.
  void PrepareSpectral() const {
    if (!spectral_) MakeSpectral();
  }
  void SetSpectralMethod(SpectralMethod method) {
    spectral_method_ = method;
    spectral_.reset();
  }
  // x_λ; *fit gets the residual, ||Γx||² (prior2, from the spectrum) and the Woodbury count.
  Image Solve(double lambda, Fit* fit = nullptr) const;

  // G(u)⁻¹ for every bin (pseudo-inverse where singular; *proper = false then).
  std::vector<Eigen::MatrixXcd> Inverses(double lambda, bool* proper, Index* woodbury_bins) const;
  // Their mean over the bins (r² x r²), summed per fixed block of bins and then in block order (the same bits on
  // any thread count) without holding every bin's inverse: 2 r² HR arrays fewer (32 at r = 4). *proper as above.
  Eigen::MatrixXcd InverseMean(double lambda, bool* proper) const;

  const MultiFrameModel& model() const { return model_; }
  double lambda0() const;  // Σ tr AᴴA / Σ tr P (made on first use)
  Index bins() const { return nb_; }
  // The rank counts (made on first use: every bin's rank against the floor, FourierSystem's costliest pass).
  Index deficient_bins() const;
  Index unconstrained() const;
  // Whether the ranks have been made (by the counts above, or by a solve at λ = 0).
  bool ranks_made() const {
    std::lock_guard<std::mutex> lock(lazy_mutex_);
    return ranks_ready_;
  }

 private:
  // One bin's A(u) (column-major N x r²), P(u) and 1/P (0 where P = 0), gathered into caller-owned scratch.
  struct BinPtr {
    const Complex* a;
    const double* p;
    const double* pinv;
  };
  struct BinData {
    std::vector<Complex> a;
    std::vector<double> p, pinv;
    BinPtr ptr() const { return {a.data(), p.data(), pinv.data()}; }
  };
  void Gather(Index bin, BinData* d) const;
  // The bins ux0 .. ux0 + count − 1 of LR row uy gathered at once (the same values as Gather), streaming along the
  // OTF rows: bin k's A at a + k·stride (stride >= N r², padded so that consecutive bins do not alias in the cache),
  // its P and 1/P at p + k·r², pinv + k·r².
  void GatherRun(Index uy, Index ux0, int count, std::size_t stride, Complex* a, double* p, double* pinv) const;
  // f(bin, BinPtr) for every bin with want(bin), on fixed blocks of bins (a partition independent of the thread
  // count; tasks in parallel), the wanted bins of each LR row gathered in runs by GatherRun.
  template <class Want, class F>
  void ForGatheredBins(const Want& want, const F& f) const;
  // The same with block_begin() and block_done() called on the block's thread before its first bin and after its
  // last.
  template <class Want, class F, class Begin, class Done>
  void ForGatheredBins(const Want& want, const F& f, const Begin& block_begin, const Done& block_done) const;
  // Bin `bin` gathered into *d, seen as Eigen matrices: A(u) column-major N x r², the data Y(u) and the prior
  // P(u) on the r² aliases. rank is -1 where not computed (the callers that read it made it first).
  struct BinView {
    Eigen::Map<const Eigen::MatrixXcd> a;
    Eigen::Map<const Eigen::VectorXcd> y;
    Eigen::Map<const Eigen::VectorXd> prior;
    bool prior_positive;
    int rank;
  };
  BinView View(Index bin, BinData* d) const;
  // The lazily made parts (each under lazy_mutex_, so concurrent const calls are safe): the floor and λ₀, and the
  // ranks of every bin or of the bins whose prior vanishes somewhere (the only ones a λ > 0 solve asks about).
  void EnsureFloor() const;
  void EnsureRanks() const;
  void EnsureZeroPriorRanks() const;
  // Makes sure Choose(bin, w) can be called for every bin (ranks where it will read them).
  void PrepareChoose(double w) const;
  // The rank of the N x cols column-major matrix a (columns of A(u)) against the floor (EnsureFloor first).
  int RankOf(const Complex* a, int cols) const;
  // The floor's inputs per bin (canonical bins), noted by any pass that gathers every canonical bin (EnsureFloor's
  // own, Solve's, MakeSpectral's), and the floor and λ₀ made from them (once; later calls do nothing).
  struct FloorNorms {
    std::vector<double> trace, col_max, prior;
  };
  FloorNorms NewFloorNorms() const;
  void NoteNorms(Index bin, BinPtr d, FloorNorms* fn) const;
  void FinishFloor(const FloorNorms& fn) const;
  bool FloorReady() const;
  struct BinSolution {
    Eigen::VectorXcd x;
    double residual2 = 0;
    double dof = 0;  // N − tr(A G⁻¹ Aᴴ)
    bool woodbury = false;
  };
  enum class Path { kWoodbury, kNormal, kMinimumNorm };
  Path Choose(Index bin, double w) const;
  BinSolution SolveBin(Index bin, double w, bool want_trace, BinData* d) const;
  // SolveBin's Woodbury or normal-equations path on the gathered bin `d` and caller scratch (max(r⁴, N² + N)
  // values) without allocation; false where the Cholesky fails (the caller falls back as SolveBin does).
  bool SolveBinInPlace(Index bin, BinPtr d, double w, Path path, Complex* x, Complex* scratch) const;
  Eigen::MatrixXcd InverseBin(Index bin, double w, bool* proper, bool* woodbury, BinData* d) const;

  // EvaluateSpectral's per-bin decomposition (empty until first use; `direct` lists the bins solved directly).
  // Flat, a fixed stride of q_max = min(N, r²) values per bin; q[i] of them are used (fewer where columns of B
  // below its rounding were dropped; the rest are directions B does not reach, counted in N − q).
  struct Spectral {
    int q_max = 0;
    std::vector<double> s2;     // s_k² of bin i at i·q_max
    std::vector<double> c;      // |u_kᴴ Y|², likewise
    std::vector<double> perp;   // ||(I − UUᴴ) Y||² per bin
    std::vector<int> q;         // values used per bin
    std::vector<int> zeros;     // z: aliases of a zero of the prior reduced away (MakeSpectral), else 0
    std::vector<char> weight;   // 2 for one bin of a mirror pair (the other copies it), 1 if self-mirror, else 0
    std::vector<Index> direct;  // bins with a zero of the prior the data do not see (solved at each λ)
    // The same values as one stream of terms (the counted bins' q values in bin order) for the λ loop:
    // s², weight·c and weight; and the λ-independent parts Σ weight·perp and Σ weight·(N − q).
    std::vector<double> term_s2, term_wc, term_weight;
    double fixed_residual = 0, fixed_dof = 0;
  };
  void MakeSpectral() const;
  void DecomposeBinSvd(Index bin, Spectral* sp, BinData* d) const;
  // One bin's whitened system prepared for the decomposition (PrepareWhitened: B with its negligible columns
  // dropped, N x kept column-major at b, and Y), in its own scratch, and where its results go.
  struct WhitenedBin {
    std::vector<double> scratch;
    int kept = 0;
    Complex* b = nullptr;
    Complex* y = nullptr;
    Complex* v = nullptr;
    double* work = nullptr;
    double* s2 = nullptr;
    double* c = nullptr;
    int* q = nullptr;
    double* perp = nullptr;
  };
  // Up to two prepared bins: bin[0] waits (pending = 1) for a second of its shape, decomposed with it.
  struct WhitenedPair {
    WhitenedBin bin[2];
    int pending = 0;
  };
  // Bin `bin` into *sp (through *pair: its results may be written at the next call or at FinishPair).
  void DecomposeBinBidiagonal(Index bin, Spectral* sp, BinPtr d, WhitenedPair* pair) const;
  void FinishPair(WhitenedPair* pair) const;
  void PrepareWhitened(int n, const Complex* a, const double* pinv, const Complex* y, WhitenedBin* out) const;
  // count (1 or 2) prepared bins of one shape decomposed, their s², |uᴴY|², q and perp written.
  void DecomposePrepared(int n, WhitenedBin* bins, int count) const;
  // The decomposition of the n x r² system a (column-major), whitened by pinv, with data y: s², |uᴴY|², the count
  // q and the part of Y outside the range.
  void DecomposeWhitened(int n, const Complex* a, const double* pinv, const Complex* y, double* s2_out, double* c_out,
                         int* q_out, double* perp_out, WhitenedBin* scratch) const;
  SpectralMethod spectral_method_ = SpectralMethod::kBidiagonal;
  // The bin of −u (LR frequencies), and whether `bin` is the one of its pair {u, −u} that is computed (the
  // other is its conjugate: real frames, real PSFs, an even prior).
  Index MirrorBin(Index bin) const;
  bool CanonicalBin(Index bin) const;
  // How often a canonical bin counts in sums over all bins: 2 (itself and its mirror), 1 (its own mirror); 0 for
  // the non-canonical bin of a pair.
  int MirrorWeight(Index bin) const { return canonical_[bin]; }
  mutable std::unique_ptr<Spectral> spectral_;

  const MultiFrameModel& model_;
  TikhonovBinSolver solver_;
  Image prior_symbol_;              // |Γ̂|² on the full HR spectrum
  double rank_tolerance_;
  int n_ = 0, r_ = 0, rr_ = 0;      // N frames, r, r² aliases
  Index nb_ = 0;                    // LR bins
  std::vector<Complex> y_;          // Y(u): bin i at i·N
  std::vector<char> prior_positive_;
  std::vector<char> canonical_;     // MirrorWeight per bin (CanonicalBin: nonzero)
  std::vector<Index> zero_prior_bins_;  // bins whose prior vanishes at some alias
  // Lazily made (lazy_mutex_): the floor and λ₀; the ranks (-1 until made).
  mutable std::mutex lazy_mutex_;
  mutable bool floor_ready_ = false, ranks_ready_ = false, zero_prior_ranks_ready_ = false;
  mutable std::vector<int> rank_;
  mutable std::vector<char> seen_;  // zero-prior bins: the data see the prior's null space (Choose)
  mutable double sv_floor_ = 0;
  mutable double lambda0_ = 1;
  mutable Index deficient_ = 0, unconstrained_ = 0;
};

// x = scale · (AᵀA + λ'ΓᵀΓ)⁻¹ b as a self-adjoint LinearOperator on the HR grid: FFT, per-bin G⁻¹, inverse
// FFT ((1/r²) IFFT(G⁻¹ FFT b), see tikhonov.hpp).
OperatorPtr FourierInverseOperator(Shape hr, int r, std::vector<Eigen::MatrixXcd> inverses, double scale);

// diag (AᵀA + λ'ΓᵀΓ)⁻¹ on the HR grid from the bins' mean inverse (FourierSystem::InverseMean): (6) of tikhonov.hpp
// without σ²/w₀.
Image InverseDiagonal(Shape hr, int r, const Eigen::MatrixXcd& mean_inverse);

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
// (tikhonov_lambda.cpp says why not the global maximum); *edge "" or a note when there is no such corner.
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
// ||Γx||² is prior_norm2 when given (the Fourier path's, from its spectrum), else the prior operator's.
void FinishSummary(const ReconstructionProblem& solved, const Image& x, double lambda,
                   const TikhonovOptions& options, TikhonovSummary* s, const double* prior_norm2 = nullptr);
// Fills the summary's rank counts when `count` or when the system has made its ranks anyway (λ = 0), else -1, and
// returns the message part: "; k of n HR frequencies unconstrained by the data (b rank-deficient bins)" or "".
std::string CountUnconstrained(const FourierSystem& sys, bool count, TikhonovSummary* s);
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
