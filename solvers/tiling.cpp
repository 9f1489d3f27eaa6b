// Tiled reconstruction (tiling.hpp): the tile geometry, the raised-cosine partition of unity, the sub-problem of
// a tile, the one choice of regularisation for the whole field, and the blend.
#include "aosr/solvers/tiling.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <map>
#include <memory>
#include <utility>

#include "aosr/core/error.hpp"
#include "aosr/core/fft.hpp"
#include "aosr/core/parallel.hpp"
#include "aosr/solvers/padded_model.hpp"
#include "tile_checkpoint.hpp"

namespace aosr {
namespace {

constexpr const char* kTilingFn = "ReconstructTiled";

Index WrapIndex(Index a, Index n) { return ((a % n) + n) % n; }

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

// One axis of a tile's blending weight over its window (HR pixels j = 0 .. rows·r − 1 at field HR position
// (start·r + j), unwrapped). With one tile on the axis: 1. Otherwise the raised-cosine ramps of half-width
// h = P·r/2 centred on both core boundaries (the field is periodic: the first core's left boundary is the last
// core's right one). The falling ramp is f(t) = ½(1 + cos πt); the rising ramp of the neighbour at the same
// boundary is 1 − f(t) with the same t, so the pair sums to 1 up to one rounding.
std::vector<double> AxisWeight(Index start, Index rows, Index core0, Index core1, int r, int overlap, int tiles) {
  std::vector<double> w(rows * r, 0.0);
  if (tiles == 1) {
    std::fill(w.begin(), w.end(), 1.0);
    return w;
  }
  const double h = 0.5 * double(overlap) * r;
  const double lo = double(core0 * r), hi = double(core1 * r);
  for (Index j = 0; j < rows * r; ++j) {
    const double x = double(start * r + j) + 0.5;  // pixel centre, HR px
    double v;
    if (h == 0) {
      v = (x >= lo && x < hi) ? 1.0 : 0.0;
    } else if (x <= lo - h || x >= hi + h) {
      v = 0.0;
    } else if (x < lo + h) {
      const double t = (x - (lo - h)) / (2 * h);
      v = 1.0 - 0.5 * (1.0 + std::cos(kPi * t));  // rising: the complement of the left neighbour's fall
    } else if (x > hi - h) {
      const double t = (x - (hi - h)) / (2 * h);
      v = 0.5 * (1.0 + std::cos(kPi * t));
    } else {
      v = 1.0;
    }
    w[j] = v;
  }
  return w;
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
ReconstructionProblem CutProblem(const ReconstructionProblem& problem, const TileWindow& tile,
                                 std::shared_ptr<const MultiFrameModel> model) {
  const Shape lr = problem.model->lr_shape();
  auto cut = [&](const Image& a) {
    Image s(tile.rows, tile.cols);
    for (Index y = 0; y < tile.rows; ++y) {
      const Index fy = WrapIndex(tile.y0 + y, lr.rows);
      for (Index x = 0; x < tile.cols; ++x) s(y, x) = a(fy, WrapIndex(tile.x0 + x, lr.cols));
    }
    return s;
  };
  ReconstructionProblem p;
  p.model = std::move(model);
  for (const Image& f : problem.frames) p.frames.push_back(cut(f));
  for (const Image& w : problem.weights) p.weights.push_back(cut(w));
  p.offsets = problem.offsets;
  return p;
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

// The overlap rule's reach (camera px, before doubling) of the method's regulariser and support.
int RegulariserReach(const ReconstructionProblem& problem, ReconstructionMethod method) {
  switch (method) {
    case ReconstructionMethod::kTotalVariation:
    case ReconstructionMethod::kMap:
      return 2;
    case ReconstructionMethod::kTikhonov:
    case ReconstructionMethod::kLinear:
      return 3;
    default: {
      double off = 0;
      for (const FrameOffset& o : problem.offsets) off = std::max({off, std::abs(o.dy), std::abs(o.dx)});
      return 1 + int(std::ceil(off / problem.model->r()));
    }
  }
}

}  // namespace

bool FixRegularisation(const ReconstructionProblem& rep, ReconstructOptions* o) {
  switch (o->method) {
    case ReconstructionMethod::kTikhonov: {
      TikhonovOptions& t = o->tikhonov;
      if (t.lambda_rule == TikhonovLambdaRule::kFixed && t.prior != TikhonovPrior::kFitted) return false;
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
      if (o->linear.kappa > 0) return false;
      ReconstructOptions ro = *o;
      ro.linear.compute_noise = false;
      ro.progress = nullptr;
      const Reconstruction r = Reconstruct(rep, ro);
      o->linear.kappa = r.linear->kappa;
      if (o->linear.kind == TargetPsfKind::kAuto) {
        o->linear.kind = TargetPsfKind::kGaussian;
        o->linear.fwhm_hr_px = r.linear->target_fwhm_hr_px;
      }
      return true;
    }
    case ReconstructionMethod::kTotalVariation:
    case ReconstructionMethod::kMap:
      if (!o->auto_regularisation || o->fixed_automatic) return false;
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
  if (overlap < -1) return fail("overlap = " + std::to_string(overlap) + "; allowed: -1 (automatic) or >= 0");
  if (!(psf_tail > 0 && psf_tail < 1)) return fail("psf_tail = " + ToString(psf_tail) + "; allowed: (0, 1)");
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

Image TileBlendWeight(const TileWindow& tile, int r, int overlap, int tiles_y, int tiles_x) {
  const std::vector<double> wy =
      AxisWeight(tile.y0, tile.rows, tile.core_y0, tile.core_y0 + tile.core_rows, r, overlap, tiles_y);
  const std::vector<double> wx =
      AxisWeight(tile.x0, tile.cols, tile.core_x0, tile.core_x0 + tile.core_cols, r, overlap, tiles_x);
  Image w(tile.rows * r, tile.cols * r);
  for (Index y = 0; y < w.rows(); ++y)
    for (Index x = 0; x < w.cols(); ++x) w(y, x) = wy[y] * wx[x];
  return w;
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

int SuggestTileOverlap(const ReconstructionProblem& problem, const ReconstructOptions& options,
                       const TilingOptions& tiling, std::string* rule) {
  const bool uses_psf = options.method == ReconstructionMethod::kTikhonov ||
                        options.method == ReconstructionMethod::kLinear ||
                        options.method == ReconstructionMethod::kTotalVariation ||
                        options.method == ReconstructionMethod::kMap;
  const int psf = uses_psf ? PaddedModel::SuggestPadding(*problem.model, tiling.psf_tail) : 0;
  const int reg = RegulariserReach(problem, options.method);
  if (rule)
    *rule = "2 x (psf " + std::to_string(psf) + " + " + ToString(options.method) + " reach " +
            std::to_string(reg) + ")";
  return 2 * (psf + reg);
}

Reconstruction ReconstructTiled(const ReconstructionProblem& problem, const ReconstructOptions& options,
                                const TilingOptions& tiling, TilingSummary* summary) {
  const auto start = std::chrono::steady_clock::now();
  problem.Validate(kTilingFn);
  std::string why;
  if (!tiling.IsValid(&why)) throw InvalidArgument(std::string(kTilingFn) + ": tiling." + why);
  if (!tiling.checkpoint_dir.empty() && !std::filesystem::is_directory(tiling.checkpoint_dir))
    throw InvalidArgument(kTilingFn, "tiling.checkpoint_dir", tiling.checkpoint_dir, "an existing folder");
  const Shape lr = problem.model->lr_shape(), hr = problem.model->hr_shape();
  const int r = problem.model->r();

  // The overlap: given, or the rule capped to what the field allows.
  TilingSummary ts;
  int overlap = tiling.overlap;
  if (overlap >= 0) {
    ts.overlap_rule = "given";
  } else {
    overlap = SuggestTileOverlap(problem, options, tiling, &ts.overlap_rule);
    Index cap = overlap;
    for (const auto& [m, axis] : {std::pair<Index, int>{lr.rows, 0}, std::pair<Index, int>{lr.cols, 1}}) {
      (void)axis;
      const std::vector<Index> c = Cuts(m, tiling.tile);
      if (c.size() <= 2) continue;
      const auto [smallest, largest] = CoreRange(c);
      cap = std::min({cap, smallest, (m - largest) / 2});
    }
    if (cap < overlap) ts.overlap_rule += ", capped at " + std::to_string(cap) + " by the tile and field sizes";
    overlap = int(cap);
  }
  ts.overlap = overlap;
  ts.tile = tiling.tile;
  ts.tiles = MakeTiles(lr, tiling.tile, overlap, kTilingFn);
  ts.tiles_y = ts.tiles.back().ty + 1;
  ts.tiles_x = ts.tiles.back().tx + 1;
  const int count = int(ts.tiles.size());
  if (count == 1) {
    // One tile: the whole field, exactly as Reconstruct solves it.
    Reconstruction out = Reconstruct(problem, options);
    ts.regularisation = out.regularisation;
    ts.regularisation_source = "whole field (one tile)";
    ts.tile_terminations = {out.summary.termination};
    out.summary.message = "tiled: 1 tile (the whole field); " + out.summary.message;
    if (summary) *summary = std::move(ts);
    return out;
  }

  // Each tile's problem: its window of the data and its model (the caller's local PSFs, or the problem's
  // kernels cut to the window: one model per window shape, shared).
  const ImageStack kernels = tiling.local_psfs ? ImageStack{} : OriginKernels(*problem.model);
  std::map<std::pair<Index, Index>, std::shared_ptr<const MultiFrameModel>> shared_models;
  auto tile_problem = [&](const TileWindow& t) {
    const Shape window{t.rows * r, t.cols * r};
    if (tiling.local_psfs) return TileProblem(problem, t, tiling.local_psfs(t));
    return CutProblem(problem, t, shared_models.at({window.rows, window.cols}));
  };
  if (!tiling.local_psfs)
    for (const TileWindow& t : ts.tiles) {
      auto& m = shared_models[{t.rows * r, t.cols * r}];
      if (!m) m = CutModel(kernels, hr, {t.rows * r, t.cols * r}, r);
    }

  // One regularisation for the field, chosen on the central tile (or the whole field).
  const int central = (ts.tiles_y / 2) * ts.tiles_x + ts.tiles_x / 2;
  ReconstructOptions o = options;
  o.progress = nullptr;  // tiles may run concurrently; the callback need not be thread-safe
  {
    const bool whole = tiling.regularisation_from_whole_field;
    const bool chosen = whole ? FixRegularisation(problem, &o) : FixRegularisation(tile_problem(ts.tiles[central]), &o);
    ts.regularisation_source = chosen ? (whole ? "whole field" : "central tile") : "given";
  }

  // The tiles, in parallel or one after the other (each writes only its own slot), each read from the checkpoint
  // folder if a previous run finished it, else solved and written there.
  const bool checkpoint = !tiling.checkpoint_dir.empty();
  const std::uint64_t fingerprint =
      checkpoint ? tiling_internal::RunFingerprint(problem, o, tiling, overlap) : 0;
  std::vector<Reconstruction> rec(count);
  std::vector<char> empty(count, 0), resumed(count, 0);
  auto solve = [&](Index k) {
    const std::string path = checkpoint ? tiling_internal::TilePath(tiling.checkpoint_dir, int(k)) : "";
    if (checkpoint && tiling_internal::ReadTile(path, fingerprint, int(k), &rec[k])) {
      resumed[k] = 1;
      empty[k] = rec[k].summary.method.empty() && rec[k].summary.message == "no data";
      return;
    }
    const ReconstructionProblem p = tile_problem(ts.tiles[k]);
    if (!AnyWeighted(p)) {  // nothing observed in the window: zeros, said in the summary
      empty[k] = 1;
      rec[k].image = Image::Zero(p.model->hr_shape().rows, p.model->hr_shape().cols);
      rec[k].summary.message = "no data";
    } else {
      rec[k] = Reconstruct(p, o);
    }
    if (checkpoint) tiling_internal::WriteTile(path, fingerprint, int(k), rec[k]);
  };
  if (tiling.parallel_tiles) {
    ParallelFor(count, solve);
  } else {
    for (Index k = 0; k < count; ++k) solve(k);
  }

  // The blend Σ w_k x_k / Σ w_k, serial in tile order (the same bytes for any thread count).
  Image num = Image::Zero(hr.rows, hr.cols), den = Image::Zero(hr.rows, hr.cols);
  const Reconstruction& c = rec[central];
  const bool has_aux = c.aux.size() > 0;
  Image aux_num = has_aux ? Image::Zero(hr.rows, hr.cols) : Image();
  Image aux_den = has_aux ? Image::Zero(hr.rows, hr.cols) : Image();  // a tile without the map adds no weight
  for (int k = 0; k < count; ++k) {
    const TileWindow& t = ts.tiles[k];
    const Image w = TileBlendWeight(t, r, overlap, ts.tiles_y, ts.tiles_x);
    const bool aux = has_aux && rec[k].aux.size() == w.size();
    for (Index y = 0; y < w.rows(); ++y) {
      const Index fy = WrapIndex(t.y0 * r + y, hr.rows);
      for (Index x = 0; x < w.cols(); ++x) {
        const double wk = w(y, x);
        if (wk == 0) continue;
        const Index fx = WrapIndex(t.x0 * r + x, hr.cols);
        num(fy, fx) += wk * rec[k].image(y, x);
        den(fy, fx) += wk;
        if (aux) {
          aux_num(fy, fx) += wk * rec[k].aux(y, x);
          aux_den(fy, fx) += wk;
        }
      }
    }
  }

  Reconstruction out;
  out.image = num / den;
  if (has_aux) {
    out.aux = (aux_den > 0).select(aux_num / aux_den, 0.0);
    out.aux_name = c.aux_name;
  }
  out.regularisation = c.regularisation;
  out.effective_psf = c.effective_psf;
  out.noise_correlation = c.noise_correlation;
  out.leakage_spectrum = c.leakage_spectrum;
  out.linear = c.linear;
  out.summary.method = c.summary.method;
  int worst = central, empties = 0;
  for (int k = 0; k < count; ++k) {
    ts.tile_terminations.push_back(rec[k].summary.termination);
    out.summary.iterations += rec[k].summary.iterations;
    empties += empty[k];
    ts.tiles_resumed += resumed[k];
    if (Severity(rec[k].summary.termination) > Severity(rec[worst].summary.termination)) worst = k;
  }
  ts.regularisation = out.regularisation;
  out.summary.termination = rec[worst].summary.termination;
  out.summary.message = "tiled: " + std::to_string(ts.tiles_y) + " x " + std::to_string(ts.tiles_x) +
                        " tiles of <= " + std::to_string(tiling.tile) + " camera px, overlap " +
                        std::to_string(overlap) + " (" + ts.overlap_rule + "); regularisation " +
                        ToString(out.regularisation) + " (" + ts.regularisation_source + ")";
  if (empties > 0) out.summary.message += "; " + std::to_string(empties) + " tiles without data (zero)";
  if (checkpoint) out.summary.message += "; " + std::to_string(ts.tiles_resumed) + " tiles resumed";
  out.summary.message += "; central tile: " + c.summary.message;
  if (worst != central)
    out.summary.message += "; worst tile " + std::to_string(worst) + " (" +
                           ToString(rec[worst].summary.termination) + "): " + rec[worst].summary.message;
  if (AllFinite(out.image)) {
    WeightedDataMisfit(problem, out.image, &out.summary.frame_residual_rms);
  } else if (!(options.method == ReconstructionMethod::kDrizzle && std::isnan(options.drizzle.fill_value))) {
    out.image.setZero();
    out.summary.termination = Termination::kFailed;
    out.summary.message = "non-finite estimate discarded (image zeroed): " + out.summary.message;
  }
  out.summary.seconds = out.seconds_total =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  if (summary) *summary = std::move(ts);
  return out;
}

}  // namespace aosr
