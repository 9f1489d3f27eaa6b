#include "aosr/optics/psf_metrics.hpp"

#include <algorithm>
#include <cmath>

#include "aosr/core/error.hpp"

namespace aosr {
namespace {
void Check(const char* fn, const Image& psf) {
  CheckArgument(psf.size() > 0, fn, "psf", "empty", "a non-empty image");
  CheckArgument(AllFinite(psf), fn, "psf", "non-finite values", "finite values");
  CheckArgument(psf.sum() > 0, fn, "psf sum", psf.sum(), "> 0");
}
}  // namespace

PsfStats MeasurePsf(const Image& psf) {
  Check("MeasurePsf", psf);
  PsfStats s;
  s.peak = psf.maxCoeff(&s.peak_y, &s.peak_x);
  s.window_sum = psf.sum();
  for (Index y = 0; y < psf.rows(); ++y)
    for (Index x = 0; x < psf.cols(); ++x) {
      s.centroid_y += y * psf(y, x);
      s.centroid_x += x * psf(y, x);
    }
  s.centroid_y /= s.window_sum;
  s.centroid_x /= s.window_sum;
  // Area above half maximum on a k x k sub-pixel grid of the bilinear interpolant: counting whole pixels
  // is biased by several per cent for cores a few pixels wide.
  constexpr int k = 8;
  double above = 0;
  double my = 0, mx = 0, myy = 0, mxx = 0, mxy = 0;  // moments of the region (sub-pixel centres)
  for (Index y = 0; y + 1 < psf.rows(); ++y)
    for (Index x = 0; x + 1 < psf.cols(); ++x) {
      const double a = psf(y, x), b = psf(y, x + 1), c = psf(y + 1, x), d = psf(y + 1, x + 1);
      if (std::max(std::max(a, b), std::max(c, d)) < 0.5 * s.peak) continue;
      for (int i = 0; i < k; ++i)
        for (int j = 0; j < k; ++j) {
          const double ty = (i + 0.5) / k, tx = (j + 0.5) / k;
          const double v = (1 - ty) * ((1 - tx) * a + tx * b) + ty * ((1 - tx) * c + tx * d);
          if (v < 0.5 * s.peak) continue;
          above += 1;
          const double py = static_cast<double>(y) + ty, px = static_cast<double>(x) + tx;
          my += py;
          mx += px;
          myy += py * py;
          mxx += px * px;
          mxy += px * py;
        }
    }
  s.fwhm_px = 2.0 * std::sqrt(above / (k * k) / M_PI);
  if (above > 0) {
    my /= above;
    mx /= above;
    // Covariance of the region plus the sub-pixel cell's own 1/(12 k^2) per axis (a continuous region).
    const double cell = 1.0 / (12.0 * k * k);
    const double cyy = myy / above - my * my + cell, cxx = mxx / above - mx * mx + cell;
    const double cxy = mxy / above - mx * my;
    const double mean = 0.5 * (cxx + cyy), diff = 0.5 * (cxx - cyy);
    const double radius = std::sqrt(diff * diff + cxy * cxy);
    s.fwhm_major_px = 4.0 * std::sqrt(std::max(mean + radius, 0.0));
    s.fwhm_minor_px = 4.0 * std::sqrt(std::max(mean - radius, 0.0));
    s.major_axis_angle_rad = 0.5 * std::atan2(2.0 * cxy, cxx - cyy);
    if (s.major_axis_angle_rad <= -0.5 * M_PI) s.major_axis_angle_rad += M_PI;
  }
  return s;
}

std::vector<double> EncircledEnergy(const Image& psf, const std::vector<double>& radii_px) {
  Check("EncircledEnergy", psf);
  Index py = 0, px = 0;
  psf.maxCoeff(&py, &px);
  const double total = psf.sum();
  std::vector<double> out;
  for (double r : radii_px) {
    CheckArgument(r >= 0 && std::isfinite(r), "EncircledEnergy", "radius", r, ">= 0 and finite");
    double s = 0;
    for (Index y = 0; y < psf.rows(); ++y)
      for (Index x = 0; x < psf.cols(); ++x)
        if (double(y - py) * (y - py) + double(x - px) * (x - px) <= r * r) s += psf(y, x);
    out.push_back(s / total);
  }
  return out;
}

std::pair<double, double> CoreCentroid(const Image& psf, double radius_px) {
  const PsfStats stats = MeasurePsf(psf);  // validates the image
  CheckArgument(std::isfinite(radius_px) && radius_px >= 0.5, "CoreCentroid", "radius_px", radius_px,
                ">= 0.5 and finite [px]");
  double cy = static_cast<double>(stats.peak_y), cx = static_cast<double>(stats.peak_x);
  const double r2 = radius_px * radius_px;
  for (int pass = 0; pass < 10; ++pass) {
    double sum = 0.0, sy = 0.0, sx = 0.0;
    const Index y0 = std::max<Index>(0, static_cast<Index>(std::floor(cy - radius_px)));
    const Index y1 = std::min<Index>(psf.rows() - 1, static_cast<Index>(std::ceil(cy + radius_px)));
    const Index x0 = std::max<Index>(0, static_cast<Index>(std::floor(cx - radius_px)));
    const Index x1 = std::min<Index>(psf.cols() - 1, static_cast<Index>(std::ceil(cx + radius_px)));
    for (Index y = y0; y <= y1; ++y) {
      for (Index x = x0; x <= x1; ++x) {
        const double dy = y - cy, dx = x - cx;
        if (dy * dy + dx * dx > r2) continue;
        sum += psf(y, x);
        sy += psf(y, x) * y;
        sx += psf(y, x) * x;
      }
    }
    if (!(sum > 0.0)) break;
    const double ny = sy / sum, nx = sx / sum;
    const double moved = std::hypot(ny - cy, nx - cx);
    cy = ny;
    cx = nx;
    if (moved < 1e-6) break;
  }
  return {cy, cx};
}

}  // namespace aosr

