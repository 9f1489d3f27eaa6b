// `aosr evaluate`: how close a reconstruction is to the truth — PSNR, SSIM, RMSE, and for star fields the
// photometric and astrometric errors of the brightest stars; with --usaf, the resolving power on a USAF target.
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <memory>
#include <optional>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "aosr/core/error.hpp"
#include "aosr/core/metrics.hpp"
#include "aosr/io/fits.hpp"
#include "aosr/io/plot.hpp"
#include "aosr/scene/dataset.hpp"
#include "aosr/scene/evaluation.hpp"
#include "aosr/scene/scene_spec.hpp"
#include "aosr/scene/star_metrics.hpp"
#include "aosr/scene/usaf_contrast.hpp"
#include "cli_util.hpp"
#include "commands.hpp"

namespace aosr::cli {
namespace {

struct EvaluateArgs {
  std::string truth;
  std::string manifest;
  std::vector<std::string> estimates;
  int crop = -1;  // < 0: the dataset's trustworthy border (in HR pixels) with --manifest, else 0
  double peak = 0;
  int stars = 20;
  double aperture = 3.0;
  std::string subtract_sky = "auto";  // auto (when the estimate's METHOD is linear) | yes | no
  int rings = 0;                      // 0: no rings
  std::string ring_centre;            // "X,Y" [HR px]; empty: the image centre
  std::string plot;                   // PNG of the ring curves; empty: none
  std::string usaf;                   // a scene whose USAF target the estimate images: the resolving-power table
  double usaf_threshold = 0.153;
  bool json = false;
  ExecutionArgs exec;
};

// The label of an estimate in tables and plots: its METHOD keyword, else its file name without extension.
std::string EstimateLabel(const std::string& path) {
  const FitsHeader h = ReadFits(path).header;
  std::string label = std::filesystem::path(path).stem().string();
  if (h.Find("METHOD") != nullptr) {
    try {
      label = h.GetString("METHOD") + " (" + label + ")";
    } catch (const InvalidArgument&) {  // not a string: keep the file name
    }
  }
  return label;
}

// The ring curves of every estimate: aligned PSNR and SSIM against the ring's mid radius, and with a catalogue the
// photometric bias.
void WriteRingPlot(const std::string& path, const std::vector<std::string>& labels,
                   const std::vector<Evaluation>& evs, double hr_mas) {
  const bool stars = !evs.empty() && !evs[0].ring_stars.empty();
  LinePlot psnr, ssim, bias;
  const std::string x_label = hr_mas > 0 ? "distance from the centre [arcsec]" : "distance from the centre [HR px]";
  psnr.x.label = ssim.x.label = bias.x.label = x_label;
  psnr.title = "aligned PSNR in rings";
  psnr.y.label = "aligned PSNR [dB]";
  ssim.title = "aligned SSIM in rings";
  ssim.y.label = "aligned SSIM";
  bias.title = "photometric bias in rings (median flux error)";
  bias.y.label = "flux bias [%]";
  for (std::size_t i = 0; i < evs.size(); ++i) {
    PlotSeries a, b, c;
    a.label = b.label = c.label = labels[i];
    for (std::size_t k = 0; k < evs[i].rings.rings.size(); ++k) {
      const RingScore& r = evs[i].rings.rings[k];
      const double mid = 0.5 * (r.inner_px + r.outer_px) * (hr_mas > 0 ? hr_mas / 1000 : 1.0);
      a.x.push_back(mid);
      a.y.push_back(r.scores.aligned.psnr);
      b.x.push_back(mid);
      b.y.push_back(r.scores.aligned.ssim);
      if (stars) {
        const RingPhotometry& p = evs[i].ring_stars[k];
        c.x.push_back(mid);
        c.y.push_back(p.stars > 0 ? 100 * p.flux_bias : std::numeric_limits<double>::quiet_NaN());
      }
    }
    psnr.series.push_back(a);
    ssim.series.push_back(b);
    bias.series.push_back(c);
  }
  std::vector<LinePlot> panels{psnr, ssim};
  if (stars) panels.push_back(bias);
  FigureOptions fo;
  fo.columns = int(panels.size());
  WriteFigure(path, panels, fo);
}

// The resolving power on the USAF target of `scene` (scene/usaf_contrast.hpp), as JSON and as text lines.
nlohmann::json UsafJson(const UsafResolvingPower& p) {
  nlohmann::json list = nlohmann::json::array();
  for (const UsafElementContrast& e : p.elements) {
    if (!e.measured) continue;
    list.push_back({{"group", e.group}, {"element", e.element}, {"bar_width_hr_px", e.bar_width_px},
                    {"cycles_per_hr_px", e.cycles_per_px}, {"cycles_per_camera_px", e.cycles_per_camera_px},
                    {"cycles_per_lambda_over_d", e.cycles_per_lambda_over_d}, {"contrast_x", e.contrast_x},
                    {"contrast_y", e.contrast_y}, {"contrast", e.contrast}, {"transfer", e.transfer}, {"resolved", e.resolved}});
  }
  nlohmann::json j = {{"threshold", p.threshold}, {"elements", list}, {"finest", nullptr}};
  if (p.finest >= 0) {
    const UsafElementContrast& f = p.elements[std::size_t(p.finest)];
    j["finest"] = {{"group", f.group}, {"element", f.element}, {"cycles_per_hr_px", f.cycles_per_px},
                   {"cycles_per_camera_px", f.cycles_per_camera_px}, {"cycles_per_lambda_over_d", f.cycles_per_lambda_over_d}};
  }
  return j;
}

void PrintUsaf(const UsafResolvingPower& p) {
  std::printf("  USAF resolving power (Michelson contrast of the three bars, min of both orientations; resolved >= %.3f):\n",
              p.threshold);
  std::printf("    group/elem  cyc/HR px  cyc/cam px  cyc/(lambda/D)  contrast_x  contrast_y  transfer\n");
  for (const UsafElementContrast& e : p.elements) {
    if (!e.measured) continue;
    std::printf("    %5d/%-4d  %9.4f  %10.4f  %14.4f  %10.3f  %10.3f  %8.3f %s\n", e.group, e.element, e.cycles_per_px,
                e.cycles_per_camera_px, e.cycles_per_lambda_over_d, e.contrast_x, e.contrast_y, e.transfer,
                e.resolved ? "resolved" : "");
  }
  if (p.finest < 0) {
    std::printf("  finest resolved element: none\n");
  } else {
    const UsafElementContrast& f = p.elements[std::size_t(p.finest)];
    std::printf("  finest resolved element: group %d element %d: %.4f cycles/HR px, %.4f cycles/camera px, %.4f cycles per lambda/D\n",
                f.group, f.element, f.cycles_per_px, f.cycles_per_camera_px, f.cycles_per_lambda_over_d);
  }
}

void RunEvaluate(const EvaluateArgs& a) {
  ApplyExecution(a.exec);
  if (!a.usaf.empty() && a.truth.empty() && a.manifest.empty()) {  // the resolving power alone: no truth needed
    const SceneSpec scene = LoadScene(a.usaf);
    std::vector<nlohmann::json> outputs;
    for (const std::string& path : a.estimates) {
      const UsafResolvingPower p = MeasureSceneUsafResolvingPower(ReadFitsImage(path), scene, a.usaf_threshold);
      outputs.push_back({{"estimate", path}, {"usaf", UsafJson(p)}});
      if (!a.json) {
        std::printf("%s:\n", path.c_str());
        PrintUsaf(p);
      }
    }
    if (a.json) {
      const nlohmann::json out = outputs.size() == 1 ? outputs[0] : nlohmann::json{{"estimates", outputs}};
      std::printf("%s\n", out.dump(2).c_str());
    }
    return;
  }
  if (a.truth.empty() == a.manifest.empty())
    throw InvalidArgument("aosr evaluate", "--truth/--manifest", a.truth.empty() ? "(neither)" : "(both)",
                          "exactly one of --truth FILE and --manifest DIR");
  if (a.rings == 0 && !a.ring_centre.empty())
    throw InvalidArgument("aosr evaluate", "--ring-centre", a.ring_centre, "only with --rings K (K >= 1)");
  if (a.rings == 0 && !a.plot.empty())
    throw InvalidArgument("aosr evaluate", "--plot", a.plot, "only with --rings K (K >= 1): it draws the ring curves");
  double centre_y = std::numeric_limits<double>::quiet_NaN(), centre_x = centre_y;
  if (!a.ring_centre.empty()) ParseRingCentre("aosr evaluate", a.ring_centre, &centre_y, &centre_x);
  if (!a.plot.empty()) CheckWritableFile(a.plot);
  Image truth;
  std::vector<PointSource> stars;
  int crop = std::max(0, a.crop);
  double hr_mas = 0.0;  // the offset in mas needs the HR pixel scale: the dataset's, or the truth's PIXSCALE
  if (!a.manifest.empty()) {
    const Dataset d = LoadDataset(a.manifest);
    if (!d.truth) throw InvalidArgument("aosr evaluate", "--manifest", a.manifest, "a dataset whose manifest names a truth image");
    truth = *d.truth;
    stars = d.stars;
    if (a.crop < 0) crop = DatasetCrop(d.trustworthy_border_px, d.r);
    hr_mas = DatasetHrPixelMas(d);
  } else {
    truth = ReadFitsImage(a.truth);
    hr_mas = FitsPixelScaleMas(a.truth);
  }
  if (2 * crop >= std::min(truth.rows(), truth.cols()))
    throw InvalidArgument("aosr evaluate", "--crop", std::to_string(crop) + (a.crop < 0 ? " (the dataset's border)" : ""),
                          "less than half the smaller image side; the border a periodic model cannot reproduce is "
                          "the PSF's half-width, so a frame smaller than the PSF window needs an explicit --crop");
  if (!std::isnan(centre_y) && !(centre_y >= -0.5 && centre_y <= truth.rows() - 0.5 && centre_x >= -0.5 &&
                                 centre_x <= truth.cols() - 0.5))
    throw InvalidArgument("aosr evaluate", "--ring-centre", a.ring_centre,
                          "a point on the " + ToString(ShapeOf(truth)) + " HR image: -0.5 <= X <= " +
                              ToString(truth.cols() - 0.5) + ", -0.5 <= Y <= " + ToString(truth.rows() - 0.5));
  std::vector<Evaluation> evs;
  std::vector<nlohmann::json> outputs;
  std::vector<std::string> labels;
  for (const std::string& path : a.estimates) {
    const Image estimate = ReadFitsImage(path);
    // The flags' own names in the messages; the library checks the same again (scene/evaluation.hpp).
    if (ShapeOf(estimate) != ShapeOf(truth))
      throw InvalidArgument("aosr evaluate", "--estimate", path + " (" + ToString(ShapeOf(estimate)) + ")",
                            "an image of the truth's shape " + ToString(ShapeOf(truth)));
    if (!AllFinite(estimate)) throw InvalidArgument("aosr evaluate", "--estimate", path, "an image with finite values only");
    EvaluationOptions eo;
    eo.crop_px = crop;
    eo.peak = a.peak;
    eo.stars = a.stars;
    eo.aperture_px = a.aperture;
    eo.hr_pixel_mas = hr_mas;
    eo.subtract_sky = a.subtract_sky == "yes" || (a.subtract_sky == "auto" && OutputKeepsSky(path));
    eo.rings = a.rings;
    eo.ring_centre_y = centre_y;
    eo.ring_centre_x = centre_x;
    Evaluation ev;
    try {
      ev = EvaluateReconstruction(truth, estimate, stars, eo);
    } catch (const InvalidArgument& e) {
      // The library names its own fields (rings, centre); say which flag they came from.
      const std::string what = e.what();
      if (what.find("rings") != std::string::npos || what.find("centre") != std::string::npos)
        throw InvalidArgument("aosr evaluate: --rings " + std::to_string(a.rings) +
                              (a.ring_centre.empty() ? "" : " --ring-centre " + a.ring_centre) + ": " + what);
      throw;
    }
    const ImageMetrics& m = ev.metrics;
    const StarMetrics& sm = ev.stars;
    nlohmann::json j = {{"estimate", path}, {"crop_px", crop}, {"psnr_db", m.psnr}, {"ssim", m.ssim}, {"rmse", m.rmse}};
    AddAlignedScores(ev, &j);
    if (eo.subtract_sky) j["sky_subtracted"] = ev.sky;
    if (ev.measured_stars) {
      nlohmann::json list = nlohmann::json::array();
      for (const StarMeasurement& s : sm.stars)
        list.push_back({{"y_hr_px", s.truth.y}, {"x_hr_px", s.truth.x}, {"flux_e", s.truth.flux}, {"flux_error", s.flux_error},
                        {"dy_hr_px", s.dy}, {"dx_hr_px", s.dx}});
      j["stars"] = {{"measured", sm.stars.size()},
                    {"skipped_at_edge", sm.skipped},
                    {"median_abs_flux_error", sm.median_abs_flux_error},
                    {"rms_position_error_hr_px", sm.rms_position_error_px},
                    {"aperture_hr_px", a.aperture},
                    {"brightest", list}};
    }
    if (ev.measured_rings) j["rings"] = EvaluationRingsJson(ev, hr_mas);
    std::optional<UsafResolvingPower> usaf;
    if (!a.usaf.empty()) {
      usaf = MeasureSceneUsafResolvingPower(estimate, LoadScene(a.usaf), a.usaf_threshold);
      j["usaf"] = UsafJson(*usaf);
    }
    if (!a.json) {
      std::printf("%s: PSNR %.2f dB  SSIM %.4f  RMSE %.4g  (crop %d px)\n", path.c_str(), m.psnr, m.ssim, m.rmse, crop);
      std::printf("  %s\n", AlignedScoresLine(ev).c_str());
      if (eo.subtract_sky)
        std::printf("  sky subtracted before scoring: %.4g per HR pixel (the estimate's median level minus the truth's)\n", ev.sky);
      if (!stars.empty())
        std::printf("  %zu brightest stars (%d skipped at the edge): median |flux error| %.2f%%, RMS position error %.3f HR px\n",
                    sm.stars.size(), sm.skipped, 100 * sm.median_abs_flux_error, sm.rms_position_error_px);
      if (ev.measured_rings) std::printf("%s", RingsTable(ev, hr_mas, "  ").c_str());
      if (usaf) PrintUsaf(*usaf);
    }
    if (!a.plot.empty()) labels.push_back(EstimateLabel(path));
    outputs.push_back(std::move(j));
    evs.push_back(std::move(ev));
  }
  if (!a.plot.empty()) {
    WriteRingPlot(a.plot, labels, evs, hr_mas);
    if (!a.json) std::printf("wrote %s (aligned PSNR%s against the distance from the centre)\n", a.plot.c_str(),
                             stars.empty() ? " and SSIM" : ", SSIM and photometric bias");
  }
  if (a.json) {
    // One estimate: its object, as before; several: {"estimates": [...]} in the order given.
    const nlohmann::json out = outputs.size() == 1 ? outputs[0] : nlohmann::json{{"estimates", outputs}};
    std::printf("%s\n", out.dump(2).c_str());
  }
}

}  // namespace

void RegisterEvaluate(CLI::App& app) {
  auto args = std::make_shared<EvaluateArgs>();
  CLI::App* cmd = app.add_subcommand(
      "evaluate",
      "Compare a reconstruction with the truth: PSNR, SSIM and RMSE (metrics.hpp), raw and after removing the "
      "sub-pixel offset of the reconstruction against the truth measured on the scored crop (apodised; applied only "
      "when it lowers neither PSNR nor SSIM, so aligned >= raw; the offset reported in HR px, and in mas when the "
      "dataset or the truth's PIXSCALE gives the pixel scale), with --manifest on a star "
      "field the aperture-photometry and centroid errors of the brightest stars (star_metrics.hpp), and with --rings "
      "the same scores in rings about a centre (the guide star), each ring aligned on its own.");
  cmd->add_option("--truth", args->truth, "truth image (FITS, HR grid)");
  cmd->add_option("--manifest", args->manifest, "a dataset (folder or manifest.json) whose truth and stars to use");
  cmd->add_option("--estimate", args->estimates,
                  "the reconstruction (FITS, HR grid); several may follow (--estimate a.fits b.fits), each scored in "
                  "turn (--json then prints {\"estimates\": [...]}) and drawn as one curve by --plot")
      ->required()
      ->expected(1, 1000);
  cmd->add_option("--crop", args->crop, "pixels ignored at each border (default: the dataset's border, else 0)")
      ->check(CLI::Range(0, 100000));
  cmd->add_option("--peak", args->peak, "PSNR/SSIM dynamic range L (default max - min of the truth)")->check(NonNegativeFinite());
  cmd->add_option("--stars", args->stars, "number of brightest stars measured")->capture_default_str()->check(CLI::Range(1, 100000));
  cmd->add_option("--aperture", args->aperture, "star aperture radius [HR px]")->capture_default_str()->check(CLI::Range(0.5, 1000.0));
  cmd->add_option("--subtract-sky", args->subtract_sky,
                  "subtract the estimate's sky (its median level minus the truth's over the scored region) before "
                  "scoring: auto (when the estimate's METHOD keyword is linear, an output that keeps the frames' sky) | yes | no")
      ->capture_default_str()
      ->check(CLI::IsMember({"auto", "yes", "no"}));
  cmd->add_option("--rings", args->rings,
                  "also score K concentric rings about --ring-centre (equal widths out to the crop's farthest corner, "
                  "each at least 11 HR px wide), each aligned on its own: PSNR, SSIM, offset and, with --manifest on "
                  "a star field, the photometric bias of its stars (core/metrics.hpp CompareImagesInRings)")
      ->check(CLI::Range(1, 100000));
  cmd->add_option("--ring-centre", args->ring_centre,
                  "X,Y: the rings' centre in HR pixels, column then row, 0-based pixel centres (e.g. the guide "
                  "star's position); default the image centre");
  cmd->add_option("--plot", args->plot,
                  "with --rings: write a PNG of aligned PSNR and SSIM (and the photometric bias with a star list) "
                  "against the distance from the centre, one curve per --estimate");
  cmd->add_option("--usaf", args->usaf,
                  "a scene file whose USAF target (its first usaf or demo object) the estimate images: print the Michelson "
                  "contrast of each element's bars in both orientations and the finest element resolved "
                  "(scene/usaf_contrast.hpp); needs no --truth");
  cmd->add_option("--usaf-threshold", args->usaf_threshold,
                  "contrast at which a USAF element counts as resolved (default 0.153, the Rayleigh dip)")
      ->check(CLI::Range(1e-6, 0.999999));
  cmd->add_flag("--json", args->json, "print the results as JSON");
  AddExecutionOptions(cmd, &args->exec);
  cmd->callback([args] { RunEvaluate(*args); });
}

}  // namespace aosr::cli
