#include "aosr/solvers/fourier_normal_system.hpp"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <new>
#include <string>
#include <vector>

#include "aosr/core/error.hpp"
#include "aosr/core/fft.hpp"
#include "aosr/core/parallel.hpp"
#include "bin_kernels.hpp"

namespace aosr {

namespace {

// Largest tolerated Woodbury amplification ||B||²_F / min D (see the header): the subtraction in
// D⁻¹v − D⁻¹BᴴK⁻¹BD⁻¹v loses about log10 of it in digits.
constexpr double kWoodburyAmplification = 1e6;
// Largest r² whose per-bin scratch lives on the stack.
constexpr int kStackBins = 64;

// (size − f) mod size for 0 <= f < size, the index of frequency −f, without an integer division (the per-bin
// gathers and scatters of SolveBins do several per HR frequency).
inline Index Mirror(Index f, Index size) { return f == 0 ? 0 : size - f; }

// The LR bins come in mirror pairs u, −u whose systems are conjugate, and only the first of each pair (in
// the order ux, then uy) is ever formed, factorised and solved (SolveBins). Returns 2 for such a bin, 1 for
// a bin that is its own mirror, 0 for a bin solved through its mirror.
inline int MirrorMultiplicity(Shape lr, Index uy, Index ux) {
  const Index muy = Mirror(uy, lr.rows), mux = Mirror(ux, lr.cols);
  if (ux == mux && uy == muy) return 1;
  return ux < mux || (ux == mux && uy < muy) ? 2 : 0;
}

// The symbol of ∇ᵀ∇ for periodic forward differences at full-spectrum HR bin (fy, fx) is
// |e^{2πi f_y/M_y} − 1|² + |e^{2πi f_x/M_x} − 1|² = 4 (sin²(π f_y/M_y) + sin²(π f_x/M_x)); this is one
// axis's table of sin²(π f/M), f = 0 .. M − 1.
std::vector<double> SineSquares(Index size) {
  std::vector<double> t(size);
  for (Index f = 0; f < size; ++f) {
    const double s = std::sin(M_PI * double(f) / double(size));
    t[f] = s * s;
  }
  return t;
}

// Two complex values [re, im, re, im] as one vector: GCC lowers it to two SSE2 operations on the baseline
// x86-64 target and to one AVX operation in WoodburySolve's AVX2 clone. Loaded and stored by memcpy (any
// alignment; compiled to vector moves), and never passed by value, which the two clones' ABIs would pass
// differently.
typedef double V4 __attribute__((vector_size(32)));

// The Woodbury solve of one bin (the header): c = D⁻¹v, t = K⁻¹ B c, v = c − D⁻¹ Bᴴ t, for B (N x r², row-major,
// [re, im] pairs), D⁻¹ (r² values) and K's factor (N x N). work holds N values. The products run two complex
// values per vector: B c as per-lane partial sums of B_ik·Re c_k and B_ik·Im c_k (combined at the end of a row),
// Bᴴ t as per-lane sums over the rows. Its summation order is fixed for a given r² and N, so the bits do not
// depend on the thread count or on which clone runs (no fused multiply-add: the AVX2 clone has no FMA).
__attribute__((target_clones("avx2", "default"))) void WoodburySolve(const double* b, const double* dinv,
                                                                    const Complex* kfactor, int n, int rr,
                                                                    Complex* v, Complex* work) {
  double* vd = reinterpret_cast<double*>(v);
  double* wd = reinterpret_cast<double*>(work);
  const int pairs = rr / 2;
  // c = D⁻¹ v, and its duplicated real and imaginary parts: re[j] = [Re c_2j, Re c_2j, Re c_2j+1, Re c_2j+1].
  // The duplicated parts of c, 4 doubles per pair of bins: [Re c_2j, Re c_2j, Re c_2j+1, Re c_2j+1], then Im.
  double stack_dup[4 * kStackBins];
  std::vector<double> heap_dup;  // r > 8 only
  double* dup = stack_dup;
  if (2 * pairs > kStackBins) {
    heap_dup.resize(std::size_t(8 * pairs));
    dup = heap_dup.data();
  }
  for (int k = 0; k < rr; ++k) {
    vd[2 * k] *= dinv[k];
    vd[2 * k + 1] *= dinv[k];
  }
  for (int j = 0; j < pairs; ++j) {
    const double r0 = vd[4 * j], i0 = vd[4 * j + 1], r1 = vd[4 * j + 2], i1 = vd[4 * j + 3];
    double* re = dup + 8 * j;
    re[0] = re[1] = r0;
    re[2] = re[3] = r1;
    re[4] = re[5] = i0;
    re[6] = re[7] = i1;
  }
  for (int i = 0; i < n; ++i) {
    const double* bi = b + 2 * i * rr;
    V4 a = {0, 0, 0, 0}, q = {0, 0, 0, 0};  // a: [Br·cr, Bi·cr, ..], q: [Br·ci, Bi·ci, ..]
    for (int j = 0; j < pairs; ++j) {
      V4 bv, cr, ci;
      std::memcpy(&bv, bi + 4 * j, sizeof bv);
      std::memcpy(&cr, dup + 8 * j, sizeof cr);
      std::memcpy(&ci, dup + 8 * j + 4, sizeof ci);
      a += bv * cr;
      q += bv * ci;
    }
    double re = (a[0] + a[2]) - (q[1] + q[3]), im = (a[1] + a[3]) + (q[0] + q[2]);
    if (rr % 2) {
      const int k = rr - 1;
      re += bi[2 * k] * vd[2 * k] - bi[2 * k + 1] * vd[2 * k + 1];
      im += bi[2 * k] * vd[2 * k + 1] + bi[2 * k + 1] * vd[2 * k];
    }
    wd[2 * i] = re;
    wd[2 * i + 1] = im;
  }
  bins::Substitute(kfactor, n, work);
  // (Bᴴ t)_k = Σ_i conj(B_ik) t_i = Σ_i (Br tr + Bi ti) + i (Br ti − Bi tr), two k per vector.
  for (int j = 0; j < pairs; ++j) {
    V4 p = {0, 0, 0, 0}, q = {0, 0, 0, 0};  // p: [Br·tr, Bi·tr, ..], q: [Br·ti, Bi·ti, ..]
    for (int i = 0; i < n; ++i) {
      V4 bv;
      std::memcpy(&bv, b + 2 * i * rr + 4 * j, sizeof bv);
      const double tr = wd[2 * i], ti = wd[2 * i + 1];
      p += bv * V4{tr, tr, tr, tr};
      q += bv * V4{ti, ti, ti, ti};
    }
    const int k = 2 * j;
    vd[2 * k] -= dinv[k] * (p[0] + q[1]);
    vd[2 * k + 1] -= dinv[k] * (q[0] - p[1]);
    vd[2 * k + 2] -= dinv[k + 1] * (p[2] + q[3]);
    vd[2 * k + 3] -= dinv[k + 1] * (q[2] - p[3]);
  }
  if (rr % 2) {
    const int k = rr - 1;
    double re = 0, im = 0;
    for (int i = 0; i < n; ++i) {
      const double br = b[2 * (i * rr + k)], bim = b[2 * (i * rr + k) + 1];
      re += br * wd[2 * i] + bim * wd[2 * i + 1];
      im += br * wd[2 * i + 1] - bim * wd[2 * i];
    }
    vd[2 * k] -= dinv[k] * re;
    vd[2 * k + 1] -= dinv[k] * im;
  }
}

}  // namespace

FourierNormalSystem::FourierNormalSystem(const MultiFrameModel& model, double data_weight)
    : hr_(model.hr_shape()), lr_(model.lr_shape()), r_(model.r()), n_(model.frames()) {
  CheckArgument(std::isfinite(data_weight) && data_weight > 0, "FourierNormalSystem", "data_weight",
                data_weight, "finite and > 0");
  const int rr = r_ * r_;
  const Index bins = lr_.size();
  // F(AᵀA x) = r² A(u)ᴴA(u) X(u) per bin (Parseval for the unnormalised DFTs): the data block is BᴴB.
  sqrt_s_ = std::sqrt(double(rr) * data_weight);
  // Uninitialised storage: only the solved bins are written (constructed in place), in parallel, so the
  // array is neither zero-filled first nor page-faulted in on one thread (64 MiB at r = 8, N = 4, 1024²).
  b_.reset(static_cast<Complex*>(std::malloc(sizeof(Complex) * std::size_t(bins * n_ * rr) + 1)));
  if (!b_) throw std::bad_alloc();
  symbol_.resize(bins * rr);
  const std::vector<double> sy2 = SineSquares(hr_.rows), sx2 = SineSquares(hr_.cols);
  ParallelFor(lr_.rows, [&](Index uy) {
    for (Index ux = 0; ux < lr_.cols; ++ux) {
      if (!MirrorMultiplicity(lr_, uy, ux)) continue;  // never read (b_ unwritten, symbol_ 0 there)
      const Index bin = uy * lr_.cols + ux;
      const Eigen::MatrixXcd a = model.AliasedSystem(uy, ux);
      for (int i = 0; i < n_; ++i)
        for (int k = 0; k < rr; ++k) new (&b_[(bin * n_ + i) * rr + k]) Complex(sqrt_s_ * a(i, k));
      for (int ky = 0; ky < r_; ++ky)
        for (int kx = 0; kx < r_; ++kx)
          symbol_[bin * rr + ky * r_ + kx] = 4.0 * (sy2[uy + ky * lr_.rows] + sx2[ux + kx * lr_.cols]);
    }
  });
}

double FourierNormalSystem::ModelNorm() const {
  std::call_once(model_norm_once_, [this] {
    // σ_max(A(u))² = λ_max(B Bᴴ) / s (B = √s A(u)) from the smaller Gram matrix (BBᴴ or BᴴB, row-major), by
    // the allocation-free Householder + QL solver, bins in parallel.
    const int rr = r_ * r_, m = std::min(n_, rr);
    const Index bins = lr_.size();
    std::vector<double> norms(bins, 0.0);
    if (m > 0)
      ParallelFor(lr_.rows, [&](Index uy) {
        std::vector<Complex> gram(std::size_t(m) * m), vectors(std::size_t(m) * m);
        std::vector<double> values(m), work(3 * std::size_t(m) * m + 2 * m);
        for (Index ux = 0; ux < lr_.cols; ++ux) {
          if (!MirrorMultiplicity(lr_, uy, ux)) continue;  // a mirror bin has the same singular values
          const Index bin = uy * lr_.cols + ux;
          const Eigen::Map<const Eigen::Matrix<Complex, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>> b(
              &b_[bin * n_ * rr], n_, rr);
          for (int i = 0; i < m; ++i)
            for (int j = 0; j < m; ++j) {
              Complex sum = 0;
              if (n_ <= rr)
                for (int k = 0; k < rr; ++k) sum += b(i, k) * std::conj(b(j, k));
              else
                for (int k = 0; k < n_; ++k) sum += std::conj(b(k, i)) * b(k, j);
              gram[i * m + j] = sum;
            }
          if (bins::HermitianEigen(gram.data(), m, values.data(), vectors.data(), work.data())) {
            norms[bin] = values[m - 1];
          } else {  // QL did not converge (not seen): Eigen's solver
            const Eigen::MatrixXcd g = n_ <= rr ? Eigen::MatrixXcd(b * b.adjoint()) : Eigen::MatrixXcd(b.adjoint() * b);
            norms[bin] = Eigen::SelfAdjointEigenSolver<Eigen::MatrixXcd>(g, Eigen::EigenvaluesOnly).eigenvalues().maxCoeff();
          }
        }
      });
    const double largest = norms.empty() ? 0.0 : *std::max_element(norms.begin(), norms.end());
    model_norm_ = double(r_) * std::sqrt(std::max(0.0, largest) / (sqrt_s_ * sqrt_s_));
  });
  return model_norm_;
}

void FourierNormalSystem::Factorize(double gradient_weight, double identity_weight) {
  CheckArgument(std::isfinite(gradient_weight) && gradient_weight >= 0, "FourierNormalSystem::Factorize",
                "gradient_weight", gradient_weight, "finite and >= 0");
  CheckArgument(std::isfinite(identity_weight) && identity_weight >= 0, "FourierNormalSystem::Factorize",
                "identity_weight", identity_weight, "finite and >= 0");
  const int rr = r_ * r_;
  FactorizeWith([&](Index bin, int k) { return gradient_weight * symbol_[bin * rr + k] + identity_weight; });
}

void FourierNormalSystem::Factorize(const Image& penalty) {
  CheckArgument(ShapeOf(penalty) == hr_, "FourierNormalSystem::Factorize", "penalty shape",
                ToString(ShapeOf(penalty)), "the HR shape " + ToString(hr_));
  CheckArgument(AllFinite(penalty) && penalty.minCoeff() >= 0, "FourierNormalSystem::Factorize", "penalty",
                "(negative or non-finite values)", "finite values >= 0");
  FactorizeWith([&](Index bin, int k) {
    const Index uy = bin / lr_.cols, ux = bin % lr_.cols;
    return penalty(uy + Index(k / r_) * lr_.rows, ux + Index(k % r_) * lr_.cols);
  });
}

template <class Penalty>
void FourierNormalSystem::FactorizeWith(const Penalty& penalty) {
  const int rr = r_ * r_, n = n_;
  const Index bins = lr_.size();
  dinv_.assign(bins * rr, 0.0);
  kfactor_.assign(bins * n * n, Complex(0));
  slot_.assign(bins, -1);
  // Pass 1 (parallel): Woodbury factors where they are cheaper and accurate; the rest are marked.
  std::vector<char> woodbury(bins, 0);
  ParallelFor(lr_.rows, [&](Index uy) {
    for (Index ux = 0; ux < lr_.cols; ++ux) {
      if (!MirrorMultiplicity(lr_, uy, ux)) continue;
      const Index bin = uy * lr_.cols + ux;
      const Complex* b = &b_[bin * n * rr];
      double* dinv = &dinv_[bin * rr];
      double dmin = std::numeric_limits<double>::infinity(), frob = 0;
      for (int k = 0; k < rr; ++k) {
        const double d = penalty(bin, k);
        dmin = std::min(dmin, d);
        dinv[k] = d > 0 ? 1.0 / d : 0.0;
      }
      for (int e = 0; e < n * rr; ++e) frob += std::norm(b[e]);
      if (!(n < rr && dmin > 0 && frob <= kWoodburyAmplification * dmin)) continue;
      // K = I + B D⁻¹ Bᴴ (N x N, Hermitian positive definite: ≥ I). The products (B_ik D⁻¹_k) conj(B_jk) in
      // real arithmetic: std::complex's operations in its order, without its NaN-recovery branch.
      Complex* kf = &kfactor_[bin * n * n];
      const double* bd = reinterpret_cast<const double*>(b);
      for (int i = 0; i < n; ++i)
        for (int j = 0; j <= i; ++j) {
          double re = i == j ? 1.0 : 0.0, im = 0.0;
          for (int k = 0; k < rr; ++k) {
            const double tr = bd[2 * (i * rr + k)] * dinv[k], ti = bd[2 * (i * rr + k) + 1] * dinv[k];
            const double cr = bd[2 * (j * rr + k)], ci = bd[2 * (j * rr + k) + 1];
            re += tr * cr + ti * ci;
            im += ti * cr - tr * ci;
          }
          kf[i * n + j] = Complex(re, im);
          kf[j * n + i] = Complex(re, -im);
        }
      woodbury[bin] = bins::CholeskyInPlace(kf, n, 1e-12);
    }
  });
  // Pass 2 (serial: few bins, and the slots are numbered in bin order): the dense r² x r² factorisations.
  // The counts include the mirror bins, which share their twin's form.
  dense_.clear();
  pseudo_.clear();
  singular_bins_ = 0;
  woodbury_bins_ = 0;
  for (Index bin = 0; bin < bins; ++bin) {
    const int multiplicity = MirrorMultiplicity(lr_, bin / lr_.cols, bin % lr_.cols);
    if (!multiplicity) continue;
    if (woodbury[bin]) {
      woodbury_bins_ += multiplicity;
      continue;
    }
    const Complex* b = &b_[bin * n * rr];
    std::vector<Complex> g(rr * rr);
    double scale = 0;
    for (int k = 0; k < rr; ++k)
      for (int l = 0; l < rr; ++l) {
        Complex s = 0;
        for (int i = 0; i < n; ++i) s += std::conj(b[i * rr + k]) * b[i * rr + l];
        if (k == l) {
          s += penalty(bin, k);
          scale = std::max(scale, std::abs(s.real()));
        }
        g[k * rr + l] = s;
      }
    slot_[bin] = int(dense_.size());
    std::vector<Complex> f = g;
    // A pivot below 1e-12 of its own diagonal entry means G(u) is singular to rounding: the Cholesky "solution"
    // would be noise of size 1e12. Use the pseudo-inverse instead. (Relative to its own entry, not the largest:
    // a general penalty's bin may hold D = 0 at one alias and 1e13 at the others, e.g. the DC bin of a Laplacian
    // prior at λ = 1e12 in tikhonov_cg.cpp's preconditioner, and that G is well conditioned once scaled.)
    if (scale > 0 && bins::CholeskyInPlace(f.data(), rr, 0.0, 1e-12)) {
      dense_.push_back(std::move(f));
      pseudo_.emplace_back();
      continue;
    }
    singular_bins_ += multiplicity;
    const Eigen::Map<const Eigen::Matrix<Complex, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>> gm(
        g.data(), rr, rr);
    const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXcd> eig{Eigen::MatrixXcd(gm)};
    const Eigen::VectorXd& ev = eig.eigenvalues();
    const double floor = 1e-12 * std::max(ev.cwiseAbs().maxCoeff(), 0.0);
    Eigen::VectorXd inv = Eigen::VectorXd::Zero(rr);
    for (int i = 0; i < rr; ++i)
      if (ev[i] > floor && ev[i] > 0) inv[i] = 1.0 / ev[i];
    dense_.emplace_back();
    pseudo_.push_back(eig.eigenvectors() * inv.asDiagonal() * eig.eigenvectors().adjoint());
  }
  factorized_ = true;
}

void FourierNormalSystem::SolveBin(Index bin, Complex* v, Complex* work) const {
  const int rr = r_ * r_, n = n_;
  const int slot = slot_[bin];
  if (slot < 0) {
    WoodburySolve(reinterpret_cast<const double*>(&b_[bin * n * rr]), &dinv_[bin * rr], &kfactor_[bin * n * n], n,
                  rr, v, work);
  } else if (!dense_[slot].empty()) {
    bins::Substitute(dense_[slot].data(), rr, v);
  } else {
    const Eigen::VectorXcd x = pseudo_[slot] * Eigen::Map<const Eigen::VectorXcd>(v, rr);
    for (int k = 0; k < rr; ++k) v[k] = x[k];
  }
}

void FourierNormalSystem::SolveBins(const ComplexImage& half, const std::vector<ComplexImage>* v,
                                    ComplexImage* out, std::vector<ComplexImage>* ax) const {
  const int rr = r_ * r_, n = n_;
  // The rhs is real, so its spectrum is Hermitian and the half spectrum (columns 0 .. M_x/2) holds it all; a
  // value at a column beyond M_x/2 is the conjugate of the mirrored stored one. The bins come in mirror pairs
  // u, −u whose systems and right-hand sides are conjugate, so only one of each pair is solved and the other
  // is its conjugate: half the work, and the output spectrum is exactly Hermitian. (Solving both would
  // splice two solutions whose rounding errors differ; for an ill-conditioned bin that error lies along
  // near-null directions of each solve but not of the splice, and the residual grew to 1e3 in a test.)
  // Every HR frequency is written by exactly one solved bin, so the bins may run on any number of threads.
  const Index half_cols = half.cols(), lr_half = lr_.cols / 2 + 1;
  auto at = [&](const ComplexImage& spectrum, Shape full, Index fy, Index fx) {
    return fx < spectrum.cols() ? spectrum(fy, fx)
                                : std::conj(spectrum(Mirror(fy, full.rows), full.cols - fx));
  };
  ParallelFor(lr_.rows, [&](Index uy) {
    Complex stack_v[kStackBins], stack_w[kStackBins];
    std::vector<Complex> heap;
    Complex* x = stack_v;
    Complex* work = stack_w;
    if (rr > kStackBins || n > kStackBins) {
      heap.resize(2 * std::max(rr, n));
      x = heap.data();
      work = heap.data() + std::max(rr, n);
    }
    const Index muy = Mirror(uy, lr_.rows);
    for (Index ux = 0; ux < lr_.cols; ++ux) {
      const Index mux = Mirror(ux, lr_.cols);
      const int multiplicity = MirrorMultiplicity(lr_, uy, ux);
      if (!multiplicity) continue;  // the mirror bin is solved instead
      const bool self_mirror = multiplicity == 1;
      const Index bin = uy * lr_.cols + ux;
      for (int ky = 0; ky < r_; ++ky)
        for (int kx = 0; kx < r_; ++kx) x[ky * r_ + kx] = at(half, hr_, uy + ky * lr_.rows, ux + kx * lr_.cols);
      const Complex* b = &b_[bin * n * rr];
      if (v) {
        // + w r² A(u)ᴴ V(u) = √s Bᴴ V(u), V the frames' spectra at u.
        for (int i = 0; i < n; ++i) work[i] = sqrt_s_ * at((*v)[i], lr_, uy, ux);
        for (int k = 0; k < rr; ++k) {
          Complex sum = 0;
          for (int i = 0; i < n; ++i) sum += std::conj(b[i * rr + k]) * work[i];
          x[k] += sum;
        }
      }
      SolveBin(bin, x, work);
      if (self_mirror) {
        // The bin is its own mirror: its exact solution satisfies X(−f) = conj X(f) within the bin. Average
        // the solve with its mirrored conjugate (also a solution), so the stored half spectrum is consistent.
        for (int k = 0; k < rr; ++k) work[k] = x[k];
        for (int ky = 0; ky < r_; ++ky)
          for (int kx = 0; kx < r_; ++kx) {
            const Index my = Mirror(uy + ky * lr_.rows, hr_.rows);
            const Index mx = Mirror(ux + kx * lr_.cols, hr_.cols);
            const int k = ky * r_ + kx, km = int(my / lr_.rows) * r_ + int(mx / lr_.cols);
            x[k] = 0.5 * (work[k] + std::conj(work[km]));
          }
      }
      for (int ky = 0; ky < r_; ++ky)
        for (int kx = 0; kx < r_; ++kx) {
          const Index fy = uy + ky * lr_.rows, fx = ux + kx * lr_.cols;
          const Complex value = x[ky * r_ + kx];
          if (fx < half_cols) (*out)(fy, fx) = value;
          const Index my = Mirror(fy, hr_.rows), mx = Mirror(fx, hr_.cols);
          if (mx < half_cols) (*out)(my, mx) = std::conj(value);
        }
      if (ax) {
        // F(A_i x)(u) = A(u) X(u) = B X / √s, and its conjugate at −u.
        for (int i = 0; i < n; ++i) {
          Complex sum = 0;
          for (int k = 0; k < rr; ++k) sum += b[i * rr + k] * x[k];
          sum /= sqrt_s_;
          if (ux < lr_half) (*ax)[i](uy, ux) = sum;
          if (mux < lr_half) (*ax)[i](muy, mux) = std::conj(sum);
        }
      }
    }
  });
}

Image FourierNormalSystem::Solve(const Image& rhs) const {
  CheckArgument(AllFinite(rhs), "FourierNormalSystem::Solve", "rhs", "(non-finite values)", "finite values");
  Workspace ws;
  Image x;
  SolveInto(rhs, &x, &ws);
  return x;
}

void FourierNormalSystem::SolveInto(const Image& rhs, Image* x, Workspace* ws) const {
  constexpr const char* kFourierNormalSystemFn = "FourierNormalSystem::Solve";
  if (!factorized_) throw InvalidArgument(std::string(kFourierNormalSystemFn) + ": call Factorize first");
  CheckArgument(ShapeOf(rhs) == hr_, kFourierNormalSystemFn, "rhs shape", ToString(ShapeOf(rhs)), "the HR shape " + ToString(hr_));
  CheckArgument(x != nullptr && ws != nullptr, kFourierNormalSystemFn, "x, ws", "null", "an output image and a workspace");
  FftR2CInto(rhs, &ws->half);
  // Solutions go to a separate half spectrum: a bin may read the mirror of a value another bin writes.
  ws->out.resize(ws->half.rows(), ws->half.cols());
  SolveBins(ws->half, nullptr, &ws->out, nullptr);
  FftC2RInto(ws->out, hr_.cols, x);
}

void FourierNormalSystem::SolveWithData(const Image& rhs, const ImageStack& v, Image* x, ImageStack* ax) const {
  constexpr const char* kFourierNormalSystemFn = "FourierNormalSystem::SolveWithData";
  CheckArgument(AllFinite(rhs), kFourierNormalSystemFn, "rhs", "(non-finite values)", "finite values");
  for (const Image& f : v) CheckArgument(AllFinite(f), kFourierNormalSystemFn, "v", "(non-finite values)", "finite values");
  Workspace ws;
  SolveWithDataInto(rhs, v, x, ax, &ws);
}

void FourierNormalSystem::SolveWithDataInto(const Image& rhs, const ImageStack& v, Image* x, ImageStack* ax,
                                            Workspace* ws) const {
  constexpr const char* kFourierNormalSystemFn = "FourierNormalSystem::SolveWithData";
  if (!factorized_) throw InvalidArgument(std::string(kFourierNormalSystemFn) + ": call Factorize first");
  CheckArgument(ShapeOf(rhs) == hr_, kFourierNormalSystemFn, "rhs shape", ToString(ShapeOf(rhs)), "the HR shape " + ToString(hr_));
  CheckArgument(Index(v.size()) == n_, kFourierNormalSystemFn, "v frames", std::to_string(v.size()), std::to_string(n_));
  CheckArgument(x != nullptr && ws != nullptr, kFourierNormalSystemFn, "x, ws", "null", "an output image and a workspace");
  for (const Image& f : v)
    CheckArgument(ShapeOf(f) == lr_, kFourierNormalSystemFn, "v frame shape", ToString(ShapeOf(f)), "the LR shape " + ToString(lr_));
  FftR2CInto(rhs, &ws->half);
  ws->spectra.resize(n_);
  ParallelFor(n_, [&](Index i) { FftR2CInto(v[i], &ws->spectra[i]); });
  ws->out.resize(ws->half.rows(), ws->half.cols());
  if (ax) {
    ws->ax_half.resize(n_);
    for (ComplexImage& a : ws->ax_half) a.resize(lr_.rows, lr_.cols / 2 + 1);
  }
  SolveBins(ws->half, &ws->spectra, &ws->out, ax ? &ws->ax_half : nullptr);
  FftC2RInto(ws->out, hr_.cols, x);
  if (ax) {
    ax->resize(n_);
    ParallelFor(n_, [&](Index i) { FftC2RInto(ws->ax_half[i], lr_.cols, &(*ax)[i]); });
  }
}

namespace {

class NormalSystemInverseOp final : public LinearOperator {
 public:
  NormalSystemInverseOp(std::shared_ptr<const FourierNormalSystem> system, Shape hr)
      : LinearOperator(hr.size(), hr.size(), "NormalSystemInverse(" + ToString(hr) + ")"),
        system_(std::move(system)),
        hr_(hr) {}

 private:
  void ApplyImpl(ConstRef b, Ref x) const override {
    FourierNormalSystem::Workspace ws;
    Image out;
    system_->SolveInto(AsImage(Vector(b), hr_), &out, &ws);
    x = AsVector(out);
  }
  void ApplyAdjointImpl(ConstRef y, Ref x) const override { ApplyImpl(y, x); }
  std::shared_ptr<const FourierNormalSystem> system_;
  Shape hr_;
};

}  // namespace

OperatorPtr NormalSystemInverse(std::shared_ptr<const FourierNormalSystem> system) {
  CheckArgument(system != nullptr, "NormalSystemInverse", "system", "null", "a factorised FourierNormalSystem");
  const Shape hr = system->hr_shape();
  return std::make_shared<NormalSystemInverseOp>(std::move(system), hr);
}

}  // namespace aosr
