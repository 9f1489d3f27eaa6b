// What only the compiled pipeline can check fails before any computation, naming the field.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include "aosr/core/fft.hpp"
#include "aosr/core/memory.hpp"
#include "aosr/io/config.hpp"
#include "aosr/scene/pipeline.hpp"
#include "support/testing.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

using ::testing::HasSubstr;

nlohmann::json WithActuators(const std::string& telescope, int count) {
  nlohmann::json frames = nlohmann::json::array();
  for (int i = 0; i < 2; ++i) frames.push_back({{"actuators_nm", std::vector<double>(count, 10.0 * i)}});
  return {{"name", "t"},
          {"telescope", telescope},
          {"frames", 2},
          {"r", telescope == "paper-bench" ? 4 : 2},
          {"offsets", {{"type", "design"}, {"frames", frames}}},
          {"detector", {{"frame_px", 16}, {"noise", "none"}}},
          {"objects", nlohmann::json::array({{{"type", "usaf"}}})}};
}

TEST(ScenePipelineErrors, ActuatorCountMustMatchTheDm) {
  const std::uint64_t ffts = FftExecutionCount();
  const std::string m = test::ErrorOf([] { ScenePipeline(ParseScene(WithActuators("paper-8m", 7), "s.json")); });
  EXPECT_THAT(m, HasSubstr("s.json: offsets.frames[0].actuators_nm has 7 values"));
  EXPECT_THAT(m, HasSubstr("one per active actuator"));
  EXPECT_EQ(FftExecutionCount(), ffts) << "nothing was computed";
}

TEST(ScenePipelineErrors, AScenePastTheMemoryLimitIsRefusedBeforeAnythingIsBuilt) {
  // Every field is within its own range (and r·frame_px within the parser's 16384); together they ask for
  // 1024 frames of 4096² at r = 4.
  nlohmann::json j = WithActuators("paper-8m", 0);
  j["frames"] = 1024;
  j["r"] = 4;
  j["offsets"] = {{"type", "raster"}};
  j["detector"]["frame_px"] = 4096;
  const std::uint64_t ffts = FftExecutionCount();
  const std::string m = test::ErrorOf<ResourceError>([&] { ScenePipeline(ParseScene(j, "bomb.json")); });
  EXPECT_THAT(m, HasSubstr("bomb.json: simulating 1024 frames of 4096x4096 at r = 4 (HR 16384x16384"));
  EXPECT_THAT(m, HasSubstr("TiB of memory (estimate), more than the limit of"));
  EXPECT_EQ(FftExecutionCount(), ffts) << "nothing was computed";
}

TEST(ScenePipelineErrors, TheMemoryLimitCanBeLowered) {
  nlohmann::json j = WithActuators("paper-8m", 0);
  j["offsets"] = {{"type", "raster"}};
  SetMemoryLimitBytes(1024.0 * 1024);  // 1 MiB: less than this small scene's PSF work
  const std::string m = test::ErrorOf<ResourceError>([&] { ScenePipeline(ParseScene(j, "small.json")); });
  SetMemoryLimitBytes(0);
  EXPECT_THAT(m, HasSubstr("more than the limit of 1 MiB (set for this run)"));
  EXPECT_NO_THROW(ScenePipeline(ParseScene(j, "small.json")));
}

TEST(ScenePipelineErrors, ActuatorsNeedADm) {
  nlohmann::json j = WithActuators("paper-8m", 3);
  nlohmann::json inline_telescope = ReadJsonFile(DataDirectory() + "/telescopes/paper-8m.json");
  inline_telescope.erase("ao");
  inline_telescope.erase("atmosphere");
  j["telescope"] = inline_telescope;
  EXPECT_THAT(test::ErrorOf([&] { ScenePipeline(ParseScene(j, "s.json")); }), HasSubstr("need a telescope with an \"ao.dm\" section"));
}

TEST(ScenePipelineErrors, ExposureOpdNeedsTheMirrorForCommands) {
  const SceneSpec s = ParseScene(WithActuators("paper-8m", 3), "s.json");
  EXPECT_THAT(test::ErrorOf([&] { ExposureOpd(s, s.offsets.frames[1], Image(), nullptr); }),
              HasSubstr("actuator commands need the deformable mirror"));
}

}  // namespace
}  // namespace aosr
