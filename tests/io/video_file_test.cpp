// Video files (io/video_file.hpp) read back through OpenCV's VideoCapture: the frame count and size (zoom
// included), the stretch's grey levels (linear and asinh, with fixed black and white levels), the label's dark box,
// and the atomic write (a writer destroyed without Close leaves no file and keeps an existing one).
#include "aosr/io/video_file.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <opencv2/core.hpp>
#include <opencv2/videoio.hpp>
#include <string>
#include <vector>

#include "temp_dir.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

using testing_io::ReadBytes;
using testing_io::TempDir;
using testing_io::WriteBytes;

// The frames OpenCV reads back (BGR, 8 bits); empty when it cannot open the file.
std::vector<cv::Mat> ReadVideoBack(const std::string& path) {
  std::vector<cv::Mat> frames;
  cv::VideoCapture cap(path);
  if (!cap.isOpened()) return frames;
  cv::Mat f;
  while (cap.read(f) && !f.empty()) frames.push_back(f.clone());
  return frames;
}

// The mean grey level of a block of a read-back frame (JPEG rounds single pixels).
double VideoBlockMean(const cv::Mat& bgr, int y0, int x0, int size) {
  return cv::mean(bgr(cv::Rect(x0, y0, size, size)))[0];
}

TEST(VideoFileTest, FramesReadBackWithTheirCountSizeAndLevels) {
  TempDir dir;
  const std::string path = dir.File("movie.avi");
  VideoFileOptions o;
  o.stretch = Stretch::kLinear;
  o.black = 0.0;
  o.white = 1.0;
  o.fps = 25;
  {
    VideoFileWriter w(path, {48, 64}, o);
    for (int k = 0; k < 5; ++k) w.Write(Image::Constant(48, 64, 0.25 * k), "t = " + std::to_string(k));
    EXPECT_EQ(w.frames(), 5);
    w.Close();
  }
  EXPECT_EQ(dir.List(), std::vector<std::string>{"movie.avi"});  // the temporary file was renamed
  const std::vector<cv::Mat> frames = ReadVideoBack(path);
  ASSERT_EQ(frames.size(), 5u) << "OpenCV read back " << frames.size() << " frames of " << path;
  for (int k = 0; k < 5; ++k) {
    EXPECT_EQ(frames[std::size_t(k)].rows, 48);
    EXPECT_EQ(frames[std::size_t(k)].cols, 64);
    // Linear stretch with fixed levels: 0.25 k maps to 255 x 0.25 k (4 levels of JPEG's error).
    EXPECT_NEAR(VideoBlockMean(frames[std::size_t(k)], 32, 40, 8), 255.0 * 0.25 * k, 4.0) << "frame " << k;
  }
  // The label sits on a black box at the top left, even on a white frame.
  EXPECT_LT(VideoBlockMean(frames[4], 0, 0, 3), 40.0);
}

TEST(VideoFileTest, AsinhStretchAndZoom) {
  TempDir dir;
  VideoFileOptions o;  // asinh, softening 0.05, black 0, white 1
  o.zoom = 2;
  const std::string path = dir.File("asinh.avi");
  {
    VideoFileWriter w(path, {24, 32}, o);
    w.Write(Image::Constant(24, 32, 0.1), "");
    w.Write(Image::Constant(24, 32, 0.1), "");
    w.Close();
  }
  const std::vector<cv::Mat> frames = ReadVideoBack(path);
  ASSERT_EQ(frames.size(), 2u);
  EXPECT_EQ(frames[0].rows, 48);
  EXPECT_EQ(frames[0].cols, 64);
  // asinh(0.1 / 0.05) / asinh(1 / 0.05) = 0.391: far above the linear 0.1 (what makes faint structure visible).
  EXPECT_NEAR(VideoBlockMean(frames[1], 20, 28, 8), 255.0 * std::asinh(2.0) / std::asinh(20.0), 4.0);
}

TEST(VideoFileTest, AWriterNotClosedLeavesNoFileAndKeepsAnExistingOne) {
  TempDir dir;
  const std::string fresh = dir.File("fresh.avi"), existing = dir.File("old.avi");
  WriteBytes(existing, "old bytes");
  {
    VideoFileWriter a(fresh, {16, 16});
    VideoFileWriter b(existing, {16, 16});
    a.Write(Image::Zero(16, 16), "x");
    b.Write(Image::Zero(16, 16), "x");
  }  // destroyed without Close (an error in the caller)
  EXPECT_EQ(dir.List(), std::vector<std::string>{"old.avi"});
  EXPECT_EQ(ReadBytes(existing), "old bytes");
}

}  // namespace AOSR_TEST_NS
}  // namespace aosr
