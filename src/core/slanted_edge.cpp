#include "aosr/core/slanted_edge.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>

#include "aosr/core/error.hpp"

namespace aosr {
namespace {

constexpr const char* kSlantedEdgeFn = "MeasureSlantedEdgeMtf";
constexpr double kEsfBin = 1.0 / kEsfOversampling;  // Δ, px
constexpr double kEsfMinHalfWidthPx = 5.0;          // the ESF must reach this far on both sides of the edge
constexpr Index kEdgeMinAcrossPx = 12;               // columns across the edge
constexpr double kEdgeBadRowFraction = 0.1;          // rows without a rising edge tolerated
constexpr double kEdgePlateauTolerance = 1e-6;       // of the region's range
constexpr double kEdgePlateauFraction = 0.01;        // of the region's pixels
constexpr double kMtfCrossingGrid = 0.005;          // cycles/px, the scan for MTF50/MTF10
constexpr double kEdgeNoiseFloor = 1e-9;             // of the contrast: rounding, not noise
constexpr double kLsfMaxTailSmoothingPx = 4.0;      // half-width cap of the LSF tails' running mean

// sinc(x) = sin(πx)/(πx), 1 at 0.
double EdgeSinc(double x) {
  if (std::abs(x) < 1e-12) return 1.0;
  return std::sin(M_PI * x) / (M_PI * x);
}

std::string EdgeFixed(double v, int digits) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.*f", digits, v);
  return buf;
}

[[noreturn]] void RefuseEdge(const std::string& where, const std::string& what) {
  throw InvalidArgument(std::string(kSlantedEdgeFn) + ": no usable edge in " + where + ": " + what);
}

// A window of half-width h centred on c: Hamming 0.54 + 0.46 cos(π u), u = |x − c| / h, held at 0.08 beyond.
double EdgeHamming(double x, double c, double h) {
  const double u = std::min(1.0, std::abs(x - c) / h);
  return 0.54 + 0.46 * std::cos(M_PI * u);
}

struct EdgeLineFit {
  double a = 0.0;  // x_e(y) = a + b y
  double b = 0.0;
  double rms = 0.0;
  int bad_rows = 0;
  int inner_bad_rows = 0;  // bad rows between the first and the last good one
};

// Step 2 of the header: per-row centroids of the windowed derivative around centre(y) = a + b y, and the
// least-squares line through the good rows.
EdgeLineFit FitEdge(const Image& a, double polarity, double contrast, double centre_a, double centre_b, Index y_first = 0,
                Index y_last = -1) {
  const Index rows = a.rows(), cols = a.cols();
  const double h = 0.5 * double(cols);
  std::vector<double> ys, xs;
  ys.reserve(rows);
  xs.reserve(rows);
  EdgeLineFit fit;
  if (y_last < 0) y_last = rows - 1;
  for (Index y = y_first; y <= y_last; ++y) {
    const double c = centre_a + centre_b * double(y);
    double s0 = 0.0, s1 = 0.0;
    for (Index x = 1; x + 1 < cols; ++x) {
      const double g = polarity * 0.5 * (a(y, x + 1) - a(y, x - 1)) * EdgeHamming(double(x), c, h);
      s0 += g;
      s1 += g * double(x);
    }
    // A rising edge's derivative integrates to the contrast; less than a quarter of it is no edge in this row.
    if (!(s0 > 0.25 * contrast)) {
      ++fit.bad_rows;
      continue;
    }
    ys.push_back(double(y));
    xs.push_back(s1 / s0);
  }
  const std::size_t n = ys.size();
  if (n >= 2) fit.inner_bad_rows = int(ys.back() - ys.front() + 1) - int(n);
  if (n < 2) {
    fit.bad_rows = int(rows);
    return fit;
  }
  double my = 0.0, mx = 0.0;
  for (std::size_t i = 0; i < n; ++i) my += ys[i], mx += xs[i];
  my /= double(n);
  mx /= double(n);
  double syy = 0.0, sxy = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    syy += (ys[i] - my) * (ys[i] - my);
    sxy += (ys[i] - my) * (xs[i] - mx);
  }
  fit.b = syy > 0 ? sxy / syy : 0.0;
  fit.a = mx - fit.b * my;
  double ss = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    const double e = xs[i] - (fit.a + fit.b * ys[i]);
    ss += e * e;
  }
  fit.rms = std::sqrt(ss / double(n));
  return fit;
}

