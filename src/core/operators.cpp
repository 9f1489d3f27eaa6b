#include "aosr/core/operators.hpp"

#include <cmath>

#include "aosr/core/error.hpp"
#include "aosr/core/fft.hpp"

namespace aosr {
namespace {

class PeriodicConvolutionOp final : public LinearOperator {
 public:
  PeriodicConvolutionOp(Shape s, std::shared_ptr<const ComplexImage> otf)
      : LinearOperator(s.size(), s.size(), "Convolve(" + ToString(s) + ")"), s_(s), otf_(std::move(otf)) {}

 private:
  void Filter(ConstRef x, Ref y, int mode) const {
    ComplexImage X = FftR2C(AsImage(Vector(x), s_));
    const ComplexImage& h = *otf_;
    if (mode == 0) X *= h;
    else if (mode == 1) X *= h.conjugate();
    else X *= h.abs2().cast<Complex>();
    y = AsVector(FftC2R(X, s_.cols));
  }
  void ApplyImpl(ConstRef x, Ref y) const override { Filter(x, y, 0); }
  void ApplyAdjointImpl(ConstRef y, Ref x) const override { Filter(y, x, 1); }
  void ApplyNormalImpl(ConstRef x, Ref z) const override { Filter(x, z, 2); }
  Shape s_;
  std::shared_ptr<const ComplexImage> otf_;  // shared with a MultiFrameModel's transfer functions (no copy)
};

class DecimateOp final : public LinearOperator {
 public:
  DecimateOp(Shape hr, int r)
      : LinearOperator(hr.size() / (r * r), hr.size(), "Decimate(r=" + std::to_string(r) + ")"),
        hr_(hr), r_(r) {}

 private:
  void ApplyImpl(ConstRef x, Ref y) const override {
    const Index lr_cols = hr_.cols / r_;
    y.setZero();
    for (Index Y = 0; Y < hr_.rows; ++Y) {
      const double* row = x.data() + Y * hr_.cols;
      double* out = y.data() + (Y / r_) * lr_cols;
      for (Index X = 0; X < hr_.cols; ++X) out[X / r_] += row[X];
    }
  }
  void ApplyAdjointImpl(ConstRef y, Ref x) const override {
    const Index lr_cols = hr_.cols / r_;
    for (Index Y = 0; Y < hr_.rows; ++Y) {
      const double* in = y.data() + (Y / r_) * lr_cols;
      double* row = x.data() + Y * hr_.cols;
      for (Index X = 0; X < hr_.cols; ++X) row[X] = in[X / r_];
    }
  }
  Shape hr_;
  Index r_;
};

class DiagonalOp final : public LinearOperator {
 public:
  explicit DiagonalOp(const Image& w)
      : LinearOperator(w.size(), w.size(), "Mask(" + ToString(ShapeOf(w)) + ")"), w_(AsVector(w)) {}

 private:
  void ApplyImpl(ConstRef x, Ref y) const override { y = w_.cwiseProduct(x); }
  void ApplyAdjointImpl(ConstRef y, Ref x) const override { x = w_.cwiseProduct(y); }
  void ApplyNormalImpl(ConstRef x, Ref z) const override { z = w_.cwiseAbs2().cwiseProduct(x); }
  Vector w_;
};

class GradientOp final : public LinearOperator {
 public:
  GradientOp(Shape s, Boundary b)
      : LinearOperator(2 * s.size(), s.size(),
                       std::string("Gradient(") + (b == Boundary::kPeriodic ? "periodic" : "neumann") + ")"),
        s_(s), periodic_(b == Boundary::kPeriodic) {}

 private:
  // Index of the forward neighbour along an axis, or -1 where the Neumann difference is zero.
  Index Next(Index i, Index n) const { return i + 1 < n ? i + 1 : (periodic_ ? 0 : -1); }

