#include "aosr/scene/evaluation.hpp"

#include <algorithm>
#include <cmath>
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
  return e;
}

}  // namespace aosr
