// `aosr mtf`: the slanted-edge MTF (ISO 12233 e-SFR) of an image or of a region of it
// (include/aosr/core/slanted_edge.hpp): the curve, MTF50, MTF10 and the MTF at the camera's Nyquist and the
// optical cut-off; optionally the curve as a PNG plot. Given several images (outputs of `aosr reconstruct`), their
// curves on one plot and in one table, with the exact transfer of the linear methods (solvers/mtf_comparison.hpp).
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <variant>
#include <vector>

#include "aosr/core/error.hpp"
#include "aosr/core/slanted_edge.hpp"
#include "aosr/io/atomic_file.hpp"
#include "aosr/io/fits.hpp"
#include "aosr/io/plot.hpp"
#include "aosr/scene/dataset.hpp"
#include "aosr/solvers/dataset_problem.hpp"
#include "aosr/solvers/mtf_comparison.hpp"
#include "cli_util.hpp"
#include "commands.hpp"

namespace aosr::cli {
namespace {

struct MtfArgs {
  std::vector<std::string> images;
  std::vector<long long> roi;  // x0, y0, width, height
  int r = -1;                  // < 0: the FITS keyword SRFACTOR when present, else none; 0: none
  double pixel_lod = 0.0;
  std::vector<double> frequencies;
  std::string window = "tukey";
  double esf_half_width = 0.0;
  double min_cnr = 10.0;
  double max_angle = 40.0;
  double curve_max = 1.0;
  CLI::Option* curve_max_option = nullptr;  // to tell a given --curve-max from the default
  bool json = false;
  bool smooth_tails = true;  // --no-smooth-tails: the plain ISO 12233 estimate
  std::string out;    // PNG of the curve(s)
  std::string table;  // --table: the curves as CSV
  // The exact transfer of tikhonov outputs: the dataset and the reconstruction's settings (as `aosr reconstruct`).
  std::string manifest;
  std::string weights = "auto";
  std::string model_psfs;
  std::string prior = "gradient";
  bool no_exact = false;
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

nlohmann::json EdgeJson(const std::string& image, const SlantedEdgeOptions& o, const SlantedEdgeMtf& m, int r,
                        double pixel_lod) {
  nlohmann::json at = nlohmann::json::array();
  for (const MtfPoint& q : m.at) at.push_back({{"frequency", q.frequency}, {"mtf", q.mtf}});
  return {{"image", image},
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
          {"cutoff", m.has_cutoff ? nlohmann::json{{"pixel_lambda_over_d", pixel_lod}, {"frequency", m.cutoff.frequency},
                                                   {"mtf", m.cutoff.mtf}}
                                  : nlohmann::json(nullptr)},
          {"curve", {{"frequency", m.frequency}, {"mtf", m.mtf}}}};
}

nlohmann::json ExactJson(const MtfComparisonEntry& e) {
  nlohmann::json j = {{"status", e.exact_status}};
  if (e.exact) {
    j["curve"] = {{"frequency", e.exact->frequency}, {"mtf", e.exact->mtf}};
    if (!e.exact->alias.empty()) j["curve"]["alias"] = e.exact->alias;
  }
  return j;
}

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
  if (!a.table.empty()) CheckWritableFile(a.table);
  if (a.manifest.empty() && (a.weights != "auto" || !a.model_psfs.empty()))
    throw InvalidArgument("aosr mtf", a.weights != "auto" ? "--weights" : "--model-psfs",
                          a.weights != "auto" ? a.weights : a.model_psfs, "only with --manifest");
  MtfComparisonOptions co;
  co.exact = !a.no_exact;
  co.tikhonov.prior = ParseTikhonovPrior(a.prior);
  if (co.tikhonov.prior == TikhonovPrior::kFitted)
    throw InvalidArgument("aosr mtf", "--prior", a.prior, "identity | gradient | laplacian | power-spectrum (the fitted "
                          "prior's spectrum is not in the output's file)");
  DatasetProblemOptions dpo;
  dpo.method = ReconstructionMethod::kTikhonov;
  dpo.weights = ParseDatasetWeights(a.weights);
  if (a.model_psfs == "stars")
    throw InvalidArgument("aosr mtf", "--model-psfs", "stars",
                          "nominal | a FITS cube of PSFs (pass what aosr reconstruct --stars-psf-out wrote)");

