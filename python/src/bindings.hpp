// Types and helpers that more than one binding file uses (the Python-side Dataset, FITS header dicts).
#pragma once

#include <map>
#include <memory>
#include <string>

#include "aosr/io/fits.hpp"
#include "aosr/scene/dataset.hpp"
#include "aosr/solvers/reconstruct.hpp"
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

}  // namespace aosr::python
