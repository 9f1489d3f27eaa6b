// Private to solvers/: the small dense kernels of the per-frequency-bin solvers (fourier_normal_system.cpp,
// tikhonov.cpp). Matrices are row-major on caller-owned memory, so a bin costs no allocation.
#pragma once

#include <algorithm>
#include <cmath>
#include <limits>

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
// The complex products are written in real arithmetic: the same operations in the same order as
// std::complex's (the same bits for finite values), without its NaN-recovery branch in the inner loops.
template <int RR>
inline void CholeskySubstitution(const Complex* l, int n, Complex* v) {
  const int size = RR > 0 ? RR : n;
  const double* ld = reinterpret_cast<const double*>(l);  // [re, im] pairs
  double* vd = reinterpret_cast<double*>(v);
  for (int i = 0; i < size; ++i) {  // L w = b
    double re = vd[2 * i], im = vd[2 * i + 1];
    for (int j = 0; j < i; ++j) {
      const double lr = ld[2 * (i * size + j)], li = ld[2 * (i * size + j) + 1];
      re -= lr * vd[2 * j] - li * vd[2 * j + 1];
      im -= lr * vd[2 * j + 1] + li * vd[2 * j];
    }
    const double d = ld[2 * (i * size + i)];
    vd[2 * i] = re * d, vd[2 * i + 1] = im * d;
  }
  for (int i = size - 1; i >= 0; --i) {  // Lᴴ x = w
    double re = vd[2 * i], im = vd[2 * i + 1];
    for (int j = i + 1; j < size; ++j) {
      const double lr = ld[2 * (j * size + i)], li = ld[2 * (j * size + i) + 1];  // conj(L_ji)
      re -= lr * vd[2 * j] + li * vd[2 * j + 1];
      im -= lr * vd[2 * j + 1] - li * vd[2 * j];
    }
    const double d = ld[2 * (i * size + i)];
    vd[2 * i] = re * d, vd[2 * i + 1] = im * d;
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

namespace aosr::bins {

// |z|² as re² + im² (std::norm in libstdc++ goes through std::abs, i.e. hypot: 10x slower).
inline double Norm2(Complex z) { return z.real() * z.real() + z.imag() * z.imag(); }

// Eigen-decomposition M = U diag(d) Uᴴ of an n x n Hermitian matrix, allocation-free for the per-bin solvers:
// `m` row-major n x n (both triangles; destroyed), `d` the n eigenvalues ascending, `u` the eigenvectors as
// the columns of a row-major n x n matrix, `work` at least 3n² + 2n doubles. Householder reduction to a
// Hermitian tridiagonal matrix, a diagonal unitary that makes it real, then the implicit QL algorithm with
// Wilkinson shifts on the real symmetric tridiagonal (the scheme of EISPACK's tql2), rotations accumulated.
// Backward stable: each eigenvalue carries an absolute error of a few n ε ||M||₂ (so small eigenvalues of a
// Gram matrix lose digits relative to the largest; FourierSystem refines them, tikhonov.cpp). False if QL does
// not converge in 60 iterations per eigenvalue (non-finite input).
inline bool HermitianEigen(Complex* m, int n, double* d, Complex* u, double* work) {
  if (n <= 0) return true;
  // Scale by a power of two (exact) so that the largest entry is O(1): the rotations below square their inputs.
  double big = 0;
  for (int i = 0; i < n * n; ++i) big = std::max(big, std::max(std::abs(m[i].real()), std::abs(m[i].imag())));
  if (!(big > 0)) {
    if (!(big == 0)) return false;  // NaN
    for (int i = 0; i < n; ++i) {
      d[i] = 0;
      for (int j = 0; j < n; ++j) u[i * n + j] = i == j ? 1.0 : 0.0;
    }
    return true;
  }
  if (!std::isfinite(big)) return false;
  const int scale_exp = -std::ilogb(big);
  const double scale = std::ldexp(1.0, scale_exp);  // a power of two: exact products (entries stay normal)
  for (int i = 0; i < n * n; ++i) m[i] = Complex(m[i].real() * scale, m[i].imag() * scale);
  double* e = work;               // n: real subdiagonal
  double* z = work + n;           // n x n real rotations (row-major)
  Complex* v = reinterpret_cast<Complex*>(work + n + n * n);  // n x n: Householder vectors (row k: vector k)
  double* tau = work + n + 3 * n * n;                           // n
  // Householder: for k = 0 .. n-3 reduce column k below the subdiagonal. H_k = I − τ_k v_k v_kᴴ acts on
  // indices k+1 .. n-1.
  Complex* sub = reinterpret_cast<Complex*>(u);  // complex subdiagonal, kept in u until the end
  for (int k = 0; k + 2 < n; ++k) {
    const int len = n - k - 1;
    Complex* vk = v + k * n;
    double alpha2 = 0;
    for (int i = 0; i < len; ++i) {
      vk[i] = m[(k + 1 + i) * n + k];
      alpha2 += Norm2(vk[i]);
    }
    const double tail2 = alpha2 - Norm2(vk[0]);
    if (!(tail2 > 0)) {  // already tridiagonal in this column
      tau[k] = 0;
      sub[k] = vk[0];
      continue;
    }
    const double alpha = std::sqrt(alpha2), a0 = std::sqrt(Norm2(vk[0]));
    const Complex phase = a0 > 0 ? vk[0] / a0 : Complex(1.0);
    vk[0] += phase * alpha;  // v = x + phase ||x|| e₁, H x = −phase ||x|| e₁
    const double vnorm2 = 2.0 * alpha * (alpha + a0);
    tau[k] = 2.0 / vnorm2;
    sub[k] = -phase * alpha;
    // A₂₂ ← H A₂₂ H:  p = τ A₂₂ v,  K = (τ/2) vᴴp,  q = p − K v,  A₂₂ −= v qᴴ + q vᴴ.
    Complex* p = reinterpret_cast<Complex*>(z);  // scratch (len complex values fit in n² doubles for n >= 2)
    for (int i = 0; i < len; ++i) {
      Complex s = 0;
      const Complex* row = m + (k + 1 + i) * n + (k + 1);
      for (int j = 0; j < len; ++j)
        s += Complex(row[j].real() * vk[j].real() - row[j].imag() * vk[j].imag(),
                     row[j].real() * vk[j].imag() + row[j].imag() * vk[j].real());
      p[i] = tau[k] * s;
    }
    Complex vp = 0;
    for (int i = 0; i < len; ++i) vp += std::conj(vk[i]) * p[i];
    const Complex kk = 0.5 * tau[k] * vp;
    for (int i = 0; i < len; ++i) p[i] -= kk * vk[i];
    for (int i = 0; i < len; ++i) {
      Complex* row = m + (k + 1 + i) * n + (k + 1);
      const Complex vi = vk[i], pi = p[i];
      for (int j = 0; j < len; ++j) {
        const Complex pj = p[j], vj = vk[j];
        row[j] -= Complex(vi.real() * pj.real() + vi.imag() * pj.imag() + pi.real() * vj.real() + pi.imag() * vj.imag(),
                          vi.imag() * pj.real() - vi.real() * pj.imag() + pi.imag() * vj.real() - pi.real() * vj.imag());
      }
    }
  }
  for (int k = 0; k < n; ++k) d[k] = m[k * n + k].real();
  if (n >= 2) sub[n - 2] = m[(n - 1) * n + (n - 2)];
  // D = diag(δ): δ₀ = 1, δ_{k+1} = δ_k s_k/|s_k|, so that Dᴴ T D has the real subdiagonal |s_k|.
  Complex* delta = v + (n - 1) * n;  // the last row of v is unused (k <= n-3)
  delta[0] = 1.0;
  for (int k = 0; k + 1 < n; ++k) {
    const double a = std::sqrt(Norm2(sub[k]));
    e[k] = a;
    delta[k + 1] = a > 0 ? delta[k] * (sub[k] / a) : delta[k];
  }
  e[n - 1] = 0;
  // Implicit QL with Wilkinson shifts on (d, e), rotations accumulated in z (tql2, EISPACK / JAMA).
  for (int i = 0; i < n * n; ++i) z[i] = 0;
  for (int i = 0; i < n; ++i) z[i * n + i] = 1;
  double f = 0, tst1 = 0;
  const double eps = std::numeric_limits<double>::epsilon();
  for (int l = 0; l < n; ++l) {
    tst1 = std::max(tst1, std::abs(d[l]) + std::abs(e[l]));
    int mm = l;
    while (mm < n && !(std::abs(e[mm]) <= eps * tst1)) ++mm;
    if (mm == n) mm = n - 1;
    if (mm > l) {
      int iter = 0;
      do {
        if (++iter > 60) return false;
        double g = d[l];
        double p = (d[l + 1] - g) / (2.0 * e[l]);
        double r = std::sqrt(p * p + 1.0);
        if (p < 0) r = -r;
        d[l] = e[l] / (p + r);
        d[l + 1] = e[l] * (p + r);
        const double dl1 = d[l + 1];
        double h = g - d[l];
        for (int i = l + 2; i < n; ++i) d[i] -= h;
        f += h;
        p = d[mm];
        double c = 1, c2 = 1, c3 = 1, el1 = e[l + 1], s = 0, s2 = 0;
        for (int i = mm - 1; i >= l; --i) {
          c3 = c2;
          c2 = c;
          s2 = s;
          g = c * e[i];
          h = c * p;
          r = std::sqrt(p * p + e[i] * e[i]);
          e[i + 1] = s * r;
          s = e[i] / r;
          c = p / r;
          p = c * d[i] - s * g;
          d[i + 1] = h + s * (c * g + s * d[i]);
          for (int k = 0; k < n; ++k) {
            h = z[k * n + i + 1];
            z[k * n + i + 1] = s * z[k * n + i] + c * h;
            z[k * n + i] = c * z[k * n + i] - s * h;
          }
        }
        p = -s * s2 * c3 * el1 * e[l] / dl1;
        e[l] = s * p;
        d[l] = c * p;
      } while (std::abs(e[l]) > eps * tst1);
    }
    d[l] += f;
    e[l] = 0;
  }
  // Sort ascending (selection sort: n <= 16 here), permuting the columns of z.
  for (int i = 0; i + 1 < n; ++i) {
    int kmin = i;
    for (int j = i + 1; j < n; ++j)
      if (d[j] < d[kmin]) kmin = j;
    if (kmin != i) {
      std::swap(d[i], d[kmin]);
      for (int r = 0; r < n; ++r) std::swap(z[r * n + i], z[r * n + kmin]);
    }
  }
  const double unscale = std::ldexp(1.0, -scale_exp);
  for (int i = 0; i < n; ++i) d[i] *= unscale;
  // U = H₀ H₁ … H_{n-3} D Z.
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j) u[i * n + j] = delta[i] * z[i * n + j];
  for (int k = n - 3; k >= 0; --k) {
    if (tau[k] == 0) continue;
    const Complex* vk = v + k * n;
    const int len = n - k - 1;
    for (int j = 0; j < n; ++j) {
      Complex s = 0;
      for (int i = 0; i < len; ++i) {
        const Complex a = vk[i], b = u[(k + 1 + i) * n + j];
        s += Complex(a.real() * b.real() + a.imag() * b.imag(), a.real() * b.imag() - a.imag() * b.real());
      }
      s *= tau[k];
      for (int i = 0; i < len; ++i) {
        const Complex a = vk[i];
        u[(k + 1 + i) * n + j] -= Complex(a.real() * s.real() - a.imag() * s.imag(), a.real() * s.imag() + a.imag() * s.real());
      }
    }
  }
  return true;
}

}  // namespace aosr::bins
