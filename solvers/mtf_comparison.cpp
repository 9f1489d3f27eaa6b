// Several outputs' slanted-edge MTFs with the exact transfer of the linear ones (mtf_comparison.hpp).
#include "aosr/solvers/mtf_comparison.hpp"

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <variant>

#include "aosr/core/edge_search.hpp"
#include "aosr/core/error.hpp"
#include "aosr/io/fits.hpp"

namespace aosr {

namespace {

// The HR Nyquist: the exact curves stop there (a discrete HR image has nothing beyond it of its own).
constexpr double kMtfCmpHrNyquist = 0.5;

std::string MtfCmpFixed(double v, int digits) {
  if (!std::isfinite(v)) return "n/a";
  char b[48];
  std::snprintf(b, sizeof b, "%.*f", digits, v);
  return b;
}

// The lowest frequency where a curve falls to `level` (linear interpolation between its points); NaN if never.
double CurveCrossing(const std::vector<double>& f, const std::vector<double>& m, double level) {
  for (std::size_t i = 1; i < f.size(); ++i)
    if (m[i] <= level && m[i - 1] > level) return f[i - 1] + (f[i] - f[i - 1]) * (m[i - 1] - level) / (m[i - 1] - m[i]);
  return std::numeric_limits<double>::quiet_NaN();
}

// A curve's value at frequency x (linear interpolation); NaN outside it.
double CurveAt(const std::vector<double>& f, const std::vector<double>& m, double x) {
  for (std::size_t i = 1; i < f.size(); ++i)
    if (x >= f[i - 1] && x <= f[i]) {
      const double t = f[i] > f[i - 1] ? (x - f[i - 1]) / (f[i] - f[i - 1]) : 0.0;
      return m[i - 1] + t * (m[i] - m[i - 1]);
    }
  return std::numeric_limits<double>::quiet_NaN();
}

std::string CsvField(const std::string& s) {
  if (s.find_first_of(",\"\n") == std::string::npos) return s;
  std::string q = "\"";
  for (char c : s) q += c == '"' ? std::string("\"\"") : std::string(1, c);
  return q + "\"";
}

}  // namespace

MtfSubject MtfSubjectFromFits(const std::string& path) {
  const FitsData fits = ReadFits(path);
  if (fits.planes.size() != 1)
    throw InvalidArgument("MtfSubjectFromFits", "image", path + " (" + std::to_string(fits.planes.size()) + " planes)",
                          "a 2-D image");
  MtfSubject s;
  s.image = fits.planes[0];
  const FitsHeader& h = fits.header;
  auto str = [&h](const char* key) {
    const FitsKeyword* k = h.Find(key);
    return k && std::holds_alternative<std::string>(k->value) ? std::get<std::string>(k->value) : std::string();
  };
  s.method = str("METHOD");
  if (s.method.empty() && str("AOSRDATA") == "truth") s.method = "truth";
  if (const FitsKeyword* k = h.Find("REGUL"); k != nullptr && s.method == "tikhonov") s.regularisation = h.GetDouble("REGUL");
  if (s.method == "linear")
    for (const std::string& e : FitsExtensionNames(path))
      if (e == "PSF") {
        const FitsData p = ReadFitsExtension(path, "PSF");
        if (p.planes.size() == 1) s.effective_psf = p.planes[0];
      }
  s.label = s.method.empty() ? std::filesystem::path(path).stem().string() : s.method;
  return s;
}

PixelRoi FindMtfRegion(const std::vector<MtfSubject>& subjects, const SlantedEdgeOptions& options, std::string* source) {
  CheckArgument(!subjects.empty(), "FindMtfRegion", "subjects", "none", "at least one image");
  std::string first_refusal;
  for (const MtfSubject& s : subjects) {
    try {
      const AutoEdgeMtf found = MeasureSlantedEdgeMtfAuto(s.image, options);
      if (source) {
        if (found.whole_image) {
          *source = "whole image";
        } else {
          const EdgeCandidate& e = found.candidates[std::size_t(found.candidate)];
          *source = "found automatically in " + s.label + ": the " + (e.vertical ? "vertical" : "horizontal") + " edge " +
                    std::to_string(found.candidate + 1) + " of " + std::to_string(found.candidates.size()) +
                    " straight edges";
        }
      }
      return found.whole_image ? PixelRoi{} : found.roi;
    } catch (const InvalidArgument& e) {
      if (first_refusal.empty()) first_refusal = s.label + ": " + e.what();
    }
  }
  throw InvalidArgument("no image has a usable edge (give a region to read); " + first_refusal);
}

MtfComparison CompareMtf(const std::vector<MtfSubject>& subjects, const MtfComparisonOptions& options) {
  constexpr const char* kFn = "CompareMtf";
  if (subjects.empty()) throw InvalidArgument(kFn, "subjects", "none", "at least one image");
  {
    std::string why;
    if (!options.edge.IsValid(&why)) throw InvalidArgument(std::string(kFn) + ": options.edge: " + why);
  }
  MtfComparison c;
  std::string first_refusal;
  const SlantedEdgeMtf* reference = nullptr;
  for (std::size_t i = 0; i < subjects.size(); ++i) {
    const MtfSubject& s = subjects[i];
    MtfComparisonEntry e;
    e.method = s.method;
    e.label = !s.label.empty() ? s.label : !s.method.empty() ? s.method : "image " + std::to_string(i + 1);
    try {
      e.edge = MeasureSlantedEdgeMtf(s.image, options.edge);
      e.measured = true;
    } catch (const InvalidArgument& err) {
      e.refusal = err.what();
      if (first_refusal.empty()) first_refusal = e.label + ": " + e.refusal;
    }
    c.entries.push_back(std::move(e));
  }
  for (const MtfComparisonEntry& e : c.entries)
    if (e.measured) {
      reference = &e.edge;
      break;
    }
  if (reference == nullptr) throw InvalidArgument(std::string(kFn) + ": no image has a usable edge; " + first_refusal);

  for (std::size_t i = 0; i < subjects.size(); ++i) {
    const MtfSubject& s = subjects[i];
    MtfComparisonEntry& e = c.entries[i];
    if (!options.exact) {
      e.exact_status = "off";
      continue;
    }
    if (s.method == "tv" || s.method == "map") {
      e.exact_status = "signal-dependent";
      continue;
    }
    if (s.method != "tikhonov" && s.method != "linear") {
      e.exact_status = "measured only";
      continue;
    }
    const SlantedEdgeMtf& edge = e.measured ? e.edge : *reference;
    TransferCurveOptions to;
    SetDirectionFromEdge(edge, &to);
    to.curve_max = std::min(kMtfCmpHrNyquist, edge.frequency.back());
    for (double f : edge.frequency)
      if (f <= to.curve_max + 1e-12) to.frequencies.push_back(std::min(f, to.curve_max));
    if (s.method == "linear") {
      if (s.effective_psf.size() == 0) {
        e.exact_status = "unavailable: no effective PSF (the PSF extension of aosr reconstruct -m linear's file)";
        continue;
      }
      e.exact = KernelTransferCurve(s.effective_psf, to);
      e.exact_status = "exact";
      continue;
    }
    if (!options.problem) {
      e.exact_status = "unavailable: needs the dataset's model (--manifest)";
      continue;
    }
    if (!(std::isfinite(s.regularisation) && s.regularisation >= 0)) {
      e.exact_status = "unavailable: the output's lambda is not known (REGUL)";
      continue;
    }
    bool exact = false;
    e.exact = TikhonovTransferCurve(*options.problem, options.tikhonov, s.regularisation, to, &exact);
    e.exact_status = exact ? "exact" : "approximate: weights vary within frames (per-frame mean weights used)";
  }
  return c;
}

std::string MtfComparison::BriefReport() const {
  std::string out;
  for (const MtfComparisonEntry& e : entries) {
    out += e.label + ": ";
    if (!e.measured) {
      out += "no curve (" + e.refusal + ")";
    } else {
      const SlantedEdgeMtf& m = e.edge;
      out += "MTF50 " + (m.mtf50.reached ? MtfCmpFixed(m.mtf50.frequency, 3) : std::string("n/a"));
      if (e.exact) out += " (exact " + MtfCmpFixed(CurveCrossing(e.exact->frequency, e.exact->mtf, 0.5), 3) + ")";
      out += " cyc/px";
      if (m.has_nyquist) {
        out += ", MTF at 1/(2r) " + MtfCmpFixed(m.nyquist.mtf, 3);
        if (e.exact) out += " (exact " + MtfCmpFixed(CurveAt(e.exact->frequency, e.exact->mtf, m.nyquist.frequency), 3) + ")";
      }
    }
    if (e.exact_status == "signal-dependent")
      out += "; signal-dependent: the edge's curve at this contrast and noise is the answer";
    else if (!e.exact_status.empty() && e.exact_status != "exact" && e.exact_status != "measured only" && e.exact_status != "off")
      out += "; exact curve " + e.exact_status;
    out += "\n";
  }
  return out;
}

std::string MtfComparisonCsv(const MtfComparison& c) {
  const MtfComparisonEntry* ref = nullptr;
  for (const MtfComparisonEntry& e : c.entries)
    if (e.measured && (ref == nullptr || e.edge.frequency.size() > ref->edge.frequency.size())) ref = &e;
  std::string out = "frequency_cycles_per_px";
  for (const MtfComparisonEntry& e : c.entries)
    if (e.measured) out += "," + CsvField(e.label + " edge");
  for (const MtfComparisonEntry& e : c.entries)
    if (e.exact) out += "," + CsvField(e.label + " exact");
  out += "\n";
  if (ref == nullptr) return out;
  char b[32];
  for (std::size_t i = 0; i < ref->edge.frequency.size(); ++i) {
    const double f = ref->edge.frequency[i];
    std::snprintf(b, sizeof b, "%.6g", f);
    out += b;
    for (const MtfComparisonEntry& e : c.entries)
      if (e.measured) {
        out += ",";
        if (i < e.edge.mtf.size()) {
          std::snprintf(b, sizeof b, "%.6f", e.edge.mtf[i]);
          out += b;
        }
      }
    for (const MtfComparisonEntry& e : c.entries)
      if (e.exact) {
        out += ",";
        if (i < e.exact->mtf.size()) {
          std::snprintf(b, sizeof b, "%.6f", e.exact->mtf[i]);
          out += b;
        }
      }
    out += "\n";
  }
  return out;
}

LinePlot MtfComparisonPlot(const MtfComparison& c, const std::string& title) {
  LinePlot p;
  bool signal_dependent = false;
  for (const MtfComparisonEntry& e : c.entries) signal_dependent |= e.measured && e.exact_status == "signal-dependent";
  p.title = !title.empty() ? title
            : signal_dependent ? "MTF: slanted edge and exact (TV/MAP: signal-dependent, no exact curve)"
                               : "MTF: slanted edge and exact transfer";
  p.x.label = "frequency [cycles per HR px]";
  p.y.label = "MTF";
  p.x.min = 0.0;
  p.y.min = 0.0;
  p.y.max = 1.05;
  double fmax = 0;
  const SlantedEdgeMtf* nyq = nullptr;
  for (const MtfComparisonEntry& e : c.entries) {
    if (!e.measured) continue;
    std::string label = e.label + " (edge)";
    if (e.exact_status == "signal-dependent") label = e.label + " (edge, signal-dep.)";
    p.series.push_back({label, e.edge.frequency, e.edge.mtf});
    fmax = std::max(fmax, e.edge.frequency.back());
    if (e.edge.has_nyquist && nyq == nullptr) nyq = &e.edge;
  }
  for (const MtfComparisonEntry& e : c.entries)
    if (e.exact) p.series.push_back({e.label + " (exact)", e.exact->frequency, e.exact->mtf});
  if (nyq != nullptr) p.series.push_back({"camera Nyquist 1/(2r)", {nyq->nyquist.frequency, nyq->nyquist.frequency}, {0.0, 1.0}});
  p.x.max = fmax > 0 ? fmax : 0.5;
  return p;
}

}  // namespace aosr
