// Fuzz target: design files (scene_spec.hpp LoadDesignFile), then each offset written back with
// DmOffsetToJson and serialised (the round trip a manifest makes).
#include <cstdint>
#include <string>

#include "aosr/scene/scene_spec.hpp"
#include "fuzz_common.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string path = aosr::fuzz::WriteScratch("design.json", data, size);
  aosr::fuzz::ExpectAosrErrors([&] {
    for (const aosr::DmOffset& offset : aosr::LoadDesignFile(path)) (void)aosr::DmOffsetToJson(offset).dump();
  });
  return 0;
}
