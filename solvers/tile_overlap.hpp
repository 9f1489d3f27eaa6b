// Private to solvers/: what the tile engine's parts share. The window models cut from the whole grid's
// kernels (tiling.cpp) and the overlap rule (tile_overlap.cpp; tiling.hpp, "The overlap rule").
#pragma once

#include <memory>
#include <string>

#include "aosr/solvers/tiling.hpp"

namespace aosr::tiling_internal {

inline Index WrapIndex(Index a, Index n) { return ((a % n) + n) % n; }

// The whole-grid kernels of the model, origin at (0, 0) (periodic).
ImageStack OriginKernels(const MultiFrameModel& model);
// A model on the window's HR grid from origin-at-(0, 0) kernels of the whole grid (`whole`), cut to the window.
std::shared_ptr<const MultiFrameModel> CutModel(const ImageStack& kernels, Shape whole, Shape window, int r);
// The same from centred kernels (image.hpp: centre pixel K/2), by the same rule.
std::shared_ptr<const MultiFrameModel> CutModelFromCentred(const ImageStack& kernels, Shape window, int r);

// Whether the method's overlap is measured from its response: tikhonov and linear with their regularisation
// fixed.
bool OverlapIsMeasured(const ReconstructOptions& options);
// The largest overlap the measurement reads on a field of `lr` camera px (a third of its probe, <= 42).
int LargestMeasuredOverlap(Shape lr);
// The smallest overlap q in [p, limit] that MakeTiles accepts and that makes the HR side of every window
// (r × (core + 2q), on each axis cut into more than one tile) a product of 2, 3, 5 and 7, where FFTW is fast;
// p when none is. At r = 4, tiles of 512 and P = 42 the windows are 2384 HR px (2^4 · 149): one FFT pair took
// 0.49 s there against 0.24 s at 2400 (P = 44) on the project's 2-core VM, and a tile's solve is mostly FFTs.
int FftFriendlyOverlap(Shape lr, int tile, int r, int p, int limit);
// The overlap rule's P (before the caps) and, in *rule (may be null), how it was made. measure = false: the
// PSF-and-reach rule even where the reach could be measured.
int OverlapRule(const ReconstructionProblem& problem, const ReconstructOptions& options, const TilingOptions& tiling,
                std::string* rule, bool measure);
int OverlapRule(const FieldData& field, const ReconstructOptions& options, const TilingOptions& tiling,
                std::string* rule, bool measure);

}  // namespace aosr::tiling_internal
