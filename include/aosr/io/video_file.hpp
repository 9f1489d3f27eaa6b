// Video files of a sequence of images (a super-resolved movie, solvers/video_stream.hpp), written through
// OpenCV's VideoWriter in the media plugin (src/io/oiio_plugin/: OpenCV's videoio links FFmpeg, so it is loaded
// only when a video is written, as OpenImageIO is for PNG/TIFF).
//
// Codec. The container follows the file's extension; the codec is a four-character code. Debian 12's OpenCV 4.6
// writes MJPG (motion JPEG) into .avi with its own encoder, without FFmpeg: the default, and the one the tests
// check. Others (e.g. "mp4v" in .mp4) go through FFmpeg where the build has them; a codec the build lacks is an
// IoError when the file is opened.
//
// Frames. Each image is mapped to 8 bits by ApplyStretch (image_io.hpp) with the writer's fixed black and white
// levels (the same for every frame, so brightness changes in the scene stay visible) and the chosen stretch
// (asinh or log: the display astronomers expect for a high dynamic range), scaled by an integer factor with
// nearest-neighbour pixels, and a label (the time stamp) is drawn at the top left. Frames of another shape are an
// InvalidArgument.
//
// Atomic: frames go to a temporary file beside the destination (same extension, so the container is the same),
// renamed onto it by Close(); a writer destroyed without Close() removes it and leaves any existing file alone.
#pragma once

#include <memory>
#include <string>

#include "aosr/core/image.hpp"
#include "aosr/io/image_io.hpp"

namespace aosr {

struct VideoFileOptions {
  double fps = 10.0;           // frames per second of playback, > 0
  std::string codec = "MJPG";  // four characters
  Stretch stretch = Stretch::kAsinh;
  double asinh_softening = 0.05;  // in units of hi - lo, > 0
  double black = 0.0, white = 1.0;  // the levels mapped to 0 and 255 (white > black, finite)
  int zoom = 1;                     // integer enlargement, 1..16
  bool IsValid(std::string* why) const;
};

class VideoFileWriter {
 public:
  // Opens the temporary file for rows x cols images (each side <= 8192 after the zoom). IoError naming `path`
  // when the plugin or the codec is unavailable or the folder is not writable; InvalidArgument for bad options.
  VideoFileWriter(const std::string& path, Shape image, const VideoFileOptions& options = {});
  ~VideoFileWriter();
  VideoFileWriter(const VideoFileWriter&) = delete;
  VideoFileWriter& operator=(const VideoFileWriter&) = delete;

  // Appends one frame (the image's shape, finite where shown: NaN shows black) with `label` drawn on it.
  void Write(const Image& image, const std::string& label);
  // Finishes the file and renames it onto the destination. Writing after Close is an InvalidArgument.
  void Close();
  int frames() const { return frames_; }

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  int frames_ = 0;
};

}  // namespace aosr
