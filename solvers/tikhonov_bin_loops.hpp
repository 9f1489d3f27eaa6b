// Private to solvers/tikhonov_fourier_system.cpp and solvers/tikhonov_spectral.cpp: the loops over FourierSystem's
// LR bins (fixed blocks, so that every task writes the same bins whatever the thread count) and the complex
// products of their inner loops.
#pragma once

#include <algorithm>
#include <vector>

#include "aosr/core/parallel.hpp"
#include "tikhonov_internal.hpp"

namespace aosr::tikhonov_internal {
namespace loops {

// Bins per parallel task of the per-bin passes: a fixed partition, so every task writes the same bins whatever
// the thread count.
inline constexpr Index kBinBlock = 512;
// Bins per run of FourierSystem::GatherRun (at most).
inline constexpr int kGatherRun = 64;

// f(i, &scratch) for every bin i, one Scratch per block (FourierSystem's gathered bins).
template <class Scratch, class F>
void ForBinBlocks(Index bins, const F& f) {
  ParallelFor((bins + kBinBlock - 1) / kBinBlock, [&](Index block) {
    Scratch scratch;
    const Index end = std::min(bins, (block + 1) * kBinBlock);
    for (Index i = block * kBinBlock; i < end; ++i) f(i, &scratch);
  });
}

// a·conj(b) and conj(a)·b without the NaN-recovery branch of std::complex's product (finite data here).
inline Complex MulConj(Complex a, Complex b) {
  return {a.real() * b.real() + a.imag() * b.imag(), a.imag() * b.real() - a.real() * b.imag()};
}
inline Complex ConjMul(Complex a, Complex b) {
  return {a.real() * b.real() + a.imag() * b.imag(), a.real() * b.imag() - a.imag() * b.real()};
}
inline Complex Mul(Complex a, Complex b) {
  return {a.real() * b.real() - a.imag() * b.imag(), a.real() * b.imag() + a.imag() * b.real()};
}

// The bin stride of a gathered run: N r² rounded up to a multiple of 4 values plus 4 (64 bytes), so that the bins
// of a run do not map to one cache set.
inline std::size_t GatherStride(int n, int rr) { return (std::size_t(n) * rr + 3) / 4 * 4 + 4; }
// The bins of a run: at most kGatherRun and ~256 KiB.
inline int GatherRunLength(std::size_t stride) {
  return int(std::clamp<std::size_t>((std::size_t(256) << 10) / (stride * sizeof(Complex)), 1, kGatherRun));
}

// The columns of a bin kept for its decomposition, given their squared norms: the columns whose norm is at most
// `threshold` are dropped, all of them if their sum fits under it, else the smallest while their sum fits
// (ascending norm, ties by index). Writes the kept indices in increasing order to keep[0 .. returned).
inline int KeptColumns(const double* norms, int count, double threshold, int* keep) {
  double small = 0;
  for (int c = 0; c < count; ++c)
    if (norms[c] <= threshold) small += norms[c];
  int kept = 0;
  if (small <= threshold) {
    for (int c = 0; c < count; ++c)
      if (norms[c] > threshold) keep[kept++] = c;
    return kept;
  }
  std::vector<int> order(count);
  for (int c = 0; c < count; ++c) order[c] = c;
  std::sort(order.begin(), order.end(),
            [&](int x, int y) { return norms[x] < norms[y] || (norms[x] == norms[y] && x < y); });
  double dropped = 0;
  std::vector<char> drop(count, 0);
  for (int c : order)
    if (dropped + norms[c] <= threshold) dropped += norms[c], drop[c] = 1;
  for (int c = 0; c < count; ++c)
    if (!drop[c]) keep[kept++] = c;
  return kept;
}

}  // namespace loops

template <class Want, class F>
inline void FourierSystem::ForGatheredBins(const Want& want, const F& f) const {
  ForGatheredBins(want, f, [] {}, [] {});
}

template <class Want, class F, class Begin, class Done>
inline void FourierSystem::ForGatheredBins(const Want& want, const F& f, const Begin& block_begin,
                                    const Done& block_done) const {
  const Index cols = model_.lr_shape().cols;
  const std::size_t stride = loops::GatherStride(n_, rr_);
  const int run = loops::GatherRunLength(stride);
  ParallelFor((nb_ + loops::kBinBlock - 1) / loops::kBinBlock, [&](Index block) {
    std::vector<Complex> a(stride * run);
    std::vector<double> p(std::size_t(rr_) * run), pinv(p.size());
    block_begin();
    const Index end = std::min(nb_, (block + 1) * loops::kBinBlock);
    Index i = block * loops::kBinBlock;
    while (i < end) {
      if (!want(i)) {
        ++i;
        continue;
      }
      // A run of wanted bins within one LR row.
      const Index row_end = std::min(end, (i / cols + 1) * cols);
      Index j = i + 1;
      while (j < row_end && j - i < run && want(j)) ++j;
      GatherRun(i / cols, i % cols, int(j - i), stride, a.data(), p.data(), pinv.data());
      for (Index k = i; k < j; ++k)
        f(k, BinPtr{&a[std::size_t(k - i) * stride], &p[std::size_t(k - i) * rr_], &pinv[std::size_t(k - i) * rr_]});
      i = j;
    }
    block_done();
  });
}

}  // namespace aosr::tikhonov_internal