// The windowed LSF and its DFT (steps 4 and 5).
class LsfSpectrum {
 public:
  LsfSpectrum(const std::vector<double>& d, const std::vector<double>& lsf, const SlantedEdgeOptions& o) {
    const std::size_t m = lsf.size();
    // The window's centre: the LSF's centroid within ±2 px of its maximum (its positive part).
    const std::size_t peak = std::size_t(std::max_element(lsf.begin(), lsf.end()) - lsf.begin());
    const std::size_t reach = std::size_t(2 * kEsfOversampling);
    double s0 = 0.0, s1 = 0.0;
    for (std::size_t k = peak >= reach ? peak - reach : 0; k < std::min(m, peak + reach + 1); ++k) {
      const double v = std::max(0.0, lsf[k]);
      s0 += v;
      s1 += v * d[k];
    }
    centre_ = s0 > 0 ? s1 / s0 : d[peak];
    const double half = std::min(centre_ - d.front(), d.back() - centre_);
    const double flat = 1.0 - o.tukey_taper;
    weighted_.resize(m);
    offset_.resize(m);
    double sum = 0.0;
    for (std::size_t k = 0; k < m; ++k) {
      const double u = half > 0 ? std::abs(d[k] - centre_) / half : 1.0;
      double w = 0.0;
      if (u <= 1.0) {
        if (o.window == LsfWindow::kHamming) {
          w = 0.54 + 0.46 * std::cos(M_PI * u);
        } else {
          w = u <= flat ? 1.0 : 0.5 * (1.0 + std::cos(M_PI * (u - flat) / o.tukey_taper));
        }
      }
      weighted_[k] = lsf[k] * w;
      offset_[k] = d[k] - centre_;
      sum += weighted_[k];
    }
    dc_ = std::abs(sum);
  }

  double dc() const { return dc_; }

  // MTF(f), corrected for the central difference and the bin average (header, step 5).
  double operator()(double f) const {
    double re = 0.0, im = 0.0;
    for (std::size_t k = 0; k < weighted_.size(); ++k) {
      const double phase = -2.0 * M_PI * f * offset_[k];
      re += weighted_[k] * std::cos(phase);
      im += weighted_[k] * std::sin(phase);
    }
    return std::hypot(re, im) / dc_ / (EdgeSinc(2.0 * f * kEsfBin) * EdgeSinc(f * kEsfBin));
  }

 private:
  double centre_ = 0.0;
  double dc_ = 0.0;
  std::vector<double> weighted_;
  std::vector<double> offset_;
};

// Step 4's tail smoothing: beyond T = 2 h + 2 px from the ESF's 50 % point (h: the larger of its distances to the
// 5 % and 95 % points), each LSF bin becomes the mean of the bins within ±min(4, (|d − d50| − T)/2) px.
std::vector<double> SmoothLsfTails(const std::vector<double>& d, const std::vector<double>& esf, const std::vector<double>& lsf,
                                double low, double high) {
  const std::size_t m = esf.size();
  auto level = [&](double p) { return low + p * (high - low); };
  std::size_t k50 = 0;
  while (k50 + 1 < m && esf[k50] < level(0.5)) ++k50;
  std::size_t k05 = k50, k95 = k50;
  while (k05 > 0 && esf[k05] > level(0.05)) --k05;
  while (k95 + 1 < m && esf[k95] < level(0.95)) ++k95;
  const double d50 = d[k50];
  const double t = 2.0 * std::max(d50 - d[k05], d[k95] - d50) + 2.0;
  std::vector<double> prefix(m + 1, 0.0);
  for (std::size_t k = 0; k < m; ++k) prefix[k + 1] = prefix[k] + lsf[k];
  std::vector<double> out = lsf;
  for (std::size_t k = 0; k < m; ++k) {
    const double beyond = std::abs(d[k] - d50) - t;
    if (beyond <= 0) continue;
    const long h = long(std::floor(std::min(kLsfMaxTailSmoothingPx, 0.5 * beyond) / kEsfBin));
    const long lo = std::max(0L, long(k) - h), hi = std::min(long(m) - 1, long(k) + h);
    out[k] = (prefix[std::size_t(hi) + 1] - prefix[std::size_t(lo)]) / double(hi - lo + 1);
  }
  return out;
}

