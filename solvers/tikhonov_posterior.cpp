// Tikhonov's posterior: the inverse (AᵀA + λ'ΓᵀΓ)⁻¹ as a Fourier operator (the CG path's preconditioner), its
// diagonal, and the posterior std map built from it (tikhonov.hpp, (6)).
#include "tikhonov_internal.hpp"

#include <Eigen/Dense>
#include <cmath>

#include "aosr/core/fft.hpp"
#include "aosr/core/parallel.hpp"

namespace aosr::tikhonov_internal {

namespace {

class FourierInverseOp final : public LinearOperator {
 public:
  FourierInverseOp(Shape hr, int r, std::vector<Eigen::MatrixXcd> inverses, double scale)
      : LinearOperator(hr.size(), hr.size(),
                       "FourierInverse(" + ToString(hr) + ", r=" + std::to_string(r) + ")"),
        hr_(hr),
        r_(r),
        inverses_(std::move(inverses)),
        scale_(scale / double(r * r)) {}

 private:
  // (1/r²) IFFT(G⁻¹ FFT b), bin by bin.
  void ApplyImpl(ConstRef b, Ref x) const override {
    const Shape lr{hr_.rows / r_, hr_.cols / r_};
    const ComplexImage B = FftForward(AsImage(Vector(b), hr_).cast<Complex>());
    ComplexImage X(hr_.rows, hr_.cols);
    // Bin rows in parallel: each task writes only its bins' r² HR entries (the same bits on any thread count).
    ParallelFor(lr.rows, [&](Index uy) {
      Eigen::VectorXcd v(r_ * r_), z(r_ * r_);
      for (Index ux = 0; ux < lr.cols; ++ux) {
        for (int ky = 0; ky < r_; ++ky)
          for (int kx = 0; kx < r_; ++kx) v[ky * r_ + kx] = B(uy + ky * lr.rows, ux + kx * lr.cols);
        z.noalias() = inverses_[uy * lr.cols + ux] * v;
        for (int ky = 0; ky < r_; ++ky)
          for (int kx = 0; kx < r_; ++kx) X(uy + ky * lr.rows, ux + kx * lr.cols) = z[ky * r_ + kx];
      }
    });
    const Image out = FftInverse(X).real() * scale_;
    x = AsVector(out);
  }
  void ApplyAdjointImpl(ConstRef y, Ref x) const override { ApplyImpl(y, x); }  // self-adjoint
  Shape hr_;
  int r_;
  std::vector<Eigen::MatrixXcd> inverses_;
  double scale_;
};

}  // namespace

OperatorPtr FourierInverseOperator(Shape hr, int r, std::vector<Eigen::MatrixXcd> inverses, double scale) {
  return std::make_shared<FourierInverseOp>(hr, r, std::move(inverses), scale);
}

Image InverseDiagonal(Shape hr, int r, const Eigen::MatrixXcd& mean) {
  const int rr = r * r;
  // C_pp = (1/r⁴) φ(p)ᴴ Ḡ φ(p), φ_k(p) = exp(−2πi k·p/r), for the r x r phases p mod r.
  Image cell(r, r);
  Eigen::VectorXcd phi(rr);
  for (int py = 0; py < r; ++py)
    for (int px = 0; px < r; ++px) {
      for (int ky = 0; ky < r; ++ky)
        for (int kx = 0; kx < r; ++kx)
          phi[ky * r + kx] = std::polar(1.0, -2.0 * M_PI * double(ky * py + kx * px) / r);
      cell(py, px) = (phi.adjoint() * mean * phi)(0, 0).real() / double(rr * rr);
    }
  Image d(hr.rows, hr.cols);
  for (Index y = 0; y < hr.rows; ++y)
    for (Index x = 0; x < hr.cols; ++x) d(y, x) = cell(y % r, x % r);
  return d;
}

bool PosteriorStd(const FourierSystem& sys, double lambda_eff, double variance_scale, Image* std_map,
                  double* mean_variance) {
  bool proper = true;
  const Eigen::MatrixXcd mean = sys.InverseMean(lambda_eff, &proper);
  if (!proper) return false;
  const Image var = InverseDiagonal(sys.model().hr_shape(), sys.model().r(), mean) * variance_scale;
  *mean_variance = var.mean();
  *std_map = var.max(0.0).sqrt();
  return true;
}

}  // namespace aosr::tikhonov_internal
