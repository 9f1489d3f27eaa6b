#include "aosr/core/forward_model.hpp"

#include <algorithm>
#include <cmath>

#include "aosr/core/error.hpp"
#include "aosr/core/fft.hpp"
#include "aosr/core/operators.hpp"
#include "aosr/core/parallel.hpp"

namespace aosr {
namespace {

// Σ_{k=0}^{r-1} exp(+2πi f k / n) for every bin f of an axis of length n.
std::vector<Complex> BoxTransfer(Index n, int r) {
  std::vector<Complex> b(n);
  for (Index f = 0; f < n; ++f) {
    Complex s = 0;
    for (int k = 0; k < r; ++k) s += std::polar(1.0, 2.0 * M_PI * double(f) * k / double(n));
    b[f] = s;
  }
  return b;
}

// The stacked model A = [D_r H_0; ...; D_r H_{N-1}] through its aliasing structure (forward_model.hpp):
//   Apply:        X = FFT_HR x;  Y_i(u) = Σ_k T_i(u + k∘m) X(u + k∘m);  y_i = FFT_LR⁻¹ Y_i
//   ApplyAdjoint: V_i = FFT_LR v_i;  X(f) = r² Σ_i conj T_i(f) V_i(f mod m);  x = FFT_HR⁻¹ X
// with T_i = B H_i / r² on the HR half spectrum. One HR and N LR transforms each way, where the composition
// of per-frame convolutions and decimations costs 2N HR transforms: the same operator (the tests compare
// them), computed with about N times fewer FFT flops. (F(Aᵀv) = r² A(u)ᴴ V(u): the HR grid has r² times the
// LR grid's points, so Parseval for the unnormalised DFTs puts r² on the adjoint.)
class AliasedStack final : public LinearOperator {
 public:
  AliasedStack(Shape hr, int r, std::vector<ComplexImage> transfer)
      : LinearOperator(Index(transfer.size()) * (hr.rows / r) * (hr.cols / r), hr.size(),
                       "AliasedStack(" + ToString(hr) + ", r=" + std::to_string(r) + ", N=" +
                           std::to_string(transfer.size()) + ")"),
        hr_(hr),
        lr_{hr.rows / r, hr.cols / r},
        r_(r),
        t_(std::move(transfer)) {}

 private:
  // Products written in real arithmetic: the same operations as std::complex's operator* (the same bits for
  // finite values), without its NaN-recovery call in the inner loops (the operands are finite: the solvers
  // validate their inputs). It was 12 % of a MAP reconstruction's time at r = 8.
  static Complex Mul(Complex a, Complex b) {
    return {a.real() * b.real() - a.imag() * b.imag(), a.real() * b.imag() + a.imag() * b.real()};
  }
  static Complex ConjMul(Complex a, Complex b) {  // conj(a) b
    return {a.real() * b.real() + a.imag() * b.imag(), a.real() * b.imag() - a.imag() * b.real()};
  }

