// Bindings of the calib layer: synthetic calibration sets and the modal-gain calibration, as `aosr calibrate`
// (--synthesize) does them, with the same library calls.
#include <filesystem>

#include "aosr/calib/calibrate.hpp"
#include "aosr/calib/calibration_file.hpp"
#include "aosr/calib/calibration_set.hpp"
#include "aosr/calib/report.hpp"
#include "aosr/core/error.hpp"
#include "aosr/io/atomic_file.hpp"
#include "bindings.hpp"
#include "common.hpp"

namespace aosr::python {
namespace {

struct PyCalibrationSet {
  std::shared_ptr<const CalibrationSet> set;
};

void EnsureFolder(const std::string& dir) {
  std::error_code ec;
  if (std::filesystem::exists(dir, ec)) {
    if (!std::filesystem::is_directory(dir, ec)) throw IoError(dir, "exists and is not a directory");
    return;
  }
  if (!std::filesystem::create_directories(dir, ec) || ec) throw IoError(dir, "cannot create directory: " + ec.message());
}

}  // namespace

void BindCalib(py::module_& m) {
  py::class_<PyCalibrationSet>(m, "CalibrationSet",
                               "A calibration set: frames of a point source while single DM modes are poked\n"
                               "(data/calibration/README.md). From aosr.synthesize_calibration or\n"
                               "aosr.CalibrationSet.load(path).")
      .def_static(
          "load",
          [](py::object path_object) {
            const std::string path = PathString(path_object);
            return PyCalibrationSet{std::make_shared<const CalibrationSet>(WithoutGil([&] { return LoadCalibrationSet(path); }))};
          },
          py::arg("path"), "Reads a calibration set folder (or its calibration-set.json).")
      .def_property_readonly("source", [](const PyCalibrationSet& s) { return s.set->source; })
      .def_property_readonly("modes", [](const PyCalibrationSet& s) {
        std::vector<std::string> names;
        for (const CalibrationMode& mode : s.set->modes) names.push_back(mode.name);
        return names;
      })
      .def_property_readonly("truth", [](const PyCalibrationSet& s) { return FromJson(s.set->truth); },
                             "what a synthetic set injected (None for measurements)")
      .def_property_readonly("frames", [](const PyCalibrationSet& s) {
        ImageStack planes;
        for (const CalibrationFrame& f : s.set->frames) planes.push_back(f.adu);
        return StackToArray(planes);
      }, "(n, rows, cols) frames, ADU (dark subtracted), a copy")
      .def("__len__", [](const PyCalibrationSet& s) { return s.set->frames.size(); })
      .def("__repr__", [](const PyCalibrationSet& s) {
        return "<aosr.CalibrationSet " + std::to_string(s.set->frames.size()) + " frames, " +
               std::to_string(s.set->modes.size()) + " modes (" + s.set->source + ")>";
      });

  m.def(
      "synthesize_calibration",
      [](py::object spec_object, py::object output, std::optional<std::vector<double>> gains,
         std::optional<double> nonlinear_above, std::optional<double> nonlinear_strength,
         std::optional<std::uint64_t> seed) {
        // As `aosr calibrate --synthesize SPEC [--gains ..] [--nonlinear-above NM] [--nonlinear-strength K] [--seed S]`.
        const std::string spec = PathString(spec_object);
        SyntheticCalibrationOptions o = LoadSyntheticCalibrationSpec(spec);
        if (gains) o.gains = *gains;
        if (nonlinear_above) {
          CheckArgument(*nonlinear_above >= 0, "aosr.synthesize_calibration", "nonlinear_above", *nonlinear_above, ">= 0 nm");
          o.nonlinear_above_m = *nonlinear_above * 1e-9;
        }
        if (nonlinear_strength) o.nonlinear_strength = *nonlinear_strength;
        if (seed) o.seed = *seed;
        std::string why;
        if (!o.IsValid(&why)) throw InvalidArgument("aosr.synthesize_calibration: " + why);
        const std::string out = output.is_none() ? std::string() : PathString(output);
        // As the CLI: the manifest written must not be the spec read.
        if (!out.empty()) CheckNotSameFile((std::filesystem::path(out) / kCalibrationSetFileName).string(), {spec});
        auto set = std::make_shared<CalibrationSet>(WithoutGil([&] {
          CalibrationSet s = SynthesizeCalibrationSet(o);
          s.truth["spec"] = spec;
          if (!out.empty()) {
            EnsureFolder(out);
            WriteCalibrationSet(out, s);
          }
          return s;
        }));
        return PyCalibrationSet{set};
      },
      py::arg("spec") = "paper-bench", py::kw_only(), py::arg("output") = py::none(), py::arg("gains") = py::none(),
      py::arg("nonlinear_above") = py::none(), py::arg("nonlinear_strength") = py::none(), py::arg("seed") = py::none(),
      R"doc(A synthetic calibration set with known gains, as `aosr calibrate --synthesize SPEC`.

spec              data/calibration/*.json name or path, or a telescope preset
output            also write the set (calibration-set.json + FITS frames) into this folder
gains             true gain per mode; nonlinear_above [nm], nonlinear_strength, seed: as the CLI's flags
Returns an aosr.CalibrationSet (its .truth holds the injected gains).)doc");

  m.def(
      "calibrate",
      [](py::object set, int threads, int static_max_noll, double tolerance, bool point_source, py::object output,
         py::object progress) {
        CalibrateOptions o;
        o.threads = threads;
        o.fit.static_max_noll = static_max_noll;
        o.fit.fit_source_size = !point_source;
        o.linearity.tolerance = tolerance;
        std::string why;
        if (!o.IsValid(&why)) throw InvalidArgument("aosr.calibrate: " + why);
        std::shared_ptr<const CalibrationSet> s;
        if (py::isinstance<PyCalibrationSet>(set)) {
          s = set.cast<PyCalibrationSet&>().set;
        } else {
          const std::string path = PathString(set);
          s = std::make_shared<const CalibrationSet>(WithoutGil([&] { return LoadCalibrationSet(path); }));
        }
        const std::string out = output.is_none() ? std::string() : PathString(output);
        const std::string json_path = (std::filesystem::path(out) / "calibration.json").string();
        const std::string png_path = (std::filesystem::path(out) / "report.png").string();
        if (!out.empty()) {
          // As `aosr calibrate`: never overwrite an input (the set's manifest or a frame), checked before any fit.
          const std::vector<std::string> inputs = CalibrationSetInputFiles(*s);
          CheckNotSameFile(json_path, inputs);
          CheckNotSameFile(png_path, inputs);
        }
        PythonProgress poll(progress);
        o.progress = poll.Callback();
        bool cancelled = false;
        nlohmann::json j = WithoutGil([&] {
          const CalibrationResult result = Calibrate(*s, o);
          cancelled = result.cancelled;
          if (cancelled) return nlohmann::json();
          nlohmann::json json = CalibrationToJson(*s, result);
          if (!out.empty()) {
            EnsureFolder(out);
            WriteCalibrationJson(json_path, json);
            WriteCalibrationReport(png_path, *s, result);
          }
          return json;
        });
        poll.RaiseIfPending();  // Ctrl-C (KeyboardInterrupt) or the progress callable's exception
        if (cancelled) return py::object(py::none());  // the progress callable returned False: nothing written
        return FromJson(j);
      },
      py::arg("set"), py::kw_only(), py::arg("threads") = 2, py::arg("static_max_noll") = 8, py::arg("tolerance") = 0.05,
      py::arg("point_source") = false, py::arg("output") = py::none(), py::arg("progress") = py::none(),
      R"doc(Fits the DM's modal gains from a calibration set, as `aosr calibrate SET -o OUT`.

set               an aosr.CalibrationSet or a set folder / calibration-set.json
threads           modes fitted in parallel
static_max_noll   fit the static aberration Z4..Z<K> common to a mode's frames (0: none)
tolerance         relative gain change tolerated in the linear range
point_source      do not fit the source size
output            also write calibration.json and report.png into this folder; refused (InvalidArgument) when
                  one of them would be an input file (the set's manifest or a frame), as the CLI refuses
progress          optional callable(dict) called after each mode fit (stage 'calibrate', iteration = modes
                  done, total = modes, value = that mode's gain); returning False cancels: then None is
                  returned and nothing is written
Returns the calibration as the dict calibration.json holds. The GIL is released; Ctrl-C stops the fit after the
modes in flight and raises KeyboardInterrupt (nothing is written).)doc");
}

}  // namespace aosr::python
