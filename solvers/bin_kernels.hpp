// Private to solvers/: the small dense kernels of the per-frequency-bin solvers (fourier_normal_system.cpp,
// tikhonov.cpp). Matrices are row-major on caller-owned memory, so a bin costs no allocation.
#pragma once

#include "aosr/core/image.hpp"

namespace aosr::bins {

// In-place Cholesky G = L Lᴴ of an n x n Hermitian matrix (row-major; the lower triangle is read). Stores L
// in the lower triangle with 1/L_ii on the diagonal (no complex division in the substitutions). False if a
// pivot falls to `pivot_floor` or below (singular to rounding; 0 accepts any positive pivot, like Eigen's LLT).
inline bool CholeskyInPlace(Complex* g, int n, double pivot_floor) {
  for (int j = 0; j < n; ++j) {
    double d = g[j * n + j].real();
    for (int k = 0; k < j; ++k) d -= std::norm(g[j * n + k]);
    if (!(d > pivot_floor)) return false;
    const double inv = 1.0 / std::sqrt(d);
    g[j * n + j] = inv;
    for (int i = j + 1; i < n; ++i) {
      Complex s = g[i * n + j];
      for (int k = 0; k < j; ++k) s -= g[i * n + k] * std::conj(g[j * n + k]);
      g[i * n + j] = s * inv;
    }
  }
  return true;
}

// Solves L Lᴴ x = b in place (v: b in, x out) for a factor from CholeskyInPlace. RR > 0 fixes the size at
// compile time (the common sizes unroll); 0 means `n` at run time.
template <int RR>
inline void CholeskySubstitution(const Complex* l, int n, Complex* v) {
  const int size = RR > 0 ? RR : n;
  for (int i = 0; i < size; ++i) {  // L w = b
    Complex s = v[i];
    for (int j = 0; j < i; ++j) s -= l[i * size + j] * v[j];
    v[i] = s * l[i * size + i].real();
  }
  for (int i = size - 1; i >= 0; --i) {  // Lᴴ x = w
    Complex s = v[i];
    for (int j = i + 1; j < size; ++j) s -= std::conj(l[j * size + i]) * v[j];
    v[i] = s * l[i * size + i].real();
  }
}

inline void Substitute(const Complex* l, int n, Complex* v) {
  switch (n) {
    case 2:
      return CholeskySubstitution<2>(l, n, v);
    case 4:
      return CholeskySubstitution<4>(l, n, v);
    case 8:
      return CholeskySubstitution<8>(l, n, v);
    case 9:
      return CholeskySubstitution<9>(l, n, v);
    case 16:
      return CholeskySubstitution<16>(l, n, v);
    default:
      return CholeskySubstitution<0>(l, n, v);
  }
}

}  // namespace aosr::bins
