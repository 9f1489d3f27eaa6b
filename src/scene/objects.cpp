#include "aosr/scene/objects.hpp"

#include <algorithm>
#include <cmath>
#include <utility>
#include <vector>

#include "aosr/core/error.hpp"

namespace aosr {
namespace {

constexpr int kMinGroup = -10;
constexpr int kMaxGroup = 12;
constexpr int kElementsPerGroup = 6;
constexpr int kMaxSupersample = 64;
constexpr Index kDemoMinSide = 64;

// Layout constants, in units of the relevant bar width w (see objects.hpp).
constexpr double kBarLength = 5.0;          // bar length; also the side of a 3-bar triplet
constexpr double kTripletGap = 2.0;         // between the vertical and the horizontal triplet
constexpr double kElementWidth = 12.0;      // 5 + 2 + 5
constexpr double kElementGap = 2.0;         // below each element, in its own w
constexpr double kColumnGap = 3.0;          // after each group's column, in the column's w(g, 1)

void CheckGroupRange(const std::string& function, int first_group, int last_group) {
  CheckArgument(first_group >= kMinGroup && first_group <= kMaxGroup, function, "first_group", first_group,
                "[" + std::to_string(kMinGroup) + ", " + std::to_string(kMaxGroup) + "]");
  CheckArgument(last_group >= kMinGroup && last_group <= kMaxGroup, function, "last_group", last_group,
                "[" + std::to_string(kMinGroup) + ", " + std::to_string(kMaxGroup) + "]");
  CheckArgument(last_group >= first_group, function, "last_group", last_group,
                ">= first_group = " + std::to_string(first_group));
}

void CheckOptions(const std::string& function, const UsafOptions& options) {
  CheckGroupRange(function, options.first_group, options.last_group);
  std::string why;
  if (!options.IsValid(&why)) throw InvalidArgument(function + ": invalid options: " + why);
}

void CheckShape(const std::string& function, Shape shape, Index min_side) {
  CheckArgument(shape.rows >= min_side && shape.cols >= min_side, function, "shape", ToString(shape),
                "rows and cols >= " + std::to_string(min_side));
}

// An element's box in target mm, before placement.
struct ElementMm {
  int group;
  int element;
  double top;
  double left;
  double w;  // bar width, mm
};

// The layout of objects.hpp in target mm: every element's top-left corner and bar width, plus the
// bounding box and each column's extent.
struct LayoutMm {
  std::vector<ElementMm> elements;
  std::vector<double> column_left;    // per group, first..last
  std::vector<double> column_height;  // per group
  double width = 0.0;
  double height = 0.0;
};

LayoutMm MakeLayout(int first_group, int last_group) {
  LayoutMm layout;
  double left = 0.0;
  for (int g = first_group; g <= last_group; ++g) {
    const double w1 = UsafBarWidthMm(g, 1);
    double top = 0.0;
    for (int e = 1; e <= kElementsPerGroup; ++e) {
      const double w = UsafBarWidthMm(g, e);
      layout.elements.push_back({g, e, top, left, w});
      top += kBarLength * w;
      if (e < kElementsPerGroup) top += kElementGap * w;
    }
    layout.column_left.push_back(left);
    layout.column_height.push_back(top);
    layout.height = std::max(layout.height, top);
    layout.width = left + kElementWidth * w1;
    left += (kElementWidth + kColumnGap) * w1;
  }
  return layout;
}

// Maps target mm to HR pixels: the bounding box centred on the field centre, scaled by pixels_per_mm.
struct Placement {
  double top0;
  double left0;
  double scale;
  double Y(double y_mm) const { return top0 + y_mm * scale; }
  double X(double x_mm) const { return left0 + x_mm * scale; }
  PixelRect Rect(double top_mm, double left_mm, double height_mm, double width_mm) const {
    return {Y(top_mm), X(left_mm), height_mm * scale, width_mm * scale};
  }
};

Placement MakePlacement(Shape shape, const LayoutMm& layout, double pixels_per_mm) {
  return {0.5 * (shape.rows - 1) - 0.5 * layout.height * pixels_per_mm,
          0.5 * (shape.cols - 1) - 0.5 * layout.width * pixels_per_mm, pixels_per_mm};
}

// The six bars of one element (objects.hpp layout), in HR pixels.
void AppendBars(const ElementMm& el, const Placement& p, std::vector<UsafBar>* bars) {
  const double w = el.w;
  for (int k = 0; k < 3; ++k) {  // vertical bars: w wide, 5w tall, at x = 0, 2w, 4w
    bars->push_back({el.group, el.element, false, p.Rect(el.top, el.left + 2 * k * w, kBarLength * w, w)});
  }
  const double right_left = el.left + (kBarLength + kTripletGap) * w;
  for (int k = 0; k < 3; ++k) {  // horizontal bars: 5w wide, w tall, at y = 0, 2w, 4w
    bars->push_back({el.group, el.element, true, p.Rect(el.top + 2 * k * w, right_left, w, kBarLength * w)});
  }
}

// Coverage of pixel i (covering [i - 1/2, i + 1/2)) by the interval [a, b): the exact overlap length, or,
// for s >= 1, the fraction of the s sub-pixel centres i - 1/2 + (k + 1/2)/s that fall inside.
double Coverage1D(double a, double b, Index i, int supersample) {
  const double lo = i - 0.5, hi = i + 0.5;
  if (supersample == 0) return std::max(0.0, std::min(b, hi) - std::max(a, lo));
  int inside = 0;
  for (int k = 0; k < supersample; ++k) {
    const double t = lo + (k + 0.5) / supersample;
    if (t >= a && t < b) ++inside;
  }
  return static_cast<double>(inside) / supersample;
}

// Adds amplitude x coverage of `rect` to *image (clipped to the grid).
void RenderRect(const PixelRect& rect, double amplitude, int supersample, Image* image) {
  const Index rows = image->rows(), cols = image->cols();
  // Pixels whose footprint [i - 1/2, i + 1/2) can meet [a, b): floor(a + 1/2) .. floor(b + 1/2).
  const auto first = [](double a) { return static_cast<Index>(std::floor(a + 0.5)); };
  const Index y0 = std::max<Index>(0, first(rect.top)), y1 = std::min<Index>(rows - 1, first(rect.bottom()));
  const Index x0 = std::max<Index>(0, first(rect.left)), x1 = std::min<Index>(cols - 1, first(rect.right()));
  if (y0 > y1 || x0 > x1) return;
  Vector cx(x1 - x0 + 1);
  for (Index x = x0; x <= x1; ++x) cx(x - x0) = Coverage1D(rect.left, rect.right(), x, supersample);
  for (Index y = y0; y <= y1; ++y) {
    const double cy = Coverage1D(rect.top, rect.bottom(), y, supersample);
    if (cy == 0.0) continue;
    image->row(y).segment(x0, cx.size()) += (amplitude * cy) * cx.transpose().array();
  }
}

// A convex polygon ((x, y) vertices in order) clipped to x (axis 0) or y (axis 1) <= bound (keep_below) or
// >= bound: one Sutherland-Hodgman step.
using Polygon = std::vector<std::pair<double, double>>;
Polygon ClipPolygon(const Polygon& in, int axis, double bound, bool keep_below) {
  Polygon out;
  const std::size_t n = in.size();
  auto inside = [&](const std::pair<double, double>& p) {
    const double v = axis == 0 ? p.first : p.second;
    return keep_below ? v <= bound : v >= bound;
  };
  for (std::size_t i = 0; i < n; ++i) {
    const auto& a = in[i];
    const auto& b = in[(i + 1) % n];
    const bool ia = inside(a), ib = inside(b);
    if (ia) out.push_back(a);
    if (ia != ib) {
      const double va = axis == 0 ? a.first : a.second, vb = axis == 0 ? b.first : b.second;
      const double t = (bound - va) / (vb - va);
      out.emplace_back(a.first + t * (b.first - a.first), a.second + t * (b.second - a.second));
    }
  }
  return out;
}

double PolygonArea(const Polygon& p) {
  double a = 0;
  for (std::size_t i = 0; i < p.size(); ++i) {
    const auto& u = p[i];
    const auto& v = p[(i + 1) % p.size()];
    a += u.first * v.second - v.first * u.second;
  }
  return 0.5 * std::abs(a);
}

// A rectangle turned by `angle` [rad] about (cy, cx), added with its exact area coverage of every pixel
// footprint [i − 1/2, i + 1/2) (the turned rectangle clipped to the pixel's square).
void RenderTurnedRect(const PixelRect& rect, double angle, double cy, double cx, double amplitude, Image* image) {
  const double c = std::cos(angle), s = std::sin(angle);
  Polygon quad;
  for (const auto& [y, x] : {std::pair{rect.top, rect.left}, std::pair{rect.top, rect.right()},
                             std::pair{rect.bottom(), rect.right()}, std::pair{rect.bottom(), rect.left}})
    quad.emplace_back(cx + (x - cx) * c - (y - cy) * s, cy + (x - cx) * s + (y - cy) * c);
  double x_lo = 1e300, x_hi = -1e300, y_lo = 1e300, y_hi = -1e300;
  for (const auto& [x, y] : quad) {
    x_lo = std::min(x_lo, x);
    x_hi = std::max(x_hi, x);
    y_lo = std::min(y_lo, y);
    y_hi = std::max(y_hi, y);
  }
  const Index rows = image->rows(), cols = image->cols();
  const Index y0 = std::max<Index>(0, Index(std::floor(y_lo + 0.5))), y1 = std::min<Index>(rows - 1, Index(std::floor(y_hi + 0.5)));
  const Index x0 = std::max<Index>(0, Index(std::floor(x_lo + 0.5))), x1 = std::min<Index>(cols - 1, Index(std::floor(x_hi + 0.5)));
  for (Index y = y0; y <= y1; ++y)
    for (Index x = x0; x <= x1; ++x) {
      Polygon p = ClipPolygon(quad, 0, double(x) - 0.5, false);
      p = ClipPolygon(p, 0, double(x) + 0.5, true);
      p = ClipPolygon(p, 1, double(y) - 0.5, false);
      p = ClipPolygon(p, 1, double(y) + 0.5, true);
      if (p.size() >= 3) (*image)(y, x) += amplitude * PolygonArea(p);
    }
}

// Interpolation weights along one axis: the two pixel indices around coordinate t in [0, n-1] and the
// weight of the upper one. At t = n - 1 the pair is (n-2, n-1) with weight 1, so both indices stay in range.
struct Bilinear1D {
  Index lo;
  Index hi;
  double frac;  // weight of hi; lo gets 1 - frac
};
Bilinear1D Split(double t, Index n) {
  if (n == 1) return {0, 0, 0.0};
  const Index lo = std::min<Index>(static_cast<Index>(std::floor(t)), n - 2);
  return {lo, lo + 1, t - static_cast<double>(lo)};
}

}  // namespace

double UsafFrequency(int group, int element) {
  CheckArgument(group >= kMinGroup && group <= kMaxGroup, "UsafFrequency", "group", group,
                "[" + std::to_string(kMinGroup) + ", " + std::to_string(kMaxGroup) + "]");
  CheckArgument(element >= 1 && element <= kElementsPerGroup, "UsafFrequency", "element", element, "1..6");
  return std::pow(2.0, group + (element - 1) / 6.0);
}

double UsafBarWidthMm(int group, int element) { return 0.5 / UsafFrequency(group, element); }

bool UsafOptions::IsValid(std::string* why) const {
  auto fail = [why](const std::string& message) {
    if (why != nullptr) *why = message;
    return false;
  };
  if (first_group < kMinGroup || first_group > kMaxGroup)
    return fail("first_group = " + std::to_string(first_group) + " (must be in [-10, 12])");
  if (last_group < kMinGroup || last_group > kMaxGroup)
    return fail("last_group = " + std::to_string(last_group) + " (must be in [-10, 12])");
  if (last_group < first_group)
    return fail("last_group = " + std::to_string(last_group) + " (must be >= first_group = " +
                std::to_string(first_group) + ")");
  if (!std::isfinite(pixels_per_mm) || pixels_per_mm <= 0.0)
    return fail("pixels_per_mm = " + ToString(pixels_per_mm) + " (must be finite and > 0)");
  if (!std::isfinite(background)) return fail("background = " + ToString(background) + " (must be finite)");
  if (!std::isfinite(bar_value)) return fail("bar_value = " + ToString(bar_value) + " (must be finite)");
  if (supersample < 0 || supersample > kMaxSupersample)
    return fail("supersample = " + std::to_string(supersample) + " (must be in [0, 64])");
  if (!(rotation_deg >= -45.0 && rotation_deg <= 45.0))
    return fail("rotation_deg = " + ToString(rotation_deg) + " (must be in [-45, 45])");
  if (rotation_deg != 0.0 && supersample != 0)
    return fail("supersample = " + std::to_string(supersample) + " with rotation_deg " + ToString(rotation_deg) +
                " (a turned chart is rendered with exact coverage: supersample 0)");
  return true;
}

UsafSize UsafTargetSize(const UsafOptions& options) {
  CheckOptions("UsafTargetSize", options);
  const LayoutMm layout = MakeLayout(options.first_group, options.last_group);
  return {layout.height, layout.width};
}

std::vector<UsafBar> UsafBars(Shape shape, const UsafOptions& options) {
  CheckShape("UsafBars", shape, 1);
  CheckOptions("UsafBars", options);
  const LayoutMm layout = MakeLayout(options.first_group, options.last_group);
  const Placement p = MakePlacement(shape, layout, options.pixels_per_mm);
  std::vector<UsafBar> bars;
  bars.reserve(6 * layout.elements.size());
  for (const ElementMm& el : layout.elements) AppendBars(el, p, &bars);
  return bars;
}

std::vector<UsafElement> UsafElements(Shape shape, const UsafOptions& options) {
  CheckShape("UsafElements", shape, 1);
  CheckOptions("UsafElements", options);
  const LayoutMm layout = MakeLayout(options.first_group, options.last_group);
  const Placement p = MakePlacement(shape, layout, options.pixels_per_mm);
  std::vector<UsafElement> elements;
  for (const ElementMm& el : layout.elements) {
    elements.push_back({el.group, el.element, UsafFrequency(el.group, el.element), el.w * p.scale,
                        p.Rect(el.top, el.left, kBarLength * el.w, kElementWidth * el.w)});
  }
  return elements;
}

Image UsafTarget(Shape shape, const UsafOptions& options) {
  CheckShape("UsafTarget", shape, 1);
  CheckOptions("UsafTarget", options);
  Image image = Image::Constant(shape.rows, shape.cols, options.background);
  const double amplitude = options.bar_value - options.background;
  const double cy = 0.5 * double(shape.rows - 1), cx = 0.5 * double(shape.cols - 1);
  for (const UsafBar& bar : UsafBars(shape, options)) {
    if (options.rotation_deg == 0.0) {
      RenderRect(bar.rect, amplitude, options.supersample, &image);
    } else {
      RenderTurnedRect(bar.rect, options.rotation_deg * M_PI / 180.0, cy, cx, amplitude, &image);
    }
  }
  return image;
}

void AddPointSources(Image* image, const std::vector<PointSource>& sources) {
  CheckArgument(image != nullptr, "AddPointSources", "image", "nullptr", "a valid Image*");
  CheckArgument(image->size() > 0, "AddPointSources", "image", ToString(ShapeOf(*image)), "a non-empty image");
  const Index rows = image->rows(), cols = image->cols();
  // Validate everything first: a bad source must not leave the image half-modified.
  for (size_t i = 0; i < sources.size(); ++i) {
    const PointSource& s = sources[i];
    const std::string name = "sources[" + std::to_string(i) + "]";
    CheckArgument(std::isfinite(s.flux), "AddPointSources", name + ".flux", s.flux, "a finite value");
    CheckArgument(std::isfinite(s.y) && s.y >= 0.0 && s.y <= rows - 1, "AddPointSources", name + ".y", s.y,
                  "[0, rows - 1] = [0, " + std::to_string(rows - 1) + "] (all four neighbours on the grid)");
    CheckArgument(std::isfinite(s.x) && s.x >= 0.0 && s.x <= cols - 1, "AddPointSources", name + ".x", s.x,
                  "[0, cols - 1] = [0, " + std::to_string(cols - 1) + "] (all four neighbours on the grid)");
  }
  for (const PointSource& s : sources) {
    const Bilinear1D by = Split(s.y, rows), bx = Split(s.x, cols);
    (*image)(by.lo, bx.lo) += (1.0 - by.frac) * (1.0 - bx.frac) * s.flux;
    (*image)(by.lo, bx.hi) += (1.0 - by.frac) * bx.frac * s.flux;
    (*image)(by.hi, bx.lo) += by.frac * (1.0 - bx.frac) * s.flux;
    (*image)(by.hi, bx.hi) += by.frac * bx.frac * s.flux;
  }
}

bool SlantedEdgeTargetOptions::IsValid(std::string* why) const {
  auto fail = [why](const std::string& message) {
    if (why != nullptr) *why = message;
    return false;
  };
  if (!(angle_deg >= -180.0 && angle_deg <= 180.0))
    return fail("angle_deg = " + ToString(angle_deg) + " (must be in [-180, 180])");
  if (std::isinf(centre_y) || std::isinf(centre_x))
    return fail("centre = (" + ToString(centre_y) + ", " + ToString(centre_x) + ") (must be finite, or NaN for the field centre)");
  if (!std::isfinite(low)) return fail("low = " + ToString(low) + " (must be finite)");
  if (!std::isfinite(high)) return fail("high = " + ToString(high) + " (must be finite)");
  return true;
}

Image SlantedEdgeTarget(Shape shape, const SlantedEdgeTargetOptions& options) {
  CheckShape("SlantedEdgeTarget", shape, 1);
  std::string why;
  if (!options.IsValid(&why)) throw InvalidArgument("SlantedEdgeTarget: invalid options: " + why);
  const double theta = options.angle_deg * M_PI / 180.0;
  const double nx = std::cos(theta), ny = -std::sin(theta);
  const double cy = std::isnan(options.centre_y) ? 0.5 * double(shape.rows - 1) : options.centre_y;
  const double cx = std::isnan(options.centre_x) ? 0.5 * double(shape.cols - 1) : options.centre_x;
  // The signed distance over the pixel is s + t, t = nx u + ny v: the sum of two uniforms of widths p >= q.
  const double p = std::max(std::abs(nx), std::abs(ny)), q = std::min(std::abs(nx), std::abs(ny));
  const double h = 0.5 * (p - q), k = 0.5 * (p + q);
  // F(t) = P(nx u + ny v <= t): 0 below -k, (t + k)²/(2pq) up to -h, (t + p/2)/p across the flat middle, then
  // the mirror image up to k.
  auto cdf = [&](double t) {
    if (t <= -k) return 0.0;
    if (t >= k) return 1.0;
    if (t <= -h) return (t + k) * (t + k) / (2.0 * p * q);
    if (t >= h) return 1.0 - (k - t) * (k - t) / (2.0 * p * q);
    return (t + 0.5 * p) / p;
  };
  Image image(shape.rows, shape.cols);
  for (Index y = 0; y < shape.rows; ++y)
    for (Index x = 0; x < shape.cols; ++x) {
      const double s = nx * (double(x) - cx) + ny * (double(y) - cy);
      const double covered = 1.0 - cdf(-s);  // area fraction where s + t > 0
      image(y, x) = options.low + (options.high - options.low) * covered;
    }
  return image;
}

UsafOptions DemoUsafOptions(Shape shape) {
  CheckShape("DemoUsafOptions", shape, kDemoMinSide);
  UsafOptions options;
  options.first_group = -2;
  options.last_group = 1;
  options.background = 0.05;
  options.bar_value = 1.0;
  const LayoutMm layout = MakeLayout(options.first_group, options.last_group);
  options.pixels_per_mm = 0.9 * std::min(shape.rows / layout.height, shape.cols / layout.width);
  return options;
}

PixelRect DemoFinestBars(Shape shape) {
  const UsafOptions options = DemoUsafOptions(shape);
  double top = 1e300, left = 1e300, bottom = -1e300, right = -1e300;
  for (const UsafElement& e : UsafElements(shape, options)) {
    if (e.group < 0) continue;
    top = std::min(top, e.box.top);
    left = std::min(left, e.box.left);
    bottom = std::max(bottom, e.box.bottom());
    right = std::max(right, e.box.right());
  }
  return {top, left, bottom - top, right - left};
}

Image DemoObject(Shape shape) {
  CheckShape("DemoObject", shape, kDemoMinSide);
  const UsafOptions options = DemoUsafOptions(shape);
  const LayoutMm layout = MakeLayout(options.first_group, options.last_group);
  Image image = UsafTarget(shape, options);

  // The empty part of the target's box: right of group -2's column and below group -1's, out to the box's
  // bottom-right corner (groups 0 and 1 are shorter than group -1, so nothing else reaches in).
  const Placement p = MakePlacement(shape, layout, options.pixels_per_mm);
  const double ya = p.Y(layout.column_height[1]), yb = p.Y(layout.height);
  const double xa = p.X(layout.column_left[1]), xb = p.X(layout.width);
  const double dy = yb - ya, dx = xb - xa;
  const std::vector<PointSource> sources = {
      {ya + 0.3 * dy, xa + 0.3 * dx, 0.9},          // isolated
      {ya + 0.3 * dy, xa + 0.75 * dx - 3.0, 0.6},   // horizontal pair, 6 px apart
      {ya + 0.3 * dy, xa + 0.75 * dx + 3.0, 0.8},
      {ya + 0.7 * dy - 1.5, xa + 0.5 * dx, 0.5},    // vertical pair, 3 px apart
      {ya + 0.7 * dy + 1.5, xa + 0.5 * dx, 0.7},
  };
  AddPointSources(&image, sources);
  return image;
}

}  // namespace aosr
