// A small, fast scene for the dataset tests (write -> load round trips): paper-8m optics without turbulence,
// 32-px frames, r = 2, N = 2 on the tip/tilt raster, no noise, gain 2 and bias 100 (so ADU != electrons),
// the demo object plus two catalogue stars (so the manifest carries a star list).
#pragma once

#include <fstream>
#include <nlohmann/json.hpp>
#include <string>

#include "aosr/scene/dataset.hpp"
#include "aosr/scene/pipeline.hpp"
#include "aosr/scene/scene_spec.hpp"

namespace aosr::test {

inline nlohmann::json SmallDatasetScene() {
  return {{"name", "dataset-test"},
          {"telescope", "paper-8m"},
          {"frames", 2},
          {"r", 2},
          {"seed", 7},
          {"ao", {{"mode", "none"}}},
          {"offsets", {{"type", "raster"}}},
          {"detector",
           {{"frame_px", 32}, {"noise", "none"}, {"saturation", false}, {"gain_e_per_adu", 2.0}, {"bias_adu", 100.0}}},
          {"objects",
           nlohmann::json::array(
               {{{"type", "demo"}, {"flux", {{"peak_e", 500.0}}}},
                {{"type", "stars"},
                 {"catalogue", nlohmann::json::array({{{"y_px", 10.25}, {"x_px", 20.5}, {"flux_e", 3000.0}},
                                                      {{"y_px", 22.0}, {"x_px", 7.75}, {"flux_e", 1500.0}}})}}})}};
}

inline void WriteJson(const std::string& path, const nlohmann::json& j) {
  std::ofstream out(path);
  out << j.dump(2) << "\n";
}

// Parses, compiles and runs `scene_json` saved as `scene_path`, and writes the dataset into `dir`.
struct WrittenSimulation {
  SceneSpec scene;
  Simulation sim;
};

inline WrittenSimulation SimulateInto(const std::string& scene_path, const nlohmann::json& scene_json,
                                      const std::string& dir) {
  WriteJson(scene_path, scene_json);
  WrittenSimulation w{LoadScene(scene_path), {}};
  const ScenePipeline pipeline(w.scene);
  w.sim = pipeline.Run();
  WriteSimulation(dir, w.scene, pipeline, w.sim);
  return w;
}

}  // namespace aosr::test