MtfCrossing FindMtfCrossing(const LsfSpectrum& mtf, double level) {
  MtfCrossing c;
  c.level = level;
  double f0 = 0.0;
  const int steps = int(std::floor(kMaxMtfFrequency / kMtfCrossingGrid + 1e-9));
  for (int i = 1; i <= steps; ++i) {
    const double f1 = i * kMtfCrossingGrid;
    const double m1 = mtf(f1);
    if (m1 <= level) {
      double lo = f0, hi = f1;  // MTF(lo) > level >= MTF(hi)
      while (hi - lo > 1e-7) {
        const double mid = 0.5 * (lo + hi);
        if (mtf(mid) > level) lo = mid; else hi = mid;
      }
      c.reached = true;
      c.frequency = 0.5 * (lo + hi);
      return c;
    }
    f0 = f1;
  }
  return c;
}

std::string EdgeRoiName(const PixelRoi& r) {
  return "the region x0 = " + std::to_string(r.x0) + ", y0 = " + std::to_string(r.y0) + ", " +
         std::to_string(r.width) + " x " + std::to_string(r.height) + " px (width x height)";
}

}  // namespace

bool SlantedEdgeOptions::IsValid(std::string* why) const {
  auto fail = [why](const std::string& m) {
    if (why) *why = m;
    return false;
  };
  if (roi.x0 < 0 || roi.y0 < 0 || roi.width < 0 || roi.height < 0)
    return fail("roi = (" + std::to_string(roi.x0) + ", " + std::to_string(roi.y0) + ", " + std::to_string(roi.width) +
                ", " + std::to_string(roi.height) + "): x0, y0, width, height must be >= 0");
  if (!(tukey_taper > 0.0 && tukey_taper <= 1.0)) return fail("tukey_taper = " + ToString(tukey_taper) + ": must be in (0, 1]");
  if (!(esf_half_width_px == 0.0 || (esf_half_width_px >= kEsfMinHalfWidthPx && esf_half_width_px <= 1e6)))
    return fail("esf_half_width_px = " + ToString(esf_half_width_px) + ": must be 0 (all the region gives) or in [5, 1e6]");
  if (min_edge_length_px < 8 || min_edge_length_px > 1000000)
    return fail("min_edge_length_px = " + std::to_string(min_edge_length_px) + ": must be in [8, 1e6]");
  if (!(max_angle_deg > 0.0 && max_angle_deg <= 45.0))
    return fail("max_angle_deg = " + ToString(max_angle_deg) + ": must be in (0, 45]");
  if (!(min_contrast_to_noise >= 0.0 && std::isfinite(min_contrast_to_noise)))
    return fail("min_contrast_to_noise = " + ToString(min_contrast_to_noise) + ": must be finite and >= 0");
  if (!(curve_max > 0.0 && curve_max <= kMaxMtfFrequency))
    return fail("curve_max = " + ToString(curve_max) + ": must be in (0, " + ToString(kMaxMtfFrequency) + "] cycles/px");
  if (!(curve_step > 0.0 && curve_step <= curve_max && curve_max / curve_step <= 1e6))
    return fail("curve_step = " + ToString(curve_step) + ": must be in (0, curve_max] with at most 1e6 steps");
  for (std::size_t i = 0; i < frequencies.size(); ++i)
    if (!(frequencies[i] >= 0.0 && frequencies[i] <= kMaxMtfFrequency))
      return fail("frequencies[" + std::to_string(i) + "] = " + ToString(frequencies[i]) + ": must be in [0, " +
                  ToString(kMaxMtfFrequency) + "] cycles/px");
  if (r < 0 || r > 64) return fail("r = " + std::to_string(r) + ": must be 0 (not given) or in [1, 64]");
  if (!(pixel_lambda_over_d == 0.0 || (pixel_lambda_over_d > 0.0 && pixel_lambda_over_d <= kMaxMtfFrequency)))
    return fail("pixel_lambda_over_d = " + ToString(pixel_lambda_over_d) + ": must be 0 (not given) or in (0, " +
                ToString(kMaxMtfFrequency) + "] (the cut-off D/lambda in cycles/px)");
  return true;
}