  std::vector<MtfSubject> subjects;
  int r = a.r;
  for (const std::string& path : a.images) {
    subjects.push_back(MtfSubjectFromFits(path));
    if (r < 0) r = HrImageFactor(ReadFits(path).header);
  }
  // Two outputs of one method (e.g. of two datasets): told apart by their files' names.
  for (std::size_t i = 0; i < subjects.size(); ++i) {
    int same = 0;
    for (const MtfSubject& t : subjects) same += t.method == subjects[i].method;
    if (same > 1 && subjects[i].label == subjects[i].method)
      subjects[i].label += " (" + std::filesystem::path(a.images[i]).stem().string() + ")";
  }
  o.r = r;
  o.pixel_lambda_over_d = a.pixel_lod;
  o.frequencies = a.frequencies;
  o.window = a.window == "hamming" ? LsfWindow::kHamming : LsfWindow::kTukey;
  o.esf_half_width_px = a.esf_half_width;
  o.min_contrast_to_noise = a.min_cnr;
  o.max_angle_deg = a.max_angle;
  // Several outputs of one HR grid: up to its Nyquist unless asked (beyond it a discrete image repeats itself).
  o.curve_max = a.images.size() > 1 && a.curve_max_option->count() == 0 ? 0.5 : a.curve_max;
  o.smooth_tails = a.smooth_tails;
  std::string why;
  if (!o.IsValid(&why)) throw InvalidArgument("aosr mtf: " + why);
  // No region given: found on the images (mtf_comparison.hpp FindMtfRegion); every image is read in it.
  std::string roi_source = "given";
  if (a.roi.empty()) {
    std::vector<MtfSubject> named = subjects;
    for (std::size_t i = 0; i < named.size(); ++i) named[i].label = a.images[i];
    o.roi = FindMtfRegion(named, o, &roi_source);
  }
  co.edge = o;
  if (!a.manifest.empty()) {
    if (a.model_psfs == "nominal") {
      dpo.nominal_psfs = true;
    } else if (!a.model_psfs.empty()) {
      dpo.model_psfs = ReadFits(a.model_psfs).planes;
    }
    co.problem = std::make_shared<const ReconstructionProblem>(ProblemFromDataset(LoadDataset(a.manifest), dpo).problem);
  }

  const MtfComparison c = CompareMtf(subjects, co);

  if (!a.out.empty()) {
    LinePlot p = MtfComparisonPlot(c, a.images.size() == 1 ? "slanted-edge MTF of " + a.images[0] : "");
    p.x.max = o.curve_max;
    if (a.images.size() == 1) {
      const SlantedEdgeMtf& m = c.entries[0].edge;
      if (m.has_cutoff) p.series.push_back({"optical cut-off D/lambda", {m.cutoff.frequency, m.cutoff.frequency}, {0.0, 1.0}});
      if (m.mtf50.reached) p.series.push_back({"MTF50", {m.mtf50.frequency}, {0.5}});
    }
    WriteFigure(a.out, {p});
  }
  if (!a.table.empty()) {
    const std::string csv = MtfComparisonCsv(c);
    AtomicWrite(a.table, [&csv](const std::string& tmp) {
      std::ofstream f(tmp);
      f << csv;
      if (!f) throw IoError(tmp, "could not write the table");
    });
  }

