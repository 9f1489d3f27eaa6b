#include "aosr/scene/star_metrics.hpp"

#include <algorithm>
#include <cmath>

#include "aosr/core/error.hpp"

namespace aosr {
namespace {

double Median(std::vector<double> v) {
  if (v.empty()) return 0.0;
  const std::size_t h = v.size() / 2;
  std::nth_element(v.begin(), v.begin() + h, v.end());
  if (v.size() % 2) return v[h];
  const double hi = v[h];
  return 0.5 * (hi + *std::max_element(v.begin(), v.begin() + h));
}

struct ApertureMeasure {
  double flux = 0.0;
  double cy = 0.0, cx = 0.0;
};

// Background-subtracted aperture flux and centroid around (y, x); false if the annulus leaves the image.
bool Measure(const Image& img, double y, double x, const StarMetricsOptions& o, ApertureMeasure* out) {
  const double ro = o.annulus_outer_px;
  if (y - ro < -0.5 || x - ro < -0.5 || y + ro > img.rows() - 0.5 || x + ro > img.cols() - 0.5) return false;
  std::vector<double> ring;
  const Index y0 = Index(std::floor(y - ro)), y1 = Index(std::ceil(y + ro));
  const Index x0 = Index(std::floor(x - ro)), x1 = Index(std::ceil(x + ro));
  for (Index i = std::max<Index>(0, y0); i <= std::min(img.rows() - 1, y1); ++i)
    for (Index j = std::max<Index>(0, x0); j <= std::min(img.cols() - 1, x1); ++j) {
      const double d = std::hypot(i - y, j - x);
      if (d >= o.annulus_inner_px && d < ro) ring.push_back(img(i, j));
    }
  const double b = Median(ring);
  ApertureMeasure a;
  double w = 0, sy = 0, sx = 0;
  for (Index i = std::max<Index>(0, y0); i <= std::min(img.rows() - 1, y1); ++i)
    for (Index j = std::max<Index>(0, x0); j <= std::min(img.cols() - 1, x1); ++j) {
      if (std::hypot(i - y, j - x) > o.aperture_px) continue;
      const double v = img(i, j) - b;
      a.flux += v;
      const double p = std::max(v, 0.0);
      w += p, sy += p * i, sx += p * j;
    }
  a.cy = w > 0 ? sy / w : y;
  a.cx = w > 0 ? sx / w : x;
  *out = a;
  return true;
}

// Iterated centroid (aperture re-centred), flux at the first (true-position) aperture.
bool MeasureStar(const Image& img, const PointSource& s, const StarMetricsOptions& o, ApertureMeasure* out) {
  ApertureMeasure a;
  if (!Measure(img, s.y, s.x, o, &a)) return false;
  const double flux = a.flux;
  for (int k = 1; k < o.centroid_iterations; ++k) {
    ApertureMeasure next;
    if (!Measure(img, a.cy, a.cx, o, &next)) break;
    a = next;
  }
  a.flux = flux;
  *out = a;
  return true;
}

}  // namespace

bool StarMetricsOptions::IsValid(std::string* why) const {
  auto fail = [why](const std::string& m) {
    if (why) *why = m;
    return false;
  };
  if (brightest < 1) return fail("brightest = " + std::to_string(brightest) + "; allowed: >= 1");
  if (!(aperture_px > 0 && std::isfinite(aperture_px))) return fail("aperture_px = " + ToString(aperture_px) + "; allowed: > 0");
  if (!(annulus_inner_px > aperture_px && annulus_outer_px > annulus_inner_px && std::isfinite(annulus_outer_px)))
    return fail("annulus_inner_px/annulus_outer_px = " + ToString(annulus_inner_px) + "/" + ToString(annulus_outer_px) +
                "; allowed: aperture_px < inner < outer, finite");
  if (centroid_iterations < 1) return fail("centroid_iterations = " + std::to_string(centroid_iterations) + "; allowed: >= 1");
  return true;
}

StarMetrics MeasureStars(const Image& truth, const Image& estimate, const std::vector<PointSource>& catalogue,
                         const StarMetricsOptions& options) {
  std::string why;
  if (!options.IsValid(&why)) throw InvalidArgument("MeasureStars: options." + why);
  CheckArgument(ShapeOf(truth) == ShapeOf(estimate), "MeasureStars", "estimate shape", ToString(ShapeOf(estimate)),
                "the truth's shape " + ToString(ShapeOf(truth)));
  CheckArgument(AllFinite(truth), "MeasureStars", "truth", "(non-finite values)", "finite values");
  CheckArgument(AllFinite(estimate), "MeasureStars", "estimate", "(non-finite values)", "finite values");
  std::vector<PointSource> sorted = catalogue;
  std::stable_sort(sorted.begin(), sorted.end(), [](const PointSource& a, const PointSource& b) { return a.flux > b.flux; });
  StarMetrics m;
  std::vector<double> abs_flux;
  double sq = 0;
  for (const PointSource& s : sorted) {
    if (int(m.stars.size()) == options.brightest) break;
    ApertureMeasure t, e;
    if (!MeasureStar(truth, s, options, &t) || !MeasureStar(estimate, s, options, &e) || !(t.flux > 0)) {
      ++m.skipped;
      continue;
    }
    StarMeasurement sm;
    sm.truth = s;
    sm.flux_truth = t.flux;
    sm.flux_estimate = e.flux;
    sm.flux_error = (e.flux - t.flux) / t.flux;
    sm.dy = e.cy - t.cy;
    sm.dx = e.cx - t.cx;
    abs_flux.push_back(std::abs(sm.flux_error));
    sq += sm.dy * sm.dy + sm.dx * sm.dx;
    m.stars.push_back(sm);
  }
  m.median_abs_flux_error = Median(abs_flux);
  m.rms_position_error_px = m.stars.empty() ? 0.0 : std::sqrt(sq / m.stars.size());
  return m;
}

}  // namespace aosr
