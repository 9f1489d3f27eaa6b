#include "aosr/scene/usaf_contrast.hpp"

#include <algorithm>
#include <cmath>
#include <map>
#include <utility>

#include "aosr/core/error.hpp"

namespace aosr {
namespace {

constexpr const char* kUsafContrastFn = "MeasureUsafResolvingPower";
constexpr double kUsafMinBarWidthPx = 0.5;

struct UsafTriplet {
  std::vector<PixelRect> vertical;    // 3 bars long along y, by increasing x
  std::vector<PixelRect> horizontal;  // 3 bars long along x, by increasing y
};

bool UsafBarInside(const PixelRect& r, Shape s) {
  return r.top >= -0.5 && r.left >= -0.5 && r.bottom() <= double(s.rows) - 0.5 && r.right() <= double(s.cols) - 0.5;
}

// Michelson contrast of three bars seen in `img` (transposed: the bars are the horizontal ones, read along y).
// `bars` are in the (possibly transposed) image's coordinates: long along its rows' index, spaced along columns.
double UsafTripletContrast(const Image& img, const std::vector<PixelRect>& bars) {
  const PixelRect& first = bars.front();
  const double w = first.width;
  // Rows in the middle three fifths of the bars' length.
  Index y0 = Index(std::ceil(first.top + 0.2 * first.height)), y1 = Index(std::floor(first.top + 0.8 * first.height));
  if (y1 < y0) y0 = y1 = Index(std::lround(first.top + 0.5 * first.height - 1e-12));
  y0 = std::clamp<Index>(y0, 0, img.rows() - 1);
  y1 = std::clamp<Index>(y1, 0, img.rows() - 1);
  auto profile = [&](Index x) {
    x = std::clamp<Index>(x, 0, img.cols() - 1);
    double s = 0.0;
    for (Index y = y0; y <= y1; ++y) s += img(y, x);
    return s / double(y1 - y0 + 1);
  };
  // Keys' cubic convolution (a = −1/2, Catmull-Rom): exact for quadratics, so a blurred bar's rounded peak is
  // not flattened as linear interpolation would (which reads a Gaussian-blurred three-bar element ~0.1 low).
  auto at = [&](double t) {
    const Index i = Index(std::floor(t));
    const double f = t - double(i);
    const double p0 = profile(i - 1), p1 = profile(i), p2 = profile(i + 1), p3 = profile(i + 2);
    return p1 + 0.5 * f * (p2 - p0 + f * (2.0 * p0 - 5.0 * p1 + 4.0 * p2 - p3 + f * (3.0 * (p1 - p2) + p3 - p0)));
  };
  double peaks = 0.0, gaps = 0.0;
  for (const PixelRect& b : bars) peaks += at(b.left + 0.5 * w);
  for (int k = 0; k < 2; ++k) gaps += at(bars[k].left + 1.5 * w);
  const double imax = peaks / 3.0, imin = gaps / 2.0;
  if (!(imax + imin > 0.0)) return 0.0;
  return (imax - imin) / (imax + imin);
}

// Transposes a horizontal bar's rectangle into the transposed image's coordinates.
PixelRect TransposedRect(const PixelRect& r) { return {r.left, r.top, r.width, r.height}; }

}  // namespace

bool UsafContrastOptions::IsValid(std::string* why) const {
  auto fail = [why](const std::string& m) {
    if (why) *why = m;
    return false;
  };
  if (!(threshold > 0.0 && threshold < 1.0)) return fail("threshold = " + ToString(threshold) + " (must be in (0, 1))");
  if (r < 0 || r > 64) return fail("r = " + std::to_string(r) + " (must be 0, not given, or in [1, 64])");
  if (!(hr_pixel_lambda_over_d >= 0.0 && std::isfinite(hr_pixel_lambda_over_d)))
    return fail("hr_pixel_lambda_over_d = " + ToString(hr_pixel_lambda_over_d) + " (must be 0, not given, or > 0)");
  return true;
}

UsafResolvingPower MeasureUsafResolvingPower(const Image& image, const UsafOptions& target,
                                             const UsafContrastOptions& options) {
  std::string why;
  if (!options.IsValid(&why)) throw InvalidArgument(std::string(kUsafContrastFn) + ": invalid options: " + why);
  if (!target.IsValid(&why)) throw InvalidArgument(std::string(kUsafContrastFn) + ": invalid target: " + why);
  CheckArgument(target.rotation_deg == 0.0, kUsafContrastFn, "target.rotation_deg", target.rotation_deg,
                "0: the bar contrasts are read along the image's axes (a turned chart is for the slanted-edge MTF, "
                "aosr mtf)");
  CheckArgument(image.size() > 0, kUsafContrastFn, "image", ToString(ShapeOf(image)), "a non-empty image");
  if (!AllFinite(image)) throw InvalidArgument(kUsafContrastFn, "image", "(NaN or Inf)", "finite pixels");
  const Shape shape = ShapeOf(image);
  std::map<std::pair<int, int>, UsafTriplet> triplets;
  for (const UsafBar& b : UsafBars(shape, target)) {
    UsafTriplet& t = triplets[{b.group, b.element}];
    (b.horizontal ? t.horizontal : t.vertical).push_back(b.rect);
  }
  const Image reference = UsafTarget(shape, target);
  const Image image_t = image.transpose(), reference_t = reference.transpose();

  UsafResolvingPower out;
  out.threshold = options.threshold;
  for (const UsafElement& e : UsafElements(shape, target)) {
    UsafElementContrast c;
    c.group = e.group;
    c.element = e.element;
    c.bar_width_px = e.bar_width_px;
    c.cycles_per_px = 0.5 / e.bar_width_px;
    if (options.r > 0) c.cycles_per_camera_px = options.r * c.cycles_per_px;
    if (options.hr_pixel_lambda_over_d > 0) c.cycles_per_lambda_over_d = c.cycles_per_px / options.hr_pixel_lambda_over_d;
    const UsafTriplet& t = triplets[{e.group, e.element}];
    bool inside = t.vertical.size() == 3 && t.horizontal.size() == 3;
    for (const PixelRect& r : t.vertical) inside = inside && UsafBarInside(r, shape);
    for (const PixelRect& r : t.horizontal) inside = inside && UsafBarInside(r, shape);
    c.measured = inside && e.bar_width_px >= kUsafMinBarWidthPx;
    if (c.measured) {
      std::vector<PixelRect> h;
      for (const PixelRect& r : t.horizontal) h.push_back(TransposedRect(r));
      c.contrast_x = UsafTripletContrast(image, t.vertical);
      c.contrast_y = UsafTripletContrast(image_t, h);
      c.contrast = std::min(c.contrast_x, c.contrast_y);
      const double ref = std::min(UsafTripletContrast(reference, t.vertical), UsafTripletContrast(reference_t, h));
      c.transfer = ref > 0 ? c.contrast / ref : 0.0;
      c.resolved = c.contrast >= options.threshold;
    }
    out.elements.push_back(c);
  }
  // Elements come by group then element: increasing frequency. The finest resolved before the first failure.
  for (std::size_t i = 0; i < out.elements.size(); ++i) {
    const UsafElementContrast& c = out.elements[i];
    if (!c.measured) continue;
    if (!c.resolved) break;
    out.finest = int(i);
  }
  return out;
}

UsafResolvingPower MeasureSceneUsafResolvingPower(const Image& hr_image, const SceneSpec& scene, double threshold) {
  const char* f = "MeasureSceneUsafResolvingPower";
  const ObjectSpec* usaf = nullptr;
  for (const ObjectSpec& o : scene.objects)
    if (!usaf && (o.kind == ObjectSpec::Kind::kUsaf || o.kind == ObjectSpec::Kind::kDemo)) usaf = &o;
  if (!usaf) throw InvalidArgument(f, "scene", scene.source, "a scene with a usaf or demo object");
  if (ShapeOf(hr_image) != scene.HrFrame())
    throw InvalidArgument(f, "image", ToString(ShapeOf(hr_image)),
                          "an image of the scene's HR frame " + ToString(scene.HrFrame()) + " (rows x cols)");
  UsafContrastOptions o;
  o.threshold = threshold;
  o.r = scene.r;
  o.hr_pixel_lambda_over_d = scene.HrPixelLambdaOverD();
  return MeasureUsafResolvingPower(hr_image, ObjectUsafOptions(*usaf, scene.HrFrame()), o);
}

}  // namespace aosr
