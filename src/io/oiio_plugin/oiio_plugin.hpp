// The OpenImageIO side of PNG/TIFF I/O (image_io.cpp), as a plugin loaded on first use.
//
// OpenImageIO 2.4 on Debian pulls in ~260 shared libraries (OpenEXR, FFmpeg, GDCM, LibRaw, ...). Linked into
// a program, the dynamic loader maps and relocates all of them before main(): 0.4-0.9 s on this project's
// 2-core machine, paid by every `aosr` command, test executable and `import aosr`, although only PNG/TIFF
// reading and writing use OpenImageIO. So the io layer does not link it: image_io.cpp dlopen()s
// libaosr_oiio.so (this interface, src/io/oiio_plugin/oiio_plugin.cpp, linked with OpenImageIO) the first
// time an image file is read or written, and the cost is paid only then. A C interface (plain structs, error
// text into a caller's buffer) keeps C++ exceptions and OIIO types out of the boundary.
//
// Where the plugin is looked up, first found wins: $AOSR_OIIO_PLUGIN; libaosr_oiio.so in the folder of the
// binary that holds the io code (the aosr engine, a test, the Python module), then in that folder's
// ../lib/aosr/; finally the build tree's copy (its absolute path, compiled in).
#pragma once

#include <cstddef>

extern "C" {

struct AosrOiioSpec {
  int width = 0, height = 0, depth = 0, channels = 0;
  int deep = 0;            // 1: a deep image
  int alpha_channel = -1;  // as OIIO::ImageSpec
  int z_channel = -1;
};

// Pixel types of the buffers.
enum AosrOiioType { kAosrOiioUint8 = 0, kAosrOiioUint16 = 1, kAosrOiioFloat = 2 };

// Writes a width x height image of `channels` interleaved channels of `type` to `path` as `format` ("png",
// "tiff"); `png_compression` 0..9 is zlib's level for PNG (-1: OpenImageIO's default, 6). Returns 1 on success;
// 0 with a message in error[error_size] otherwise. Entry point "aosr_oiio_write2" (the "2": the level was added;
// a stale plugin without it is refused by name, not called with the wrong arguments).
typedef int (*AosrOiioWriteFn)(const char* format, const char* path, int width, int height, int channels,
                               int type, const void* pixels, int png_compression, char* error,
                               std::size_t error_size);
// Opens `path` for reading and fills *spec. Returns a handle, or null with a message in error.
typedef void* (*AosrOiioOpenFn)(const char* path, AosrOiioSpec* spec, char* error, std::size_t error_size);
// Reads every channel of the opened image as `type` into buffer (width x height x channels values). 1 on
// success.
typedef int (*AosrOiioReadFn)(void* handle, int type, void* buffer, char* error, std::size_t error_size);
// Closes and frees a handle (null is allowed).
typedef void (*AosrOiioCloseFn)(void* handle);

// Video files through OpenCV's VideoWriter (io/video_file.hpp), in this plugin for the same reason: OpenCV's
// videoio pulls in FFmpeg. Opens `path` (the container from its extension) for width x height colour frames at
// `fps` with the four-character codec `fourcc`; returns a handle, or null with a message in error.
typedef void* (*AosrVideoOpenFn)(const char* path, const char* fourcc, double fps, int width, int height, char* error,
                                 std::size_t error_size);
// Appends one frame of width x height x 3 bytes (B, G, R interleaved, rows top to bottom). 1 on success.
typedef int (*AosrVideoWriteFn)(void* handle, const unsigned char* bgr, char* error, std::size_t error_size);
// Finishes the file and frees the handle (null is allowed).
typedef void (*AosrVideoCloseFn)(void* handle);

}  // extern "C"
