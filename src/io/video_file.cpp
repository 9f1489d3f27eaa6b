// Video files through the media plugin (io/video_file.hpp): the stretch, the enlargement and the label drawn with
// OpenCV's core and imgproc (linked by the io layer already), the encoding by the plugin's VideoWriter.
#include "aosr/io/video_file.hpp"

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <vector>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "aosr/core/error.hpp"
#include "oiio_plugin/oiio_plugin.hpp"

namespace aosr {

void* MediaPluginSymbol(const char* name, std::string* error);  // image_io.cpp

bool VideoFileOptions::IsValid(std::string* why) const {
  auto fail = [why](const std::string& m) {
    if (why) *why = m;
    return false;
  };
  if (!(std::isfinite(fps) && fps > 0 && fps <= 1000)) return fail("fps = " + ToString(fps) + "; allowed: (0, 1000]");
  if (codec.size() != 4) return fail("codec = '" + codec + "'; allowed: four characters, e.g. MJPG");
  if (!(std::isfinite(asinh_softening) && asinh_softening > 0))
    return fail("asinh_softening = " + ToString(asinh_softening) + "; allowed: > 0");
  if (!(std::isfinite(black) && std::isfinite(white) && white > black))
    return fail("black, white = " + ToString(black) + ", " + ToString(white) + "; allowed: finite, white > black");
  if (zoom < 1 || zoom > 16) return fail("zoom = " + std::to_string(zoom) + "; allowed: 1..16");
  return true;
}

struct VideoFileWriter::Impl {
  std::string path, tmp;
  Shape image;
  VideoFileOptions options;
  AosrVideoWriteFn write = nullptr;
  AosrVideoCloseFn close = nullptr;
  void* handle = nullptr;
  bool closed = false;
  cv::Mat gray, bgr;  // reused frame by frame: a fresh 512² frame would cost a page fault per 4 KB
  std::vector<unsigned char> lut;     // grey level of t = k / 65535 (Write)
  std::vector<unsigned char> levels;  // one image row's grey levels
};

namespace {

// The displayed fraction S(t) in [0, 1] of t in [0, 1].
double VideoStretch(const VideoFileOptions& o, double t) {
  switch (o.stretch) {
    case Stretch::kAsinh:
      return std::asinh(t / o.asinh_softening) / std::asinh(1.0 / o.asinh_softening);
    case Stretch::kLog:
      return std::log10(1.0 + 1000.0 * t) / std::log10(1001.0);
    default:
      return t;
  }
}

}  // namespace

VideoFileWriter::VideoFileWriter(const std::string& path, Shape image, const VideoFileOptions& options)
    : impl_(std::make_unique<Impl>()) {
  constexpr const char* kFn = "VideoFileWriter";
  std::string why;
  if (!options.IsValid(&why)) throw InvalidArgument(std::string(kFn) + ": options." + why);
  CheckArgument(image.rows > 0 && image.cols > 0 && image.rows * options.zoom <= 8192 && image.cols * options.zoom <= 8192,
                kFn, "image shape x zoom", ToString(image) + " x " + std::to_string(options.zoom), "1..8192 pixels a side");
  namespace fs = std::filesystem;
  const fs::path p(path);
  std::error_code ec;
  const fs::path dir = p.parent_path().empty() ? fs::path(".") : p.parent_path();
  if (!fs::is_directory(dir, ec)) throw IoError(path, "its folder does not exist");
  static int counter = 0;
  impl_->path = path;
  impl_->tmp = (dir / (p.stem().string() + ".tmp-" + std::to_string(::getpid()) + "-" + std::to_string(counter++) +
                       p.extension().string()))
                   .string();
  impl_->image = image;
  impl_->options = options;
  impl_->lut.resize(65536);
  for (std::size_t k = 0; k < impl_->lut.size(); ++k)
    impl_->lut[k] = static_cast<unsigned char>(std::lround(255.0 * VideoStretch(options, double(k) / 65535.0)));
  std::string error;
  auto open = reinterpret_cast<AosrVideoOpenFn>(MediaPluginSymbol("aosr_video_open", &error));
  impl_->write = reinterpret_cast<AosrVideoWriteFn>(MediaPluginSymbol("aosr_video_write", &error));
  impl_->close = reinterpret_cast<AosrVideoCloseFn>(MediaPluginSymbol("aosr_video_close", &error));
  if (!open || !impl_->write || !impl_->close) throw IoError(path, "video files are unavailable: " + error);
  char message[512] = {0};
  impl_->handle = open(impl_->tmp.c_str(), options.codec.c_str(), options.fps, int(image.cols * options.zoom),
                       int(image.rows * options.zoom), message, sizeof message);
  if (!impl_->handle) {
    fs::remove(impl_->tmp, ec);
    throw IoError(path, message);
  }
}

VideoFileWriter::~VideoFileWriter() {
  if (impl_ && !impl_->closed) {
    if (impl_->handle) impl_->close(impl_->handle);
    std::error_code ec;
    std::filesystem::remove(impl_->tmp, ec);
  }
}

void VideoFileWriter::Write(const Image& image, const std::string& label) {
  constexpr const char* kFn = "VideoFileWriter::Write";
  CheckArgument(!impl_->closed, kFn, "writer", "closed", "an open writer");
  CheckArgument(ShapeOf(image) == impl_->image, kFn, "image", ToString(ShapeOf(image)),
                "the video's shape " + ToString(impl_->image));
  const VideoFileOptions& o = impl_->options;
  const int z = o.zoom, rows = int(image.rows()) * z, cols = int(image.cols()) * z;
  cv::Mat& gray = impl_->gray;
  gray.create(rows, cols, CV_8UC1);
  // The grey level of a value v is lround(255 S(t)), t = clamp((v − black) / (white − black), 0, 1), S the
  // stretch: read from a table of S on 65536 steps of t, made once per writer (an asinh or a log per pixel cost
  // ~10 ms per 512² frame; a binary search over the 255 level thresholds, its mispredicted branches as much). A
  // value within 1/131070 of a level's threshold in t may show one level off. NaN shows black.
  const std::vector<unsigned char>& lut = impl_->lut;
  const double scale = double(lut.size() - 1) / (o.white - o.black);
  std::vector<unsigned char>& levels = impl_->levels;
  levels.resize(std::size_t(image.cols()));
  for (int y = 0; y < int(image.rows()); ++y) {
    for (Index x = 0; x < image.cols(); ++x) {
      const double v = image(y, x);
      const double i = std::clamp((v - o.black) * scale, 0.0, double(lut.size() - 1));
      levels[std::size_t(x)] = std::isnan(v) ? 0 : lut[std::size_t(i + 0.5)];
    }
    for (int zy = 0; zy < z; ++zy) {
      unsigned char* row = gray.ptr<unsigned char>(y * z + zy);
      for (int x = 0; x < cols; ++x) row[x] = levels[std::size_t(x / z)];
    }
  }
  cv::Mat& bgr = impl_->bgr;
  cv::cvtColor(gray, bgr, cv::COLOR_GRAY2BGR);
  if (!label.empty()) {
    // A dark box under the text keeps it legible on a bright scene.
    const double scale = std::max(0.35, std::min(1.0, cols / 640.0));
    int baseline = 0;
    const cv::Size ts = cv::getTextSize(label, cv::FONT_HERSHEY_SIMPLEX, scale, 1, &baseline);
    cv::rectangle(bgr, cv::Rect(0, 0, std::min(cols, ts.width + 8), std::min(rows, ts.height + baseline + 8)),
                  cv::Scalar(0, 0, 0), cv::FILLED);
    cv::putText(bgr, label, cv::Point(4, ts.height + 4), cv::FONT_HERSHEY_SIMPLEX, scale, cv::Scalar(80, 255, 255), 1,
                cv::LINE_AA);
  }
  char message[512] = {0};
  if (!impl_->write(impl_->handle, bgr.ptr<unsigned char>(0), message, sizeof message))
    throw IoError(impl_->path, message);
  ++frames_;
}

void VideoFileWriter::Close() {
  if (impl_->closed) return;
  impl_->close(impl_->handle);
  impl_->handle = nullptr;
  impl_->closed = true;
  std::error_code ec;
  std::filesystem::rename(impl_->tmp, impl_->path, ec);
  if (ec) {
    std::filesystem::remove(impl_->tmp, ec);
    throw IoError(impl_->path, "cannot rename the finished video onto it: " + ec.message());
  }
}

}  // namespace aosr
