// Fuzz target: FITS images, cubes and headers (fits.hpp ReadFits, ReadFitsImage), with every header keyword
// read back through the typed accessors.
#include <cstdint>
#include <string>

#include "aosr/io/fits.hpp"
#include "fuzz_common.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string path = aosr::fuzz::WriteScratch("input.fits", data, size);
  aosr::fuzz::ExpectAosrErrors([&] {
    const aosr::FitsData fits = aosr::ReadFits(path);
    for (const aosr::FitsKeyword& k : fits.header.keywords()) {
      (void)fits.header.Has(k.name);
      aosr::fuzz::ExpectAosrErrors([&] { (void)fits.header.GetDouble(k.name); });
      aosr::fuzz::ExpectAosrErrors([&] { (void)fits.header.GetString(k.name); });
    }
    double sum = 0.0;
    for (const aosr::Image& plane : fits.planes) sum += plane.size() > 0 ? plane(0, 0) : 0.0;
    (void)sum;
  });
  aosr::fuzz::ExpectAosrErrors([&] { (void)aosr::ReadFitsImage(path); });
  return 0;
}