  void ApplyImpl(ConstRef x, Ref y) const override {
    const ComplexImage X = FftR2C(AsImage(Vector(x), hr_));
    const Index lr_half = lr_.cols / 2 + 1, hr_half = X.cols();
    const int n = int(t_.size());
    std::vector<ComplexImage> Y(n, ComplexImage::Zero(lr_.rows, lr_half));
    // Y_i(u) = Σ_k T_i(u + k∘m) X(u + k∘m), the aliases k in the same order for every u, each accumulated along a
    // contiguous stretch of the HR rows (one stream per alias instead of r² streams per bin). Along a stretch,
    // the bins below the HR half spectrum's width are read directly and the rest from their mirror −f by
    // Hermitian symmetry: two branch-free loops split where the one meets the other. The loop is memory-bound
    // (the N transfer functions are N HR spectra), so each HR row of X is read once for all the frames; the
    // tasks are LR rows, each writing only its own rows of every Y_i.
    ParallelFor(lr_.rows, [&](Index uy) {
      for (int ky = 0; ky < r_; ++ky) {
        const Index fy = uy + ky * lr_.rows, my = (hr_.rows - fy) % hr_.rows;
        const Complex* x_row = &X(fy, 0);
        const Complex* x_mirror = &X(my, 0);
        for (int i = 0; i < n; ++i) {
          Complex* y_row = &Y[i](uy, 0);
          const Complex* t_row = &t_[i](fy, 0);
          const Complex* t_mirror = &t_[i](my, 0);
          for (int kx = 0; kx < r_; ++kx) {
            const Index base = kx * lr_.cols;
            const Index split = std::clamp<Index>(hr_half - base, 0, lr_half);
            for (Index ux = 0; ux < split; ++ux) y_row[ux] += Mul(t_row[base + ux], x_row[base + ux]);
            for (Index ux = split; ux < lr_half; ++ux) {
              const Index m = hr_.cols - base - ux;
              y_row[ux] += std::conj(Mul(t_mirror[m], x_mirror[m]));
            }
          }
        }
      }
    });
    ParallelFor(n, [&](Index i) { y.segment(i * lr_.size(), lr_.size()) = AsVector(FftC2R(Y[i], lr_.cols)); });
  }
  void ApplyAdjointImpl(ConstRef v, Ref x) const override {
    const int n = int(t_.size());
    std::vector<ComplexImage> V(n);
    ParallelFor(n, [&](Index i) {
      V[i] = FftR2C(AsImage(Vector(v.segment(i * lr_.size(), lr_.size())), lr_));
    });
    const Index half_cols = hr_.cols / 2 + 1, lr_half = lr_.cols / 2 + 1;
    const double rr = double(r_ * r_);
    ComplexImage X(hr_.rows, half_cols);
    // X(f) = r² Σ_i conj T_i(f) V_i(f mod m), V_i at LR bins past its half spectrum read from the mirror.
    // Each row of X accumulates frame by frame in the frames' order (the same sums as bin by bin), along
    // stretches of m bins (f mod m without a division), each split where V's stored half ends.
    ParallelFor(hr_.rows, [&](Index fy) {
      const Index uy = fy % lr_.rows, my = (lr_.rows - uy) % lr_.rows;
      Complex* x_row = &X(fy, 0);
      for (Index fx = 0; fx < half_cols; ++fx) x_row[fx] = 0;
      for (int i = 0; i < n; ++i) {
        const Complex* t_row = &t_[i](fy, 0);
        const Complex* v_row = &V[i](uy, 0);
        const Complex* v_mirror = &V[i](my, 0);
        for (Index base = 0; base < half_cols; base += lr_.cols) {
          const Index len = std::min(lr_.cols, half_cols - base), split = std::min(len, lr_half);
          for (Index ux = 0; ux < split; ++ux) x_row[base + ux] += ConjMul(t_row[base + ux], v_row[ux]);
          for (Index ux = split; ux < len; ++ux)
            x_row[base + ux] += ConjMul(t_row[base + ux], std::conj(v_mirror[lr_.cols - ux]));
        }
      }
      for (Index fx = 0; fx < half_cols; ++fx) x_row[fx] = rr * x_row[fx];
    });
    x = AsVector(FftC2R(X, hr_.cols));
  }

