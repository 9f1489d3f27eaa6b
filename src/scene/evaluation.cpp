#include "aosr/scene/evaluation.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include "aosr/core/error.hpp"
#include "aosr/io/fits.hpp"

namespace aosr {

double DatasetHrPixelMas(const Dataset& d) {
  constexpr double kMasPerRad = 180.0 / M_PI * 3600.0 * 1000.0;
  return d.camera_pixel_rad > 0 && d.r > 0 ? d.camera_pixel_rad / d.r * kMasPerRad : 0.0;
}

double FitsPixelScaleMas(const std::string& path) {
  const FitsHeader h = ReadFits(path).header;
  if (h.Find("PIXSCALE") == nullptr) return 0.0;
  try {
    const double scale = h.GetDouble("PIXSCALE");
    return std::isfinite(scale) && scale > 0 ? scale : 0.0;
  } catch (const InvalidArgument&) {  // not a number: unknown
    return 0.0;
  }
}

double SkyLevelDifference(const Image& reference, const Image& estimate, int crop_px) {
  const char* f = "SkyLevelDifference";
  CheckArgument(ShapeOf(estimate) == ShapeOf(reference), f, "estimate", ToString(ShapeOf(estimate)),
                "an image of the reference's shape " + ToString(ShapeOf(reference)));
  const Index c = crop_px, rows = reference.rows() - 2 * c, cols = reference.cols() - 2 * c;
  CheckArgument(crop_px >= 0 && rows > 0 && cols > 0, f, "crop_px", crop_px, "0 .. less than half the smaller image side");
  auto median = [&](const Image& img) {
    std::vector<double> v;
    v.reserve(std::size_t(rows * cols));
    for (Index y = 0; y < rows; ++y)
      for (Index x = 0; x < cols; ++x) v.push_back(img(c + y, c + x));
    std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
    return v[v.size() / 2];
  };
  return median(estimate) - median(reference);
}

bool OutputKeepsSky(const std::string& fits_path) {
  const FitsHeader h = ReadFits(fits_path).header;
  if (h.Find("METHOD") == nullptr) return false;
  try {
    return h.GetString("METHOD") == "linear";
  } catch (const InvalidArgument&) {  // not a string: not ours
    return false;
  }
}

namespace {

double EvaluationMedian(std::vector<double> v) {
  if (v.empty()) return std::numeric_limits<double>::quiet_NaN();
  const std::size_t h = v.size() / 2;
  std::nth_element(v.begin(), v.begin() + h, v.end());
  if (v.size() % 2) return v[h];
  const double hi = v[h];
  return 0.5 * (hi + *std::max_element(v.begin(), v.begin() + h));
}

// Each ring's photometry: all catalogue stars measured (brightest first), each assigned to the ring its true
// position falls in (stars in the crop's border belong to none), the first `o.stars` of each ring kept.
std::vector<RingPhotometry> RingStars(const Image& truth, const Image& estimate, const std::vector<PointSource>& stars,
                                      const RingMetrics& rings, const EvaluationOptions& o) {
  StarMetricsOptions so;
  so.brightest = int(std::min<std::size_t>(stars.size(), std::size_t(std::numeric_limits<int>::max())));
  so.aperture_px = o.aperture_px;
  so.annulus_inner_px = o.aperture_px + 2;
  so.annulus_outer_px = o.aperture_px + 5;
  const StarMetrics all = MeasureStars(truth, estimate, stars, so);
  const std::size_t k_rings = rings.rings.size();
  std::vector<std::vector<double>> errors(k_rings);
  const double c = o.crop_px;
  for (const StarMeasurement& s : all.stars) {
    // In the crop: within half a pixel of its outermost pixel centres.
    if (s.truth.y < c - 0.5 || s.truth.x < c - 0.5 || s.truth.y > truth.rows() - c - 0.5 ||
        s.truth.x > truth.cols() - c - 0.5)
      continue;
    const double rho = std::hypot(s.truth.y - rings.centre_y, s.truth.x - rings.centre_x);
    std::size_t k = 0;
    while (k + 1 < k_rings && rho >= rings.rings[k].outer_px) ++k;
    if (rho < rings.rings[0].inner_px || int(errors[k].size()) >= o.stars) continue;
    errors[k].push_back(s.flux_error);
  }
  std::vector<RingPhotometry> out(k_rings);
  for (std::size_t k = 0; k < k_rings; ++k) {
    out[k].stars = int(errors[k].size());
    out[k].flux_bias = EvaluationMedian(errors[k]);
    std::vector<double> abs_errors;
    for (double v : errors[k]) abs_errors.push_back(std::abs(v));
    out[k].median_abs_flux_error = EvaluationMedian(abs_errors);
  }
  return out;
}

}  // namespace

Evaluation EvaluateReconstruction(const Image& truth, const Image& estimate, const std::vector<PointSource>& stars,
                                  const EvaluationOptions& o) {
  const char* f = "EvaluateReconstruction";
  CheckArgument(ShapeOf(estimate) == ShapeOf(truth), f, "estimate", ToString(ShapeOf(estimate)),
                "an image of the truth's shape " + ToString(ShapeOf(truth)));
  CheckArgument(AllFinite(estimate), f, "estimate", "(non-finite values)", "an image with finite values only");
  CheckArgument(o.crop_px >= 0 && 2 * Index(o.crop_px) < std::min(truth.rows(), truth.cols()), f, "crop", o.crop_px,
                "0 .. less than half the smaller image side; the border a periodic model cannot reproduce is the "
                "PSF's half-width, so a frame smaller than the PSF window needs an explicit crop");
  CheckArgument(o.stars >= 1, f, "stars", o.stars, ">= 1");
  CheckArgument(o.aperture_px >= 0.5 && o.aperture_px <= 1000, f, "aperture", o.aperture_px, "0.5 .. 1000 HR px");
  CheckArgument(std::isfinite(o.hr_pixel_mas) && o.hr_pixel_mas >= 0, f, "hr_pixel_mas", o.hr_pixel_mas,
                ">= 0 and finite [mas] (0: unknown)");
  CheckArgument(o.rings >= 0, f, "rings", o.rings, ">= 0 (0: no rings)");
  MetricOptions mo;
  mo.crop_px = o.crop_px;
  mo.peak = o.peak;
  Evaluation e;
  Image scored;
  if (o.subtract_sky) {
    e.sky = SkyLevelDifference(truth, estimate, o.crop_px);
    scored = estimate.array() - e.sky;
  }
  const Image& est = o.subtract_sky ? scored : estimate;
  const AlignedImageMetrics am = CompareImagesAligned(truth, est, mo);
  e.metrics = am.raw;
  e.aligned = am.aligned;
  e.offset = am.offset;
  e.measured_offset = am.measured_offset;
  e.offset_applied = am.offset_applied;
  e.offset_mas_known = o.hr_pixel_mas > 0;
  e.offset_mas[0] = am.offset.dy * o.hr_pixel_mas;
  e.offset_mas[1] = am.offset.dx * o.hr_pixel_mas;
  if (!stars.empty()) {
    StarMetricsOptions so;
    so.brightest = o.stars;
    so.aperture_px = o.aperture_px;
    so.annulus_inner_px = o.aperture_px + 2;
    so.annulus_outer_px = o.aperture_px + 5;
    e.stars = MeasureStars(truth, est, stars, so);
    e.measured_stars = true;
  }
  if (o.rings > 0) {
    RingOptions ro;
    ro.rings = o.rings;
    ro.centre_y = o.ring_centre_y;
    ro.centre_x = o.ring_centre_x;
    e.rings = CompareImagesInRings(truth, est, ro, mo);
    e.measured_rings = true;
    if (!stars.empty()) e.ring_stars = RingStars(truth, est, stars, e.rings, o);
  }
  return e;
}

nlohmann::json EvaluationRingsJson(const Evaluation& ev, double hr_mas) {
  if (!ev.measured_rings) return nullptr;
  const RingMetrics& rm = ev.rings;
  nlohmann::json list = nlohmann::json::array();
  for (std::size_t k = 0; k < rm.rings.size(); ++k) {
    const RingScore& r = rm.rings[k];
    const AlignedImageMetrics& m = r.scores;
    nlohmann::json j = {{"inner_hr_px", r.inner_px},
                        {"outer_hr_px", r.outer_px},
                        {"pixels", r.pixels},
                        {"area_hr_px2", r.area_px},
                        {"ssim_positions", r.ssim_positions},
                        {"psnr_db", m.raw.psnr},
                        {"ssim", m.raw.ssim},
                        {"rmse", m.raw.rmse},
                        {"aligned", {{"psnr_db", m.aligned.psnr}, {"ssim", m.aligned.ssim}, {"rmse", m.aligned.rmse}}},
                        {"offset_hr_px", {{"dy", m.offset.dy}, {"dx", m.offset.dx}}},
                        {"offset_measured_hr_px", {{"dy", m.measured_offset.dy}, {"dx", m.measured_offset.dx}}},
                        {"offset_applied", m.offset_applied}};
    if (hr_mas > 0) {
      j["inner_arcsec"] = r.inner_px * hr_mas / 1000;
      j["outer_arcsec"] = r.outer_px * hr_mas / 1000;
    }
    if (!ev.ring_stars.empty()) {
      const RingPhotometry& p = ev.ring_stars[k];
      j["stars"] = {{"measured", p.stars},
                    {"flux_bias", p.stars > 0 ? nlohmann::json(p.flux_bias) : nlohmann::json(nullptr)},
                    {"median_abs_flux_error",
                     p.stars > 0 ? nlohmann::json(p.median_abs_flux_error) : nlohmann::json(nullptr)}};
    }
    list.push_back(j);
  }
  return {{"count", rm.rings.size()},
          {"centre_hr_px", {{"x", rm.centre_x}, {"y", rm.centre_y}}},
          {"peak", rm.peak},
          {"rings", list}};
}

}  // namespace aosr
