#include "aosr/solvers/reconstruction_header.hpp"

#include <filesystem>

namespace aosr {

FitsHeader ReconstructionHeader(const Dataset& d, ReconstructionMethod method, const Reconstruction& rec,
                                const DatasetProblem* dp, const TilingSummary* ts) {
  FitsHeader h;
  h.Set("ORIGIN", std::string("aosr ") + AOSR_VERSION, "software that wrote this file");
  h.Set("AOSRDATA", "reconstruction", "content of this HDU");
  h.Set("METHOD", std::string(ToString(method)), "reconstruction method");
  h.Set("SRFACTOR", static_cast<long long>(d.r), "super-resolution factor r");
  h.Set("NFRAMES", static_cast<long long>(d.size()), "number of sub-exposures N");
  h.Set("REGUL", rec.regularisation, "lambda (tikhonov, map) or mu (tv); 0 for baselines");
  h.Set("TERMINAT", std::string(ToString(rec.summary.termination)), "solver termination");
  h.Set("NITER", static_cast<long long>(rec.summary.iterations), "iterations");
  if (dp && dp->psf_field)
    h.Set("PSFFIELD",
          std::string(ToString(dp->psf_field->approach)) + " " + std::to_string(dp->psf_field->grid.ny()) + "x" +
              std::to_string(dp->psf_field->grid.nx()),
          dp->stars_psf ? "field-varying model of the stars PSFs' grid (solvers/stars_psf.hpp)"
                        : "field-varying model of the dataset's PSF grid (solvers/psf_field_model.hpp)");
  if (ts && !ts->tiles.empty()) {
    h.Set("TILE", static_cast<long long>(ts->tile), "[camera px] largest tile core (solvers/tiling.hpp)");
    h.Set("TILEOVER", static_cast<long long>(ts->overlap), "[camera px] tile overlap on each side");
    h.Set("NTILES", static_cast<long long>(ts->tiles.size()), "tiles reconstructed and blended");
  }
  if (d.camera_pixel_rad > 0) h.Set("HRPIXRAD", d.camera_pixel_rad / d.r, "[rad] HR pixel angular pitch");
  return h;
}

std::string ReconstructionAuxPath(const std::string& out, ReconstructionMethod method) {
  const std::filesystem::path p(out);
  const std::string aux = method == ReconstructionMethod::kDrizzle ? "weight" : "std";
  return (p.parent_path() / (p.stem().string() + "_" + aux + p.extension().string())).string();
}

}  // namespace aosr
