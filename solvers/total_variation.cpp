#include "aosr/solvers/total_variation.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <memory>
#include <sstream>
#include <vector>

#include "aosr/core/error.hpp"
#include "aosr/core/fft.hpp"
#include "aosr/core/operators.hpp"
#include "aosr/core/parallel.hpp"
#include "aosr/solvers/conjugate_gradient.hpp"

namespace aosr {

const char* ToString(TotalVariationXUpdate x_update) {
  switch (x_update) {
    case TotalVariationXUpdate::kAuto:
      return "auto";
    case TotalVariationXUpdate::kFourier:
      return "fourier";
    case TotalVariationXUpdate::kFourierSplit:
      return "fourier-split";
    case TotalVariationXUpdate::kConjugateGradient:
      return "conjugate-gradient";
  }
  return "unknown";
}

bool TotalVariationOptions::IsValid(std::string* why) const {
  auto fail = [why](const std::string& m) {
    if (why) *why = m;
    return false;
  };
  auto finite_at_least = [](double v, double lo) { return std::isfinite(v) && v >= lo; };
  if (!finite_at_least(mu, 0)) return fail("mu must be finite and >= 0, got " + ToString(mu));
  if (!finite_at_least(rho, 0))
    return fail("rho must be finite and >= 0 (0: automatic), got " + ToString(rho));
  if (!(std::isfinite(rho_balance) && rho_balance > 1))
    return fail("rho_balance must be finite and > 1, got " + ToString(rho_balance));
  if (!(std::isfinite(rho_factor) && rho_factor > 1))
    return fail("rho_factor must be finite and > 1, got " + ToString(rho_factor));
  if (max_rho_updates < 0) return fail("max_rho_updates must be >= 0, got " + ToString(max_rho_updates));
  if (!(relaxation >= 1 && relaxation <= 1.9))
    return fail("relaxation must be in [1, 1.9], got " + ToString(relaxation));
  if (!finite_at_least(absolute_tolerance, 0))
    return fail("absolute_tolerance must be finite and >= 0, got " + ToString(absolute_tolerance));
  if (!(relative_tolerance > 0 && relative_tolerance < 1))
    return fail("relative_tolerance must be in (0, 1), got " + ToString(relative_tolerance));
  if (!(change_tolerance >= 0 && change_tolerance < 1))
    return fail("change_tolerance must be in [0, 1) (0: off), got " + ToString(change_tolerance));
  if (max_iterations < 1) return fail("max_iterations must be >= 1, got " + ToString(max_iterations));
  if (!(cg_tolerance > 0 && cg_tolerance < 1))
    return fail("cg_tolerance must be in (0, 1), got " + ToString(cg_tolerance));
  if (cg_max_iterations < 1)
    return fail("cg_max_iterations must be >= 1, got " + ToString(cg_max_iterations));
  if (x_update != TotalVariationXUpdate::kAuto && x_update != TotalVariationXUpdate::kFourier &&
      x_update != TotalVariationXUpdate::kFourierSplit && x_update != TotalVariationXUpdate::kConjugateGradient)
    return fail("x_update must be auto, fourier, fourier-split or conjugate-gradient");
  return true;
}

// ---------------------------------------------------------------------------------------------------------
// Objective

double IsotropicTotalVariation(const Image& x) {
  CheckArgument(x.size() > 0, "IsotropicTotalVariation", "x shape", ToString(ShapeOf(x)), "non-empty");
  const Index rows = x.rows(), cols = x.cols();
  double tv = 0;
  for (Index y = 0; y < rows; ++y) {
    const Index yn = y + 1 < rows ? y + 1 : 0;
    for (Index c = 0; c < cols; ++c) {
      const Index cn = c + 1 < cols ? c + 1 : 0;
      const double dy = x(yn, c) - x(y, c), dx = x(y, cn) - x(y, c);
      tv += std::sqrt(dy * dy + dx * dx);
    }
  }
  return tv;
}

double TotalVariationObjective(const ReconstructionProblem& problem, const Image& x, double mu) {
  problem.Validate("TotalVariationObjective");
  CheckArgument(std::isfinite(mu) && mu >= 0, "TotalVariationObjective", "mu", mu, "finite and >= 0");
  CheckArgument(ShapeOf(x) == problem.model->hr_shape(), "TotalVariationObjective", "x shape",
                ToString(ShapeOf(x)), "the model's HR shape " + ToString(problem.model->hr_shape()));
  CheckArgument(AllFinite(x), "TotalVariationObjective", "x", "(non-finite values)", "finite values");
  return WeightedDataMisfit(problem, x) + mu * IsotropicTotalVariation(x);
}

// ---------------------------------------------------------------------------------------------------------
// ADMM

namespace {

constexpr const char* kFunction = "TotalVariationAdmm";

// The pixel-wise parts of an ADMM iteration, fused into one pass over the image (they are memory-bound: at
// 512² one sweep of the state costs about as much as the per-bin solves, so the number of full-image
// sweeps is what sets their time). ∇ is the periodic forward difference of core/operators.hpp written out:
// (∇x)_y[p] = x[p + row] − x[p], (∇x)_x[p] = x[p + 1] − x[p] (wrapping), and its adjoint gathers
// (∇ᵀq)[p] = q_y[p − row] − q_y[p] + q_x[p − 1] − q_x[p].
//
// One iteration's pass, from the new x:
//   z-update   g = ∇x; ĝ = α g + (1 − α) z; z ← shrink_t(ĝ + u); u ← u + ĝ − z; dz = z_new − z_old
//   v-update   (positivity) v̂ = α x + (1 − α) v; v ← max(v̂ + s, 0); s ← s + v̂ − v; dv = v_new − v_old
//   rhs        the next x-update's right-hand side [c +] ρ∇ᵀ(z − u) [+ ρ(v − s)] (c: the x-update's
//              constant part, AᵀWy for the Fourier path, so that its solve reads one array)
//   sums       ||∇x − z||², ||∇x||², ||z||² (and the v block's), ||∇ᵀdz [+ dv]||² (dual residual),
//              ||∇ᵀu [+ s]||² (dual tolerance), ||x − x_prev||², ||x||², Σ 0·x (NaN iff x is not finite)
//              and ||ρ∇ᵀ(z − u) [+ ρ(v − s)]||² (the right-hand side's finiteness)
// The adjoint of row y needs the new z, u and dz of rows y − 1 and y, so a row's rhs is formed right after
// its z-update while both rows are in cache, and dz lives only in a two-row ring (never a full array). Rows
// go in fixed blocks of about kPassBlockPixels pixels (a function of the shape only), in parallel; the first
// row of each block needs the previous block's last row, so it is done in a second, short parallel pass
// once every block is through (dz of each block's first and last rows are kept for it). Each block's sums
// are added in block order afterwards, so the result does not depend on the thread count. Inside a row the
// loop is a SIMD loop (`omp simd`, compiled with -fopenmp-simd: no OpenMP runtime): its sums are kept per
// SIMD lane and added at the end of the row, a fixed order for a given build. The wrap-around column
// (periodic boundary) is done apart, so the main loop has no branch. The arithmetic of z, u, v, s and the
// right-hand side is that of the separate steps, operation for operation: the iterates do not change.
constexpr Index kPassBlockPixels = 16384;

Index PassBlockRows(Shape hr) { return std::max<Index>(1, kPassBlockPixels / std::max<Index>(hr.cols, 1)); }

struct PassSums {
  double primal2 = 0, kx2 = 0, zeta2 = 0;        // the z block
  double v_primal2 = 0, v_kx2 = 0, v_zeta2 = 0;  // the v block (positivity)
  double dual2 = 0, ktu2 = 0;
  double change2 = 0, x2 = 0, x_probe = 0;
  double rhs2 = 0;
  void Add(const PassSums& o) {
    primal2 += o.primal2, kx2 += o.kx2, zeta2 += o.zeta2;
    v_primal2 += o.v_primal2, v_kx2 += o.v_kx2, v_zeta2 += o.v_zeta2;
    dual2 += o.dual2, ktu2 += o.ktu2;
    change2 += o.change2, x2 += o.x2, x_probe += o.x_probe;
    rhs2 += o.rhs2;
  }
};

// The arrays of a pass. z, u hold the y then the x components (2n each); v, s are null without positivity;
// offset (the rhs's constant part) may be null; x_prev is null in a pass that only forms the rhs.
struct PassArrays {
  Shape hr;
  const double* x = nullptr;
  const double* x_prev = nullptr;
  double* z = nullptr;
  double* u = nullptr;
  double* v = nullptr;
  double* s = nullptr;
  const double* offset = nullptr;
  double* rhs = nullptr;
  double alpha = 1, t = 0, rho = 1;
};

// The z-update of row y (and the x sums); dz of the row into dzy[0..C), dzx[0..C).
void ZRow(const PassArrays& a, Index y, double* dzy, double* dzx, PassSums* sums) {
  const Index R = a.hr.rows, C = a.hr.cols, n = a.hr.size();
  const double* xs = a.x;
  const double* xp = a.x_prev;
  double* zy = a.z;
  double* zx = a.z + n;
  double* uy = a.u;
  double* ux = a.u + n;
  const double alpha = a.alpha, t = a.t;
  const Index row = y * C, down = (y + 1 < R ? y + 1 : 0) * C - row;
  double primal2 = 0, kx2 = 0, zeta2 = 0, change2 = 0, x2 = 0, probe = 0;
  // One pixel p with its forward neighbours at `below` (next row) and `right` (next column); returns its
  // terms of the sums (a value, so that the SIMD loop's per-lane sums stay private).
  struct Terms {
    double primal2, kx2, zeta2, change2, x2, probe;
  };
  auto pixel = [&](Index p, Index below, Index right) {
    const double gy = xs[below] - xs[p], gx = xs[right] - xs[p];
    const double hy = alpha * gy + (1 - alpha) * zy[p], hx = alpha * gx + (1 - alpha) * zx[p];
    const double ty = hy + uy[p], tx = hx + ux[p];
    const double norm = std::sqrt(ty * ty + tx * tx);
    // f = norm > t ? 1 − t/norm : 0, written without a branch so that the loop vectorises (GCC does not
    // if-convert arithmetic that may trap): 1 − t/norm > 0 exactly when norm > t (division rounds
    // monotonically), and std::max(0.0, ·) returns 0 for the NaN of t = norm = 0.
    const double f = std::max(0.0, 1.0 - t / norm);
    const double ny = f * ty, nx = f * tx;
    uy[p] += hy - ny;
    ux[p] += hx - nx;
    dzy[p - row] = ny - zy[p];
    dzx[p - row] = nx - zx[p];
    zy[p] = ny;
    zx[p] = nx;
    const double dx = xs[p] - xp[p];
    return Terms{(gy - ny) * (gy - ny) + (gx - nx) * (gx - nx), gy * gy + gx * gx, ny * ny + nx * nx, dx * dx,
                 xs[p] * xs[p], xs[p] * 0.0};
  };
#pragma omp simd reduction(+ : primal2, kx2, zeta2, change2, x2, probe)
  for (Index p = row; p < row + C - 1; ++p) {
    const Terms q = pixel(p, p + down, p + 1);
    primal2 += q.primal2;
    kx2 += q.kx2;
    zeta2 += q.zeta2;
    change2 += q.change2;
    x2 += q.x2;
    probe += q.probe;
  }
  const Index last = row + C - 1;
  const Terms q = pixel(last, last + down, row);
  sums->primal2 += primal2 + q.primal2;
  sums->kx2 += kx2 + q.kx2;
  sums->zeta2 += zeta2 + q.zeta2;
  sums->change2 += change2 + q.change2;
  sums->x2 += x2 + q.x2;
  sums->x_probe += probe + q.probe;
}

// Row y of the right-hand side [c +] ρ∇ᵀ(z − u) [+ ρ(v − s)] with its sums, after the v-update of the row
// (kPos). kDual: with the dual sums, from dz of rows y (dzy, dzx) and y − 1 (dzy_up); without, the rhs and
// its norm only (after a ρ change, or before the first iteration).
template <bool kPos, bool kOffset, bool kDual>
void AdjointRow(const PassArrays& a, Index y, const double* dzy, const double* dzx, const double* dzy_up,
                PassSums* sums) {
  const Index R = a.hr.rows, C = a.hr.cols, n = a.hr.size();
  const double* zy = a.z;
  const double* zx = a.z + n;
  const double* uy = a.u;
  const double* ux = a.u + n;
  const double* xs = a.x;
  double* vs = a.v;
  double* ss = a.s;
  const double* off = a.offset;
  double* out = a.rhs;
  const double rho = a.rho, alpha = a.alpha;
  const Index row = y * C, up = (y > 0 ? y - 1 : R - 1) * C - row;
  double dual2 = 0, ktu2 = 0, rhs2 = 0, vp2 = 0, vk2 = 0, vz2 = 0;
  struct Terms {
    double dual2, ktu2, rhs2, vp2, vk2, vz2;
  };
  // One pixel p with its backward neighbours at p + up (previous row) and `left` (previous column).
  auto pixel = [&](Index p, Index left) {
    const Index c = p - row, cl = left - row;
    const double tz = (zy[p + up] - zy[p]) + (zx[left] - zx[p]);
    const double tu = (uy[p + up] - uy[p]) + (ux[left] - ux[p]);
    double d = 0, k = tu, r = rho * (tz - tu);
    if (kDual) d = (dzy_up[c] - dzy[c]) + (dzx[cl] - dzx[c]);
    Terms q{0, 0, 0, 0, 0, 0};
    if (kPos) {
      double dv = 0;
      if (kDual) {
        const double vhat = alpha * xs[p] + (1 - alpha) * vs[p];
        const double vn = std::max(vhat + ss[p], 0.0);
        ss[p] += vhat - vn;
        dv = vn - vs[p];
        vs[p] = vn;
        q.vp2 = (xs[p] - vn) * (xs[p] - vn);
        q.vk2 = xs[p] * xs[p];
        q.vz2 = vn * vn;
      }
      r += rho * (vs[p] - ss[p]);
      d += dv;
      k += ss[p];
    }
    out[p] = kOffset ? off[p] + r : r;
    q.dual2 = d * d;
    q.ktu2 = k * k;
    q.rhs2 = r * r;
    return q;
  };
  const Terms first = pixel(row, row + C - 1);
#pragma omp simd reduction(+ : dual2, ktu2, rhs2, vp2, vk2, vz2)
  for (Index p = row + 1; p < row + C; ++p) {
    const Terms q = pixel(p, p - 1);
    dual2 += q.dual2;
    ktu2 += q.ktu2;
    rhs2 += q.rhs2;
    vp2 += q.vp2;
    vk2 += q.vk2;
    vz2 += q.vz2;
  }
  sums->dual2 += first.dual2 + dual2;
  sums->ktu2 += first.ktu2 + ktu2;
  sums->rhs2 += first.rhs2 + rhs2;
  sums->v_primal2 += first.vp2 + vp2;
  sums->v_kx2 += first.vk2 + vk2;
  sums->v_zeta2 += first.vz2 + vz2;
}

template <bool kDual>
using AdjointRowFn = void (*)(const PassArrays&, Index, const double*, const double*, const double*, PassSums*);

template <bool kDual>
AdjointRowFn<kDual> PickAdjointRow(const PassArrays& a) {
  if (a.v) return a.offset ? AdjointRow<true, true, kDual> : AdjointRow<true, false, kDual>;
  return a.offset ? AdjointRow<false, true, kDual> : AdjointRow<false, false, kDual>;
}

// Reusable buffers of the pass: per block the dz of its first row and a two-row ring (y and x parts each).
struct PassBuffers {
  std::vector<double> dz;
  std::vector<PassSums> partial;
};

// The whole iteration's pass (above). x_prev, z, u (and v, s) must be set.
PassSums IterationPass(const PassArrays& a, PassBuffers* buffers) {
  const Index R = a.hr.rows, C = a.hr.cols;
  const Index per = PassBlockRows(a.hr), blocks = (R + per - 1) / per;
  buffers->dz.resize(std::size_t(blocks) * 6 * C);
  buffers->partial.assign(2 * blocks, PassSums{});
  double* dz = buffers->dz.data();
  PassSums* partial = buffers->partial.data();
  const AdjointRowFn<true> adjoint = PickAdjointRow<true>(a);
  // Block b's dz rows: slot 0 its first row, slots 1 and 2 the ring of the rows after it; a slot is
  // 2C values (y then x parts).
  const auto slot = [&](Index b, Index y) {
    const Index k = y == b * per ? 0 : 1 + ((y - b * per) & 1);
    return dz + (b * 6 + 2 * k) * C;
  };
  ParallelFor(blocks, [&](Index b) {
    PassSums s;
    for (Index y = b * per, y_end = std::min(R, y + per); y < y_end; ++y) {
      double* cur = slot(b, y);
      ZRow(a, y, cur, cur + C, &s);
      if (y > b * per) adjoint(a, y, cur, cur + C, slot(b, y - 1), &s);
    }
    partial[b] = s;
  });
  ParallelFor(blocks, [&](Index b) {
    const Index y = b * per, pb = (b + blocks - 1) % blocks;
    const Index last = std::min(R, (pb + 1) * per) - 1;  // the previous block's last row (wrapping)
    PassSums s;
    double* cur = slot(b, y);
    adjoint(a, y, cur, cur + C, slot(pb, last), &s);
    partial[blocks + b] = s;
  });
  PassSums sums;
  for (Index b = 0; b < 2 * blocks; ++b) sums.Add(partial[b]);
  return sums;
}

// z = ∇x (y then x parts, the periodic forward differences of core/operators.hpp's Gradient, the same
// subtractions) and u = 0, in parallel over the pass's row blocks (the first write of these arrays).
void InitialSplitting(Shape hr, const double* x, double* z, double* u) {
  const Index R = hr.rows, C = hr.cols, n = hr.size();
  const Index per = PassBlockRows(hr), blocks = (R + per - 1) / per;
  ParallelFor(blocks, [&](Index b) {
    for (Index y = b * per, y_end = std::min(R, y + per); y < y_end; ++y) {
      const Index row = y * C, below = (y + 1 < R ? y + 1 : 0) * C;
      for (Index c = 0; c < C; ++c) {
        const Index p = row + c;
        z[p] = x[below + c] - x[p];
        z[n + p] = x[row + (c + 1 < C ? c + 1 : 0)] - x[p];
        u[p] = 0.0;
        u[n + p] = 0.0;
      }
    }
  });
}

// The right-hand side alone (v, s unchanged), with its norm: before the first iteration and after a ρ change.
double RhsPass(const PassArrays& a, PassBuffers* buffers) {
  const Index R = a.hr.rows;
  const Index per = PassBlockRows(a.hr), blocks = (R + per - 1) / per;
  buffers->partial.assign(blocks, PassSums{});
  PassSums* partial = buffers->partial.data();
  const AdjointRowFn<false> adjoint = PickAdjointRow<false>(a);
  ParallelFor(blocks, [&](Index b) {
    PassSums s;
    for (Index y = b * per, y_end = std::min(R, y + per); y < y_end; ++y)
      adjoint(a, y, nullptr, nullptr, nullptr, &s);
    partial[b] = s;
  });
  double rhs2 = 0;
  for (Index b = 0; b < blocks; ++b) rhs2 += partial[b].rhs2;
  return rhs2;
}

// The weights of all frames stacked like MultiFrameModel::Flatten (ones when the problem has none).
Vector StackedWeights(const ReconstructionProblem& problem) {
  const Index lr = problem.model->lr_shape().size();
  Vector w(problem.frame_count() * lr);
  for (int i = 0; i < problem.frame_count(); ++i) w.segment(i * lr, lr) = AsVector(problem.Weight(i));
  return w;
}

// ρ₀ = tr(AᵀWA) / tr(∇ᵀ∇). With periodic convolution every row of A_i has the same norm, ||A_iᵀ e||² for
// an LR delta e, so tr(A_iᵀ W_i A_i) = (Σ_p w_i[p]) ||A_iᵀ e||²; tr(∇ᵀ∇) = 4n (periodic differences). By
// Parseval ||A_iᵀ e||² = (1/n) Σ_f |B(f) H_i(f)|² over the full HR spectrum (B the pixel transfer, H_i the
// OTF; core/forward_model.hpp): a sum over the stored half spectrum, each column but 0 (and C/2 for even C)
// counted twice by Hermitian symmetry, instead of an HR convolution per frame.
double AutomaticRho(const ReconstructionProblem& problem) {
  const MultiFrameModel& model = *problem.model;
  const Shape hr = model.hr_shape();
  const Index half = hr.cols / 2 + 1;
  Image b2(hr.rows, half);  // |B|² times the column's multiplicity
  for (Index fy = 0; fy < hr.rows; ++fy)
    for (Index fx = 0; fx < half; ++fx) {
      const Complex b = model.PixelTransfer(fy, fx);
      b2(fy, fx) = (b.real() * b.real() + b.imag() * b.imag()) * (fx == 0 || 2 * fx == hr.cols ? 1.0 : 2.0);
    }
  const Index count = b2.size();
  double trace = 0;
  for (int i = 0; i < model.frames(); ++i) {
    const double* w = b2.data();
    const Complex* h = model.otf(i).data();
    double sum = 0;
    for (Index p = 0; p < count; ++p) sum += w[p] * (h[p].real() * h[p].real() + h[p].imag() * h[p].imag());
    trace += problem.Weight(i).sum() * (sum / double(hr.size()));
  }
  const double rho = trace / (4.0 * double(hr.size()));
  return rho > 0 && std::isfinite(rho) ? rho : 1.0;
}

// The x-update strategies. Each owns the data term's part of the ADMM: the x-subproblem
//   x ← argmin f_data(x) + ρ/2 ||∇x − z + u||² + ρ_v/2 ||x − v + s||²
// for the current ρ, ρ_v, and (split only) its own splitting variables and their residuals.
class XUpdate {
 public:
  virtual ~XUpdate() = default;
  // The system for a new ρ (ρ_v = ρ with positivity, else 0).
  virtual void Prepare(double rho, double rho_v) = 0;
  // The constant part c of the right-hand side that the caller's pixel pass adds to the prior part, so that
  // Solve reads one array (null: none).
  virtual const double* RhsOffset() const { return nullptr; }
  // x from rhs = [c +] ρ∇ᵀ(z − u) + ρ_v(v − s) (HR shape; c as RhsOffset), x_prev the previous iterate; x
  // is HR-shaped and is overwritten. False if it failed (x is then overwritten by the caller).
  virtual bool Solve(const Image& rhs, const Image& x_prev, Image* x) = 0;
  // After the x-update: the split data block's own updates with relaxation α (nothing otherwise).
  virtual void UpdateSplit(double /*alpha*/) {}
  // ρ changed by `factor`: scaled duals shrink by it (the unscaled ones are unchanged).
  virtual void RescaleDual(double /*factor*/) {}
  // The split block's contributions (its constraint is √κ (Ax − ω) = 0): primal² κ||Ax − ω||², κ||Ax||²,
  // κ||ω||², and a bound on its part of the dual residual, ρκ ||A||₂ ||ω − ω_prev|| >= ρκ ||Aᵀ(ω − ω_prev)||.
  struct Split {
    double primal2 = 0, kx2 = 0, zeta2 = 0, dual = 0;
  };
  virtual Split SplitResiduals(double /*rho*/) const { return {}; }
  virtual std::string Report() const { return ""; }
};

// Uniform weights w: (w AᵀA + ρ∇ᵀ∇ + ρ_v I) x = w Aᵀy + prior_rhs, exact per bin.
class FourierXUpdate final : public XUpdate {
 public:
  // cache (optional): a system built for the same model, w and (ρ, ρ_v) is taken from it instead of built; on
  // return it holds this run's system, for the next run.
  FourierXUpdate(const ReconstructionProblem& problem, double w, Vector aty, TotalVariationSummary* s,
                 TotalVariationState::Cache* cache)
      : aty_(std::move(aty)), summary_(s), cache_(cache) {
    if (cache_ && cache_->system && cache_->model == problem.model && cache_->weight == w) {
      system_ = cache_->system;
      factorized_ = {cache_->rho, cache_->rho_v};
    } else {
      system_ = std::make_shared<FourierNormalSystem>(*problem.model, w);
      if (cache_) *cache_ = {problem.model, w, -1.0, -1.0, system_};
    }
  }
  void Prepare(double rho, double rho_v) override {
    if (factorized_ != std::make_pair(rho, rho_v)) {
      system_->Factorize(rho, rho_v);
      factorized_ = {rho, rho_v};
      if (cache_) cache_->rho = rho, cache_->rho_v = rho_v;
    }
    summary_->singular_bins = std::max(summary_->singular_bins, system_->singular_bins());
  }
  const double* RhsOffset() const override { return aty_.data(); }
  // rhs already holds w Aᵀy + ρ∇ᵀ(z − u) [+ ρ_v(v − s)]: the solve reads it and writes x, nothing else.
  bool Solve(const Image& rhs, const Image& /*x_prev*/, Image* x) override {
    system_->SolveInto(rhs, x, &workspace_);
    return true;
  }
  std::string Report() const override {
    return " (" + std::to_string(system_->woodbury_bins()) + " of " + std::to_string(system_->bins()) +
           " bins in Woodbury form)";
  }

