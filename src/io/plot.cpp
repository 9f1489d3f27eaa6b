#include "aosr/io/plot.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "aosr/core/error.hpp"
#include "aosr/core/memory.hpp"

namespace aosr {
namespace {

constexpr const char* kPlotFn = "RenderFigure";
constexpr int kFont = cv::FONT_HERSHEY_SIMPLEX;
constexpr double kTickFont = 0.42, kLabelFont = 0.5, kTitleFont = 0.55, kLegendFont = 0.45;
const cv::Scalar kBlack(0, 0, 0), kGrid(225, 225, 225), kAxisGrey(90, 90, 90), kWhite(255, 255, 255);

// Hershey fonts have ASCII glyphs only: spell out the symbols reports use, '?' for anything else.
std::string Ascii(const std::string& s) {
  static const std::pair<const char*, const char*> kMap[] = {
      {"λ", "lambda"}, {"μ", "mu"}, {"σ", "sigma"}, {"×", "x"},  {"²", "^2"}, {"³", "^3"}, {"—", "-"},
      {"–", "-"},      {"≈", "~"},  {"≤", "<="},    {"≥", ">="}, {"⁻", "-"},  {"¹", "1"}};
  std::string out;
  for (std::size_t i = 0; i < s.size();) {
    const unsigned char c = static_cast<unsigned char>(s[i]);
    if (c < 0x80) {
      out += (c >= 0x20 && c < 0x7f) ? char(c) : ' ';
      ++i;
      continue;
    }
    bool mapped = false;
    for (const auto& [from, to] : kMap) {
      const std::size_t n = std::char_traits<char>::length(from);
      if (s.compare(i, n, from) == 0) {
        out += to;
        i += n;
        mapped = true;
        break;
      }
    }
    if (mapped) continue;
    // Skip the whole UTF-8 sequence (lead byte 11xxxxxx, continuation bytes 10xxxxxx).
    ++i;
    while (i < s.size() && (static_cast<unsigned char>(s[i]) & 0xC0) == 0x80) ++i;
    out += '?';
  }
  return out;
}

cv::Size TextSize(const std::string& s, double scale, int* baseline = nullptr) {
  int b = 0;
  const cv::Size z = cv::getTextSize(s, kFont, scale, 1, &b);
  if (baseline) *baseline = b;
  return z;
}

// Draws s with its left end at x and its vertical centre at y.
void Text(cv::Mat& m, const std::string& s, int x, int y, double scale, const cv::Scalar& colour = kBlack) {
  const cv::Size z = TextSize(s, scale);
  cv::putText(m, s, cv::Point(x, y + z.height / 2), kFont, scale, colour, 1, cv::LINE_AA);
}

// Shortest %g form with 3 significant digits, exponents without '+' and leading zeros (1e+06 -> 1e6).
std::string TickLabel(double v) {
  if (std::abs(v) < 1e-300) v = 0;
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.3g", v);
  std::string s = buf;
  const std::size_t e = s.find('e');
  if (e == std::string::npos) return s;
  std::string mant = s.substr(0, e), exp = s.substr(e + 1);
  bool neg = false;
  if (!exp.empty() && (exp[0] == '+' || exp[0] == '-')) {
    neg = exp[0] == '-';
    exp.erase(0, 1);
  }
  while (exp.size() > 1 && exp[0] == '0') exp.erase(0, 1);
  return mant + "e" + (neg ? "-" : "") + exp;
}

// 1, 2 or 5 x 10^k, the smallest such step giving at most `max_ticks` ticks over `span`.
double NiceStep(double span, int max_ticks) {
  const double raw = span / std::max(1, max_ticks - 1);
  const double p = std::pow(10.0, std::floor(std::log10(raw)));
  for (double f : {1.0, 2.0, 5.0, 10.0})
    if (f * p >= raw) return f * p;
  return 10 * p;
}

std::vector<double> LinearTicks(double lo, double hi) {
  const double step = NiceStep(hi - lo, 7);
  std::vector<double> t;
  for (double k = std::ceil(lo / step - 1e-9); k * step <= hi + 1e-9 * step; k += 1) t.push_back(k * step);
  return t;
}

// Ticks of a log axis whose range is [10^lo, 10^hi] (lo, hi in decades).
std::vector<double> LogTicks(double lo, double hi) {
  std::vector<double> t;
  const double span = hi - lo;
  if (span < 1.0) {
    // Less than a decade: 1-2-5 steps in data units, placed logarithmically.
    for (double v : LinearTicks(std::pow(10.0, lo), std::pow(10.0, hi)))
      if (v > 0) t.push_back(v);
    return t;
  }
  const int every = std::max(1, int(std::ceil(span / 8.0)));
  for (int d = int(std::ceil(lo - 1e-9)); d <= int(std::floor(hi + 1e-9)); ++d)
    if (d % every == 0) t.push_back(std::pow(10.0, d));
  if (span < 3.0) {
    for (int d = int(std::floor(lo)); d <= int(std::ceil(hi)); ++d)
      for (double f : {2.0, 5.0}) {
        const double v = f * std::pow(10.0, d);
        const double l = std::log10(v);
        if (l >= lo - 1e-9 && l <= hi + 1e-9) t.push_back(v);
      }
    std::sort(t.begin(), t.end());
  }
  return t;
}

// One axis' mapping from data to pixels.
struct Scale {
  bool log = false;
  double lo = 0, hi = 1;  // in axis units (log10 of the data on a log axis)
  double Unit(double v) const { return log ? std::log10(v) : v; }
  double Fraction(double v) const { return (Unit(v) - lo) / (hi - lo); }
};

Scale MakeScale(const PlotAxis& axis, const std::vector<double>& values) {
  Scale s;
  s.log = axis.log;
  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  for (double v : values)
    if (std::isfinite(v)) {
      lo = std::min(lo, s.Unit(v));
      hi = std::max(hi, s.Unit(v));
    }
  const bool fixed_lo = std::isfinite(axis.min), fixed_hi = std::isfinite(axis.max);
  if (!(lo <= hi)) {  // no data
    lo = 0.0;  // [0, 1], or [1, 10] on a log axis (axis units are decades there)
    hi = 1.0;
  } else if (hi - lo < 1e-12 * std::max(1.0, std::abs(hi))) {
    lo -= 0.5;
    hi += 0.5;
  } else {
    const double pad = 0.05 * (hi - lo);
    lo -= pad;
    hi += pad;
  }
  if (fixed_lo) lo = s.Unit(axis.min);
  if (fixed_hi) hi = s.Unit(axis.max);
  if (!(hi > lo)) {  // one fixed end beyond the data's other end
    if (fixed_lo)
      hi = lo + 1;
    else
      lo = hi - 1;
  }
  s.lo = lo;
  s.hi = hi;
  return s;
}

bool CheckAxis(const PlotAxis& a, const char* name, std::string* why) {
  const auto fail = [&](const std::string& m) {
    if (why) *why = m;
    return false;
  };
  if (std::isfinite(a.min) && std::isfinite(a.max) && !(a.min < a.max))
    return fail(std::string(name) + ".min = " + ToString(a.min) + " >= " + name +
                ".max = " + ToString(a.max) + "; need min < max");
  if (a.log && ((std::isfinite(a.min) && a.min <= 0) || (std::isfinite(a.max) && a.max <= 0)))
    return fail(std::string(name) + ": a log axis needs a positive fixed range, got [" + ToString(a.min) +
                ", " + ToString(a.max) + "]");
  return true;
}

cv::Scalar Bgr(int i) {
  const auto c = SeriesColour(i);
  return cv::Scalar(c[2], c[1], c[0]);
}

void DrawPanel(cv::Mat& m, const LinePlot& p) {
  // Legend entries: series with at least one drawable point and a label.
  std::vector<int> legend;
  int legend_text_w = 0;
  for (std::size_t i = 0; i < p.series.size(); ++i) {
    const PlotSeries& s = p.series[i];
    bool any = false;
    for (std::size_t k = 0; k < s.x.size(); ++k)
      any = any || (std::isfinite(s.x[k]) && std::isfinite(s.y[k]));
    if (any && !s.label.empty()) {
      legend.push_back(int(i));
      legend_text_w = std::max(legend_text_w, TextSize(Ascii(s.label), kLegendFont).width);
    }
  }
  legend_text_w = std::min(legend_text_w, m.cols / 3);
  const int legend_w = legend.empty() ? 0 : legend_text_w + 44;

  // Data ranges.
  std::vector<double> xs, ys;
  for (const PlotSeries& s : p.series)
    for (std::size_t k = 0; k < s.x.size(); ++k)
      if (std::isfinite(s.x[k]) && std::isfinite(s.y[k])) {
        xs.push_back(s.x[k]);
        ys.push_back(s.y[k]);
      }
  const Scale sx = MakeScale(p.x, xs), sy = MakeScale(p.y, ys);
  std::vector<double> xt = sx.log ? LogTicks(sx.lo, sx.hi) : LinearTicks(sx.lo, sx.hi);
  std::vector<double> yt = sy.log ? LogTicks(sy.lo, sy.hi) : LinearTicks(sy.lo, sy.hi);

  // Layout: title on top, y tick labels and the rotated y label on the left, x tick labels and label below,
  // legend on the right.
  int ytick_w = 0;
  for (double v : yt) ytick_w = std::max(ytick_w, TextSize(TickLabel(v), kTickFont).width);
  const int text_h = TextSize("Ay", kLabelFont).height;
  const int left = 12 + (p.y.label.empty() ? 0 : text_h + 12) + ytick_w + 8;
  const int top = p.title.empty() ? 16 : 16 + TextSize("Ay", kTitleFont).height + 14;
  const int bottom = 16 + TextSize("0", kTickFont).height + 10 + (p.x.label.empty() ? 0 : text_h + 12);
  const int right = 16 + legend_w;
  const cv::Rect area(left, top, std::max(20, m.cols - left - right), std::max(20, m.rows - top - bottom));
  const auto X = [&](double v) { return area.x + sx.Fraction(v) * area.width; };
  const auto Y = [&](double v) { return area.y + area.height - sy.Fraction(v) * area.height; };
  const auto inside = [&](double px, double py) {
    return px >= area.x - 0.5 && px <= area.x + area.width + 0.5 && py >= area.y - 0.5 &&
           py <= area.y + area.height + 0.5;
  };

  // Grid and ticks.
  for (double v : xt) {
    const int x = int(std::lround(X(v)));
    if (x < area.x || x > area.x + area.width) continue;
    cv::line(m, {x, area.y}, {x, area.y + area.height}, kGrid, 1);
    cv::line(m, {x, area.y + area.height}, {x, area.y + area.height + 5}, kAxisGrey, 1);
    const std::string l = TickLabel(v);
    const cv::Size z = TextSize(l, kTickFont);
    Text(m, l, x - z.width / 2, area.y + area.height + 10 + z.height / 2, kTickFont);
  }
  for (double v : yt) {
    const int y = int(std::lround(Y(v)));
    if (y < area.y || y > area.y + area.height) continue;
    cv::line(m, {area.x, y}, {area.x + area.width, y}, kGrid, 1);
    cv::line(m, {area.x - 5, y}, {area.x, y}, kAxisGrey, 1);
    const std::string l = TickLabel(v);
    Text(m, l, area.x - 8 - TextSize(l, kTickFont).width, y, kTickFont);
  }
  cv::rectangle(m, area, kAxisGrey, 1);

  // Series: lines (clipped to the plot area), then markers on top.
  const cv::Rect clip(area.x, area.y, area.width + 1, area.height + 1);
  for (std::size_t i = 0; i < p.series.size(); ++i) {
    const PlotSeries& s = p.series[i];
    bool have_prev = false;
    cv::Point prev;
    for (std::size_t k = 0; k < s.x.size(); ++k) {
      if (!(std::isfinite(s.x[k]) && std::isfinite(s.y[k]))) {
        have_prev = false;
        continue;
      }
      cv::Point q(int(std::lround(X(s.x[k]))), int(std::lround(Y(s.y[k]))));
      if (have_prev) {
        cv::Point a = prev, b = q;
        if (cv::clipLine(clip, a, b)) cv::line(m, a, b, Bgr(int(i)), 2, cv::LINE_AA);
      }
      prev = q;
      have_prev = true;
    }
    for (std::size_t k = 0; k < s.x.size(); ++k) {
      if (!(std::isfinite(s.x[k]) && std::isfinite(s.y[k]))) continue;
      const double px = X(s.x[k]), py = Y(s.y[k]);
      if (!inside(px, py)) continue;
      const cv::Point q(int(std::lround(px)), int(std::lround(py)));
      cv::circle(m, q, 4, Bgr(int(i)), cv::FILLED, cv::LINE_AA);
      cv::circle(m, q, 4, kBlack, 1, cv::LINE_AA);
      // The point's label to its upper right, inside the plot area (left of the point near the right edge).
      if (k < s.point_labels.size() && !s.point_labels[k].empty()) {
        const std::string l = Ascii(s.point_labels[k]);
        const int w = TextSize(l, kTickFont).width;
        const int tx = q.x + 7 + w <= area.x + area.width ? q.x + 7 : q.x - 7 - w;
        Text(m, l, tx, std::max(area.y + 6, q.y - 9), kTickFont);
      }
    }
  }

  // Labels and title.
  if (!p.x.label.empty()) {
    const std::string l = Ascii(p.x.label);
    Text(m, l, area.x + (area.width - TextSize(l, kLabelFont).width) / 2, m.rows - 12 - text_h / 2,
         kLabelFont);
  }
  if (!p.y.label.empty()) {
    // Drawn horizontally into a scratch image, rotated a quarter turn counter-clockwise and pasted.
    const std::string l = Ascii(p.y.label);
    int baseline = 0;
    const cv::Size z = TextSize(l, kLabelFont, &baseline);
    cv::Mat t(z.height + baseline + 4, z.width + 4, m.type(), kWhite);
    cv::putText(t, l, cv::Point(2, z.height + 2), kFont, kLabelFont, kBlack, 1, cv::LINE_AA);
    cv::Mat r;
    cv::rotate(t, r, cv::ROTATE_90_COUNTERCLOCKWISE);
    const int h = std::min(r.rows, m.rows), w = std::min(r.cols, m.cols);
    const int y0 = std::clamp(area.y + (area.height - h) / 2, 0, m.rows - h);
    r(cv::Rect(0, 0, w, h)).copyTo(m(cv::Rect(10, y0, w, h)));
  }
  if (!p.title.empty()) {
    const std::string l = Ascii(p.title);
    const int w = TextSize(l, kTitleFont).width;
    cv::putText(m, l,
                cv::Point(std::max(4, area.x + (area.width - w) / 2), 12 + TextSize("Ay", kTitleFont).height),
                kFont, kTitleFont, kBlack, 1, cv::LINE_AA);
  }

  // Legend, right of the plot area, top-aligned.
  const int row_h = std::max(18, TextSize("Ay", kLegendFont).height + 8);
  int y = area.y + 10;
  for (int i : legend) {
    if (y + row_h / 2 > m.rows) break;
    const int x0 = area.x + area.width + 12;
    cv::line(m, {x0, y}, {x0 + 22, y}, Bgr(i), 2, cv::LINE_AA);
    cv::circle(m, {x0 + 11, y}, 4, Bgr(i), cv::FILLED, cv::LINE_AA);
    cv::circle(m, {x0 + 11, y}, 4, kBlack, 1, cv::LINE_AA);
    std::string l = Ascii(p.series[std::size_t(i)].label);
    while (l.size() > 3 && TextSize(l, kLegendFont).width > legend_text_w)
      l = l.substr(0, l.size() - 4) + "..";
    Text(m, l, x0 + 28, y, kLegendFont);
    y += row_h;
  }
}

// OpenCV draws in BGR; RgbImage is row-major RGB.
RgbImage ToRgb(const cv::Mat& fig) {
  RgbImage out;
  out.rows = fig.rows;
  out.cols = fig.cols;
  out.rgb.resize(std::size_t(3) * fig.rows * fig.cols);
  for (int y = 0; y < fig.rows; ++y)
    for (int x = 0; x < fig.cols; ++x) {
      const cv::Vec3b& bgr = fig.at<cv::Vec3b>(y, x);
      std::uint8_t* o = &out.rgb[std::size_t(3) * (std::size_t(y) * fig.cols + x)];
      o[0] = bgr[2];
      o[1] = bgr[1];
      o[2] = bgr[0];
    }
  return out;
}

}  // namespace

bool LinePlot::IsValid(std::string* why) const {
  const auto fail = [&](const std::string& m) {
    if (why) *why = m;
    return false;
  };
  if (!CheckAxis(x, "x", why) || !CheckAxis(y, "y", why)) return false;
  for (std::size_t i = 0; i < series.size(); ++i) {
    const PlotSeries& s = series[i];
    const std::string name = "series[" + std::to_string(i) + "] ('" + s.label + "')";
    if (s.x.size() != s.y.size())
      return fail(name + ": x has " + std::to_string(s.x.size()) + " points, y " +
                  std::to_string(s.y.size()));
    if (!s.point_labels.empty() && s.point_labels.size() != s.x.size())
      return fail(name + ": point_labels has " + std::to_string(s.point_labels.size()) + " entries for " +
                  std::to_string(s.x.size()) + " points (empty, or one per point)");
    for (std::size_t k = 0; k < s.x.size(); ++k) {
      if (x.log && std::isfinite(s.x[k]) && s.x[k] <= 0)
        return fail(name + ".x[" + std::to_string(k) + "] = " + ToString(s.x[k]) +
                    ": a log x axis needs x > 0 (drop the point or use a linear axis)");
      if (y.log && std::isfinite(s.y[k]) && s.y[k] <= 0)
        return fail(name + ".y[" + std::to_string(k) + "] = " + ToString(s.y[k]) +
                    ": a log y axis needs y > 0 (drop the point or use a linear axis)");
    }
  }
  return true;
}

bool FigureOptions::IsValid(std::string* why) const {
  const auto fail = [&](const std::string& m) {
    if (why) *why = m;
    return false;
  };
  if (panel_width < 240 || panel_width > 4000)
    return fail("panel_width = " + std::to_string(panel_width) + "; need 240..4000");
  if (panel_height < 180 || panel_height > 4000)
    return fail("panel_height = " + std::to_string(panel_height) + "; need 180..4000");
  if (columns < 1) return fail("columns = " + std::to_string(columns) + "; need >= 1");
  return true;
}

std::array<std::uint8_t, 3> SeriesColour(int i) {
  static const std::array<std::uint8_t, 3> kTab10[10] = {
      {{31, 119, 180}}, {{255, 127, 14}},  {{44, 160, 44}},   {{214, 39, 40}},  {{148, 103, 189}},
      {{140, 86, 75}},  {{227, 119, 194}}, {{127, 127, 127}}, {{188, 189, 34}}, {{23, 190, 207}}};
  return kTab10[((i % 10) + 10) % 10];
}

RgbImage RenderFigure(const std::vector<LinePlot>& panels, const FigureOptions& options) {
  std::string why;
  if (!options.IsValid(&why)) throw InvalidArgument(std::string(kPlotFn) + ": invalid FigureOptions: " + why);
  CheckArgument(!panels.empty(), kPlotFn, "panels", "0 panels", "at least one");
  for (std::size_t i = 0; i < panels.size(); ++i)
    if (!panels[i].IsValid(&why))
      throw InvalidArgument(std::string(kPlotFn) + ": panel " + std::to_string(i) +
                            (panels[i].title.empty() ? "" : " ('" + panels[i].title + "')") + ": " + why);
  const int n = int(panels.size());
  const int cols = std::min(options.columns, n), rows = (n + cols - 1) / cols;
  CheckMemory(6.0 * rows * options.panel_height * double(cols) * options.panel_width,
              std::string(kPlotFn) + ": a figure of " + std::to_string(n) + " panels");
  cv::Mat fig(rows * options.panel_height, cols * options.panel_width, CV_8UC3, kWhite);
  for (int i = 0; i < n; ++i) {
    cv::Mat panel = fig(cv::Rect((i % cols) * options.panel_width, (i / cols) * options.panel_height,
                                 options.panel_width, options.panel_height));
    DrawPanel(panel, panels[std::size_t(i)]);
  }
  return ToRgb(fig);
}

void WriteFigure(const std::string& path, const std::vector<LinePlot>& panels, const FigureOptions& options) {
  WriteRgbImage(path, RenderFigure(panels, options));
}

bool PanelFigureOptions::IsValid(std::string* why) const {
  auto fail = [why](const std::string& m) {
    if (why) *why = m;
    return false;
  };
  if (columns < 1) return fail("columns = " + std::to_string(columns) + "; allowed: >= 1");
  if (gap_px < 0 || gap_px > 200) return fail("gap_px = " + std::to_string(gap_px) + "; allowed: 0..200");
  if (!(text_scale > 0 && text_scale <= 4)) return fail("text_scale = " + ToString(text_scale) + "; allowed: (0, 4]");
  return true;
}

RgbImage RenderImagePanels(const std::vector<ImagePanel>& panels, const PanelFigureOptions& options) {
  constexpr const char* kPanelsFn = "RenderImagePanels";
  std::string why;
  if (!options.IsValid(&why)) throw InvalidArgument(std::string(kPanelsFn) + ": invalid PanelFigureOptions: " + why);
  CheckArgument(!panels.empty(), kPanelsFn, "panels", "0 panels", "at least one");
  int cell_w = 0, cell_h = 0;
  for (std::size_t i = 0; i < panels.size(); ++i) {
    const ImagePanel& p = panels[i];
    const std::string name = "panels[" + std::to_string(i) + "]";
    CheckArgument(p.image.size() > 0, kPanelsFn, name + ".image", "empty", "a non-empty image");
    CheckArgument(p.zoom >= 1 && p.zoom <= 64, kPanelsFn, name + ".zoom", p.zoom, "1..64");
    for (const PanelBox& b : p.boxes)
      CheckArgument(b.top >= 0 && b.left >= 0 && b.height >= 1 && b.width >= 1 && b.top + b.height <= p.image.rows() &&
                        b.left + b.width <= p.image.cols(),
                    kPanelsFn, name + ".boxes",
                    "(" + std::to_string(b.top) + ", " + std::to_string(b.left) + ", " + std::to_string(b.height) +
                        ", " + std::to_string(b.width) + ")",
                    "inside the " + ToString(ShapeOf(p.image)) + " image, at least 1 x 1");
    cell_w = std::max<int>(cell_w, int(p.image.cols()) * p.zoom);
    cell_h = std::max<int>(cell_h, int(p.image.rows()) * p.zoom);
  }
  const double sub_scale = 0.9 * options.text_scale;
  const int line1 = TextSize("Ag", options.text_scale).height, line2 = TextSize("Ag", sub_scale).height;
  auto split = [](const std::string& t) {
    std::vector<std::string> lines;
    std::size_t start = 0;
    while (start <= t.size() && !t.empty()) {
      const std::size_t nl = t.find('\n', start);
      lines.push_back(t.substr(start, nl == std::string::npos ? std::string::npos : nl - start));
      if (nl == std::string::npos) break;
      start = nl + 1;
    }
    return lines;
  };
  std::size_t sub_lines = 1;
  for (const ImagePanel& p : panels) sub_lines = std::max(sub_lines, split(p.subtitle).size());
  const int pad = std::max(3, line1 / 2);
  const int band = line1 + int(sub_lines) * (line2 + pad) + 2 * pad;  // title band above each image
  const int n = int(panels.size());
  const int cols = std::min(options.columns, n), rows = (n + cols - 1) / cols, gap = options.gap_px;
  const std::vector<std::string> caption = split(options.caption);
  const int caption_h = caption.empty() ? 0 : int(caption.size()) * (line2 + pad) + pad;
  const int fig_w = cols * cell_w + (cols + 1) * gap,
            fig_h = caption_h + rows * (cell_h + band) + (rows + 1) * gap;
  CheckMemory(6.0 * double(fig_w) * double(fig_h), std::string(kPanelsFn) + ": a figure of " + std::to_string(n) + " panels");
  cv::Mat fig(fig_h, fig_w, CV_8UC3, kWhite);
  const cv::Scalar kBox(14, 127, 255);  // orange (BGR)
  for (std::size_t k = 0; k < caption.size(); ++k)
    cv::putText(fig, Ascii(caption[k]), cv::Point(gap, gap + int(k + 1) * (line2 + pad)), kFont, sub_scale, kBlack, 1,
                cv::LINE_AA);
  for (int i = 0; i < n; ++i) {
    const ImagePanel& p = panels[std::size_t(i)];
    const int x0 = gap + (i % cols) * (cell_w + gap), y0 = caption_h + gap + (i / cols) * (cell_h + band + gap);
    if (!p.title.empty()) {
      const std::string t = Ascii(p.title);
      const cv::Size z = TextSize(t, options.text_scale);
      cv::putText(fig, t, cv::Point(x0 + std::max(0, (cell_w - z.width) / 2), y0 + pad + line1), kFont,
                  options.text_scale, kBlack, 2, cv::LINE_AA);
    }
    const std::vector<std::string> lines = split(p.subtitle);
    for (std::size_t k = 0; k < lines.size(); ++k) {
      const std::string t = Ascii(lines[k]);
      const cv::Size z = TextSize(t, sub_scale);
      cv::putText(fig, t,
                  cv::Point(x0 + std::max(0, (cell_w - z.width) / 2), y0 + pad + line1 + int(k + 1) * (line2 + pad)),
                  kFont, sub_scale, kAxisGrey, 1, cv::LINE_AA);
    }
    const int w = int(p.image.cols()) * p.zoom, h = int(p.image.rows()) * p.zoom;
    const int ix = x0 + (cell_w - w) / 2, iy = y0 + band;
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x) {
        const double v = p.image(y / p.zoom, x / p.zoom);
        const int g = std::isnan(v) ? 0 : int(std::lround(255.0 * std::clamp(v, 0.0, 1.0)));
        fig.at<cv::Vec3b>(iy + y, ix + x) = cv::Vec3b(std::uint8_t(g), std::uint8_t(g), std::uint8_t(g));
      }
    for (const PanelBox& b : p.boxes)
      cv::rectangle(fig, cv::Rect(ix + int(b.left) * p.zoom, iy + int(b.top) * p.zoom, int(b.width) * p.zoom,
                                  int(b.height) * p.zoom),
                    kBox, std::max(1, p.zoom), cv::LINE_8);
  }
  return ToRgb(fig);
}

}  // namespace aosr