std::string SlantedEdgeMtf::BriefReport() const {
  auto f = [](const MtfCrossing& c) { return c.reached ? EdgeFixed(c.frequency, 4) + " cyc/px" : std::string("not reached"); };
  return "MTF50 " + f(mtf50) + ", MTF10 " + f(mtf10) + ", " + (vertical ? "near-vertical" : "near-horizontal") +
         " edge at " + EdgeFixed(angle_deg, 2) + " deg, contrast-to-noise " +
         (std::isfinite(contrast_to_noise) ? EdgeFixed(contrast_to_noise, 1) : std::string("inf"));
}

SlantedEdgeMtf MeasureSlantedEdgeMtf(const Image& image, const SlantedEdgeOptions& options) {
  std::string why;
  if (!options.IsValid(&why)) throw InvalidArgument(std::string(kSlantedEdgeFn) + ": invalid options: " + why);
  CheckArgument(image.size() > 0, kSlantedEdgeFn, "image", ToString(ShapeOf(image)), "a non-empty image");
  PixelRoi roi = options.roi;
  if (roi.width == 0) roi.width = image.cols() - roi.x0;
  if (roi.height == 0) roi.height = image.rows() - roi.y0;
  if (roi.x0 >= image.cols() || roi.y0 >= image.rows() || roi.width <= 0 || roi.height <= 0 ||
      roi.x0 + roi.width > image.cols() || roi.y0 + roi.height > image.rows())
    throw InvalidArgument(kSlantedEdgeFn, "roi",
                          "x0 = " + std::to_string(options.roi.x0) + ", y0 = " + std::to_string(options.roi.y0) +
                              ", width = " + std::to_string(options.roi.width) +
                              ", height = " + std::to_string(options.roi.height),
                          "a region inside the " + ToString(ShapeOf(image)) + " image (rows x cols)");
  const std::string where = EdgeRoiName(roi);
  const Image region = image.block(roi.y0, roi.x0, roi.height, roi.width);
  if (!AllFinite(region)) throw InvalidArgument(kSlantedEdgeFn, "image", "(NaN or Inf in " + where + ")", "finite pixels");
  const double vmax = region.maxCoeff(), vmin = region.minCoeff();
  if (!(vmax > vmin)) RefuseEdge(where, "no edge: the region is flat (every pixel is " + ToString(vmin) + ")");

  // 1. Orientation: the edge runs along the direction of the smaller summed differences.
  double sum_dx = 0.0, sum_dy = 0.0;
  for (Index y = 0; y < region.rows(); ++y)
    for (Index x = 0; x + 1 < region.cols(); ++x) sum_dx += std::abs(region(y, x + 1) - region(y, x));
  for (Index y = 0; y + 1 < region.rows(); ++y)
    for (Index x = 0; x < region.cols(); ++x) sum_dy += std::abs(region(y + 1, x) - region(y, x));
  SlantedEdgeMtf out;
  out.vertical = sum_dx >= sum_dy;
  const Image a = out.vertical ? region : Image(region.transpose());
  const Index rows = a.rows(), cols = a.cols();
  const char* along = out.vertical ? "rows" : "columns";
  const char* across = out.vertical ? "columns" : "rows";
  out.edge_length_px = rows;
  if (rows < options.min_edge_length_px)
    RefuseEdge(where, std::string("too short: the ") + (out.vertical ? "near-vertical" : "near-horizontal") + " edge spans " +
                      std::to_string(rows) + " " + along + ", fewer than min_edge_length_px = " +
                      std::to_string(options.min_edge_length_px) + "; use a longer region");
  if (cols < kEdgeMinAcrossPx)
    RefuseEdge(where, "too short across the edge: " + std::to_string(cols) + " " + across + ", fewer than " +
                      std::to_string(kEdgeMinAcrossPx));

  // Polarity and a first contrast: the outer quarters of the columns.
  const Index q = std::max<Index>(1, cols / 4);
  const double left = a.leftCols(q).mean(), right = a.rightCols(q).mean();
  const double polarity = right >= left ? 1.0 : -1.0;
  const double contrast0 = std::abs(right - left);
  if (!(contrast0 > 0.25 * (vmax - vmin)))
    RefuseEdge(where, "no edge: the outer quarters of the region differ by " + ToString(contrast0) + ", less than a quarter of its range " +
                      ToString(vmax - vmin) + ": a bar, a line or a spot, not one edge between two levels");

  // 2. The edge line, twice.
  EdgeLineFit fit = FitEdge(a, polarity, contrast0, 0.5 * double(cols - 1), 0.0);
  if (fit.bad_rows <= int(kEdgeBadRowFraction * double(rows))) {
    // The second pass fits the centred rows spanning a whole number of pixels of phase (step 3): a sharp edge's
    // centroids carry a bias periodic in the phase, which a whole number of periods leaves out of the slope.
    const double span = double(rows) * std::abs(fit.b) / std::sqrt(1.0 + fit.b * fit.b);
    Index first = 0, last = rows - 1;
    if (span >= 1.0) {
      const Index n = std::clamp<Index>(Index(std::floor(std::floor(span + 1e-9) / span * double(rows) + 1e-9)), 2, rows);
      first = (rows - n) / 2;
      last = first + n - 1;
    }
    fit = FitEdge(a, polarity, contrast0, fit.a, fit.b, first, last);
  }
  // The rows without an edge may be those where the edge has left the region: say so when the line through the
  // others (at least half the rows, the bad ones all at the ends) comes within kEsfMinHalfWidthPx of a side.
  const auto leaves = [&](const EdgeLineFit& f) {
    const double first = f.a, last = f.a + f.b * double(rows - 1);
    return std::min(std::min(first, last), double(cols - 1) - std::max(first, last)) / std::sqrt(1.0 + f.b * f.b);
  };
  auto refuse_leaving = [&](double margin) {
    RefuseEdge(where, "the edge leaves the region: in some " + std::string(along) + " it lies " + EdgeFixed(std::max(0.0, margin), 2) +
                      " px from the region's side (or beyond it), fewer than " + ToString(kEsfMinHalfWidthPx) +
                      " px; centre the region on the edge or widen it");
  };
  if (fit.bad_rows > int(kEdgeBadRowFraction * double(rows)) && 2 * fit.bad_rows <= rows && fit.inner_bad_rows == 0 &&
      leaves(fit) < kEsfMinHalfWidthPx)
    refuse_leaving(leaves(fit));
  if (fit.bad_rows > int(kEdgeBadRowFraction * double(rows)))
    RefuseEdge(where, "no edge: " + std::to_string(fit.bad_rows) + " of " + std::to_string(rows) + " " + along +
                      " hold no single rising edge (their windowed derivative sums to less than a quarter of the "
                      "contrast " + ToString(contrast0) + "); the region must hold one straight edge, not a bar or "
                      "a corner");
  const double b = fit.b;
  const double cos_t = 1.0 / std::sqrt(1.0 + b * b);
  out.angle_deg = std::atan(b) * 180.0 / M_PI;
  out.fit_rms_px = fit.rms;
  if (std::abs(out.angle_deg) > options.max_angle_deg)
    RefuseEdge(where, "too tilted: the edge is " + EdgeFixed(std::abs(out.angle_deg), 1) + " deg from the " +
                      (out.vertical ? "vertical" : "horizontal") + ", more than max_angle_deg = " +
                      ToString(options.max_angle_deg) + " (ISO 12233 edges are ~5 deg off an axis)");
  const double phase_span = double(rows) * std::abs(b) * cos_t;
  if (phase_span < 1.0)
    RefuseEdge(where, std::string("too close to ") + (out.vertical ? "vertical" : "horizontal") + ": the edge is at " +
                      EdgeFixed(out.angle_deg, 2) + " deg, so over its " + std::to_string(rows) + " " + along +
                      " it moves across by " + EdgeFixed(phase_span, 2) +
                      " px, less than one pixel, and the 4x oversampled ESF has empty phases; tilt it by at least " +
                      EdgeFixed(std::atan(1.0 / double(rows)) * 180.0 / M_PI, 2) + " deg (2-10 deg is usual) or use a longer region");

  // 3. The range every row covers, symmetric about the edge.
  const double xe_first = fit.a, xe_last = fit.a + b * double(rows - 1);
  const double xe_min = std::min(xe_first, xe_last), xe_max = std::max(xe_first, xe_last);
  double half = std::min(xe_min, double(cols - 1) - xe_max) * cos_t;
  if (half < kEsfMinHalfWidthPx) refuse_leaving(half);
  if (options.esf_half_width_px > 0) half = std::min(half, options.esf_half_width_px);
  const int kmax = int(std::floor(half / kEsfBin));
  const std::size_t m = std::size_t(2 * kmax + 1);

  // The rows binned: a whole number of phase cycles (the edge crosses a whole number of pixels over them, as
  // sfrmat4 trims), centred, so that every sub-pixel phase is sampled equally often and a bin's samples spread
  // evenly over it, which the bin-average correction of step 5 assumes. (On its own it changed a pixel-box edge's
  // curve by < 0.01; the bins' mean positions of step 5 did the rest.)
  const Index cycle_rows = Index(std::floor(std::floor(phase_span + 1e-9) / (std::abs(b) * cos_t) + 1e-9));
  const Index used_rows = std::clamp<Index>(cycle_rows, 1, rows);
  const Index y_begin = (rows - used_rows) / 2, y_end = y_begin + used_rows;
  out.rows_binned = used_rows;

  // Distances (+ toward the bright side), bins, and the clipping plateaus over the binned rows.
  const double range = vmax - vmin;
  const double tol = kEdgePlateauTolerance * range;
  std::vector<double> sum(m, 0.0), sum_d(m, 0.0);
  std::vector<int> count(m, 0);
  Index n_top = 0, n_bottom = 0, n_in = 0;
  double d_top = std::numeric_limits<double>::infinity(), d_bottom = std::numeric_limits<double>::infinity();
  for (Index y = y_begin; y < y_end; ++y) {
    const double xe = fit.a + b * double(y);
    for (Index x = 0; x < cols; ++x) {
      const double d = polarity * (double(x) - xe) * cos_t;
      const double v = a(y, x);
      const long k = std::lround(d / kEsfBin);
      if (k < -kmax || k > kmax) continue;
      ++n_in;
      if (v >= vmax - tol) ++n_top, d_top = std::min(d_top, std::abs(d));
      if (v <= vmin + tol) ++n_bottom, d_bottom = std::min(d_bottom, std::abs(d));
      sum[std::size_t(k + kmax)] += v;
      sum_d[std::size_t(k + kmax)] += d;
      ++count[std::size_t(k + kmax)];
    }
  }
  // Empty bins: isolated ones (or one at an end) interpolated, two in a row refused.
  std::vector<double> esf(m);
  for (std::size_t k = 0; k < m; ++k) esf[k] = count[k] > 0 ? sum[k] / count[k] : std::numeric_limits<double>::quiet_NaN();
  for (std::size_t k = 0; k < m; ++k) {
    if (count[k] > 0) continue;
    const bool lo = k > 0 && count[k - 1] > 0, hi = k + 1 < m && count[k + 1] > 0;
    if ((k == 0 && hi) || (k + 1 == m && lo) || (lo && hi)) {
      esf[k] = k == 0 ? esf[1] : k + 1 == m ? esf[m - 2] : 0.5 * (esf[k - 1] + esf[k + 1]);
      ++out.empty_bins;
      continue;
    }
    RefuseEdge(where, "too close to a critical angle: at " + EdgeFixed(out.angle_deg, 2) +
                      " deg the pixels' distances to the edge fall on a lattice and the 4x oversampled ESF has two "
                      "empty bins in a row near d = " + EdgeFixed((double(k) - kmax) * kEsfBin, 2) +
                      " px; change the angle slightly (2-10 deg off a small-integer ratio) or the region's length");
  }

  std::vector<double> dist(m);
  for (std::size_t k = 0; k < m; ++k) dist[k] = (double(k) - kmax) * kEsfBin;
  const std::size_t quarter = std::max<std::size_t>(1, m / 4);
  double lo_sum = 0.0, hi_sum = 0.0;
  for (std::size_t k = 0; k < quarter; ++k) lo_sum += esf[k], hi_sum += esf[m - 1 - k];
  out.low = lo_sum / double(quarter);
  out.high = hi_sum / double(quarter);
  const double contrast = out.high - out.low;
  if (!(contrast > 0.0)) RefuseEdge(where, "no edge: the ESF's outer quarters have the same level");
  // One edge steps from one level to the other; a bar or a line rises and falls back (its ESF spans far more
  // than the step between its ends). Ringing or overshoot of a sharpened edge stays well inside this.
  const double esf_range = *std::max_element(esf.begin(), esf.end()) - *std::min_element(esf.begin(), esf.end());
  if (contrast < 0.5 * esf_range)
    RefuseEdge(where, "no edge: the ESF spans " + ToString(esf_range) + " but steps by only " + ToString(contrast) +
                      " between its ends: the region holds a bar or a line, not one edge");
  const Index plateau_min = std::max<Index>(4, Index(std::ceil(kEdgePlateauFraction * double(n_in))));
  const bool top = n_top >= plateau_min, bottom = n_bottom >= plateau_min;
  // A plateau counts as clipping only where the edge is still rising: within twice the ESF's 10-90 % rise of
  // the edge (a frame blurred by a finite PSF window is exactly dark far from the edge, which is no clipping).
  std::size_t k50 = 0;
  while (k50 + 1 < m && esf[k50] < out.low + 0.5 * contrast) ++k50;
  std::size_t k10 = k50, k90 = k50;
  while (k10 > 0 && esf[k10] > out.low + 0.1 * contrast) --k10;
  while (k90 + 1 < m && esf[k90] < out.low + 0.9 * contrast) ++k90;
  const double rise = std::max(1.0, double(k90 - k10) * kEsfBin);
  auto clipped = [&](bool here, bool there, double d_here, double d_there) {
    return here && d_here < 2.0 * rise && (!there || d_here < 0.5 * d_there);
  };
  const bool clip_top = clipped(top, bottom, d_top, d_bottom), clip_bottom = clipped(bottom, top, d_bottom, d_top);
  if (clip_top || clip_bottom) {
    const bool t = clip_top;
    const Index n = t ? n_top : n_bottom;
    const double d_here = t ? d_top : d_bottom, d_there = t ? d_bottom : d_top;
    RefuseEdge(where, std::string("clipped (saturated) at its ") + (t ? "maximum " : "minimum ") + ToString(t ? vmax : vmin) +
                      ": " + std::to_string(n) + " pixels sit at that value from " + EdgeFixed(d_here, 2) +
                      " px of the edge on, while the " + (t ? "minimum" : "maximum") + "'s plateau " +
                      (std::isfinite(d_there) && (t ? bottom : top) ? "starts " + EdgeFixed(d_there, 2) + " px away"
                                                                      : "does not exist") +
                      "; a symmetric blur approaches both levels alike: lower the exposure or pick an unsaturated edge");
  }


  // Noise: the robust residual of the pixels about the ESF (linear between bin centres).
  std::vector<double> residual;
  residual.reserve(std::size_t(rows * cols));
  for (Index y = y_begin; y < y_end; ++y) {
    const double xe = fit.a + b * double(y);
    for (Index x = 0; x < cols; ++x) {
      const double t = polarity * (double(x) - xe) * cos_t / kEsfBin + kmax;
      if (t < 0.0 || t > double(m - 1)) continue;
      const std::size_t k = std::min(std::size_t(t), m - 2);
      const double w = t - double(k);
      residual.push_back(std::abs(a(y, x) - ((1.0 - w) * esf[k] + w * esf[k + 1])));
    }
  }
  auto mid = residual.begin() + std::ptrdiff_t(residual.size() / 2);
  std::nth_element(residual.begin(), mid, residual.end());
  // Below 1e-9 of the contrast the residual is the arithmetic's, not noise: a noise-free image.
  out.noise_rms = 1.4826 * *mid;
  if (out.noise_rms < kEdgeNoiseFloor * (out.high - out.low)) out.noise_rms = 0.0;
  out.contrast_to_noise = out.noise_rms > 0 ? contrast / out.noise_rms : std::numeric_limits<double>::infinity();
  if (out.contrast_to_noise < options.min_contrast_to_noise)
    RefuseEdge(where, "too noisy: contrast-to-noise " + EdgeFixed(out.contrast_to_noise, 1) + " (contrast " + ToString(contrast) +
                      ", noise RMS " + ToString(out.noise_rms) + "), below min_contrast_to_noise = " +
                      ToString(options.min_contrast_to_noise) + "; average more frames or use a higher-contrast edge");

  // 4. LSF.
  std::vector<double> lsf(m);
  for (std::size_t k = 1; k + 1 < m; ++k) lsf[k] = (esf[k + 1] - esf[k - 1]) / (2.0 * kEsfBin);
  lsf[0] = (esf[1] - esf[0]) / kEsfBin;
  lsf[m - 1] = (esf[m - 1] - esf[m - 2]) / kEsfBin;
  // The DFT's phases at each bin's mean sample distance rather than its centre (header, step 5).
  std::vector<double> where_k(m);
  for (std::size_t k = 0; k < m; ++k) where_k[k] = count[k] > 0 ? sum_d[k] / count[k] : dist[k];
  const LsfSpectrum spectrum(where_k, options.smooth_tails ? SmoothLsfTails(dist, esf, lsf, out.low, out.high) : lsf, options);
  if (!(spectrum.dc() > 0.0)) RefuseEdge(where, "no edge: the windowed LSF sums to zero");

  // 5. The curve and its figures.
  const int n = int(std::floor(options.curve_max / options.curve_step + 1e-9));
  for (int i = 0; i <= n; ++i) {
    const double f = i * options.curve_step;
    out.frequency.push_back(f);
    out.mtf.push_back(spectrum(f));
  }
  out.mtf50 = FindMtfCrossing(spectrum, 0.5);
  out.mtf10 = FindMtfCrossing(spectrum, 0.1);
  for (double f : options.frequencies) out.at.push_back({f, spectrum(f)});
  if (options.r > 0) {
    out.has_nyquist = true;
    out.nyquist = {0.5 / options.r, spectrum(0.5 / options.r)};
  }
  if (options.pixel_lambda_over_d > 0) {
    out.has_cutoff = true;
    out.cutoff = {options.pixel_lambda_over_d, spectrum(options.pixel_lambda_over_d)};
  }

  // The edge in image coordinates: the point of the line at the middle of the rows along it.
  const double along_mid = 0.5 * double(rows - 1), across_mid = fit.a + b * along_mid;
  out.centre_y = double(roi.y0) + (out.vertical ? along_mid : across_mid);
  out.centre_x = double(roi.x0) + (out.vertical ? across_mid : along_mid);
  out.esf_distance = std::move(dist);
  out.esf = std::move(esf);
  out.lsf = std::move(lsf);
  return out;
}

}  // namespace aosr
