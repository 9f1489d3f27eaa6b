// Bindings of the streaming solvers: aosr.video (solvers/video_stream.hpp, a dataset as a super-resolved movie)
// and aosr.watch (solvers/quick_look.hpp, the live quick-look of a folder a camera writes into). Their keyword
// options are aosr.reconstruct's (ReconstructTable, solvers.cpp), parsed as `aosr video` / `aosr watch` parse them.
#include <chrono>
#include <memory>
#include <optional>
#include <string>

#include "aosr/core/error.hpp"
#include "aosr/solvers/dataset_problem.hpp"
#include "aosr/solvers/quick_look.hpp"
#include "aosr/solvers/reconstruct.hpp"
#include "aosr/solvers/video_stream.hpp"
#include "bindings.hpp"
#include "common.hpp"

namespace aosr::python {
namespace {

// The streaming options of aosr.video and aosr.watch, parsed and checked as `aosr video` / `aosr watch` do.
VideoOptions StreamOptions(const char* fn, const std::string& method, const std::string& window, int tv_iterations,
                           bool slot_filter, const py::kwargs& kwargs) {
  VideoOptions vo;
  vo.reconstruct = CliDefaults();
  ReconstructTable().Apply(vo.reconstruct, kwargs);
  vo.method = ParseReconstructionMethod(method);
  vo.reconstruct.method = vo.method;
  vo.window = ParseVideoWindow(window);
  vo.tv_iterations = tv_iterations;
  vo.slot_filter = slot_filter;
  std::string why;
  if (!vo.IsValid(&why)) throw InvalidArgument(std::string(fn) + ": " + why);
  return vo;
}

DatasetProblemOptions StreamProblem(const char* fn, const std::string& weights, const py::object& model_psfs) {
  DatasetProblemOptions dpo;
  dpo.weights = ParseDatasetWeights(weights);
  if (py::isinstance<py::str>(model_psfs) && model_psfs.cast<std::string>() == "nominal")
    dpo.nominal_psfs = true;
  else if (py::isinstance<py::str>(model_psfs))
    throw InvalidArgument(fn, "model_psfs", model_psfs.cast<std::string>(),
                          "'nominal' | an (N, K, K) array (one per phase, or one shared)");
  else if (!model_psfs.is_none())
    dpo.model_psfs = StackFromArray(model_psfs, "model_psfs");
  return dpo;
}

// aosr.video's iterator: the library's DatasetVideo (solvers/video_stream.hpp), one output per __next__.
struct PyVideoStream {
  std::unique_ptr<DatasetVideo> video;
  std::string method, window;
  int phases = 0;
  bool info = false;
  int limit = 0;     // 0: every output
  int produced = 0;
  bool done = false;
};

py::dict VideoSetupDict(const VideoSetup& s) {
  py::dict d;
  d["lambda_unweighted"] = s.lambda_unweighted >= 0 ? py::object(py::float_(s.lambda_unweighted)) : py::object(py::none());
  d["kappa"] = s.kappa > 0 ? py::object(py::float_(s.kappa)) : py::object(py::none());
  d["mu"] = s.mu >= 0 ? py::object(py::float_(s.mu)) : py::object(py::none());
  d["filter_built"] = s.filter_built;
  d["filter_seconds"] = s.filter_seconds;
  d["filter_outputs"] = s.filter_outputs;
  d["batch_outputs"] = s.batch_outputs;
  return d;
}

py::object VideoNext(PyVideoStream& v) {
  if (v.done || (v.limit > 0 && v.produced >= v.limit)) {
    v.done = true;
    throw py::stop_iteration();
  }
  std::optional<VideoFrame> f = WithoutGil([&] { return v.video->Next(); });
  if (!f) {
    v.done = true;
    throw py::stop_iteration();
  }
  ++v.produced;
  const double t = f->time_s;
  if (!v.info) return py::make_tuple(t, MoveImage(std::move(f->image)));
  py::dict info;
  info["index"] = f->index;
  info["time_s"] = f->time_s;
  info["window_start_s"] = f->window_start_s;
  info["frames"] = f->frames;
  info["path"] = f->path;
  info["iterations"] = f->iterations;
  info["seconds"] = f->seconds;
  info["summary"] = SummaryDict(f->summary);
  return py::make_tuple(t, MoveImage(std::move(f->image)), info);
}

// aosr.watch's iterator: the library's QuickLook (solvers/quick_look.hpp), one event per file.
struct PyQuickLook {
  std::unique_ptr<QuickLook> quick_look;
  std::string directory, method, window;
  int max_files = 0;         // 0: no limit
  double idle_timeout = 0;   // s; 0: wait for ever
  int files = 0;
  bool done = false;
};

py::object QuickLookNext(PyQuickLook& q) {
  if (q.done || (q.max_files > 0 && q.files >= q.max_files)) {
    q.done = true;
    throw py::stop_iteration();
  }
  const auto start = std::chrono::steady_clock::now();
  for (;;) {
    // Short waits without the GIL; Ctrl-C (KeyboardInterrupt) is seen between them.
    std::optional<QuickLookEvent> e = WithoutGil([&] { return q.quick_look->Next(0.2); });
    if (e) {
      ++q.files;
      py::dict d;
      d["file"] = e->file;
      d["status"] = e->status;
      d["message"] = e->message;
      d["phase"] = e->slot >= 0 ? py::object(py::int_(e->slot)) : py::object(py::none());
      d["frame"] = e->frame >= 0 ? py::object(py::int_(e->frame)) : py::object(py::none());
      d["time_s"] = e->time_s;
      d["read_s"] = e->read_s;
      d["reconstruct_s"] = e->reconstruct_s;
      d["write_s"] = e->write_s;
      d["written_output"] = e->written_output >= 0 ? py::object(py::int_(e->written_output)) : py::object(py::none());
      d["latency_s"] = e->written_output >= 0 ? py::object(py::float_(e->latency_s)) : py::object(py::none());
      if (e->output) {
        d["output"] = e->output->index;
        d["frames"] = e->output->frames;
        d["path"] = e->output->path;
        d["image"] = MoveImage(std::move(e->output->image));
      } else {
        d["output"] = py::none();
        d["frames"] = py::none();
        d["path"] = py::none();
        d["image"] = py::none();
      }
      return std::move(d);
    }
    if (PyErr_CheckSignals() != 0) throw py::error_already_set();
    const double waited = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    if (q.idle_timeout > 0 && waited >= q.idle_timeout) {
      q.done = true;
      throw py::stop_iteration();
    }
  }
}
}  // namespace

void BindStreaming(py::module_& m) {
  py::class_<PyVideoStream, std::shared_ptr<PyVideoStream>>(
      m, "VideoStream",
      "What aosr.video returns: an iterator of the super-resolved outputs of a frame sequence, computed one per\n"
      "next() (the library's DatasetVideo, include/aosr/solvers/video_stream.hpp).")
      .def("__iter__", [](py::object self) { return self; })
      .def("__next__", &VideoNext,
           "The next output: (time_s, image) or, with info=True, (time_s, image, info); StopIteration at the end.")
      .def_property_readonly("setup", [](const PyVideoStream& v) { return VideoSetupDict(v.video->engine().setup()); },
                             "what was chosen once: {'lambda_unweighted' (tikhonov: lambda of unit-weight frames), "
                             "'kappa' (linear), 'mu' (tv): None until chosen, 'filter_built', 'filter_seconds', "
                             "'filter_outputs', 'batch_outputs'}")
      .def_property_readonly("frames_total", [](const PyVideoStream& v) { return v.video->frames_total(); })
      .def_property_readonly("frames_read", [](const PyVideoStream& v) { return v.video->frames_read(); })
      .def_property_readonly("phases", [](const PyVideoStream& v) { return v.phases; }, "N: the DM phases (slots)")
      .def_property_readonly("weights_source", [](const PyVideoStream& v) { return v.video->weights_source(); })
      .def("__repr__", [](const PyVideoStream& v) {
        return "<aosr.VideoStream " + v.method + ", " + v.window + " window, " + std::to_string(v.phases) + " phases: " +
               std::to_string(v.video->frames_read()) + " of " + std::to_string(v.video->frames_total()) +
               " frames read, " + std::to_string(v.produced) + " outputs>";
      });

  m.def(
      "video",
      [](py::object dataset, const std::string& method, const std::string& window, const std::string& weights,
         py::object model_psfs, double frame_rate, int tv_iterations, bool slot_filter, bool info, int limit,
         py::kwargs kwargs) {
        constexpr const char* kFn = "aosr.video";
        // Everything is parsed and checked before any work (as `aosr video` does).
        const VideoOptions vo = StreamOptions(kFn, method, window, tv_iterations, slot_filter, kwargs);
        if (limit < 0) throw InvalidArgument(kFn, "limit", std::to_string(limit), ">= 0 (0: every output)");
        const DatasetProblemOptions dpo = StreamProblem(kFn, weights, model_psfs);
        const std::shared_ptr<const Dataset> d = DatasetArgument(dataset, kFn);
        auto out = std::make_shared<PyVideoStream>();
        out->method = ToString(vo.method);
        out->window = ToString(vo.window);
        out->info = info;
        out->limit = limit;
        out->phases = d->slot_count > 0 ? d->slot_count : d->size();
        WithoutGil([&] { out->video = std::make_unique<DatasetVideo>(*d, vo, dpo, frame_rate); });
        if (!out->video->warning().empty() &&
            PyErr_WarnEx(PyExc_UserWarning, (std::string(kFn) + ": " + out->video->warning()).c_str(), 1) != 0)
          throw py::error_already_set();
        return out;
      },
      py::arg("dataset"), py::arg("method") = "tikhonov", py::arg("window") = "sliding", py::kw_only(),
      py::arg("weights") = "auto", py::arg("model_psfs") = py::none(), py::arg("frame_rate") = 1.0,
      py::arg("tv_iterations") = 10, py::arg("slot_filter") = true, py::arg("info") = false, py::arg("limit") = 0,
      R"doc(A super-resolved movie of a frame sequence, one output at a time: the library's streaming engine
(include/aosr/solvers/video_stream.hpp), what `aosr video DATASET -o DIR` runs, with the same defaults and bits.

    for t, image in aosr.video("seq/", "linear"):          # image: (r*rows, r*cols) float64, e- per HR pixel
        ...

dataset   an aosr.Dataset or a dataset folder / manifest path: a manifest `sequence` ({"slots": the DM phase of
          each frame, "times_s": their times}; include/aosr/scene/dataset.hpp), or any dataset as one cycle
method    'tikhonov' (lambda given, else chosen once by lambda_rule on the first window, then fixed) | 'linear'
          (the target-PSF output) | 'tv' (warm-started from the previous output, tv_iterations ADMM iterations each)
window    'sliding': an output after every frame once each phase has one, from the latest frame of each phase;
          'cycle': one output per full cycle (each phase with a new frame)
weights, model_psfs   as aosr.reconstruct (weights resolved once over the whole sequence); model_psfs 'nominal'
          or an array (one per phase, or one shared)
frame_rate  frames per second, for times index / rate when the dataset has none
slot_filter False: the batch solver on every window (to compare); the filter applies where it is exact
info      True: yield (time_s, image, info) with info = {'index', 'time_s', 'window_start_s', 'frames' (the input
          frame of each phase), 'path' ('slot-filter' | 'batch' | 'tv' | 'tv-warm'), 'iterations', 'seconds',
          'summary'}; False: (time_s, image)
limit     stop after this many outputs (0: all)
**options aosr.reconstruct's options (lambda_, lambda_rule, prior, target_psf, leakage, mu, iterations: the first
          tv window's limit, tikhonov_*, linear_*, tv_*, ...)

Linear outputs equal aosr.reconstruct of the same window (frames in time order) to rounding: per-phase Fourier
weights are made once, then each output costs one FFT of the new frame, an N-term sum per frequency and one HR
inverse FFT. Windows with non-uniform weights fall back to the batch solver. Returns an aosr.VideoStream
(iterator; its setup, frames_read, frames_total, phases, weights_source describe the run). Everything is checked
when called: InvalidArgument (a ValueError) naming the argument, IoError for an unreadable dataset.)doc");

  py::class_<PyQuickLook, std::shared_ptr<PyQuickLook>>(
      m, "QuickLook",
      "What aosr.watch returns: an iterator of one event (a dict) per file the camera writes into the folder\n"
      "(the library's QuickLook, include/aosr/solvers/quick_look.hpp).")
      .def("__iter__", [](py::object self) { return self; })
      .def("__next__", &QuickLookNext,
           "The next file's event; StopIteration after max_files files or idle_timeout seconds without one.")
      .def_property_readonly("used", [](const PyQuickLook& q) { return q.quick_look->used(); })
      .def_property_readonly("outputs", [](const PyQuickLook& q) { return q.quick_look->outputs(); })
      .def_property_readonly("late", [](const PyQuickLook& q) { return q.quick_look->late(); })
      .def_property_readonly("rejected", [](const PyQuickLook& q) { return q.quick_look->rejected(); })
      .def_property_readonly("incomplete", [](const PyQuickLook& q) { return q.quick_look->incomplete(); })
      .def_property_readonly("superseded", [](const PyQuickLook& q) { return q.quick_look->superseded(); },
                             "outputs never written to the quick-look files: a newer file was already waiting")
      .def_property_readonly("inotify", [](const PyQuickLook& q) { return q.quick_look->using_inotify(); },
                             "True: the kernel reports new files (inotify); False: the folder is scanned")
      .def_property_readonly("phases", [](const PyQuickLook& q) { return q.quick_look->video().slot_count(); })
      .def("__repr__", [](const PyQuickLook& q) {
        return "<aosr.QuickLook " + q.directory + ": " + q.method + ", " + q.window + " window, " +
               std::to_string(q.files) + " files, " + std::to_string(q.quick_look->outputs()) + " outputs>";
      });

  m.def(
      "watch",
      [](py::object directory_path, py::object model, const std::string& method, const std::string& window,
         py::object output, const std::string& phase_key, py::object time_key, bool existing, int max_files,
         double idle_timeout, const std::string& weights, py::object model_psfs, int tv_iterations, bool slot_filter,
         bool png, double poll_interval, double abandon_after, py::kwargs kwargs) {
        constexpr const char* kFn = "aosr.watch";
        const std::string directory = py::str(directory_path).cast<std::string>();
        QuickLookOptions o;
        o.video = StreamOptions(kFn, method, window, tv_iterations, slot_filter, kwargs);
        o.problem = StreamProblem(kFn, weights, model_psfs);
        o.phase_key = phase_key;
        if (!time_key.is_none()) o.time_key = time_key.cast<std::string>();
        if (!output.is_none()) o.output_dir = py::str(output).cast<std::string>();
        o.write_png = png;
        o.watch.existing = existing;
        o.watch.poll_interval_s = poll_interval;
        o.watch.abandon_after_s = abandon_after;
        std::string why;
        if (!o.IsValid(&why)) throw InvalidArgument(std::string(kFn) + ": " + why);
        if (max_files < 0) throw InvalidArgument(kFn, "max_files", std::to_string(max_files), ">= 0 (0: no limit)");
        if (!(std::isfinite(idle_timeout) && idle_timeout >= 0))
          throw InvalidArgument(kFn, "idle_timeout", std::to_string(idle_timeout), "finite and >= 0 (0: wait for ever)");
        const std::shared_ptr<const Dataset> d = DatasetArgument(model, kFn);
        auto out = std::make_shared<PyQuickLook>();
        out->directory = directory;
        out->method = ToString(o.video.method);
        out->window = ToString(o.video.window);
        out->max_files = max_files;
        out->idle_timeout = idle_timeout;
        WithoutGil([&] { out->quick_look = std::make_unique<QuickLook>(directory, *d, o); });
        return out;
      },
      py::arg("directory"), py::arg("model"), py::arg("method") = "tikhonov", py::arg("window") = "sliding",
      py::kw_only(), py::arg("output") = py::none(), py::arg("phase_key") = "DMPHASE", py::arg("time_key") = py::none(),
      py::arg("existing") = false, py::arg("max_files") = 0, py::arg("idle_timeout") = 0.0, py::arg("weights") = "auto",
      py::arg("model_psfs") = py::none(), py::arg("tv_iterations") = 10, py::arg("slot_filter") = true,
      py::arg("png") = true, py::arg("poll_interval") = 1.0, py::arg("abandon_after") = 60.0,
      R"doc(Live quick-look: reconstructs the frames a camera writes into `directory` as each file completes (the
library's QuickLook, include/aosr/solvers/quick_look.hpp; what `aosr watch` runs, with the same defaults).

    for event in aosr.watch("/data/tonight", "model/", idle_timeout=30):
        if event["image"] is not None:
            show(event["image"])                 # (r*rows, r*cols) float64, e- per HR pixel

directory  the folder the camera writes into: one FITS file per frame (primary HDU or first image extension, the
           model's frame shape, ADU), the DM phase index (0-based) in header keyword phase_key
model      an aosr.Dataset or a dataset folder / manifest taken with the same design: the phases' PSFs, the detector
           (gain, bias, mask, noise level); as aosr.video reads it
method, window, weights, model_psfs, tv_iterations, slot_filter, **options   as aosr.video
output     a folder (must exist) where quicklook.fits and quicklook.png (png=False: FITS only) are replaced
           atomically after each output; None: nothing written
time_key   FITS keyword with the frame's time in seconds; None: the file's modification time (s since the start)
existing   also the frames already in the folder (in name order)
max_files  stop after this many files (0: no limit); idle_timeout: stop after this many seconds without one (0: never)
poll_interval, abandon_after   seconds between scans of the folder (the fallback without inotify) and before a
           half-written file that stopped changing is reported 'incomplete'

Each event is a dict: file, status ('used' | 'late': older than its phase's current frame | 'rejected': not a
usable frame | 'incomplete': never finished), message (why), phase, frame (number among the used frames), time_s,
output (the output's index or None), image (ndarray or None), frames (the frame used for each phase), path,
written_output (the output put in place during this event, or None: only the newest is written when files queue
up), latency_s (its file completed -> quick-look written, or None), read_s, reconstruct_s, write_s. Half-written
files are never read.
Ctrl-C raises KeyboardInterrupt between waits. Returns an aosr.QuickLook (its used, outputs, late, rejected,
incomplete, inotify, phases count the run). InvalidArgument (a ValueError) naming a bad argument, IoError for a
missing folder or an unreadable model.)doc");

}

}  // namespace aosr::python
