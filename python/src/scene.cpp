// Bindings of the scene layer: scenes (from a file or a dict), simulate(), datasets (opened from disk, made
// from a simulation or from the caller's arrays) and evaluate().
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <limits>
#include <vector>

#include "aosr/calib/calibration_file.hpp"
#include "aosr/core/error.hpp"
#include "aosr/core/metrics.hpp"
#include "aosr/io/config.hpp"
#include "aosr/io/wcs.hpp"
#include "aosr/scene/dataset.hpp"
#include "aosr/scene/dataset_memory.hpp"
#include "aosr/scene/evaluation.hpp"
#include "aosr/scene/pipeline.hpp"
#include "aosr/scene/scene_spec.hpp"
#include "aosr/scene/star_metrics.hpp"
#include "aosr/scene/usaf_contrast.hpp"
#include "bindings.hpp"
#include "common.hpp"

namespace aosr::python {
namespace {

// aosr.Scene: the scene's JSON as read (kept so that simulate(seed=...) re-parses it exactly as
// `aosr simulate --set seed=...` does) and the parsed, validated spec.
struct PyScene {
  nlohmann::json json;
  std::string source;
  std::shared_ptr<const SceneSpec> spec;
};

PyScene MakeScene(nlohmann::json json, const std::string& source) {
  PyScene s;
  s.spec = std::make_shared<const SceneSpec>(ParseScene(json, source));
  s.json = std::move(json);
  s.source = source;
  return s;
}

py::object Cached(py::object self, const std::string& key, const std::function<py::array()>& make) {
  PyDataset& d = self.cast<PyDataset&>();
  auto it = d.stacks.find(key);
  if (it != d.stacks.end()) return it->second;
  py::array a = make();
  py::detail::array_proxy(a.ptr())->flags &= ~py::detail::npy_api::NPY_ARRAY_WRITEABLE_;
  d.stacks[key] = a;
  return std::move(a);
}

py::object WrapDataset(Dataset&& d) {
  PyDataset p;
  p.dataset = std::make_shared<const Dataset>(std::move(d));
  return py::cast(std::move(p));
}

std::vector<DmOffset> ShiftOffsets(py::handle offsets) {
  std::vector<DmOffset> out;
  if (offsets.is_none()) return out;
  for (py::handle item : offsets) {
    const py::sequence pair = py::reinterpret_borrow<py::sequence>(item);
    if (pair.size() != 2) OptionError("offsets", py::repr(item), "(dy, dx) camera-pixel shifts, one pair per frame");
    DmOffset o;
    o.shift_y_px = pair[0].cast<double>();
    o.shift_x_px = pair[1].cast<double>();
    out.push_back(o);
  }
  return out;
}


Image ImageOrFits(py::handle object, const std::string& what) {
  if (py::isinstance<py::str>(object) || py::hasattr(object, "__fspath__")) {
    const std::string path = PathString(object);
    return WithoutGil([&] { return ReadFitsImage(path); });
  }
  return ImageFromArray(object, what);
}

}  // namespace

std::shared_ptr<const Dataset> DatasetArgument(py::handle object, const std::string& function) {
  if (py::isinstance<PyDataset>(object)) return object.cast<PyDataset&>().dataset;
  if (py::isinstance<py::str>(object) || py::hasattr(object, "__fspath__")) {
    const std::string path = PathString(object);
    return std::make_shared<const Dataset>(WithoutGil([&] { return LoadDataset(path); }));
  }
  throw InvalidArgument(function, "dataset", std::string(py::str(py::type::of(object).attr("__name__"))),
                        "an aosr.Dataset or a dataset folder / manifest path");
}

void BindScene(py::module_& m) {
  m.def(
      "usaf_resolving_power",
      [](py::handle image, py::handle scene, double threshold) {
        const Image x = ImageOrFits(image, "image");
        std::shared_ptr<const SceneSpec> spec;
        if (py::isinstance<PyScene>(scene)) {
          spec = scene.cast<PyScene&>().spec;
        } else if (py::isinstance<py::str>(scene) || py::hasattr(scene, "__fspath__")) {
          const std::string path = PathString(scene);
          spec = std::make_shared<const SceneSpec>(WithoutGil([&] { return LoadScene(path); }));
        } else {
          throw InvalidArgument("aosr.usaf_resolving_power", "scene", std::string(py::str(py::type::of(scene).attr("__name__"))),
                                "an aosr.Scene or a scene file path");
        }
        const UsafResolvingPower p = WithoutGil([&] { return MeasureSceneUsafResolvingPower(x, *spec, threshold); });
        py::list elements;
        for (const UsafElementContrast& e : p.elements) {
          if (!e.measured) continue;
          elements.append(py::dict(py::arg("group") = e.group, py::arg("element") = e.element,
                                   py::arg("bar_width_hr_px") = e.bar_width_px, py::arg("cycles_per_hr_px") = e.cycles_per_px,
                                   py::arg("cycles_per_camera_px") = e.cycles_per_camera_px,
                                   py::arg("cycles_per_lambda_over_d") = e.cycles_per_lambda_over_d,
                                   py::arg("contrast_x") = e.contrast_x, py::arg("contrast_y") = e.contrast_y,
                                   py::arg("contrast") = e.contrast, py::arg("transfer") = e.transfer,
                                   py::arg("resolved") = e.resolved));
        }
        py::dict d;
        d["threshold"] = p.threshold;
        d["elements"] = elements;
        d["finest"] = py::none();
        if (p.finest >= 0) {
          const UsafElementContrast& f = p.elements[std::size_t(p.finest)];
          d["finest"] = py::dict(py::arg("group") = f.group, py::arg("element") = f.element,
                                 py::arg("cycles_per_hr_px") = f.cycles_per_px, py::arg("cycles_per_camera_px") = f.cycles_per_camera_px,
                                 py::arg("cycles_per_lambda_over_d") = f.cycles_per_lambda_over_d);
        }
        return d;
      },
      py::arg("image"), py::arg("scene"), py::kw_only(), py::arg("threshold") = 0.153,
      "Resolving power on the USAF target of `scene` (an aosr.Scene or a scene file; its first usaf or demo object)\n"
      "seen in `image`, an HR image of the scene (array or FITS path): per element the Michelson contrast of its\n"
      "three bars along x and y, and the finest element resolved at `threshold` (scene/usaf_contrast.hpp).\n"
      "Returns {'threshold', 'elements': [{group, element, bar_width_hr_px, cycles_per_hr_px,\n"
      "cycles_per_camera_px, cycles_per_lambda_over_d, contrast_x, contrast_y, contrast, transfer, resolved}],\n"
      "'finest': {group, element, cycles_per_hr_px, cycles_per_camera_px, cycles_per_lambda_over_d} or None}.");
  m.def(
      "read_json", [](py::object path) { return FromJson(ReadJsonFile(PathString(path))); }, py::arg("path"),
      "Reads a JSON file as aosr does (errors name the file and position).");

  py::class_<PyScene>(m, "Scene",
                      "A parsed and validated scene (data/scenes/README.md): what aosr.simulate renders.\n"
                      "Make one with aosr.load_scene(path) or aosr.Scene(dict).")
      .def(py::init([](py::dict json, const std::string& source) { return MakeScene(ToJson(json), source); }),
           py::arg("json"), py::arg("source") = "<dict>",
           "A scene from its JSON as a dict. `source` names it in errors; relative paths inside (design files,\n"
           "images) resolve against its folder (the current folder for '<dict>').")
      .def_static(
          "load",
          [](py::object path) {
            const std::string p = PathString(path);
            return MakeScene(ReadJsonFile(p), p);
          }, py::arg("path"),
          "Reads and validates a scene file (errors name the file and field).")
      .def_property_readonly("name", [](const PyScene& s) { return s.spec->name; })
      .def_property_readonly("source", [](const PyScene& s) { return s.source; })
      .def_property_readonly("frames", [](const PyScene& s) { return s.spec->frames; }, "N sub-exposures")
      .def_property_readonly("r", [](const PyScene& s) { return s.spec->r; }, "super-resolution factor")
      .def_property_readonly("frame_shape", [](const PyScene& s) { return py::make_tuple(s.spec->frame.rows, s.spec->frame.cols); })
      .def_property_readonly("hr_shape", [](const PyScene& s) {
        const Shape h = s.spec->HrFrame();
        return py::make_tuple(h.rows, h.cols);
      })
      .def_property_readonly("seed", [](const PyScene& s) { return s.spec->seed; })
      .def_property_readonly("sky_oversampling", [](const PyScene& s) { return s.spec->sky_oversampling; },
                             "the sky's sampling against the HR grid (1: a grid of HR pixels; s > 1: s times finer)")
      .def("_spec_json", [](const PyScene& s) { return py::make_tuple(FromJson(s.json), s.source); },
           "(json, source): what the scene was parsed from (for functions that re-parse it)")
      .def_property_readonly("json", [](const PyScene& s) { return FromJson(s.json); },
                             "the scene's JSON as read (a copy: edit it and make a new Scene)")
      .def(py::pickle([](const PyScene& s) { return py::make_tuple(FromJson(s.json), s.source); },
                      [](py::tuple t) { return MakeScene(ToJson(t[0]), t[1].cast<std::string>()); }))
      .def("plan", [](const PyScene& s) { return ScenePipeline(*s.spec).PlanReport(); },
           "The compiled pipeline (`aosr simulate --plan`): stages, estimated time and memory.")
      .def("__repr__", [](const PyScene& s) {
        return "<aosr.Scene " + s.spec->name + ": " + std::to_string(s.spec->frames) + " frames of " +
               ToString(s.spec->frame) + ", r = " + std::to_string(s.spec->r) + ">";
      });

  m.def(
      "simulate",
      [](const PyScene& scene, std::optional<std::uint64_t> seed, py::object calibration, py::object output,
         py::object progress) {
        nlohmann::json json = scene.json;
        std::optional<std::string> out;
        if (!output.is_none()) out = PathString(output);
        std::optional<std::string> cal;
        if (!calibration.is_none()) cal = PathString(calibration);
        PythonProgress poll(progress);
        const ProgressCallback callback = poll.Callback();
        bool cancelled = false;
        std::optional<Dataset> d = WithoutGil([&]() -> std::optional<Dataset> {
          // As `aosr simulate [--set seed=S] [--calibration C] [-o OUT]`: the same JSON, the same parse.
          if (seed) json["seed"] = *seed;
          SceneSpec spec = ParseScene(json, scene.source);
          if (cal) {
            const Calibration c = LoadCalibration(*cal);
            for (DmOffset& o : spec.offsets.frames) o = DmResponse(o, c);
            json["comment_calibration"] = "offsets applied through the DM gains of " + *cal +
                                          " (the manifest's offsets are the applied ones)";
          }
          const ScenePipeline pipeline(std::move(spec));
          if (out) PrepareSimulationOutput(*out, pipeline.scene());
          const Simulation sim = pipeline.Run(callback);
          if (sim.cancelled) {
            cancelled = true;
            return std::nullopt;
          }
          if (out) WriteSimulation(*out, pipeline.scene(), pipeline, sim, &json);
          return DatasetFromSimulation(pipeline.scene(), sim);
        });
        poll.RaiseIfPending();  // Ctrl-C (KeyboardInterrupt) or the progress callable's exception
        if (cancelled) return py::object(py::none());
        return WrapDataset(std::move(*d));
      },
      py::arg("scene"), py::kw_only(), py::arg("seed") = py::none(), py::arg("calibration") = py::none(),
      py::arg("output") = py::none(), py::arg("progress") = py::none(),
      R"doc(Simulates the scene's N frames (object, optics, AO, DM offsets, detector) and returns the dataset; a scene
with a `sequence` gives its M frames cycling through the N phases, with Dataset.times_s, .slots and (when objects
move or vary) .truth_frames, the truth at each frame's time.

seed         replaces the scene's seed (as `aosr simulate --set seed=S`); None keeps it. Same scene and seed:
             the same bytes.
calibration  a calibration.json: the simulated DM applies each commanded mode times its gain
output       also write the dataset folder (frames.fits, ..., manifest.json) as `aosr simulate -o` does
progress     optional callable(dict) called after the object, each distinct PSF and each later stage (stage
             'simulate', iteration of total steps); returning False cancels: then None is returned and no dataset
             is written. Ctrl-C stops the run at the next step and raises KeyboardInterrupt.

The returned Dataset holds what open_dataset() would read from that folder, bit for bit.)doc");

  py::class_<PyDataset>(m, "Dataset",
                        R"doc(A dataset: N frames with their masks, weights, PSFs, offsets and (for simulations) truth.

Arrays follow image.hpp: (rows, cols) = (y, x); stacks are (N, rows, cols). Stacks are read-only copies made
once per dataset; truth is a read-only view (no copy). Frames are in ADU; frames_electrons() converts.
Make one with aosr.simulate, aosr.open_dataset(path) or aosr.Dataset.from_arrays(...).)doc")
      .def_static(
          "from_arrays",
          [](py::handle frames, py::handle psfs, int r, double gain, double bias, py::handle valid, py::handle weights,
             py::handle truth, py::handle nominal_psfs, py::handle offsets, int trustworthy_border_px,
             double camera_pixel_rad, double wavelength_m) {
            DatasetArrays a;
            a.frames = StackFromArray(frames, "frames");
            a.psfs = StackFromArray(psfs, "psfs");
            a.r = r;
            a.gain_e_per_adu = gain;
            a.bias_adu = bias;
            if (!valid.is_none()) a.valid = StackFromArray(valid, "valid");
            if (!weights.is_none()) a.weights = StackFromArray(weights, "weights");
            if (!truth.is_none()) a.truth = ImageFromArray(truth, "truth");
            if (!nominal_psfs.is_none()) a.nominal_psfs = StackFromArray(nominal_psfs, "nominal_psfs");
            a.offsets = ShiftOffsets(offsets);
            a.trustworthy_border_px = trustworthy_border_px;
            a.camera_pixel_rad = camera_pixel_rad;
            a.wavelength_m = wavelength_m;
            return WrapDataset(DatasetFromArrays(std::move(a)));
          },
          py::arg("frames"), py::arg("psfs"), py::kw_only(), py::arg("r"), py::arg("gain") = 1.0, py::arg("bias") = 0.0,
          py::arg("valid") = py::none(), py::arg("weights") = py::none(), py::arg("truth") = py::none(),
          py::arg("nominal_psfs") = py::none(), py::arg("offsets") = py::none(), py::arg("trustworthy_border_px") = -1,
          py::arg("camera_pixel_rad") = 0.0, py::arg("wavelength_m") = 0.0,
          R"doc(A dataset from your own arrays, checked and normalised exactly as a manifest with "psfs" is
(include/aosr/scene/dataset.hpp).

frames   (N, rows, cols) ADU          psfs     (N, K, K) or (K, K) shared, HR sampling, K even; renormalised
r        super-resolution factor      gain, bias   e- per ADU, pedestal ADU
valid    (N, rows, cols) of 1/0       weights  (N, rows, cols) inverse variances, ADU^-2
truth    (r*rows, r*cols) e-/frame    nominal_psfs  model PSFs (as psfs)
offsets  [(dy, dx), ...] camera-pixel shifts per frame (for shift-add/drizzle 'dm' offsets)
Arrays are copied into the dataset (float64, C order); non-finite frame pixels become invalid.)doc")
      .def("__len__", [](const PyDataset& d) { return d.dataset->size(); })
      .def_property_readonly("r", [](const PyDataset& d) { return d.dataset->r; })
      .def_property_readonly("frame_shape", [](const PyDataset& d) { return py::make_tuple(d.dataset->frame.rows, d.dataset->frame.cols); })
      .def_property_readonly("hr_shape", [](const PyDataset& d) { return py::make_tuple(d.dataset->hr_frame.rows, d.dataset->hr_frame.cols); })
      .def_property_readonly("frames", [](py::object self) {
        return Cached(self, "frames", [&] { return StackToArray(self.cast<PyDataset&>().dataset->frames); });
      }, "(N, rows, cols) recorded frames, ADU")
      .def_property_readonly("valid", [](py::object self) {
        return Cached(self, "valid", [&] { return StackToArray(self.cast<PyDataset&>().dataset->valid); });
      }, "(N, rows, cols) masks: 1 usable, 0 bad or saturated")
      .def_property_readonly("weights", [](py::object self) -> py::object {
        const auto& w = self.cast<PyDataset&>().dataset->weights;
        if (!w) return py::none();
        return Cached(self, "weights", [&] { return StackToArray(*w); });
      }, "(N, rows, cols) inverse variances, ADU^-2 (0 where invalid), or None")
      .def_property_readonly("psfs", [](py::object self) {
        return Cached(self, "psfs", [&] { return StackToArray(self.cast<PyDataset&>().dataset->psfs); });
      }, "(N, K, K) PSFs at HR sampling, each of unit sum")
      .def_property_readonly("nominal_psfs", [](py::object self) -> py::object {
        const ImageStack& p = self.cast<PyDataset&>().dataset->nominal_psfs;
        if (p.empty()) return py::none();
        return Cached(self, "nominal_psfs", [&] { return StackToArray(p); });
      }, "(N, K, K) nominal model PSFs (closed-loop simulations), or None")
      .def_property_readonly("psf_field", [](py::object self) -> py::object {
        const auto& f = self.cast<PyDataset&>().dataset->psf_field;
        if (!f) return py::none();
        auto flat = [](const std::vector<ImageStack>& nodes) {
          ImageStack planes;
          for (const ImageStack& n : nodes) planes.insert(planes.end(), n.begin(), n.end());
          py::array a = StackToArray(planes);
          const std::size_t k = nodes.size(), n = nodes.front().size();
          return a.reshape({py::ssize_t(k), py::ssize_t(n), a.shape(1), a.shape(2)});
        };
        py::list nodes;
        for (int k = 0; k < f->grid.nodes(); ++k) {
          const auto p = f->grid.Node(k);
          nodes.append(py::make_tuple(p[0], p[1]));
        }
        py::dict d;
        d["grid"] = py::make_tuple(f->grid.ny(), f->grid.nx());
        d["nodes_hr_px"] = nodes;
        d["psfs"] = flat(f->psfs);
        d["nominal_psfs"] = f->nominal_psfs.empty() ? py::object(py::none()) : py::object(flat(f->nominal_psfs));
        d["guide_star_arcsec"] = py::make_tuple(f->guide_star_x_arcsec, f->guide_star_y_arcsec);
        return d;
      }, "the PSF across the field (a scene's psf_field), or None: {'grid': (ny, nx), 'nodes_hr_px': [(y, x)] "
         "row-major, 'psfs': (ny*nx, N, K, K) unit sum, 'nominal_psfs': the same or None, 'guide_star_arcsec': (x, y)}")
      .def_property_readonly("truth", [](py::object self) -> py::object {
        const auto& t = self.cast<PyDataset&>().dataset->truth;
        if (!t) return py::none();
        return ViewImage(*t, self, false);
      }, "the HR object (r*rows, r*cols), e- per frame per HR pixel (a read-only view), or None")
      .def_property_readonly("truth_frames", [](py::object self) -> py::object {
        const ImageStack& t = self.cast<PyDataset&>().dataset->truth_frames;
        if (t.empty()) return py::none();
        return Cached(self, "truth_frames", [&] { return StackToArray(t); });
      }, "(N, r*rows, r*cols) the truth at each frame's time (a sequence whose objects change), or None")
      .def_property_readonly("times_s", [](const PyDataset& d) -> py::object {
        const std::vector<double>& t = d.dataset->times_s;
        if (t.empty()) return py::none();
        return py::array_t<double>(py::ssize_t(t.size()), t.data());
      }, "(N,) each frame's time in seconds (a sequence's; simulations: mid-exposure), or None")
      .def_property_readonly("slots", [](const PyDataset& d) {
        std::vector<int> s = d.dataset->slots;
        if (s.size() != d.dataset->frames.size())
          for (int i = int(s.size()); i < d.dataset->size(); ++i) s.push_back(i);
        return s;
      }, "each frame's DM phase (slot), 0..phases-1 (frame i is phase i without a sequence)")
      .def_property_readonly("phases", [](const PyDataset& d) {
        return d.dataset->slot_count > 0 ? d.dataset->slot_count : d.dataset->size();
      }, "the number of DM phases the frames cycle through (the frame count without a sequence)")
      .def_property_readonly("offsets", [](const PyDataset& d) {
        py::list out;
        for (const DmOffset& o : d.dataset->offsets) out.append(FromJson(DmOffsetToJson(o)));
        return out;
      }, "the N DM offsets as the manifest writes them ({'shift_px': [dy, dx], 'zernike': [...], ...})")
      .def_property_readonly("masks", [](py::object self) { return self.attr("valid"); }, "= valid")
      .def_property_readonly("shifts", [](const PyDataset& d) {
        py::array_t<double> a({py::ssize_t(d.dataset->offsets.size()), py::ssize_t(2)});
        auto v = a.mutable_unchecked<2>();
        for (std::size_t i = 0; i < d.dataset->offsets.size(); ++i) {
          v(i, 0) = d.dataset->offsets[i].shift_y_px;
          v(i, 1) = d.dataset->offsets[i].shift_x_px;
        }
        return a;
      }, "(N, 2) the DM offsets' image shifts (dy, dx) in camera pixels")
      .def_property_readonly("stars", [](const PyDataset& d) {
        py::array_t<double> a({py::ssize_t(d.dataset->stars.size()), py::ssize_t(3)});
        auto v = a.mutable_unchecked<2>();
        for (std::size_t i = 0; i < d.dataset->stars.size(); ++i) {
          v(i, 0) = d.dataset->stars[i].y;
          v(i, 1) = d.dataset->stars[i].x;
          v(i, 2) = d.dataset->stars[i].flux;
        }
        return a;
      }, "(n, 3) star catalogue: y, x (HR pixels), flux (e- per frame)")
      .def_property_readonly("gain", [](const PyDataset& d) { return d.dataset->gain_e_per_adu; }, "e- per ADU")
      .def_property_readonly("bias", [](const PyDataset& d) { return d.dataset->bias_adu; }, "pedestal, ADU")
      .def_property_readonly("trustworthy_border_px", [](const PyDataset& d) { return d.dataset->trustworthy_border_px; },
                             "camera pixels of each edge a periodic model cannot reproduce")
      .def_property_readonly("camera_pixel_rad", [](const PyDataset& d) { return d.dataset->camera_pixel_rad; })
      .def_property_readonly("wavelength_m", [](const PyDataset& d) { return d.dataset->wavelength_m; })
      .def_property_readonly("manifest_path", [](const PyDataset& d) { return d.dataset->manifest_path; },
                             "the manifest read ('' for datasets made in memory)")
      .def_property_readonly("manifest", [](const PyDataset& d) { return FromJson(d.dataset->manifest); })
      .def(
          "hr_header",
          [](const PyDataset& d, const std::string& bunit) {
            FitsHeader h;
            SetHrImageKeywords(*d.dataset, bunit, &h);
            return HeaderToDict(h);
          },
          py::arg("bunit") = "electron",
          "FITS keywords of an HR image of this dataset (a reconstruction): the HR grid's WCS when the dataset has\n"
          "sky coordinates, and BUNIT; a dict astropy.io.fits.Header accepts (what `aosr reconstruct` writes).")
      .def_property_readonly("has_wcs", [](const PyDataset& d) { return d.dataset->wcs.has_value(); },
                             "whether the dataset carries sky coordinates (frame 0's WCS)")
      .def("frames_electrons", [](const PyDataset& d) { return StackToArray(d.dataset->FramesElectrons()); },
           "(N, rows, cols) frames in electrons: (ADU - bias) * gain (a new array)")
      .def("__repr__", [](const PyDataset& d) {
        return "<aosr.Dataset " + std::to_string(d.dataset->size()) + " frames of " + ToString(d.dataset->frame) +
               ", r = " + std::to_string(d.dataset->r) + (d.dataset->truth ? ", with truth" : "") +
               (d.dataset->manifest_path.empty() ? "" : " (" + d.dataset->manifest_path + ")") + ">";
      })
      // Pickled as its arrays (Dask ships datasets to workers this way); the manifest path and JSON are kept.
      .def(py::pickle(
          [](py::object self) {
            const Dataset& d = *self.cast<PyDataset&>().dataset;
            py::dict s;
            s["frames"] = StackToArray(d.frames);
            s["valid"] = StackToArray(d.valid);
            s["weights"] = d.weights ? py::object(StackToArray(*d.weights)) : py::none();
            s["psfs"] = StackToArray(d.psfs);
            s["nominal_psfs"] = d.nominal_psfs.empty() ? py::none() : py::object(StackToArray(d.nominal_psfs));
            s["truth"] = d.truth ? py::object(ViewImage(*d.truth, self, false)) : py::none();
            s["truth_frames"] = d.truth_frames.empty() ? py::none() : py::object(StackToArray(d.truth_frames));
            s["slots"] = d.slots;
            s["slot_count"] = d.slot_count;
            s["times_s"] = d.times_s;
            py::list offsets;
            for (const DmOffset& o : d.offsets) offsets.append(FromJson(DmOffsetToJson(o)));
            s["offsets"] = offsets;
            py::list stars;
            for (const PointSource& p : d.stars) stars.append(py::make_tuple(p.y, p.x, p.flux));
            s["stars"] = stars;
            s["r"] = d.r;
            s["gain"] = d.gain_e_per_adu;
            s["bias"] = d.bias_adu;
            s["border"] = d.trustworthy_border_px;
            s["camera_pixel_rad"] = d.camera_pixel_rad;
            s["wavelength_m"] = d.wavelength_m;
            s["manifest_path"] = d.manifest_path;
            s["manifest"] = FromJson(d.manifest);
            s["expected_file"] = d.expected_file;
            FitsHeader wcs;
            if (d.wcs) WriteWcs(*d.wcs, &wcs);
            s["wcs"] = d.wcs ? py::object(HeaderToDict(wcs)) : py::none();
            return s;
          },
          [](py::dict s) {
            // Restored field by field (not through DatasetFromArrays): the pickled dataset is already normalised,
            // and dividing a unit-sum PSF by its sum again could move its last bit.
            Dataset d;
            d.frames = StackFromArray(s["frames"], "frames");
            d.valid = StackFromArray(s["valid"], "valid");
            if (!s["weights"].is_none()) d.weights = StackFromArray(s["weights"], "weights");
            d.psfs = StackFromArray(s["psfs"], "psfs");
            if (!s["nominal_psfs"].is_none()) d.nominal_psfs = StackFromArray(s["nominal_psfs"], "nominal_psfs");
            if (!s["truth"].is_none()) d.truth = ImageFromArray(s["truth"], "truth");
            if (s.contains("truth_frames") && !s["truth_frames"].is_none())
              d.truth_frames = StackFromArray(s["truth_frames"], "truth_frames");
            if (s.contains("slots")) {
              d.slots = s["slots"].cast<std::vector<int>>();
              d.slot_count = s["slot_count"].cast<int>();
              d.times_s = s["times_s"].cast<std::vector<double>>();
            }
            for (py::handle o : s["offsets"]) {
              // DmOffsetToJson's inline-design form, parsed back through a one-frame design (scene_spec.hpp).
              const nlohmann::json j = ToJson(o);
              DmOffset off;
              if (j.contains("shift_px")) {
                off.shift_y_px = j["shift_px"][0].get<double>();
                off.shift_x_px = j["shift_px"][1].get<double>();
              }
              if (j.contains("zernike"))
                for (const auto& z : j["zernike"]) off.zernike.push_back({z["noll"].get<int>(), z["rms_nm"].get<double>() * 1e-9});
              if (j.contains("actuators_nm"))
                for (const auto& a : j["actuators_nm"]) off.actuators_m.push_back(a.get<double>() * 1e-9);
              d.offsets.push_back(off);
            }
            for (py::handle p : s["stars"]) {
              const py::tuple t = py::reinterpret_borrow<py::tuple>(p);
              d.stars.push_back({t[0].cast<double>(), t[1].cast<double>(), t[2].cast<double>()});
            }
            d.r = s["r"].cast<int>();
            d.frame = ShapeOf(d.frames.front());
            d.hr_frame = {d.frame.rows * d.r, d.frame.cols * d.r};
            d.gain_e_per_adu = s["gain"].cast<double>();
            d.bias_adu = s["bias"].cast<double>();
            d.trustworthy_border_px = s["border"].cast<Index>();
            d.camera_pixel_rad = s["camera_pixel_rad"].cast<double>();
            d.wavelength_m = s["wavelength_m"].cast<double>();
            d.manifest_path = s["manifest_path"].cast<std::string>();
            d.manifest = ToJson(s["manifest"]);
            d.expected_file = s["expected_file"].cast<std::string>();
            if (s.contains("wcs") && !s["wcs"].is_none()) d.wcs = WcsFromHeader(HeaderFromDict(s["wcs"], py::none()));
            PyDataset p;
            p.dataset = std::make_shared<const Dataset>(std::move(d));
            return p;
          }));

  m.def(
      "open_dataset",
      [](py::handle path) {
        const std::string p = PathString(path);
        return WrapDataset(WithoutGil([&] { return LoadDataset(p); }));
      },
      py::arg("path"),
      "Reads a dataset folder (or its manifest.json): what `aosr simulate -o` writes, or a hand-written manifest of\n"
      "measured frames (include/aosr/scene/dataset.hpp). Errors name the manifest and field.");

  m.def(
      "_dataset_input_files",
      [](py::handle path) {
        std::vector<std::string> out;
        for (const auto& f : DatasetInputFiles(PathString(path))) out.push_back(f.string());
        return out;
      },
      py::arg("path"),
      "Internal: the resolved paths of a dataset's manifest and the files it names (what an output must never\n"
      "replace; the CLI's rule). Empty for a manifest it cannot read.");

  m.def(
      "evaluate",
      [](py::handle estimate, py::handle truth, py::handle dataset, std::optional<int> crop, double peak, int stars,
         double aperture, std::optional<bool> subtract_sky, int rings, py::object ring_centre) {
        // As `aosr evaluate` (src/cli/evaluate_command.cpp): exactly one of truth and dataset.
        if (truth.is_none() == dataset.is_none())
          throw InvalidArgument("aosr.evaluate", "truth/dataset", truth.is_none() ? "(neither)" : "(both)",
                                "exactly one of truth= (array or FITS path) and dataset=");
        CheckArgument(!crop || *crop >= 0, "aosr.evaluate", "crop", crop.value_or(0), ">= 0 or None");
        CheckArgument(rings >= 0, "aosr.evaluate", "rings", rings, ">= 0 (0: no rings)");
        double centre_x = std::numeric_limits<double>::quiet_NaN(), centre_y = centre_x;
        if (!ring_centre.is_none()) {
          std::vector<double> xy;
          try {
            xy = ring_centre.cast<std::vector<double>>();
          } catch (const py::cast_error&) {
            xy.clear();
          }
          CheckArgument(xy.size() == 2 && std::isfinite(xy[0]) && std::isfinite(xy[1]), "aosr.evaluate", "ring_centre",
                        py::str(ring_centre).cast<std::string>(),
                        "(x, y): two finite numbers, column then row in HR px, or None for the image centre");
          CheckArgument(rings > 0, "aosr.evaluate", "ring_centre", py::str(ring_centre).cast<std::string>(),
                        "only with rings=K (K >= 1)");
          centre_x = xy[0];
          centre_y = xy[1];
        }
        Image t;
        std::vector<PointSource> catalogue;
        int c = crop.value_or(0);
        double hr_mas = 0.0;
        if (!dataset.is_none()) {
          const std::shared_ptr<const Dataset> d = DatasetArgument(dataset, "aosr.evaluate");
          if (!d->truth) throw InvalidArgument("aosr.evaluate", "dataset", d->manifest_path, "a dataset with a truth image");
          t = *d->truth;
          catalogue = d->stars;
          if (!crop) c = DatasetCrop(d->trustworthy_border_px, d->r);
          hr_mas = DatasetHrPixelMas(*d);
        } else {
          t = ImageOrFits(truth, "truth");
          if (py::isinstance<py::str>(truth) || py::hasattr(truth, "__fspath__")) {
            const std::string path = PathString(truth);
            hr_mas = WithoutGil([&] { return FitsPixelScaleMas(path); });
          }
        }
        const Image e = ImageOrFits(estimate, "estimate");
        EvaluationOptions eo;
        eo.crop_px = c;
        eo.peak = peak;
        eo.stars = stars;
        eo.aperture_px = aperture;
        eo.hr_pixel_mas = hr_mas;
        eo.rings = rings;
        eo.ring_centre_y = centre_y;
        eo.ring_centre_x = centre_x;
        // None: as `aosr evaluate --subtract-sky auto`, from the file's METHOD keyword (an array has none).
        if (subtract_sky) {
          eo.subtract_sky = *subtract_sky;
        } else if (py::isinstance<py::str>(estimate) || py::hasattr(estimate, "__fspath__")) {
          const std::string path = PathString(estimate);
          eo.subtract_sky = WithoutGil([&] { return OutputKeepsSky(path); });
        }
        const Evaluation ev = WithoutGil([&] { return EvaluateReconstruction(t, e, catalogue, eo); });
        const ImageMetrics& im = ev.metrics;
        const StarMetrics& sm = ev.stars;
        py::dict j;
        j["crop_px"] = c;
        j["psnr_db"] = im.psnr;
        j["ssim"] = im.ssim;
        j["rmse"] = im.rmse;
        j["sky_subtracted"] = eo.subtract_sky ? py::object(py::float_(ev.sky)) : py::object(py::none());
        j["aligned"] = py::dict(py::arg("psnr_db") = ev.aligned.psnr, py::arg("ssim") = ev.aligned.ssim,
                                py::arg("rmse") = ev.aligned.rmse);
        j["offset_hr_px"] = py::dict(py::arg("dy") = ev.offset.dy, py::arg("dx") = ev.offset.dx);
        j["offset_measured_hr_px"] =
            py::dict(py::arg("dy") = ev.measured_offset.dy, py::arg("dx") = ev.measured_offset.dx);
        j["offset_applied"] = ev.offset_applied;
        if (ev.offset_mas_known)
          j["offset_mas"] = py::dict(py::arg("dy") = ev.offset_mas[0], py::arg("dx") = ev.offset_mas[1]);
        else
          j["offset_mas"] = py::none();
        if (ev.measured_stars) {
          py::list list;
          for (const StarMeasurement& s : sm.stars) {
            py::dict st;
            st["y_hr_px"] = s.truth.y;
            st["x_hr_px"] = s.truth.x;
            st["flux_e"] = s.truth.flux;
            st["flux_error"] = s.flux_error;
            st["dy_hr_px"] = s.dy;
            st["dx_hr_px"] = s.dx;
            list.append(st);
          }
          py::dict sd;
          sd["measured"] = sm.stars.size();
          sd["skipped_at_edge"] = sm.skipped;
          sd["median_abs_flux_error"] = sm.median_abs_flux_error;
          sd["rms_position_error_hr_px"] = sm.rms_position_error_px;
          sd["aperture_hr_px"] = aperture;
          sd["brightest"] = list;
          j["stars"] = sd;
        }
        if (ev.measured_rings) j["rings"] = FromJson(EvaluationRingsJson(ev, hr_mas));
        return j;
      },
      py::arg("estimate"), py::kw_only(), py::arg("truth") = py::none(), py::arg("dataset") = py::none(),
      py::arg("crop") = py::none(), py::arg("peak") = 0.0, py::arg("stars") = 20, py::arg("aperture") = 3.0,
      py::arg("subtract_sky") = py::none(), py::arg("rings") = 0, py::arg("ring_centre") = py::none(),
      R"doc(Compares a reconstruction with the truth, as `aosr evaluate`: PSNR [dB], SSIM, RMSE, raw and after removing
the global sub-pixel offset of the estimate against the truth ('aligned'), the offset itself ('offset_hr_px' and,
when the dataset or the truth file's PIXSCALE gives the pixel scale, 'offset_mas'; else None) and, for a dataset
with a star list, the aperture photometry and centroid errors of the brightest `stars`.

estimate  2-D array or FITS path (the HR grid)
truth     2-D array or FITS path; or dataset= (an aosr.Dataset or path) whose truth and stars are used
crop      pixels ignored at each border; default the dataset's trustworthy border (r * border px), else 0
peak      PSNR/SSIM dynamic range L (0: max - min of the truth)
subtract_sky  remove the estimate's sky (its median level minus the truth's over the scored region) before scoring;
          None: when the estimate is a FITS file whose METHOD is linear (an output that keeps the frames' sky), as
          `aosr evaluate --subtract-sky auto`. 'sky_subtracted' says what was removed (None when not asked)
rings     K >= 1: also score K concentric rings about ring_centre, each aligned on its own, with each ring's
          photometric bias when the dataset has a star list ('rings': {'count', 'centre_hr_px': {'x', 'y'}, 'peak',
          'rings': [...]}, as `aosr evaluate --rings K --json`); 0 (default): none
ring_centre  (x, y) [HR px: column, row; 0-based pixel centres], e.g. the guide star; None: the image centre
The offset is measured on the scored crop and applied only when it lowers neither PSNR nor SSIM there
('offset_applied'; 'offset_measured_hr_px' is what was found), so the aligned scores are never below the raw ones.
Returns the dict `aosr evaluate --json` prints (without 'estimate').)doc");
}

}  // namespace aosr::python
