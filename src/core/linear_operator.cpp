#include "aosr/core/linear_operator.hpp"

#include <cmath>

#include "aosr/core/error.hpp"

namespace aosr {

LinearOperator::LinearOperator(Index rows, Index cols, std::string name)
    : rows_(rows), cols_(cols), name_(std::move(name)) {
  CheckArgument(rows >= 0 && cols >= 0, "LinearOperator", "shape", ToString(Shape{rows, cols}),
                "non-negative rows and cols");
}

namespace {
void CheckSize(const std::string& op, const char* what, Index got, Index want) {
  if (got != want)
    throw InvalidArgument(op, what, std::to_string(got) + " elements", std::to_string(want) + " elements");
}
}  // namespace

void LinearOperator::Apply(ConstRef x, Ref y) const {
  CheckSize(name_ + " Apply", "x", x.size(), cols_);
  CheckSize(name_ + " Apply", "y", y.size(), rows_);
  ApplyImpl(x, y);
}
void LinearOperator::ApplyAdjoint(ConstRef y, Ref x) const {
  CheckSize(name_ + " ApplyAdjoint", "y", y.size(), rows_);
  CheckSize(name_ + " ApplyAdjoint", "x", x.size(), cols_);
  ApplyAdjointImpl(y, x);
}
void LinearOperator::ApplyNormal(ConstRef x, Ref z) const {
  CheckSize(name_ + " ApplyNormal", "x", x.size(), cols_);
  CheckSize(name_ + " ApplyNormal", "z", z.size(), cols_);
  ApplyNormalImpl(x, z);
}
Vector LinearOperator::Apply(ConstRef x) const {
  Vector y(rows_);
  Apply(x, y);
  return y;
}
Vector LinearOperator::ApplyAdjoint(ConstRef y) const {
  Vector x(cols_);
  ApplyAdjoint(y, x);
  return x;
}
Vector LinearOperator::ApplyNormal(ConstRef x) const {
  Vector z(cols_);
  ApplyNormal(x, z);
  return z;
}
void LinearOperator::ApplyNormalImpl(ConstRef x, Ref z) const {
  Vector y(rows_);
  ApplyImpl(x, y);
  ApplyAdjointImpl(y, z);
}

namespace {

class ComposeOp final : public LinearOperator {
 public:
  ComposeOp(OperatorPtr a, OperatorPtr b)
      : LinearOperator(a->rows(), b->cols(), "Compose(" + a->name() + ", " + b->name() + ")"),
        a_(std::move(a)), b_(std::move(b)) {}

 private:
  void ApplyImpl(ConstRef x, Ref y) const override {
    Vector t(b_->rows());
    b_->Apply(x, t);
    a_->Apply(t, y);
  }
  void ApplyAdjointImpl(ConstRef y, Ref x) const override {
    Vector t(a_->cols());
    a_->ApplyAdjoint(y, t);
    b_->ApplyAdjoint(t, x);
  }
  // (AB)ᵀ(AB) = Bᵀ(AᵀA)B: lets an inner operator's cheap normal (e.g. a Fourier-diagonal one) be used.
  void ApplyNormalImpl(ConstRef x, Ref z) const override {
    Vector t(b_->rows()), u(b_->rows());
    b_->Apply(x, t);
    a_->ApplyNormal(t, u);
    b_->ApplyAdjoint(u, z);
  }
  OperatorPtr a_, b_;
};

std::string JoinNames(const char* head, const std::vector<OperatorPtr>& parts) {
  std::string s = std::string(head) + "(";
  for (std::size_t i = 0; i < parts.size(); ++i) {
    if (i == 3 && parts.size() > 4) {
      s += ", ... " + std::to_string(parts.size() - 3) + " more";
      break;
    }
    s += (i ? ", " : "") + parts[i]->name();
  }
  return s + ")";
}

Index TotalRows(const std::vector<OperatorPtr>& parts) {
  Index n = 0;
  for (const auto& p : parts) n += p->rows();
  return n;
}

class StackOp final : public LinearOperator {
 public:
  explicit StackOp(std::vector<OperatorPtr> parts)
      : LinearOperator(TotalRows(parts), parts.front()->cols(), JoinNames("Stack", parts)),
        parts_(std::move(parts)) {}

 private:
  void ApplyImpl(ConstRef x, Ref y) const override {
    Index off = 0;
    for (const auto& p : parts_) {
      p->Apply(x, y.segment(off, p->rows()));
      off += p->rows();
    }
  }
  void ApplyAdjointImpl(ConstRef y, Ref x) const override {
    x.setZero();
    Vector t(cols());
    Index off = 0;
    for (const auto& p : parts_) {
      p->ApplyAdjoint(y.segment(off, p->rows()), t);
      x += t;
      off += p->rows();
    }
  }
  void ApplyNormalImpl(ConstRef x, Ref z) const override {
    z.setZero();
    Vector t(cols());
    for (const auto& p : parts_) {
      p->ApplyNormal(x, t);
      z += t;
    }
  }
  std::vector<OperatorPtr> parts_;
};

class SumOp final : public LinearOperator {
 public:
  explicit SumOp(std::vector<OperatorPtr> parts)
      : LinearOperator(parts.front()->rows(), parts.front()->cols(), JoinNames("Sum", parts)),
        parts_(std::move(parts)) {}