  void ApplyImpl(ConstRef x, Ref g) const override {
    const Index R = s_.rows, C = s_.cols, n = s_.size();
    for (Index y = 0; y < R; ++y) {
      const Index yn = Next(y, R);
      for (Index c = 0; c < C; ++c) {
        const Index cn = Next(c, C);
        const double v = x[y * C + c];
        g[y * C + c] = yn < 0 ? 0.0 : x[yn * C + c] - v;
        g[n + y * C + c] = cn < 0 ? 0.0 : x[y * C + cn] - v;
      }
    }
  }
  // Adjoint of the forward difference: each difference d = x[next] - x[i] sends +d to next, -d to i.
  void ApplyAdjointImpl(ConstRef g, Ref x) const override {
    const Index R = s_.rows, C = s_.cols, n = s_.size();
    x.setZero();
    for (Index y = 0; y < R; ++y) {
      const Index yn = Next(y, R);
      for (Index c = 0; c < C; ++c) {
        const Index cn = Next(c, C);
        if (yn >= 0) {
          const double d = g[y * C + c];
          x[yn * C + c] += d;
          x[y * C + c] -= d;
        }
        if (cn >= 0) {
          const double d = g[n + y * C + c];
          x[y * C + cn] += d;
          x[y * C + c] -= d;
        }
      }
    }
  }
  Shape s_;
  bool periodic_;
};

class PadOp final : public LinearOperator {
 public:
  // pad=true: inner -> outer (embed); pad=false: outer -> inner (crop).
  PadOp(Shape inner, Shape outer, Index top, Index left, bool pad)
      : LinearOperator(pad ? outer.size() : inner.size(), pad ? inner.size() : outer.size(),
                       std::string(pad ? "ZeroPad(" : "Crop(") + ToString(inner) + " in " + ToString(outer) + ")"),
        inner_(inner), outer_(outer), top_(top), left_(left), pad_(pad) {}

