#include "aosr/solvers/shift_and_add.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <opencv2/imgproc.hpp>

#include "aosr/core/error.hpp"
#include "aosr/core/fft.hpp"
#include "aosr/core/operators.hpp"

namespace aosr {
namespace {

void CheckFrames(const char* fn, const ImageStack& frames, int r) {
  CheckArgument(!frames.empty(), fn, "frames", "empty", "at least one frame");
  CheckArgument(r >= 1, fn, "r", r, ">= 1");
  for (std::size_t i = 0; i < frames.size(); ++i) {
    if (ShapeOf(frames[i]) != ShapeOf(frames[0]) || frames[i].size() == 0)
      throw InvalidArgument(fn, "frame " + std::to_string(i) + " shape", ToString(ShapeOf(frames[i])),
                            "non-empty and equal to frame 0's " + ToString(ShapeOf(frames[0])));
    if (!AllFinite(frames[i]))
      throw InvalidArgument(fn, "frame " + std::to_string(i), "contains NaN or Inf", "finite values");
  }
}

// Moves an HR image by (dy, dx) pixels: integer shifts exactly (circular), others by Fourier shift.
Image Shift(const Image& img, double dy, double dx) {
  if (dy == std::round(dy) && dx == std::round(dx)) {
    const Index R = img.rows(), C = img.cols();
    const Index sy = ((Index(dy) % R) + R) % R, sx = ((Index(dx) % C) + C) % C;
    Image out(R, C);
    for (Index y = 0; y < R; ++y)
      for (Index x = 0; x < C; ++x) out((y + sy) % R, (x + sx) % C) = img(y, x);
    return out;
  }
  const ComplexImage X = FftR2C(img) * ShiftTransfer(ShapeOf(img), dy, dx);
  return FftC2R(X, img.cols());
}

// The median of v (reordered; non-empty): the middle value, or the mean of the two middle values.
double Median(std::vector<double>& v) {
  const std::size_t h = v.size() / 2;
  std::nth_element(v.begin(), v.begin() + h, v.end());
  const double upper = v[h];
  return v.size() % 2 ? upper : 0.5 * (upper + *std::max_element(v.begin(), v.begin() + h));
}

}  // namespace

Image ShiftAndAdd(const ImageStack& frames, const std::vector<FrameOffset>& offsets, int r, Combine combine,
                  SolverSummary* summary) {
  CheckFrames("ShiftAndAdd", frames, r);
  CheckArgument(offsets.size() == frames.size(), "ShiftAndAdd", "offsets count", offsets.size(),
                "one per frame (" + std::to_string(frames.size()) + ")");
  const auto start = std::chrono::steady_clock::now();
  const Index R = frames[0].rows() * r, C = frames[0].cols() * r;
  ImageStack registered;
  for (std::size_t i = 0; i < frames.size(); ++i) {
    Image up(R, C);
    for (Index y = 0; y < R; ++y)
      for (Index x = 0; x < C; ++x) up(y, x) = frames[i](y / r, x / r) / double(r * r);
    registered.push_back(Shift(up, -offsets[i].dy, -offsets[i].dx));
  }
  Image out(R, C);
  if (combine == Combine::kMean) {
    out.setZero();
    for (const Image& f : registered) out += f;
    out /= double(registered.size());
  } else {
    std::vector<double> v(registered.size());
    for (Index p = 0; p < out.size(); ++p) {
      for (std::size_t i = 0; i < registered.size(); ++i) v[i] = registered[i].data()[p];
      out.data()[p] = Median(v);
    }
  }
  if (summary) {
    *summary = SolverSummary{};
    summary->method = combine == Combine::kMean ? "shift-and-add (mean)" : "shift-and-add (median)";
    summary->seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  }
  return out;
}

Image ShiftAndAdd(const ReconstructionProblem& problem, Combine combine, SolverSummary* summary) {
  constexpr const char* kShiftAndAddFn = "ShiftAndAdd";
  problem.Validate(kShiftAndAddFn);
  CheckArgument(problem.offsets.size() == problem.frames.size(), kShiftAndAddFn, "problem.offsets count",
                problem.offsets.size(), "one per frame (" + std::to_string(problem.frames.size()) + ")");
  const auto start = std::chrono::steady_clock::now();
  const int r = problem.model->r();
  const Shape hr = problem.model->hr_shape();
  const ImageStack clean = problem.CleanFrames();
  const std::size_t n = clean.size();
  ImageStack values, masks;
  for (std::size_t i = 0; i < n; ++i) {
    const Image w = problem.Weight(int(i));
    Image up(hr.rows, hr.cols), m(hr.rows, hr.cols);
    for (Index y = 0; y < hr.rows; ++y)
      for (Index x = 0; x < hr.cols; ++x) {
        const bool ok = w(y / r, x / r) > 0;
        m(y, x) = ok ? 1.0 : 0.0;
        up(y, x) = ok ? clean[i](y / r, x / r) / double(r * r) : 0.0;
      }
    values.push_back(Shift(up, -problem.offsets[i].dy, -problem.offsets[i].dx));
    masks.push_back(Shift(m, -problem.offsets[i].dy, -problem.offsets[i].dx));
  }
  Image out = Image::Zero(hr.rows, hr.cols);
  Index holes = 0;
  std::vector<double> v;
  for (Index p = 0; p < out.size(); ++p) {
    if (combine == Combine::kMean) {
      double num = 0, den = 0;
      for (std::size_t i = 0; i < n; ++i) num += values[i].data()[p], den += masks[i].data()[p];
      // A Fourier-shifted mask rings around holes; below ½ a frame's worth of coverage the ratio is noise.
      if (den > 0.5) out.data()[p] = num / den; else ++holes;
    } else {
      v.clear();
      for (std::size_t i = 0; i < n; ++i) {
        const double m = masks[i].data()[p];
        if (m > 0.5) v.push_back(values[i].data()[p] / m);
      }
      if (v.empty()) {
        ++holes;
        continue;
      }
      out.data()[p] = Median(v);
    }
  }
  if (summary) {
    *summary = SolverSummary{};
    summary->method = combine == Combine::kMean ? "shift-and-add (mean)" : "shift-and-add (median)";
    summary->termination = holes == out.size() ? Termination::kFailed : Termination::kConverged;
    summary->message = holes == 0 ? "every HR pixel covered"
                                  : std::to_string(holes) + " HR pixels reached by no valid frame (set to 0)";
    summary->seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  }
  return out;
}

Image BicubicUpsample(const Image& frame, int r) {
  CheckFrames("BicubicUpsample", {frame}, r);
  cv::Mat src(int(frame.rows()), int(frame.cols()), CV_64F, const_cast<double*>(frame.data()));
  cv::Mat dst;
  cv::resize(src, dst, cv::Size(int(frame.cols() * r), int(frame.rows() * r)), 0, 0, cv::INTER_CUBIC);
  Image out(dst.rows, dst.cols);
  for (int y = 0; y < dst.rows; ++y)
    for (int x = 0; x < dst.cols; ++x) out(y, x) = dst.at<double>(y, x) / double(r * r);
  return out;
}

}  // namespace aosr
