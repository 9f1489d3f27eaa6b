// `aosr mtf`: the slanted-edge MTF (ISO 12233 e-SFR) of an image or of a region of it
// (include/aosr/core/slanted_edge.hpp): the curve, MTF50, MTF10 and the MTF at the camera's Nyquist and the
// optical cut-off; optionally the curve as a PNG plot.
#include <cmath>
#include <cstdio>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <variant>
#include <vector>

#include "aosr/core/error.hpp"
#include "aosr/core/slanted_edge.hpp"
#include "aosr/io/fits.hpp"
#include "aosr/io/plot.hpp"
#include "cli_util.hpp"
#include "commands.hpp"

namespace aosr::cli {
namespace {

struct MtfArgs {
  std::string image;
  std::vector<long long> roi;  // x0, y0, width, height
  int r = -1;                  // < 0: the FITS keyword SRFACTOR when present, else none; 0: none
  double pixel_lod = 0.0;
  std::vector<double> frequencies;
  std::string window = "tukey";
  double esf_half_width = 0.0;
  double min_cnr = 10.0;
  double max_angle = 40.0;
  double curve_max = 1.0;
  bool json = false;
  std::string out;  // PNG of the curve
};

// The super-resolution factor of an HR image from its header: SRFACTOR on the files aosr writes on the HR grid (a
// simulation's truth, a reconstruction: AOSRDATA "truth" / "reconstruction", or HRPIXRAD); 0 for anything else
// (frames carry SRFACTOR too, but their pixels are the camera's).
int HrImageFactor(const FitsHeader& h) {
  const FitsKeyword* f = h.Find("SRFACTOR");
  if (f == nullptr || !std::holds_alternative<long long>(f->value)) return 0;
  const FitsKeyword* what = h.Find("AOSRDATA");
  const bool hr = h.Find("HRPIXRAD") != nullptr ||
                  (what != nullptr && std::holds_alternative<std::string>(what->value) &&
                   (std::get<std::string>(what->value) == "truth" || std::get<std::string>(what->value) == "reconstruction"));
  const long long r = std::get<long long>(f->value);
  return hr && r >= 1 && r <= 64 ? int(r) : 0;
}

nlohmann::json MtfNumber(double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr); }

nlohmann::json MtfCrossingJson(const MtfCrossing& c) { return c.reached ? nlohmann::json(c.frequency) : nlohmann::json(nullptr); }

void RunMtf(const MtfArgs& a) {
  SlantedEdgeOptions o;
  if (!a.roi.empty()) {
    if (a.roi.size() != 4) throw InvalidArgument("aosr mtf", "--roi", std::to_string(a.roi.size()) + " numbers", "X0,Y0,W,H");
    o.roi = {Index(a.roi[0]), Index(a.roi[1]), Index(a.roi[2]), Index(a.roi[3])};
    if (a.roi[2] <= 0 || a.roi[3] <= 0)
      throw InvalidArgument("aosr mtf", "--roi", std::to_string(a.roi[2]) + "x" + std::to_string(a.roi[3]),
                            "a width and height >= 1");
  }
  if (!a.out.empty()) CheckWritableFile(a.out);
  const FitsData fits = ReadFits(a.image);
  if (fits.planes.size() != 1)
    throw InvalidArgument("aosr mtf", "IMAGE", a.image + " (" + std::to_string(fits.planes.size()) + " planes)", "a 2-D image");
  int r = a.r;
  if (r < 0) r = HrImageFactor(fits.header);
  o.r = r;
  o.pixel_lambda_over_d = a.pixel_lod;
  o.frequencies = a.frequencies;
  o.window = a.window == "hamming" ? LsfWindow::kHamming : LsfWindow::kTukey;
  o.esf_half_width_px = a.esf_half_width;
  o.min_contrast_to_noise = a.min_cnr;
  o.max_angle_deg = a.max_angle;
  o.curve_max = a.curve_max;
  std::string why;
  if (!o.IsValid(&why)) throw InvalidArgument("aosr mtf: " + why);
  const SlantedEdgeMtf m = MeasureSlantedEdgeMtf(fits.planes[0], o);

  if (!a.out.empty()) {
    LinePlot p;
    p.title = "slanted-edge MTF of " + a.image;
    p.x.label = "frequency [cycles/px]";
    p.y.label = "MTF";
    p.x.min = 0.0;
    p.x.max = o.curve_max;
    p.y.min = 0.0;
    p.y.max = 1.05;
    char label[96];
    std::snprintf(label, sizeof label, "MTF (%s edge, %.1f deg)", m.vertical ? "near-vertical" : "near-horizontal", m.angle_deg);
    p.series.push_back({label, m.frequency, m.mtf});
    if (m.has_nyquist) p.series.push_back({"camera Nyquist 1/(2r)", {m.nyquist.frequency, m.nyquist.frequency}, {0.0, 1.0}});
    if (m.has_cutoff) p.series.push_back({"optical cut-off D/lambda", {m.cutoff.frequency, m.cutoff.frequency}, {0.0, 1.0}});
    if (m.mtf50.reached) p.series.push_back({"MTF50", {m.mtf50.frequency}, {0.5}});
    WriteFigure(a.out, {p});
  }

  if (a.json) {
    nlohmann::json at = nlohmann::json::array();
    for (const MtfPoint& q : m.at) at.push_back({{"frequency", q.frequency}, {"mtf", q.mtf}});
    nlohmann::json j = {
        {"image", a.image},
        {"roi", {{"x0", o.roi.x0}, {"y0", o.roi.y0}, {"width", o.roi.width}, {"height", o.roi.height}}},
        {"edge",
         {{"orientation", m.vertical ? "vertical" : "horizontal"},
          {"angle_deg", m.angle_deg},
          {"centre_px", {{"y", m.centre_y}, {"x", m.centre_x}}},
          {"length_px", m.edge_length_px},
          {"fit_rms_px", m.fit_rms_px},
          {"low", m.low},
          {"high", m.high},
          {"noise_rms", m.noise_rms},
          {"contrast_to_noise", MtfNumber(m.contrast_to_noise)},
          {"empty_bins", m.empty_bins}}},
        {"mtf50_cycles_per_px", MtfCrossingJson(m.mtf50)},
        {"mtf10_cycles_per_px", MtfCrossingJson(m.mtf10)},
        {"at", at},
        {"nyquist", m.has_nyquist ? nlohmann::json{{"r", r}, {"frequency", m.nyquist.frequency}, {"mtf", m.nyquist.mtf}}
                                  : nlohmann::json(nullptr)},
        {"cutoff", m.has_cutoff ? nlohmann::json{{"pixel_lambda_over_d", a.pixel_lod}, {"frequency", m.cutoff.frequency},
                                                 {"mtf", m.cutoff.mtf}}
                                : nlohmann::json(nullptr)},
        {"curve", {{"frequency", m.frequency}, {"mtf", m.mtf}}}};
    if (!a.out.empty()) j["plot"] = a.out;
    std::printf("%s\n", j.dump(2).c_str());
    return;
  }
  std::printf("%s: %s\n", a.image.c_str(), m.BriefReport().c_str());
  std::printf("  edge through (y, x) = (%.2f, %.2f) px, %lld px long, line-fit RMS %.3f px; levels %.4g -> %.4g, noise RMS %.3g\n",
              m.centre_y, m.centre_x, static_cast<long long>(m.edge_length_px), m.fit_rms_px, m.low, m.high, m.noise_rms);
  if (m.has_nyquist)
    std::printf("  MTF at the camera's Nyquist 1/(2r) = %.4f cycles/px (r = %d): %.4f\n", m.nyquist.frequency, r, m.nyquist.mtf);
  if (m.has_cutoff)
    std::printf("  MTF at the optical cut-off D/lambda = %.4f cycles/px: %.4f\n", m.cutoff.frequency, m.cutoff.mtf);
  for (const MtfPoint& q : m.at) std::printf("  MTF at %.4f cycles/px: %.4f\n", q.frequency, q.mtf);
  if (!a.out.empty()) std::printf("  curve written to %s\n", a.out.c_str());
}

}  // namespace

