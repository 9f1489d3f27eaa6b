#include "aosr/scene/evaluation.hpp"

#include <algorithm>

#include "aosr/core/error.hpp"

namespace aosr {

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
  MetricOptions mo;
  mo.crop_px = o.crop_px;
  mo.peak = o.peak;
  Evaluation e;
  e.metrics = CompareImages(truth, estimate, mo);
  if (!stars.empty()) {
    StarMetricsOptions so;
    so.brightest = o.stars;
    so.aperture_px = o.aperture_px;
    so.annulus_inner_px = o.aperture_px + 2;
    so.annulus_outer_px = o.aperture_px + 5;
    e.stars = MeasureStars(truth, estimate, stars, so);
    e.measured_stars = true;
  }
  return e;
}

}  // namespace aosr
