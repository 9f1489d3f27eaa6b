#include "aosr/core/forward_model.hpp"

#include <cmath>

#include "aosr/core/error.hpp"
#include "aosr/core/fft.hpp"
#include "aosr/core/operators.hpp"

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

}  // namespace

MultiFrameModel::MultiFrameModel(Shape hr, int r, std::vector<ComplexImage> otfs)
    : hr_(hr), r_(r), otfs_(std::move(otfs)) {
  CheckArgument(hr.rows > 0 && hr.cols > 0, "MultiFrameModel", "hr_shape", ToString(hr), "positive");
  CheckArgument(r >= 1, "MultiFrameModel", "r", r, ">= 1");
  if (hr.rows % r || hr.cols % r)
    throw InvalidArgument("MultiFrameModel", "r", std::to_string(r), "a divisor of the HR grid " + ToString(hr));
  CheckArgument(!otfs_.empty(), "MultiFrameModel", "otfs", "empty", "at least one frame");
  const OperatorPtr decimate = Decimate(hr, r);
  std::vector<OperatorPtr> parts;
  for (std::size_t i = 0; i < otfs_.size(); ++i) {
    if (ShapeOf(otfs_[i]) != Shape{hr.rows, hr.cols / 2 + 1})
      throw InvalidArgument("MultiFrameModel", "otf " + std::to_string(i) + " shape", ToString(ShapeOf(otfs_[i])),
                            ToString(Shape{hr.rows, hr.cols / 2 + 1}) + " (half spectrum of the HR grid)");
    // The explicit Fourier formulas below must see the same (real-kernel) transfer function that the
    // spatial operator's c2r applies.
    otfs_[i] = HermitianProjection(otfs_[i], hr.cols);
    frame_ops_.push_back(Compose(decimate, PeriodicConvolution(hr, otfs_[i])));
    parts.push_back(frame_ops_.back());
  }
  op_ = Stack(parts);
  box_y_ = BoxTransfer(hr.rows, r);
  box_x_ = BoxTransfer(hr.cols, r);
}

MultiFrameModel MultiFrameModel::FromKernels(Shape hr, int r, const ImageStack& centred_psfs) {
  std::vector<ComplexImage> otfs;
  for (const Image& k : centred_psfs) otfs.push_back(TransferFunction(hr, k));
  return MultiFrameModel(hr, r, std::move(otfs));
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
  const ComplexImage& h = otfs_[i];
  if (fx < h.cols()) return h(fy, fx);
  return std::conj(h((hr_.rows - fy) % hr_.rows, hr_.cols - fx));
}

Eigen::MatrixXcd MultiFrameModel::AliasedSystem(Index uy, Index ux) const {
  const Shape lr = lr_shape();
  const int n = frames();
  Eigen::MatrixXcd a(n, r_ * r_);
  const double inv = 1.0 / (r_ * r_);
  for (int ky = 0; ky < r_; ++ky)
    for (int kx = 0; kx < r_; ++kx) {
      const Index fy = uy + ky * lr.rows, fx = ux + kx * lr.cols;
      const Complex b = PixelTransfer(fy, fx) * inv;
      for (int i = 0; i < n; ++i) a(i, ky * r_ + kx) = b * Otf(i, fy, fx);
    }
  return a;
}

}  // namespace aosr
