// Fuzz target: telescope presets (telescope.hpp LoadTelescopePreset), then the cheap derived quantities a
// scene asks of a preset: λ/D and, for a small pupil grid, the pupil amplitude (geometry or mask file).
#include <cstdint>
#include <string>

#include "aosr/scene/telescope.hpp"
#include "fuzz_common.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string path = aosr::fuzz::WriteScratch("telescope.json", data, size);
  aosr::fuzz::ExpectAosrErrors([&] {
    const aosr::TelescopePreset preset = aosr::LoadTelescopePreset(path);
    (void)preset.LambdaOverD();
    if (preset.pupil_px <= 256) (void)preset.PupilAmplitude();
  });
  return 0;
}
