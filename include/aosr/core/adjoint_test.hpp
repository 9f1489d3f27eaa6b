// The adjoint test (DESIGN.md §6), a library function so every layer's tests call the same check.
//
// For random x, y (fixed seed) it returns
//     |<Ax, y> - <x, Aᵀy>| / (|<Ax, y>| + |<x, Aᵀy>|)
// normalised by the inner products themselves, not by norms: a norm-normalised test passes wrong
// adjoints on large images. Exact operators give ~1e-15; the suite requires < 1e-10. It also checks
// ApplyNormal against ApplyAdjoint(Apply(x)) and reports the larger relative discrepancy.
#pragma once

#include <cstdint>

#include "aosr/core/linear_operator.hpp"

namespace aosr {

struct AdjointTestResult {
  double adjoint_error = 0.0;  // relative <Ax,y> vs <x,Aᵀy> mismatch
  double normal_error = 0.0;   // ||AᵀA x - ApplyNormal(x)|| / ||AᵀA x||
  double worst() const { return adjoint_error > normal_error ? adjoint_error : normal_error; }
};

AdjointTestResult AdjointTest(const LinearOperator& op, std::uint64_t seed = 1);

}  // namespace aosr
