// Registration from the data on the paper's system (paper-sim-r2/-r4: 8 m telescope, K band, camera pixel
// λ/D, the analytic long-exposure AO PSF, a USAF target, Gaussian noise σ = 1 % of the brightest noiseless
// pixel), simulated by the scene pipeline with a DM that applies offsets other than the commanded ones:
//   * a DM gain error: every raster shift ×1.1 (±0.275 instead of ±0.25 camera px);
//   * a jitter per frame: the commanded shift plus N(0, 0.05²) camera px per axis (fixed seed).
// The dataset records the commanded offsets and the reconstructor models them (the analytic-AO PSFs of the
// commanded offsets); `--offsets estimate` (ProblemFromDataset, DatasetOffsets::kEstimate) must recover the
// applied ones to ≤ 0.02 camera px RMS after removing the common shift the data cannot see (the anchor keeps
// the commanded mean; a jitter moves the applied mean), and the Tikhonov reconstruction with them must be
// within 0.1 dB of the one with the applied offsets' PSFs under the same anchor (moved by that common shift:
// otherwise the unaligned PSNR scores the unobservable mean jitter, 0.2 dB at r = 2), and within 0.1 dB of
// the applied offsets' own after the global alignment (metrics.hpp).
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "aosr/core/metrics.hpp"
#include "aosr/scene/dataset_memory.hpp"
#include "aosr/scene/pipeline.hpp"
#include "aosr/scene/scene_spec.hpp"
#include "aosr/solvers/dataset_problem.hpp"
#include "aosr/solvers/reconstruct.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

using Shifts = std::vector<std::pair<double, double>>;  // camera px

nlohmann::json PaperScene(int r, const Shifts& shifts, bool noise) {
  nlohmann::json frames = nlohmann::json::array();
  for (auto [dy, dx] : shifts) frames.push_back({{"shift_px", {dy, dx}}});
  nlohmann::json j = {
      {"name", "registration-physics"},
      {"seed", 2024},
      {"telescope", "paper-8m"},
      {"frames", int(shifts.size())},
      {"r", r},
      {"ao", {{"mode", "analytic"}}},
      {"offsets", {{"type", "design"}, {"frames", frames}}},
      {"objects", {{{"type", "usaf"}, {"fill", 0.9}, {"first_group", -2}, {"last_group", 1}, {"flux", {{"peak_e", 1000}}}}}},
      {"detector", {{"frame_px", 64}, {"saturation", false}}}};
  if (noise) {
    j["detector"]["noise"] = "peak-fraction";
    j["detector"]["peak_noise_fraction"] = 0.01;
  } else {
    j["detector"]["noise"] = "none";
  }
  return j;
}

const Shifts kRaster = {{-0.25, -0.25}, {-0.25, 0.25}, {0.25, -0.25}, {0.25, 0.25}};

void Check(int r, const Shifts& applied, const char* what) {
  SCOPED_TRACE(std::string(what) + ", r = " + std::to_string(r));
  const SceneSpec applied_scene = ParseScene(PaperScene(r, applied, true), "<applied>");
  const SceneSpec commanded_scene = ParseScene(PaperScene(r, kRaster, false), "<commanded>");
  const Simulation sim = ScenePipeline(applied_scene).Run();
  Dataset d = DatasetFromSimulation(applied_scene, sim);
  const Image truth = *d.truth;
  // What the observer knows: the commanded offsets and the PSFs they would give.
  d.offsets = commanded_scene.offsets.frames;
  DatasetProblemOptions est;
  est.offsets = DatasetOffsets::kEstimate;
  est.model_psfs = ScenePipeline(commanded_scene).ComputePsfs(nullptr, nullptr, nullptr);
  const DatasetProblem dp = ProblemFromDataset(d, est);
  ASSERT_TRUE(dp.registration.has_value());
  const RegistrationResult& reg = *dp.registration;
  double my = 0, mx = 0;
  const int n = int(applied.size());
  for (int i = 0; i < n; ++i) {
    my += (reg.estimated[i].dy / r - applied[i].first) / n;
    mx += (reg.estimated[i].dx / r - applied[i].second) / n;
  }
  double s = 0, s0 = 0;
  for (int i = 0; i < n; ++i) {
    s += std::pow(reg.estimated[i].dy / r - applied[i].first - my, 2) + std::pow(reg.estimated[i].dx / r - applied[i].second - mx, 2);
    s0 += std::pow(kRaster[i].first - applied[i].first, 2) + std::pow(kRaster[i].second - applied[i].second, 2);
  }
  const double rms = std::sqrt(s / (2 * n)), rms0 = std::sqrt(s0 / (2 * n));
  // Tikhonov (GCV) with the applied offsets' PSFs (the dataset's own), the estimated ones, the commanded ones.
  DatasetProblemOptions exact_o, cmd_o;
  cmd_o.model_psfs = est.model_psfs;
  ReconstructOptions ro;
  const ReconstructionProblem exact = ProblemFromDataset(d, exact_o).problem;
  const ReconstructionProblem exact_anchored = ShiftProblemFrames(exact, std::vector<FrameOffset>(n, {-my * r, -mx * r}));
  const Image x_exact = Reconstruct(exact, ro).image, x_est = Reconstruct(dp.problem, ro).image;
  const double p_exact = Psnr(truth, Reconstruct(exact_anchored, ro).image);
  const double p_est = Psnr(truth, x_est);
  const double a_exact = CompareImagesAligned(truth, x_exact).aligned.psnr;
  const double a_est = CompareImagesAligned(truth, x_est).aligned.psnr;
  const double p_cmd = Psnr(truth, Reconstruct(ProblemFromDataset(d, cmd_o).problem, ro).image);
  std::printf("%s, r = %d: commanded offsets off by %.4f camera px RMS, estimated by %.4f (%d rounds); Tikhonov "
              "PSNR with the applied offsets (same anchor) %.2f dB, estimated %.2f, commanded %.2f; aligned: applied "
              "%.2f, estimated %.2f (common shift %.4f, %.4f camera px)\n",
              what, r, rms0, rms, reg.rounds, p_exact, p_est, p_cmd, a_exact, a_est, my, mx);
  EXPECT_LE(rms, 0.02);
  EXPECT_NEAR(p_est, p_exact, 0.1);
  EXPECT_NEAR(a_est, a_exact, 0.1);
  EXPECT_GT(p_est, p_cmd);
}

TEST(RegistrationPhysics, DmGainErrorOnThePaperSystem) {
  Shifts applied;
  for (auto [dy, dx] : kRaster) applied.push_back({1.1 * dy, 1.1 * dx});
  Check(2, applied, "DM gain 1.1");
  Check(4, applied, "DM gain 1.1");
}

TEST(RegistrationPhysics, JitterPerFrameOnThePaperSystem) {
  std::mt19937_64 rng(23);
  std::normal_distribution<double> n01;
  Shifts applied;
  for (auto [dy, dx] : kRaster) applied.push_back({dy + 0.05 * n01(rng), dx + 0.05 * n01(rng)});
  Check(2, applied, "jitter 0.05 camera px RMS");
  Check(4, applied, "jitter 0.05 camera px RMS");
}

}  // namespace
}  // namespace aosr
