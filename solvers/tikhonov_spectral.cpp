// The spectral decomposition of FourierSystem (tikhonov_internal.hpp) that the λ rules evaluate (MakeSpectral,
// EvaluateSpectral). Per canonical LR bin (one of each conjugate pair, counted twice): the singular values of the
// prior-whitened system A(u) P(u)^(−1/2) and the data's squared coordinates on its left singular vectors, by
// Eigen's SVD (SpectralMethod::kSvd) or by the bidiagonalisation of bin_kernels.hpp on whitened bins taken in
// pairs. Bins whose prior vanishes at some aliases are reduced to the complement of that null space where the data
// see it, else solved at each λ. Made once; then GCV, UPRE, the L-curve and the discrepancy principle evaluate any
// λ in one pass over the bins, without solving.
#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include "aosr/core/error.hpp"
#include "aosr/core/parallel.hpp"
#include "bin_kernels.hpp"
#include "tikhonov_bin_loops.hpp"
#include "tikhonov_internal.hpp"

namespace aosr::tikhonov_internal {

using bins::Norm2;
using loops::ConjMul;
using loops::ForBinBlocks;
using loops::kBinBlock;
using loops::Mul;

void FourierSystem::DecomposeBinSvd(Index i, Spectral* sp, BinData* d) const {
  // The SVD of B = A P^(-1/2) with the full U (N x N), whose columns past q span the complement of A's range, so
  // the part of Y no λ can fit is a sum of squares, not a difference ||Y||² − ||UᴴY||².
  const BinView b = View(i, d);
  const int q = std::min(n_, rr_);
  const Eigen::MatrixXcd whitened = b.a * b.prior.cwiseSqrt().cwiseInverse().asDiagonal();
  const Eigen::JacobiSVD<Eigen::MatrixXcd> svd(whitened, Eigen::ComputeFullU);
  const Eigen::VectorXcd uy = svd.matrixU().adjoint() * b.y;
  for (int k = 0; k < q; ++k) {
    sp->s2[i * sp->q_max + k] = svd.singularValues()[k] * svd.singularValues()[k];
    sp->c[i * sp->q_max + k] = Norm2(uy[k]);
  }
  sp->q[i] = q;
  sp->perp[i] = uy.tail(uy.size() - q).squaredNorm();
}

void FourierSystem::DecomposeBinBidiagonal(Index i, Spectral* sp, BinPtr bd, WhitenedPair* pair) const {
  // Bins of one shape are decomposed two at a time (bins::SingularSpectra<2>: the same bits as one by one): the
  // pending one waits in pair->bin[0] until a second of its shape comes, or FinishPair.
  WhitenedBin& next = pair->bin[pair->pending];
  PrepareWhitened(n_, bd.a, bd.pinv, &y_[i * n_], &next);
  next.s2 = &sp->s2[i * sp->q_max];
  next.c = &sp->c[i * sp->q_max];
  next.q = &sp->q[i];
  next.perp = &sp->perp[i];
  if (pair->pending == 0) {
    pair->pending = 1;
    return;
  }
  if (pair->bin[0].kept == next.kept) {
    DecomposePrepared(n_, pair->bin, 2);
    pair->pending = 0;
  } else {  // shapes differ: the older alone, the newer waits
    DecomposePrepared(n_, pair->bin, 1);
    std::swap(pair->bin[0], pair->bin[1]);
  }
}

void FourierSystem::FinishPair(WhitenedPair* pair) const {
  if (pair->pending) DecomposePrepared(n_, pair->bin, 1);
  pair->pending = 0;
}

void FourierSystem::PrepareWhitened(int n, const Complex* a, const double* pinv, const Complex* y,
                                    WhitenedBin* out) const {
  // B = A P^(-1/2) (N x r², column-major), and the data Y. GCV, UPRE, the L-curve and the discrepancy rule weigh the
  // small singular values of B too (aliases beyond the optical cutoff, 1e-10 .. 1e-20 of the largest in most bins
  // of the shipped scenes), which an eigen-decomposition of the Gram matrix B Bᴴ would hold only to ~ε s_max²
  // absolutely. So they come from B itself (bins::SingularSpectrum: Householder bidiagonalisation and implicit QR
  // sweeps, the left transformations applied to Y alone), to the accuracy of an SVD of B: s² to ~ε s_max s, and
  // |uᴴY|² without forming U. Columns of B whose squared norms sum to at most ε² ||B||²_F (below the rounding of
  // any factorisation of B) are dropped first. Where N > kept columns, the part of Y no λ fits is the sum of
  // squares of the trailing entries of PᴴY (no cancellation).
  const int rr = rr_;
  const int qn = std::min(n, rr);
  // Scratch (doubles): B 2·n·rr, Y 2n, v 4·max(n, rr), d and e 2qn, norms rr, keep rr.
  const std::size_t need =
      2 * std::size_t(n) * rr + 2 * n + 4 * std::size_t(std::max(n, rr)) + 2 * qn + 2 * std::size_t(rr) + 16;
  if (out->scratch.size() < need) out->scratch.resize(need);
  double* base = out->scratch.data();
  Complex* bw = reinterpret_cast<Complex*>(base);
  Complex* yv = bw + std::size_t(n) * rr;
  Complex* v = yv + n;
  double* de = reinterpret_cast<double*>(v + 2 * std::max(n, rr));
  double* norms = de + 2 * qn;
  int* keep = reinterpret_cast<int*>(norms + rr);
  out->b = bw;
  out->y = yv;
  out->v = v;
  out->work = de;
  // B and its column norms; columns below ε² ||B||²_F in total dropped (ascending, ties by index).
  double total = 0;
  for (int c = 0; c < rr; ++c) {
    const double sc = std::sqrt(pinv[c]);
    double s = 0;
    for (int f = 0; f < n; ++f) {
      const Complex z = a[c * n + f] * sc;
      bw[c * n + f] = z;
      s += Norm2(z);
    }
    norms[c] = s;
    total += s;
  }
  const double eps = std::numeric_limits<double>::epsilon();
  const double threshold = eps * eps * total;
  const int kept = loops::KeptColumns(norms, rr, threshold, keep);
  for (int k = 0; k < kept; ++k)
    if (keep[k] != k)
      for (int f = 0; f < n; ++f) bw[k * n + f] = bw[keep[k] * n + f];
  for (int f = 0; f < n; ++f) yv[f] = y[f];
  out->kept = kept;
}

void FourierSystem::DecomposePrepared(int n, WhitenedBin* bins, int count) const {
  // q = min(N, kept) singular values of the N x kept matrix B and the projections of Y (count bins of one shape).
  bins::SpectrumJob jobs[2];
  for (int l = 0; l < count; ++l) {
    WhitenedBin& w = bins[l];
    jobs[l] = bins::SpectrumJob{w.b, w.y, w.s2, w.c, w.perp, w.work, w.v};
    *w.q = std::min(n, w.kept);
  }
  if (count == 2)
    bins::SingularSpectra<2>(jobs, n, bins[0].kept, n);
  else
    bins::SingularSpectra<1>(jobs, n, bins[0].kept, n);
  for (int l = 0; l < count; ++l)
    if (!jobs[l].ok)
      throw NumericalError("Tikhonov spectral decomposition: the SVD did not converge (non-finite data?)");
}

void FourierSystem::DecomposeWhitened(int n, const Complex* a, const double* pinv, const Complex* y, double* s2_out,
                                      double* c_out, int* q_out, double* perp_out, WhitenedBin* scratch) const {
  PrepareWhitened(n, a, pinv, y, scratch);
  scratch->s2 = s2_out;
  scratch->c = c_out;
  scratch->q = q_out;
  scratch->perp = perp_out;
  DecomposePrepared(n, scratch, 1);
}

void FourierSystem::MakeSpectral() const {
  auto sp = std::make_unique<Spectral>();
  sp->q_max = std::min(n_, rr_);
  sp->s2.assign(nb_ * sp->q_max, 0.0);
  sp->c.assign(nb_ * sp->q_max, 0.0);
  sp->perp.assign(nb_, 0.0);
  sp->q.assign(nb_, 0);
  sp->zeros.assign(nb_, 0);
  sp->weight.assign(nb_, 0);
  for (Index i = 0; i < nb_; ++i) {
    if (!prior_positive_[i]) {
      sp->direct.push_back(i);
    } else if (CanonicalBin(i)) {
      // Bins u and −u have conjugate systems and data (real frames, real PSFs, an even prior), hence the same
      // singular values and |UᴴY|²: one of each pair is decomposed and counted twice.
      sp->weight[i] = char(MirrorWeight(i));
    }
  }
  // One decomposition per counted bin, on fixed blocks of bins: each writes only its own slots.
  if (spectral_method_ == SpectralMethod::kSvd) {
    ForBinBlocks<BinData>(nb_, [&](Index i, BinData* d) {
      if (sp->weight[i]) DecomposeBinSvd(i, sp.get(), d);
    });
  } else {
    // Every canonical bin is gathered: the decomposition's, and the floor's norms where not made yet.
    const bool note_norms = !FloorReady();
    FloorNorms norms;
    if (note_norms) norms = NewFloorNorms();
    // The decomposition's scratch and pending bin, per thread (grown once), nothing pending across blocks.
    thread_local WhitenedPair pair;
    ForGatheredBins([&](Index i) { return CanonicalBin(i) && (note_norms || sp->weight[i] != 0); },
                    [&](Index i, BinPtr d) {
                      if (note_norms) NoteNorms(i, d, &norms);
                      if (sp->weight[i]) DecomposeBinBidiagonal(i, sp.get(), d, &pair);
                    },
                    [&] { pair.pending = 0; }, [&] { FinishPair(&pair); });
    if (note_norms) FinishFloor(norms);
    // The bins whose prior vanishes at aliases Z, where the data see that null space (EnsureZeroPriorRanks): x_Z
    // is fitted without penalty, so with Q_Z from the QR of A(u)_Z the objective is ||Π(Y − A_R x_R)||² +
    // w ||P_R^½ x_R||² on the complement Π = I − Q_Z Q_Zᴴ (N − z dimensions), a Tikhonov problem with a positive
    // prior: the same decomposition on the N − z reflected rows, with N − tr H = Σ w/(s² + w) + (N − z − q).
    // The others stay direct (solved at each λ).
    EnsureZeroPriorRanks();
    std::vector<Index> direct;
    BinData d;
    WhitenedBin scratch;
    std::vector<Complex> reduced, yr;
    for (Index i : sp->direct) {
      if (!seen_[i]) {
        direct.push_back(i);
        continue;
      }
      if (!CanonicalBin(i)) continue;  // counted twice through its canonical mirror
      Gather(i, &d);
      std::vector<Complex>& a = d.a;
      std::vector<Complex> y(y_.begin() + i * n_, y_.begin() + (i + 1) * n_);
      int z = 0;
      for (int c = 0; c < rr_ && z < n_; ++c) {
        if (d.p[c] > 0) continue;
        // Householder on rows z .. N-1 of column c, applied to every column and to Y.
        Complex* x = &a[std::size_t(c) * n_ + z];
        const int len = n_ - z;
        double alpha2 = 0;
        for (int t = 0; t < len; ++t) alpha2 += Norm2(x[t]);
        const double alpha = std::sqrt(alpha2), a0 = std::sqrt(Norm2(x[0]));
        if (alpha > 0) {
          const Complex phase = a0 > 0 ? x[0] / a0 : Complex(1.0);
          std::vector<Complex> v(x, x + len);
          v[0] += phase * alpha;
          const double scale = 1.0 / (alpha * (alpha + a0));
          const auto reflect = [&](Complex* col) {
            Complex dot = 0;
            for (int t = 0; t < len; ++t) dot += ConjMul(v[t], col[t]);
            dot *= scale;
            for (int t = 0; t < len; ++t) col[t] -= Mul(v[t], dot);
          };
          for (int k = 0; k < rr_; ++k) reflect(&a[std::size_t(k) * n_ + z]);
          reflect(&y[z]);
        }
        ++z;
      }
      const int nr = n_ - z;
      reduced.assign(std::size_t(nr) * rr_, Complex(0));
      for (int k = 0; k < rr_; ++k)
        for (int t = 0; t < nr; ++t) reduced[std::size_t(k) * nr + t] = a[std::size_t(k) * n_ + z + t];
      yr.assign(y.begin() + z, y.end());
      DecomposeWhitened(nr, reduced.data(), d.pinv.data(), yr.data(), &sp->s2[i * sp->q_max], &sp->c[i * sp->q_max],
                        &sp->q[i], &sp->perp[i], &scratch);
      sp->zeros[i] = z;
      sp->weight[i] = char(MirrorWeight(i));
    }
    sp->direct = std::move(direct);
  }
  std::size_t terms = 0;
  for (Index i = 0; i < nb_; ++i)
    if (sp->weight[i]) terms += std::size_t(sp->q[i]);
  sp->term_s2.resize(terms);
  sp->term_wc.resize(terms);
  sp->term_weight.resize(terms);
  std::size_t t = 0;
  for (Index i = 0; i < nb_; ++i) {
    const int weight = sp->weight[i];
    if (!weight) continue;
    for (int k = 0; k < sp->q[i]; ++k, ++t) {
      sp->term_s2[t] = sp->s2[i * sp->q_max + k];
      sp->term_wc[t] = weight * sp->c[i * sp->q_max + k];
      sp->term_weight[t] = weight;
    }
    sp->fixed_residual += weight * sp->perp[i];
    sp->fixed_dof += weight * double(n_ - sp->zeros[i] - sp->q[i]);
  }
  spectral_ = std::move(sp);
}

FourierSystem::Fit FourierSystem::EvaluateSpectral(double lambda, bool want_prior) const {
  if (!spectral_) MakeSpectral();
  const Spectral& sp = *spectral_;
  const double rr = double(rr_);
  const double w = lambda / rr;
  const Index n = n_;
  Fit f;
  double prior = 0, dprior = 0;
  if (w > 0 && !want_prior) {
    // The search's common case, one stream of terms: w/(s² + w) and its square, in fixed blocks of terms on
    // four independent lanes each (vectorisable without reassociation), lanes and blocks reduced in a fixed
    // order (the same bits on any thread count and instruction set).
    constexpr Index kTerms = 8192;
    const Index count = Index(sp.term_s2.size()), blocks = (count + kTerms - 1) / kTerms;
    std::vector<double> part(2 * blocks, 0.0);
    const double* s2 = sp.term_s2.data();
    const double* wc = sp.term_wc.data();
    const double* wt = sp.term_weight.data();
    ParallelFor(blocks, [&](Index block) {
      double res[4] = {0, 0, 0, 0}, dof[4] = {0, 0, 0, 0};
      const Index end = std::min(count, (block + 1) * kTerms);
      Index t = block * kTerms;
      for (; t + 4 <= end; t += 4)
        for (int l = 0; l < 4; ++l) {
          const double g = w / (s2[t + l] + w);
          res[l] += g * g * wc[t + l];
          dof[l] += g * wt[t + l];
        }
      for (; t < end; ++t) {
        const double g = w / (s2[t] + w);
        res[0] += g * g * wc[t];
        dof[0] += g * wt[t];
      }
      part[2 * block] = (res[0] + res[1]) + (res[2] + res[3]);
      part[2 * block + 1] = (dof[0] + dof[1]) + (dof[2] + dof[3]);
    });
    f.residual2 = sp.fixed_residual;
    f.dof = sp.fixed_dof;
    for (Index b = 0; b < blocks; ++b) {
      f.residual2 += part[2 * b];
      f.dof += part[2 * b + 1];
    }
  } else {
    // Sums over the decomposed bins, on fixed blocks of bins, reduced in block order (the same bits on any number of
    // threads).
    const Index blocks = (nb_ + kBinBlock - 1) / kBinBlock;
    std::vector<double> part(4 * blocks, 0.0);
    ParallelFor(blocks, [&](Index block) {
      double res_sum = 0, dof_sum = 0, prior_sum = 0, dprior_sum = 0;  // Σ_u ||P^½ X||² and its derivative by w
      const Index end = std::min(nb_, (block + 1) * kBinBlock);
      for (Index i = block * kBinBlock; i < end; ++i) {
        const int weight = sp.weight[i];
        if (!weight) continue;
        const int q = sp.q[i];
        const double* s2 = &sp.s2[i * sp.q_max];
        const double* c = &sp.c[i * sp.q_max];
        double res = sp.perp[i], dof = double(n - sp.zeros[i] - q), prior = 0, dprior = 0;
        for (int k = 0; k < q; ++k) {
          // w / (s² + w), 1 where both vanish (an unseen direction keeps all its data in the residual).
          const double d = s2[k] + w;
          const double g = d > 0 ? w / d : 1.0;
          res += g * g * c[k];
          dof += g;
          if (want_prior && d > 0) {
            // z = P^½ X = s/(s² + w) (uᴴY) v: ||z||² = s² c/(s² + w)², d/dw = −2 s² c/(s² + w)³.
            const double e = s2[k] * c[k] / (d * d);
            prior += e;
            dprior -= 2.0 * e / d;
          }
        }
        res_sum += weight * res;
        dof_sum += weight * dof;
        prior_sum += weight * prior;
        dprior_sum += weight * dprior;
      }
      part[4 * block] = res_sum;
      part[4 * block + 1] = dof_sum;
      part[4 * block + 2] = prior_sum;
      part[4 * block + 3] = dprior_sum;
    });
    for (Index b = 0; b < blocks; ++b) {
      f.residual2 += part[4 * b];
      f.dof += part[4 * b + 1];
      prior += part[4 * b + 2];
      dprior += part[4 * b + 3];
    }
  }
  if (!sp.direct.empty()) PrepareChoose(w);
  BinData bd;
  for (Index i : sp.direct) {
    const BinSolution s = SolveBin(i, w, true, &bd);
    const BinView b = View(i, &bd);
    f.residual2 += s.residual2;
    f.dof += s.dof;
    if (want_prior) {
      // dX/dw = −G⁻¹ P X, so d||P^½X||²/dw = −2 Re (PX)ᴴ G⁻¹ (PX).
      const Eigen::VectorXcd px = b.prior.cast<Complex>().cwiseProduct(s.x);
      prior += (s.x.conjugate().cwiseProduct(px)).sum().real();
      bool proper = true, woodbury = false;
      BinData gd;
      const Eigen::MatrixXcd g = InverseBin(i, w, &proper, &woodbury, &gd);
      dprior -= 2.0 * (px.adjoint() * g * px)(0, 0).real();
    }
  }
  f.residual2 /= double(nb_);  // Parseval, as in Evaluate
  if (want_prior) {
    // ||Γx||² = (1/M²) Σ_u ||P^½ X(u)||², M² = m² r²; dη/dλ = (dη/dw)/r².
    f.prior2 = prior / (double(nb_) * rr);
    f.dprior2 = dprior / (double(nb_) * rr * rr);
  }
  return f;
}

}  // namespace aosr::tikhonov_internal