  if (a.json) {
    nlohmann::json j;
    if (a.images.size() == 1) {
      j = EdgeJson(a.images[0], o, c.entries[0].edge, r, a.pixel_lod);
      j["method"] = c.entries[0].method;
      j["exact"] = ExactJson(c.entries[0]);
    } else {
      nlohmann::json outs = nlohmann::json::array();
      for (std::size_t i = 0; i < c.entries.size(); ++i) {
        const MtfComparisonEntry& e = c.entries[i];
        nlohmann::json oj = e.measured ? EdgeJson(a.images[i], o, e.edge, r, a.pixel_lod)
                                       : nlohmann::json{{"image", a.images[i]}, {"refusal", e.refusal}};
        oj["label"] = e.label;
        oj["method"] = e.method;
        oj["exact"] = ExactJson(e);
        outs.push_back(oj);
      }
      j = {{"outputs", outs}};
    }
    j["roi_source"] = roi_source;
    if (!a.out.empty()) j["plot"] = a.out;
    if (!a.table.empty()) j["table"] = a.table;
    std::printf("%s\n", j.dump(2).c_str());
    return;
  }
  if (a.images.size() > 1) {
    if (roi_source != "given") std::printf("region: %s\n", roi_source.c_str());
    std::printf("%s", c.BriefReport().c_str());
    for (const MtfComparisonEntry& e : c.entries)
      if (!e.measured) std::fprintf(stderr, "aosr mtf: warning: %s: no usable edge: %s\n", e.label.c_str(), e.refusal.c_str());
    if (!a.out.empty()) std::printf("curves written to %s\n", a.out.c_str());
    if (!a.table.empty()) std::printf("table written to %s\n", a.table.c_str());
    return;
  }
  const SlantedEdgeMtf& m = c.entries[0].edge;
  std::printf("%s: %s\n", a.images[0].c_str(), m.BriefReport().c_str());
  if (roi_source != "given")
    std::printf("  region x %lld..%lld, y %lld..%lld (%s)\n", (long long)o.roi.x0,
                (long long)(o.roi.width > 0 ? o.roi.x0 + o.roi.width - 1 : subjects[0].image.cols() - 1), (long long)o.roi.y0,
                (long long)(o.roi.height > 0 ? o.roi.y0 + o.roi.height - 1 : subjects[0].image.rows() - 1), roi_source.c_str());
  std::printf("  edge through (y, x) = (%.2f, %.2f) px, %lld px long, line-fit RMS %.3f px; levels %.4g -> %.4g, noise RMS %.3g\n",
              m.centre_y, m.centre_x, static_cast<long long>(m.edge_length_px), m.fit_rms_px, m.low, m.high, m.noise_rms);
  if (m.has_nyquist)
    std::printf("  MTF at the camera's Nyquist 1/(2r) = %.4f cycles/px (r = %d): %.4f\n", m.nyquist.frequency, r, m.nyquist.mtf);
  if (m.has_cutoff)
    std::printf("  MTF at the optical cut-off D/lambda = %.4f cycles/px: %.4f\n", m.cutoff.frequency, m.cutoff.mtf);
  for (const MtfPoint& q : m.at) std::printf("  MTF at %.4f cycles/px: %.4f\n", q.frequency, q.mtf);
  const MtfComparisonEntry& e = c.entries[0];
  if (e.exact) {
    std::printf("  exact transfer (%s): %s", e.method.c_str(), c.BriefReport().substr(e.label.size() + 2).c_str());
  } else if (e.exact_status == "signal-dependent") {
    std::printf("  %s is signal-dependent: no exact curve; this edge's curve at its contrast and noise is the answer\n",
                e.method.c_str());
  } else if (e.exact_status.rfind("unavailable", 0) == 0) {
    std::printf("  exact transfer %s\n", e.exact_status.c_str());
  }
  if (!a.out.empty()) std::printf("  curve written to %s\n", a.out.c_str());
  if (!a.table.empty()) std::printf("  table written to %s\n", a.table.c_str());
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
  cmd->add_option("IMAGE", args->images,
                  "the image(s) (FITS; reconstructions, a frame, a truth); several: their curves on one plot and in "
                  "one table, read in the same region")
      ->required()
      ->expected(1, 64);
  cmd->add_option("--roi", args->roi, "region holding the edge: X0,Y0,W,H in pixels (x = column); default: the whole image if it holds one edge, else "
                  "the longest straight edge found in the (first) image that measures (core/edge_search.hpp)")
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
  args->curve_max_option = cmd->add_option("--curve-max", args->curve_max,
                                           "the curve's last frequency [cycles/px] (several images: default 0.5, the "
                                           "HR Nyquist)")
      ->capture_default_str()
      ->check(CLI::Range(0.01, kMaxMtfFrequency));
  cmd->add_flag("--no-smooth-tails", [args](std::int64_t) { args->smooth_tails = false; },
                "plain ISO 12233 LSF (no tail smoothing): for noise-free or ringing edges such as reconstructions, "
                "whose ringing tails the smoothing would remove (solvers/linear_transfer.hpp)");
  cmd->add_flag("--json", args->json, "print the results (and the curve) as JSON");
  cmd->add_option("-o,--out", args->out, "write the curve(s) as a PNG plot");
  cmd->add_option("--table", args->table, "write the curves (edge and exact) as a CSV table");
  cmd->add_option("--manifest", args->manifest,
                  "the dataset the images were reconstructed from: its model gives tikhonov outputs their exact "
                  "transfer (linear outputs carry theirs in the PSF extension)");
  cmd->add_option("--weights", args->weights, "with --manifest: the weights the reconstruction used (as aosr reconstruct)")
      ->capture_default_str();
  cmd->add_option("--model-psfs", args->model_psfs,
                  "with --manifest: the model PSFs the reconstruction used: nominal | a FITS cube (default the dataset's)");
  cmd->add_option("--prior", args->prior, "tikhonov's prior for its exact transfer (as aosr reconstruct --prior)")
      ->capture_default_str();
  cmd->add_flag("--no-exact", args->no_exact, "measured curves only");
  cmd->callback([args] { RunMtf(*args); });
}

}  // namespace aosr::cli
