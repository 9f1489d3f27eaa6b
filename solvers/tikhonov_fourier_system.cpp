// The per-frequency Tikhonov engine (FourierSystem of tikhonov_internal.hpp): each LR bin's N x r² system A(u)
// gathered from the model's OTFs, the rank floor and ranks (pivoted QR), the Woodbury / normal-equation /
// minimum-norm solves per bin, and the per-bin inverses. The spectral decomposition the λ rules evaluate is in
// tikhonov_spectral.cpp; the bin loops both use in tikhonov_bin_loops.hpp.
#include "tikhonov_internal.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <limits>
#include <mutex>

#include "aosr/core/error.hpp"
#include "aosr/core/fft.hpp"
#include "aosr/core/parallel.hpp"
#include "bin_kernels.hpp"
#include "tikhonov_bin_loops.hpp"

namespace aosr::tikhonov_internal {

namespace {

using bins::Norm2;
using loops::ConjMul;
using loops::ForBinBlocks;
using loops::kBinBlock;
using loops::Mul;
using loops::MulConj;

// AllFinite on fixed row blocks in parallel (the answer does not depend on the partition).
bool AllFiniteParallel(const Image& x) {
  constexpr Index kRows = 64;
  const Index blocks = (x.rows() + kRows - 1) / kRows;
  std::vector<char> ok(blocks, 1);
  ParallelFor(blocks, [&](Index b) {
    // v·0 is 0 for finite v and NaN otherwise; the sum (four lanes) is NaN iff some value is not finite.
    const Index r0 = b * kRows, count = std::min(kRows, x.rows() - r0) * x.cols();
    const double* v = x.data() + r0 * x.cols();
    double lane[4] = {0, 0, 0, 0};
    Index k = 0;
    for (; k + 4 <= count; k += 4)
      for (int l = 0; l < 4; ++l) lane[l] += v[k + l] * 0.0;
    for (; k < count; ++k) lane[0] += v[k] * 0.0;
    ok[b] = (lane[0] + lane[1]) + (lane[2] + lane[3]) == 0.0;
  });
  return std::all_of(ok.begin(), ok.end(), [](char c) { return c != 0; });
}

// bins::CholeskyInPlace with |z|² as re² + im² (no hypot): the same factor layout (1/L_ii on the diagonal).
inline bool Cholesky(Complex* g, int n, double pivot_floor) {
  for (int j = 0; j < n; ++j) {
    double d = g[j * n + j].real();
    for (int k = 0; k < j; ++k) d -= Norm2(g[j * n + k]);
    if (!(d > pivot_floor)) return false;
    const double inv = 1.0 / std::sqrt(d);
    g[j * n + j] = inv;
    for (int i = j + 1; i < n; ++i) {
      Complex s = g[i * n + j];
      for (int k = 0; k < j; ++k) s -= MulConj(g[i * n + k], g[j * n + k]);
      g[i * n + j] = s * inv;
    }
  }
  return true;
}

// Gram matrix of the columns `keep` (all r² if keep is null) of the column-major N x r² matrix a: the smaller of
// A Aᴴ (N x N) and Aᴴ A (k x k), row-major, both triangles. Returns its size.
int Gram(const Complex* a, int n, const int* keep, int kept, Complex* g) {
  const bool rows = n <= kept;
  const int size = rows ? n : kept;
  for (int p = 0; p < size; ++p)
    for (int q = 0; q <= p; ++q) {
      Complex sum = 0;
      if (rows) {
        for (int k = 0; k < kept; ++k) {
          const Complex* col = a + Index(keep ? keep[k] : k) * n;
          sum += MulConj(col[p], col[q]);
        }
      } else {
        const Complex* cp = a + Index(keep ? keep[p] : p) * n;
        const Complex* cq = a + Index(keep ? keep[q] : q) * n;
        for (int f = 0; f < n; ++f) sum += ConjMul(cp[f], cq[f]);
      }
      g[p * size + q] = sum;
      g[q * size + p] = std::conj(sum);
    }
  return size;
}

// The rank of the column-major n x k matrix `a` (destroyed) against `floor`, certified without forming a Gram
// matrix: Householder QR with column pivoting, A Π = Q [R₁₁ R₁₂; 0 R₂₂], stopped at the first step j where the
// trailing columns' Frobenius norm is at most floor/2. Then σ_{j+1}(A) <= ||R₂₂||₂ <= floor/2 and
// σ_j(A) >= σ_min(R₁₁) >= 1/||R₁₁⁻¹||_F; rank j is certified when that bound is at least 2·floor. Householder
// QR is backward stable (errors ε σ_max(A), far below a floor of 1e-9 σ_max), so the bounds hold to that margin.
// Returns -1 when not certified (a singular value within a factor 2 of the floor). `work`: 2k doubles + n complex.
int PivotedQrRank(Complex* a, int n, int k, double floor, double* work, Complex* v) {
  double* norms = work;
  const int steps = std::min(n, k);
  int j = 0;
  for (; j < steps; ++j) {
    double rest = 0, best = -1;
    int pivot = j;
    for (int c = j; c < k; ++c) {
      double s = 0;
      for (int i = j; i < n; ++i) s += Norm2(a[c * n + i]);
      norms[c] = s;
      rest += s;
      if (s > best) best = s, pivot = c;
    }
    if (rest <= 0.25 * floor * floor) break;
    if (pivot != j)
      for (int i = 0; i < n; ++i) std::swap(a[j * n + i], a[pivot * n + i]);
    // Householder on rows j..n-1 of column j: H x = −phase ||x|| e₁.
    Complex* x = a + j * n + j;
    const int len = n - j;
    const double alpha = std::sqrt(norms[pivot]);
    const double a0 = std::sqrt(Norm2(x[0]));
    const Complex phase = a0 > 0 ? x[0] / a0 : Complex(1.0);
    for (int i = 0; i < len; ++i) v[i] = x[i];
    v[0] += phase * alpha;
    const double vnorm2 = 2.0 * alpha * (alpha + a0);
    x[0] = -phase * alpha;
    for (int i = 1; i < len; ++i) x[i] = 0;
    if (vnorm2 > 0)
      for (int c = j + 1; c < k; ++c) {
        Complex* col = a + c * n + j;
        Complex dot = 0;
        for (int i = 0; i < len; ++i) dot += ConjMul(v[i], col[i]);
        dot *= 2.0 / vnorm2;
        for (int i = 0; i < len; ++i) col[i] -= Mul(v[i], dot);
      }
  }
  if (j == 0) return 0;
  // ||R₁₁⁻¹||²_F row by row of R₁₁⁻¹ᴴ... column by column of R₁₁⁻¹: back substitution of e_i (R upper, R(p,q) =
  // a[q n + p]).
  double inv2 = 0;
  Complex* z = v;
  for (int e = 0; e < j; ++e) {
    for (int p = j - 1; p >= 0; --p) {
      if (p > e) {
        z[p] = 0;
        continue;
      }
      Complex sum = p == e ? Complex(1.0) : Complex(0.0);
      for (int q = p + 1; q <= e; ++q) sum -= Mul(a[q * n + p], z[q]);
      const Complex d = a[p * n + p];
      if (!(Norm2(d) > 0)) return -1;
      z[p] = sum / d;
      inv2 += Norm2(z[p]);
    }
  }
  return inv2 > 0 && 1.0 / inv2 >= 4.0 * floor * floor ? j : -1;
}

}  // namespace

void FourierSystem::Gather(Index bin, BinData* d) const {
  // A(u): entries (1/r²) B(f_k) H_i(f_k) (MultiFrameModel::AliasedSystem's arithmetic), H_i from the half spectrum
  // (MultiFrameModel::Otf); P(u) and 1/P on the r² aliases.
  const Shape lr = model_.lr_shape(), hr = model_.hr_shape();
  const int n = n_, r = r_;
  d->a.resize(std::size_t(n) * rr_);
  d->p.resize(rr_);
  d->pinv.resize(rr_);
  const Index uy = bin / lr.cols, ux = bin % lr.cols, half = hr.cols / 2 + 1;
  const double inv_rr = 1.0 / double(rr_);
  for (int ky = 0; ky < r; ++ky) {
    const Index fy = uy + ky * lr.rows, my = (hr.rows - fy) % hr.rows;
    const double* sym = &prior_symbol_(fy, 0);
    for (int kx = 0; kx < r; ++kx) {
      const int c = ky * r + kx;
      const Index fx = ux + kx * lr.cols;
      const Complex b = model_.PixelTransfer(fy, fx) * inv_rr;
      Complex* out = &d->a[std::size_t(c) * n];
      if (fx < half) {
        for (int f = 0; f < n; ++f) out[f] = Mul(b, model_.otf(f)(fy, fx));
      } else {
        for (int f = 0; f < n; ++f) out[f] = Mul(b, std::conj(model_.otf(f)(my, hr.cols - fx)));
      }
      const double pv = sym[fx];
      d->p[c] = pv;
      d->pinv[c] = pv > 0 ? 1.0 / pv : 0.0;
    }
  }
}

void FourierSystem::GatherRun(Index uy, Index ux0, int count, std::size_t stride, Complex* a, double* p,
                              double* pinv) const {
  // Gather's arithmetic, HR row by HR row: for each alias row ky and frame, one forward sweep along the OTF's row
  // (and its mirror row), the stretches of the r alias columns in order, so the hardware prefetcher sees a stream.
  const Shape lr = model_.lr_shape(), hr = model_.hr_shape();
  const int n = n_, r = r_, rr = rr_;
  const Index half = hr.cols / 2 + 1;
  const double inv_rr = 1.0 / double(rr_);
  thread_local std::vector<Complex> b_heap;
  b_heap.resize(std::size_t(r) * count);
  Complex* b = b_heap.data();  // b[kx·count + k] = B(f)/r² of bin k's alias (ky, kx)
  for (int ky = 0; ky < r; ++ky) {
    const Index fy = uy + ky * lr.rows, my = (hr.rows - fy) % hr.rows;
    const double* sym = &prior_symbol_(fy, 0);
    if (ky + 1 < r) {  // the next alias row's prior stretches (a stream of its own, prefetched as the OTFs' below)
      const double* next = &prior_symbol_(fy + lr.rows, 0);
      for (int kx = 0; kx < r; ++kx)
        for (int k = 0; k < count; k += 8) __builtin_prefetch(next + ux0 + kx * lr.cols + k);
    }
    for (int kx = 0; kx < r; ++kx) {
      const int c = ky * r + kx;
      const Index fx0 = ux0 + kx * lr.cols;
      for (int k = 0; k < count; ++k) {
        const Index fx = fx0 + k;
        b[kx * count + k] = model_.PixelTransfer(fy, fx) * inv_rr;
        const double pv = sym[fx];
        p[std::size_t(k) * rr + c] = pv;
        pinv[std::size_t(k) * rr + c] = pv > 0 ? 1.0 / pv : 0.0;
      }
    }
    for (int f = 0; f < n; ++f) {
      const Complex* h = &model_.otf(f)(fy, 0);
      const Complex* hm = &model_.otf(f)(my, 0);
      {
        // Prefetch the stretches the next (frame, alias row) reads: short strided streams the hardware prefetcher
        // picks up too late (the reads below were most of this function's time).
        const int nf = f + 1 < n ? f + 1 : 0;
        const Index nfy = f + 1 < n ? fy : fy + lr.rows;
        if (nfy < hr.rows) {
          const Index nmy = (hr.rows - nfy) % hr.rows;
          const Complex* nh = &model_.otf(nf)(nfy, 0);
          const Complex* nhm = &model_.otf(nf)(nmy, 0);
          for (int kx = 0; kx < r; ++kx) {
            const Index fx0 = ux0 + kx * lr.cols;
            for (int k = 0; k < count; k += 4) {
              const Index fx = fx0 + k;
              __builtin_prefetch(fx < half ? static_cast<const void*>(nh + fx)
                                           : static_cast<const void*>(nhm + (hr.cols - fx)));
            }
          }
        }
      }
      for (int kx = 0; kx < r; ++kx) {
        const Index fx0 = ux0 + kx * lr.cols;
        const Complex* bk = b + kx * count;
        Complex* out = a + std::size_t(ky * r + kx) * n + f;
        int k = 0;
        for (; k < count && fx0 + k < half; ++k) out[k * stride] = Mul(bk[k], h[fx0 + k]);
        for (; k < count; ++k) out[k * stride] = Mul(bk[k], std::conj(hm[hr.cols - (fx0 + k)]));
      }
    }
  }
}

FourierSystem::BinView FourierSystem::View(Index bin, BinData* d) const {
  Gather(bin, d);
  return BinView{Eigen::Map<const Eigen::MatrixXcd>(d->a.data(), n_, rr_),
                 Eigen::Map<const Eigen::VectorXcd>(&y_[bin * n_], n_),
                 Eigen::Map<const Eigen::VectorXd>(d->p.data(), rr_), prior_positive_[bin] != 0,
                 rank_.empty() ? -1 : rank_[bin]};
}

FourierSystem::FourierSystem(const MultiFrameModel& model, Image prior_symbol, double rank_tolerance,
                             TikhonovBinSolver solver)
    : model_(model), solver_(solver), prior_symbol_(std::move(prior_symbol)), rank_tolerance_(rank_tolerance) {
  const Shape lr = model.lr_shape(), hr = model.hr_shape();
  r_ = model.r();
  n_ = model.frames();
  rr_ = r_ * r_;
  nb_ = lr.size();
  if (ShapeOf(prior_symbol_) != hr)
    throw InvalidArgument("FourierSystem", "prior_symbol shape", ToString(ShapeOf(prior_symbol_)),
                          "the model's HR shape " + ToString(hr));
  y_.assign(nb_ * n_, Complex(0));
  // The bins whose prior vanishes at some alias (the DC bin of the gradient and Laplacian priors): the only ones
  // whose path a λ > 0 solve decides by their rank.
  prior_positive_.assign(nb_, 1);
  ParallelFor(lr.rows, [&](Index uy) {  // LR row uy: its HR rows uy + ky·m_y, written only to its own bins
    for (Index fy = uy; fy < hr.rows; fy += lr.rows) {
      const double* row = &prior_symbol_(fy, 0);
      for (Index fx = 0; fx < hr.cols; ++fx)
        if (!(row[fx] > 0)) prior_positive_[uy * lr.cols + fx % lr.cols] = 0;
    }
  });
  for (Index i = 0; i < nb_; ++i)
    if (!prior_positive_[i]) zero_prior_bins_.push_back(i);
  canonical_.resize(nb_);
  for (Index uy = 0; uy < lr.rows; ++uy) {
    const Index muy = (lr.rows - uy) % lr.rows;
    for (Index ux = 0; ux < lr.cols; ++ux) {
      const Index mux = (lr.cols - ux) % lr.cols;
      // 2 for the computed bin of a pair {u, −u}, 1 for a bin that is its own mirror, 0 for the other of a pair.
      const bool canonical = ux < mux || (ux == mux && uy <= muy);
      canonical_[uy * lr.cols + ux] = canonical ? (ux == mux && uy == muy ? 1 : 2) : 0;
    }
  }
}

void FourierSystem::NoteNorms(Index i, BinPtr d, FloorNorms* fn) const {
  // ||A(u)||²_F = tr of its Gram matrix, its largest squared column norm (a lower bound of σ_max(A(u))², a
  // diagonal entry of AᴴA) and tr P(u).
  double trace = 0, cmax = 0, psum = 0;
  for (int c = 0; c < rr_; ++c) {
    double col = 0;
    for (int f = 0; f < n_; ++f) col += Norm2(d.a[std::size_t(c) * n_ + f]);
    trace += col;
    cmax = std::max(cmax, col);
    psum += d.p[c];
  }
  fn->trace[i] = trace;
  fn->col_max[i] = cmax;
  fn->prior[i] = psum;
}

FourierSystem::FloorNorms FourierSystem::NewFloorNorms() const {
  FloorNorms fn;
  fn.trace.assign(nb_, 0.0);
  fn.col_max.assign(nb_, 0.0);
  fn.prior.assign(nb_, 0.0);
  return fn;
}

void FourierSystem::FinishFloor(const FloorNorms& fn) const {
  std::lock_guard<std::mutex> lock(lazy_mutex_);
  if (floor_ready_) return;
  // Over the canonical bins (a mirror bin's system is the conjugate: the same norms and singular values), in bin
  // order. The largest σ² over all bins sets the rank floor. σ_max(u)² lies in [col_max(u), tr(u)], so only bins
  // whose trace reaches the largest lower bound can hold it (usually the DC bin alone): their Gram's eigenvalues.
  const int n_gram = std::min(n_, rr_);
  double lower = 0, trace_ata = 0, trace_p = 0;
  for (Index i = 0; i < nb_; ++i)
    if (CanonicalBin(i)) lower = std::max(lower, fn.col_max[i]);
  double sv2_max = 0;
  std::vector<Complex> g(std::size_t(n_gram) * n_gram);
  BinData d;
  for (Index i = 0; i < nb_; ++i) {
    if (!CanonicalBin(i)) continue;
    const double weight = MirrorWeight(i);
    trace_ata += weight * fn.trace[i];
    trace_p += weight * fn.prior[i];
    if (n_gram == 0 || fn.trace[i] < lower) continue;
    Gather(i, &d);
    Gram(d.a.data(), n_, nullptr, rr_, g.data());
    const Eigen::Map<const Eigen::Matrix<Complex, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>> gm(
        g.data(), n_gram, n_gram);
    sv2_max = std::max(sv2_max, Eigen::SelfAdjointEigenSolver<Eigen::MatrixXcd>(Eigen::MatrixXcd(gm),
                                                                                 Eigen::EigenvaluesOnly)
                                    .eigenvalues()
                                    .maxCoeff());
  }
  sv_floor_ = rank_tolerance_ * std::sqrt(sv2_max);
  lambda0_ = trace_p > 0 && trace_ata > 0 ? trace_ata / trace_p : 1.0;
  floor_ready_ = true;
}

bool FourierSystem::FloorReady() const {
  std::lock_guard<std::mutex> lock(lazy_mutex_);
  return floor_ready_;
}

void FourierSystem::EnsureFloor() const {
  if (FloorReady()) return;
  FloorNorms fn = NewFloorNorms();
  ForGatheredBins([&](Index i) { return CanonicalBin(i); }, [&](Index i, BinPtr d) { NoteNorms(i, d, &fn); });
  FinishFloor(fn);
}

double FourierSystem::lambda0() const {
  EnsureFloor();
  return lambda0_;
}

int FourierSystem::RankOf(const Complex* a, int cols) const {
  // Columns whose squared norms sum to at most 1e-4 floor² move no singular value by more than 1 % of the floor
  // (Weyl), so they are dropped first (aliases beyond the optical cutoff or on a zero of the pixel box). The
  // rank of the rest is certified by the Cholesky factor L of its Gram matrix G (n' x n'): λ_min(G) >=
  // 1/tr G⁻¹ = 1/||L⁻¹||²_F, with a margin of 4x over the floor plus the Gram's rounding. Bins it cannot decide
  // (a σ near or below the floor) try a pivoted Householder QR (bounds on σ without squaring), then singular values
  // to an SVD's accuracy (bins::SingularSpectrum), and an SVD where one lies within 1e-4 of the floor².
  const int rr = cols;
  const double floor2 = sv_floor_ * sv_floor_;
  double norms[256];
  int keep[256];
  std::vector<double> norm_heap;
  std::vector<int> keep_heap;
  double* nrm = rr <= 256 ? norms : (norm_heap.resize(rr), norm_heap.data());
  int* kp = rr <= 256 ? keep : (keep_heap.resize(rr), keep_heap.data());
  const double threshold = 1e-4 * floor2;
  for (int c = 0; c < rr; ++c) {
    double s = 0;
    for (int f = 0; f < n_; ++f) s += Norm2(a[c * n_ + f]);
    nrm[c] = s;
  }
  const int kept = loops::KeptColumns(nrm, rr, threshold, kp);
  const int size = std::min(n_, kept);
  if (size == 0) return 0;
  std::vector<Complex> g(std::size_t(size) * size), l(g.size()), w(size);
  Gram(a, n_, kp, kept, g.data());
  double trace = 0;
  for (int p = 0; p < size; ++p) trace += g[p * size + p].real();
  const double noise = 64.0 * std::numeric_limits<double>::epsilon() * double(size) * trace;
  l = g;
  if (Cholesky(l.data(), size, noise)) {
    double inv_trace = 0;  // ||L⁻¹||²_F, column by column of L⁻¹ (forward substitution of e_j)
    for (int j = 0; j < size; ++j)
      for (int p = j; p < size; ++p) {
        Complex sum = p == j ? 1.0 : 0.0;
        for (int q = j; q < p; ++q) sum -= Mul(l[p * size + q], w[q]);
        w[p] = sum * l[p * size + p].real();
        inv_trace += Norm2(w[p]);
      }
    if (inv_trace > 0 && 1.0 / inv_trace > 4.0 * (floor2 + noise)) return size;
  }
  // Not certified by the Gram: the pivoted QR of the reduced A(u), and where even that cannot decide, its SVD.
  std::vector<Complex> reduced(std::size_t(n_) * kept), v(n_);
  std::vector<double> qr_work(2 * std::size_t(kept));
  for (int k = 0; k < kept; ++k)
    for (int f = 0; f < n_; ++f) reduced[std::size_t(k) * n_ + f] = a[kp[k] * n_ + f];
  const int qr_rank = PivotedQrRank(reduced.data(), n_, kept, sv_floor_, qr_work.data(), v.data());
  if (qr_rank >= 0) return qr_rank;
  // The singular values of the reduced A(u) to an SVD's accuracy (bins::SingularSpectrum); an SVD only where
  // one lies within 1e-4 of the floor², closer than that accuracy can be trusted to classify.
  const int p = std::min(n_, kept);
  std::vector<Complex> x(std::size_t(n_) * kept), y(n_, Complex(0)), sv_v(2 * std::size_t(std::max(n_, kept)));
  std::vector<double> dv(p), cv(p), sv_work(2 * std::size_t(p));
  for (int c = 0; c < kept; ++c)
    for (int f = 0; f < n_; ++f) x[std::size_t(c) * n_ + f] = a[kp[c] * n_ + f];
  Eigen::VectorXd sv2 = Eigen::Map<Eigen::VectorXd>(dv.data(), p);
  double perp = 0;
  bool decided = bins::SingularSpectrum(x.data(), n_, kept, n_, y.data(), dv.data(), cv.data(), &perp,
                                        sv_work.data(), sv_v.data());
  if (decided) {
    sv2 = Eigen::Map<Eigen::VectorXd>(dv.data(), p);
    decided = !((sv2.array() - floor2).abs() <= 1e-4 * floor2).any();
  }
  if (!decided) {
    Eigen::MatrixXcd dense(n_, kept);
    for (int c = 0; c < kept; ++c)
      for (int f = 0; f < n_; ++f) dense(f, c) = a[kp[c] * n_ + f];
    sv2 = Eigen::JacobiSVD<Eigen::MatrixXcd>(dense).singularValues().array().square().matrix();
  }
  return int((sv2.array() > floor2).count());
}

void FourierSystem::EnsureRanks() const {
  EnsureFloor();
  std::lock_guard<std::mutex> lock(lazy_mutex_);
  if (ranks_ready_) return;
  // One bin of each mirror pair: u and −u have conjugate systems, hence the same rank.
  std::vector<int> rank(nb_, -1);
  ForGatheredBins([&](Index i) { return CanonicalBin(i); },
                  [&](Index i, BinPtr d) { rank[i] = RankOf(d.a, rr_); });
  deficient_ = unconstrained_ = 0;
  for (Index i = 0; i < nb_; ++i) {
    if (!CanonicalBin(i)) rank[i] = rank[MirrorBin(i)];
    if (rank[i] < rr_) {
      ++deficient_;
      unconstrained_ += rr_ - rank[i];
    }
  }
  rank_ = std::move(rank);
  ranks_ready_ = true;
}

void FourierSystem::EnsureZeroPriorRanks() const {
  if (zero_prior_bins_.empty()) return;
  EnsureFloor();
  std::lock_guard<std::mutex> lock(lazy_mutex_);
  if (zero_prior_ranks_ready_) return;
  // For each bin whose prior vanishes at some aliases Z: whether the data see that null space, i.e. the columns
  // A(u)_Z have full column rank against the floor (RankOf on those columns alone). Then G = AᴴA + wP is
  // nonsingular for every w > 0 and the normal equations solve the bin; else the minimum-norm path.
  seen_.assign(nb_, 0);
  BinData d;
  std::vector<Complex> z;
  for (Index i : zero_prior_bins_) {
    const Index c = CanonicalBin(i) ? i : MirrorBin(i);
    if (c == i) {
      Gather(c, &d);
      z.clear();
      int zc = 0;
      for (int k = 0; k < rr_; ++k)
        if (!(d.p[k] > 0)) {
          z.insert(z.end(), d.a.begin() + std::size_t(k) * n_, d.a.begin() + std::size_t(k + 1) * n_);
          ++zc;
        }
      seen_[c] = RankOf(z.data(), zc) == zc;
    }
  }
  for (Index i : zero_prior_bins_) seen_[i] = seen_[CanonicalBin(i) ? i : MirrorBin(i)];
  zero_prior_ranks_ready_ = true;
}

void FourierSystem::PrepareChoose(double w) const {
  // Choose reads a bin's rank only where w = 0, and whether the data see the prior's null space where a bin's
  // prior vanishes somewhere.
  if (!(w > 0)) {
    EnsureRanks();
  } else {
    EnsureZeroPriorRanks();
  }
}

Index FourierSystem::deficient_bins() const {
  EnsureRanks();
  return deficient_;
}

Index FourierSystem::unconstrained() const {
  EnsureRanks();
  return unconstrained_;
}

void FourierSystem::SetData(const ImageStack& frames) {
  spectral_.reset();  // made from the data: stale now
  const Shape lr = model_.lr_shape();
  // The N frames' r2c transforms in parallel (task i writes only frame i's entries), the full spectrum from the
  // half by Hermitian symmetry.
  ParallelFor(n_, [&](Index i) {
    const ComplexImage s = FftR2C(frames.at(i));
    const Index half = s.cols();
    for (Index uy = 0; uy < lr.rows; ++uy) {
      const Index my = (lr.rows - uy) % lr.rows;
      for (Index ux = 0; ux < lr.cols; ++ux)
        y_[(uy * lr.cols + ux) * n_ + i] = ux < half ? s(uy, ux) : std::conj(s(my, lr.cols - ux));
    }
  });
}

FourierSystem::Path FourierSystem::Choose(Index bin, double w) const {
  const bool positive = prior_positive_[bin] != 0;
  if (w > 0 && positive && solver_ != TikhonovBinSolver::kNormalEquations &&
      (solver_ == TikhonovBinSolver::kWoodbury || n_ < rr_))
    return Path::kWoodbury;
  if (w > 0) return positive || seen_[bin] ? Path::kNormal : Path::kMinimumNorm;  // (PrepareChoose made seen_)
  if (rank_[bin] == rr_) return Path::kNormal;  // w = 0: the rank (PrepareChoose made it)
  return Path::kMinimumNorm;
}

namespace {

// The stacked system [A; √(wP)] of a bin, its SVD with the global floor (minimum-norm path).
template <class A, class P>
Eigen::JacobiSVD<Eigen::MatrixXcd> StackedSvd(const A& a, const P& prior, double w, double sv_floor) {
  const Index n = a.rows(), rr = a.cols();
  Eigen::MatrixXcd stacked = Eigen::MatrixXcd::Zero(n + rr, rr);
  stacked.topRows(n) = a;
  for (Index k = 0; k < rr; ++k) stacked(n + k, k) = std::sqrt(w * prior[k]);
  Eigen::JacobiSVD<Eigen::MatrixXcd> svd(stacked, Eigen::ComputeThinU | Eigen::ComputeThinV);
  const double local_max = svd.singularValues().size() ? svd.singularValues()[0] : 0.0;
  svd.setThreshold(local_max > 0 ? std::min(1.0, sv_floor / local_max) : 1.0);
  return svd;
}

}  // namespace

FourierSystem::BinSolution FourierSystem::SolveBin(Index bin, double w, bool want_trace, BinData* d) const {
  const BinView b = View(bin, d);
  const Index n = b.a.rows(), rr = b.a.cols();
  BinSolution s;
  Path path = Choose(bin, w);
  if (path == Path::kWoodbury) {
    // (3): K = A P⁻¹ Aᴴ + w I (N x N), X = P⁻¹ Aᴴ K⁻¹ Y.
    const Eigen::MatrixXcd ap = b.a * b.prior.cwiseInverse().asDiagonal();  // A P⁻¹
    Eigen::MatrixXcd k = ap * b.a.adjoint();
    k.diagonal().array() += w;
    const Eigen::LLT<Eigen::MatrixXcd> llt(k);
    if (llt.info() == Eigen::Success) {
      s.x = ap.adjoint() * llt.solve(b.y);
      s.woodbury = true;
      if (want_trace) {
        // N − tr H = w tr K⁻¹ = w ||L⁻¹||²: the residual degrees of freedom without cancellation.
        s.dof = w * llt.matrixL().solve(Eigen::MatrixXcd::Identity(n, n)).squaredNorm();
      }
    } else {
      path = Path::kNormal;
    }
  }
  if (path == Path::kNormal) {
    // Well posed: Cholesky of the Hermitian positive definite normal matrix (2).
    Eigen::MatrixXcd normal = b.a.adjoint() * b.a;
    normal.diagonal().array() += w * b.prior.array();
    const Eigen::LLT<Eigen::MatrixXcd> llt(normal);
    if (llt.info() == Eigen::Success) {
      s.x = llt.solve(b.a.adjoint() * b.y);
      if (want_trace) s.dof = double(n) - llt.matrixL().solve(b.a.adjoint()).squaredNorm();  // N − ||L⁻¹Aᴴ||²
    } else {
      path = Path::kMinimumNorm;
    }
  }
  if (path == Path::kMinimumNorm) {
    // The minimum-norm least-squares solution of the stacked system [A; √w P^½], singular values below the
    // global floor dropped: unconstrained frequencies come back as zero.
    const auto svd = StackedSvd(b.a, b.prior, w, sv_floor_);
    Eigen::VectorXcd rhs = Eigen::VectorXcd::Zero(n + rr);
    rhs.head(n) = b.y;
    s.x = svd.solve(rhs);
    if (want_trace) {
      Eigen::MatrixXcd e = Eigen::MatrixXcd::Zero(n + rr, n);
      e.topRows(n).setIdentity();
      s.dof = double(n) - (b.a * svd.solve(e)).trace().real();
    }
  }
  s.residual2 = (b.y - b.a * s.x).squaredNorm();
  return s;
}

Eigen::MatrixXcd FourierSystem::InverseBin(Index bin, double w, bool* proper, bool* woodbury, BinData* d) const {
  const BinView b = View(bin, d);
  const Index rr = b.a.cols();
  Path path = Choose(bin, w);
  *woodbury = false;
  if (path == Path::kWoodbury) {
    // G⁻¹ = (P⁻¹ − P⁻¹Aᴴ K⁻¹ A P⁻¹) / w.
    const Eigen::VectorXd pinv = b.prior.cwiseInverse();
    const Eigen::MatrixXcd ap = b.a * pinv.asDiagonal();
    Eigen::MatrixXcd k = ap * b.a.adjoint();
    k.diagonal().array() += w;
    const Eigen::LLT<Eigen::MatrixXcd> llt(k);
    if (llt.info() == Eigen::Success) {
      const Eigen::MatrixXcd z = llt.matrixL().solve(ap);  // L⁻¹ A P⁻¹
      Eigen::MatrixXcd g = -(z.adjoint() * z);
      g.diagonal() += pinv.cast<Complex>();
      *woodbury = true;
      return g / w;
    }
    path = Path::kNormal;
  }
  if (path == Path::kNormal) {
    Eigen::MatrixXcd normal = b.a.adjoint() * b.a;
    normal.diagonal().array() += w * b.prior.array();
    const Eigen::LLT<Eigen::MatrixXcd> llt(normal);
    if (llt.info() == Eigen::Success) return llt.solve(Eigen::MatrixXcd::Identity(rr, rr));
  }
  // Pseudo-inverse of G = SᴴS, S the stacked system: V diag(1/s²) Vᴴ over the singular values kept.
  const auto svd = StackedSvd(b.a, b.prior, w, sv_floor_);
  const Eigen::VectorXd& sv = svd.singularValues();
  Eigen::VectorXd inv2 = Eigen::VectorXd::Zero(sv.size());
  for (Index k = 0; k < sv.size(); ++k) {
    if (sv[k] > sv_floor_ && sv[k] > 0) {
      inv2[k] = 1.0 / (sv[k] * sv[k]);
    } else {
      *proper = false;
    }
  }
  return svd.matrixV() * inv2.asDiagonal() * svd.matrixV().adjoint();
}

FourierSystem::Fit FourierSystem::Evaluate(double lambda, bool want_trace) const {
  const double w = lambda / double(rr_);
  PrepareChoose(w);
  Fit f;
  BinData d;
  for (Index i = 0; i < nb_; ++i) {
    const BinSolution s = SolveBin(i, w, want_trace, &d);
    f.residual2 += s.residual2;
    f.dof += s.dof;
    f.woodbury_bins += s.woodbury;
  }
  f.residual2 /= double(nb_);  // Parseval for the unnormalised DFT: ||y||² = Σ|Y|² / m²
  return f;
}

Index FourierSystem::MirrorBin(Index bin) const {
  const Shape lr = model_.lr_shape();
  const Index uy = bin / lr.cols, ux = bin % lr.cols;
  return ((lr.rows - uy) % lr.rows) * lr.cols + (lr.cols - ux) % lr.cols;
}

bool FourierSystem::CanonicalBin(Index bin) const { return canonical_[bin] != 0; }

bool FourierSystem::SolveBinInPlace(Index bin, BinPtr d, double w, Path path, Complex* x, Complex* scratch) const {
  // The per-bin solves of SolveBin on caller-owned scratch (no allocation): A is column-major N x r².
  const int n = n_, rr = rr_;
  const Complex* a = d.a;
  const Complex* y = &y_[bin * n];
  const double* p = d.p;
  const double* pinv = d.pinv;
  if (path == Path::kWoodbury) {
    // (3): K = A P⁻¹ Aᴴ + w I (N x N), X = P⁻¹ Aᴴ K⁻¹ Y.
    Complex* k = scratch;
    Complex* z = scratch + n * n;
    for (int i = 0; i < n; ++i)
      for (int j = 0; j <= i; ++j) {
        Complex sum = 0;
        for (int c = 0; c < rr; ++c) sum += MulConj(a[c * n + i], a[c * n + j]) * pinv[c];
        if (i == j) sum = Complex(sum.real() + w, 0.0);
        k[i * n + j] = sum;
        k[j * n + i] = std::conj(sum);
      }
    if (!Cholesky(k, n, 0.0)) return false;
    for (int i = 0; i < n; ++i) z[i] = y[i];
    bins::Substitute(k, n, z);
    for (int c = 0; c < rr; ++c) {
      Complex sum = 0;
      for (int i = 0; i < n; ++i) sum += ConjMul(a[c * n + i], z[i]);
      x[c] = sum * pinv[c];
    }
    return true;
  }
  // kNormal: (AᴴA + w P) X = Aᴴ Y by Cholesky.
  Complex* g = scratch;
  for (int c = 0; c < rr; ++c)
    for (int d = 0; d <= c; ++d) {
      Complex sum = 0;
      const Complex* ac = a + c * n;
      const Complex* ad = a + d * n;
      for (int i = 0; i < n; ++i) sum += ConjMul(ac[i], ad[i]);
      if (c == d) sum = Complex(sum.real() + w * p[c], 0.0);
      g[c * rr + d] = sum;
      g[d * rr + c] = std::conj(sum);
    }
  if (!Cholesky(g, rr, 0.0)) return false;
  for (int c = 0; c < rr; ++c) {
    Complex sum = 0;
    for (int i = 0; i < n; ++i) sum += ConjMul(a[c * n + i], y[i]);
    x[c] = sum;
  }
  bins::Substitute(g, rr, x);
  return true;
}

Image FourierSystem::Solve(double lambda, Fit* fit) const {
  const Shape hr = model_.hr_shape(), lr = model_.lr_shape();
  const int r = model_.r(), rr = r * r, n = model_.frames();
  const double w = lambda / double(rr);
  // At w > 0 the bins whose prior vanishes somewhere are solved after the others, once the floor (noted by this
  // pass where not made yet) has decided their path; the rest need nothing made beforehand.
  const bool defer = w > 0 && !zero_prior_bins_.empty();
  const bool note_norms = defer && !FloorReady();
  FloorNorms norms;
  if (note_norms) norms = NewFloorNorms();
  if (!defer) PrepareChoose(w);
  // Only one bin of each mirror pair u, −u is solved; the other is its conjugate (the data are real), so the
  // output spectrum is exactly Hermitian and half the bins cost nothing (fourier_normal_system.hpp).
  const Index half_cols = hr.cols / 2 + 1;
  ComplexImage X(hr.rows, half_cols);
  std::vector<double> row_residual(lr.rows, 0.0), row_prior(lr.rows, 0.0);
  std::vector<Index> row_woodbury(lr.rows, 0);
  // The bins of a row in runs gathered at once (GatherRun); stride and run length as ForGatheredBins'.
  const std::size_t stride = loops::GatherStride(n, rr);
  const int run = loops::GatherRunLength(stride);
  // Solves canonical bin (uy, ux) from its gathered system bp into X; returns its residual and Woodbury counts.
  const auto solve_bin = [&](Index uy, Index ux, BinPtr bp, Complex* x, Complex* scratch, BinData* d, double* residual,
                             double* prior_norm, Index* woodbury_count) {
    const Index muy = (lr.rows - uy) % lr.rows, mux = (lr.cols - ux) % lr.cols;
    const bool self_mirror = ux == mux && uy == muy;
    const Index bin = uy * lr.cols + ux;
    Path path = Choose(bin, w);
    bool done = false, woodbury = false;
    if (path == Path::kWoodbury) {
      done = woodbury = SolveBinInPlace(bin, bp, w, Path::kWoodbury, x, scratch);
      if (!done) path = Path::kNormal;
    }
    if (!done && path == Path::kNormal) done = SolveBinInPlace(bin, bp, w, Path::kNormal, x, scratch);
    if (!done) {  // the minimum-norm path (rare: a rank-deficient bin with a zero of the prior)
      const BinSolution s = SolveBin(bin, w, false, d);
      for (int c = 0; c < rr; ++c) x[c] = s.x[c];
    }
    // The residual |Y − A X|², frame by frame (A column-major: frame i of alias c at c·N + i).
    const Complex* a = bp.a;
    const Complex* y = &y_[bin * n];
    double res = 0;
    for (int i = 0; i < n; ++i) {
      Complex ax = 0;
      for (int c = 0; c < rr; ++c) ax += Mul(a[c * n + i], x[c]);
      res += Norm2(y[i] - ax);
    }
    *residual += self_mirror ? res : 2 * res;
    *woodbury_count += woodbury ? (self_mirror ? 1 : 2) : 0;
    if (self_mirror) {  // keep the stored spectrum Hermitian within the bin (see FourierNormalSystem)
      for (int c = 0; c < rr; ++c) scratch[c] = x[c];
      for (int ky = 0; ky < r; ++ky)
        for (int kx = 0; kx < r; ++kx) {
          const Index my = (hr.rows - (uy + ky * lr.rows)) % hr.rows;
          const Index mx = (hr.cols - (ux + kx * lr.cols)) % hr.cols;
          x[ky * r + kx] = 0.5 * (scratch[ky * r + kx] + std::conj(scratch[int(my / lr.rows) * r + int(mx / lr.cols)]));
        }
    }
    double pn = 0;  // ||P^½ X(u)||²
    for (int ky = 0; ky < r; ++ky)
      for (int kx = 0; kx < r; ++kx) {
        const Index fy = uy + ky * lr.rows, fx = ux + kx * lr.cols;
        if (fx < half_cols) X(fy, fx) = x[ky * r + kx];
        const Index my = (hr.rows - fy) % hr.rows, mx = (hr.cols - fx) % hr.cols;
        if (mx < half_cols) X(my, mx) = std::conj(x[ky * r + kx]);
        pn += bp.p[ky * r + kx] * Norm2(x[ky * r + kx]);
      }
    *prior_norm += self_mirror ? pn : 2 * pn;
  };
  const std::size_t scratch_size = std::max(rr * rr, n * n + n);
  ParallelFor(lr.rows, [&](Index uy) {
    std::vector<Complex> scratch(scratch_size + rr);
    Complex* x = scratch.data() + scratch_size;
    std::vector<Complex> run_a(stride * run);
    std::vector<double> run_p(std::size_t(rr) * run), run_pinv(run_p.size());
    BinData d;
    const Index muy = (lr.rows - uy) % lr.rows;
    const auto canonical = [&](Index ux) {
      const Index mux = (lr.cols - ux) % lr.cols;
      return ux < mux || (ux == mux && uy <= muy);
    };
    Index run_begin = 0, run_end = 0;  // the gathered bins [run_begin, run_end) of this row
    for (Index ux = 0; ux < lr.cols; ++ux) {
      if (!canonical(ux)) continue;
      if (ux >= run_end) {
        run_begin = ux;
        run_end = ux + 1;
        while (run_end < lr.cols && run_end - run_begin < run && canonical(run_end)) ++run_end;
        GatherRun(uy, run_begin, int(run_end - run_begin), stride, run_a.data(), run_p.data(), run_pinv.data());
      }
      const std::size_t k = std::size_t(ux - run_begin);
      const BinPtr bp{&run_a[k * stride], &run_p[k * rr], &run_pinv[k * rr]};
      const Index bin = uy * lr.cols + ux;
      if (note_norms) NoteNorms(bin, bp, &norms);
      if (defer && !prior_positive_[bin]) continue;
      solve_bin(uy, ux, bp, x, scratch.data(), &d, &row_residual[uy], &row_prior[uy], &row_woodbury[uy]);
    }
  });
  if (defer) {
    // The bins whose prior vanishes somewhere, in bin order, after their row's others.
    if (note_norms) FinishFloor(norms);
    PrepareChoose(w);
    std::vector<Complex> scratch(scratch_size + rr);
    BinData d;
    for (Index bin : zero_prior_bins_) {
      if (!CanonicalBin(bin)) continue;
      Gather(bin, &d);
      solve_bin(bin / lr.cols, bin % lr.cols, d.ptr(), scratch.data() + scratch_size, scratch.data(), &d,
                &row_residual[bin / lr.cols], &row_prior[bin / lr.cols], &row_woodbury[bin / lr.cols]);
    }
  }
  Fit f;
  for (Index uy = 0; uy < lr.rows; ++uy) {
    f.residual2 += row_residual[uy];
    f.prior2 += row_prior[uy];
    f.woodbury_bins += row_woodbury[uy];
  }
  f.residual2 /= double(nb_);  // Parseval, as in Evaluate
  f.prior2 /= double(nb_) * double(rr);  // ||Γx||² = (1/M²) Σ_u ||P^½ X(u)||², M² = m² r² (EvaluateSpectral)
  if (fit) *fit = f;
  Image x = FftC2R(X, hr.cols);
  if (!AllFiniteParallel(x)) throw NumericalError("Tikhonov Fourier solve produced non-finite values");
  return x;
}

std::vector<Eigen::MatrixXcd> FourierSystem::Inverses(double lambda, bool* proper,
                                                      Index* woodbury_bins) const {
  const double w = lambda / double(model_.r() * model_.r());
  PrepareChoose(w);
  std::vector<Eigen::MatrixXcd> out(nb_);
  std::vector<char> ok(nb_, 1), used(nb_, 0);
  // Each bin's inverse on its own; the flags are reduced in bin order afterwards.
  ForBinBlocks<BinData>(nb_, [&](Index i, BinData* d) {
    bool proper_i = true, woodbury_i = false;
    out[i] = InverseBin(i, w, &proper_i, &woodbury_i, d);
    ok[i] = proper_i;
    used[i] = woodbury_i;
  });
  Index wb = 0;
  bool all_ok = true;
  for (Index i = 0; i < nb_; ++i) {
    all_ok = all_ok && ok[i];
    wb += used[i];
  }
  if (proper) *proper = all_ok;
  if (woodbury_bins) *woodbury_bins = wb;
  return out;
}

Eigen::MatrixXcd FourierSystem::InverseMean(double lambda, bool* proper) const {
  const double w = lambda / double(model_.r() * model_.r());
  PrepareChoose(w);
  const Index blocks = (nb_ + kBinBlock - 1) / kBinBlock;
  std::vector<Eigen::MatrixXcd> partial(std::size_t(blocks), Eigen::MatrixXcd::Zero(rr_, rr_));
  std::vector<char> ok(std::size_t(blocks), 1);
  // ForBinBlocks runs each block's bins in order on one task, so block i / kBinBlock is written by one thread.
  ForBinBlocks<BinData>(nb_, [&](Index i, BinData* d) {
    bool proper_i = true, woodbury_i = false;
    partial[std::size_t(i / kBinBlock)] += InverseBin(i, w, &proper_i, &woodbury_i, d);
    if (!proper_i) ok[std::size_t(i / kBinBlock)] = 0;
  });
  Eigen::MatrixXcd sum = Eigen::MatrixXcd::Zero(rr_, rr_);
  bool all_ok = true;
  for (Index b = 0; b < blocks; ++b) {
    sum += partial[std::size_t(b)];
    all_ok = all_ok && ok[std::size_t(b)];
  }
  if (proper) *proper = all_ok;
  return sum / double(nb_);
}

}  // namespace aosr::tikhonov_internal
