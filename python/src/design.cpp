// Bindings of the design layer (filled in by the design-study commit).
#include "common.hpp"

namespace aosr::python {

void BindDesign(py::module_&) {}

}  // namespace aosr::python
