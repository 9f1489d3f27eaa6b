// What every binding file of the aosr Python module shares: numpy <-> Image conversion, the GIL and Ctrl-C
// around long calls, JSON <-> Python, and the one option table that maps keyword arguments onto the
// library's options structs.
//
// Rules, written once for the whole module (docs/python.md repeats them for users):
//  * Arrays are (rows, cols) = (y, x) as in include/aosr/core/image.hpp; stacks are (N, rows, cols).
//  * Out: a 2-D image the library computed (a reconstruction, a PSF, a dataset's truth) is handed to numpy
//    without a copy: the array views memory owned by a C++ object that the array keeps alive (its .base).
//    Stacks (frames, weights, masks, PSFs) are held by the library as separate planes, so they come out as
//    one (N, rows, cols) array, copied once and cached by the object that owns them, read-only.
//  * In: the library's images own their pixels, so an input array is copied once into C++ storage. A
//    C-contiguous float64 array is copied as raw memory (a memcpy); any other dtype or layout goes through
//    numpy's converting copy first. Inputs are never modified.
//  * Long calls run with the GIL released. Those with iterations (tv, map, their pilot) poll for Ctrl-C
//    through core/progress.hpp's callback and raise KeyboardInterrupt after the solver has stopped cleanly.
//  * aosr::Error subclasses become aosr.Error subclasses that are also the matching builtin (ValueError,
//    OSError, MemoryError, ArithmeticError), with the C++ message unchanged.
#pragma once

#include <pybind11/functional.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <functional>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "aosr/core/image.hpp"
#include "aosr/core/progress.hpp"

namespace aosr::python {

namespace py = pybind11;

// ---- numpy ----------------------------------------------------------------------------------------------

// A (rows, cols) float64 view of `image`, which must live as long as `owner` (the array keeps a reference
// to it). Read-only unless `writeable`.
py::array ViewImage(const Image& image, py::handle owner, bool writeable = false);
// Moves `image` into a new numpy array (no pixel copy: the array owns the Eigen buffer through a capsule).
py::array MoveImage(Image&& image);
// One (N, rows, cols) float64 array holding the planes (a copy; planes must share a shape).
py::array StackToArray(const ImageStack& planes);
// Copies a 2-D array-like into an Image. `what` names the argument in errors (InvalidArgument).
Image ImageFromArray(py::handle array, const std::string& what);
// Copies an (N, rows, cols) array, a 2-D array (one plane) or a sequence of 2-D arrays into planes.
ImageStack StackFromArray(py::handle array, const std::string& what);

// ---- JSON -----------------------------------------------------------------------------------------------

// Python dict/list/str/number/bool/None <-> nlohmann::json (through Python's json module, the one
// serialiser both sides agree on; doubles round-trip exactly).
nlohmann::json ToJson(py::handle object);
py::object FromJson(const nlohmann::json& json);

// ---- GIL and Ctrl-C -------------------------------------------------------------------------------------

// A progress callback for a solve that runs with the GIL released: on each report it takes the GIL, checks
// for a pending signal (Ctrl-C) and calls the user's Python callable, if any, with the report as a dict
// (returning False from it cancels too). A Python exception (KeyboardInterrupt or the callable's own) is
// kept and the solve is cancelled; RaiseIfPending() (GIL held) raises it after the solve has returned.
class PythonProgress {
 public:
  explicit PythonProgress(py::object user_callback = py::none());
  ProgressCallback Callback();
  // Raises the kept exception, if any. Call with the GIL held.
  void RaiseIfPending();
  // Polls for Ctrl-C between independent steps of a loop run with the GIL released (e.g. per mode);
  // returns false (and keeps the exception) when one is pending.
  bool Poll();

