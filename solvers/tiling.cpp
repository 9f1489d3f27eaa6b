// Tiled reconstruction (tiling.hpp): the tile geometry, the raised-cosine partition of unity, the sub-problem of
// a tile, the one choice of regularisation for the whole field, and the blend.
#include "aosr/solvers/tiling.hpp"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <map>
#include <limits>
#include <memory>
#include <mutex>
#include <optional>
#include <set>
#include <utility>

#include "aosr/core/error.hpp"
#include "aosr/core/fft.hpp"
#include "aosr/core/memory.hpp"
#include "aosr/core/parallel.hpp"
#include "aosr/core/progress.hpp"
#include "aosr/solvers/padded_model.hpp"
#include "aosr/solvers/target_psf.hpp"
#include "tile_blend.hpp"
#include "tile_checkpoint.hpp"
#include "tile_overlap.hpp"

namespace aosr {

using tiling_internal::AxisWeight;
using tiling_internal::CutModel;
using tiling_internal::CutModelFromCentred;
using tiling_internal::LastTileRow;
using tiling_internal::RowBlend;
using tiling_internal::OriginKernels;
using tiling_internal::OverlapIsMeasured;
using tiling_internal::OverlapRule;
using tiling_internal::WrapIndex;

namespace {

constexpr const char* kTilingFn = "ReconstructTiled";


// The core boundaries of one axis: n = ceil(m / T) cores, boundary k at round(k m / n) (sizes differ by <= 1).
std::vector<Index> Cuts(Index m, int tile) {
  const Index n = std::max<Index>(1, (m + tile - 1) / tile);
  std::vector<Index> b(n + 1);
  for (Index k = 0; k <= n; ++k) b[k] = (2 * k * m + n) / (2 * n);
  return b;
}

// The smallest and largest core of an axis cut by Cuts.
std::pair<Index, Index> CoreRange(const std::vector<Index>& c) {
  Index lo = c.back(), hi = 0;
  for (std::size_t k = 0; k + 1 < c.size(); ++k) lo = std::min(lo, c[k + 1] - c[k]), hi = std::max(hi, c[k + 1] - c[k]);
  return {lo, hi};
}


}  // namespace

namespace tiling_internal {

int FftFriendlyOverlap(Shape lr, int tile, int r, int p, int limit) {
  auto smooth = [](Index n) {
    for (const Index f : {2, 3, 5, 7})
      while (n % f == 0) n /= f;
    return n == 1;
  };
  auto friendly = [&](int q) {
    for (const Index m : {lr.rows, lr.cols}) {
      const std::vector<Index> c = Cuts(m, tile);
      if (c.size() <= 2) continue;  // one tile on the axis: its window is the field's side, whatever q
      const auto [smallest, largest] = CoreRange(c);
      if (q > smallest || largest + 2 * Index(q) > m) return false;  // MakeTiles' limits
      for (std::size_t k = 0; k + 1 < c.size(); ++k)
        if (!smooth(Index(r) * (c[k + 1] - c[k] + 2 * Index(q)))) return false;
    }
    return true;
  };
  for (int q = p; q <= limit; ++q)
    if (friendly(q)) return q;
  return p;
}

// The whole-grid kernels of the model, origin at (0, 0) (periodic).
ImageStack OriginKernels(const MultiFrameModel& model) {
  ImageStack k;
  for (int i = 0; i < model.frames(); ++i) k.push_back(FftC2R(model.otf(i), model.hr_shape().cols));
  return k;
}

// A model on the window's HR grid from origin-at-(0,0) kernels of the whole grid: each entry at signed offset
// s (per axis, in (−M/2, M/2]) kept where s is also a signed offset of the window grid, dropped otherwise (the
// kernel cut to the window; the overlap rule keeps the cut part below psf_tail of the energy).
std::shared_ptr<const MultiFrameModel> CutModel(const ImageStack& kernels, Shape whole, Shape window, int r) {
  std::vector<ComplexImage> otfs;
  for (const Image& k : kernels) {
    Image kp = Image::Zero(window.rows, window.cols);
    for (Index y = 0; y < whole.rows; ++y) {
      const Index sy = SignedFrequency(y, whole.rows), wy = WrapIndex(sy, window.rows);
      if (SignedFrequency(wy, window.rows) != sy) continue;
      for (Index x = 0; x < whole.cols; ++x) {
        const Index sx = SignedFrequency(x, whole.cols), wx = WrapIndex(sx, window.cols);
        if (SignedFrequency(wx, window.cols) != sx) continue;
        kp(wy, wx) = k(y, x);
      }
    }
    otfs.push_back(FftR2C(kp));
  }
  return std::make_shared<const MultiFrameModel>(window, r, std::move(otfs));
}

// The frames' and weights' windows and the offsets of `tile` (wrapped), with `model` on the window's HR grid.
ReconstructionProblem CutWindow(Shape lr, const ImageStack& frames, const ImageStack& weights,
                                const std::vector<FrameOffset>& offsets, const TileWindow& tile,
                                std::shared_ptr<const MultiFrameModel> model) {
  std::vector<Index> fx(std::size_t(tile.cols));  // the field column of each window column (wrapped)
  for (Index x = 0; x < tile.cols; ++x) fx[std::size_t(x)] = WrapIndex(tile.x0 + x, lr.cols);
  auto cut = [&](const Image& a) {
    Image s(tile.rows, tile.cols);
    for (Index y = 0; y < tile.rows; ++y) {
      const double* row = &a(WrapIndex(tile.y0 + y, lr.rows), 0);
      double* out = &s(y, 0);
      for (Index x = 0; x < tile.cols; ++x) out[x] = row[fx[std::size_t(x)]];
    }
    return s;
  };
  ReconstructionProblem p;
  p.model = std::move(model);
  for (const Image& f : frames) p.frames.push_back(cut(f));
  for (const Image& w : weights) p.weights.push_back(cut(w));
  p.offsets = offsets;
  return p;
}

ReconstructionProblem CutProblem(const ReconstructionProblem& problem, const TileWindow& tile,
                                 std::shared_ptr<const MultiFrameModel> model) {
  return CutWindow(problem.model->lr_shape(), problem.frames, problem.weights, problem.offsets, tile,
                   std::move(model));
}

// A model on the window's HR grid from centred kernels (image.hpp: centre pixel K/2): each entry at signed
// offset s = index − K/2 (per axis) kept where s is also a signed offset of the window grid, dropped otherwise
// (the rule CutModel applies to the whole grid's kernels, so that both give the same window models).
std::shared_ptr<const MultiFrameModel> CutModelFromCentred(const ImageStack& kernels, Shape window, int r) {
  std::vector<ComplexImage> otfs;
  for (const Image& k : kernels) {
    Image kp = Image::Zero(window.rows, window.cols);
    for (Index y = 0; y < k.rows(); ++y) {
      const Index sy = y - k.rows() / 2, wy = WrapIndex(sy, window.rows);
      if (SignedFrequency(wy, window.rows) != sy) continue;
      for (Index x = 0; x < k.cols(); ++x) {
        const Index sx = x - k.cols() / 2, wx = WrapIndex(sx, window.cols);
        if (SignedFrequency(wx, window.cols) != sx) continue;
        kp(wy, wx) += k(y, x);
      }
    }
    otfs.push_back(FftR2C(kp));
  }
  return std::make_shared<const MultiFrameModel>(window, r, std::move(otfs));
}

}  // namespace tiling_internal

using tiling_internal::CutProblem;
using tiling_internal::CutWindow;

namespace {

// The periodic component of an image (Moisan, "Periodic plus smooth image decomposition", J. Math. Imaging
// Vis. 39, 2011): u = p + s with s smooth (the solution of a Poisson problem driven by the jumps across u's
// opposite edges) and p periodic, without those jumps. A window cut out of a field wraps around with a jump
// at each edge, which GCV reads as detail (on tiling_test's scene a 64 px window of the 96 px field gave
// λ = 3e-10 against 7e-3); p keeps the window's detail and noise and drops the jumps. Returns s.
Image SmoothComponent(const Image& u) {
  const Index m = u.rows(), n = u.cols();
  Image v = Image::Zero(m, n);
  for (Index x = 0; x < n; ++x) {
    const double d = u(m - 1, x) - u(0, x);
    v(0, x) += d;
    v(m - 1, x) -= d;
  }
  for (Index y = 0; y < m; ++y) {
    const double d = u(y, n - 1) - u(y, 0);
    v(y, 0) += d;
    v(y, n - 1) -= d;
  }
  ComplexImage s = FftR2C(v);
  for (Index q = 0; q < s.rows(); ++q)
    for (Index r = 0; r < s.cols(); ++r) {
      const double den = 2 * std::cos(kTwoPi * double(q) / double(m)) + 2 * std::cos(kTwoPi * double(r) / double(n)) - 4;
      s(q, r) = (q == 0 && r == 0) ? Complex(0) : s(q, r) / den;
    }
  return FftC2R(s, n);
}

// The frames of a window without their wrap-around jumps: each frame less the smooth component of the frames'
// mean (one s for all, so that the frames stay consistent with each other: each its own s made GCV's λ 76
// times the whole field's on tiling_test's scene).
void RemoveWrapJumps(ReconstructionProblem* p) {
  const ImageStack clean = p->CleanFrames();
  Image mean = Image::Zero(clean.front().rows(), clean.front().cols());
  for (const Image& f : clean) mean += f / double(clean.size());
  const Image s = SmoothComponent(mean);
  for (std::size_t i = 0; i < clean.size(); ++i) p->frames[i] = clean[i] - s;
}

bool AnyWeighted(const ReconstructionProblem& p) {
  if (p.weights.empty()) return true;
  for (const Image& w : p.weights)
    if ((w.array() > 0).any()) return true;
  return false;
}

// How bad a termination is, for the summary's worst tile.
int Severity(Termination t) {
  switch (t) {
    case Termination::kConverged: return 0;
    case Termination::kStagnated: return 1;
    case Termination::kMaxIterations: return 2;
    case Termination::kUserCancelled: return 3;
    case Termination::kFailed: return 4;
  }
  return 4;
}

}  // namespace

bool RegularisationIsFixed(const ReconstructOptions& o) {
  switch (o.method) {
    case ReconstructionMethod::kTikhonov:
      return o.tikhonov.lambda_rule == TikhonovLambdaRule::kFixed && o.tikhonov.prior != TikhonovPrior::kFitted;
    case ReconstructionMethod::kLinear:
      return o.linear.kappa > 0;
    case ReconstructionMethod::kTotalVariation:
    case ReconstructionMethod::kMap:
      return !o.auto_regularisation || o.fixed_automatic.has_value();
    default:
      return true;
  }
}

bool FixRegularisation(const ReconstructionProblem& rep, ReconstructOptions* o) {
  if (RegularisationIsFixed(*o)) return false;
  switch (o->method) {
    case ReconstructionMethod::kTikhonov: {
      TikhonovOptions& t = o->tikhonov;
      ReconstructOptions ro = *o;
      ro.tikhonov.compute_std = false;
      ro.progress = nullptr;
      const double lambda = Reconstruct(rep, ro).regularisation;
      if (t.prior == TikhonovPrior::kFitted) {
        // The fitted spectrum, at that λ (kFitted with a fixed λ fits the same spectrum and solves once more).
        TikhonovOptions f = ro.tikhonov;
        f.lambda_rule = TikhonovLambdaRule::kFixed;
        f.lambda = lambda;
        const TikhonovResult fr = ReconstructTikhonov(rep, f);
        t.prior = TikhonovPrior::kPowerSpectrum;
        t.spectrum_slope = fr.summary.fitted_spectrum.slope;
        t.spectrum_corner = fr.summary.fitted_spectrum.corner;
      }
      t.lambda_rule = TikhonovLambdaRule::kFixed;
      t.lambda = lambda;
      return true;
    }
    case ReconstructionMethod::kLinear: {
      // κ's search alone (no solve); e_max with it lets a tile analyse its bins once (target_psf.hpp).
      const TargetPsfChoice c = ChooseTargetPsf(rep, o->linear);
      o->linear.kappa = c.kappa;
      o->linear.e_max = c.e_max;
      if (o->linear.kind == TargetPsfKind::kAuto) {
        o->linear.kind = TargetPsfKind::kGaussian;
        o->linear.fwhm_hr_px = c.target_fwhm_hr_px;
      }
      return true;
    }
    case ReconstructionMethod::kTotalVariation:
    case ReconstructionMethod::kMap:
      o->fixed_automatic = ChooseAutomaticRegularisation(rep, *o);
      return true;
    default:
      return false;
  }
}

bool TilingOptions::IsValid(std::string* why) const {
  auto fail = [why](const std::string& m) {
    if (why) *why = m;
    return false;
  };
  if (tile < 1) return fail("tile = " + std::to_string(tile) + "; allowed: >= 1 camera pixel");
  if (!only_tiles.empty() && checkpoint_dir.empty())
    return fail("only_tiles without checkpoint_dir; allowed: only_tiles with a checkpoint folder to solve them into");
  if (!only_tiles.empty() && plan_only) return fail("only_tiles with plan_only; allowed: one or the other");
  if (overlap < -1) return fail("overlap = " + std::to_string(overlap) + "; allowed: -1 (automatic) or >= 0");
  if (!(psf_tail > 0 && psf_tail < 1)) return fail("psf_tail = " + ToString(psf_tail) + "; allowed: (0, 1)");
  if (!(tolerance > 0 && tolerance < 1)) return fail("tolerance = " + ToString(tolerance) + "; allowed: (0, 1)");
  if (max_overlap < 0) return fail("max_overlap = " + std::to_string(max_overlap) + "; allowed: 0 (none) or >= 1");
  return true;
}

std::vector<TileWindow> MakeTiles(Shape lr, int tile, int overlap, const char* function) {
  CheckArgument(tile >= 1, function, "tile", tile, ">= 1 camera pixel");
  CheckArgument(overlap >= 0, function, "overlap", overlap, ">= 0 camera pixels");
  const std::vector<Index> cy = Cuts(lr.rows, tile), cx = Cuts(lr.cols, tile);
  const int ny = int(cy.size()) - 1, nx = int(cx.size()) - 1;
  // Per cut axis: P <= every core (a ramp must not reach the next boundary) and the window within the field.
  auto check_axis = [&](const std::vector<Index>& c, Index m, const char* axis) {
    if (c.size() <= 2) return;
    const auto [smallest, largest_core] = CoreRange(c);
    if (overlap > smallest)
      throw InvalidArgument(function, "overlap", std::to_string(overlap),
                            std::string("at most the smallest tile core along ") + axis + " (" +
                                std::to_string(smallest) + " camera px for tile " + std::to_string(tile) +
                                " on " + std::to_string(m) + " px): choose a larger tile or a smaller overlap");
    const Index largest = largest_core + 2 * Index(overlap);
    if (largest > m)
      throw InvalidArgument(function, "tile, overlap", std::to_string(tile) + ", " + std::to_string(overlap),
                            std::string("tile + 2 overlap <= the field's ") + axis + " side (" + std::to_string(m) +
                                " camera px): use fewer, larger tiles or a smaller overlap");
  };
  check_axis(cy, lr.rows, "rows");
  check_axis(cx, lr.cols, "columns");
  std::vector<TileWindow> tiles;
  for (int ty = 0; ty < ny; ++ty)
    for (int tx = 0; tx < nx; ++tx) {
      TileWindow t;
      t.index = ty * nx + tx;
      t.ty = ty;
      t.tx = tx;
      t.core_y0 = cy[ty];
      t.core_rows = cy[ty + 1] - cy[ty];
      t.core_x0 = cx[tx];
      t.core_cols = cx[tx + 1] - cx[tx];
      const Index py = ny > 1 ? overlap : 0, px = nx > 1 ? overlap : 0;
      t.y0 = ny > 1 ? t.core_y0 - py : 0;
      t.rows = ny > 1 ? t.core_rows + 2 * py : lr.rows;
      t.x0 = nx > 1 ? t.core_x0 - px : 0;
      t.cols = nx > 1 ? t.core_cols + 2 * px : lr.cols;
      tiles.push_back(t);
    }
  return tiles;
}


ReconstructionProblem TileProblem(const ReconstructionProblem& problem, const TileWindow& tile,
                                  const ImageStack& psfs) {
  problem.Validate("TileProblem");
  const int r = problem.model->r();
  const Shape window{tile.rows * r, tile.cols * r};
  std::shared_ptr<const MultiFrameModel> model;
  if (!psfs.empty()) {
    CheckArgument(int(psfs.size()) == problem.frame_count(), "TileProblem", "psfs",
                  std::to_string(psfs.size()) + " kernels", "one per frame (" +
                                                                std::to_string(problem.frame_count()) + ")");
    model = std::make_shared<const MultiFrameModel>(MultiFrameModel::FromKernels(window, r, psfs));
  } else {
    model = CutModel(OriginKernels(*problem.model), problem.model->hr_shape(), window, r);
  }
  return CutProblem(problem, tile, std::move(model));
}

void FieldData::Validate(const std::string& function) const {
  CheckArgument(r >= 1, function, "field.r", r, ">= 1");
  CheckArgument(lr.rows >= 1 && lr.cols >= 1, function, "field.lr", ToString(lr), "at least 1 x 1 camera px");
  const std::size_t n = std::size_t(frame_count());
  CheckArgument(n >= 1, function, "field.frames", 0, "at least one frame");
  if (sections) {
    CheckArgument(frames.empty() && weights.empty() && bool(sections->read), function, "field.sections",
                  "set with held frames or without a reader", "a reader, and no held frames or weights");
    CheckArgument(kernels.size() == n, function, "field.kernels", kernels.size(),
                  "one per frame (" + std::to_string(n) + ")");
    CheckArgument(offsets.empty() || offsets.size() == n, function, "field.offsets", offsets.size(),
                  "0 or one per frame (" + std::to_string(n) + ")");
    for (std::size_t i = 0; i < n; ++i) {
      const Image& k = kernels[i];
      CheckArgument(k.size() > 0 && AllFinite(k) && k.sum() > 0, function, "field.kernels[" + std::to_string(i) + "]",
                    k.size() == 0 ? std::string("empty") : "sum " + ToString(k.sum()), "finite values with a positive sum");
    }
    return;  // the pixels are checked window by window (Reconstruct validates each tile's problem)
  }
  CheckArgument(kernels.size() == n, function, "field.kernels", kernels.size(),
                "one per frame (" + std::to_string(n) + ")");
  CheckArgument(weights.empty() || weights.size() == n, function, "field.weights", weights.size(),
                "0 or one per frame (" + std::to_string(n) + ")");
  CheckArgument(offsets.empty() || offsets.size() == n, function, "field.offsets", offsets.size(),
                "0 or one per frame (" + std::to_string(n) + ")");
  for (std::size_t i = 0; i < n; ++i) {
    const std::string f = "field.frames[" + std::to_string(i) + "]";
    CheckArgument(ShapeOf(frames[i]) == lr, function, f + " shape", ToString(ShapeOf(frames[i])), ToString(lr));
    if (!weights.empty())
      CheckArgument(ShapeOf(weights[i]) == lr, function, "field.weights[" + std::to_string(i) + "] shape",
                    ToString(ShapeOf(weights[i])), ToString(lr));
    if (!AllFinite(frames[i]))  // the pixel-by-pixel search only when some pixel is not finite
    for (Index y = 0; y < lr.rows; ++y)
      for (Index x = 0; x < lr.cols; ++x)
        if (!std::isfinite(frames[i](y, x)) && (weights.empty() || weights[i](y, x) > 0))
          throw InvalidArgument(function + ": " + f + "(" + std::to_string(y) + ", " + std::to_string(x) + ") = " +
                                ToString(frames[i](y, x)) + "; allowed: finite values, or weight 0 at that pixel (mask it)");
    if (!weights.empty())
      CheckArgument(AllFinite(weights[i]) && weights[i].minCoeff() >= 0, function,
                    "field.weights[" + std::to_string(i) + "]", "(negative or non-finite values)",
                    "finite weights >= 0 (0 masks a pixel)");
    const Image& k = kernels[i];
    CheckArgument(k.size() > 0 && AllFinite(k) && k.sum() > 0, function, "field.kernels[" + std::to_string(i) + "]",
                  k.size() == 0 ? std::string("empty") : "sum " + ToString(k.sum()),
                  "finite values with a positive sum");
  }
}

namespace {

// Whether every weight of the field is one positive value (ReconstructionProblem::HasUniformWeights's rule): the
// tiles' solves then take the Fourier path, which EstimateSolveBytes counts as unweighted (Tikhonov: 2N + 14 HR
// arrays, not the CG path's 2N + 32).
bool UniformWeights(const FieldData& field) {
  if (field.sections) return field.sections->uniform_weights;
  if (field.weights.empty()) return true;
  const double w0 = field.weights.front()(0, 0);
  if (!(w0 > 0)) return false;
  for (const Image& w : field.weights)
    if ((w.array() != w0).any()) return false;
  return true;
}

// The memory plan's functions with the weights' kind decided once (`weighted`: not UniformWeights, a scan of every
// weight, which the plan's loops would otherwise repeat for each candidate tile and overlap).
double TiledBytes(const FieldData& field, ReconstructionMethod method, int tile, int overlap, int concurrent, bool aux,
                  bool weighted) {
  const double lr_px = double(field.lr.rows) * double(field.lr.cols);
  const double data = 8.0 * lr_px * double(field.frames.size() + field.weights.size());  // 0 when read by sections
  const double side = double(std::min<Index>(tile + 2 * Index(overlap), std::max(field.lr.rows, field.lr.cols)));
  const double window_hr = side * side * double(field.r) * double(field.r);
  // A tile's solve, its cut frames and the result it hands back (image, second map, the blend weight).
  const double solve = EstimateSolveBytes(method, field.frame_count(), window_hr, weighted) + 8.0 * 3 * window_hr;
  // Two tile rows of output accumulators (numerator and denominator, twice with a second map).
  const double band = 2.0 * side * field.r * double(field.lr.cols) * field.r * 8.0 * (aux ? 4 : 2);
  // The window models, one per window shape, kept for the run (~8 bytes per HR px per frame for each half
  // spectrum). Up to 9 shapes (first, inner, last along each axis): TV's run at --memory-limit 4G showed the
  // estimate had once left them out (peak RSS 4.6 GiB). A model holds two half spectra per frame (its OTF and
  // the aliased stack's transfer); one is counted, because the measured peaks stay well inside the limit with
  // the other terms' margins (2.9 GiB at 4G, bench/results/whole_detector.md), and counting both moves the
  // 8192² linear plan's overlap from 44 to 42, a window size where FFTW is twice as slow.
  int shapes = 9;
  try {
    std::set<std::pair<Index, Index>> distinct;
    for (const TileWindow& t : MakeTiles(field.lr, tile, overlap, "EstimateTiledBytes")) distinct.insert({t.rows, t.cols});
    shapes = int(distinct.size());
  } catch (const InvalidArgument&) {
  }
  const double models = double(shapes) * 8.0 * double(field.frame_count()) * window_hr;
  return data + concurrent * solve + band + models;
}

int RegularisationWindow(const FieldData& field, ReconstructionMethod method, double limit_bytes, bool weighted) {
  const double data =
      8.0 * double(field.lr.rows) * double(field.lr.cols) * double(field.frames.size() + field.weights.size());
  const Index largest = std::max(field.lr.rows, field.lr.cols);
  for (const int w : {512, 384, 256, 192, 128, 96, 64, 48, 32}) {
    const Index wy = std::min<Index>(w, field.lr.rows), wx = std::min<Index>(w, field.lr.cols);
    const double hr = double(wy * field.r) * double(wx * field.r);
    if (data + EstimateSolveBytes(method, field.frame_count(), hr, weighted) <= limit_bytes)
      return w >= largest ? 0 : w;
  }
  return 32;
}

TilingOptions Tiling(const FieldData& field, ReconstructionMethod method, int overlap, int threads, double limit_bytes,
                     bool aux, bool weighted) {
  CheckArgument(overlap >= 0, "ChooseTiling", "overlap", overlap, ">= 0 camera px");
  CheckArgument(threads >= 1, "ChooseTiling", "threads", threads, ">= 1");
  TilingOptions t;
  t.overlap = overlap;
  t.regularisation_window = RegularisationWindow(field, method, limit_bytes, weighted);
  double smallest = 0;
  int smallest_tile = 0;
  for (const int tile : {512, 384, 256, 192, 128, 96, 64, 48, 32, 24, 16}) {
    // Not past twice the field, and a core must hold the overlap's ramp (MakeTiles).
    if (tile > 2 * std::max(field.lr.rows, field.lr.cols) || (tile < overlap && smallest_tile > 0)) continue;
    smallest_tile = tile;
    for (const bool parallel : {true, false}) {
      if (parallel && threads == 1) continue;
      const double need = TiledBytes(field, method, tile, overlap, parallel ? threads : 1, aux, weighted);
      smallest = need;
      if (need <= limit_bytes) {
        t.tile = tile;
        t.parallel_tiles = parallel;
        return t;
      }
    }
  }
  throw ResourceError("ChooseTiling: the smallest tiling of " + ToString(field.lr) + " camera px x " +
                      std::to_string(field.frame_count()) + " frames at r = " + std::to_string(field.r) + " (" +
                      ToString(method) + ", tiles of " + std::to_string(smallest_tile) +
                      " camera px one at a time, overlap " + std::to_string(overlap) +
                      ") needs about " + FormatBytes(smallest) + " of memory (estimate), more than the limit of " +
                      FormatBytes(limit_bytes) + ": raise --memory-limit (AOSR_MEMORY_LIMIT) or give fewer or smaller frames");
}

}  // namespace

double EstimateTiledBytes(const FieldData& field, ReconstructionMethod method, int tile, int overlap, int concurrent,
                          bool aux) {
  return TiledBytes(field, method, tile, overlap, concurrent, aux, !UniformWeights(field));
}

int ChooseRegularisationWindow(const FieldData& field, ReconstructionMethod method, double limit_bytes) {
  return RegularisationWindow(field, method, limit_bytes, !UniformWeights(field));
}

TilingOptions ChooseTiling(const FieldData& field, ReconstructionMethod method, int overlap, int threads,
                           double limit_bytes, bool aux) {
  return Tiling(field, method, overlap, threads, limit_bytes, aux, !UniformWeights(field));
}

void FitTilingToMemory(const FieldData& field, const ReconstructOptions& options, double limit_bytes,
                       TilingOptions* tiling) {
  // The overlap the memory is planned for. A reach measured only once the regularisation is fixed (RunTiles)
  // is planned at twice the PSF-and-reach rule (the tile chosen for that) and bounded by what those tiles leave
  // room for (max_overlap, below); the overlap stays automatic.
  // A measured reach whose tiles do not fit falls back to that rule's overlap (max_overlap: the summary's rule
  // says "capped by the memory plan").
  const bool aux = options.method == ReconstructionMethod::kTikhonov && options.tikhonov.compute_std;
  const bool weighted = !UniformWeights(field);
  const int rule = OverlapRule(field, options, *tiling, nullptr, false);
  int plan = tiling->overlap;
  const bool fixed_here = plan < 0 && !(options.method == ReconstructionMethod::kTikhonov ||
                                        options.method == ReconstructionMethod::kLinear);
  if (plan < 0) {
    const bool linear = options.method == ReconstructionMethod::kTikhonov || options.method == ReconstructionMethod::kLinear;
    plan = linear ? (OverlapIsMeasured(options) ? SuggestTileOverlap(field, options, *tiling) : 2 * rule) : rule;
    if (linear) {
      if (tiling->tile <= 0) {
        try {
          Tiling(field, options.method, plan, DefaultThreads(), limit_bytes, aux, weighted);
        } catch (const ResourceError&) {
          plan = std::min(plan, rule);
        }
      }
      tiling->max_overlap = tiling->max_overlap > 0 ? std::min(tiling->max_overlap, plan) : plan;
    } else {
      tiling->overlap = plan;
    }
  }
  if (tiling->tile <= 0) {
    const TilingOptions chosen = Tiling(field, options.method, plan, DefaultThreads(), limit_bytes, aux, weighted);
    tiling->tile = chosen.tile;
    tiling->parallel_tiles = chosen.parallel_tiles;
    // A reach still to measure may use more than the plan where the chosen tiles leave the memory for it: up to
    // the probe's largest (AO PSFs ask for it, bench/results/whole_detector.md: 2.1e-6 of the peak at 32 camera
    // px, 2.1e-7 at 42), never changing the tile.
    if (tiling->overlap < 0 && tiling->max_overlap == plan && !OverlapIsMeasured(options)) {
      const int concurrent = tiling->parallel_tiles ? DefaultThreads() : 1;
      // (A quarter above the probe's largest: room for RunTiles' raise to FFT-friendly windows.)
      const int largest = tiling_internal::LargestMeasuredOverlap(field.lr);
      for (int p = largest + largest / 4; p > plan; --p)
        if (p <= tiling->tile &&
            TiledBytes(field, options.method, tiling->tile, p, concurrent, aux, weighted) <= limit_bytes) {
          tiling->max_overlap = p;
          break;
        }
    }
  }
  // The other methods' rule is fixed here: raised, as RunTiles raises an automatic overlap, to windows of
  // FFT-friendly sizes where the memory allows.
  if (fixed_here) {
    const int concurrent = tiling->parallel_tiles ? DefaultThreads() : 1;
    const int fast = tiling_internal::FftFriendlyOverlap(field.lr, tiling->tile, field.r, tiling->overlap,
                                                         tiling->overlap + tiling->overlap / 4);
    if (fast != tiling->overlap &&
        TiledBytes(field, options.method, tiling->tile, fast, concurrent, aux, weighted) <= limit_bytes)
      tiling->overlap = fast;
  }
  tiling->regularisation_window = RegularisationWindow(field, options.method, limit_bytes, weighted);
}

namespace {

// What the engine reads of a field: a problem with its whole-grid model, or FieldData (kernels only).
struct TiledInput {
  Shape lr, hr;
  int r = 0;
  const ImageStack* frames = nullptr;
  const ImageStack* weights = nullptr;
  const std::vector<FrameOffset>* offsets = nullptr;
  const ReconstructionProblem* problem = nullptr;  // set when the whole problem exists
  const FieldData* field = nullptr;                // else this
  int n = 0;                                       // frames
};


Reconstruction RunTiles(const TiledInput& in, const ReconstructOptions& options, const TilingOptions& tiling,
                        TilingSummary* summary) {
  const auto start = std::chrono::steady_clock::now();
  std::string why;
  if (!tiling.IsValid(&why)) throw InvalidArgument(std::string(kTilingFn) + ": tiling." + why);
  CheckArgument(tiling.regularisation_window >= 0, kTilingFn, "tiling.regularisation_window",
                tiling.regularisation_window, "0 (the whole field) or W >= 1 camera px");
  if (!tiling.checkpoint_dir.empty() && !std::filesystem::is_directory(tiling.checkpoint_dir))
    throw InvalidArgument(kTilingFn, "tiling.checkpoint_dir", tiling.checkpoint_dir, "an existing folder");
  const Shape lr = in.lr, hr = in.hr;
  const int r = in.r;
  const bool whole_model = in.problem != nullptr;

  // The overlap: given, or the rule capped to what the field allows (measured again below once the
  // regularisation is fixed, for the methods whose reach is measured).
  TilingSummary ts;
  // Tiles with local PSFs (a field-varying model) take the PSF-and-reach rule, undoubled, not the measured reach:
  // each tile's PSF is right only near its centre, so a wider window adds model error faster than it removes
  // the truncation's (tiling.hpp, "The overlap rule", with the measurements).
  const bool measure = !tiling.local_psfs;
  auto local_psfs = [&](const TileWindow& t) {
    ImageStack psfs = tiling.local_psfs(t);
    CheckArgument(int(psfs.size()) == in.n, kTilingFn, "local_psfs", std::to_string(psfs.size()) + " kernels",
                  "one per frame (" + std::to_string(in.n) + ")");
    return psfs;
  };
  auto automatic_overlap = [&](const ReconstructOptions& with, std::string* rule) {
    int p = 0;
    if (tiling.local_psfs) {
      // The rule on the local PSFs of the field's centre, from the kernels themselves: the whole grid's model
      // would cost an HR-sized inverse FFT per frame for the same reach.
      TileWindow centre;
      centre.core_rows = centre.rows = lr.rows;
      centre.core_cols = centre.cols = lr.cols;
      FieldData probe;
      probe.lr = lr;
      probe.r = r;
      probe.offsets = *in.offsets;
      probe.kernels = local_psfs(centre);
      p = OverlapRule(probe, with, tiling, rule, false);
    } else {
      p = whole_model ? OverlapRule(*in.problem, with, tiling, rule, measure)
                      : OverlapRule(*in.field, with, tiling, rule, measure);
    }
    Index cap = p;
    for (const Index m : {lr.rows, lr.cols}) {
      const std::vector<Index> c = Cuts(m, tiling.tile);
      if (c.size() <= 2) continue;
      const auto [smallest, largest] = CoreRange(c);
      cap = std::min({cap, smallest, (m - largest) / 2});
    }
    if (cap < p) *rule += ", capped at " + std::to_string(cap) + " by the tile and field sizes";
    p = int(cap);
    if (tiling.max_overlap > 0 && p > tiling.max_overlap) {
      *rule += ", capped at " + std::to_string(tiling.max_overlap) + " by the memory plan";
      p = tiling.max_overlap;
    }
    // Up to a quarter more, within the caps, for windows whose FFTs are fast (FftFriendlyOverlap keeps
    // MakeTiles' limits).
    int limit = p + p / 4;
    if (tiling.max_overlap > 0) limit = std::min(limit, tiling.max_overlap);
    const int fast = tiling_internal::FftFriendlyOverlap(lr, tiling.tile, r, p, limit);
    if (fast != p) *rule += ", raised to " + std::to_string(fast) + " for windows of FFT-friendly sizes";
    return fast;
  };
  int overlap = tiling.overlap;
  if (overlap >= 0) {
    ts.overlap_rule = "given";
  } else {
    overlap = automatic_overlap(options, &ts.overlap_rule);
  }
  ts.overlap = overlap;
  ts.tile = tiling.tile;
  ts.tiles = MakeTiles(lr, tiling.tile, overlap, kTilingFn);
  ts.tiles_y = ts.tiles.back().ty + 1;
  ts.tiles_x = ts.tiles.back().tx + 1;
  const int count = int(ts.tiles.size());
  if (count == 1 && whole_model && !tiling.rows && !tiling.plan_only && tiling.only_tiles.empty()) {
    // One tile: the whole field, exactly as Reconstruct solves it.
    Reconstruction out = Reconstruct(*in.problem, options);
    ts.regularisation = out.regularisation;
    ts.regularisation_source = "whole field (one tile)";
    ts.tile_terminations = {out.summary.termination};
    out.summary.message = "tiled: 1 tile (the whole field); " + out.summary.message;
    if (summary) *summary = std::move(ts);
    return out;
  }

  // Each window's model: the caller's local PSFs, or the whole model's kernels (or the field's) cut to the
  // window, one model per window shape, shared.
  const ImageStack kernels = tiling.local_psfs || !whole_model ? ImageStack{} : OriginKernels(*in.problem->model);
  // Made on first use (a job of one tile needs one shape, a plan none), under a lock: tiles run concurrently.
  TileModelStore local_store;
  TileModelStore& store = tiling.model_store && !tiling.local_psfs ? *tiling.model_store : local_store;
  auto window_model = [&](Shape window) {
    if (whole_model) return CutModel(kernels, hr, window, r);
    return CutModelFromCentred(in.field->kernels, window, r);
  };
  auto shared_model = [&](Shape window) {
    const std::lock_guard<std::mutex> lock(store.mutex);
    std::shared_ptr<const MultiFrameModel>& m = store.models[{window.rows, window.cols}];
    if (!m) m = window_model(window);
    return m;
  };
  // A window's frames, weights and offsets (no model yet): cut from the held frames, or read by sections.
  auto window_data = [&](const TileWindow& t) {
    if (!in.field || !in.field->sections) return CutWindow(lr, *in.frames, *in.weights, *in.offsets, t, nullptr);
    // An edge tile's window wraps around the periodic field (CutWindow): up to two pieces per axis, each a
    // section inside the field, placed where CutWindow would put them.
    auto pieces = [](Index start, Index length, Index m) {
      const Index a = WrapIndex(start, m), first = std::min(length, m - a);
      std::vector<std::array<Index, 3>> out{{a, first, 0}};  // field start, length, window offset
      if (first < length) out.push_back({0, length - first, first});
      return out;
    };
    ReconstructionProblem p;
    for (const auto& [fy, ny, wy] : pieces(t.y0, t.rows, lr.rows))
      for (const auto& [fx, nx, wx] : pieces(t.x0, t.cols, lr.cols)) {
        ImageStack frames, weights;
        in.field->sections->read(fy, fx, ny, nx, &frames, &weights);
        CheckArgument(int(frames.size()) == in.n && (weights.empty() || int(weights.size()) == in.n) &&
                          (p.frames.empty() || weights.empty() == p.weights.empty()),
                      kTilingFn, "field.sections", std::to_string(frames.size()) + " frames read",
                      "one frame (and 0 or one weight map, the same for every section) per frame (" +
                          std::to_string(in.n) + ")");
        if (p.frames.empty()) {
          p.frames.assign(std::size_t(in.n), Image(t.rows, t.cols));
          if (!weights.empty()) p.weights.assign(std::size_t(in.n), Image(t.rows, t.cols));
        }
        for (int i = 0; i < in.n; ++i) {
          CheckArgument(ShapeOf(frames[i]) == Shape{ny, nx} && (weights.empty() || ShapeOf(weights[i]) == Shape{ny, nx}),
                        kTilingFn, "field.sections", ToString(ShapeOf(frames[i])) + " read",
                        "the section's " + ToString(Shape{ny, nx}));
          p.frames[i].block(wy, wx, ny, nx) = frames[i];
          if (!weights.empty()) p.weights[i].block(wy, wx, ny, nx) = weights[i];
        }
      }
    p.offsets = *in.offsets;
    return p;
  };
  auto tile_model = [&](const TileWindow& t, bool share_model = true) {
    const Shape window{t.rows * r, t.cols * r};
    std::shared_ptr<const MultiFrameModel> model;
    if (tiling.local_psfs) {
      model = std::make_shared<const MultiFrameModel>(MultiFrameModel::FromKernels(window, r, local_psfs(t)));
    } else {
      model = share_model ? shared_model(window) : window_model(window);
    }
    return model;
  };
  auto window_problem = [&](const TileWindow& t, bool share_model = true) {
    ReconstructionProblem p = window_data(t);
    p.model = tile_model(t, share_model);
    return p;
  };

  // One regularisation for the field, chosen on the whole field, a central window of it, or the central tile.
  const int central = (ts.tiles_y / 2) * ts.tiles_x + ts.tiles_x / 2;
  ReconstructOptions o = options;
  o.progress = nullptr;  // tiles may run concurrently; the callback need not be thread-safe
  if (tiling.stop) {
    const std::function<bool()> stop = tiling.stop;
    o.progress = [stop](const Progress&) { return !stop(); };
  }
  {
    bool chosen = false;
    ReconstructOptions fix = options;
    fix.progress = nullptr;
    if (RegularisationIsFixed(fix)) {
      // Nothing to choose (given values, or a plan's): no representative problem to build.
    } else if (!tiling.regularisation_from_whole_field) {
      ReconstructionProblem p = window_problem(ts.tiles[central]);
      RemoveWrapJumps(&p);
      chosen = FixRegularisation(p, &fix);
      ts.regularisation_source = "central tile";
    } else if (tiling.regularisation_window == 0 && whole_model && !tiling.local_psfs) {
      chosen = FixRegularisation(*in.problem, &fix);
      ts.regularisation_source = "whole field";
    } else {
      TileWindow rep;
      const Index wy = tiling.regularisation_window == 0 ? lr.rows : std::min<Index>(tiling.regularisation_window, lr.rows);
      const Index wx = tiling.regularisation_window == 0 ? lr.cols : std::min<Index>(tiling.regularisation_window, lr.cols);
      rep.core_y0 = rep.y0 = (lr.rows - wy) / 2;
      rep.core_x0 = rep.x0 = (lr.cols - wx) / 2;
      rep.core_rows = rep.rows = wy;
      rep.core_cols = rep.cols = wx;
      ReconstructionProblem p = window_problem(rep, /*share_model=*/false);
      // A window smaller than the field: its frames' periodic components (no wrap-around jumps).
      if (wy < lr.rows || wx < lr.cols) RemoveWrapJumps(&p);
      chosen = FixRegularisation(p, &fix);
      ts.regularisation_source = (wy == lr.rows && wx == lr.cols)
                                     ? std::string("whole field")
                                     : "central " + std::to_string(wy) + " x " + std::to_string(wx) + " camera px";
    }
    if (!chosen) ts.regularisation_source = "given";
    ts.options = fix;
    fix.progress = o.progress;
    o = fix;
  }
  if (measure && tiling.overlap < 0 && !OverlapIsMeasured(options) && OverlapIsMeasured(ts.options)) {
    // The reach at the regularisation just fixed; the regularisation was chosen with the tiles of the rule.
    overlap = automatic_overlap(ts.options, &ts.overlap_rule);
    ts.overlap = overlap;
    ts.tiles = MakeTiles(lr, tiling.tile, overlap, kTilingFn);
  }
  if (tiling.plan_only) {
    Reconstruction planned;
    planned.summary.method = ToString(options.method);
    planned.summary.message = "planned: " + std::to_string(ts.tiles_y) + " x " + std::to_string(ts.tiles_x) +
                              " tiles of <= " + std::to_string(tiling.tile) + " camera px, overlap " +
                              std::to_string(overlap) + "; regularisation (" + ts.regularisation_source + ")";
    if (summary) *summary = std::move(ts);
    return planned;
  }
  for (const int k : tiling.only_tiles)
    CheckArgument(k >= 0 && k < count, kTilingFn, "tiling.only_tiles", k,
                  "a tile index in [0, " + std::to_string(count) + ")");

  // The tiles in batches (one per thread, or one at a time), each read from the checkpoint folder if a previous
  // run finished it, else solved (and written there). A batch is blended in tile order, then dropped.
  const bool checkpoint = !tiling.checkpoint_dir.empty();
  ReconstructOptions fingerprint_options = o;
  fingerprint_options.progress = nullptr;
  const std::uint64_t fingerprint =
      !checkpoint ? 0
      : whole_model ? tiling_internal::RunFingerprint(*in.problem, fingerprint_options, tiling, overlap)
                    : tiling_internal::RunFingerprint(*in.field, fingerprint_options, tiling, overlap);
  // Without a whole image at the end, the residual is each tile's over its core. So it is for the linear output,
  // whose residual is that of its ridge solution (target_psf.hpp), which only the tiles have.
  // So it is for tiles with local PSFs: the whole model's PSF is the field centre's, which is not the one the
  // tiles fitted (and its render of the whole field cost 15 % of a wide field's run).
  const bool misfit_by_tiles = !whole_model || bool(tiling.rows) ||
                               options.method == ReconstructionMethod::kLinear || bool(tiling.local_psfs);
  const int n = in.n;
  struct TileOutcome {
    Reconstruction rec;
    bool empty = false, resumed = false, cancelled = false;
    std::vector<double> ss, px;  // per frame: Σ residual² and pixel count over the core (misfit_by_tiles)
  };
  auto solve = [&](int k, TileOutcome* out) {
    const std::string path = checkpoint ? tiling_internal::TilePath(tiling.checkpoint_dir, k) : "";
    const TileWindow& t = ts.tiles[k];
    std::optional<ReconstructionProblem> p;
    std::vector<double> stored;  // the misfit a checkpoint kept: per frame Σ r², then per frame the pixels
    bool solved = false;
    // The tile's fingerprint: the run's and the window's own data (what the tile depends on).
    std::uint64_t tile_fingerprint = 0;
    if (checkpoint) {
      p = window_data(t);
      tile_fingerprint = tiling_internal::TileFingerprint(fingerprint, p->frames, p->weights);
    }
    if (checkpoint && tiling_internal::ReadTile(path, tile_fingerprint, k, &out->rec, &stored)) {
      out->resumed = true;
      out->empty = out->rec.summary.method.empty() && out->rec.summary.message == "no data";
      if (misfit_by_tiles && int(stored.size()) == 2 * n) {
        out->ss.assign(stored.begin(), stored.begin() + n);
        out->px.assign(stored.begin() + n, stored.end());
      }
    } else {
      if (p) p->model = tile_model(t);
      else p = window_problem(t);
      // The solver reports its residuals over the core: no second render of the tile for them below.
      if (misfit_by_tiles) p->residual_region = {t.core_y0 - t.y0, t.core_x0 - t.x0, t.core_rows, t.core_cols};
      if (!AnyWeighted(*p)) {  // nothing observed in the window: zeros, said in the summary
        out->empty = true;
        out->rec.image = Image::Zero(p->model->hr_shape().rows, p->model->hr_shape().cols);
        out->rec.summary.message = "no data";
      } else {
        out->rec = Reconstruct(*p, o);
        if (out->rec.summary.termination == Termination::kUserCancelled) {
          out->cancelled = true;
          return;
        }
      }
      solved = true;
    }
    if (misfit_by_tiles && !out->empty && out->ss.empty()) {
      // Per frame Σ r² and the weighted pixels over the core: from the solver's RMS there (each method's own
      // residual, as its whole-grid run reports), else (a method that reports none) from a render of the tile.
      const Index cy = t.core_y0 - t.y0, cx = t.core_x0 - t.x0;
      if (!p) p = window_data(t);
      const std::vector<double>& rms = out->rec.summary.frame_residual_rms;
      const bool from_solver = solved && int(rms.size()) == n;
      ImageStack predicted;
      if (!from_solver) {
        if (!p->model) p->model = tile_model(t);
        predicted = p->model->Render(out->rec.image);
      }
      out->ss.assign(n, 0.0);
      out->px.assign(n, 0.0);
      for (int i = 0; i < n; ++i) {
        for (Index y = cy; y < cy + t.core_rows; ++y)
          for (Index x = cx; x < cx + t.core_cols; ++x) {
            if (!p->weights.empty() && !(p->weights[i](y, x) > 0)) continue;
            out->px[i] += 1;
            if (from_solver) continue;
            const double d = p->frames[i](y, x) - predicted[i](y, x);
            out->ss[i] += d * d;
          }
        if (from_solver) out->ss[i] = rms[i] * rms[i] * out->px[i];
      }
    }
    if (solved && checkpoint) {
      std::vector<double> misfit = out->ss;
      misfit.insert(misfit.end(), out->px.begin(), out->px.end());
      tiling_internal::WriteTile(path, tile_fingerprint, k, out->rec, misfit);
    }
  };

  if (!tiling.only_tiles.empty()) {
    // Separate jobs: these tiles into the checkpoint folder, nothing blended.
    const std::vector<int>& ks = tiling.only_tiles;
    std::vector<TileOutcome> outcomes(ks.size());
    if (tiling.parallel_tiles) {
      ParallelFor(Index(ks.size()), [&](Index j) { solve(ks[j], &outcomes[j]); });
    } else {
      for (std::size_t j = 0; j < ks.size(); ++j) solve(ks[j], &outcomes[j]);
    }
    Reconstruction job;
    job.summary.method = ToString(options.method);
    job.summary.termination = Termination::kConverged;
    int resumed = 0;
    for (const TileOutcome& t : outcomes) {
      const Termination term = t.cancelled ? Termination::kUserCancelled : t.rec.summary.termination;
      ts.tile_terminations.push_back(term);
      if (Severity(term) > Severity(job.summary.termination)) job.summary.termination = term;
      job.summary.iterations += t.rec.summary.iterations;
      resumed += t.resumed;
    }
    ts.tiles_resumed = resumed;
    job.summary.message = "solved " + std::to_string(ks.size()) + " of " + std::to_string(count) +
                          " tiles into " + tiling.checkpoint_dir + " (" + std::to_string(resumed) + " already there)";
    job.summary.seconds = job.seconds_total =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    if (summary) *summary = std::move(ts);
    return job;
  }

  const int batch = tiling.parallel_tiles ? std::max(1, DefaultThreads()) : 1;
  const std::vector<int> last_row = LastTileRow(ts.tiles, ts.tiles_x, r, overlap, ts.tiles_y, hr.rows);
  RowBlend blend(hr, true);
  bool has_aux = false;
  std::string aux_name;
  Reconstruction out;
  out.image = tiling.rows ? Image() : Image::Zero(hr.rows, hr.cols);
  Image aux_whole;
  int emitted_rows = 0;  // tile rows whose final HR rows have been handed on
  auto emit = [&](Index y0, Index y1) {
    if (y1 <= y0) return;
    Image rows, aux_rows;
    blend.Take(y0, y1, &rows, &aux_rows);
    if (!has_aux) aux_rows = Image();
    if (tiling.rows) {
      tiling.rows(y0, rows, aux_rows);
    } else {
      out.image.middleRows(y0, y1 - y0) = rows;
      if (has_aux) {
        if (aux_whole.size() == 0) aux_whole = Image::Zero(hr.rows, hr.cols);
        aux_whole.middleRows(y0, y1 - y0) = aux_rows;
      }
    }
  };
  // Hands on every row whose last tile row is among the first `done_rows`, in runs of consecutive rows.
  auto emit_finished = [&](int done_rows) {
    for (; emitted_rows < done_rows; ++emitted_rows) {
      Index y = 0;
      while (y < hr.rows) {
        if (last_row[y] != emitted_rows) {
          ++y;
          continue;
        }
        Index e = y;
        while (e < hr.rows && last_row[e] == emitted_rows) ++e;
        emit(y, e);
        y = e;
      }
    }
  };

  // Every batch is reported (a tile takes seconds to minutes: no rate limit needed), so a caller can stop
  // after any batch.
  ProgressReporter reporter(options.progress, "tiles", count, "", 0.0);
  Reconstruction central_rec;
  std::vector<Termination> terminations(count, Termination::kConverged);
  std::vector<std::string> messages(count);
  std::vector<double> ss(n, 0.0), px(n, 0.0);
  int empties = 0, done = 0;
  bool cancelled = false;
  for (int b0 = 0; b0 < count && !cancelled; b0 += batch) {
    const int b1 = std::min(count, b0 + batch);
    if (tiling.await_tiles) tiling.await_tiles(b0, b1);
    std::vector<TileOutcome> outcomes(b1 - b0);
    if (tiling.parallel_tiles) {
      ParallelFor(b1 - b0, [&](Index j) { solve(b0 + int(j), &outcomes[j]); });
    } else {
      for (int j = 0; j < b1 - b0; ++j) solve(b0 + j, &outcomes[j]);
    }
    for (int j = 0; j < b1 - b0 && !cancelled; ++j) {
      const int k = b0 + j;
      TileOutcome& t = outcomes[j];
      if (t.cancelled) {
        cancelled = true;
        break;
      }
      if (k == 0 || (!has_aux && t.rec.aux.size() > 0)) {
        has_aux = has_aux || t.rec.aux.size() > 0;
        if (t.rec.aux.size() > 0) aux_name = t.rec.aux_name;
      }
      const TileWindow& tk = ts.tiles[k];
      const std::vector<double> wy =
          AxisWeight(tk.y0, tk.rows, tk.core_y0, tk.core_y0 + tk.core_rows, r, overlap, ts.tiles_y);
      const std::vector<double> wx =
          AxisWeight(tk.x0, tk.cols, tk.core_x0, tk.core_x0 + tk.core_cols, r, overlap, ts.tiles_x);
      const bool aux = t.rec.aux.size() == Index(wy.size() * wx.size());
      blend.Add(tk, r, wy, wx, t.rec.image, aux ? &t.rec.aux : nullptr);
      terminations[k] = t.rec.summary.termination;
      messages[k] = t.rec.summary.message;
      out.summary.iterations += t.rec.summary.iterations;
      empties += t.empty;
      ts.tiles_resumed += t.resumed;
      for (int i = 0; i < int(t.ss.size()); ++i) ss[i] += t.ss[i], px[i] += t.px[i];
      if (k == central) {
        central_rec = std::move(t.rec);
        central_rec.image = Image();
        central_rec.aux = Image();
      } else {
        t.rec = Reconstruction();
      }
      ++done;
      if ((k + 1) % ts.tiles_x == 0) emit_finished((k + 1) / ts.tiles_x);
    }
    if (!cancelled && !reporter.Report(done, std::numeric_limits<double>::quiet_NaN(), done == count))
      cancelled = done < count;
    if (!cancelled && tiling.stop && done < count && tiling.stop()) cancelled = true;
  }
  reporter.Finish(done, std::numeric_limits<double>::quiet_NaN());
  reporter.RethrowIfThrown();
  if (!tiling.rows) {
    // What is left (rows of tiles not solved when cancelled): as blended so far, 0 where nothing was added.
    for (Index y = 0; y < hr.rows;) {
      if (last_row[y] < emitted_rows) {
        ++y;
        continue;
      }
      Index e = y;
      while (e < hr.rows && last_row[e] >= emitted_rows) ++e;
      emit(y, e);
      y = e;
    }
  }

  const Reconstruction& c = central_rec;
  if (has_aux && !tiling.rows) {
    out.aux = aux_whole.size() ? aux_whole : Image::Zero(hr.rows, hr.cols);
    out.aux_name = aux_name;
  } else if (has_aux) {
    out.aux_name = aux_name;
  }
  out.regularisation = c.regularisation;
  out.effective_psf = c.effective_psf;
  out.noise_correlation = c.noise_correlation;
  out.leakage_spectrum = c.leakage_spectrum;
  out.linear = c.linear;
  out.summary.method = c.summary.method.empty() ? ToString(options.method) : c.summary.method;
  int worst = central;
  for (int k = 0; k < done; ++k)
    if (Severity(terminations[k]) > Severity(terminations[worst])) worst = k;
  ts.tile_terminations.assign(terminations.begin(), terminations.begin() + done);
  ts.regularisation = out.regularisation;
  out.summary.termination = cancelled ? Termination::kUserCancelled : terminations[worst];
  out.summary.message = "tiled: " + std::to_string(ts.tiles_y) + " x " + std::to_string(ts.tiles_x) +
                        " tiles of <= " + std::to_string(tiling.tile) + " camera px, overlap " +
                        std::to_string(overlap) + " (" + ts.overlap_rule + "); regularisation " +
                        ToString(out.regularisation) + " (" + ts.regularisation_source + ")";
  if (cancelled)
    out.summary.message += "; cancelled by the caller after " + std::to_string(done) + " of " +
                           std::to_string(count) + " tiles";
  if (empties > 0) out.summary.message += "; " + std::to_string(empties) + " tiles without data (zero)";
  if (checkpoint) out.summary.message += "; " + std::to_string(ts.tiles_resumed) + " tiles resumed";
  if (central < done) out.summary.message += "; central tile: " + messages[central];
  if (worst != central && worst < done)
    out.summary.message += "; worst tile " + std::to_string(worst) + " (" + ToString(terminations[worst]) +
                           "): " + messages[worst];
  if (misfit_by_tiles) {
    out.summary.frame_residual_rms.clear();
    for (int i = 0; i < n; ++i) out.summary.frame_residual_rms.push_back(px[i] > 0 ? std::sqrt(ss[i] / px[i]) : 0.0);
    out.summary.message += "; residuals are the tiles' over their cores";
  } else if (AllFinite(out.image)) {
    WeightedDataMisfit(*in.problem, out.image, &out.summary.frame_residual_rms);
  }
  if (!tiling.rows && !AllFinite(out.image) &&
      !(options.method == ReconstructionMethod::kDrizzle && std::isnan(options.drizzle.fill_value))) {
    out.image.setZero();
    out.summary.termination = Termination::kFailed;
    out.summary.message = "non-finite estimate discarded (image zeroed): " + out.summary.message;
  }
  out.summary.seconds = out.seconds_total =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  if (summary) *summary = std::move(ts);
  return out;
}

}  // namespace

Reconstruction ReconstructTiled(const ReconstructionProblem& problem, const ReconstructOptions& options,
                                const TilingOptions& tiling, TilingSummary* summary) {
  problem.Validate(kTilingFn);
  TiledInput in;
  in.lr = problem.model->lr_shape();
  in.hr = problem.model->hr_shape();
  in.r = problem.model->r();
  in.frames = &problem.frames;
  in.weights = &problem.weights;
  in.offsets = &problem.offsets;
  in.problem = &problem;
  in.n = problem.frame_count();
  return RunTiles(in, options, tiling, summary);
}

Reconstruction ReconstructTiled(const FieldData& field, const ReconstructOptions& options, const TilingOptions& tiling,
                                TilingSummary* summary) {
  field.Validate(kTilingFn);
  TiledInput in;
  in.lr = field.lr;
  in.hr = {field.lr.rows * field.r, field.lr.cols * field.r};
  in.r = field.r;
  in.frames = &field.frames;
  in.weights = &field.weights;
  in.offsets = &field.offsets;
  in.field = &field;
  in.n = field.frame_count();
  return RunTiles(in, options, tiling, summary);
}

}  // namespace aosr
