// Invalid sequences, variations and planets fail at parse time with the file, the field path, the value and
// what is allowed (scene_spec.hpp, SequenceSpec, ObjectVariation, planet objects).
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>
#include <string>

#include "aosr/core/error.hpp"
#include "aosr/scene/scene_spec.hpp"
#include "support/testing.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

using aosr::test::ErrorOf;
using ::testing::AllOf;
using ::testing::HasSubstr;
using Json = nlohmann::json;

// Four phases on a 32-pixel frame; frame time 0.25 s.
Json SequenceScene() {
  return Json{{"name", "seq"},
              {"telescope", "paper-8m"},
              {"frames", 4},
              {"r", 2},
              {"detector", {{"frame_px", 32}}},
              {"sequence", {{"frames", 8}}},
              {"objects", Json::array({Json{{"type", "stars"}, {"catalogue", {{{"y_px", 10}, {"x_px", 10}, {"flux_e", 100}}}}}})}};
}

std::string ParseError(const Json& scene) {
  return ErrorOf([&] { ParseScene(scene, "mem.json"); });
}

TEST(SequenceErrors, SequenceSection) {
  Json j = SequenceScene();
  j["sequence"]["frames"] = 3;
  EXPECT_THAT(ParseError(j), AllOf(HasSubstr("mem.json"), HasSubstr("sequence.frames = 3"), HasSubstr("N = 4 phases")));
  j = SequenceScene();
  j["sequence"]["frames"] = 0;
  EXPECT_THAT(ParseError(j), HasSubstr("sequence.frames = 0"));
  j = SequenceScene();
  j["sequence"]["frame_interval_s"] = 0.2;
  EXPECT_THAT(ParseError(j), AllOf(HasSubstr("sequence.frame_interval_s = 0.2"), HasSubstr("frame time"), HasSubstr("0.25")));
  j = SequenceScene();
  j["sequence"]["rate_hz"] = 50;
  EXPECT_THAT(ParseError(j), HasSubstr("rate_hz"));
  j = SequenceScene();
  j["sequence"]["start_s"] = "soon";
  EXPECT_THAT(ParseError(j), HasSubstr("sequence.start_s"));
}

TEST(SequenceErrors, Variation) {
  Json j = SequenceScene();
  j.erase("sequence");
  j["objects"][0]["variation"] = {{"velocity_px_per_s", {1.0, 0.0}}};
  EXPECT_THAT(ParseError(j), AllOf(HasSubstr("objects[0].variation"), HasSubstr("\"sequence\" section")));
  j = SequenceScene();
  j["objects"][0]["variation"] = {{"velocity_px_per_s", {1.0}}};
  EXPECT_THAT(ParseError(j), HasSubstr("velocity_px_per_s"));
  j["objects"][0]["variation"] = {{"spin", 1.0}};
  EXPECT_THAT(ParseError(j), HasSubstr("spin"));
  j["objects"][0]["variation"] = {{"light_curve", {{"kind", "sine"}, {"period_s", 1.0}, {"amplitude", 1.5}}}};
  EXPECT_THAT(ParseError(j), AllOf(HasSubstr("light_curve.amplitude = 1.5"), HasSubstr("1")));
  j["objects"][0]["variation"] = {{"light_curve", {{"kind", "sine"}, {"period_s", 0.0}, {"amplitude", 0.5}}}};
  EXPECT_THAT(ParseError(j), HasSubstr("light_curve.period_s = 0"));
  j["objects"][0]["variation"] = {{"light_curve", {{"kind", "blink"}}}};
  EXPECT_THAT(ParseError(j), HasSubstr("light_curve.kind"));
  j["objects"][0]["variation"] = {{"light_curve", {{"kind", "table"}, {"times_s", {0.0, 1.0}}, {"factors", {1.0}}}}};
  EXPECT_THAT(ParseError(j), AllOf(HasSubstr("light_curve.factors"), HasSubstr("one per time (2)")));
  j["objects"][0]["variation"] = {{"light_curve", {{"kind", "table"}, {"times_s", {0.0, 0.0}}, {"factors", {1.0, 2.0}}}}};
  EXPECT_THAT(ParseError(j), AllOf(HasSubstr("light_curve.times_s"), HasSubstr("increasing")));
  j["objects"][0]["variation"] = {{"light_curve", {{"kind", "table"}, {"times_s", {0.0, 1.0}}, {"factors", {1.0, -2.0}}}}};
  EXPECT_THAT(ParseError(j), HasSubstr("light_curve.factors"));
}

TEST(SequenceErrors, Planet) {
  Json j = SequenceScene();
  j["objects"] = Json::array({Json{{"type", "planet"}}});
  EXPECT_THAT(ParseError(j), HasSubstr("radius_px"));
  j["objects"][0]["radius_px"] = -2.0;
  EXPECT_THAT(ParseError(j), HasSubstr("objects[0].radius_px = -2"));
  j["objects"][0]["radius_px"] = 5.0;
  j["objects"][0]["limb_darkening"] = 1.2;
  EXPECT_THAT(ParseError(j), HasSubstr("limb_darkening = 1.2"));
  j["objects"][0]["limb_darkening"] = 0.5;
  j["objects"][0]["sub_observer_latitude_deg"] = 95;
  EXPECT_THAT(ParseError(j), HasSubstr("sub_observer_latitude_deg = 95"));
  j["objects"][0]["sub_observer_latitude_deg"] = 0;
  j["objects"][0]["texture"] = {{"band_contrast", 1.0}};
  EXPECT_THAT(ParseError(j), HasSubstr("texture.band_contrast = 1"));
  j["objects"][0]["texture"] = {{"stripes", 3}};
  EXPECT_THAT(ParseError(j), HasSubstr("stripes"));
  j["objects"][0]["texture"] = Json::object();
  j["objects"][0]["texture_path"] = "missing.fits";
  EXPECT_THAT(ParseError(j), AllOf(HasSubstr("texture"), HasSubstr("one of texture and texture_path")));
  j["objects"][0].erase("texture");
  EXPECT_THAT(ParseError(j), AllOf(HasSubstr("texture_path"), HasSubstr("missing.fits"), HasSubstr("an existing")));
  j["objects"][0].erase("texture_path");
  j["objects"][0]["rotation_period_s"] = 1e-12;
  EXPECT_THAT(ParseError(j), HasSubstr("rotation_period_s"));
  j["objects"][0]["rotation_period_s"] = 10.0;
  EXPECT_NO_THROW(ParseScene(j, "mem.json"));
}

}  // namespace AOSR_TEST_NS
}  // namespace aosr