 private:
  struct State {
    py::object user;
    std::optional<py::error_already_set> error;
  };
  std::shared_ptr<State> state_;
};

// Runs fn() with the GIL released.
template <typename F>
auto WithoutGil(F&& fn) -> decltype(fn()) {
  py::gil_scoped_release release;
  return fn();
}

// ---- Options: keyword arguments -> options structs --------------------------------------------------------

// A table of the settable fields of an options struct S, so that one generic loop turns keyword arguments
// (or a dict) into S and describes every field for help(). Each row names a field, its type, its doc line,
// how to set it from a Python value and how to read it back (the default shown by describe()).
template <typename S>
class OptionTable {
 public:
  struct Row {
    std::string name, type, doc;
    // Sets the field from a Python value; `shown` is the name errors give (the full prefixed name).
    std::function<void(S&, py::handle, const std::string& shown)> set;
    std::function<py::object(const S&)> get;
  };

  // A plain field: double, int, bool, std::string or std::uint64_t.
  template <typename T>
  OptionTable& Field(const std::string& name, T S::*member, const std::string& doc) {
    rows_.push_back({name, TypeName<T>(), doc,
                     [member](S& s, py::handle v, const std::string& shown) { s.*member = Cast<T>(v, shown); },
                     [member](const S& s) { return py::cast(s.*member); }});
    return *this;
  }
  // An enum field set by name: `names` lists every (Python name, value) pair.
  template <typename E>
  OptionTable& Enum(const std::string& name, E S::*member, std::vector<std::pair<std::string, E>> names,
                    const std::string& doc) {
    std::string allowed;
    for (const auto& [n, e] : names) allowed += (allowed.empty() ? "" : " | ") + n;
    rows_.push_back({name, allowed, doc,
                     [member, names, allowed](S& s, py::handle v, const std::string& shown) {
                       const std::string text = Cast<std::string>(v, shown);
                       for (const auto& [n, e] : names)
                         if (n == text) {
                           s.*member = e;
                           return;
                         }
                       Fail(shown, text, allowed);
                     },
                     [member, names](const S& s) -> py::object {
                       for (const auto& [n, e] : names)
                         if (e == s.*member) return py::str(n);
                       return py::none();
                     }});
    return *this;
  }
  // An enum field set by name through the library's own Parse/ToString pair, so that a value added to the enum
  // (and to its Parse) is accepted here without an edit; Parse's InvalidArgument lists what is allowed.
  template <typename E>
  OptionTable& EnumParsed(const std::string& name, E S::*member, E (*parse)(const std::string&),
                          const char* (*to_string)(E), const std::string& type, const std::string& doc) {
    rows_.push_back({name, type, doc,
                     [member, parse](S& s, py::handle v, const std::string& shown) {
                       s.*member = parse(Cast<std::string>(v, shown));
                     },
                     [member, to_string](const S& s) -> py::object { return py::str(to_string(s.*member)); }});
    return *this;
  }
  // A row with its own setter (aliases that set several fields, like the CLI's --mu) and getter.
  OptionTable& Custom(const std::string& name, const std::string& type, const std::string& doc,
                      std::function<void(S&, py::handle)> set, std::function<py::object(const S&)> get) {
    rows_.push_back({name, type, doc, [set](S& s, py::handle v, const std::string&) { set(s, v); }, std::move(get)});
    return *this;
  }
  // Every row of `sub` as "<prefix>_<row>" on the member `sub_member`, plus "<prefix>" taking a dict of the
  // sub-table's names (reconstruct(..., tv={"max_iterations": 50}) = reconstruct(..., tv_max_iterations=50)).
  template <typename Sub>
  OptionTable& Nested(const std::string& prefix, Sub S::*sub_member, const OptionTable<Sub>& sub) {
    for (const auto& row : sub.rows())
      rows_.push_back({prefix + "_" + row.name, row.type, row.doc,
                       [sub_member, set = row.set](S& s, py::handle v, const std::string& shown) { set(s.*sub_member, v, shown); },
                       [sub_member, get = row.get](const S& s) { return get(s.*sub_member); }});
    rows_.push_back({prefix, "dict", "options of " + prefix + " by their names above, without the prefix",
                     [sub_member, sub, prefix](S& s, py::handle v, const std::string&) {
                       if (!py::isinstance<py::dict>(v)) Fail(prefix, py::str(v), "a dict of " + prefix + " options");
                       sub.Apply(s.*sub_member, v.cast<py::dict>(), prefix + "_");
                     },
                     [](const S&) { return py::none(); }});
    return *this;
  }

