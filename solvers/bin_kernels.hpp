// Private to solvers/: the small dense kernels of the per-frequency-bin solvers (fourier_normal_system.cpp,
// tikhonov_fourier_system.cpp, tikhonov_spectral.cpp). Matrices are row-major on caller-owned memory, so a bin costs no allocation.
#pragma once

#include <algorithm>
#include <cmath>
#include <limits>

#include "aosr/core/image.hpp"

namespace aosr::bins {

// In-place Cholesky G = L Lᴴ of an n x n Hermitian matrix (row-major; the lower triangle is read). Stores L
// in the lower triangle with 1/L_ii on the diagonal (no complex division in the substitutions). False if a
// pivot falls to `pivot_floor` or below (singular to rounding; 0 accepts any positive pivot, like Eigen's LLT),
// or to `relative_floor` times its own diagonal entry or below: the test of the matrix scaled to a unit diagonal,
// on which Cholesky's accuracy depends (a diagonally dominant G whose diagonal spans 1e12 is accurate to rounding).
inline bool CholeskyInPlace(Complex* g, int n, double pivot_floor, double relative_floor = 0.0) {
  for (int j = 0; j < n; ++j) {
    const double diagonal = g[j * n + j].real();
    double d = diagonal;
    for (int k = 0; k < j; ++k) d -= std::norm(g[j * n + k]);
    if (!(d > pivot_floor) || !(d > relative_floor * diagonal)) return false;
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
// Gram matrix lose digits relative to the largest: where those matter, take the SVD of the factor instead,
// SingularSpectrum below). False if QL does
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

namespace aosr::bins {

// A Householder reflector in LAPACK's zlarfg convention: for x (m values) finds τ and v (v₀ = 1, v₁.. written over
// x₁..) with Hᴴ x = β e₁ for H = I − τ v vᴴ and β real, and returns β (τ = 0, H = I, where x is already β e₁).
inline double Reflector(Complex* x, int m, Complex* tau) {
  const Complex alpha = x[0];
  double tail = 0;
  for (int i = 1; i < m; ++i) tail += Norm2(x[i]);
  if (tail == 0 && alpha.imag() == 0) {
    *tau = 0;
    return alpha.real();
  }
  const double beta = -std::copysign(std::sqrt(Norm2(alpha) + tail), alpha.real());
  *tau = Complex((beta - alpha.real()) / beta, -alpha.imag() / beta);
  // 1/(α − β) = conj(α − β)/|α − β|², with |α − β| >= |β|: no cancellation, no overflow.
  const double dr = alpha.real() - beta, di = alpha.imag(), inv = 1.0 / (dr * dr + di * di);
  const double sr = dr * inv, si = -di * inv;
  for (int i = 1; i < m; ++i)
    x[i] = Complex(x[i].real() * sr - x[i].imag() * si, x[i].real() * si + x[i].imag() * sr);
  return beta;
}

// The columns a_t (t < cols; rows values each, column stride ld) ← Hᴴ a_t = a_t − conj(τ) v (vᴴ a_t), for the
// reflector (τ, v) of Reflector (v₀ = 1 implicit, v₁.. at v). The columns' dot products accumulate side by side
// (independent chains, each in the order of i). `w`: cols complex scratch.
// ReflectColumns for a fixed number of columns C (the few columns right of a reflector of the tall bins, and y):
// the column loop unrolled.
template <int C>
inline void ReflectFewColumns(Complex tau, const Complex* v, int rows, Complex* a, int ld) {
  double wr[C], wi[C];
  for (int t = 0; t < C; ++t) wr[t] = a[t * ld].real(), wi[t] = a[t * ld].imag();
  for (int i = 1; i < rows; ++i) {
    const double vr = v[i].real(), vi = v[i].imag();
    for (int t = 0; t < C; ++t) {
      const Complex z = a[t * ld + i];
      wr[t] += vr * z.real() + vi * z.imag();
      wi[t] += vr * z.imag() - vi * z.real();
    }
  }
  for (int t = 0; t < C; ++t) {
    const double fr = tau.real() * wr[t] + tau.imag() * wi[t];
    const double fi = tau.real() * wi[t] - tau.imag() * wr[t];
    Complex* col = a + t * ld;
    col[0] -= Complex(fr, fi);
    for (int i = 1; i < rows; ++i)
      col[i] -= Complex(fr * v[i].real() - fi * v[i].imag(), fr * v[i].imag() + fi * v[i].real());
  }
}

inline void ReflectColumns(Complex tau, const Complex* v, int rows, Complex* a, int ld, int cols, Complex* w) {
  switch (cols) {
    case 0:
      return;
    case 1:
      return ReflectFewColumns<1>(tau, v, rows, a, ld);
    case 2:
      return ReflectFewColumns<2>(tau, v, rows, a, ld);
    case 3:
      return ReflectFewColumns<3>(tau, v, rows, a, ld);
    default:
      break;
  }
  for (int t = 0; t < cols; ++t) w[t] = a[t * ld];
  for (int i = 1; i < rows; ++i) {
    const double vr = v[i].real(), vi = v[i].imag();
    for (int t = 0; t < cols; ++t) {
      const Complex z = a[t * ld + i];
      w[t] += Complex(vr * z.real() + vi * z.imag(), vr * z.imag() - vi * z.real());
    }
  }
  for (int t = 0; t < cols; ++t) {
    const Complex dot = w[t];
    const double fr = tau.real() * dot.real() + tau.imag() * dot.imag();
    const double fi = tau.real() * dot.imag() - tau.imag() * dot.real();
    Complex* col = a + t * ld;
    col[0] -= Complex(fr, fi);
    for (int i = 1; i < rows; ++i)
      col[i] -= Complex(fr * v[i].real() - fi * v[i].imag(), fr * v[i].imag() + fi * v[i].real());
  }
}

// The rows a_r (r < rows; m values each at column stride ld, rows contiguous) ← a_r H = a_r − τ (a_r v) vᴴ. The
// rows' products accumulate side by side, each in the order of i. `s`: rows complex scratch.
// ReflectRows for a fixed number of rows R (the few rows below a reflector of the wide bins): the row loop unrolled.
template <int R>
inline void ReflectFewRows(Complex tau, const Complex* v, int m, Complex* a, int ld) {
  double sr[R], si[R];
  for (int r = 0; r < R; ++r) sr[r] = a[r].real(), si[r] = a[r].imag();
  for (int i = 1; i < m; ++i) {
    const double vr = v[i].real(), vi = v[i].imag();
    const Complex* col = a + i * ld;
    for (int r = 0; r < R; ++r) {
      sr[r] += col[r].real() * vr - col[r].imag() * vi;
      si[r] += col[r].real() * vi + col[r].imag() * vr;
    }
  }
  for (int r = 0; r < R; ++r) {
    const double zr = sr[r], zi = si[r];
    sr[r] = tau.real() * zr - tau.imag() * zi;
    si[r] = tau.real() * zi + tau.imag() * zr;
    a[r] -= Complex(sr[r], si[r]);
  }
  for (int i = 1; i < m; ++i) {  // f conj(v_i)
    const double vr = v[i].real(), vi = v[i].imag();
    Complex* col = a + i * ld;
    for (int r = 0; r < R; ++r) col[r] -= Complex(sr[r] * vr + si[r] * vi, si[r] * vr - sr[r] * vi);
  }
}

inline void ReflectRows(Complex tau, const Complex* v, int m, Complex* a, int ld, int rows, Complex* s) {
  switch (rows) {
    case 0:
      return;
    case 1:
      return ReflectFewRows<1>(tau, v, m, a, ld);
    case 2:
      return ReflectFewRows<2>(tau, v, m, a, ld);
    case 3:
      return ReflectFewRows<3>(tau, v, m, a, ld);
    default:
      break;
  }
  for (int r = 0; r < rows; ++r) s[r] = a[r];
  for (int i = 1; i < m; ++i) {
    const double vr = v[i].real(), vi = v[i].imag();
    const Complex* col = a + i * ld;
    for (int r = 0; r < rows; ++r)
      s[r] += Complex(col[r].real() * vr - col[r].imag() * vi, col[r].real() * vi + col[r].imag() * vr);
  }
  for (int r = 0; r < rows; ++r) {
    const Complex z = s[r];
    s[r] = Complex(tau.real() * z.real() - tau.imag() * z.imag(), tau.real() * z.imag() + tau.imag() * z.real());
    a[r] -= s[r];
  }
  for (int i = 1; i < m; ++i) {  // f conj(v_i)
    const double vr = v[i].real(), vi = v[i].imag();
    Complex* col = a + i * ld;
    for (int r = 0; r < rows; ++r)
      col[r] -= Complex(s[r].real() * vr + s[r].imag() * vi, s[r].imag() * vr - s[r].real() * vi);
  }
}

// A plane rotation (c, s) with c f + s g = r >= 0 and −s f + c g = 0; (1, 0) where f and g are both zero (or
// both below the square root of the smallest normal number: entries far below the convergence tolerance of
// SingularSpectrum, whose matrix's largest entry is within 2^±256 of 1).
inline double Rotation(double f, double g, double* c, double* s) {
  const double r = std::sqrt(f * f + g * g);
  if (!(r > 0)) {
    *c = 1, *s = 0;
    return 0;
  }
  *c = f / r, *s = g / r;
  return r;
}

// The singular values of the p x k complex matrix X (element (i, j) at x[j ld + i]; destroyed) and the squared
// projections |u_jᴴ y|² of y (p values; destroyed) on its left singular vectors u_j, without forming them:
// q = min(p, k) values s2 (σ², ascending) and c, and *perp = ||y||² − Σ c, the part of y outside span{u_j}, as a sum
// of squares (the trailing rows of Uᴴy when p > k; 0 when p <= k). `work`: 2q doubles, `v`: 2 max(p, k) complex.
//
// Golub-Kahan: Householder bidiagonalisation X = P B Qᴴ (P's reflectors applied to y), with real β's so that B is
// real: upper bidiagonal when p >= k; lower when p < k, turned upper by q − 1 rotations from the left (applied to y
// too). Then implicit-shift QR sweeps on B (Golub & Van Loan, Algorithms 8.6.1-8.6.2: Wilkinson shift from the
// trailing 2 x 2 of BᵀB, a zero diagonal chased off its row or column first), the left rotations applied to y
// only. Backward stable on X: every σ carries an absolute error of a few ε ||X||₂ (the accuracy of an SVD of X),
// so σ² is exact to ~ε σ_max σ, unlike an eigen-decomposition of X Xᴴ (~ε σ_max²). The sweeps converge when an
// off-diagonal entry is at most ε ||B|| (that absolute accuracy; no relative accuracy is claimed). X is scaled
// by a power of two first (exact) where its largest entry is far from 1. False if the sweeps do not converge (60
// per singular value; non-finite input).
//
// Two rows (p = 2, the bins of N = 2 frames) take a closed form instead (TwoRowSpectrum, the same accuracy).
//
// SingularSpectra<L> does the same for L matrices of one shape at once, their steps interleaved (each matrix's
// arithmetic exactly as alone, so the same bits): the bidiagonalisations reflector by reflector and the QR sweeps
// sweep by sweep, so that the long chains of square roots and divisions of one matrix overlap the other's.
struct SpectrumJob {
  Complex* x;
  Complex* y;
  double* s2;
  double* c;
  double* perp;
  double* work;
  Complex* v;
  bool ok = true;  // out: false if the sweeps did not converge
};

namespace detail {

// X scaled by a power of two (exact) where its largest entry lies outside [2⁻²⁵⁶, 2²⁵⁶], so that the squares below
// neither overflow nor underflow where it matters; false if X holds a non-finite value. (Scaling by a power of two
// changes no bit of the results but the exponents: within that range it is skipped.)
inline bool ScaleToUnit(Complex* x, int p, int k, int ld, int* scale_exp) {
  double big = 0;
  bool nan = false;
  for (int j = 0; j < k; ++j)
    for (int i = 0; i < p; ++i) {
      const double re = x[j * ld + i].real(), im = x[j * ld + i].imag();
      nan |= (re != re) | (im != im);
      big = std::max(big, std::max(std::abs(re), std::abs(im)));
    }
  *scale_exp = 0;
  if (nan || !(big <= std::numeric_limits<double>::max())) return false;
  if (big > 0 && (big < 0x1p-256 || big > 0x1p256)) {
    *scale_exp = -std::ilogb(big);
    const double scale = std::ldexp(1.0, *scale_exp);
    for (int j = 0; j < k; ++j)
      for (int i = 0; i < p; ++i) x[j * ld + i] *= scale;
  }
  return true;
}

// Step j of the bidiagonalisation of SingularSpectrum (d, e in job.work).
inline void BidiagonalStep(SpectrumJob& job, int p, int k, int ld, int j) {
  const int q = std::min(p, k);
  Complex* x = job.x;
  Complex* y = job.y;
  Complex* v = job.v;
  Complex* w = v + std::max(p, k);  // the reflectors' scratch
  double* d = job.work;
  double* e = job.work + q;
  Complex tau;
  if (p >= k) {  // upper bidiagonal: reflectors on column j (rows j..), then on row j (columns j+1..)
    Complex* col = x + j * ld + j;
    d[j] = Reflector(col, p - j, &tau);
    if (tau != Complex(0)) {
      ReflectColumns(tau, col, p - j, x + (j + 1) * ld + j, ld, k - j - 1, w);
      ReflectColumns(tau, col, p - j, y + j, 0, 1, w);
    }
    if (j + 1 < k) {
      const int m = k - j - 1;
      for (int t = 0; t < m; ++t) v[t] = std::conj(x[(j + 1 + t) * ld + j]);
      e[j] = Reflector(v, m, &tau);
      if (tau != Complex(0)) ReflectRows(tau, v, m, x + (j + 1) * ld + j + 1, ld, p - j - 1, w);
    }
  } else {  // lower bidiagonal: reflectors on row j (columns j..), then on column j (rows j+1..)
    const int m = k - j;
    for (int t = 0; t < m; ++t) v[t] = std::conj(x[(j + t) * ld + j]);
    d[j] = Reflector(v, m, &tau);
    if (tau != Complex(0)) ReflectRows(tau, v, m, x + j * ld + j + 1, ld, p - j - 1, w);
    if (j + 1 < p) {
      Complex* col = x + j * ld + j + 1;
      e[j] = Reflector(col, p - j - 1, &tau);
      if (tau != Complex(0)) {
        ReflectColumns(tau, col, p - j - 1, x + (j + 1) * ld + j + 1, ld, k - j - 1, w);
        ReflectColumns(tau, col, p - j - 1, y + j + 1, 0, 1, w);
      }
    }
  }
}

// Two rows (p = 2, k >= 2), in closed form: the reflector from the right that makes row 0 β₀e₀ᵀ, applied to row 1,
// gives X = [L 0] Q with L = [β₀ 0; l₁₀ n₁] (n₁ = ||row 1 past column 0||, without forming its reflector). The
// eigenvalues of M = L Lᴴ = [a z; z̄ c] are λ₊ = (a + c)/2 + √(((a − c)/2)² + |z|²) (a sum of positive terms) and
// λ₋ = det M/λ₊ = (β₀ n₁)²/λ₊ (a product: no cancellation), as accurate as L, i.e. as an SVD of X; u₊ is the
// eigenvector column of M − λ₊I without cancellation, u₋ ⊥ u₊, and y is untouched by Q.
inline void TwoRowSpectrum(SpectrumJob& job, int k, int ld, int scale_exp) {
  Complex* x = job.x;
  Complex* v = job.v;
  Complex* w = v + k;
  Complex tau;
  for (int t = 0; t < k; ++t) v[t] = std::conj(x[t * ld]);
  const double beta = Reflector(v, k, &tau);
  if (tau != Complex(0)) ReflectRows(tau, v, k, x + 1, ld, 1, w);
  const Complex l10 = x[1];
  double n1sq = 0;  // n₁²
  for (int t = 1; t < k; ++t) n1sq += Norm2(x[t * ld + 1]);
  const double a = beta * beta, c = Norm2(l10) + n1sq;
  const Complex z(beta * l10.real(), -beta * l10.imag());  // M(0, 1) = β₀ conj(l₁₀)
  const double half = 0.5 * (a - c);
  const double plus = 0.5 * (a + c) + std::sqrt(half * half + Norm2(z));
  const double minus = plus > 0 ? a * n1sq / plus : 0.0;  // (β₀ n₁)²/λ₊
  Complex u0, u1;  // u₊
  if (a >= c) {
    u0 = plus - c, u1 = std::conj(z);
  } else {
    u0 = z, u1 = plus - a;
  }
  const double norm = std::sqrt(Norm2(u0) + Norm2(u1));
  if (norm > 0) {
    u0 /= norm, u1 /= norm;
  } else {  // M = a I: any basis
    u0 = 1, u1 = 0;
  }
  const Complex y0 = job.y[0], y1 = job.y[1];
  const Complex p_plus = std::conj(u0) * y0 + std::conj(u1) * y1;  // u₊ᴴy
  const Complex p_minus = -u1 * y0 + u0 * y1;                        // u₋ᴴy, u₋ = (−conj(u₁), conj(u₀))
  const double unscale = std::ldexp(1.0, -scale_exp);
  job.s2[0] = minus * unscale * unscale;
  job.s2[1] = plus * unscale * unscale;
  job.c[0] = Norm2(p_minus);
  job.c[1] = Norm2(p_plus);
  *job.perp = 0;
}

// Step j of the LQ factorisation X = [L 0] Q of a wide X (p < k): a reflector from the right on row j (columns j..)
// applied to the rows below; L (p x p, lower triangular, real diagonal) is left in X's first p columns, zeros above.
inline void LqStep(SpectrumJob& job, int p, int k, int ld, int j) {
  Complex* x = job.x;
  Complex* v = job.v;
  Complex* w = v + std::max(p, k);
  Complex tau;
  const int m = k - j;
  for (int t = 0; t < m; ++t) v[t] = std::conj(x[(j + t) * ld + j]);
  const double beta = Reflector(v, m, &tau);
  if (tau != Complex(0)) ReflectRows(tau, v, m, x + j * ld + j + 1, ld, p - j - 1, w);
  x[j * ld + j] = beta;
  for (int c = j + 1; c < p; ++c) x[c * ld + j] = 0;
}

// After the bidiagonalisation: the part of y outside the range, the lower bidiagonal turned upper, e[q-1] = 0.
inline void FinishBidiagonal(SpectrumJob& job, int p, int k) {
  const int q = std::min(p, k);
  double* d = job.work;
  double* e = job.work + q;
  Complex* y = job.y;
  *job.perp = 0;
  if (p >= k) {
    for (int i = k; i < p; ++i) *job.perp += Norm2(y[i]);
  } else {
    // Lower -> upper: a rotation of rows j, j+1 zeroes the subdiagonal e_j and fills the superdiagonal.
    for (int j = 0; j + 1 < q; ++j) {
      double cs, sn;
      d[j] = Rotation(d[j], e[j], &cs, &sn);
      e[j] = sn * d[j + 1];
      d[j + 1] *= cs;
      const Complex a = y[j], b = y[j + 1];
      y[j] = cs * a + sn * b;
      y[j + 1] = cs * b - sn * a;
    }
  }
  e[q - 1] = 0;
}

// The implicit QR sweeps on the upper bidiagonal (d, e) of one matrix, one step at a time.
struct BidiagonalQr {
  double* d = nullptr;
  double* e = nullptr;
  Complex* y = nullptr;
  int hi = 0, budget = 0;
  double tol = 0;
  bool failed = false;

  BidiagonalQr() = default;
  BidiagonalQr(SpectrumJob& job, int q) : d(job.work), e(job.work + q), y(job.y), hi(q - 1), budget(60 * q) {
    double anorm = 0;
    for (int i = 0; i < q; ++i) anorm = std::max(anorm, std::abs(d[i]) + std::abs(e[i]));
    tol = std::numeric_limits<double>::epsilon() * anorm;
  }
  bool Active() const { return hi > 0 && !failed; }

  // One deflation, zero chase or sweep.
  void Step() {
    if (std::abs(e[hi - 1]) <= tol) {
      e[hi - 1] = 0;
      --hi;
      return;
    }
    int lo = hi - 1;
    while (lo > 0 && std::abs(e[lo - 1]) > tol) --lo;
    if (lo > 0) e[lo - 1] = 0;
    if (--budget < 0) {
      failed = true;
      return;
    }
    // A zero on the diagonal of the block: chase its row's superdiagonal off to the right (rotations from the
    // left, applied to y), or for the last one its column's upwards (rotations from the right).
    int zero = -1;
    for (int i = lo; i <= hi; ++i)
      if (std::abs(d[i]) <= tol) {
        zero = i;
        break;
      }
    if (zero >= 0 && zero < hi) {
      const int i = zero;
      double f = e[i];
      d[i] = 0, e[i] = 0;
      for (int j = i + 1; j <= hi; ++j) {
        double cs, sn;
        const double r = Rotation(d[j], f, &cs, &sn);  // rows j (c) and i (s): zeroes (i, j)
        d[j] = r;
        if (j < hi) {
          f = -sn * e[j];
          e[j] *= cs;
        }
        const Complex a = y[i], b = y[j];
        y[j] = cs * b + sn * a;
        y[i] = cs * a - sn * b;
      }
      return;
    }
    if (zero == hi) {
      double f = e[hi - 1];
      d[hi] = 0, e[hi - 1] = 0;
      for (int j = hi - 1; j >= lo; --j) {
        double cs, sn;
        d[j] = Rotation(d[j], f, &cs, &sn);  // columns j and hi: zeroes (j, hi)
        if (j > lo) {
          f = -sn * e[j - 1];
          e[j - 1] *= cs;
        }
      }
      return;
    }
    // Wilkinson shift μ: the eigenvalue of the trailing 2 x 2 of BᵀB (block lo..hi) nearer its last entry.
    const double dm = d[hi - 1], em = e[hi - 1], dn = d[hi];
    const double t11 = dm * dm + (hi - 1 > lo ? e[hi - 2] * e[hi - 2] : 0.0);
    const double t12 = dm * em, t22 = dn * dn + em * em;
    const double delta = 0.5 * (t11 - t22);
    const double root = std::sqrt(delta * delta + t12 * t12);
    const double denom = delta + (delta >= 0 ? root : -root);
    const double mu = denom != 0 ? t22 - t12 * t12 / denom : t22;
    // The sweep: a right rotation from the first column of BᵀB − μI, then the bulge chased down the block.
    double f = d[lo] * d[lo] - mu, g = d[lo] * e[lo];
    for (int j = lo; j < hi; ++j) {
      double cs, sn;
      double r = Rotation(f, g, &cs, &sn);  // columns j, j+1
      if (j > lo) e[j - 1] = r;
      f = cs * d[j] + sn * e[j];
      e[j] = cs * e[j] - sn * d[j];
      g = sn * d[j + 1];
      d[j + 1] *= cs;
      r = Rotation(f, g, &cs, &sn);  // rows j, j+1
      d[j] = r;
      f = cs * e[j] + sn * d[j + 1];
      d[j + 1] = cs * d[j + 1] - sn * e[j];
      if (j + 1 < hi) {
        g = sn * e[j + 1];
        e[j + 1] *= cs;
      }
      const Complex a = y[j], b = y[j + 1];
      y[j] = cs * a + sn * b;
      y[j + 1] = cs * b - sn * a;
    }
    e[hi - 1] = f;
  }
};

// σ² ascending with their projections (insertion sort: q <= 16 here), unscaled.
inline void SortSpectrum(const SpectrumJob& job, int q, int scale_exp) {
  const double unscale = std::ldexp(1.0, -scale_exp);
  const double* d = job.work;
  for (int i = 0; i < q; ++i) {
    const double sv = d[i] * unscale;
    const double s2i = sv * sv, ci = Norm2(job.y[i]);
    int j = i;
    while (j > 0 && job.s2[j - 1] > s2i) {
      job.s2[j] = job.s2[j - 1];
      job.c[j] = job.c[j - 1];
      --j;
    }
    job.s2[j] = s2i;
    job.c[j] = ci;
  }
}

}  // namespace detail

template <int L>
inline void SingularSpectra(SpectrumJob* jobs, int p, int k, int ld) {
  const int q = std::min(p, k);
  if (q == 0) {  // nothing to decompose: all of y is outside the range
    for (int l = 0; l < L; ++l) {
      jobs[l].ok = true;
      *jobs[l].perp = 0;
      for (int i = 0; i < p; ++i) *jobs[l].perp += Norm2(jobs[l].y[i]);
    }
    return;
  }
  int scale_exp[L];
  for (int l = 0; l < L; ++l) jobs[l].ok = detail::ScaleToUnit(jobs[l].x, p, k, ld, &scale_exp[l]);
  if (p == 2 && k >= 2) {
    for (int l = 0; l < L; ++l)
      if (jobs[l].ok) detail::TwoRowSpectrum(jobs[l], k, ld, scale_exp[l]);
    return;
  }
  // (A non-finite matrix goes through the reflectors like the others, its values meaningless, and is not swept.)
  // A much wider X (k > 4p) is first reduced to the square L of X = [L 0] Q (2p²k operations; bidiagonalising X
  // itself costs 4p²k), then L is bidiagonalised (narrower ones gain nothing: more reflectors in the chain).
  int kb = k;
  if (k > 4 * p) {
    for (int j = 0; j < p; ++j)
      for (int l = 0; l < L; ++l) detail::LqStep(jobs[l], p, k, ld, j);
    kb = p;
  }
  for (int j = 0; j < q; ++j)
    for (int l = 0; l < L; ++l) detail::BidiagonalStep(jobs[l], p, kb, ld, j);
  detail::BidiagonalQr qr[L];
  for (int l = 0; l < L; ++l) {
    detail::FinishBidiagonal(jobs[l], p, kb);
    qr[l] = detail::BidiagonalQr(jobs[l], q);
    qr[l].failed = !jobs[l].ok;
  }
  for (bool active = true; active;) {
    active = false;
    for (int l = 0; l < L; ++l)
      if (qr[l].Active()) {
        qr[l].Step();
        active = true;
      }
  }
  for (int l = 0; l < L; ++l) {
    jobs[l].ok = !qr[l].failed;
    if (jobs[l].ok) detail::SortSpectrum(jobs[l], q, scale_exp[l]);
  }
}

inline bool SingularSpectrum(Complex* x, int p, int k, int ld, Complex* y, double* s2, double* c, double* perp,
                             double* work, Complex* v) {
  SpectrumJob job{x, y, s2, c, perp, work, v};
  SingularSpectra<1>(&job, p, k, ld);
  return job.ok;
}

}  // namespace aosr::bins