 private:
  std::shared_ptr<FourierNormalSystem> system_;
  std::pair<double, double> factorized_{-1.0, -1.0};  // the (ρ, ρ_v) of the system's factorisation
  Vector aty_;
  TotalVariationSummary* summary_;
  TotalVariationState::Cache* cache_;
  FourierNormalSystem::Workspace workspace_;  // reused every iteration
};

// Any weights: matrix-free CG on (AᵀWA + ρ∇ᵀ∇ + ρ_v I), warm-started from the previous x.
class CgXUpdate final : public XUpdate {
 public:
  CgXUpdate(const ReconstructionProblem& problem, const Vector& weights, Vector aty,
            const TotalVariationOptions& options, TotalVariationSummary* s)
      : aty_(std::move(aty)), n_(problem.model->hr_shape().size()), summary_(s) {
    const MultiFrameModel& model = *problem.model;
    const Shape stacked{Index(model.frames()) * model.lr_shape().rows, model.lr_shape().cols};
    data_normal_ = Normal(Compose(Mask(ToImage(weights.cwiseSqrt(), stacked)), model.Operator()));
    grad_normal_ = Normal(Gradient(model.hr_shape(), Boundary::kPeriodic));
    cg_.tolerance = options.cg_tolerance;
    cg_.max_iterations = options.cg_max_iterations;
  }
  void Prepare(double rho, double rho_v) override {
    std::vector<OperatorPtr> parts = {data_normal_, Scale(rho, grad_normal_)};
    if (rho_v > 0) parts.push_back(Scale(rho_v, Identity(n_)));
    normal_ = Sum(parts);
  }
  bool Solve(const Image& rhs, const Image& x_prev, Image* x) override {
    Vector xv = AsVector(x_prev);  // warm start
    const SolverSummary cg = ConjugateGradient(*normal_, Vector(aty_ + AsVector(rhs)), &xv, cg_);
    AsVector(*x) = xv;
    summary_->cg_iterations += cg.iterations;
    if (cg.termination == Termination::kMaxIterations) ++summary_->cg_unconverged;
    return cg.termination != Termination::kFailed;
  }
  std::string Report() const override {
    return " (" + std::to_string(summary_->cg_iterations) + " CG steps, " +
           std::to_string(summary_->cg_unconverged) + " unconverged)";
  }

