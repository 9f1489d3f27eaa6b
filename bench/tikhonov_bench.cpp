// Tikhonov phase profile: where the Fourier path's time goes, per phase, against its FFT floor, on the shipped
// scenes at several frame counts (issue 22, item 3).
//
// For each configuration (scene, N) the scene is simulated in-process with `frames` overridden, written and
// read back as reconstruct_bench does, and turned into a ReconstructionProblem by ProblemFromDataset. Its
// frames are then solved with uniform weights (the Fourier path; the dataset's own weights are uniform on the
// paper scenes) and the phases of ReconstructTikhonov are timed one by one through the library's internal
// engine (solvers/tikhonov_internal.hpp):
//   prior      PriorSymbolImage: |Γ̂|² on the HR spectrum
//   system     FourierSystem's constructor (the bins whose prior vanishes, the mirror-pair flags: A(u) is gathered
//              from the OTFs by each pass, and the rank floor, λ₀ and ranks are made on first use)
//   data       SetData: N LR FFTs and the per-bin data vectors
//   spectral   the λ search's per-bin decomposition (the first EvaluateSpectral; with the floor and λ₀)
//   search     the rest of the GCV search (sums over the decomposition, one pass per λ tried)
//   solve      Solve at the chosen λ (per-bin solves + one c2r HR FFT)
//   summary    FinishSummary (data misfit through the forward model; the prior norm comes from the solve)
// and end to end: ReconstructTikhonov with λ fixed (at GCV's λ) and with the GCV search, each the minimum of
// `--repeats` runs (default 5; the machine is shared), on 1 thread and on 2 threads, with the images compared
// bit for bit, and the 2-thread speed-up in wall time (1- and 2-thread runs alternated, the ratio of the minima). floor = FFTs executed x one out-of-place r2c FFTW transform of the HR grid (FFTW_PATIENT's plan from the shipped wisdom, minimum
// of 15 batches), the same unit as bench/results/reconstruct.md. One-thread times (and the floor) are process CPU
// time, two-thread times wall time: the machine is shared.
//
// With --weighted the dataset's own weights are kept (the CG path, with GCV chosen on the unweighted frames by
// Reconstruct); only the end-to-end rows are timed then.
//
// With --profile K only the end-to-end runs are made, K times each (λ fixed, then GCV) on one thread, and nothing
// is timed: a workload for `perf record -g`.
//
// Usage: build/bench/tikhonov_bench [--scene NAME] [--frames N,...] [--repeats K] [--weighted] [--profile K]
//   default: demo, paper-sim-r2, paper-sim-r4, paper-sim-r8 at N = 2, 4, 8, 16 (r8: 2, 4, 8).
#include <fftw3.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <ctime>
#include <cstdio>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "fft_floor.hpp"
#include "aosr/core/memory.hpp"
#include "aosr/core/fft.hpp"
#include "aosr/core/parallel.hpp"
#include "aosr/io/config.hpp"
#include "aosr/scene/dataset.hpp"
#include "aosr/scene/pipeline.hpp"
#include "aosr/scene/scene_spec.hpp"
#include "aosr/solvers/dataset_problem.hpp"
#include "aosr/solvers/reconstruct.hpp"
#include "aosr/solvers/tikhonov.hpp"
#include "solvers/tikhonov_internal.hpp"

namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;
using aosr::Image;
using aosr::ImageStack;

double Since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

// Process CPU seconds: on this shared 2-core machine wall time of a 1-thread run moves with the other jobs' load,
// its CPU time much less. (2-thread runs are timed by the wall clock.)
double CpuNow() {
  timespec t;
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
  return double(t.tv_sec) + 1e-9 * double(t.tv_nsec);
}

// The FFT floor: bench/fft_floor.hpp, on process CPU time.
double FftSeconds(int rows, int cols) { return aosr::bench::R2cFloorSeconds(rows, cols, CpuNow); }

// The minimum over `repeats` runs of f: CPU time on one thread, wall time on more.
template <class F>
double MinTime(int repeats, F&& f, bool wall = false) {
  double best = 1e300;
  for (int k = 0; k < repeats; ++k) {
    const auto t0 = Clock::now();
    const double c0 = CpuNow();
    f();
    best = std::min(best, wall ? Since(t0) : CpuNow() - c0);
  }
  return best;
}

