#include "aosr/core/edge_search.hpp"

#include <algorithm>
#include <cmath>
#include <deque>

#include "aosr/core/error.hpp"

namespace aosr {

bool EdgeSearchOptions::IsValid(std::string* why) const {
  auto fail = [why](const std::string& m) {
    if (why) *why = m;
    return false;
  };
  if (!(threshold > 0 && threshold < 1)) return fail("threshold = " + ToString(threshold) + " (must be in (0, 1))");
  if (min_length_px < 8) return fail("min_length_px = " + std::to_string(min_length_px) + " (must be >= 8)");
  if (max_half_width_px < 6 || max_half_width_px > 1000)
    return fail("max_half_width_px = " + std::to_string(max_half_width_px) + " (must be in [6, 1000])");
  if (max_candidates < 1 || max_candidates > 1000)
    return fail("max_candidates = " + std::to_string(max_candidates) + " (must be in [1, 1000])");
  return true;
}

namespace {

// The measurement needs the edge >= 5 px from its region's sides (slanted_edge.hpp), and a level on each side.
constexpr Index kMinClearPx = 5;

// Edge pixels of an image, with x across the edges sought (those nearer the column direction): `across`
// holds +1 / −1 (the polarity: brighter toward +x / −x) where the Sobel gradient is mostly along x, strong
// and a maximum along the row; `along` marks the other orientation's edge pixels (maximum along the column),
// which bound the regions too.
struct EdgeMaps {
  Eigen::Array<signed char, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> across, along;
};

EdgeMaps FindEdgePixels(const Image& a, double threshold) {
  const Index rows = a.rows(), cols = a.cols();
  Image gx = Image::Zero(rows, cols), gy = Image::Zero(rows, cols);
  for (Index y = 1; y + 1 < rows; ++y)
    for (Index x = 1; x + 1 < cols; ++x) {
      gx(y, x) = (a(y - 1, x + 1) + 2 * a(y, x + 1) + a(y + 1, x + 1)) - (a(y - 1, x - 1) + 2 * a(y, x - 1) + a(y + 1, x - 1));
      gy(y, x) = (a(y + 1, x - 1) + 2 * a(y + 1, x) + a(y + 1, x + 1)) - (a(y - 1, x - 1) + 2 * a(y - 1, x) + a(y - 1, x + 1));
    }
  const Image mag = (gx.square() + gy.square()).sqrt();
  std::vector<double> m(mag.data(), mag.data() + mag.size());
  const std::size_t k = std::min(m.size() - 1, std::size_t(0.999 * double(m.size())));
  std::nth_element(m.begin(), m.begin() + std::ptrdiff_t(k), m.end());
  const double cut = threshold * m[k];
  EdgeMaps e;
  e.across.setZero(rows, cols);
  e.along.setZero(rows, cols);
  if (!(m[k] > 0)) return e;
  for (Index y = 1; y + 1 < rows; ++y)
    for (Index x = 1; x + 1 < cols; ++x) {
      const double v = mag(y, x);
      if (v < cut) continue;
      if (std::abs(gx(y, x)) >= std::abs(gy(y, x))) {
        if (v >= mag(y, x - 1) && v > mag(y, x + 1)) e.across(y, x) = gx(y, x) > 0 ? 1 : -1;
      } else if (v >= mag(y - 1, x) && v > mag(y + 1, x)) {
        e.along(y, x) = 1;
      }
    }
  return e;
}

// The candidates of the edges nearer the column direction of `a` (step 2-3 of the header), in a's coordinates.
std::vector<EdgeCandidate> SearchAcross(const Image& a, const EdgeSearchOptions& o) {
  const Index rows = a.rows(), cols = a.cols();
  const EdgeMaps e = FindEdgePixels(a, o.threshold);
  Eigen::Array<int, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> chain(rows, cols);
  chain.setConstant(-1);
  std::vector<EdgeCandidate> out;
  int id = 0;
  for (Index sy = 0; sy < rows; ++sy)
    for (Index sx = 0; sx < cols; ++sx) {
      if (e.across(sy, sx) == 0 || chain(sy, sx) >= 0) continue;
      // One chain: the 8-connected edge pixels of this polarity.
      const signed char polarity = e.across(sy, sx);
      std::vector<std::pair<Index, Index>> pts;
      std::deque<std::pair<Index, Index>> queue{{sy, sx}};
      chain(sy, sx) = id;
      while (!queue.empty()) {
        const auto [y, x] = queue.front();
        queue.pop_front();
        pts.emplace_back(y, x);
        for (Index dy = -1; dy <= 1; ++dy)
          for (Index dx = -1; dx <= 1; ++dx) {
            const Index ny = y + dy, nx = x + dx;
            if (ny < 0 || nx < 0 || ny >= rows || nx >= cols || e.across(ny, nx) != polarity || chain(ny, nx) >= 0) continue;
            chain(ny, nx) = id;
            queue.emplace_back(ny, nx);
          }
      }
      const int this_chain = id++;
      Index y_min = rows, y_max = -1;
      for (const auto& p : pts) {
        y_min = std::min(y_min, p.first);
        y_max = std::max(y_max, p.first);
      }
      const Index span = y_max - y_min + 1;
      if (span < o.min_length_px || double(pts.size()) > 1.5 * double(span)) continue;
      // x = c + b y by least squares.
      double sy_ = 0, sx_ = 0, syy = 0, sxy = 0;
      for (const auto& p : pts) {
        sy_ += double(p.first);
        sx_ += double(p.second);
        syy += double(p.first) * double(p.first);
        sxy += double(p.first) * double(p.second);
      }
      const double n = double(pts.size());
      const double den = n * syy - sy_ * sy_;
      if (!(den > 0)) continue;
      const double b = (n * sxy - sy_ * sx_) / den, c = (sx_ - b * sy_) / n;
      double ss = 0;
      for (const auto& p : pts) ss += std::pow(double(p.second) - c - b * double(p.first), 2);
      const double rms = std::sqrt(ss / n);
      if (rms > 0.75) continue;
      // Rows less a tenth at each end (a bar's corners). Across: per row, where the nearest other edge pixel lies
      // on each side (the other edges of a chart's bars, any orientation).
      const Index trim = std::max<Index>(2, span / 10);
      const Index ya = y_min + trim, yb = y_max - trim;
      if (yb - ya + 1 < 8) continue;
      const Index reach = o.max_half_width_px + Index(std::ceil(std::abs(b) * double(span))) + 4;
      std::vector<double> left(std::size_t(yb - ya + 1)), right(left.size());  // x of the nearest other edge pixel
      for (Index y = ya; y <= yb; ++y) {
        const Index xi = Index(std::lround(c + b * double(y)));
        for (int side : {-1, 1}) {
          Index d = 1;
          for (; d <= reach; ++d) {
            const Index x = xi + side * d;
            if (x < 0 || x >= cols) break;
            if ((e.across(y, x) != 0 && chain(y, x) != this_chain) || e.along(y, x) != 0) break;
          }
          (side < 0 ? left : right)[std::size_t(y - ya)] = double(xi + side * d);
        }
      }
      // The region is a rectangle, so over R rows the slanted edge sweeps R |b| px inside it and the rows at one
      // end bring the neighbouring edges closer to its sides. Half-width for rows y0..y1: the room between the
      // rectangle's sides and the nearest other edge pixel in any of its rows, 2 px short of it (its blur).
      auto half_width = [&](Index y0, Index y1, double* lo, double* hi) {
        double xl = 1e300, xh = -1e300, other_l = -1e300, other_r = 1e300;
        for (Index y = y0; y <= y1; ++y) {
          const double xe = c + b * double(y);
          xl = std::min(xl, xe);
          xh = std::max(xh, xe);
          other_l = std::max(other_l, left[std::size_t(y - ya)]);
          other_r = std::min(other_r, right[std::size_t(y - ya)]);
        }
        *lo = xl;
        *hi = xh;
        return std::min<Index>({Index(std::floor(xl - other_l)) - 3, Index(std::floor(other_r - xh)) - 3,
                                Index(o.max_half_width_px)});
      };
      // The most rows (centred on the chain) that keep 8 px clear, else 5 (the measurement's least), down to 20
      // rows or the rows one pixel of phase needs, whichever is more.
      const Index all_rows = yb - ya + 1;
      const Index fewest = std::min(all_rows, std::max<Index>(20, Index(std::ceil(1.0 / std::max(std::abs(b), 1e-6)))));
      Index hw = -1, y0 = ya, y1 = yb;
      double x_lo = 0, x_hi = 0;
      for (const Index want : {Index(8), kMinClearPx}) {
        for (Index rows_used = all_rows; rows_used >= fewest && hw < want; rows_used -= std::max<Index>(1, rows_used / 10)) {
          const Index s0 = ya + (all_rows - rows_used) / 2, s1 = s0 + rows_used - 1;
          double lo = 0, hi = 0;
          const Index h = half_width(s0, s1, &lo, &hi);
          if (h >= want) {
            hw = h;
            y0 = s0;
            y1 = s1;
            x_lo = lo;
            x_hi = hi;
          }
        }
        if (hw >= want) break;
      }
      if (hw < 0) hw = std::max<Index>(half_width(ya, yb, &x_lo, &x_hi), 0);  // listed, too crowded to measure
      EdgeCandidate cand;
      cand.clear_px = hw;
      hw = std::max<Index>(hw, 1);
      const Index c0 = std::max<Index>(0, Index(std::floor(x_lo)) - hw);
      const Index c1 = std::min<Index>(cols - 1, Index(std::ceil(x_hi)) + hw);
      cand.roi = {c0, y0, c1 - c0 + 1, y1 - y0 + 1};
      cand.vertical = true;
      cand.angle_deg = std::atan(b) * 180.0 / M_PI;
      cand.length_px = span;
      cand.fit_rms_px = rms;
      double diff = 0;
      for (Index y = y0; y <= y1; ++y) {
        const double xe = c + b * double(y);
        const Index xr = std::clamp<Index>(Index(std::lround(xe + 0.5 * double(hw))), 0, cols - 1);
        const Index xl = std::clamp<Index>(Index(std::lround(xe - 0.5 * double(hw))), 0, cols - 1);
        diff += a(y, xr) - a(y, xl);
      }
      cand.contrast = std::abs(diff) / double(y1 - y0 + 1);
      out.push_back(cand);
    }
  return out;
}

std::string Describe(const EdgeCandidate& c) {
  char buf[200];
  std::snprintf(buf, sizeof buf, "%s edge at %+.2f deg, %lld px long, region x %lld..%lld, y %lld..%lld",
                c.vertical ? "vertical" : "horizontal", c.angle_deg, (long long)c.length_px, (long long)c.roi.x0,
                (long long)(c.roi.x0 + c.roi.width - 1), (long long)c.roi.y0, (long long)(c.roi.y0 + c.roi.height - 1));
  return buf;
}

}  // namespace

std::vector<EdgeCandidate> FindStraightEdges(const Image& image, const EdgeSearchOptions& options) {
  const char* fn = "FindStraightEdges";
  std::string why;
  if (!options.IsValid(&why)) throw InvalidArgument(std::string(fn) + ": options." + why);
  CheckArgument(image.rows() >= 3 && image.cols() >= 3, fn, "image", ToString(ShapeOf(image)), "at least 3 x 3 pixels");
  CheckArgument(AllFinite(image), fn, "image", "non-finite pixels", "finite pixels");
  std::vector<EdgeCandidate> all = SearchAcross(image, options);
  const Image t = image.transpose();
  for (EdgeCandidate c : SearchAcross(t, options)) {
    c.vertical = false;
    c.roi = {c.roi.y0, c.roi.x0, c.roi.height, c.roi.width};
    all.push_back(c);
  }
  // Those with room for the measurement first, then the longest.
  std::stable_sort(all.begin(), all.end(), [](const EdgeCandidate& p, const EdgeCandidate& q) {
    const bool rp = p.clear_px >= kMinClearPx, rq = q.clear_px >= kMinClearPx;
    if (rp != rq) return rp;
    return p.length_px != q.length_px ? p.length_px > q.length_px : p.contrast > q.contrast;
  });
  if (int(all.size()) > options.max_candidates) all.resize(std::size_t(options.max_candidates));
  return all;
}

AutoEdgeMtf MeasureSlantedEdgeMtfAuto(const Image& image, const SlantedEdgeOptions& options,
                                      const EdgeSearchOptions& search) {
  const char* fn = "MeasureSlantedEdgeMtfAuto";
  SlantedEdgeOptions o = options;
  o.roi = PixelRoi{};
  std::string why;
  if (!o.IsValid(&why)) throw InvalidArgument(std::string(fn) + ": options." + why);
  if (!search.IsValid(&why)) throw InvalidArgument(std::string(fn) + ": search." + why);
  AutoEdgeMtf out;
  std::string whole;
  try {
    out.mtf = MeasureSlantedEdgeMtf(image, o);
    out.whole_image = true;
    out.roi = {0, 0, image.cols(), image.rows()};
    return out;
  } catch (const InvalidArgument& e) {
    whole = e.what();
  }
  out.candidates = FindStraightEdges(image, search);
  for (std::size_t k = 0; k < out.candidates.size(); ++k) {
    if (out.candidates[k].clear_px < kMinClearPx) {
      out.refused.push_back(Describe(out.candidates[k]) + ": only " + std::to_string(out.candidates[k].clear_px) +
                            " px clear of the next edge across it (" + std::to_string(kMinClearPx) +
                            " needed on each side)");
      continue;
    }
    o.roi = out.candidates[k].roi;
    try {
      out.mtf = MeasureSlantedEdgeMtf(image, o);
      out.roi = o.roi;
      out.candidate = int(k);
      return out;
    } catch (const InvalidArgument& e) {
      out.refused.push_back(Describe(out.candidates[k]) + ": " + e.what());
    }
  }
  // Nothing measured: say what was found.
  int near_axis = 0, crowded = 0;
  Index widest = 0;
  for (const EdgeCandidate& c : out.candidates) {
    near_axis += std::abs(c.angle_deg) < 1.0;
    crowded += c.clear_px < kMinClearPx;
    widest = std::max(widest, c.clear_px);
  }
  std::string m = std::string(fn) + ": no measurable edge in the " + ToString(ShapeOf(image)) + " image. The whole image: " +
                  whole.substr(0, 240) + ". ";
  if (out.candidates.empty()) {
    m += "No straight edge of at least " + std::to_string(search.min_length_px) + " px was found.";
  } else {
    m += std::to_string(out.candidates.size()) + " straight edge(s) found";
    if (near_axis > 0)
      m += ", " + std::to_string(near_axis) + " of them within 1 deg of an axis, which a slanted-edge MTF cannot read "
           "(the edge must cross at least a pixel of phase along its length: tilt the target by 2-10 deg, e.g. a "
           "scene's usaf object with rotation_deg 5, or a slanted-edge object)";
    if (crowded > 0)
      m += ", " + std::to_string(crowded) + " of them with less than " + std::to_string(kMinClearPx) +
           " px clear of the next edge on a side (at most " + std::to_string(widest) +
           " px: bars this narrow at this sampling leave no level on either side to read; enlarge the chart, e.g. its "
           "fill or first_group, or use a slanted-edge object)";
    m += ". The first tried: " + out.refused.front().substr(0, 400);
  }
  throw InvalidArgument(m);
}

}  // namespace aosr
