// Tiled reconstruction: the HR output grid cut into overlapping tiles, each reconstructed by any method through
// the one entry point (reconstruct.hpp), blended into one image with no seam. The one tile engine that the
// whole-detector work (a grid too large for one solve) and the wide-field work (a PSF that changes across the
// field: each tile its own local PSFs) both build on.
//
// Geometry (camera pixels; HR pixels are r times finer). Along each axis the m camera pixels are cut into
// n = ceil(m / T) cores of at most T pixels, as equal as possible (the boundaries at round(k·m/n)). Tile (ty, tx)
// reconstructs the window of its core grown by the overlap P on each side: (core + 2P)² camera pixels, i.e.
// the frames' sub-windows, their weights (masks, bad pixels) and the same offsets, with the model PSFs (or the
// caller's local PSFs, TilingOptions::local_psfs). Windows that pass the field's edge wrap around, because the
// whole-grid solvers treat the field as periodic: a tiled run then approximates the whole-grid solution at the
// edges too. An axis with a single tile is not cut (its window is the whole axis, exactly periodic).
//
// Why an overlap: each tile's solver sees its window as periodic, so the window's edges carry an artefact (the
// data wrapped around, the prior's coupling cut) that decays into the window over the reach of the
// reconstruction: the PSF's extent (a pixel's data constrain the object within the PSF) plus the regulariser's
// coupling length. Only the inner part of a window is used.
//
// Blending (a partition of unity). Around each inner core boundary c (HR position c·r) the two tiles are mixed
// over a ramp of width P camera pixels centred on c: w_left = ½(1 + cos πt), w_right = 1 − w_left, t in (0, 1)
// across the ramp (raised cosine: continuous with a continuous slope, so no seam, and no tile's weight reaches
// the outer half of its overlap: every used pixel is at least P/2 from its window's edge). The 2-D weight is the
// product of the axis weights; the blended image is Σ w_k x_k / Σ w_k, so the weights sum to exactly 1 up to
// one rounding. Needs P <= every core (a ramp must not reach the next boundary).
//
// The overlap rule (TilingOptions::overlap = -1).
//   tikhonov and linear (linear estimators): P is measured, once their regularisation is fixed (below). The
//     response x of the method to a point source rendered through the model (its resolution kernel) is computed
//     on a periodic probe of the model's kernels (the field's camera side up to 128 px); tail(d) is Σ|x| beyond
//     Chebyshev distance d (camera px) over |Σx|. A tile's pixel at distance d from its window's edge misses the
//     sources beyond the edge and sees those wrapped in from the other side instead, each worth up to tail(d) of
//     the level, and it enters the blend with weight w_P(d) (0 up to P/2, 1 from 3P/2). With E(P) = 2 max_d
//     w_P(d) tail(d), P is the smallest overlap with 4 E(P) <= TilingOptions::tolerance (1e-6), at most a third
//     of the probe (42 camera px). On tiling_test's 288² scene (Gaussian PSFs) the tiled error was 1.5x E(P)
//     for Tikhonov and 1.4x for the linear output (noise and sources cut at the edges add to it), hence the
//     margin 4; the rule then gave P = 38 (error 9.2e-8 of the peak) and P = 25 (2.5e-7). E(P) is far above
//     the truth for kernels that ring (an AO PSF's sharp MTF cut-off counts every ring with one sign: 2e-3 at
//     42 camera px against 2.1e-7 measured, bench/results/whole_detector.md); the rule then takes the probe's
//     largest overlap, and says so. Why measured: these kernels decay at a rate set by the PSF, the sampling
//     and λ or κ (bench/results/kernel_reach.md), so a fixed reach was too short for 1e-6 (P = 12 gave 1e-3 on
//     the test's scene). With a regularisation still to choose, the tiles of that choice (the central-tile
//     source) are those of the rule below; then P is measured.
//   the other methods: P = psf_reach + regulariser_reach (camera px), where
//     psf_reach = PaddedModel::SuggestPadding(model, psf_tail): the Chebyshev radius holding all but psf_tail
//               (1e-4) of the model PSFs' energy Σh², in camera px, rounded up (the largest over the frames;
//               the problem's model PSFs, or with local PSFs those at the field's centre);
//     regulariser_reach = 2 for tv and map (TV couples neighbours; its staircase settles within a few pixels),
//               3 for tikhonov and linear before their regularisation is fixed, 1 for shift-add and drizzle
//               (their drops reach one pixel, plus the offsets: ceil(max |offset| / r) more);
//     then doubled (the ramp uses the inner half of the overlap, see Blending).
//   tiles with local PSFs (TilingOptions::local_psfs, a field-varying model): psf_reach + regulariser_reach for
//     every method, not doubled. A tile's PSF is right only near its centre, so a wider window adds model error
//     faster than it removes truncation error. Against the exact space-variant operator on the wide scene
//     (bench/results/wide_field.md; Tikhonov at one λ, RMS of tiles − operator over the peak), tiles of 64
//     camera px with overlaps 8, 11, 16, 22 and 43 gave 2.33, 2.30, 2.30, 2.43 and 3.43e-4, and tiles of 128
//     with 11, 16 and 22 gave 3.82, 3.79 and 3.82e-4; the rule gives 11 there (raised to 13 for FFT sizes),
//     and its windows hold 1.9x the field's pixels instead of 2.9x.
// Either way P is capped so that P <= every core and the window fits in the field, and at max_overlap (a memory
// plan's); an automatic P is then raised by up to a quarter, within those caps, to the first overlap whose
// windows' HR sides are products of 2, 3, 5 and 7, where FFTW is fast (at r = 4 and tiles of 512, P = 42 gave
// windows of 2384 = 2^4 · 149 HR px and one FFT pair 0.49 s; P = 44 gives 2400 and 0.24 s). The measured errors
// against the whole-grid solution are in tests/solvers/tiling_test.cpp; give a larger overlap where more accuracy
// is needed.
//
// One regularisation for the whole field (what a user expects: the same λ or TV weight everywhere, so the
// image's resolution and noise do not change from tile to tile). The method's automatic choices are made
// once on the representative problem (the whole field, by default; or the central tile's window with its PSFs,
// see TilingOptions::regularisation_from_whole_field), then fixed for every tile:
//   tikhonov  λ of the rule (GCV, L-curve, UPRE, discrepancy, Wiener; a fitted prior's spectrum too) -> kFixed;
//   linear    κ (the leakage bound's) and, for kAuto, the target's FWHM -> TargetPsfOptions::kappa, kGaussian;
//   tv, map   the automatic rule's pilot λ, μ and contrast (ReconstructOptions::fixed_automatic); each tile
//             still runs its pilot (at that λ) for its warm start.
// A fixed λ, κ, μ given by the caller is used as given. A tile's own statistics never change it.
//
// Determinism: tiles are solved in parallel (ParallelFor over tiles, each solve then serial inside) or one after
// the other (TilingOptions::parallel_tiles = false; each solve parallel inside); blending is serial in tile order.
// The bytes are the same for any thread count either way.
//
// Second maps and the linear method's kernels: aux maps (posterior std, noise std, Drizzle weight) are blended
// with the same weights (a std map blended linearly: exact where tiles agree, an approximation in the ramps);
// effective_psf, noise_correlation, leakage_spectrum (on the tile's grid) and the linear summary are the
// central tile's.
//
// A whole detector (issue 32). A field too large for one solve is given as FieldData: the frames, weights and
// offsets of the whole field and each frame's PSF as a small centred kernel, with no whole-grid model (the
// model of an 8192² HR grid alone holds N half spectra of 0.5 GiB each). Each tile's model is built from the
// kernels on its window (kernels larger than the window are cut to it, as the whole-grid kernels are above).
// What it costs in memory:
//   * the tiles run in batches (one tile per thread when parallel_tiles, else one at a time); a batch's
//     results are blended in tile order, then dropped;
//   * the blend keeps only the output rows that a tile still to come touches: the band of one tile row (its
//     window, r·(core + 2P) HR rows) plus, because windows wrap around the field, the first tile row's ramp
//     into the field's last rows and the last tile row's ramp into its first rows, which are complete only at
//     the end. Finished rows go to TilingOptions::rows (a FITS file written by rows, for example) and are
//     freed; without a sink they are copied into the result's image.
// So the peak is the data (frames and weights), the batch's solves (EstimateSolveBytes) and about two tile
// rows of output, independent of the field's size. The bytes are those of the same tiling blended whole.
//
// Progress and cancellation: with ReconstructOptions::progress set, the engine reports the stage "tiles" after
// each batch (iteration = tiles done, total = tiles) from the calling thread, and stops before the next batch
// when the callback returns false (Termination::kUserCancelled; the finished tiles are checkpointed when
// checkpoint_dir is set, so a rerun resumes). TilingOptions::stop, safe to call from any thread, is read by the
// tiles' own solvers between iterations, so a tile in progress stops too (its result is discarded, never
// blended or checkpointed). The tiles' solvers report nothing else (they may run concurrently).
#pragma once

