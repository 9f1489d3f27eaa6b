#include "aosr/solvers/psf_field_model.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>
#include <string>
#include <utility>

#include "aosr/core/error.hpp"
#include "aosr/core/parallel.hpp"

namespace aosr {

std::function<ImageStack(const TileWindow&)> FieldTilePsfs(PsfFieldGrid grid, std::vector<ImageStack> psfs, int r) {
  if (grid.empty() || int(psfs.size()) != grid.nodes())
    throw InvalidArgument("FieldTilePsfs", "psfs", std::to_string(psfs.size()) + " nodes",
                          std::to_string(grid.nodes()) + " (one stack per node of the grid)");
  if (r < 1) throw InvalidArgument("FieldTilePsfs", "r", std::to_string(r), ">= 1");
  const std::size_t frames = psfs.front().size();
  for (const ImageStack& node : psfs)
    if (node.size() != frames || frames == 0)
      throw InvalidArgument("FieldTilePsfs", "psfs", std::to_string(node.size()) + " frames at a node",
                            "the same number (>= 1) at every node");
  // Shared and immutable: the hook is called from the tiles' threads.
  auto by_frame = std::make_shared<std::vector<ImageStack>>(frames);
  for (std::size_t i = 0; i < frames; ++i)
    for (const ImageStack& node : psfs) (*by_frame)[i].push_back(node[i]);
  auto g = std::make_shared<const PsfFieldGrid>(std::move(grid));
  return [g, by_frame, r](const TileWindow& t) {
    // The core's centre in HR pixels of the field: camera pixel c covers HR c·r .. c·r + r − 1.
    const double y = (double(t.core_y0) + 0.5 * double(t.core_rows)) * r - 0.5;
    const double x = (double(t.core_x0) + 0.5 * double(t.core_cols)) * r - 0.5;
    ImageStack out;
    out.reserve(by_frame->size());
    for (const ImageStack& frame : *by_frame) out.push_back(g->Interpolate(frame, y, x));
    return out;
  };
}

int SuggestFieldTile(const PsfFieldGrid& grid, int r, Shape lr) {
  const std::array<double, 2> spacing = grid.Spacing();
  auto axis = [&](double s, Index side) {
    if (s <= 0.0) return int(side);  // one node along the axis: the PSF does not vary along it
    return std::max(16, int(std::ceil(0.5 * s / double(r))));
  };
  return std::min(axis(spacing[0], lr.rows), axis(spacing[1], lr.cols));
}

namespace {

// The tiles of a field model: local PSFs, the default tile and the regularisation's central window, and the
// nodes' PSFs in the checkpoint fingerprint.
TilingOptions FieldTiling(const DatasetProblem& problem, TilingOptions tiling) {
  const int r = problem.field ? problem.field->r : problem.problem.model->r();
  const Shape lr = problem.field ? problem.field->lr : problem.problem.model->lr_shape();
  if (tiling.tile == 0) tiling.tile = SuggestFieldTile(problem.psf_field->grid, r, lr);
  tiling.local_psfs = FieldTilePsfs(problem.psf_field->grid, problem.psf_field->psfs, r);
  if (tiling.regularisation_from_whole_field)
    tiling.regularisation_window = FieldRegularisationWindow(tiling.regularisation_window);
  // The checkpoint fingerprint covers the whole field's model; the nodes' PSFs enter through this checksum.
  double checksum = 0.0;
  for (std::size_t k = 0; k < problem.psf_field->psfs.size(); ++k)
    for (std::size_t i = 0; i < problem.psf_field->psfs[k].size(); ++i) {
      const Image& p = problem.psf_field->psfs[k][i];
      for (Index j = 0; j < p.size(); ++j) checksum += p.data()[j] * double(1 + j % 97) * double(k + 1) * double(i + 1);
    }
  char text[64];
  std::snprintf(text, sizeof text, "|psf_field tiles %dx%d %.17g", problem.psf_field->grid.ny(),
                problem.psf_field->grid.nx(), checksum);
  tiling.checkpoint_key += text;
  return tiling;
}

}  // namespace

void FitDatasetTilingToMemory(const DatasetProblem& problem, const ReconstructOptions& options, double limit_bytes,
                              TilingOptions* tiling) {
  if (!problem.field)
    throw InvalidArgument("FitDatasetTilingToMemory", "problem.field", "none",
                          "a dataset problem without a whole-grid model (DatasetProblemOptions::whole_grid_model false)");
  const FieldData& field = *problem.field;
  if (!problem.psf_field) {
    FitTilingToMemory(field, options, limit_bytes, tiling);
    return;
  }
  const int window = ChooseRegularisationWindow(field, options.method, limit_bytes);
  if (tiling->tile == 0) {
    // The tiles that fit (ResourceError when none does). The field's own tiles (half the node spacing) are
    // usually smaller; a coarse grid over a large detector asks for larger ones than the memory allows.
    TilingOptions fit = *tiling;
    FitTilingToMemory(field, options, limit_bytes, &fit);
    const int own = SuggestFieldTile(problem.psf_field->grid, field.r, field.lr);
    if (fit.tile < own) {
      *tiling = fit;
    } else {
      // Smaller tiles than the plan's: side by side where the plan's overlap lets them fit (the bytes do not
      // depend on it, only the peak memory).
      const bool aux = options.method == ReconstructionMethod::kTikhonov && options.tikhonov.compute_std;
      const int overlap = fit.overlap >= 0 ? fit.overlap : std::max(fit.max_overlap, 0);
      tiling->parallel_tiles =
          tiling->parallel_tiles &&
          EstimateTiledBytes(field, options.method, own, std::min(overlap, own), DefaultThreads(), aux) <= limit_bytes;
    }
  }
  tiling->regularisation_window = FieldRegularisationWindow(window);
}

Reconstruction ReconstructDataset(const DatasetProblem& problem, const ReconstructOptions& options,
                                  TilingOptions tiling, TilingSummary* summary) {
  if (problem.psf_field && problem.psf_field->approach == DatasetPsfField::kOperator) {
    if (tiling.tile > 0)
      throw InvalidArgument("ReconstructDataset", "tiling.tile", std::to_string(tiling.tile),
                            "0 with psf_field operator (one space-variant solve over the whole field)");
    // The regularisation the tiles would use (their plan: the central window with the centre's local PSFs),
    // then one solve of the space-variant operator: the reference solves the tiles' problem exactly.
    TilingOptions plan = FieldTiling(problem, tiling);
    plan.plan_only = true;
    plan.checkpoint_dir.clear();
    TilingSummary planned;
    ReconstructTiled(problem.problem, options, plan, &planned);
    ReconstructOptions o = planned.options;
    o.progress = options.progress;
    return Reconstruct(problem.problem, o);
  }
  if (problem.psf_field) {
    tiling = FieldTiling(problem, std::move(tiling));
    if (problem.field) return ReconstructTiled(*problem.field, options, tiling, summary);
    return ReconstructTiled(problem.problem, options, tiling, summary);
  }
  if (problem.field) {
    if (tiling.tile <= 0)
      throw InvalidArgument("ReconstructDataset", "tiling.tile", std::to_string(tiling.tile),
                            ">= 1 for a problem without a whole-grid model (ChooseTiling picks one)");
    return ReconstructTiled(*problem.field, options, tiling, summary);
  }
  if (tiling.tile > 0) return ReconstructTiled(problem.problem, options, tiling, summary);
  return Reconstruct(problem.problem, options);
}

}  // namespace aosr