  Shape hr_, lr_;
  int r_;
  std::vector<ComplexImage> t_;
};

}  // namespace

MultiFrameModel::MultiFrameModel(Shape hr, int r, std::vector<ComplexImage> otfs) : hr_(hr), r_(r) {
  CheckArgument(hr.rows > 0 && hr.cols > 0, "MultiFrameModel", "hr_shape", ToString(hr), "positive");
  CheckArgument(r >= 1, "MultiFrameModel", "r", r, ">= 1");
  if (hr.rows % r || hr.cols % r)
    throw InvalidArgument("MultiFrameModel", "r", std::to_string(r), "a divisor of the HR grid " + ToString(hr));
  CheckArgument(!otfs.empty(), "MultiFrameModel", "otfs", "empty", "at least one frame");
  const OperatorPtr decimate = Decimate(hr, r);
  std::vector<OperatorPtr> parts;
  for (std::size_t i = 0; i < otfs.size(); ++i) {
    if (ShapeOf(otfs[i]) != Shape{hr.rows, hr.cols / 2 + 1})
      throw InvalidArgument("MultiFrameModel", "otf " + std::to_string(i) + " shape", ToString(ShapeOf(otfs[i])),
                            ToString(Shape{hr.rows, hr.cols / 2 + 1}) + " (half spectrum of the HR grid)");
    CheckArgument(AllFinite(otfs[i]), "MultiFrameModel", "otf " + std::to_string(i), "non-finite values",
                  "finite values");
    // The explicit Fourier formulas below must see the same (real-kernel) transfer function that the
    // spatial operator's c2r applies. One copy, shared with the frame's convolution (a whole-detector tile's
    // window model holds N half spectra of ~45 MB each: a copy per operator tripled it).
    HermitianProjectInPlace(&otfs[i], hr.cols);
    otfs_.push_back(std::make_shared<const ComplexImage>(std::move(otfs[i])));
    frame_ops_.push_back(Compose(decimate, PeriodicConvolution(hr, otfs_.back())));
    parts.push_back(frame_ops_.back());
  }
  box_y_ = BoxTransfer(hr.rows, r);
  box_x_ = BoxTransfer(hr.cols, r);
  // The stack through the aliasing structure (Stack(parts) is the same operator at N times the FFT cost).
  const double inv = 1.0 / double(r * r);
  std::vector<ComplexImage> transfer;
  for (std::size_t i = 0; i < otfs_.size(); ++i) {
    ComplexImage t(hr.rows, hr.cols / 2 + 1);
    const ComplexImage& h = *otfs_[i];
    ParallelFor(hr.rows, [&](Index fy) {
      for (Index fx = 0; fx < hr.cols / 2 + 1; ++fx) t(fy, fx) = inv * PixelTransfer(fy, fx) * h(fy, fx);
    });
    transfer.push_back(std::move(t));
  }
  op_ = std::make_shared<AliasedStack>(hr, r, std::move(transfer));
}

MultiFrameModel MultiFrameModel::Isoplanatic() const {
  std::vector<ComplexImage> otfs;
  for (const auto& h : otfs_) otfs.push_back(*h);  // projected again: the projection is exact on its own result
  return MultiFrameModel(hr_, r_, std::move(otfs));
}

MultiFrameModel MultiFrameModel::FromKernels(Shape hr, int r, const ImageStack& centred_psfs) {
  std::vector<ComplexImage> otfs;
  for (const Image& k : centred_psfs) otfs.push_back(TransferFunction(hr, k));
  return MultiFrameModel(hr, r, std::move(otfs));
}

MultiFrameModel MultiFrameModel::WithPsfField(const PsfFieldGrid& grid, const std::vector<ImageStack>& node_psfs) const {
  const char* fn = "MultiFrameModel::WithPsfField";
  if (grid.empty() || grid.hr_shape() != hr_)
    throw InvalidArgument(fn, "grid", grid.empty() ? std::string("(empty)") : ToString(grid.hr_shape()),
                          "a grid over the model's HR grid " + ToString(hr_));
  if (int(node_psfs.size()) != grid.nodes())
    throw InvalidArgument(fn, "node_psfs", std::to_string(node_psfs.size()) + " nodes",
                          std::to_string(grid.nodes()) + " (one per node of the grid)");
  MultiFrameModel out = *this;
  out.field_grid_ = grid;
  std::vector<OperatorPtr> stack_terms;
  std::vector<std::vector<OperatorPtr>> frame_terms(frames());
  for (int k = 0; k < grid.nodes(); ++k) {
    if (int(node_psfs[k].size()) != frames())
      throw InvalidArgument(fn, "node_psfs[" + std::to_string(k) + "]", std::to_string(node_psfs[k].size()) + " PSFs",
                            std::to_string(frames()) + " (one per frame)");
    const MultiFrameModel node = FromKernels(hr_, r_, node_psfs[k]);
    const OperatorPtr weight = Mask(grid.WeightMap(k));
    // Σ_k A_k ∘ diag(w_k): the aliased stack of node k's frames after the object's weighting.
    stack_terms.push_back(Compose(node.Operator(), weight));
    for (int i = 0; i < frames(); ++i) frame_terms[i].push_back(Compose(node.FrameOperator(i), weight));
  }
  out.op_ = stack_terms.size() == 1 ? stack_terms.front() : Sum(std::move(stack_terms));
  for (int i = 0; i < frames(); ++i)
    out.frame_ops_[i] = frame_terms[i].size() == 1 ? frame_terms[i].front() : Sum(std::move(frame_terms[i]));
  return out;
}

ImageStack MultiFrameModel::Render(const Image& x) const {
  if (ShapeOf(x) != hr_)
    throw InvalidArgument("MultiFrameModel::Render", "object shape", ToString(ShapeOf(x)), ToString(hr_));
  return Unflatten(op_->Apply(AsVector(x)));
}

Vector MultiFrameModel::Flatten(const ImageStack& frames) const {
  CheckArgument(static_cast<int>(frames.size()) == this->frames(), "MultiFrameModel::Flatten", "frame count",
                frames.size(), std::to_string(this->frames()));
  const Shape lr = lr_shape();
  Vector y(op_->rows());
  for (std::size_t i = 0; i < frames.size(); ++i) {
    if (ShapeOf(frames[i]) != lr)
      throw InvalidArgument("MultiFrameModel::Flatten", "frame " + std::to_string(i) + " shape",
                            ToString(ShapeOf(frames[i])), ToString(lr));
    y.segment(i * lr.size(), lr.size()) = AsVector(frames[i]);
  }
  return y;
}

ImageStack MultiFrameModel::Unflatten(const Vector& y) const {
  CheckArgument(y.size() == op_->rows(), "MultiFrameModel::Unflatten", "size", y.size(),
                std::to_string(op_->rows()));
  const Shape lr = lr_shape();
  ImageStack out;
  for (int i = 0; i < frames(); ++i) out.push_back(ToImage(y.segment(i * lr.size(), lr.size()), lr));
  return out;
}

Complex MultiFrameModel::PixelTransfer(Index fy, Index fx) const { return box_y_[fy] * box_x_[fx]; }

Complex MultiFrameModel::Otf(int i, Index fy, Index fx) const {
  const ComplexImage& h = *otfs_[i];
  if (fx < h.cols()) return h(fy, fx);
  return std::conj(h(fy == 0 ? 0 : hr_.rows - fy, hr_.cols - fx));  // (−fy) mod rows without a division
}

Eigen::MatrixXcd MultiFrameModel::AliasedSystem(Index uy, Index ux) const {
  const Shape lr = lr_shape();
  const int n = frames();
  Eigen::MatrixXcd a(n, r_ * r_);
  const double inv = 1.0 / (r_ * r_);
  const Index half_cols = hr_.cols / 2 + 1;
  for (int ky = 0; ky < r_; ++ky)
    for (int kx = 0; kx < r_; ++kx) {
      const Index fy = uy + ky * lr.rows, fx = ux + kx * lr.cols;
      const Complex b = PixelTransfer(fy, fx) * inv;
      // Otf(i, fy, fx) for every frame: the stored half spectrum, or the conjugate of its mirror.
      if (fx < half_cols) {
        for (int i = 0; i < n; ++i) a(i, ky * r_ + kx) = b * (*otfs_[i])(fy, fx);
      } else {
        const Index my = fy == 0 ? 0 : hr_.rows - fy, mx = hr_.cols - fx;
        for (int i = 0; i < n; ++i) a(i, ky * r_ + kx) = b * std::conj((*otfs_[i])(my, mx));
      }
    }
  return a;
}

}  // namespace aosr
