#include "aosr/io/image_io.hpp"

#include <dlfcn.h>
#include <link.h>
#include <limits.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <mutex>

#include "aosr/core/error.hpp"
#include "aosr/core/memory.hpp"
#include "aosr/io/atomic_file.hpp"
#include "aosr/io/fits.hpp"
#include "oiio_plugin/oiio_plugin.hpp"

namespace aosr {

// The most channels an image file may have to be read (ReadImage, ReadRgbImage).
constexpr int kMaxImageChannels = 16;
namespace {

std::string LowerExtension(const std::string& path) {
  std::string ext = std::filesystem::path(path).extension().string();
  for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return ext;
}

bool LooksLikeFits(const std::string& path) {
  const std::string ext = LowerExtension(path);
  if (ext == ".fits" || ext == ".fit" || ext == ".fts") return true;
  std::ifstream in(path, std::ios::binary);
  char magic[9] = {0};
  in.read(magic, sizeof magic);
  return in.gcount() == 9 && std::string(magic, 9) == "SIMPLE  =";
}

// Percentile p (in %) of the values, linear interpolation between order statistics: the value of sorted rank
// p/100 · (n − 1), found with two selections instead of a sort (O(n): a 512² quick-look's levels cost ~2 ms
// instead of ~15; the result is the same number). `values` is reordered.
double Percentile(std::vector<double>& values, double p) {
  const double rank = p / 100.0 * static_cast<double>(values.size() - 1);
  const size_t i = static_cast<size_t>(std::floor(rank));
  const auto at = values.begin() + static_cast<std::ptrdiff_t>(std::min(i, values.size() - 1));
  std::nth_element(values.begin(), at, values.end());
  if (i + 1 >= values.size()) return *at;
  const double frac = rank - static_cast<double>(i);
  const double next = *std::min_element(at + 1, values.end());  // rank i + 1: the least of the larger part
  return *at + frac * (next - *at);
}

// Rounds t in [0, 1] to the nearest of 0..max_value.
template <typename T>
std::vector<T> Quantise(const Image& t, double max_value) {
  std::vector<T> out(static_cast<size_t>(t.size()));
  for (Index i = 0; i < t.size(); ++i) out[i] = static_cast<T>(std::lround(t.data()[i] * max_value));
  return out;
}

// ---- OpenImageIO, loaded on first use (oiio_plugin/oiio_plugin.hpp says why and where it is looked up) ----

struct OiioPlugin {
  AosrOiioWriteFn write = nullptr;
  AosrOiioOpenFn open = nullptr;
  AosrOiioReadFn read = nullptr;
  AosrOiioCloseFn close = nullptr;
  void* handle = nullptr;  // the dlopen handle (for the video entry points, video_file.cpp)
  std::string error;       // why it could not be loaded
};

std::string FolderOf(const std::string& file) {
  std::error_code ec;
  const std::filesystem::path p = std::filesystem::weakly_canonical(file, ec);
  return (ec ? std::filesystem::path(file) : p).parent_path().string();
}

const OiioPlugin& Oiio() {
  static OiioPlugin plugin;
  static std::once_flag once;
  std::call_once(once, [] {
    std::vector<std::string> candidates;
    if (const char* env = std::getenv("AOSR_OIIO_PLUGIN"); env && *env) candidates.push_back(env);
    Dl_info info;
    link_map* map = nullptr;
    if (dladdr1(reinterpret_cast<void*>(&FolderOf), &info, reinterpret_cast<void**>(&map), RTLD_DL_LINKMAP) != 0 &&
        map != nullptr) {
      // In a shared object (the Python module) its own path; in the program itself (its link map has no name:
      // dladdr would give argv[0], which the launcher's exec leaves as the launcher's) /proc/self/exe.
      std::string self = map->l_name ? map->l_name : "";
      if (self.empty()) {
        char exe[PATH_MAX];
        const ssize_t n = readlink("/proc/self/exe", exe, sizeof exe - 1);
        if (n > 0) self.assign(exe, std::size_t(n));
      }
      const std::string dir = FolderOf(self);
      candidates.push_back(dir + "/libaosr_oiio.so");
      candidates.push_back(dir + "/../lib/aosr/libaosr_oiio.so");
    }
    candidates.push_back(AOSR_OIIO_PLUGIN_BUILD_PATH);
    std::string tried;
    for (const std::string& c : candidates) {
      std::error_code ec;
      if (!std::filesystem::exists(c, ec)) {
        tried += (tried.empty() ? "" : ", ") + c;
        continue;
      }
      void* handle = dlopen(c.c_str(), RTLD_NOW | RTLD_LOCAL);
      if (!handle) {
        const char* e = dlerror();
        plugin.error = "cannot load " + c + ": " + (e ? e : "dlopen failed");
        return;
      }
      plugin.handle = handle;
      plugin.write = reinterpret_cast<AosrOiioWriteFn>(dlsym(handle, "aosr_oiio_write2"));
      plugin.open = reinterpret_cast<AosrOiioOpenFn>(dlsym(handle, "aosr_oiio_open"));
      plugin.read = reinterpret_cast<AosrOiioReadFn>(dlsym(handle, "aosr_oiio_read"));
      plugin.close = reinterpret_cast<AosrOiioCloseFn>(dlsym(handle, "aosr_oiio_close"));
      if (!plugin.write || !plugin.open || !plugin.read || !plugin.close) {
        plugin.error = c + " lacks the aosr_oiio_* entry points (a stale build?)";
        plugin.write = nullptr;
      }
      return;  // never dlclose'd: OpenImageIO keeps global state
    }
    plugin.error = "libaosr_oiio.so (aosr's OpenImageIO plugin) not found; looked for " + tried +
                   " (set AOSR_OIIO_PLUGIN to its path)";
  });
  return plugin;
}

}  // namespace

// The plugin's entry point `name` (video_file.cpp), or null with the reason in *error.
void* MediaPluginSymbol(const char* name, std::string* error) {
  const OiioPlugin& p = Oiio();
  if (!p.handle) {
    *error = p.error;
    return nullptr;
  }
  void* f = dlsym(p.handle, name);
  if (!f) *error = std::string("the media plugin lacks ") + name + " (a stale build?)";
  return f;
}

namespace {

// The plugin, or IoError naming `path` and why PNG/TIFF I/O is unavailable.
const OiioPlugin& OiioFor(const std::string& path) {
  const OiioPlugin& p = Oiio();
  if (!p.write) throw IoError(path, "PNG/TIFF I/O is unavailable: " + p.error);
  return p;
}

// An opened input image, closed when it goes out of scope.
class OiioInput {
 public:
  explicit OiioInput(const std::string& path) : plugin_(OiioFor(path)), path_(path) {
    handle_ = plugin_.open(path.c_str(), &spec_, error_, sizeof error_);
    if (!handle_) throw IoError(path, error_);
  }
  ~OiioInput() { plugin_.close(handle_); }
  OiioInput(const OiioInput&) = delete;
  OiioInput& operator=(const OiioInput&) = delete;
  const AosrOiioSpec& spec() const { return spec_; }
  void Read(int type, void* buffer) {
    if (!plugin_.read(handle_, type, buffer, error_, sizeof error_)) throw IoError(path_, error_);
  }

