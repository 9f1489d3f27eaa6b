// Reconstructing through a PSF that changes across the field (issue 31): the field-varying model of a dataset
// (scene/dataset.hpp, Dataset::psf_field; core/psf_field.hpp) given to the model-based reconstructors.
//
// Approach: overlapping tiles with local PSFs (piecewise-constant PSFs blended smoothly, Nagy & O'Leary 1998).
// The field is cut into tiles (solvers/tiling.hpp); each tile is reconstructed by the method's own solver, with
// the frames' PSFs interpolated bilinearly at the centre of the tile's core, and the tiles are blended with
// the tile engine's raised-cosine partition of unity. Every method keeps its Fourier-domain speed inside a tile
// (one FFT solve per tile instead of one for the field), and the regularisation is chosen once, on the field's
// central kFieldRegularisationWindow² camera px with the PSFs of the field's centre (tiling.hpp: one λ for the
// field, so resolution and noise do not jump from tile to tile). The linear output's target PSF is the same in
// every tile: the uniformity that makes it useful for photometry (IMCOM's). Each tile reports its residual over
// its core, through its own PSFs.
//
// The approximation: inside a tile the PSF is taken as constant, the one at the core's centre. Its error grows
// with the PSF's change across a tile, so tiles should be a fraction of the field grid's spacing
// (SuggestFieldTile); the blending ramps make the model continuous across tile boundaries.
//
// The reference: one space-variant operator over the whole field (DatasetPsfField::kOperator; MultiFrameModel::
// WithPsfField: y_i = D_r Σ_k H_{i,k}(w_k ⊙ x), exact for the interpolated PSF, exact adjoint), solved by the
// methods' operator paths: Tikhonov by PCG preconditioned with the Fourier inverse of the centre's model, TV
// with its CG x-update, MAP as it is. It costs K times the operator applications of one PSF (K field points)
// and gives up the per-frequency solve; the linear method, a per-frequency design, has no operator form and
// refuses it. bench/results/wide_field.md compares the two.
#pragma once

#include <functional>

#include "aosr/core/psf_field.hpp"
#include "aosr/solvers/dataset_problem.hpp"
#include "aosr/solvers/tiling.hpp"

namespace aosr {

// The tile engine's local_psfs hook (TilingOptions::local_psfs) for a field model: tile → each frame's PSF
// interpolated at the centre of the tile's core, ((core_y0 + core_rows / 2) r − ½, likewise x) in HR pixels of
// the field. `psfs[k][i]`: node k's PSF of frame i (all of one shape, centred). Safe to call concurrently.
// The kernels are not cut: the tile engine fits them to the window.
std::function<ImageStack(const TileWindow&)> FieldTilePsfs(PsfFieldGrid grid, std::vector<ImageStack> psfs, int r);

// The side (camera px) of the central window on which a field model's regularisation is chosen (the whole field
// where it is smaller; TilingOptions::regularisation_window, a memory plan's smaller window kept). The whole
// field would cost one whole-grid solve of its own, more than the tiles themselves (a field run cost 2.6x the
// single-PSF run with it, bench/results/wide_field.md). GCV's λ scatters by about ±20 % with the window it sees,
// and that scatter sets the size: on the 512² wide scene (Tikhonov, tiles of 64) the central windows of 500,
// 384, 320, 256 and 192 camera px chose λ = 3.46, 3.70, 4.56, 3.25 and 4.34e-6 (the whole field 3.86e-6; the
// rings' PSNR within 0.12 dB of its), 128 chose 13.9e-6. 256 is the smallest window inside that scatter,
// with a margin.
constexpr int kFieldRegularisationWindow = 256;
// The window a field model's regularisation is chosen on, given another rule's (0: the whole field): the
// smaller of the two.
inline int FieldRegularisationWindow(int window) {
  return window == 0 || window > kFieldRegularisationWindow ? kFieldRegularisationWindow : window;
}

// The default tile (camera px) for a field model: half the grid's node spacing (so that a tile's PSF is never
// more than a quarter spacing from where it applies), at least 16 camera px, and the whole axis when the grid
// has one node along it. `lr`: the camera frame.
int SuggestFieldTile(const PsfFieldGrid& grid, int r, Shape lr);

// Completes *tiling for a dataset run without a whole-grid model (DatasetProblem::field) under limit_bytes, as
// `aosr reconstruct`, aosr.reconstruct and aosr.distributed plan it. Without a field model: FitTilingToMemory.
// With one: its own tile (tiling.tile, or SuggestFieldTile when 0), but never larger than the tiles that fit
// (FitTilingToMemory's choice, whose overlap plan and parallelism then come with it), and tiles run one at a time
// when the field's tiles would not fit side by side; the regularisation on FieldRegularisationWindow of the
// memory plan's window. ResourceError (ChooseTiling's) when not even the smallest tile fits.
void FitDatasetTilingToMemory(const DatasetProblem& problem, const ReconstructOptions& options, double limit_bytes,
                              TilingOptions* tiling);

// The one entry point of a dataset reconstruction, for the CLI and Python alike: with a field model
// (DatasetProblem::psf_field) by tiles with local PSFs (tiling.tile 0: SuggestFieldTile), or with the
// space-variant operator (the regularisation the tiles' plan fixes, so that it solves the tiles' problem
// exactly; tiling.tile must be 0); without one, tiled when tiling.tile > 0, else the whole grid (Reconstruct). A problem
// without a whole-grid model (DatasetProblem::field) is always tiled (tiling.tile >= 1 unless a field model
// suggests it). `summary` (may be null) is filled when tiled.
Reconstruction ReconstructDataset(const DatasetProblem& problem, const ReconstructOptions& options,
                                  TilingOptions tiling = {}, TilingSummary* summary = nullptr);

}  // namespace aosr
