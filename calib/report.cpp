#include "aosr/calib/report.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "aosr/core/error.hpp"
#include "aosr/io/image_io.hpp"

namespace aosr {
namespace {

constexpr int kScale = 2;      // tile magnification (nearest neighbour)
constexpr int kGap = 4;
constexpr int kPlotW = 280;

// √-stretch of (x − b) / (peak − b), clipped to [0, 1], magnified.
cv::Mat Tile(const Image& img, double background, double peak) {
  cv::Mat t(int(img.rows()), int(img.cols()), CV_64F);
  for (int r = 0; r < t.rows; ++r)
    for (int c = 0; c < t.cols; ++c) {
      const double v = (img(r, c) - background) / std::max(1e-300, peak - background);
      t.at<double>(r, c) = std::sqrt(std::clamp(std::isfinite(v) ? v : 0.0, 0.0, 1.0));
    }
  cv::Mat big;
  cv::resize(t, big, cv::Size(), kScale, kScale, cv::INTER_NEAREST);
  return big;
}

void Text(cv::Mat& m, const std::string& s, int x, int y, double size = 0.4) {
  cv::putText(m, s, cv::Point(x, y), cv::FONT_HERSHEY_SIMPLEX, size, cv::Scalar(0.0), 1, cv::LINE_AA);
}

// Gain against amplitude, white background, black marks.
cv::Mat Plot(const ModeCalibration& mc, int height) {
  cv::Mat p(height, kPlotW, CV_64F, cv::Scalar(1.0));
  const ModalFitResult& f = mc.final_fit;
  char buf[128];
  std::snprintf(buf, sizeof buf, "%s  g = %.4f +- %.4f", mc.name.c_str(), f.gain, f.gain_sigma);
  Text(p, buf, 4, 14);
  const LinearityReport& lin = mc.linearity;
  std::snprintf(buf, sizeof buf, "%s, chi2/dof %.2f", lin.levels.empty() ? "no levels" : lin.verdict.c_str(), f.reduced_chi2);
  Text(p, buf, 4, 30);
  if (lin.levels.empty()) return p;
  const int x0 = 40, x1 = kPlotW - 10, y0 = height - 22, y1 = 42;  // axes box (y grows downwards)
  double amax = 0, gmin = f.gain, gmax = f.gain;
  for (const AmplitudeGain& l : lin.levels) {
    amax = std::max(amax, l.amplitude_m);
    gmin = std::min(gmin, l.gain - l.sigma);
    gmax = std::max(gmax, l.gain + l.sigma);
  }
  const double pad = std::max(0.02 * std::abs(f.gain), 0.1 * (gmax - gmin));
  gmin -= pad, gmax += pad;
  auto X = [&](double a) { return int(x0 + (x1 - x0) * a / (1.1 * amax)); };
  auto Y = [&](double g) { return int(y0 - (y0 - y1) * (g - gmin) / (gmax - gmin)); };
  if (lin.onset_m > 0) cv::rectangle(p, cv::Point(X(lin.onset_m), y1), cv::Point(x1, y0), cv::Scalar(0.85), cv::FILLED);
  cv::rectangle(p, cv::Point(x0, y1), cv::Point(x1, y0), cv::Scalar(0.0), 1);
  cv::line(p, cv::Point(x0, Y(f.gain)), cv::Point(x1, Y(f.gain)), cv::Scalar(0.5), 1);
  for (const AmplitudeGain& l : lin.levels) {
    const int x = X(l.amplitude_m);
    cv::line(p, cv::Point(x, Y(l.gain - l.sigma)), cv::Point(x, Y(l.gain + l.sigma)), cv::Scalar(0.0), 1);
    cv::circle(p, cv::Point(x, Y(l.gain)), 3, cv::Scalar(0.0), cv::FILLED, cv::LINE_AA);
  }
  std::snprintf(buf, sizeof buf, "%.3g", gmax);
  Text(p, buf, 2, y1 + 10, 0.33);
  std::snprintf(buf, sizeof buf, "%.3g", gmin);
  Text(p, buf, 2, y0, 0.33);
  std::snprintf(buf, sizeof buf, "|a| [nm] to %.0f", amax * 1e9);
  Text(p, buf, x0, height - 6, 0.33);
  return p;
}

}  // namespace

void WriteCalibrationReport(const std::string& path, const CalibrationSet& set, const CalibrationResult& result) {
  CheckArgument(result.modes.size() == set.modes.size(), "WriteCalibrationReport", "result",
                std::to_string(result.modes.size()) + " modes", std::to_string(set.modes.size()) + " (the set's)");
  CheckArgument(!result.modes.empty(), "WriteCalibrationReport", "result", "no modes", "a calibration");
  const int th = int(set.shape().rows) * kScale, tw = int(set.shape().cols) * kScale;
  const int row_h = std::max(2 * th + kGap + 14, 150);
  std::size_t max_levels = 0;
  for (const ModeCalibration& mc : result.modes) max_levels = std::max(max_levels, mc.linearity.levels.size());
  const int cols = kPlotW + kGap + int(max_levels + 1) * (tw + kGap);
  cv::Mat page(int(result.modes.size()) * (row_h + kGap), cols, CV_64F, cv::Scalar(1.0));
  for (std::size_t m = 0; m < result.modes.size(); ++m) {
    const ModeCalibration& mc = result.modes[m];
    CheckArgument(mc.frames.size() == mc.joint.model.size(), "WriteCalibrationReport", "result",
                  "mode " + mc.name + " models", "one per fitted frame");
    const int top = int(m) * (row_h + kGap);
    Plot(mc, row_h).copyTo(page(cv::Rect(0, top, kPlotW, row_h)));
    // Reference, then the positive poke of each level (the largest |a| frame if none is positive).
    std::vector<std::pair<std::string, int>> shown;  // label, index into mc.frames
    for (std::size_t k = 0; k < mc.frames.size(); ++k)
      if (set.frames[mc.frames[k]].reference) {
        shown.push_back({"ref", int(k)});
        break;
      }
    for (const AmplitudeGain& l : mc.linearity.levels) {
      int pick = -1;
      for (std::size_t k = 0; k < mc.frames.size(); ++k) {
        const double a = set.frames[mc.frames[k]].amplitude_m;
        if (std::abs(std::abs(a) - l.amplitude_m) <= 1e-9 * l.amplitude_m && (pick < 0 || a > 0)) pick = int(k);
      }
      char buf[32];
      std::snprintf(buf, sizeof buf, "%.0f nm", l.amplitude_m * 1e9);
      if (pick >= 0) shown.push_back({buf, pick});
    }
    for (std::size_t s = 0; s < shown.size() && s < max_levels + 1; ++s) {
      const int k = shown[s].second;
      const CalibrationFrame& fr = set.frames[mc.frames[k]];
      const double b = mc.joint.background[k];
      const double peak = std::max(fr.adu.maxCoeff(), mc.joint.model[k].maxCoeff());
      const int x = kPlotW + kGap + int(s) * (tw + kGap);
      Tile(fr.adu, b, peak).copyTo(page(cv::Rect(x, top, tw, th)));
      Tile(mc.joint.model[k], b, peak).copyTo(page(cv::Rect(x, top + th + kGap, tw, th)));
      Text(page, shown[s].first, x + 2, top + 2 * th + kGap + 12, 0.35);
    }
  }
  Image img(page.rows, page.cols);
  for (int r = 0; r < page.rows; ++r)
    for (int c = 0; c < page.cols; ++c) img(r, c) = page.at<double>(r, c);
  img(0, 0) = 0.0;  // pin the stretch to [0, 1]
  ViewOptions v;
  v.low_percentile = 0, v.high_percentile = 100;
  WriteViewImage(path, img, v);
}

}  // namespace aosr