 private:
  const OiioPlugin& plugin_;
  std::string path_;
  AosrOiioSpec spec_;
  void* handle_ = nullptr;
  char error_[1024] = {0};
};

// Writes through the plugin (to `tmp`, the atomic write's temporary file); IoError naming `path`.
void OiioWrite(const std::string& path, const std::string& tmp, const std::string& format, int width, int height,
               int channels, int type, const void* pixels, int png_compression = -1) {
  const OiioPlugin& p = OiioFor(path);
  char error[1024] = {0};
  if (!p.write(format.c_str(), tmp.c_str(), width, height, channels, type, pixels, png_compression, error,
               sizeof error))
    throw IoError(path, error);
}

}  // namespace

bool ViewOptions::IsValid(std::string* why) const {
  auto fail = [why](const std::string& message) {
    if (why != nullptr) *why = message;
    return false;
  };
  if (stretch != Stretch::kLinear && stretch != Stretch::kLog && stretch != Stretch::kAsinh) {
    return fail("stretch = " + std::to_string(static_cast<int>(stretch)) + " is not a Stretch value");
  }
  if (!(low_percentile >= 0.0 && low_percentile < high_percentile && high_percentile <= 100.0)) {
    return fail("low_percentile = " + ToString(low_percentile) +
                ", high_percentile = " + ToString(high_percentile) + "; need 0 <= low < high <= 100");
  }
  if (bits != 8 && bits != 16 && bits != 32)
    return fail("bits = " + std::to_string(bits) + "; need 8, 16 or 32");
  if (png_compression < -1 || png_compression > 9)
    return fail("png_compression = " + std::to_string(png_compression) + "; need -1 (the default) or 0..9");
  if (!(std::isfinite(asinh_softening) && asinh_softening > 0.0)) {
    return fail("asinh_softening = " + ToString(asinh_softening) + "; need a finite value > 0");
  }
  return true;
}

Image ApplyStretch(const Image& img, const ViewOptions& options) {
  std::string why;
  if (!options.IsValid(&why)) throw InvalidArgument("ApplyStretch: invalid ViewOptions: " + why);
  std::vector<double> finite;
  finite.reserve(static_cast<size_t>(img.size()));
  for (Index i = 0; i < img.size(); ++i) {
    if (std::isfinite(img.data()[i])) finite.push_back(img.data()[i]);
  }
  Image out = Image::Zero(img.rows(), img.cols());
  if (finite.empty()) return out;
  const double lo = Percentile(finite, options.low_percentile);
  const double hi = Percentile(finite, options.high_percentile);
  if (!(hi > lo)) return out;

  const double s = options.asinh_softening;
  const double log_norm = std::log10(1001.0), asinh_norm = std::asinh(1.0 / s);
  for (Index i = 0; i < img.size(); ++i) {
    const double v = img.data()[i];
    if (std::isnan(v)) continue;                                  // NaN -> 0.
    const double t = std::clamp((v - lo) / (hi - lo), 0.0, 1.0);  // +-Inf clamp to 1 / 0.
    switch (options.stretch) {
      case Stretch::kLinear:
        out.data()[i] = t;
        break;
      case Stretch::kLog:
        out.data()[i] = std::log10(1.0 + 1000.0 * t) / log_norm;
        break;
      case Stretch::kAsinh:
        out.data()[i] = std::asinh(t / s) / asinh_norm;
        break;
    }
  }
  return out;
}

void WriteViewImage(const std::string& path, const Image& img, const ViewOptions& options) {
  std::string why;
  if (!options.IsValid(&why)) throw InvalidArgument("WriteViewImage: invalid ViewOptions: " + why);
  const std::string ext = LowerExtension(path);
  std::string format;
  if (ext == ".png") {
    format = "png";
  } else if (ext == ".tif" || ext == ".tiff") {
    format = "tiff";
  } else {
    throw InvalidArgument("WriteViewImage", "file extension", "'" + ext + "' (" + path + ")",
                          ".png, .tif or .tiff");
  }
  CheckArgument(format == "tiff" || options.bits != 32, "WriteViewImage", "bits", options.bits,
                "8 or 16 for PNG (32 = float is TIFF only)");
  CheckArgument(img.size() > 0, "WriteViewImage", "image shape", ToString(ShapeOf(img)), "non-empty");

  const Image t = ApplyStretch(img, options);
  std::vector<std::uint8_t> u8;
  std::vector<std::uint16_t> u16;
  std::vector<float> f32;
  int type;
  const void* pixels = nullptr;
  if (options.bits == 8) {
    u8 = Quantise<std::uint8_t>(t, 255.0);
    type = kAosrOiioUint8;
    pixels = u8.data();
  } else if (options.bits == 16) {
    u16 = Quantise<std::uint16_t>(t, 65535.0);
    type = kAosrOiioUint16;
    pixels = u16.data();
  } else {
    f32.assign(t.data(), t.data() + t.size());
    type = kAosrOiioFloat;
    pixels = f32.data();
  }

  AtomicWrite(path, [&](const std::string& tmp) {
    // Written by format name: the temporary file's name does not end in the format's extension.
    OiioWrite(path, tmp, format, static_cast<int>(img.cols()), static_cast<int>(img.rows()), 1, type, pixels,
              options.png_compression);
  });
}

void WriteRgbImage(const std::string& path, const RgbImage& img) {
  const std::string ext = LowerExtension(path);
  std::string format;
  if (ext == ".png") {
    format = "png";
  } else if (ext == ".tif" || ext == ".tiff") {
    format = "tiff";
  } else {
    throw InvalidArgument("WriteRgbImage", "file extension", "'" + ext + "' (" + path + ")", ".png, .tif or .tiff");
  }
  CheckArgument(img.rows > 0 && img.cols > 0, "WriteRgbImage", "image shape",
                std::to_string(img.rows) + "x" + std::to_string(img.cols), "non-empty");
  CheckArgument(img.rgb.size() == static_cast<size_t>(3 * img.rows * img.cols), "WriteRgbImage", "rgb.size()",
                img.rgb.size(), "3 * rows * cols = " + std::to_string(3 * img.rows * img.cols));
  AtomicWrite(path, [&](const std::string& tmp) {
    OiioWrite(path, tmp, format, static_cast<int>(img.cols), static_cast<int>(img.rows), 3, kAosrOiioUint8,
              img.rgb.data());
  });
}

RgbImage ReadRgbImage(const std::string& path) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) throw IoError(path, "no such file (or not a regular file)");
  OiioInput in(path);
  const AosrOiioSpec& spec = in.spec();
  const int channels = spec.channels;
  if (channels < 1 || spec.width < 1 || spec.height < 1 || spec.depth > 1) throw IoError(path, "empty or volume image");
  if (channels > kMaxImageChannels)
    throw IoError(path, std::to_string(channels) + " channels; at most " + std::to_string(kMaxImageChannels) +
                            " are read (grey, RGB, RGBA and a few extra planes)");
  CheckMemory((1.0 * channels + 3.0) * double(spec.width) * double(spec.height),
              path + ": an image of " + std::to_string(spec.height) + "x" + std::to_string(spec.width) + " pixels");
  std::vector<std::uint8_t> buffer(static_cast<size_t>(spec.width) * spec.height * channels);
  in.Read(kAosrOiioUint8, buffer.data());
  RgbImage img;
  img.rows = spec.height;
  img.cols = spec.width;
  img.rgb.resize(static_cast<size_t>(3 * img.rows * img.cols));
  const bool gray = channels < 3;
  for (Index i = 0; i < img.rows * img.cols; ++i)
    for (int c = 0; c < 3; ++c) img.rgb[size_t(3 * i + c)] = buffer[size_t(i * channels + (gray ? 0 : c))];
  return img;
}

