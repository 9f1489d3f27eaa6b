// Types and helpers that more than one binding file uses (the Python-side Dataset, FITS header dicts).
#pragma once

#include <map>
#include <memory>
#include <string>

#include "aosr/core/memory.hpp"
#include "aosr/io/fits.hpp"
#include "aosr/scene/dataset.hpp"
#include "aosr/solvers/dataset_problem.hpp"
#include "aosr/solvers/reconstruct.hpp"
#include "aosr/solvers/registration.hpp"
#include "aosr/solvers/stars_psf.hpp"
#include "aosr/solvers/tiling.hpp"
#include "common.hpp"

namespace aosr::python {

// aosr.Dataset: an immutable library Dataset, shared with the results and tasks that use it, and the
// (N, rows, cols) arrays already handed to Python (copied once, read-only; common.hpp's rule).
struct PyDataset {
  std::shared_ptr<const Dataset> dataset;
  std::map<std::string, py::object> stacks;
};

// A Dataset from an aosr.Dataset, or from a folder / manifest path (LoadDataset, GIL released).
// InvalidArgument naming `function` for anything else.
std::shared_ptr<const Dataset> DatasetArgument(py::handle object, const std::string& function);

// FITS headers <-> {KEYWORD: value} dicts (io.cpp).
py::dict HeaderToDict(const FitsHeader& header);
py::dict HeaderComments(const FitsHeader& header);
FitsHeader HeaderFromDict(py::handle header, py::handle comments);

// The keyword options of aosr.reconstruct with their defaults (solvers.cpp).
py::dict ReconstructOptionsHelp();
// aosr.reconstruct's keyword table, the CLI's defaults it starts from, and a solver summary as a dict
// (solvers.cpp); the streaming bindings (streaming.cpp) take the same options.
const OptionTable<ReconstructOptions>& ReconstructTable();
ReconstructOptions CliDefaults();
py::dict SummaryDict(const SolverSummary& summary);
// What aosr.reconstruct and the tile jobs of aosr.distributed both start from: the method's options (the CLI's
// defaults, then the keywords) and the dataset's weights and offsets rules (solvers.cpp).
void DatasetRunOptions(const std::string& method, const py::dict& kwargs, const std::string& weights,
                       const std::string& offsets, ReconstructOptions* o, DatasetProblemOptions* dpo);

// aosr.Reconstruction (solvers.cpp), what aosr.reconstruct and the blend of aosr.distributed.reconstruct_tiles
// (tiles.cpp) return: the library's Reconstruction (images viewed, not copied) and where the
// problem's weights and offsets came from.
struct PyReconstruction {
  Reconstruction rec;
  std::string method, weights_source, offsets_source;
  bool model_psfs_replaced = false;
  Index masked_pixels = 0;
  std::optional<RegistrationResult> registration;
  std::optional<StarsPsfResult> stars_psf;
  std::string psf_field = "none";  // the field model used: "none" | "tiles"
  int r = 1;
  // Set when the whole grid did not fit the memory limit and the run went by tiles without a whole-grid model.
  std::optional<TilingOptions> by_tiles_for_memory;
  double whole_grid_bytes = 0, memory_limit_bytes = 0;
};

// A memory limit argument: None (the process's), bytes, or '512M' / '8G' (solvers.cpp).
MemoryLimit MemoryLimitArgument(const py::object& memory_limit, const char* fn);

}  // namespace aosr::python