void RegisterMtf(CLI::App& app) {
  auto args = std::make_shared<MtfArgs>();
  CLI::App* cmd = app.add_subcommand(
      "mtf",
      "Slanted-edge MTF (ISO 12233 e-SFR) of an image or of a region holding one straight edge 2-40 deg off an "
      "axis (core/slanted_edge.hpp): MTF50, MTF10 and the curve in cycles per pixel, the MTF at the camera's "
      "Nyquist 1/(2r) and at the optical cut-off D/lambda. An edge that is too short, too tilted, too close to an "
      "axis, clipped or too noisy is refused with the reason.");
  cmd->add_option("IMAGE", args->image, "the image (FITS; a reconstruction, a frame, a truth)")->required();
  cmd->add_option("--roi", args->roi, "region holding the edge: X0,Y0,W,H in pixels (x = column; default the whole image)")
      ->delimiter(',')
      ->expected(4);
  cmd->add_option("--r", args->r,
                  "super-resolution factor of an HR image: report the MTF at the camera's Nyquist 1/(2r) cycles/px "
                  "(default: the FITS keyword SRFACTOR of an HR image aosr wrote, a truth or a reconstruction; 0: none)")
      ->check(CLI::Range(0, 64));
  cmd->add_option("--pixel-lod", args->pixel_lod,
                  "the pixel's size in lambda/D: report the MTF at the optical cut-off D/lambda = this many cycles/px")
      ->check(CLI::Range(0.0, kMaxMtfFrequency));
  cmd->add_option("--freq", args->frequencies, "further frequencies to report, cycles/px (comma-separated)")
      ->delimiter(',')
      ->check(CLI::Range(0.0, kMaxMtfFrequency));
  cmd->add_option("--window", args->window, "LSF window: tukey (flat middle, half the length tapered) | hamming (ISO 12233's)")
      ->capture_default_str()
      ->check(CLI::IsMember({"tukey", "hamming"}));
  cmd->add_option("--esf-half-width", args->esf_half_width,
                  "cap on the ESF's half-length in px (0: all the region gives; >= 5): shorter is less noisy but cuts "
                  "the LSF's tails")
      ->capture_default_str()
      ->check(NonNegativeFinite());
  cmd->add_option("--min-cnr", args->min_cnr, "smallest contrast-to-noise ratio accepted")->capture_default_str()->check(NonNegativeFinite());
  cmd->add_option("--max-angle", args->max_angle, "largest edge angle from the nearer axis [deg], (0, 45]")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 45.0));
  cmd->add_option("--curve-max", args->curve_max, "the curve's last frequency [cycles/px]")
      ->capture_default_str()
      ->check(CLI::Range(0.01, kMaxMtfFrequency));
  cmd->add_flag("--json", args->json, "print the results (and the curve) as JSON");
  cmd->add_option("-o,--out", args->out, "write the curve as a PNG plot");
  cmd->callback([args] { RunMtf(*args); });
}

}  // namespace aosr::cli
