// Bindings of the io layer: FITS images and cubes with their headers as dicts.
//
// Headers: {KEYWORD: value} with bool, int, float or str values, in file order: the form
// astropy.io.fits.Header(d) accepts. Keywords longer than 8 characters are given as "HIERARCH NAME" (what
// astropy expects for them, and what cfitsio wrote); write_fits accepts either form.
#include "aosr/core/error.hpp"
#include "aosr/io/fits.hpp"
#include "aosr/io/image_io.hpp"
#include "aosr/io/plot.hpp"
#include "common.hpp"

namespace aosr::python {
namespace {

std::string PythonKey(const std::string& name) { return name.size() > 8 ? "HIERARCH " + name : name; }

py::object PythonValue(const FitsValue& v) {
  return std::visit([](const auto& x) -> py::object { return py::cast(x); }, v);
}

}  // namespace

py::dict HeaderToDict(const FitsHeader& header) {
  py::dict d;
  for (const FitsKeyword& k : header.keywords()) d[py::str(PythonKey(k.name))] = PythonValue(k.value);
  return d;
}

py::dict HeaderComments(const FitsHeader& header) {
  py::dict d;
  for (const FitsKeyword& k : header.keywords()) d[py::str(PythonKey(k.name))] = k.comment;
  return d;
}

FitsHeader HeaderFromDict(py::handle header, py::handle comments) {
  FitsHeader h;
  if (header.is_none()) return h;
  // A dict, or anything with .items() (astropy's Header yields (keyword, value) pairs).
  if (!py::hasattr(header, "items"))
    throw InvalidArgument("aosr.write_fits", "header", std::string(py::str(py::type::of(header))),
                          "a dict {keyword: value} or an astropy.io.fits.Header");
  py::dict notes = comments.is_none() ? py::dict() : py::dict(py::reinterpret_borrow<py::object>(comments));
  for (py::handle item : header.attr("items")()) {
    const py::tuple kv = py::reinterpret_borrow<py::tuple>(item);
    std::string key = py::str(kv[0]);
    const std::string comment = notes.contains(kv[0]) ? std::string(py::str(notes[kv[0]])) : std::string();
    if (key.rfind("HIERARCH ", 0) == 0) key = key.substr(9);
    if (key.empty() || FitsHeader::IsStructural(key)) continue;  // written by the writer itself
    const py::handle v = kv[1];
    if (py::isinstance<py::bool_>(v)) h.Set(key, v.cast<bool>(), comment);
    else if (py::isinstance<py::int_>(v)) h.Set(key, v.cast<long long>(), comment);
    else if (py::isinstance<py::float_>(v) || (py::hasattr(v, "__float__") && !py::isinstance<py::str>(v)))
      h.Set(key, v.cast<double>(), comment);
    else if (py::isinstance<py::str>(v)) h.Set(key, v.cast<std::string>(), comment);
    else
      throw InvalidArgument("aosr.write_fits", "header[" + key + "]", std::string(py::repr(v)),
                            "a bool, int, float or str");
  }
  return h;
}

void BindIo(py::module_& m) {
  m.def(
      "read_fits",
      [](py::object path_object, bool with_comments) -> py::tuple {
        const std::string path = PathString(path_object);
        FitsData data = WithoutGil([&] { return ReadFits(path); });
        py::object array = data.planes.size() == 1 ? py::object(MoveImage(std::move(data.planes.front())))
                                                   : py::object(StackToArray(data.planes));
        if (with_comments) return py::make_tuple(array, HeaderToDict(data.header), HeaderComments(data.header));
        return py::make_tuple(array, HeaderToDict(data.header));
      },
      py::arg("path"), py::kw_only(), py::arg("with_comments") = false,
      "Reads a FITS image or cube (the primary HDU, or the first image extension with data).\n\n"
      "Returns (data, header): data float64, (rows, cols) for an image or (N, rows, cols) for a cube, in\n"
      "astropy's orientation; header a dict {KEYWORD: value} that astropy.io.fits.Header(header) accepts.\n"
      "with_comments=True adds a third dict {KEYWORD: comment}. Raises IoError naming the path.");
  m.def(
      "write_fits",
      [](py::object path_object, py::handle data, py::handle header, py::handle comments, const std::string& dtype) {
        const std::string path = PathString(path_object);
        FitsType type = FitsType::kFloat32;
        if (dtype == "float64") type = FitsType::kFloat64;
        else if (dtype != "float32") throw InvalidArgument("aosr.write_fits", "dtype", dtype, "float32 | float64");
        const FitsHeader h = HeaderFromDict(header, comments);
        const py::array a = py::array::ensure(data);
        if (a && a.ndim() == 3) {
          const ImageStack planes = StackFromArray(data, "data");
          WithoutGil([&] { WriteFitsCube(path, planes, h, type); });
        } else {
          const Image img = ImageFromArray(data, "data");
          WithoutGil([&] { WriteFits(path, img, h, type); });
        }
      },
      py::arg("path"), py::arg("data"), py::arg("header") = py::none(), py::kw_only(),
      py::arg("comments") = py::none(), py::arg("dtype") = "float32",
      "Writes a 2-D image or an (N, rows, cols) cube as FITS, atomically (write to a temporary name, then\n"
      "rename). header: a dict {KEYWORD: value} or an astropy Header (structural keywords are skipped);\n"
      "comments: {KEYWORD: comment}. dtype 'float32' (default) or 'float64' (exact).");
  m.def(
      "write_image",
      [](py::object path_object, py::handle image, const std::string& stretch, double low, double high, int bits,
         double softening) {
        const std::string path = PathString(path_object);
        const Image img = ImageFromArray(image, "image");
        ViewOptions o;
        if (stretch == "linear") {
          o.stretch = Stretch::kLinear;
        } else if (stretch == "log") {
          o.stretch = Stretch::kLog;
        } else if (stretch == "asinh") {
          o.stretch = Stretch::kAsinh;
        } else {
          throw InvalidArgument("aosr.write_image", "stretch", stretch, "linear | log | asinh");
        }
        o.low_percentile = low;
        o.high_percentile = high;
        o.bits = bits;
        o.asinh_softening = softening;
        std::string why;
        if (!o.IsValid(&why)) throw InvalidArgument("aosr.write_image: " + why);
        WithoutGil([&] { WriteViewImage(path, img, o); });
      },
      py::arg("path"), py::arg("image"), py::kw_only(), py::arg("stretch") = "asinh", py::arg("low") = 0.5,
      py::arg("high") = 99.8, py::arg("bits") = 8, py::arg("softening") = 0.05,
      "Writes a 2-D image as a grayscale PNG (.png) or TIFF (.tif, .tiff), atomically, for viewing\n"
      "(include/aosr/io/image_io.hpp): the values between the low and high percentiles (in %) mapped through the\n"
      "stretch ('linear' | 'log' | 'asinh' with the given softening) to 0..2^bits-1 (8 or 16; 32: float TIFF).\n"
      "Row 0 is the top row of the file. The quick-look PNG of aosr watch is this with the defaults.");
  m.def(
      "write_figure",
      [](py::object path_object, py::list panels, int panel_width, int panel_height, int columns) {
        const std::string path = PathString(path_object);
        // Strict keys, as the config files: a misspelt key is an error, not a silent default.
        auto keys = [](py::dict d, std::initializer_list<const char*> allowed, const std::string& where) {
          for (auto item : d) {
            const std::string k = py::str(item.first);
            bool ok = false;
            for (const char* a : allowed) ok = ok || k == a;
            if (!ok) throw InvalidArgument("aosr.write_figure", where + "." + k, "(unknown key)", "a documented key");
          }
        };
        auto axis = [&](py::dict d, const std::string& where) {
          PlotAxis a;
          keys(d, {"label", "log", "min", "max"}, where);
          if (d.contains("label")) a.label = d["label"].cast<std::string>();
          if (d.contains("log")) a.log = d["log"].cast<bool>();
          if (d.contains("min")) a.min = d["min"].cast<double>();
          if (d.contains("max")) a.max = d["max"].cast<double>();
          return a;
        };
        std::vector<LinePlot> plots;
        for (std::size_t p = 0; p < panels.size(); ++p) {
          const std::string where = "panels[" + std::to_string(p) + "]";
          const py::dict d = panels[p].cast<py::dict>();
          keys(d, {"title", "x", "y", "series"}, where);
          LinePlot lp;
          if (d.contains("title")) lp.title = d["title"].cast<std::string>();
          if (d.contains("x")) lp.x = axis(d["x"].cast<py::dict>(), where + ".x");
          if (d.contains("y")) lp.y = axis(d["y"].cast<py::dict>(), where + ".y");
          if (d.contains("series"))
            for (py::handle s : d["series"].cast<py::list>()) {
              const py::dict sd = s.cast<py::dict>();
              keys(sd, {"label", "x", "y", "point_labels"}, where + ".series");
              PlotSeries ps;
              if (sd.contains("label")) ps.label = sd["label"].cast<std::string>();
              if (sd.contains("point_labels")) ps.point_labels = sd["point_labels"].cast<std::vector<std::string>>();
              ps.x = sd["x"].cast<std::vector<double>>();
              ps.y = sd["y"].cast<std::vector<double>>();
              lp.series.push_back(std::move(ps));
            }
          plots.push_back(std::move(lp));
        }
        FigureOptions o;
        o.panel_width = panel_width;
        o.panel_height = panel_height;
        o.columns = columns;
        WithoutGil([&] { WriteFigure(path, plots, o); });
      },
      py::arg("path"), py::arg("panels"), py::kw_only(), py::arg("panel_width") = 720, py::arg("panel_height") = 460,
      py::arg("columns") = 2,
      "Writes line plots as a PNG, atomically (include/aosr/io/plot.hpp: the pictures of aosr tradeoff and\n"
      "evaluate). panels: a list of {'title': str, 'x': {'label', 'log', 'min', 'max'}, 'y': {...},\n"
      "'series': [{'label': str, 'x': [...], 'y': [...], 'point_labels': [str per point] (optional)}]};\n"
      "non-finite points break a line. For benches and\n"
      "reports without matplotlib. Raises ValueError naming the bad panel, series or key.");
}

}  // namespace aosr::python