#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "aosr/solvers/reconstruct.hpp"

namespace aosr {

// One tile: its core (the part of the output it owns, before blending) and its window (what it reconstructs),
// in camera pixels of the field. The window may start below 0 or end past the field: it wraps around.
struct TileWindow {
  int index = 0;          // row-major: ty · tiles_x + tx
  int ty = 0, tx = 0;     // position in the tile grid
  Index core_y0 = 0, core_x0 = 0, core_rows = 0, core_cols = 0;
  Index y0 = 0, x0 = 0, rows = 0, cols = 0;
};

// Window models by HR shape (TilingOptions::model_store).
struct TileModelStore {
  std::mutex mutex;
  std::map<std::pair<Index, Index>, std::shared_ptr<const MultiFrameModel>> models;
};

struct TilingOptions {
  // T: the largest core side in camera pixels (>= 1). Tiles larger than the field leave that axis uncut.
  int tile = 0;
  // P: camera pixels added on each side of a core (>= 0); -1: the rule at the top of the file.
  int overlap = -1;
  // The PSF tail left out of the overlap rule's PSF reach (energy fraction), in (0, 1).
  double psf_tail = 1e-4;
  // The measured overlap rule's bound on the tiled error of tikhonov and linear, a fraction of a pixel's
  // response (see "The overlap rule"), in (0, 1).
  double tolerance = 1e-6;
  // The largest automatic overlap (camera px; 0: no bound): a memory plan's (FitTilingToMemory), which sized the
  // tiles for it before the regularisation, and with it the measured reach, was known.
  int max_overlap = 0;
  // Choose the regularisation on the whole field (default) or on the central tile. The whole field costs one
  // whole-grid solve (tikhonov's λ rules, the linear method's κ; tv and map their pilot) but is right: measured
  // on tiling_test's scene (3 x 3 tiles of 32 camera px), GCV on the central tile's window picked λ = 3e-10
  // against the whole field's 7e-3 (its wrapped edges look like detail to GCV), seven decades too small. Use
  // the central tile only where one whole-grid solve does not fit, and check its λ.
  bool regularisation_from_whole_field = true;
  // Solve tiles in parallel (each solve serial inside) or one after the other (each solve parallel inside).
  bool parallel_tiles = true;
  // The hook for field-varying PSFs: if set, called once per tile (and for the representative tile) with its
  // window; returns that tile's model PSFs, one per frame, centred kernels at HR sampling (image.hpp layout),
  // each fitting in the window's HR grid. Empty: the problem's model PSFs, cut to the window. Called from the
  // tile's thread, so concurrently when parallel_tiles: it must be safe to call so.
  std::function<ImageStack(const TileWindow&)> local_psfs;
  // Resuming: a folder (which must exist) where each finished tile is written (tile_<index>.bin, atomically)
  // and where tiles a previous run of the same problem left are read instead of solved, so that a killed run
  // continues and the final bytes are those of an uninterrupted run. The files carry a fingerprint of the run
  // (the data, the model, the tile geometry, the method's options with the regularisation fixed, and
  // checkpoint_key); another run's tile is refused with InvalidArgument, never mixed in. Empty: none.
  std::string checkpoint_dir;
  // What else the fingerprint should cover (the caller's description of its local PSFs or options the
  // fingerprint does not list; the CLI gives its arguments).
  std::string checkpoint_key;
  // The representative problem of the regularisation when regularisation_from_whole_field: 0 the whole field;
  // W > 0 the central W x W camera px of the field (the whole axis where the field is smaller), solved as
  // one periodic window. For a field whose whole-grid solve does not fit in memory (ChooseTiling picks it), and
  // for a field model (psf_field_model.hpp: at most kFieldRegularisationWindow). With local_psfs the window, the
  // whole field included, takes the hook's PSFs at its centre, not the whole model's.
  int regularisation_window = 0;
  // Where finished output rows go (see "A whole detector" above): called from the calling thread, rows in
  // increasing order within each call, every HR row exactly once. `aux_rows` is empty when the method has no
  // second map. With a sink the result's image and aux are left empty. Empty: the result holds the image.
  std::function<void(Index hr_row0, const Image& rows, const Image& aux_rows)> rows;
  // Asks the tiles in progress to stop (see "Progress and cancellation"); safe to call from any thread.
  std::function<bool()> stop;
  // The tiles as separate jobs (aosr.distributed.reconstruct_tiles: any process may solve any tile):
  //  * plan_only: stop once the overlap, the tiles and the regularisation are fixed; the summary holds them
  //    (TilingSummary::options), the result no image;
  //  * only_tiles: solve just these tiles (indices into the summary's tiles) into checkpoint_dir, which is
  //    required, and blend nothing (the result has no image). With the options a plan fixed, a later run of
  //    the whole tiling with the same checkpoint_dir resumes every tile: the bytes of one serial run.
  bool plan_only = false;
  std::vector<int> only_tiles;
  //  * await_tiles: the blend of tiles other processes are still solving (aosr.distributed): called from the
  //    calling thread before tiles [first, last) are taken (read from checkpoint_dir, or solved if missing), so
  //    that the caller can wait there for those jobs and the blend runs beside the rest. An exception it throws
  //    ends the run.
  std::function<void(int first, int last)> await_tiles;
  // Jobs of one field in one process (only_tiles, a call per tile): window models kept across the calls, so that
  // tiles of one shape share a model as they do in one run. The caller keeps one store per field (same kernels,
  // r and model options). Empty: the models live for one call.
  std::shared_ptr<TileModelStore> model_store;

