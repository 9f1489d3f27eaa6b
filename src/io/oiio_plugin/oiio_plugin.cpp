// libaosr_oiio.so: PNG/TIFF through OpenImageIO behind the C interface of oiio_plugin.hpp (which says why it
// is a plugin). Every entry point catches everything: no exception crosses the C boundary.
#include "oiio_plugin.hpp"

#include <OpenImageIO/imageio.h>

#include <opencv2/core.hpp>
#include <opencv2/videoio.hpp>

#include <cstring>
#include <memory>
#include <string>

namespace {

void SetError(char* error, std::size_t size, const std::string& message) {
  if (!error || size == 0) return;
  std::strncpy(error, message.c_str(), size - 1);
  error[size - 1] = '\0';
}

std::string OiioError(const std::string& fallback) {
  std::string e = OIIO::geterror();
  return e.empty() ? fallback : e;
}

OIIO::TypeDesc TypeOf(int type) {
  return type == kAosrOiioUint8    ? OIIO::TypeDesc::UINT8
         : type == kAosrOiioUint16 ? OIIO::TypeDesc::UINT16
                                   : OIIO::TypeDesc::FLOAT;
}

}  // namespace

extern "C" {

__attribute__((visibility("default"))) int aosr_oiio_write2(const char* format, const char* path, int width,
                                                            int height, int channels, int type,
                                                            const void* pixels, int png_compression, char* error,
                                                            std::size_t error_size) {
  try {
    // Created by format name: the (temporary) file's name need not end in the format's extension.
    auto out = OIIO::ImageOutput::create(format);
    if (!out)
      return SetError(error, error_size, OiioError(std::string("no OpenImageIO writer for ") + format)), 0;
    OIIO::ImageSpec spec(width, height, channels, TypeOf(type));
    if (png_compression >= 0 && std::string(format) == "png") spec.attribute("png:compressionLevel", png_compression);
    if (!out->open(path, spec))
      return SetError(error, error_size, "cannot open for writing: " + out->geterror()), 0;
    if (!out->write_image(TypeOf(type), pixels))
      return SetError(error, error_size, "cannot write pixels: " + out->geterror()), 0;
    if (!out->close()) return SetError(error, error_size, "cannot close: " + out->geterror()), 0;
    return 1;
  } catch (const std::exception& e) {
    SetError(error, error_size, std::string("OpenImageIO: ") + e.what());
  } catch (...) {
    SetError(error, error_size, "OpenImageIO: unknown exception");
  }
  return 0;
}

__attribute__((visibility("default"))) void* aosr_oiio_open(const char* path, AosrOiioSpec* spec, char* error,
                                                            std::size_t error_size) {
  try {
    auto in = OIIO::ImageInput::open(path);
    if (!in)
      return SetError(error, error_size, "cannot open as an image: " + OiioError("unknown format")), nullptr;
    const OIIO::ImageSpec& s = in->spec();
    spec->width = s.width;
    spec->height = s.height;
    spec->depth = s.depth;
    spec->channels = s.nchannels;
    spec->deep = s.deep ? 1 : 0;
    spec->alpha_channel = s.alpha_channel;
    spec->z_channel = s.z_channel;
    return in.release();
  } catch (const std::exception& e) {
    SetError(error, error_size, std::string("OpenImageIO: ") + e.what());
  } catch (...) {
    SetError(error, error_size, "OpenImageIO: unknown exception");
  }
  return nullptr;
}

__attribute__((visibility("default"))) int aosr_oiio_read(void* handle, int type, void* buffer, char* error,
                                                          std::size_t error_size) {
  try {
    auto* in = static_cast<OIIO::ImageInput*>(handle);
    if (!in->read_image(0, 0, 0, in->spec().nchannels, TypeOf(type), buffer))
      return SetError(error, error_size, "cannot read pixels: " + in->geterror()), 0;
    return 1;
  } catch (const std::exception& e) {
    SetError(error, error_size, std::string("OpenImageIO: ") + e.what());
  } catch (...) {
    SetError(error, error_size, "OpenImageIO: unknown exception");
  }
  return 0;
}

__attribute__((visibility("default"))) void aosr_oiio_close(void* handle) {
  if (!handle) return;
  std::unique_ptr<OIIO::ImageInput> in(static_cast<OIIO::ImageInput*>(handle));
  try {
    in->close();
  } catch (...) {
  }
}

}  // extern "C"

namespace {
struct AosrVideo {
  cv::VideoWriter writer;
  int width = 0, height = 0;
};
}  // namespace

extern "C" {

__attribute__((visibility("default"))) void* aosr_video_open(const char* path, const char* fourcc, double fps, int width,
                                                             int height, char* error, std::size_t error_size) {
  try {
    if (!fourcc || std::strlen(fourcc) != 4) {
      SetError(error, error_size, "the codec must be four characters (e.g. MJPG)");
      return nullptr;
    }
    auto v = std::make_unique<AosrVideo>();
    v->width = width;
    v->height = height;
    const int code = cv::VideoWriter::fourcc(fourcc[0], fourcc[1], fourcc[2], fourcc[3]);
    if (!v->writer.open(path, code, fps, cv::Size(width, height), true) || !v->writer.isOpened()) {
      SetError(error, error_size, std::string("OpenCV's VideoWriter cannot write codec ") + fourcc +
                                      " to this file (its extension chooses the container; MJPG in .avi is built in)");
      return nullptr;
    }
    return v.release();
  } catch (const std::exception& e) {
    SetError(error, error_size, e.what());
  } catch (...) {
    SetError(error, error_size, "unknown error opening the video");
  }
  return nullptr;
}

__attribute__((visibility("default"))) int aosr_video_write(void* handle, const unsigned char* bgr, char* error,
                                                            std::size_t error_size) {
  try {
    auto* v = static_cast<AosrVideo*>(handle);
    if (!v || !bgr) {
      SetError(error, error_size, "no video or no frame");
      return 0;
    }
    const cv::Mat frame(v->height, v->width, CV_8UC3, const_cast<unsigned char*>(bgr));
    v->writer.write(frame);
    return 1;
  } catch (const std::exception& e) {
    SetError(error, error_size, e.what());
  } catch (...) {
    SetError(error, error_size, "unknown error writing a video frame");
  }
  return 0;
}

__attribute__((visibility("default"))) void aosr_video_close(void* handle) {
  std::unique_ptr<AosrVideo> v(static_cast<AosrVideo*>(handle));
  try {
    if (v) v->writer.release();
  } catch (...) {
  }
}

}  // extern "C"