void Run(const std::string& scene, int frames, int repeats, bool weighted, int profile) {
  const std::string path = (fs::path(aosr::DataDirectory()) / "scenes" / scene).string();
  nlohmann::json j = aosr::ReadJsonFile(path);
  j["frames"] = frames;
  const aosr::ScenePipeline pipeline(aosr::ParseScene(j, path));
  const aosr::Simulation sim = pipeline.Run();
  const fs::path dir = fs::temp_directory_path() / ("aosr_tikhonov_bench_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  aosr::WriteSimulation(dir.string(), pipeline.scene(), pipeline, sim, &j);
  const aosr::Dataset d = aosr::LoadDataset(dir.string());
  fs::remove_all(dir);
  const aosr::DatasetProblem dp = aosr::ProblemFromDataset(d);
  aosr::ReconstructionProblem p = dp.problem;
  if (!weighted) p.weights.clear();
  const aosr::MultiFrameModel& model = *p.model;
  const int r = model.r();
  const aosr::Shape hr = model.hr_shape();
  const double fft_s = FftSeconds(int(hr.rows), int(hr.cols));
  namespace ti = aosr::tikhonov_internal;

  aosr::TikhonovOptions gcv;
  gcv.lambda_rule = aosr::TikhonovLambdaRule::kGcv;
  aosr::ReconstructOptions ro;
  ro.method = aosr::ReconstructionMethod::kTikhonov;
  aosr::Reconstruct(p, ro);  // warm-up: FFT plans
  const double lambda = aosr::Reconstruct(p, ro).regularisation;
  aosr::ReconstructOptions rf = ro;
  rf.tikhonov.lambda_rule = aosr::TikhonovLambdaRule::kFixed;
  rf.tikhonov.lambda = lambda;
  if (profile > 0) {  // --profile K: only the end-to-end runs, K each on one thread, for `perf record`
    for (int k = 0; k < profile; ++k) aosr::Reconstruct(p, rf);
    for (int k = 0; k < profile; ++k) aosr::Reconstruct(p, ro);
    return;
  }

  auto end_to_end = [&](const aosr::ReconstructOptions& o, int threads, Image* image, std::uint64_t* ffts) {
    aosr::SetDefaultThreads(threads);
    const std::uint64_t f0 = aosr::FftExecutionCount();
    const double s = MinTime(repeats, [&] { *image = aosr::Reconstruct(p, o).image; }, threads > 1);
    *ffts = (aosr::FftExecutionCount() - f0) / std::uint64_t(repeats);
    aosr::SetDefaultThreads(1);
    return s;
  };
  Image fixed1, fixed2, gcv1, gcv2;
  std::uint64_t ffts_fixed = 0, ffts_gcv = 0, dummy = 0;
  const double t_fixed = end_to_end(rf, 1, &fixed1, &ffts_fixed);
  const double t_gcv = end_to_end(ro, 1, &gcv1, &ffts_gcv);
  const double t_fixed2 = end_to_end(rf, 2, &fixed2, &dummy);
  const double t_gcv2 = end_to_end(ro, 2, &gcv2, &dummy);
  const bool same = (fixed1 == fixed2).all() && (gcv1 == gcv2).all();
  // The 2-thread speed-up in wall time: 1-thread and 2-thread runs alternated (the load moves between them
  // less than between two series), the ratio of the minima.
  auto speedup = [&](const aosr::ReconstructOptions& o) {
    double one = 1e300, two = 1e300;
    for (int k = 0; k < repeats; ++k)
      for (int threads : {1, 2}) {
        aosr::SetDefaultThreads(threads);
        const auto t0 = Clock::now();
        aosr::Reconstruct(p, o);
        (threads == 1 ? one : two) = std::min(threads == 1 ? one : two, Since(t0));
      }
    aosr::SetDefaultThreads(1);
    return one / two;
  };
  const double speedup_fixed = speedup(rf), speedup_gcv = speedup(ro);

  std::printf("| %s | %lld | %d | %d | %s | %.2f | %.2f | %.1f | %.2f | %.2f | %.1f | %.2f / %.2f | %.2f / %.2f | %s |",
              scene.c_str(), (long long)hr.rows, r, frames, weighted ? "weighted (CG)" : "uniform", fft_s * 1e3,
              t_fixed * 1e3, t_fixed / (double(ffts_fixed) * fft_s), double(ffts_fixed), t_gcv * 1e3,
              t_gcv / (double(ffts_gcv) * fft_s), t_fixed2 * 1e3, t_gcv2 * 1e3, speedup_fixed, speedup_gcv,
              same ? "yes" : "NO");
  if (weighted) {
    std::printf(" | | | | | | | |\n");
    std::fflush(stdout);
    return;
  }
  // The phases, on one thread.
  const ImageStack clean = p.CleanFrames();
  Image symbol;
  std::unique_ptr<ti::FourierSystem> sys;
  const double t_prior = MinTime(repeats, [&] { symbol = ti::PriorSymbolImage(gcv, hr); });
  const double t_system = MinTime(repeats, [&] {
    sys = std::make_unique<ti::FourierSystem>(model, symbol, gcv.rank_tolerance, gcv.bin_solver);
  });
  const double t_data = MinTime(repeats, [&] { sys->SetData(clean); });
  const double t_spectral = MinTime(repeats, [&] {
    sys->SetData(clean);
    sys->EvaluateSpectral(sys->lambda0());
  }) - t_data;
  double score = 0;
  int evaluations = 0;
  const double t_search = MinTime(repeats, [&] { ti::GcvSearch(*sys, gcv, &score, &evaluations); });
  Image x;
  ti::FourierSystem::Fit fit;
  const double t_solve = MinTime(repeats, [&] { x = sys->Solve(lambda, &fit); });
  aosr::TikhonovSummary summary;
  const double t_summary = MinTime(repeats, [&] { ti::FinishSummary(p, x, lambda, gcv, &summary, &fit.prior2); });
  const double unit = double(ffts_fixed) * fft_s;
  std::printf(" %.2f | %.2f | %.2f | %.2f | %.2f (%d) | %.2f | %.2f |\n", t_prior / unit, t_system / unit,
              t_data / unit, t_spectral / unit, t_search / unit, evaluations, t_solve / unit, t_summary / unit);
  std::fflush(stdout);
}

}  // namespace