Image ReadImage(const std::string& path) {
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) throw IoError(path, "no such file");
  if (std::filesystem::is_directory(path, ec)) throw IoError(path, "is a directory, not an image file");
  // A device or FIFO (/dev/zero, found by fuzz_calibration_set) never ends: the format probes would read forever.
  if (!std::filesystem::is_regular_file(path, ec)) throw IoError(path, "is not a regular file (a device, FIFO or socket)");
  if (LooksLikeFits(path)) return ReadFitsImage(path);

  OiioInput in(path);
  const AosrOiioSpec& spec = in.spec();
  if (spec.depth > 1)
    throw IoError(path, "volume images (depth " + std::to_string(spec.depth) + ") are not supported");
  if (spec.deep) throw IoError(path, "deep images are not supported");
  const int channels = spec.channels;
  const Index rows = spec.height, cols = spec.width;
  if (channels < 1 || rows < 1 || cols < 1) throw IoError(path, "empty image");
  // A sky image is grey, RGB or RGBA, perhaps with a few extra planes. A header promising hundreds of channels
  // (fuzz_image found a 386-byte TIFF declaring 9 x 46554 pixels of 255 float channels) would make OpenImageIO
  // fill ~430 MB from nothing, for ~20 s, before the colour average below threw nearly all of it away.
  if (channels > kMaxImageChannels)
    throw IoError(path, std::to_string(channels) + " channels; at most " + std::to_string(kMaxImageChannels) +
                            " are read (grey, RGB, RGBA and a few extra planes)");
  CheckMemory((4.0 * channels + 8.0) * double(rows) * double(cols),
              path + ": an image of " + std::to_string(rows) + "x" + std::to_string(cols) + " pixels and " +
                  std::to_string(channels) + " channel(s)");

  std::vector<float> buffer(static_cast<size_t>(rows * cols * channels));
  in.Read(kAosrOiioFloat, buffer.data());

  // Colour channels: all but alpha and depth (z); a lone alpha-like channel is used as it is.
  std::vector<int> colour;
  for (int c = 0; c < channels; ++c) {
    if (c != spec.alpha_channel && c != spec.z_channel) colour.push_back(c);
  }
  if (colour.empty()) colour.push_back(0);

  Image img(rows, cols);
  for (Index i = 0; i < rows * cols; ++i) {
    double sum = 0.0;
    for (int c : colour) sum += buffer[static_cast<size_t>(i * channels + c)];
    img.data()[i] = sum / static_cast<double>(colour.size());
  }
  return img;
}

