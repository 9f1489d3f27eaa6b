// The shared helpers of common.hpp, and the module's entry point.
#include "common.hpp"

#include <Python.h>

#include <cstring>

#include "aosr/core/error.hpp"
#include "aosr/core/memory.hpp"

namespace aosr::python {

py::array ViewImage(const Image& image, py::handle owner, bool writeable) {
  const std::vector<py::ssize_t> shape = {py::ssize_t(image.rows()), py::ssize_t(image.cols())};
  const std::vector<py::ssize_t> strides = {py::ssize_t(image.cols() * sizeof(double)), py::ssize_t(sizeof(double))};
  py::array a(py::dtype::of<double>(), shape, strides, image.data(), owner);
  if (!writeable) py::detail::array_proxy(a.ptr())->flags &= ~py::detail::npy_api::NPY_ARRAY_WRITEABLE_;
  return a;
}

py::array MoveImage(Image&& image) {
  auto* owned = new Image(std::move(image));
  py::capsule owner(owned, [](void* p) { delete static_cast<Image*>(p); });
  return ViewImage(*owned, owner, /*writeable=*/true);
}

py::array StackToArray(const ImageStack& planes) {
  if (planes.empty()) return py::array_t<double>(std::vector<py::ssize_t>{0, 0, 0});
  const Index rows = planes.front().rows(), cols = planes.front().cols();
  py::array_t<double> out({py::ssize_t(planes.size()), py::ssize_t(rows), py::ssize_t(cols)});
  double* dst = out.mutable_data();
  for (const Image& p : planes) {
    CheckArgument(p.rows() == rows && p.cols() == cols, "aosr (python)", "stack", ToString(ShapeOf(p)),
                  "planes of one shape");
    std::memcpy(dst, p.data(), sizeof(double) * p.size());
    dst += p.size();
  }
  return std::move(out);
}

namespace {

// A C-contiguous float64 array of `array` (the object itself when it already is one; numpy's converting
// copy otherwise). InvalidArgument naming `what` if it is not numeric.
py::array_t<double, py::array::c_style | py::array::forcecast> AsDoubleArray(py::handle array, const std::string& what) {
  if (array.is_none()) throw InvalidArgument("aosr: " + what + " is None; allowed: a numeric array");
  try {
    return py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(array);
  } catch (const py::error_already_set&) {
  }
  throw InvalidArgument("aosr: " + what + " = " + std::string(py::str(py::repr(array))).substr(0, 80) +
                        "; allowed: an array of numbers");
}

Image CopyPlane(const double* src, Index rows, Index cols) {
  Image img(rows, cols);
  std::memcpy(img.data(), src, sizeof(double) * rows * cols);
  return img;
}

}  // namespace

Image ImageFromArray(py::handle array, const std::string& what) {
  auto a = AsDoubleArray(array, what);
  if (!a || a.ndim() != 2 || a.shape(0) == 0 || a.shape(1) == 0)
    throw InvalidArgument("aosr: invalid " + what + " with " + std::to_string(a ? a.ndim() : 0) +
                          " dimensions; allowed: a non-empty 2-D array (rows, cols)");
  return CopyPlane(a.data(), a.shape(0), a.shape(1));
}

ImageStack StackFromArray(py::handle array, const std::string& what) {
  if (py::isinstance<py::list>(array) || py::isinstance<py::tuple>(array)) {
    // A sequence of planes (possibly of numpy arrays): each plane on its own, no intermediate cube.
    ImageStack out;
    const py::sequence seq = py::reinterpret_borrow<py::sequence>(array);
    bool planes = seq.size() > 0;
    for (py::handle item : seq) planes = planes && (py::isinstance<py::array>(item) || py::isinstance<py::list>(item));
    if (planes) {
      for (std::size_t i = 0; i < seq.size(); ++i) out.push_back(ImageFromArray(seq[i], what + "[" + std::to_string(i) + "]"));
      return out;
    }
  }
  auto a = AsDoubleArray(array, what);
  if (a.ndim() == 2 && a.shape(0) > 0 && a.shape(1) > 0) return {CopyPlane(a.data(), a.shape(0), a.shape(1))};
  if (a.ndim() != 3 || a.shape(0) == 0 || a.shape(1) == 0 || a.shape(2) == 0)
    throw InvalidArgument("aosr: invalid " + what + " with " + std::to_string(a.ndim()) +
                          " dimensions; allowed: a non-empty (N, rows, cols) array, one (rows, cols) plane or a "
                          "list of planes");
  ImageStack out;
  const Index rows = a.shape(1), cols = a.shape(2);
  for (py::ssize_t i = 0; i < a.shape(0); ++i) out.push_back(CopyPlane(a.data() + i * rows * cols, rows, cols));
  return out;
}

nlohmann::json ToJson(py::handle object) {
  const py::module_ json = py::module_::import("json");
  std::string text;
  try {
    text = py::str(json.attr("dumps")(object, py::arg("allow_nan") = false));
  } catch (const py::error_already_set& e) {
    throw InvalidArgument(std::string("aosr: a value that JSON cannot hold (") + e.what() + ")");
  }
  return nlohmann::json::parse(text);
}

py::object FromJson(const nlohmann::json& json) {
  // NaN/Inf cannot appear in nlohmann output as numbers (they become null), so plain loads suffices.
  return py::module_::import("json").attr("loads")(json.dump());
}

PythonProgress::PythonProgress(py::object user_callback) : state_(std::make_shared<State>()) {
  state_->user = std::move(user_callback);
}

ProgressCallback PythonProgress::Callback() {
  std::shared_ptr<State> state = state_;
  return [state](const Progress& p) -> bool {
    py::gil_scoped_acquire gil;
    if (state->error) return false;
    if (PyErr_CheckSignals() != 0) {
      state->error.emplace();  // fetches (and clears) the pending KeyboardInterrupt
      return false;
    }
    if (state->user.is_none()) return true;
    try {
      py::dict d;
      d["stage"] = p.stage;
      d["iteration"] = p.iteration;
      d["total"] = p.total;
      d["value"] = p.value;
      d["value_name"] = p.value_name;
      d["elapsed_seconds"] = p.elapsed_seconds;
      const py::object r = state->user(d);
      // None (a callable that returns nothing) continues; False cancels.
      return r.is_none() || r.cast<bool>();
    } catch (py::error_already_set& e) {
      state->error.emplace(std::move(e));
      return false;
    }
  };
}

bool PythonProgress::Poll() {
  py::gil_scoped_acquire gil;
  if (state_->error) return false;
  if (PyErr_CheckSignals() != 0) {
    state_->error.emplace();
    return false;
  }
  return true;
}

void PythonProgress::RaiseIfPending() {
  if (!state_->error) return;
  py::error_already_set e = std::move(*state_->error);
  state_->error.reset();
  throw e;
}

void OptionError(const std::string& name, const std::string& value, const std::string& allowed) {
  throw InvalidArgument("aosr: invalid option " + name + " = " + value + "; allowed: " + allowed);
}

std::string PathString(py::handle path) {
  if (py::isinstance<py::str>(path)) return path.cast<std::string>();
  try {
    return py::str(py::module_::import("os").attr("fspath")(path));
  } catch (py::error_already_set&) {
    throw InvalidArgument("aosr: invalid path " + std::string(py::repr(path)) + "; allowed: a str or os.PathLike");
  }
}

py::object Pop(py::dict& kwargs, const char* key) {
  if (!kwargs.contains(key)) return py::none();
  py::object v = kwargs[key];
  PyDict_DelItemString(kwargs.ptr(), key);
  return v;
}

}  // namespace aosr::python

