// What a reconstruction's FITS file says about itself, shared by `aosr reconstruct` and
// aosr.distributed.reconstruct_tiles, so that the same run gives the same keywords from either.
#pragma once
#include <string>

#include "aosr/io/fits.hpp"
#include "aosr/scene/dataset.hpp"
#include "aosr/solvers/dataset_problem.hpp"
#include "aosr/solvers/reconstruct.hpp"
#include "aosr/solvers/tiling.hpp"

namespace aosr {

// The keywords of a reconstruction of `d` by `method` (ORIGIN, AOSRDATA, METHOD, SRFACTOR, NFRAMES, REGUL,
// TERMINAT, NITER; PSFFIELD for a field model of `dp`; TILE, TILEOVER and NTILES for a tiled run, `ts` with tiles;
// HRPIXRAD when the pixel scale is known). Not the unit or the WCS: SetHrImageKeywords adds them per HDU.
FitsHeader ReconstructionHeader(const Dataset& d, ReconstructionMethod method, const Reconstruction& rec,
                                const DatasetProblem* dp = nullptr, const TilingSummary* ts = nullptr);

// Where the second map of a reconstruction written to `out` goes: <stem>_weight<ext> for drizzle (its weight
// map), <stem>_std<ext> for the others (their σ).
std::string ReconstructionAuxPath(const std::string& out, ReconstructionMethod method);

}  // namespace aosr
