// Simulation benchmark: for every shipped scene (data/scenes/*.json, or the scene files given), the time to
// simulate it end to end and, stage by stage, the measured time beside the pipeline's cost model
// (src/scene/pipeline.cpp). The first run of a scene also pays for FFTW planning (FFTW_MEASURE) of its
// shapes; the table reports the second run (plans cached), and the first run's total for reference.
//
// Usage: build/bench/simulate_bench [scene.json ...]
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <map>
#include <string>
#include <thread>
#include <vector>

#include "aosr/core/memory.hpp"
#include "aosr/core/fft.hpp"
#include "aosr/scene/pipeline.hpp"
#include "aosr/scene/telescope.hpp"

namespace {

// Which measured bucket (Simulation::timings) each planned stage's estimate belongs to.
std::string Bucket(const std::string& stage) {
  if (stage == "static-aberrations" || stage == "dm-offsets" || stage == "ao-loop" || stage == "psf") return "psf";
  if (stage == "point-sources") return "convolution";
  return stage;
}

}  // namespace

int main(int argc, char** argv) {
  aosr::TuneAllocatorForLargeArrays();  // as the CLI does (memory.hpp)
  namespace fs = std::filesystem;
  std::vector<std::string> scenes;
  for (int i = 1; i < argc; ++i) scenes.push_back(argv[i]);
  if (scenes.empty()) {
    for (const auto& e : fs::directory_iterator(fs::path(aosr::DataDirectory()) / "scenes"))
      if (e.path().extension() == ".json") scenes.push_back(e.path().string());
    std::sort(scenes.begin(), scenes.end());
  }
  std::printf("# build/bench/simulate_bench | hardware threads %u | one thread, FFTW_MEASURE plans cached after run 1\n",
              std::thread::hardware_concurrency());
  std::printf("%-22s %-18s %11s %11s %9s\n", "scene", "stage", "model [s]", "measured [s]", "ratio");
  for (const std::string& path : scenes) {
    const aosr::ScenePipeline pipeline(aosr::LoadScene(path));
    const std::string name = pipeline.scene().name;
    const auto t0 = std::chrono::steady_clock::now();
    const aosr::Simulation first = pipeline.Run();
    const double first_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    const aosr::Simulation sim = pipeline.Run();
    std::map<std::string, double> model;
    double model_total = 0;
    for (const aosr::PipelineStage& s : pipeline.stages()) {
      model[Bucket(s.name)] += s.estimated_s;
      model_total += s.estimated_s;
    }
    for (const aosr::StageTiming& t : sim.timings) {
      const std::string bucket = t.name == "ao-loop+psf" ? "psf" : t.name == "point-sources" ? "convolution" : t.name;
      const double m = model.count(bucket) ? model[bucket] : 0.0;
      std::printf("%-22s %-18s %11.4f %11.4f %9.2f\n", name.c_str(), t.name.c_str(), m, t.seconds,
                  m > 0 ? t.seconds / m : 0.0);
    }
    std::printf("%-22s %-18s %11.4f %11.4f %9.2f   (first run %.3f s; %llu FFTs, %d PSFs, %d loop steps)\n", name.c_str(),
                "TOTAL", model_total, sim.seconds, sim.seconds / model_total, first_s,
                static_cast<unsigned long long>(sim.counters.fft_executions), sim.counters.psfs_computed,
                sim.counters.loop_steps);
  }
  return 0;
}