PYBIND11_MODULE(_aosr, m) {
  using namespace aosr::python;
  m.doc() =
      "aosr: super-resolved imaging with adaptive optics (pybind11 bindings of the C++ library).\n\n"
      "Use the package `aosr`, which re-exports this module; see docs/python.md.";
  // The same allocator settings as the CLI (memory.hpp): freed image-sized arrays are reused instead of being
  // page-faulted in again; AOSR_MALLOC_TUNING=0 before the import keeps the interpreter's own settings.
  static bool tuned = aosr::TuneAllocatorForLargeArrays();
  m.def("allocator_tuned", [] { return tuned; },
        "Whether aosr set glibc's malloc thresholds (on import, or by tune_allocator): freed image-sized arrays\n"
        "reused instead of returned to the kernel (core/memory.hpp). False outside glibc, or when\n"
        "AOSR_MALLOC_TUNING=0 or the environment's malloc settings were left alone.");
  m.def(
      "tune_allocator",
      [](bool override_environment) {
        if (aosr::TuneAllocatorForLargeArrays(override_environment)) tuned = true;
        return tuned;
      },
      pybind11::arg("override_environment") = false,
      "Sets glibc's malloc thresholds as the import does; override_environment=True also over malloc settings in\n"
      "the environment (not AOSR_MALLOC_TUNING=0). aosr.distributed's tasks call it with True: Dask's nanny starts\n"
      "workers with MALLOC_TRIM_THRESHOLD_=65536, which returns every freed image to the kernel. Returns\n"
      "allocator_tuned().");
  BindCore(m);
  BindIo(m);
  BindOptics(m);
  BindScene(m);
  BindSolvers(m);
  BindTiles(m);
  BindStreaming(m);
  BindDesign(m);
  BindCalib(m);
}