  const std::vector<Row>& rows() const { return rows_; }
  const Row* Find(const std::string& name) const {
    for (const Row& r : rows_)
      if (r.name == name) return &r;
    return nullptr;
  }
  // Sets every key of `kwargs` (an unknown key is InvalidArgument listing the known ones).
  void Apply(S& s, const py::dict& kwargs, const std::string& shown_prefix = "") const {
    for (const auto& [key, value] : kwargs) {
      const std::string name = py::str(key);
      const Row* row = Find(name);
      if (!row) Fail(shown_prefix + name, "(unknown option)", "one of: " + Names());
      row->set(s, value, shown_prefix + name);
    }
  }
  std::string Names() const {
    std::string out;
    for (const Row& r : rows_) out += (out.empty() ? "" : ", ") + r.name;
    return out;
  }
  // {name: {"type", "default", "doc"}} for help() and docs.
  py::dict Describe(const S& defaults) const {
    py::dict d;
    for (const Row& r : rows_) {
      py::dict e;
      e["type"] = r.type;
      e["default"] = r.get(defaults);
      e["doc"] = r.doc;
      d[py::str(r.name)] = e;
    }
    return d;
  }

  [[noreturn]] static void Fail(const std::string& name, const std::string& value, const std::string& allowed);

 private:
  template <typename T>
  static std::string TypeName() {
    if constexpr (std::is_same_v<T, bool>) return "bool";
    else if constexpr (std::is_integral_v<T>) return "int";
    else if constexpr (std::is_floating_point_v<T>) return "float";
    else return "str";
  }
  template <typename T>
  static T Cast(py::handle v, const std::string& name) {
    // bool is checked strictly (Python's True is an int, and 0/1 for a flag is a likely typo of another option).
    if constexpr (std::is_same_v<T, bool>) {
      if (!py::isinstance<py::bool_>(v)) Fail(name, py::repr(v), "True or False");
      return v.cast<bool>();
    } else if constexpr (std::is_integral_v<T>) {
      if (py::isinstance<py::bool_>(v) || !py::isinstance<py::int_>(v)) Fail(name, py::repr(v), "an int");
      return v.cast<T>();
    } else if constexpr (std::is_floating_point_v<T>) {
      if (py::isinstance<py::bool_>(v) || !(py::isinstance<py::int_>(v) || py::isinstance<py::float_>(v) ||
                                            py::hasattr(v, "__float__")))
        Fail(name, py::repr(v), "a number");
      return v.cast<T>();
    } else {
      if (!py::isinstance<py::str>(v)) Fail(name, py::repr(v), "a str");
      return v.cast<std::string>();
    }
  }

  std::vector<Row> rows_;
};

// Throws aosr::InvalidArgument("aosr.<function>: invalid <name> = <value>; allowed: <allowed>").
[[noreturn]] void OptionError(const std::string& name, const std::string& value, const std::string& allowed);

template <typename S>
void OptionTable<S>::Fail(const std::string& name, const std::string& value, const std::string& allowed) {
  OptionError(name, value, allowed);
}

// A path argument: a str or any os.PathLike (pathlib.Path), as os.fspath() gives it.
std::string PathString(py::handle path);

// Pops `key` from kwargs if present.
py::object Pop(py::dict& kwargs, const char* key);

// ---- Registration, one function per binding file ---------------------------------------------------------

void BindCore(py::module_& m);
void BindIo(py::module_& m);
void BindOptics(py::module_& m);
void BindScene(py::module_& m);
void BindSolvers(py::module_& m);
void BindTiles(py::module_& m);
void BindStreaming(py::module_& m);
void BindDesign(py::module_& m);
void BindCalib(py::module_& m);

}  // namespace aosr::python