 private:
  void Embed(ConstRef in, Ref out) const {
    out.setZero();
    for (Index y = 0; y < inner_.rows; ++y)
      out.segment((y + top_) * outer_.cols + left_, inner_.cols) = in.segment(y * inner_.cols, inner_.cols);
  }
  void Extract(ConstRef in, Ref out) const {
    for (Index y = 0; y < inner_.rows; ++y)
      out.segment(y * inner_.cols, inner_.cols) = in.segment((y + top_) * outer_.cols + left_, inner_.cols);
  }
  void ApplyImpl(ConstRef x, Ref y) const override { pad_ ? Embed(x, y) : Extract(x, y); }
  void ApplyAdjointImpl(ConstRef y, Ref x) const override { pad_ ? Extract(y, x) : Embed(y, x); }
  Shape inner_, outer_;
  Index top_, left_;
  bool pad_;
};

void CheckShape(const char* fn, Shape s) {
  CheckArgument(s.rows > 0 && s.cols > 0, fn, "shape", ToString(s), "positive rows and cols");
}

void CheckWindow(const char* fn, Shape inner, Shape outer, Index top, Index left) {
  CheckShape(fn, inner);
  CheckShape(fn, outer);
  if (top < 0 || left < 0 || top + inner.rows > outer.rows || left + inner.cols > outer.cols)
    throw InvalidArgument(fn, "window", ToString(inner) + " at (" + std::to_string(top) + ", " + std::to_string(left) + ")",
                          "inside the outer grid " + ToString(outer));
}

}  // namespace

ComplexImage TransferFunction(Shape s, const Image& centred_kernel) {
  CheckShape("TransferFunction", s);
  CheckArgument(AllFinite(centred_kernel), "TransferFunction", "kernel", "non-finite values", "finite values");
  return FftR2C(CentredToOrigin(centred_kernel, s));
}

ComplexImage ShiftTransfer(Shape s, double dy, double dx) {
  CheckShape("ShiftTransfer", s);
  CheckArgument(std::isfinite(dy) && std::isfinite(dx), "ShiftTransfer", "shift",
                ToString(dy) + ", " + ToString(dx), "finite values");
  ComplexImage t(s.rows, s.cols / 2 + 1);
  for (Index fy = 0; fy < s.rows; ++fy)
    for (Index fx = 0; fx < t.cols(); ++fx) {
      const double ph = -2.0 * M_PI *
                        (double(SignedFrequency(fy, s.rows)) * dy / double(s.rows) + double(fx) * dx / double(s.cols));
      t(fy, fx) = std::polar(1.0, ph);
    }
  return HermitianProjection(t, s.cols);
}

OperatorPtr PeriodicConvolution(Shape s, ComplexImage otf_half) {
  CheckShape("PeriodicConvolution", s);
  if (otf_half.rows() != s.rows || otf_half.cols() != s.cols / 2 + 1)
    throw InvalidArgument("PeriodicConvolution", "otf_half shape", ToString(ShapeOf(otf_half)),
                          ToString(Shape{s.rows, s.cols / 2 + 1}) + " (half spectrum of the grid)");
  CheckArgument(AllFinite(otf_half), "PeriodicConvolution", "otf_half", "non-finite values", "finite values");
  HermitianProjectInPlace(&otf_half, s.cols);
  return std::make_shared<PeriodicConvolutionOp>(s, std::make_shared<const ComplexImage>(std::move(otf_half)));
}

OperatorPtr PeriodicConvolution(Shape s, std::shared_ptr<const ComplexImage> otf_half_hermitian) {
  CheckShape("PeriodicConvolution", s);
  CheckArgument(otf_half_hermitian != nullptr, "PeriodicConvolution", "otf_half", "null", "a transfer function");
  if (otf_half_hermitian->rows() != s.rows || otf_half_hermitian->cols() != s.cols / 2 + 1)
    throw InvalidArgument("PeriodicConvolution", "otf_half shape", ToString(ShapeOf(*otf_half_hermitian)),
                          ToString(Shape{s.rows, s.cols / 2 + 1}) + " (half spectrum of the grid)");
  return std::make_shared<PeriodicConvolutionOp>(s, std::move(otf_half_hermitian));
}

OperatorPtr PeriodicConvolutionFromKernel(Shape s, const Image& centred_kernel) {
  return PeriodicConvolution(s, TransferFunction(s, centred_kernel));
}

OperatorPtr LinearConvolution(Shape s, const Image& centred_kernel) {
  CheckShape("LinearConvolution", s);
  CheckShape("LinearConvolution", ShapeOf(centred_kernel));
  // Padding by the kernel's extent on each side keeps every wrapped contribution out of the crop.
  const Index pr = centred_kernel.rows(), pc = centred_kernel.cols();
  const Shape padded{s.rows + pr, s.cols + pc};
  const Index top = pr / 2, left = pc / 2;
  return Compose(Crop(padded, s, top, left),
                 Compose(PeriodicConvolutionFromKernel(padded, centred_kernel), ZeroPad(s, padded, top, left)));
}

OperatorPtr Decimate(Shape hr, int r) {
  CheckShape("Decimate", hr);
  CheckArgument(r >= 1, "Decimate", "r", r, ">= 1");
  if (hr.rows % r != 0 || hr.cols % r != 0)
    throw InvalidArgument("Decimate", "r", std::to_string(r), "a divisor of the HR grid " + ToString(hr));
  return std::make_shared<DecimateOp>(hr, r);
}

OperatorPtr Mask(const Image& weights) {
  CheckShape("Mask", ShapeOf(weights));
  CheckArgument(AllFinite(weights), "Mask", "weights", "non-finite values", "finite values");
  return std::make_shared<DiagonalOp>(weights);
}

OperatorPtr Gradient(Shape s, Boundary boundary) {
  CheckShape("Gradient", s);
  return std::make_shared<GradientOp>(s, boundary);
}

OperatorPtr ZeroPad(Shape inner, Shape outer, Index top, Index left) {
  CheckWindow("ZeroPad", inner, outer, top, left);
  return std::make_shared<PadOp>(inner, outer, top, left, true);
}

OperatorPtr Crop(Shape outer, Shape inner, Index top, Index left) {
  CheckWindow("Crop", inner, outer, top, left);
  return std::make_shared<PadOp>(inner, outer, top, left, false);
}

}  // namespace aosr
