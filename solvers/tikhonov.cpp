#include "aosr/solvers/tikhonov.hpp"

#include <Eigen/Dense>
#include <chrono>
#include <cmath>
#include <limits>

#include "aosr/core/error.hpp"
#include "aosr/core/fft.hpp"
#include "aosr/core/operators.hpp"

namespace aosr {

const char* ToString(TikhonovPrior p) {
  switch (p) {
    case TikhonovPrior::kIdentity: return "identity";
    case TikhonovPrior::kGradient: return "gradient";
    case TikhonovPrior::kLaplacian: return "laplacian";
  }
  return "unknown";
}

TikhonovPrior ParseTikhonovPrior(const std::string& name) {
  if (name == "identity") return TikhonovPrior::kIdentity;
  if (name == "gradient") return TikhonovPrior::kGradient;
  if (name == "laplacian") return TikhonovPrior::kLaplacian;
  throw InvalidArgument("ParseTikhonovPrior", "prior", name, "identity, gradient or laplacian");
}

bool TikhonovOptions::IsValid(std::string* why) const {
  auto fail = [why](const std::string& m) {
    if (why) *why = m;
    return false;
  };
  if (!(lambda >= 0 && std::isfinite(lambda))) return fail("lambda must be finite and >= 0, got " + ToString(lambda));
  if (!(rank_tolerance > 0 && rank_tolerance < 1))
    return fail("rank_tolerance must be in (0, 1), got " + ToString(rank_tolerance));
  if (lambda_rule == TikhonovLambdaRule::kGcv && !(gcv_decades > 0 && gcv_decades <= 20 && gcv_steps_per_decade >= 1 &&
                                                  gcv_steps_per_decade <= 20))
    return fail("gcv_decades must be in (0, 20] and gcv_steps_per_decade in 1..20");
  return true;
}

OperatorPtr TikhonovPriorOperator(Shape hr, TikhonovPrior prior) {
  switch (prior) {
    case TikhonovPrior::kIdentity: return Identity(hr.size());
    case TikhonovPrior::kGradient: return Gradient(hr, Boundary::kPeriodic);
    case TikhonovPrior::kLaplacian: return Normal(Gradient(hr, Boundary::kPeriodic));  // ∇ᵀ∇
  }
  throw InvalidArgument("TikhonovPriorOperator", "prior", "unknown", "identity, gradient or laplacian");
}

double TikhonovPriorSymbol(TikhonovPrior prior, Shape hr, Index fy, Index fx) {
  if (prior == TikhonovPrior::kIdentity) return 1.0;
  const double sy = std::sin(M_PI * double(fy) / double(hr.rows));
  const double sx = std::sin(M_PI * double(fx) / double(hr.cols));
  const double g = 4.0 * (sy * sy + sx * sx);
  return prior == TikhonovPrior::kGradient ? g : g * g;
}

namespace {

// Everything about one LR frequency bin that does not depend on λ.
struct Bin {
  Eigen::MatrixXcd a;        // N x r² aliased system
  Eigen::VectorXcd y;        // N data values
  Eigen::VectorXd prior;     // |Γ̂|² on the r² aliased HR bins
  int rank = 0;              // numerical rank of a
};

struct BinSolution {
  Eigen::VectorXcd x;
  double residual2 = 0;  // |y - A x|²
  double trace = 0;      // tr(A (AᴴA + wP)⁺ Aᴴ): the bin's share of the influence-matrix trace
};

// Solves one bin for weight w = λ/r² (see the header's normal equations).
BinSolution SolveBin(const Bin& b, double w, double sv_floor, bool want_trace) {
  const Index n = b.a.rows(), rr = b.a.cols();
  BinSolution s;
  const bool prior_positive = (b.prior.array() > 0).all();
  if (b.rank == rr || (w > 0 && prior_positive)) {
    // Well posed: Cholesky of the Hermitian positive definite normal matrix.
    Eigen::MatrixXcd normal = b.a.adjoint() * b.a;
    normal.diagonal().array() += w * b.prior.array();
    const Eigen::LLT<Eigen::MatrixXcd> llt(normal);
    s.x = llt.solve(b.a.adjoint() * b.y);
    if (want_trace) {
      const Eigen::MatrixXcd z = llt.matrixL().solve(b.a.adjoint());  // L⁻¹Aᴴ
      s.trace = z.squaredNorm();
    }
  } else {
    // Otherwise the minimum-norm least-squares solution of the stacked system [A; sqrt(w) P^½] by SVD,
    // singular values below the global floor dropped: unconstrained frequencies come back as zero.
    Eigen::MatrixXcd stacked = Eigen::MatrixXcd::Zero(n + rr, rr);
    stacked.topRows(n) = b.a;
    for (Index k = 0; k < rr; ++k) stacked(n + k, k) = std::sqrt(w * b.prior[k]);
    Eigen::JacobiSVD<Eigen::MatrixXcd> svd(stacked, Eigen::ComputeThinU | Eigen::ComputeThinV);
    const double local_max = svd.singularValues().size() ? svd.singularValues()[0] : 0.0;
    svd.setThreshold(local_max > 0 ? std::min(1.0, sv_floor / local_max) : 1.0);
    Eigen::VectorXcd rhs = Eigen::VectorXcd::Zero(n + rr);
    rhs.head(n) = b.y;
    s.x = svd.solve(rhs);
    if (want_trace) {
      Eigen::MatrixXcd e = Eigen::MatrixXcd::Zero(n + rr, n);
      e.topRows(n).setIdentity();
      s.trace = (b.a * svd.solve(e)).trace().real();
    }
  }
  s.residual2 = (b.y - b.a * s.x).squaredNorm();
  return s;
}

}  // namespace

Image TikhonovFourier(const MultiFrameModel& model, const ImageStack& frames, const TikhonovOptions& options,
                      TikhonovSummary* summary) {
  std::string why;
  if (!options.IsValid(&why)) throw InvalidArgument("TikhonovFourier: " + why);
  const Vector y_all = model.Flatten(frames);  // checks count and shapes
  for (std::size_t i = 0; i < frames.size(); ++i)
    if (!AllFinite(frames[i]))
      throw InvalidArgument("TikhonovFourier", "frame " + std::to_string(i), "contains NaN or Inf",
                            "finite values (mask bad pixels with an iterative solver)");
  const auto start = std::chrono::steady_clock::now();
  const Shape hr = model.hr_shape(), lr = model.lr_shape();
  const int r = model.r(), n = model.frames(), rr = r * r;

  std::vector<ComplexImage> spectra;
  for (const Image& f : frames) spectra.push_back(FftForward(f.cast<Complex>()));

  // Per-bin systems, their singular values (to report what the data cannot determine) and the scale
  // λ₀ = Σ tr(AᴴA) / Σ tr(P) that makes λ/λ₀ dimensionless for the GCV search.
  std::vector<Bin> bins(lr.size());
  std::vector<double> smallest(lr.size());
  double sv_max = 0, trace_ata = 0, trace_p = 0;
  for (Index uy = 0; uy < lr.rows; ++uy)
    for (Index ux = 0; ux < lr.cols; ++ux) {
      Bin& b = bins[uy * lr.cols + ux];
      b.a = model.AliasedSystem(uy, ux);
      b.y.resize(n);
      for (int i = 0; i < n; ++i) b.y[i] = spectra[i](uy, ux);
      b.prior.resize(rr);
      for (int ky = 0; ky < r; ++ky)
        for (int kx = 0; kx < r; ++kx)
          b.prior[ky * r + kx] = TikhonovPriorSymbol(options.prior, hr, uy + ky * lr.rows, ux + kx * lr.cols);
      trace_ata += b.a.squaredNorm();
      trace_p += b.prior.sum();
    }
  std::vector<Eigen::VectorXd> svs(bins.size());
  for (std::size_t i = 0; i < bins.size(); ++i) {
    svs[i] = Eigen::JacobiSVD<Eigen::MatrixXcd>(bins[i].a).singularValues();
    if (svs[i].size()) sv_max = std::max(sv_max, svs[i][0]);
  }
  const double sv_floor = options.rank_tolerance * sv_max;
  Index deficient = 0, unconstrained = 0;
  for (std::size_t i = 0; i < bins.size(); ++i) {
    bins[i].rank = int((svs[i].array() > sv_floor).count());
    if (bins[i].rank < rr) {
      ++deficient;
      unconstrained += rr - bins[i].rank;
    }
  }

  // λ: fixed, or the minimiser of generalised cross-validation (Golub, Heath & Wahba 1979)
  //     GCV(λ) = n_data · ||y − A x_λ||² / (n_data − tr H_λ)²,
  // evaluated exactly per bin (Parseval: both terms are sums over bins) on a log grid of λ/λ₀.
  double lambda = options.lambda;
  double gcv_best = 0;
  const double lambda0 = trace_p > 0 ? trace_ata / trace_p : 1.0;
  if (options.lambda_rule == TikhonovLambdaRule::kGcv) {
    const double n_data = double(n) * double(lr.size());
    const int steps = int(std::lround(options.gcv_decades * options.gcv_steps_per_decade));
    gcv_best = std::numeric_limits<double>::infinity();
    for (int k = 0; k <= steps; ++k) {
      const double lam = lambda0 * std::pow(10.0, -options.gcv_decades + double(k) / options.gcv_steps_per_decade);
      double res2 = 0, trace = 0;
      for (const Bin& b : bins) {
        const BinSolution s = SolveBin(b, lam / rr, sv_floor, true);
        res2 += s.residual2;
        trace += s.trace;
      }
      // Parseval for the unnormalised DFT: ||y||² = Σ|Y|² / m².
      const double g = n_data * (res2 / double(lr.size())) / std::pow(n_data - trace, 2);
      if (g < gcv_best) gcv_best = g, lambda = lam;
    }
  }

  ComplexImage X(hr.rows, hr.cols);
  for (Index uy = 0; uy < lr.rows; ++uy)
    for (Index ux = 0; ux < lr.cols; ++ux) {
      const BinSolution s = SolveBin(bins[uy * lr.cols + ux], lambda / rr, sv_floor, false);
      for (int ky = 0; ky < r; ++ky)
        for (int kx = 0; kx < r; ++kx) X(uy + ky * lr.rows, ux + kx * lr.cols) = s.x[ky * r + kx];
    }
  Image x = FftInverse(X).real();
  if (!AllFinite(x)) throw NumericalError("TikhonovFourier: the solve produced non-finite values");

  if (summary) {
    TikhonovSummary& s = *summary;
    s = TikhonovSummary{};
    s.method = "tikhonov";
    s.lambda = lambda;
    s.gcv = gcv_best;
    s.lr_bins = lr.size();
    s.rank_deficient_bins = deficient;
    s.unconstrained_frequencies = unconstrained;
    const Vector resid = model.Operator()->Apply(AsVector(x)) - y_all;
    const Vector gx = TikhonovPriorOperator(hr, options.prior)->Apply(AsVector(x));
    s.final_cost = resid.squaredNorm() + lambda * gx.squaredNorm();
    for (int i = 0; i < n; ++i)
      s.frame_residual_rms.push_back(std::sqrt(resid.segment(i * lr.size(), lr.size()).squaredNorm() / lr.size()));
    s.message = "lambda " + ToString(lambda) + (options.lambda_rule == TikhonovLambdaRule::kGcv ? " (GCV)" : "") +
                "; " + std::to_string(unconstrained) + " of " + std::to_string(hr.size()) +
                " HR frequencies unconstrained by the data (" + std::to_string(deficient) + " rank-deficient bins)";
    s.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  }
  return x;
}

}  // namespace aosr
