#include "aosr/solvers/tikhonov.hpp"

#include <Eigen/Dense>
#include <chrono>
#include <cmath>

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
  if (!(lambda >= 0 && std::isfinite(lambda))) return *why = "lambda must be finite and >= 0, got " + ToString(lambda), false;
  if (!(rank_tolerance > 0 && rank_tolerance < 1))
    return *why = "rank_tolerance must be in (0, 1), got " + ToString(rank_tolerance), false;
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

  // Pass 1: singular values of every A(u), to report what the data cannot determine.
  const Index bins = lr.size();
  const int nsv = std::min(n, rr);
  Eigen::MatrixXd sv(bins, nsv);
  for (Index uy = 0; uy < lr.rows; ++uy)
    for (Index ux = 0; ux < lr.cols; ++ux)
      sv.row(uy * lr.cols + ux) = Eigen::JacobiSVD<Eigen::MatrixXcd>(model.AliasedSystem(uy, ux)).singularValues();
  const double sv_floor = options.rank_tolerance * sv.maxCoeff();

  ComplexImage X(hr.rows, hr.cols);
  Index deficient = 0, unconstrained = 0;
  const double weight = options.lambda / rr;
  Eigen::VectorXcd rhs(rr), yu(n), sol(rr);
  Eigen::MatrixXcd normal(rr, rr);
  std::vector<double> prior_diag(rr);
  for (Index uy = 0; uy < lr.rows; ++uy)
    for (Index ux = 0; ux < lr.cols; ++ux) {
      const Index bin = uy * lr.cols + ux;
      int rank = 0;
      for (int k = 0; k < nsv; ++k) rank += sv(bin, k) > sv_floor;
      if (rank < rr) {
        ++deficient;
        unconstrained += rr - rank;
      }
      const Eigen::MatrixXcd a = model.AliasedSystem(uy, ux);
      for (int i = 0; i < n; ++i) yu[i] = spectra[i](uy, ux);
      normal.noalias() = a.adjoint() * a;
      bool prior_positive = true;
      for (int ky = 0; ky < r; ++ky)
        for (int kx = 0; kx < r; ++kx) {
          const int k = ky * r + kx;
          prior_diag[k] = TikhonovPriorSymbol(options.prior, hr, uy + ky * lr.rows, ux + kx * lr.cols);
          prior_positive = prior_positive && prior_diag[k] > 0;
          normal(k, k) += weight * prior_diag[k];
        }
      rhs.noalias() = a.adjoint() * yu;
      // Well-posed bins (full column rank, or a prior that is positive on every aliased frequency)
      // take a Cholesky solve; the others the minimum-norm least-squares solution by SVD of the
      // stacked system [A; sqrt(λ/r²) P^½], with singular values below the global floor dropped.
      if (rank == rr || (weight > 0 && prior_positive)) {
        sol = normal.llt().solve(rhs);
      } else {
        Eigen::MatrixXcd stacked(n + rr, rr);
        stacked.topRows(n) = a;
        stacked.bottomRows(rr).setZero();
        for (int k = 0; k < rr; ++k) stacked(n + k, k) = std::sqrt(weight * prior_diag[k]);
        Eigen::VectorXcd b = Eigen::VectorXcd::Zero(n + rr);
        b.head(n) = yu;
        Eigen::JacobiSVD<Eigen::MatrixXcd> svd(stacked, Eigen::ComputeThinU | Eigen::ComputeThinV);
        const double local_max = svd.singularValues().size() ? svd.singularValues()[0] : 0.0;
        svd.setThreshold(local_max > 0 ? std::min(1.0, sv_floor / local_max) : 1.0);
        sol = svd.solve(b);
      }
      for (int ky = 0; ky < r; ++ky)
        for (int kx = 0; kx < r; ++kx) X(uy + ky * lr.rows, ux + kx * lr.cols) = sol[ky * r + kx];
    }
  const ComplexImage xc = FftInverse(X);
  Image x = xc.real();
  if (!AllFinite(x)) throw NumericalError("TikhonovFourier: the solve produced non-finite values");

  if (summary) {
    TikhonovSummary& s = *summary;
    s = TikhonovSummary{};
    s.method = "tikhonov";
    s.lr_bins = bins;
    s.rank_deficient_bins = deficient;
    s.unconstrained_frequencies = unconstrained;
    const Vector resid = model.Operator()->Apply(AsVector(x)) - y_all;
    const Vector gx = TikhonovPriorOperator(hr, options.prior)->Apply(AsVector(x));
    s.final_cost = resid.squaredNorm() + options.lambda * gx.squaredNorm();
    for (int i = 0; i < n; ++i)
      s.frame_residual_rms.push_back(std::sqrt(resid.segment(i * lr.size(), lr.size()).squaredNorm() / lr.size()));
    s.message = std::to_string(unconstrained) + " of " + std::to_string(hr.size()) +
                " HR frequencies unconstrained by the data (" + std::to_string(deficient) + " rank-deficient bins)";
    s.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  }
  return x;
}

}  // namespace aosr
