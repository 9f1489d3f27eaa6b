// The linear-operator vocabulary that carries aosr's single forward model (DESIGN.md §3).
//
// A LinearOperator A maps R^cols -> R^rows. Images enter and leave as flat row-major vectors
// (see AsVector/AsImage in image.hpp). Every operator supplies
//   Apply:         y = A x
//   ApplyAdjoint:  x = Aᵀ y       (the exact adjoint under the plain Euclidean inner product)
//   ApplyNormal:   z = AᵀA x      (defaults to ApplyAdjoint(Apply(x)); override when cheaper)
// Operators are immutable once built and shared by std::shared_ptr<const LinearOperator>, so the
// simulator, every solver and the phase-design objective can hold the same model.
//
// Composition is in maths order: Compose(A, B) is A∘B, i.e. x -> A(B(x)).
//   Stack({A1..An}) = [A1; ...; An]   (the frames of a sequence; its adjoint sums)
//   Sum({A1..An})   = A1 + ... + An
//   Scale(a, A)     = a A
//   Adjoint(A) = Aᵀ,  Normal(A) = AᵀA
//
// API rules for every operator here and in other layers:
//  * Public Apply* check sizes and throw InvalidArgument naming the operator; the private *Impl
//    receive correctly sized arguments and write every output element.
//  * Nothing in this header allocates per element; large intermediates are per call.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "aosr/core/image.hpp"

namespace aosr {

class LinearOperator {
 public:
  using ConstRef = Eigen::Ref<const Vector>;
  using Ref = Eigen::Ref<Vector>;

  virtual ~LinearOperator() = default;
  LinearOperator(const LinearOperator&) = delete;
  LinearOperator& operator=(const LinearOperator&) = delete;

  Index rows() const { return rows_; }
  Index cols() const { return cols_; }
  // A short human-readable description, e.g. "Compose(Decimate(r=2), Convolve(128x128))".
  const std::string& name() const { return name_; }

  void Apply(ConstRef x, Ref y) const;
  void ApplyAdjoint(ConstRef y, Ref x) const;
  void ApplyNormal(ConstRef x, Ref z) const;
  Vector Apply(ConstRef x) const;
  Vector ApplyAdjoint(ConstRef y) const;
  Vector ApplyNormal(ConstRef x) const;

 protected:
  LinearOperator(Index rows, Index cols, std::string name);

 private:
  virtual void ApplyImpl(ConstRef x, Ref y) const = 0;
  virtual void ApplyAdjointImpl(ConstRef y, Ref x) const = 0;
  virtual void ApplyNormalImpl(ConstRef x, Ref z) const;

  Index rows_;
  Index cols_;
  std::string name_;
};

using OperatorPtr = std::shared_ptr<const LinearOperator>;

// A∘B. Requires a->cols() == b->rows().
OperatorPtr Compose(OperatorPtr a, OperatorPtr b);
// Vertical stack; all parts must share cols(). Adjoint sums the parts' adjoints.
OperatorPtr Stack(std::vector<OperatorPtr> parts);
// Sum of operators of identical shape.
OperatorPtr Sum(std::vector<OperatorPtr> parts);
// alpha * A (alpha finite).
OperatorPtr Scale(double alpha, OperatorPtr a);
// Aᵀ as an operator (Apply and ApplyAdjoint swapped).
OperatorPtr Adjoint(OperatorPtr a);
// AᵀA as a (square, self-adjoint) operator; uses a's ApplyNormal, so a cheap normal is kept.
OperatorPtr Normal(OperatorPtr a);
// The n x n identity.
OperatorPtr Identity(Index n);

}  // namespace aosr
