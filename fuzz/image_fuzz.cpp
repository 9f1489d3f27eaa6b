// Fuzz target: PNG/TIFF (and FITS) images (image_io.hpp ReadImage), then one step past reading: the image
// made into a scene object on a small HR grid (image_object.hpp LoadImageObject) with two option sets.
//
// The scratch file's extension follows the input's magic bytes (.png, .tif, .fits, else .img) as a user's
// file would.
#include <cstdint>
#include <cstring>
#include <string>

#include "aosr/io/image_io.hpp"
#include "aosr/scene/image_object.hpp"
#include "fuzz_common.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const char* ext = ".img";
  if (size >= 8 && std::memcmp(data, "\x89PNG", 4) == 0) ext = ".png";
  else if (size >= 4 && (std::memcmp(data, "II*", 4) == 0 || std::memcmp(data, "MM\0*", 4) == 0)) ext = ".tif";
  else if (size >= 6 && std::memcmp(data, "SIMPLE", 6) == 0) ext = ".fits";
  const std::string path = aosr::fuzz::WriteScratch(std::string("input") + ext, data, size);
  aosr::fuzz::ExpectAosrErrors([&] { (void)aosr::ReadImage(path); });
  aosr::fuzz::ExpectAosrErrors([&] { (void)aosr::LoadImageObject(path, {12, 20}); });
  aosr::fuzz::ExpectAosrErrors([&] {
    aosr::ImageObjectOptions options;
    options.fit = aosr::ImageFit::kStretch;
    options.values = aosr::PixelValues::kFluxPerPixel;
    options.background = aosr::ImageBackground::kBorderMedian;
    options.normalisation = aosr::FluxNormalisation::kPeak;
    (void)aosr::LoadImageObject(path, {7, 5}, options);
  });
  return 0;
}
