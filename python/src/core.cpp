// Bindings of the core layer: the error types, execution settings (threads, FFT planner, memory limit),
// the image metrics and the slanted-edge MTF.
#include <algorithm>
#include <cmath>
#include <thread>

#include "aosr/core/error.hpp"
#include "aosr/core/fft.hpp"
#include "aosr/core/memory.hpp"
#include "aosr/core/metrics.hpp"
#include "aosr/core/parallel.hpp"
#include "aosr/core/edge_search.hpp"
#include "aosr/core/slanted_edge.hpp"
#include "aosr/scene/telescope.hpp"
#include "common.hpp"

namespace aosr::python {
namespace {

// Python classes: aosr.Error(Exception) and one subclass per C++ error, each also the builtin a Python user
// would catch for it (a bad argument is a ValueError, a file problem an OSError, ...).
PyObject* NewException(py::module_& m, const char* name, PyObject* bases, const char* doc) {
  const std::string qualified = std::string("aosr.") + name;
  PyObject* type = PyErr_NewExceptionWithDoc(qualified.c_str(), doc, bases, nullptr);
  if (!type) throw py::error_already_set();
  m.add_object(name, py::handle(type));
  return type;
}

MetricOptions Metrics(int crop, double peak) {
  MetricOptions o;
  o.crop_px = crop;
  o.peak = peak;
  std::string why;
  if (!o.IsValid(&why)) throw InvalidArgument("aosr.compare_images: " + why);
  return o;
}

}  // namespace

void BindCore(py::module_& m) {
  static PyObject* error = nullptr;
  static PyObject* invalid = nullptr;
  static PyObject* io = nullptr;
  static PyObject* resource = nullptr;
  static PyObject* numerical = nullptr;
  error = NewException(m, "Error", PyExc_Exception, "Base class of every error aosr raises.");
  invalid = NewException(m, "InvalidArgument", py::make_tuple(py::handle(error), py::handle(PyExc_ValueError)).release().ptr(),
                         "A bad argument or file content; the message names the function, argument, value and what "
                         "is allowed. Also a ValueError.");
  io = NewException(m, "IoError", py::make_tuple(py::handle(error), py::handle(PyExc_OSError)).release().ptr(),
                    "A file could not be read or written; the message starts with the path. Also an OSError.");
  resource = NewException(m, "ResourceError", py::make_tuple(py::handle(error), py::handle(PyExc_MemoryError)).release().ptr(),
                          "A request that needs more memory than the limit (set_memory_limit). Also a MemoryError.");
  numerical = NewException(m, "NumericalError",
                           py::make_tuple(py::handle(error), py::handle(PyExc_ArithmeticError)).release().ptr(),
                           "A NaN/Inf that would otherwise leak into a result. Also an ArithmeticError.");
  py::register_exception_translator([](std::exception_ptr p) {
    if (!p) return;
    try {
      std::rethrow_exception(p);
    } catch (const InvalidArgument& e) {
      PyErr_SetString(invalid, e.what());
    } catch (const IoError& e) {
      // OSError(message) keeps str() equal to the C++ message; the path is an attribute too.
      py::object exc = py::reinterpret_steal<py::object>(PyObject_CallFunction(io, "s", e.what()));
      if (exc) {
        exc.attr("path") = e.path();
        PyErr_SetObject(io, exc.ptr());
      }
    } catch (const ResourceError& e) {
      PyErr_SetString(resource, e.what());
    } catch (const NumericalError& e) {
      PyErr_SetString(numerical, e.what());
    } catch (const Error& e) {
      PyErr_SetString(error, e.what());
    }
  });

  // As the CLI without --threads: every hardware thread (results do not depend on the count).
  SetDefaultThreads(std::min(int(std::max(1u, std::thread::hardware_concurrency())), 256));
  m.attr("__version__") = AOSR_VERSION;
  m.attr("_data_dir") = AOSR_SOURCE_DATA_DIR;
  m.def("_set_default_data_dir", &SetDefaultDataDirectory, py::arg("dir"),
        "Points the library's default data folder (telescope presets by name) at `dir`; $AOSR_DATA_DIR still wins.\n"
        "aosr/__init__.py calls it when the package ships its own data/ (a pip install).");

  m.def(
      "set_threads", [](int threads) {
        CheckArgument(threads >= 0 && threads <= 256, "aosr.set_threads", "threads", threads, "0 (all hardware threads) .. 256");
        const int hw = int(std::max(1u, std::thread::hardware_concurrency()));
        SetDefaultThreads(threads > 0 ? threads : std::min(hw, 256));
      },
      py::arg("threads"),
      "Sets the threads every aosr call uses (0: all hardware threads). Results are the same bytes for any count.\n"
      "aosr.distributed sets 1 per task, so that workers x tasks do not oversubscribe the cores.");
  m.def("threads", &DefaultThreads, "The thread count aosr calls use (set_threads).");
  m.def(
      "set_fft_planner", [](const std::string& planner) {
        FftSettings s = GetFftSettings();
        if (planner == "estimate" || planner == "heuristic") s.planner = FftSettings::Planner::kEstimate;
        else if (planner == "measure") s.planner = FftSettings::Planner::kMeasure;
        else if (planner == "patient") s.planner = FftSettings::Planner::kPatient;
        else
          throw InvalidArgument("aosr.set_fft_planner", "planner", planner,
                                "estimate | heuristic | measure | patient");
        s.shipped_wisdom = planner != "heuristic";
        SetFftSettings(s);
      },
      py::arg("planner"),
      "FFTW planning: 'estimate' (default, reproducible bytes: the plans aosr ships in its FFTW wisdom, FFTW's\n"
      "heuristics for other shapes), 'heuristic' (reproducible: FFTW_ESTIMATE's heuristics alone), 'measure' or\n"
      "'patient' (time candidates for shapes the wisdom lacks; the last bits of results then vary from run to run).\n"
      "The CLI's --fft-planner.");
  m.def("fft_wisdom_loaded", &FftWisdomLoaded,
        "Whether FFTW accepted aosr's shipped wisdom when the last plan was made (False before any transform, or\n"
        "when this FFTW build cannot read it: plans are then FFTW_ESTIMATE's, slower at 512^2 and up).");
  m.def(
      "set_memory_limit", [](const std::string& limit) { SetMemoryLimitBytes(ParseByteSize(limit, "limit")); },
      py::arg("limit"),
      "Refuse work whose estimated memory exceeds `limit` (e.g. '8G'), raising ResourceError before allocating.\n"
      "The CLI's --memory-limit.");
  m.def(
      "compare_images",
      [](py::handle truth, py::handle estimate, int crop, double peak) {
        const Image t = ImageFromArray(truth, "truth"), e = ImageFromArray(estimate, "estimate");
        const MetricOptions o = Metrics(crop, peak);
        const ImageMetrics r = WithoutGil([&] { return CompareImages(t, e, o); });
        py::dict d;
        d["psnr_db"] = r.psnr;
        d["ssim"] = r.ssim;
        d["rmse"] = r.rmse;
        d["crop_px"] = crop;
        return d;
      },
      py::arg("truth"), py::arg("estimate"), py::kw_only(), py::arg("crop") = 0, py::arg("peak") = 0.0,
      "PSNR [dB], SSIM and RMSE of `estimate` against `truth` (2-D arrays of one shape), ignoring `crop` pixels\n"
      "at each border. PSNR = 10 log10(L^2 / MSE) with L = `peak`, or max - min of the cropped truth when 0\n"
      "(include/aosr/core/metrics.hpp). Returns {'psnr_db', 'ssim', 'rmse', 'crop_px'}.");
  m.def(
      "compare_images_aligned",
      [](py::handle truth, py::handle estimate, int crop, double peak) {
        const Image t = ImageFromArray(truth, "truth"), e = ImageFromArray(estimate, "estimate");
        const MetricOptions o = Metrics(crop, peak);
        const AlignedImageMetrics r = WithoutGil([&] { return CompareImagesAligned(t, e, o); });
        py::dict d;
        d["psnr_db"] = r.raw.psnr;
        d["ssim"] = r.raw.ssim;
        d["rmse"] = r.raw.rmse;
        d["crop_px"] = crop;
        d["aligned"] = py::dict(py::arg("psnr_db") = r.aligned.psnr, py::arg("ssim") = r.aligned.ssim,
                                py::arg("rmse") = r.aligned.rmse);
        d["offset_px"] = py::dict(py::arg("dy") = r.offset.dy, py::arg("dx") = r.offset.dx);
        d["offset_measured_px"] = py::dict(py::arg("dy") = r.measured_offset.dy, py::arg("dx") = r.measured_offset.dx);
        d["offset_applied"] = r.offset_applied;
        return d;
      },
      py::arg("truth"), py::arg("estimate"), py::kw_only(), py::arg("crop") = 0, py::arg("peak") = 0.0,
      "compare_images, plus the sub-pixel offset of `estimate` against `truth` measured on the scored crop\n"
      "(apodised upsampled cross-correlation, Guizar-Sicairos et al. 2008; estimate ~ truth moved by (dy, dx) px, +dx\n"
      "toward +x) and the scores after moving the estimate back by it (a Fourier shift on the periodic grid). The\n"
      "offset is applied only when it lowers neither PSNR nor SSIM on the crop, so 'aligned' >= raw; otherwise\n"
      "'offset_px' is 0, 'offset_applied' False and 'offset_measured_px' what was found: {'psnr_db', 'ssim', 'rmse',\n"
      "'crop_px', 'aligned': {'psnr_db', 'ssim', 'rmse'}, 'offset_px': {'dy', 'dx'}, 'offset_measured_px',\n"
      "'offset_applied'} (include/aosr/core/metrics.hpp).");
  m.def(
      "compare_images_rings",
      [](py::handle truth, py::handle estimate, int rings, py::object centre, int crop, double peak) {
        const Image t = ImageFromArray(truth, "truth"), e = ImageFromArray(estimate, "estimate");
        const MetricOptions o = Metrics(crop, peak);
        RingOptions ro;
        ro.rings = rings;
        if (!centre.is_none()) {
          std::vector<double> xy;
          try {
            xy = centre.cast<std::vector<double>>();
          } catch (const py::cast_error&) {
            xy.clear();
          }
          CheckArgument(xy.size() == 2, "aosr.compare_images_rings", "centre", py::str(centre).cast<std::string>(),
                        "(x, y): two numbers [px], or None for the image centre");
          ro.centre_x = xy[0];
          ro.centre_y = xy[1];
          CheckArgument(std::isfinite(ro.centre_x) && std::isfinite(ro.centre_y), "aosr.compare_images_rings",
                        "centre", ToString(ro.centre_x) + ", " + ToString(ro.centre_y), "finite (x, y) [px]");
        }
        const RingMetrics r = WithoutGil([&] { return CompareImagesInRings(t, e, ro, o); });
        py::list list;
        for (const RingScore& ring : r.rings) {
          const AlignedImageMetrics& m = ring.scores;
          py::dict d;
          d["inner_px"] = ring.inner_px;
          d["outer_px"] = ring.outer_px;
          d["pixels"] = ring.pixels;
          d["area_px2"] = ring.area_px;
          d["ssim_positions"] = ring.ssim_positions;
          d["psnr_db"] = m.raw.psnr;
          d["ssim"] = m.raw.ssim;
          d["rmse"] = m.raw.rmse;
          d["aligned"] = py::dict(py::arg("psnr_db") = m.aligned.psnr, py::arg("ssim") = m.aligned.ssim,
                                  py::arg("rmse") = m.aligned.rmse);
          d["offset_px"] = py::dict(py::arg("dy") = m.offset.dy, py::arg("dx") = m.offset.dx);
          d["offset_measured_px"] = py::dict(py::arg("dy") = m.measured_offset.dy, py::arg("dx") = m.measured_offset.dx);
          d["offset_applied"] = m.offset_applied;
          list.append(d);
        }
        py::dict out;
        out["centre"] = py::make_tuple(r.centre_x, r.centre_y);
        out["peak"] = r.peak;
        out["crop_px"] = crop;
        out["rings"] = list;
        return out;
      },
      py::arg("truth"), py::arg("estimate"), py::kw_only(), py::arg("rings") = 4, py::arg("centre") = py::none(),
      py::arg("crop") = 0, py::arg("peak") = 0.0,
      "Scores across the field: PSNR [dB], SSIM and RMSE of `estimate` against `truth` in `rings` concentric rings\n"
      "about `centre` = (x, y) [px: column, row; 0-based pixel centres; None: the image centre], equal widths out to\n"
      "the crop's farthest pixel (each >= 11 px), each ring raw and aligned with its own offset (as\n"
      "compare_images_aligned, on the ring). Every ring uses the crop's dynamic range L = `peak` or max - min of the\n"
      "cropped truth. Returns {'centre': (x, y), 'peak', 'crop_px', 'rings': [{'inner_px', 'outer_px', 'pixels',\n"
      "'area_px2', 'ssim_positions', 'psnr_db', 'ssim', 'rmse', 'aligned', 'offset_px', 'offset_measured_px',\n"
      "'offset_applied'}, ...]} innermost first (include/aosr/core/metrics.hpp CompareImagesInRings).");
  m.def(
      "fourier_shift",
      [](py::handle image, double dy, double dx) {
        const Image x = ImageFromArray(image, "image");
        return MoveImage(WithoutGil([&] { return FourierShiftImage(x, dy, dx); }));
      },
      py::arg("image"), py::arg("dy"), py::arg("dx"),
      "The image moved by (dy, dx) px on its periodic grid, out(y, x) = image(y - dy, x - dx): a Fourier (sinc)\n"
      "shift (core/metrics.hpp FourierShiftImage).");
  m.def(
      "mtf",
      [](py::handle image, py::object roi, int r, double pixel_lambda_over_d, std::vector<double> frequencies,
         const std::string& window, double esf_half_width, double min_contrast_to_noise, double max_angle_deg,
         double curve_max, double curve_step, bool smooth_tails) {
        const Image x = ImageFromArray(image, "image");
        SlantedEdgeOptions o;
        o.smooth_tails = smooth_tails;
        if (!roi.is_none()) {
          const std::vector<long long> v = roi.cast<std::vector<long long>>();
          if (v.size() != 4 || v[2] <= 0 || v[3] <= 0)
            throw InvalidArgument("aosr.mtf", "roi", ToString(py::str(roi).cast<std::string>()),
                                  "(x0, y0, width, height) with width, height >= 1");
          o.roi = {Index(v[0]), Index(v[1]), Index(v[2]), Index(v[3])};
        }
        if (window != "tukey" && window != "hamming")
          throw InvalidArgument("aosr.mtf", "window", "'" + window + "'", "'tukey' or 'hamming'");
        o.window = window == "hamming" ? LsfWindow::kHamming : LsfWindow::kTukey;
        o.r = r;
        o.pixel_lambda_over_d = pixel_lambda_over_d;
        o.frequencies = std::move(frequencies);
        o.esf_half_width_px = esf_half_width;
        o.min_contrast_to_noise = min_contrast_to_noise;
        o.max_angle_deg = max_angle_deg;
        o.curve_max = curve_max;
        o.curve_step = curve_step;
        std::string why;
        if (!o.IsValid(&why)) throw InvalidArgument("aosr.mtf: " + why);
        // No roi: the whole image if it holds one edge, else the first straight edge found that measures.
        std::string roi_source = "given";
        PixelRoi used = o.roi;
        const SlantedEdgeMtf e = WithoutGil([&] {
          if (!roi.is_none()) return MeasureSlantedEdgeMtf(x, o);
          const AutoEdgeMtf found = MeasureSlantedEdgeMtfAuto(x, o);
          roi_source = found.whole_image ? "whole image" : "found automatically";
          used = found.roi;
          return found.mtf;
        });
        auto array = [](const std::vector<double>& v) { return py::array_t<double>(py::ssize_t(v.size()), v.data()); };
        auto crossing = [](const MtfCrossing& c) { return c.reached ? py::object(py::float_(c.frequency)) : py::object(py::none()); };
        py::dict d;
        d["frequency"] = array(e.frequency);
        d["mtf"] = array(e.mtf);
        d["mtf50"] = crossing(e.mtf50);
        d["mtf10"] = crossing(e.mtf10);
        py::list at;
        for (const MtfPoint& p : e.at) at.append(py::make_tuple(p.frequency, p.mtf));
        d["at"] = at;
        d["nyquist"] = e.has_nyquist ? py::object(py::dict(py::arg("frequency") = e.nyquist.frequency, py::arg("mtf") = e.nyquist.mtf))
                                     : py::object(py::none());
        d["cutoff"] = e.has_cutoff ? py::object(py::dict(py::arg("frequency") = e.cutoff.frequency, py::arg("mtf") = e.cutoff.mtf))
                                   : py::object(py::none());
        d["edge"] = py::dict(py::arg("orientation") = e.vertical ? "vertical" : "horizontal", py::arg("angle_deg") = e.angle_deg,
                             py::arg("centre_px") = py::make_tuple(e.centre_y, e.centre_x), py::arg("length_px") = e.edge_length_px,
                             py::arg("fit_rms_px") = e.fit_rms_px, py::arg("low") = e.low, py::arg("high") = e.high,
                             py::arg("noise_rms") = e.noise_rms, py::arg("contrast_to_noise") = e.contrast_to_noise,
                             py::arg("empty_bins") = e.empty_bins);
        d["esf_distance"] = array(e.esf_distance);
        d["esf"] = array(e.esf);
        d["lsf"] = array(e.lsf);
        d["report"] = e.BriefReport();
        d["roi"] = roi.is_none() ? py::make_tuple(used.x0, used.y0, used.width, used.height) : py::tuple(roi);
        d["roi_source"] = roi_source;
        return d;
      },
      py::arg("image"), py::kw_only(), py::arg("roi") = py::none(), py::arg("r") = 0, py::arg("pixel_lambda_over_d") = 0.0,
      py::arg("frequencies") = std::vector<double>{}, py::arg("window") = "tukey", py::arg("esf_half_width") = 0.0,
      py::arg("min_contrast_to_noise") = 10.0, py::arg("max_angle_deg") = 40.0, py::arg("curve_max") = 1.0,
      py::arg("curve_step") = 0.01, py::arg("smooth_tails") = true,
      "Slanted-edge MTF (ISO 12233 e-SFR) of a 2-D image, or of roi = (x0, y0, width, height) in it; without roi\n"
      "the whole image if it holds one edge, else the longest straight edge found that measures\n"
      "(include/aosr/core/edge_search.hpp; 'roi' and 'roi_source' in the result say which)\n"
      "(include/aosr/core/slanted_edge.hpp). Returns {'frequency', 'mtf' (arrays, cycles/px), 'mtf50', 'mtf10'\n"
      "(cycles/px, None when not reached), 'at' [(f, mtf)] at `frequencies`, 'nyquist' {frequency, mtf} at 1/(2r)\n"
      "when r > 0, 'cutoff' at D/lambda = pixel_lambda_over_d cycles/px when given, 'edge' {orientation,\n"
      "angle_deg, centre_px, length_px, fit_rms_px, low, high, noise_rms, contrast_to_noise, empty_bins},\n"
      "'esf_distance', 'esf', 'lsf', 'report'}. An edge too short, too tilted, too close to an axis, clipped\n"
      "or too noisy raises aosr.InvalidArgument saying which. smooth_tails=False: the plain ISO 12233 LSF (for\n"
      "noise-free or ringing edges such as reconstructions, whose ringing the tail smoothing removes).");
  m.def(
      "psnr",
      [](py::handle truth, py::handle estimate, int crop, double peak) {
        return Psnr(ImageFromArray(truth, "truth"), ImageFromArray(estimate, "estimate"), Metrics(crop, peak));
      },
      py::arg("truth"), py::arg("estimate"), py::kw_only(), py::arg("crop") = 0, py::arg("peak") = 0.0,
      "PSNR [dB] of `estimate` against `truth` (compare_images).");
}

}  // namespace aosr::python