 private:
  void ApplyImpl(ConstRef x, Ref y) const override {
    y.setZero();
    Vector t(rows());
    for (const auto& p : parts_) {
      p->Apply(x, t);
      y += t;
    }
  }
  void ApplyAdjointImpl(ConstRef y, Ref x) const override {
    x.setZero();
    Vector t(cols());
    for (const auto& p : parts_) {
      p->ApplyAdjoint(y, t);
      x += t;
    }
  }
  std::vector<OperatorPtr> parts_;
};

class ScaleOp final : public LinearOperator {
 public:
  ScaleOp(double alpha, OperatorPtr a)
      : LinearOperator(a->rows(), a->cols(), "Scale(" + ToString(alpha) + ", " + a->name() + ")"),
        alpha_(alpha), a_(std::move(a)) {}

 private:
  void ApplyImpl(ConstRef x, Ref y) const override {
    a_->Apply(x, y);
    y *= alpha_;
  }
  void ApplyAdjointImpl(ConstRef y, Ref x) const override {
    a_->ApplyAdjoint(y, x);
    x *= alpha_;
  }
  void ApplyNormalImpl(ConstRef x, Ref z) const override {
    a_->ApplyNormal(x, z);
    z *= alpha_ * alpha_;
  }
  double alpha_;
  OperatorPtr a_;
};

class IdentityOp final : public LinearOperator {
 public:
  explicit IdentityOp(Index n) : LinearOperator(n, n, "Identity(" + std::to_string(n) + ")") {}

 private:
  void ApplyImpl(ConstRef x, Ref y) const override { y = x; }
  void ApplyAdjointImpl(ConstRef y, Ref x) const override { x = y; }
  void ApplyNormalImpl(ConstRef x, Ref z) const override { z = x; }
};

class AdjointOp final : public LinearOperator {
 public:
  explicit AdjointOp(OperatorPtr a) : LinearOperator(a->cols(), a->rows(), "Adjoint(" + a->name() + ")"), a_(std::move(a)) {}

 private:
  void ApplyImpl(ConstRef x, Ref y) const override { a_->ApplyAdjoint(x, y); }
  void ApplyAdjointImpl(ConstRef y, Ref x) const override { a_->Apply(y, x); }
  OperatorPtr a_;
};

class NormalOp final : public LinearOperator {
 public:
  explicit NormalOp(OperatorPtr a) : LinearOperator(a->cols(), a->cols(), "Normal(" + a->name() + ")"), a_(std::move(a)) {}

 private:
  void ApplyImpl(ConstRef x, Ref y) const override { a_->ApplyNormal(x, y); }
  void ApplyAdjointImpl(ConstRef y, Ref x) const override { a_->ApplyNormal(y, x); }
  OperatorPtr a_;
};

void CheckNotNull(const OperatorPtr& p, const char* fn, const char* arg) {
  if (!p) throw InvalidArgument(fn, arg, "null", "a non-null operator");
}

}  // namespace

OperatorPtr Compose(OperatorPtr a, OperatorPtr b) {
  CheckNotNull(a, "Compose", "a");
  CheckNotNull(b, "Compose", "b");
  if (a->cols() != b->rows())
    throw InvalidArgument("Compose", "shapes", a->name() + " has cols " + std::to_string(a->cols()) +
                                                   " but " + b->name() + " has rows " + std::to_string(b->rows()),
                          "a.cols == b.rows");
  return std::make_shared<ComposeOp>(std::move(a), std::move(b));
}

OperatorPtr Stack(std::vector<OperatorPtr> parts) {
  CheckArgument(!parts.empty(), "Stack", "parts", "empty list", "at least one operator");
  for (const auto& p : parts) {
    CheckNotNull(p, "Stack", "parts[i]");
    if (p->cols() != parts.front()->cols())
      throw InvalidArgument("Stack", "cols", std::to_string(p->cols()),
                            "all parts with cols " + std::to_string(parts.front()->cols()));
  }
  return std::make_shared<StackOp>(std::move(parts));
}

OperatorPtr Sum(std::vector<OperatorPtr> parts) {
  CheckArgument(!parts.empty(), "Sum", "parts", "empty list", "at least one operator");
  for (const auto& p : parts) {
    CheckNotNull(p, "Sum", "parts[i]");
    if (p->rows() != parts.front()->rows() || p->cols() != parts.front()->cols())
      throw InvalidArgument("Sum", "shape", ToString(Shape{p->rows(), p->cols()}),
                            "all parts " + ToString(Shape{parts.front()->rows(), parts.front()->cols()}));
  }
  return std::make_shared<SumOp>(std::move(parts));
}

OperatorPtr Scale(double alpha, OperatorPtr a) {
  CheckNotNull(a, "Scale", "a");
  CheckArgument(std::isfinite(alpha), "Scale", "alpha", alpha, "a finite number");
  return std::make_shared<ScaleOp>(alpha, std::move(a));
}

OperatorPtr Adjoint(OperatorPtr a) {
  CheckNotNull(a, "Adjoint", "a");
  return std::make_shared<AdjointOp>(std::move(a));
}

OperatorPtr Normal(OperatorPtr a) {
  CheckNotNull(a, "Normal", "a");
  return std::make_shared<NormalOp>(std::move(a));
}

OperatorPtr Identity(Index n) {
  CheckArgument(n >= 0, "Identity", "n", n, ">= 0");
  return std::make_shared<IdentityOp>(n);
}

}  // namespace aosr