  bool IsValid(std::string* why) const;
};

struct TilingSummary {
  int tiles_y = 0, tiles_x = 0;
  int tile = 0;                      // T used (camera px)
  int overlap = 0;                   // P used (camera px)
  std::string overlap_rule;          // "given" or how the rule made it, e.g. "psf 3 + regulariser 3, x2"
  double regularisation = 0;         // the λ / κ / μ every tile used (Reconstruction::regularisation)
  std::string regularisation_source; // "given", "central tile" or "whole field"
  std::vector<TileWindow> tiles;
  std::vector<Termination> tile_terminations;
  int tiles_resumed = 0;             // read from checkpoint_dir instead of solved
  ReconstructOptions options;        // what every tile is solved with: the caller's, the regularisation fixed
};

// The tiles of an m_rows x m_cols camera field (core and window rule above). InvalidArgument (naming
// `function`) unless tile >= 1, overlap >= 0, overlap <= every core of a cut axis, and the window fits in the field.
std::vector<TileWindow> MakeTiles(Shape lr, int tile, int overlap, const char* function = "MakeTiles");

// The blending weight of `tile` over its window's HR grid (r HR px per camera px): the product of the axis
// ramps above; 0 outside [core − P/2, core + P/2), 1 inside the core away from the ramps.
Image TileBlendWeight(const TileWindow& tile, int r, int overlap, int tiles_y, int tiles_x);

// The sub-problem of one tile: the frames', weights' windows (wrapped), the offsets, and a model on the
// window's HR grid from `psfs` (centred kernels) or, if empty, from the problem's model (its kernels cut to
// the window: entries beyond half the window are dropped).
ReconstructionProblem TileProblem(const ReconstructionProblem& problem, const TileWindow& tile,
                                  const ImageStack& psfs = {});

// The overlap rule's P for this problem and method (before the cap), from the problem's model PSFs (also when
// TilingOptions::local_psfs is set: give the overlap explicitly if the local PSFs are wider); *rule says how.
int SuggestTileOverlap(const ReconstructionProblem& problem, const ReconstructOptions& options,
                       const TilingOptions& tiling, std::string* rule = nullptr);

// The method's automatic choices (λ, κ and the target's width, TV's and MAP's pilot), made once on `rep` and
// fixed in *options (the top of the file, "One regularisation for the whole field"): what every tile uses, and
// what a whole-field solve of another model of the same frames can use to match it. Returns whether anything
// was chosen (false: the options' values are used as given).
bool FixRegularisation(const ReconstructionProblem& rep, ReconstructOptions* options);
// Whether the options leave nothing for FixRegularisation to choose.
bool RegularisationIsFixed(const ReconstructOptions& options);

// A field without a whole-grid model (see "A whole detector" above). frames, weights and offsets as in
// ReconstructionProblem (problem.hpp) on the camera grid `lr`; kernels: one per frame, centred (image.hpp
// layout), at HR sampling, of positive sum (used as given, as MultiFrameModel::FromKernels does).
struct FieldData {
  Shape lr;
  int r = 0;
  ImageStack frames, weights;
  std::vector<FrameOffset> offsets;
  ImageStack kernels;
  // The frames read by sections instead of held (`frames` and `weights` then empty): a job that solves one tile
  // of a dataset on shared storage reads only its window (aosr.distributed.reconstruct_tiles). Read(y0, x0, rows,
  // cols) returns the frames and weights of that window (camera px, inside the field), with the values the held
  // frames would have there; it may be called from several tiles at once. (An edge tile's window, which wraps
  // around the periodic field, is read in up to four sections.)
  struct Sections {
    int frames = 0;
    bool uniform_weights = false;  // every weight one positive value (or none): EstimateTiledBytes' rule
    std::function<void(Index y0, Index x0, Index rows, Index cols, ImageStack* frames, ImageStack* weights)> read;
  };
  std::shared_ptr<const Sections> sections;
  int frame_count() const { return sections ? sections->frames : int(frames.size()); }
  // InvalidArgument naming `function` unless the shapes and counts agree (the pixels are checked per tile).
  void Validate(const std::string& function) const;
};

// The memory a tiled run of a field holds at its peak (see "A whole detector"): the data, `concurrent` tile
// solves of windows (tile + 2 overlap)² and two tile rows of output (with the second map when `aux`).
double EstimateTiledBytes(const FieldData& field, ReconstructionMethod method, int tile, int overlap,
                          int concurrent, bool aux);

// The representative window of the regularisation under a memory limit: the largest of 512, 384, 256, 192,
// 128, 96, 64, 48, 32 camera px whose solve fits next to the data (0 when that is the whole field; 32 when
// none fits, and the solve's own memory check then says so).
int ChooseRegularisationWindow(const FieldData& field, ReconstructionMethod method, double limit_bytes);

// The tiling for a field under a memory limit `limit_bytes` (core/memory.hpp): the largest tile from
// 512, 384, 256, 192, 128, 96, 64, 48, 32, 24, 16 camera px (none below the overlap, the ramp's width) whose
// run fits (tiles in parallel on `threads` threads if that fits, else one at a time), with the overlap
// `overlap` (camera px, >= 0) and the regularisation on ChooseRegularisationWindow's window. ResourceError
// when not even the smallest fits.
TilingOptions ChooseTiling(const FieldData& field, ReconstructionMethod method, int overlap, int threads,
                           double limit_bytes, bool aux);

// The overlap rule's P for a FieldData (its kernels' reach and the method's).
int SuggestTileOverlap(const FieldData& field, const ReconstructOptions& options, const TilingOptions& tiling,
                       std::string* rule = nullptr);

// Completes *tiling for a FieldData run under a memory limit, as `aosr reconstruct` and aosr.reconstruct do when
// the whole grid does not fit: the overlap by SuggestTileOverlap unless set (>= 0); unless a tile is set (> 0),
// ChooseTiling's tile and whether tiles run in parallel (on DefaultThreads()); and always ChooseRegularisationWindow's
// window. ResourceError as ChooseTiling's.
void FitTilingToMemory(const FieldData& field, const ReconstructOptions& options, double limit_bytes,
                       TilingOptions* tiling);

// Reconstruct a FieldData by tiles (tiling.tile >= 1), as the overload below does a problem. The summary's
// frame_residual_rms is that of each tile's solution over its core (the blended image is never held whole), as
// each method reports it (ReconstructionProblem::residual_region; the linear output's is its ridge solution's).
Reconstruction ReconstructTiled(const FieldData& field, const ReconstructOptions& options, const TilingOptions& tiling,
                                TilingSummary* summary = nullptr);

// Reconstruct `problem` by tiles (see the top of the file). The result is a Reconstruction of the whole field
// as Reconstruct returns it: image (and aux) on the whole HR grid; summary with the worst tile's termination,
// the summed iterations, the whole field's per-frame residual RMS (the linear output's: the tiles' ridge
// solutions' over their cores) and a message saying how it was tiled. Validates like Reconstruct, plus the tiling (InvalidArgument naming "ReconstructTiled" and the field).
Reconstruction ReconstructTiled(const ReconstructionProblem& problem, const ReconstructOptions& options,
                                const TilingOptions& tiling, TilingSummary* summary = nullptr);

}  // namespace aosr