 private:
  Vector aty_;
  Index n_;
  TotalVariationSummary* summary_;
  OperatorPtr data_normal_, grad_normal_, normal_;
  ConjugateGradientOptions cg_;
};

// Any weights, exact per bin: the data term is split off as ω = Ax (Almeida & Figueiredo 2013, "Deconvolving
// images with unknown boundaries using the alternating direction method of multipliers", IEEE TIP 22(8)).
// The constraint √κ (Ax − ω) = 0 joins ∇x = z (and x = v) under the same penalty ρ, so this is plain ADMM
// with one penalty and the stopping rule and residual balancing apply unchanged; t is its scaled dual:
//   x ← (κ AᵀA + ∇ᵀ∇ + [pos] I)⁻¹ (κ Aᵀ(ω − t) + ∇ᵀ(z − u) + [pos] (v − s))     independent of ρ
//   â ← α Ax + (1 − α) ω;   ω ← (W∘y + ρκ (â + t)) / (W + ρκ)   per pixel (W = 0: masked, ω = â + t);
//   t ← t + â − ω.
// κ = w̄ / ρ₀ (w̄ the mean positive weight, ρ₀ the initial ρ) makes the x-update matrix at ρ₀ the one the
// uniform path would use at weight w̄. The matrix does not depend on ρ, so it is factorised once; Ax comes
// out of the same per-bin solve.
class SplitXUpdate final : public XUpdate {
 public:
  SplitXUpdate(const ReconstructionProblem& problem, const Vector& weights, const Vector& y, const Vector& x0,
               double rho0, bool positivity)
      : model_(*problem.model), weights_(weights), wy_(weights.cwiseProduct(y)), hr_(model_.hr_shape()) {
    double sum = 0;
    Index count = 0;
    for (Index p = 0; p < weights.size(); ++p)
      if (weights[p] > 0) sum += weights[p], ++count;
    kappa_ = (count > 0 ? sum / double(count) : 1.0) / rho0;
    system_ = std::make_unique<FourierNormalSystem>(model_, kappa_);
    system_->Factorize(1.0, positivity ? 1.0 : 0.0);
    ax_ = model_.Operator()->Apply(x0);
    omega_ = ax_;
    t_ = Vector::Zero(ax_.size());
  }
  void Prepare(double rho, double /*rho_v*/) override { rho_ = rho; }
  bool Solve(const Image& rhs, const Image& /*x_prev*/, Image* x) override {
    const Shape lr = model_.lr_shape();
    const Index frames = model_.frames();
    rhs_.resize(hr_.rows, hr_.cols);
    rhs_ = rhs / rho_;
    v_.resize(frames);
    for (Index i = 0; i < frames; ++i) {
      v_[i].resize(lr.rows, lr.cols);
      AsVector(v_[i]) = omega_.segment(i * lr.size(), lr.size()) - t_.segment(i * lr.size(), lr.size());
    }
    system_->SolveWithDataInto(rhs_, v_, x, &ax_frames_, &workspace_);
    for (Index i = 0; i < frames; ++i) ax_.segment(i * lr.size(), lr.size()) = AsVector(ax_frames_[i]);
    return true;
  }
  void UpdateSplit(double alpha) override {
    const double c = rho_ * kappa_;
    // One fused pass per pixel: â = α Ax + (1 − α) ω_prev, ω = (W∘y + c(â + t)) / (W + c), t += â − ω, with
    // the sums of SplitResiduals: ||Ax − ω||², ||Ax||², ||ω||², ||ω − ω_prev||².
    const double* ax = ax_.data();
    const double* wy = wy_.data();
    const double* weights = weights_.data();
    double* omega = omega_.data();
    double* t = t_.data();
    double primal2 = 0, kx2 = 0, zeta2 = 0, domega2 = 0;
#pragma omp simd reduction(+ : primal2, kx2, zeta2, domega2)
    for (Index p = 0; p < omega_.size(); ++p) {
      const double prev = omega[p];
      const double ahat = alpha * ax[p] + (1 - alpha) * prev;
      const double w = (wy[p] + c * (ahat + t[p])) / (weights[p] + c);
      t[p] += ahat - w;
      omega[p] = w;
      primal2 += (ax[p] - w) * (ax[p] - w);
      kx2 += ax[p] * ax[p];
      zeta2 += w * w;
      domega2 += (w - prev) * (w - prev);
    }
    primal2_ = primal2, kx2_ = kx2, zeta2_ = zeta2, domega2_ = domega2;
  }
  void RescaleDual(double factor) override { t_ /= factor; }
  Split SplitResiduals(double rho) const override {
    Split s;
    s.primal2 = kappa_ * primal2_;
    s.kx2 = kappa_ * kx2_;
    s.zeta2 = kappa_ * zeta2_;
    s.dual = rho * kappa_ * system_->ModelNorm() * std::sqrt(domega2_);
    return s;
  }
  std::string Report() const override {
    return " (data split, kappa " + ToString(kappa_) + "; " + std::to_string(system_->woodbury_bins()) +
           " of " + std::to_string(system_->bins()) + " bins in Woodbury form)";
  }