int main(int argc, char** argv) {
  aosr::TuneAllocatorForLargeArrays();  // as the CLI does (memory.hpp)
  std::vector<std::string> scenes;
  std::vector<int> frames;
  int repeats = 5;
  bool weighted = false;
  int profile = 0;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--scene" && i + 1 < argc) {
      std::string s = argv[++i];
      if (s.size() < 5 || s.substr(s.size() - 5) != ".json") s += ".json";
      scenes.push_back(s);
    } else if (a == "--frames" && i + 1 < argc) {
      std::stringstream ss(argv[++i]);
      for (std::string t; std::getline(ss, t, ',');) frames.push_back(std::stoi(t));
    } else if (a == "--repeats" && i + 1 < argc) {
      repeats = std::max(1, std::stoi(argv[++i]));
    } else if (a == "--profile" && i + 1 < argc) {
      profile = std::max(1, std::stoi(argv[++i]));
    } else if (a == "--weighted") {
      weighted = true;
    } else {
      std::fprintf(stderr, "usage: tikhonov_bench [--scene NAME] [--frames N,...] [--repeats K] [--weighted] [--profile K]\n");
      return 2;
    }
  }
  if (scenes.empty()) scenes = {"demo.json", "paper-sim-r2.json", "paper-sim-r4.json", "paper-sim-r8.json"};
  std::printf(
      "| scene | HR | r | N | weights | one HR r2c [ms] | λ fixed [ms] | ×floor | FFTs | GCV [ms] | ×floor | 2 threads "
      "fixed / GCV [ms] | 2 threads ÷ 1 (wall) fixed / GCV | bit-identical | prior | system | data | spectral | search (λs) | solve | summary |\n"
      "|---|---:|---:|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|---|---:|---:|---:|---:|---:|---:|---:|\n");
  for (const std::string& s : scenes) {
    std::vector<int> ns = frames;
    if (ns.empty()) ns = s.find("r8") != std::string::npos ? std::vector<int>{2, 4, 8} : std::vector<int>{2, 4, 8, 16};
    for (int n : ns) Run(s, n, repeats, weighted, profile);
  }
  std::printf("\nPhase columns (prior .. summary) in units of the λ-fixed run's FFT floor (FFTs x one HR r2c).\n");
  return 0;
}