Image Montage(const std::vector<Image>& tiles, int columns, int gap_px, double gap_value) {
  CheckArgument(!tiles.empty(), "Montage", "tiles", "0 tiles", "at least one tile");
  CheckArgument(columns >= 1, "Montage", "columns", columns, ">= 1");
  CheckArgument(gap_px >= 0, "Montage", "gap_px", gap_px, ">= 0");
  Index cell_rows = 0, cell_cols = 0;
  for (size_t i = 0; i < tiles.size(); ++i) {
    CheckArgument(tiles[i].size() > 0, "Montage", ("tile " + std::to_string(i) + " shape").c_str(),
                  ToString(ShapeOf(tiles[i])), "non-empty");
    cell_rows = std::max(cell_rows, tiles[i].rows());
    cell_cols = std::max(cell_cols, tiles[i].cols());
  }
  const Index n = static_cast<Index>(tiles.size());
  const Index grid_cols = std::min<Index>(columns, n);
  const Index grid_rows = (n + grid_cols - 1) / grid_cols;
  Image out = Image::Constant(grid_rows * cell_rows + (grid_rows - 1) * gap_px,
                              grid_cols * cell_cols + (grid_cols - 1) * gap_px, gap_value);
  for (Index i = 0; i < n; ++i) {
    const Image& tile = tiles[static_cast<size_t>(i)];
    const Index top = (i / grid_cols) * (cell_rows + gap_px) + (cell_rows - tile.rows()) / 2;
    const Index left = (i % grid_cols) * (cell_cols + gap_px) + (cell_cols - tile.cols()) / 2;
    out.block(top, left, tile.rows(), tile.cols()) = tile;
  }
  return out;
}

}  // namespace aosr