 private:
  const MultiFrameModel& model_;
  Vector weights_, wy_;
  Shape hr_;
  double kappa_ = 1, rho_ = 1;
  std::unique_ptr<FourierNormalSystem> system_;
  Vector ax_, omega_, t_;
  double primal2_ = 0, kx2_ = 0, zeta2_ = 0, domega2_ = 0;  // the sums of the last UpdateSplit
  Image rhs_;  // reused every iteration, as are these frames and the workspace
  ImageStack v_, ax_frames_;
  FourierNormalSystem::Workspace workspace_;
};

}  // namespace

Image TotalVariationAdmm(const ReconstructionProblem& problem, const TotalVariationOptions& options,
                         TotalVariationSummary* summary, const Image* initial, TotalVariationState* state) {
  std::string why;
  if (!options.IsValid(&why)) throw InvalidArgument(std::string(kFunction) + ": invalid options: " + why);
  problem.Validate(kFunction);
  const MultiFrameModel& model = *problem.model;
  const Shape hr = model.hr_shape();
  const Index n = hr.size();
  const bool resume = state && !state->empty();
  if (resume) {
    // The caller's own earlier state: checked for fit (shapes, positivity) and finiteness, as `initial` is.
    const bool fits = ShapeOf(state->x) == hr && state->z.size() == 2 * n && state->u.size() == 2 * n &&
                      (options.positivity ? state->v.size() == n && state->s.size() == n
                                          : state->v.size() == 0 && state->s.size() == 0) &&
                      std::isfinite(state->rho);
    CheckArgument(fits, kFunction, "state", "(shapes, positivity or rho unlike this problem's)",
                  "the state of a run on the same HR grid with the same positivity setting");
    CheckArgument(AllFinite(state->x) && state->z.allFinite() && state->u.allFinite() && state->v.allFinite() &&
                      state->s.allFinite(),
                  kFunction, "state", "(non-finite values)", "finite values");
  } else if (initial) {
    CheckArgument(ShapeOf(*initial) == hr, kFunction, "initial shape", ToString(ShapeOf(*initial)),
                  "the model's HR shape " + ToString(hr));
    CheckArgument(AllFinite(*initial), kFunction, "initial", "(non-finite values)", "finite values");
  }
  const bool uniform = problem.HasUniformWeights();
  // A space-variant model (forward_model.hpp, WithPsfField): only the operator (CG) x-update is exact.
  const bool space_variant = model.space_variant();
  if (space_variant && options.x_update != TotalVariationXUpdate::kAuto &&
      options.x_update != TotalVariationXUpdate::kConjugateGradient)
    throw InvalidArgument(kFunction, "options.x_update", ToString(options.x_update),
                          "auto or conjugate-gradient for a space-variant model (the Fourier x-updates need one "
                          "PSF per frame over the whole field)");
  if (options.x_update == TotalVariationXUpdate::kFourier && !uniform)
    throw InvalidArgument(
        kFunction, "options.x_update", "fourier",
        "auto, fourier-split or conjugate-gradient when the weights are not uniform (masked or varying pixels)");
  TotalVariationXUpdate path = options.x_update;
  if (path == TotalVariationXUpdate::kAuto)
    path = space_variant ? TotalVariationXUpdate::kConjugateGradient
                         : uniform ? TotalVariationXUpdate::kFourier : TotalVariationXUpdate::kFourierSplit;
  const auto start = std::chrono::steady_clock::now();

  TotalVariationSummary s;
  s.method = "tv";
  s.mu = options.mu;
  s.x_update = path;

  // Data: AᵀW y with unweighted pixels zeroed (they are never read, problem.hpp).
  const OperatorPtr& a = model.Operator();
  const Vector weights = StackedWeights(problem);
  const Vector y = model.Flatten(problem.CleanFrames());
  Vector aty = a->ApplyAdjoint(weights.cwiseProduct(y));
  // Squared norms of the data-sized vectors must exist in double precision, or no residual is meaningful.
  const bool aty_finite = std::isfinite(aty.squaredNorm());

  // State: x, z = ∇x (+ u), v = x (+ s). Start consistent with x, duals at zero. x and x_prev swap their
  // buffers every iteration (the x-update writes the new x over the one before the last).
  Image x = resume ? std::move(state->x) : initial ? *initial : Image(Image::Zero(hr.rows, hr.cols));
  Image x_prev(hr.rows, hr.cols);
  double rho = resume ? state->rho : options.rho > 0 ? options.rho : AutomaticRho(problem);
  s.initial_rho = rho;
  std::unique_ptr<XUpdate> x_update;
  if (path == TotalVariationXUpdate::kFourier)
    x_update = std::make_unique<FourierXUpdate>(problem, weights[0], std::move(aty), &s, state ? &state->cache : nullptr);
  else if (path == TotalVariationXUpdate::kFourierSplit)
    x_update = std::make_unique<SplitXUpdate>(problem, weights, y, AsVector(x), rho, options.positivity);
  else
    x_update = std::make_unique<CgXUpdate>(problem, weights, std::move(aty), options, &s);

  const bool pos = options.positivity;
  x_update->Prepare(rho, pos ? rho : 0.0);

  Vector z(2 * n), u(2 * n);
  Vector v, sv;
  if (resume) {
    z = std::move(state->z);
    u = std::move(state->u);
    v = std::move(state->v);
    sv = std::move(state->s);
    state->rho = 0;  // moved from (x too): empty until the run ends
  } else {
    InitialSplitting(hr, x.data(), z.data(), u.data());
    if (pos) {
      v = AsVector(x).cwiseMax(0.0);
      sv = Vector::Zero(n);
    }
  }
  const double alpha = options.relaxation;
  const double sqrt_p = std::sqrt(double((pos ? 3 : 2) * n)), sqrt_n = std::sqrt(double(n));
  // rhs holds the next x-update's right-hand side [c +] ρ∇ᵀ(z − u) [+ ρ(v − s)] (c: RhsOffset), formed by
  // the pixel passes; rhs2 is the squared norm of its ρ-part.
  Image rhs(hr.rows, hr.cols);
  PassBuffers buffers;
  PassArrays arrays;
  arrays.hr = hr;
  arrays.z = z.data();
  arrays.u = u.data();
  arrays.v = pos ? v.data() : nullptr;
  arrays.s = pos ? sv.data() : nullptr;
  arrays.offset = x_update->RhsOffset();
  arrays.rhs = rhs.data();
  arrays.alpha = alpha;
  const auto prepare_rhs = [&] {
    arrays.rho = rho;
    return RhsPass(arrays, &buffers);
  };
  double rhs2 = prepare_rhs();

  auto objective = [&](const Image& xx) {
    const Vector r = a->Apply(AsVector(xx)) - y;
    return 0.5 * weights.dot(r.cwiseAbs2()) + options.mu * IsotropicTotalVariation(xx);
  };

  ProgressReporter reporter(options.progress, "tv", options.max_iterations, "primal/tol");
  const auto primal_over_tolerance = [&s] {
    return s.primal_tolerance > 0 ? s.primal_residual / s.primal_tolerance
                                  : std::numeric_limits<double>::quiet_NaN();
  };
  s.termination = Termination::kMaxIterations;
  int still_iterations = 0;  // consecutive iterations in which x did not move beyond rounding
  // Squared norms of the data-sized vectors must exist in double precision, or no residual is meaningful.
  bool failed = !aty_finite;
  if (failed)
    s.message = "the data are too large for double precision (||AᵀWy||² overflows); rescale the frames";
  for (int k = 0; !failed && k < options.max_iterations; ++k) {
    // x-update: the data term's system with right-hand side [c +] ρ∇ᵀ(z − u) + ρ_v(v − s) (in rhs).
    if (!std::isfinite(rhs2)) {
      failed = true;
      s.message = "x-update right-hand side overflows double precision at iteration " +
                  std::to_string(k + 1) + "; returned the last finite iterate";
      break;
    }
    x.swap(x_prev);  // O(1): x_prev is now the last iterate, x's buffer is overwritten
    if (!x_update->Solve(rhs, x_prev, &x)) x.setConstant(std::numeric_limits<double>::quiet_NaN());

    // One pass: z-update (relaxed) with its dual update, v likewise with positivity, the next right-hand
    // side and every sum below (IterationPass). Its x_probe is NaN iff x is not finite; then z, u (and v,
    // s) are garbage, but the loop ends here with the last finite iterate.
    arrays.x = x.data();
    arrays.x_prev = x_prev.data();
    arrays.t = options.mu / rho;
    arrays.rho = rho;
    const PassSums ps = IterationPass(arrays, &buffers);
    if (!std::isfinite(ps.x_probe)) {
      x.swap(x_prev);
      failed = true;
      s.message = "non-finite x-update at iteration " + std::to_string(k + 1) + " (rho " + ToString(rho) +
                  "); returned the last finite iterate";
      break;
    }
    rhs2 = ps.rhs2;
    double primal2 = ps.primal2, kx2 = ps.kx2, zeta2 = ps.zeta2;
    if (pos) {
      primal2 += ps.v_primal2;
      kx2 += ps.v_kx2;
      zeta2 += ps.v_zeta2;
    }
    x_update->UpdateSplit(alpha);

    // Residuals and tolerances (Boyd §3.3.1; the split block's dual part is bounded, so the rule never
    // stops early. Its ε_dual keeps the scale ρ||∇ᵀu + s||: with the data split off, the full Kᵀ(ρu) tends
    // to 0 at the optimum and would make the relative tolerance vanish.)
    const XUpdate::Split split = x_update->SplitResiduals(rho);
    primal2 += split.primal2;
    kx2 += split.kx2;
    zeta2 += split.zeta2;
    const double primal = std::sqrt(primal2);
    const double dual_res = rho * std::sqrt(ps.dual2) + split.dual;
    const double eps_pri =
        sqrt_p * options.absolute_tolerance + options.relative_tolerance * std::sqrt(std::max(kx2, zeta2));
    const double eps_dual =
        sqrt_n * options.absolute_tolerance + options.relative_tolerance * rho * std::sqrt(ps.ktu2);
    s.iterations = k + 1;
    s.primal_residual = primal;
    s.dual_residual = dual_res;
    s.primal_tolerance = eps_pri;
    s.dual_tolerance = eps_dual;
    if (options.record_history) {
      s.history_primal.push_back(primal);
      s.history_dual.push_back(dual_res);
      s.history_primal_tolerance.push_back(eps_pri);
      s.history_dual_tolerance.push_back(eps_dual);
      s.history_rho.push_back(rho);
      s.history_cost.push_back(objective(pos ? Image(x.cwiseMax(0.0)) : x));
    }
    if (!std::isfinite(primal) || !std::isfinite(dual_res)) {
      x.swap(x_prev);
      failed = true;
      s.message = "non-finite ADMM residuals at iteration " + std::to_string(k + 1) +
                  "; returned the last finite iterate";
      break;
    }
    bool done = false;
    const double change = std::sqrt(ps.change2), x_norm = std::sqrt(ps.x2);
    if (primal <= eps_pri && dual_res <= eps_dual) {
      s.termination = Termination::kConverged;
      s.message = "primal and dual residuals within tolerance";
      done = true;
    } else if (options.change_tolerance > 0 && change <= options.change_tolerance * x_norm) {
      s.termination = Termination::kConverged;
      s.message = "relative change of x below change_tolerance";
      done = true;
    } else if (change <= 4 * std::numeric_limits<double>::epsilon() * x_norm) {
      // Stagnation: x has not moved beyond rounding (4ε relative) for 3 iterations while the residuals still
      // exceed tolerances that double precision cannot resolve for this problem: stop and say so.
      if (++still_iterations >= 3) {
        s.termination = Termination::kStagnated;
        s.message = "x unchanged to rounding for 3 iterations with the residuals above tolerance";
        done = true;
      }
    } else {
      still_iterations = 0;
    }
    // Progress (reads scalars only). A cancellation on the last iteration cuts nothing short.
    const bool last = done || k + 1 == options.max_iterations;
    if (!reporter.Report(k + 1, primal_over_tolerance(), last) && !last) {
      s.termination = Termination::kUserCancelled;
      s.message = "cancelled by the caller after iteration " + std::to_string(k + 1);
      done = true;
    }
    if (done) break;

    // Residual balancing on the tolerance-normalised residuals.
    if (options.adaptive_rho && s.rho_updates < options.max_rho_updates && eps_pri > 0 && eps_dual > 0) {
      const double rp = primal / eps_pri, rd = dual_res / eps_dual;
      double factor = 1;
      if (rp > options.rho_balance * rd)
        factor = options.rho_factor;
      else if (rd > options.rho_balance * rp)
        factor = 1.0 / options.rho_factor;
      if (factor != 1) {
        rho *= factor;
        u /= factor;  // the unscaled dual ρu is unchanged
        if (pos) sv /= factor;
        x_update->RescaleDual(factor);
        ++s.rho_updates;
        x_update->Prepare(rho, pos ? rho : 0.0);
        rhs2 = prepare_rhs();  // the right-hand side for the new ρ and rescaled duals
      }
    }
  }
  if (failed) s.termination = Termination::kFailed;
  reporter.Finish(s.iterations, primal_over_tolerance());  // a failure path ends without a last report
  reporter.RethrowIfThrown();
  s.final_rho = rho;

  if (state && !failed) {
    state->x = x;
    state->z = std::move(z);
    state->u = std::move(u);
    state->v = std::move(v);
    state->s = std::move(sv);
    state->rho = rho;
  }
  Image out = pos ? Image(x.cwiseMax(0.0)) : std::move(x);
  if (!AllFinite(out)) throw NumericalError("TotalVariationAdmm: the estimate is not finite");  // unreachable
  s.data_misfit = WeightedDataMisfit(problem, out, &s.frame_residual_rms);
  s.total_variation = IsotropicTotalVariation(out);
  s.final_cost = s.data_misfit + options.mu * s.total_variation;
  if (!std::isfinite(s.final_cost) && !failed) {
    s.termination = Termination::kFailed;
    s.message = "the objective at the estimate overflows double precision (" + s.message + ")";
  }
  std::ostringstream msg;
  if (s.message.empty())
    msg << "iteration limit reached";
  else
    msg << s.message;
  msg << "; primal " << s.primal_residual << " (tol " << s.primal_tolerance << "), dual " << s.dual_residual
      << " (tol " << s.dual_tolerance << "); rho " << s.initial_rho << " -> " << rho << " (" << s.rho_updates
      << " updates); x-update " << ToString(s.x_update) << x_update->Report();
  if (s.singular_bins > 0) msg << "; " << s.singular_bins << " singular bins (pseudo-inverse)";
  s.message = msg.str();
  s.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  if (summary) *summary = std::move(s);
  return out;
}

}  // namespace aosr
