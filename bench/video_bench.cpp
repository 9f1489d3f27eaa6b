// Streaming super-resolution benchmark (issue 34; solvers/video_stream.hpp): how many super-resolved outputs per
// second the linear slot filter makes at 512² (128² frames, r = 4, N = 4), on 1 and 2 threads, beside the FFT
// floor timed in the same run, and how exact those outputs are.
//
// Data: data/scenes/demo.json with r = 4 (128² frames, 512² HR grid, the 4-frame raster), simulated in-process and
// written as a dataset (WriteSimulation), then made into a sequence of M frames (default 200): frame j is the
// noiseless frame of phase j mod 4 (expected.fits) plus fresh Gaussian noise of the simulation's own σ, in ADU,
// with the manifest's `sequence` (slots j mod 4, times 0.02 j s) and the frames file's header (its WCS). The
// stream is read back by LoadDataset and run through DatasetVideo, the path `aosr video` takes (weights 'auto':
// the detector model's background weights, uniform).
//
// Rows (per method and thread count): the filter build (the N impulse solves, once), and per steady-state output
// (every output after the first; each Next() call timed on its own wall clock: it includes the Push of the new frame,
// its check, its LR FFT, the N-term sum, the HR inverse FFT and the new output image) the median, and the best
// mean over batches of 16 consecutive outputs (the least disturbed estimate on a shared machine). outputs/s =
// 1 / median.
//
// The floor, timed in the same run on one thread: FFTW's own plans (bench/fft_floor.hpp: FFTW_PATIENT's choice
// from the shipped wisdom) of one 128² r2c (the new frame) and one 512² c2r (the output); c2r destroys its input,
// so each call first copies the half spectrum back from a pristine copy, and that copy is timed alone and taken
// off. Beside it, aosr's own FftR2CInto(128²) and FftC2RInto(512²) on 1 and 2 threads (what the engine calls), and
// SlotFilter::SetFrame and Output alone (Output = the N-term sum + the HR c2r). All timings: minimum over 15
// batches of the batch mean, except the streaming rows (above).
//
// Exactness: every K-th output (--check, default 25) against the batch Reconstruct of its window built
// independently (ProblemFromDataset of SelectFrames of the window's frames in time order) with what the stream
// fixed once (VideoReconstructor::BatchOptions: Tikhonov's λ, the linear output's κ), max |difference| / peak,
// which must be below 1e-10; for the linear output also against the batch with its own κ search on those frames
// in time order, which differs (docs/video.md: the search's U_min moves with the order of the frames).
//
// TV (--tv OUTPUTS, default 25; 0 skips it): the warm-started stream on 1 thread, 10 ADMM iterations per output
// (RunTv below), its time per output and its PSNR gap to TV run to convergence on the same windows; on the static
// sequence above, and on a moving one (MakeMovingSequence: the simulator's own sequence of the same demo scene with a
// companion crossing at 1 HR px per frame and a star varying by ±80 %), each output there scored against the truth
// at its newest frame.
//
// Usage: build/bench/video_bench [--frames M] [--check K] [--tv OUTPUTS] [--out FILE] [--keep NEW_DIR]
//   --out   also write the Markdown report to FILE (bench/results/video.md)
//   --keep  write the sequence dataset into NEW_DIR (which must not exist) and keep it (seq.json), e.g. to time
//           `aosr video NEW_DIR/seq.json` on the same data
#include <fftw3.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <map>
#include <fstream>
#include <nlohmann/json.hpp>
#include <optional>
#include <random>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "aosr/core/fft.hpp"
#include "aosr/core/memory.hpp"
#include "aosr/core/metrics.hpp"
#include "aosr/core/parallel.hpp"
#include "aosr/io/config.hpp"
#include "aosr/io/fits.hpp"
#include "aosr/scene/dataset.hpp"
#include "aosr/scene/pipeline.hpp"
#include "aosr/scene/scene_spec.hpp"
#include "aosr/scene/telescope.hpp"
#include "aosr/solvers/dataset_problem.hpp"
#include "aosr/solvers/fourier_normal_system.hpp"
#include "aosr/solvers/reconstruct.hpp"
#include "aosr/solvers/video_stream.hpp"
#include "fft_floor.hpp"

namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;
using aosr::Image;
using aosr::ImageStack;
using aosr::Index;

double Since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

std::string Fmt(const char* f, double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, f, v);
  return buf;
}

// Seconds per call of fn: the minimum over 15 batches of the batch mean (batches of about 10 ms).
template <class F>
double BestSeconds(F&& fn) {
  fn();  // warm-up: plans made, pages touched
  const auto t0 = Clock::now();
  fn();
  const double once = std::max(1e-7, Since(t0));
  const int reps = std::max(3, int(0.01 / once));
  double best = 1e300;
  for (int b = 0; b < 15; ++b) {
    const auto a = Clock::now();
    for (int k = 0; k < reps; ++k) fn();
    best = std::min(best, Since(a) / reps);
  }
  return best;
}

// The sequence dataset (top of the file); returns its manifest path.
std::string MakeSequence(const fs::path& dir, int frames) {
  const std::string scene_path = (fs::path(aosr::DataDirectory()) / "scenes" / "demo.json").string();
  nlohmann::json j = aosr::ReadJsonFile(scene_path);
  j["r"] = 4;
  j["frames"] = 4;
  const aosr::ScenePipeline pipeline(aosr::ParseScene(j, scene_path));
  const aosr::Simulation sim = pipeline.Run();
  fs::remove_all(dir);
  aosr::WriteSimulation(dir.string(), pipeline.scene(), pipeline, sim, &j);
  nlohmann::json m = aosr::ReadJsonFile((dir / "manifest.json").string());
  const aosr::FitsData recorded = aosr::ReadFits((dir / "frames.fits").string());
  const ImageStack expected = aosr::ReadFits((dir / "expected.fits").string()).planes;
  const double gain = m["gain_e_per_adu"].get<double>(), bias = m["bias_adu"].get<double>();
  // The simulation's own noise level: the RMS of recorded - expected over its frames, in e-.
  double ss = 0;
  Index count = 0;
  for (std::size_t i = 0; i < expected.size(); ++i) {
    const Image e = (recorded.planes[i].array() - bias) * gain - expected[i].array();
    ss += e.square().sum();
    count += e.size();
  }
  const double sigma = std::sqrt(ss / double(count));
  std::mt19937_64 rng(34);
  std::normal_distribution<double> n01;
  ImageStack seq;
  nlohmann::json slots = nlohmann::json::array(), times = nlohmann::json::array();
  for (int f = 0; f < frames; ++f) {
    Image e = expected[std::size_t(f % 4)];
    for (Index k = 0; k < e.size(); ++k) e.data()[k] += sigma * n01(rng);
    seq.push_back(e / gain + bias);
    slots.push_back(f % 4);
    times.push_back(0.02 * f);
  }
  aosr::WriteFitsCube((dir / "seq_frames.fits").string(), seq, recorded.header, aosr::FitsType::kFloat64);
  m["frames"] = "seq_frames.fits";
  for (const char* k : {"valid", "weights", "expected"}) m.erase(k);
  m["sequence"] = {{"slots", slots}, {"times_s", times}};
  const std::string path = (dir / "seq.json").string();
  std::ofstream(path) << m.dump(1);
  std::fprintf(stderr, "sequence: %d frames of %dx%d, noise sigma %.3g e-\n", frames, int(expected[0].rows()),
               int(expected[0].cols()), sigma);
  return path;
}

// A moving sequence (issue 34 item 1): the demo scene at r = 4 as a simulated `sequence` of `frames` exposures at
// 50 per second with a companion (2e4 e-) crossing the lower part at 12.5 camera px/s (1 HR px per frame) and a
// star varying as 1 + 0.8 sin(2π t / 0.4 s), written into `dir`; returns its folder. The truth at every frame is
// in the dataset (truth_frames).
std::string MakeMovingSequence(const fs::path& dir, int frames) {
  const std::string scene_path = (fs::path(aosr::DataDirectory()) / "scenes" / "demo.json").string();
  nlohmann::json j = aosr::ReadJsonFile(scene_path);
  j["r"] = 4;
  j["frames"] = 4;
  j["detector"]["total_exposure_s"] = 0.08;
  j["sequence"] = {{"frames", frames}, {"frame_interval_s", 0.02}};
  j["objects"].push_back({{"type", "stars"},
                          {"catalogue", {{{"y_px", 112.3}, {"x_px", 20.6}, {"flux_e", 2e4}}}},
                          {"variation", {{"velocity_px_per_s", {0.0, 12.5}}}}});
  j["objects"].push_back({{"type", "stars"},
                          {"catalogue", {{{"y_px", 16.4}, {"x_px", 112.2}, {"flux_e", 1.5e4}}}},
                          {"variation", {{"light_curve", {{"kind", "sine"}, {"period_s", 0.4}, {"amplitude", 0.8}}}}}});
  const aosr::ScenePipeline pipeline(aosr::ParseScene(j, scene_path));
  const aosr::Simulation sim = pipeline.Run();
  fs::remove_all(dir);
  aosr::WriteSimulation(dir.string(), pipeline.scene(), pipeline, sim, &j);
  std::fprintf(stderr, "moving sequence: %d frames, simulated in %.2f s\n", frames, sim.seconds);
  return dir.string();
}

struct StreamRow {
  std::string method;
  int threads = 0, outputs = 0, checked = 0;
  double build_s = 0, median_ms = 0, best_batch_ms = 0, mean_ms = 0, max_dev = 0;
  double max_dev_own = -1, kappa_spread = 0;  // linear: against the batch's own κ search
  std::string paths;
};

StreamRow RunStream(const aosr::Dataset& d, aosr::ReconstructionMethod method, int threads, int check_every) {
  aosr::SetDefaultThreads(threads);
  aosr::VideoOptions vo;
  vo.method = method;
  if (method == aosr::ReconstructionMethod::kTikhonov) {
    vo.reconstruct.tikhonov.lambda_rule = aosr::TikhonovLambdaRule::kFixed;
    vo.reconstruct.tikhonov.lambda = 1e-3;
  }
  aosr::DatasetVideo video(d, vo);
  StreamRow row;
  row.method = aosr::ToString(method);
  row.threads = threads;
  std::vector<double> per;
  int filter = 0, batch = 0;
  while (true) {
    const auto t0 = Clock::now();
    std::optional<aosr::VideoFrame> f = video.Next();
    const double s = Since(t0);
    if (!f) break;
    ++row.outputs;
    (f->path == "slot-filter" ? filter : batch)++;
    if (f->index > 0) per.push_back(s);
    if (check_every > 0 && f->index % check_every == 1) {
      std::vector<int> w = f->frames;
      std::sort(w.begin(), w.end());
      aosr::DatasetProblemOptions po;
      po.method = method;
      const aosr::DatasetProblem dp = aosr::ProblemFromDataset(aosr::SelectFrames(d, w), po);
      // The batch with what the stream fixed once (tikhonov: λ = λ' w̄ of this window; linear: κ).
      const Image ref = aosr::Reconstruct(dp.problem, video.engine().BatchOptions(dp.problem)).image;
      row.max_dev = std::max(row.max_dev, (f->image - ref).abs().maxCoeff() / ref.abs().maxCoeff());
      if (method == aosr::ReconstructionMethod::kLinear) {
        // And the batch with its own κ search on the window's frames in time order (video.md: that search
        // moves with the order of the frames).
        aosr::ReconstructOptions own;
        own.method = method;
        const aosr::Reconstruction b = aosr::Reconstruct(dp.problem, own);
        row.max_dev_own = std::max(row.max_dev_own, (f->image - b.image).abs().maxCoeff() / b.image.abs().maxCoeff());
        const double k = b.regularisation / video.engine().setup().kappa;
        row.kappa_spread = std::max(row.kappa_spread, std::abs(k - 1));
      }
      ++row.checked;
    }
  }
  row.build_s = video.engine().setup().filter_seconds;
  row.paths = std::to_string(filter) + " slot-filter, " + std::to_string(batch) + " batch";
  std::vector<double> sorted = per;
  std::sort(sorted.begin(), sorted.end());
  row.median_ms = sorted.empty() ? 0 : 1e3 * sorted[sorted.size() / 2];
  double sum = 0;
  for (double v : per) sum += v;
  row.mean_ms = per.empty() ? 0 : 1e3 * sum / double(per.size());
  row.best_batch_ms = 1e300;
  for (std::size_t b = 0; b + 16 <= per.size(); b += 16) {
    double s = 0;
    for (std::size_t k = b; k < b + 16; ++k) s += per[k];
    row.best_batch_ms = std::min(row.best_batch_ms, 1e3 * s / 16);
  }
  if (row.best_batch_ms > 1e299) row.best_batch_ms = row.median_ms;
  return row;
}

// TV warm-started (video_stream.hpp): the first window to convergence (Reconstruct's automatic μ, ADMM to its
// tolerance), then each output `iterations` ADMM iterations from the previous one. Per warm output: the median time;
// at a few outputs, PSNR against the truth (cropped by the trustworthy border) of the warm output and of TV run to
// convergence on the same window (BatchOptions: the same μ; 3000 iterations, relative tolerance 1e-6).
struct TvRow {
  std::string sequence;  // "static" or "moving"
  int iterations = 0, outputs = 0;
  int threads = 1;
  bool warm_duals = true;
  double first_s = 0, median_ms = 0, max_gap_db = 0, mean_gap_db = 0;
  std::vector<std::string> checks;
};

// check: score outputs against TV to convergence (the same on any thread count: the outputs are the same bytes).
// converged: the PSNR (and iterations) of TV to convergence per output index, filled on first use and shared by the
// rows of one sequence (the same windows).
TvRow RunTv(const aosr::Dataset& d, int iterations, bool warm_duals, int outputs, int threads, bool check,
            std::map<int, std::pair<double, int>>* converged) {
  aosr::SetDefaultThreads(threads);
  aosr::VideoOptions vo;
  vo.method = aosr::ReconstructionMethod::kTotalVariation;
  vo.tv_iterations = iterations;
  vo.tv_warm_duals = warm_duals;
  aosr::DatasetVideo video(d, vo);
  aosr::MetricOptions m;
  m.crop_px = int(d.trustworthy_border_px) * d.r;
  TvRow row;
  row.iterations = iterations;
  row.threads = threads;
  row.warm_duals = warm_duals;
  std::vector<double> per;
  int checked = 0;
  while (row.outputs < outputs) {
    const auto t0 = Clock::now();
    std::optional<aosr::VideoFrame> f = video.Next();
    const double s = Since(t0);
    if (!f) break;
    ++row.outputs;
    if (f->index == 0) row.first_s = s;
    else per.push_back(s);
    if (check && f->index > 0 && (f->index % 8 == 0 || row.outputs == outputs)) {
      auto cached = converged->find(int(f->index));
      if (cached == converged->end()) {
        const aosr::ReconstructionProblem w = video.engine().WindowProblem();
        aosr::ReconstructOptions o = video.engine().BatchOptions(w);
        o.tv.max_iterations = 3000;
        o.tv.relative_tolerance = 1e-6;
        const aosr::Reconstruction full = aosr::Reconstruct(w, o);
        const int newest = *std::max_element(f->frames.begin(), f->frames.end());
        const aosr::Image& truth = d.truth_frames.empty() ? *d.truth : d.truth_frames[std::size_t(newest)];
        cached = converged
                     ->emplace(int(f->index), std::make_pair(aosr::CompareImages(truth, full.image, m).psnr,
                                                             int(full.summary.iterations)))
                     .first;
      }
      // A moving sequence: the truth at the output's newest frame (what a viewer sees then).
      const int newest = *std::max_element(f->frames.begin(), f->frames.end());
      const aosr::Image& truth = d.truth_frames.empty() ? *d.truth : d.truth_frames[std::size_t(newest)];
      const double warm = aosr::CompareImages(truth, f->image, m).psnr;
      const double conv = cached->second.first;
      row.max_gap_db = std::max(row.max_gap_db, conv - warm);
      row.mean_gap_db += conv - warm;
      ++checked;
      row.checks.push_back("output " + std::to_string(f->index) + ": " + Fmt("%.2f", warm) + " dB warm, " +
                           Fmt("%.2f", conv) + " dB converged (" + std::to_string(cached->second.second) + " it.)");
    }
  }
  if (checked) row.mean_gap_db /= checked;
  std::sort(per.begin(), per.end());
  row.median_ms = per.empty() ? 0 : 1e3 * per[per.size() / 2];
  return row;
}

}  // namespace

int main(int argc, char** argv) {
  aosr::TuneAllocatorForLargeArrays();  // as the CLI does (memory.hpp)
  int frames = 200, check = 25;
  std::string out, keep;
  int tv_outputs = 25;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--frames" && i + 1 < argc) frames = std::atoi(argv[++i]);
    else if (a == "--check" && i + 1 < argc) check = std::atoi(argv[++i]);
    else if (a == "--out" && i + 1 < argc) out = argv[++i];
    else if (a == "--keep" && i + 1 < argc) keep = argv[++i];
    else if (a == "--tv" && i + 1 < argc) tv_outputs = std::atoi(argv[++i]);
    else {
      std::fprintf(stderr, "usage: video_bench [--frames M] [--check K] [--tv OUTPUTS] [--out FILE] [--keep NEW_DIR]\n");
      return 2;
    }
  }
  if (frames < 8) frames = 8;
  if (!keep.empty() && fs::exists(keep)) {
    std::fprintf(stderr, "--keep %s: the folder exists; give a new one\n", keep.c_str());
    return 2;
  }
  const fs::path dir = keep.empty() ? fs::temp_directory_path() / ("aosr_video_bench_" + std::to_string(::getpid()))
                                    : fs::path(keep);
  const std::string manifest = MakeSequence(dir, frames);
  const aosr::Dataset d = aosr::LoadDataset(manifest);
  const Index lr = d.frame.rows, hr = d.hr_frame.rows;

  std::vector<StreamRow> rows;
  for (int t : {1, 2})
    for (auto m : {aosr::ReconstructionMethod::kLinear, aosr::ReconstructionMethod::kTikhonov}) {
      rows.push_back(RunStream(d, m, t, check));
      const StreamRow& r = rows.back();
      std::fprintf(stderr, "%s, %d thread(s): median %.3f ms, best batch %.3f ms, max dev %.2e\n", r.method.c_str(), t,
                   r.median_ms, r.best_batch_ms, r.max_dev);
    }

  std::vector<TvRow> tv_rows;
  if (tv_outputs > 0) {
    const aosr::Dataset moving = aosr::LoadDataset(MakeMovingSequence(dir / "moving", tv_outputs + 3));
    std::map<int, std::pair<double, int>> converged_static, converged_moving;
    struct Config {
      int threads, iterations;
      bool warm_duals;
    };
    // The default (10 iterations from the whole state), the same from x alone (what the stream did before), and
    // a smaller budget; on 2 threads the two budgets.
    for (const Config& c : std::vector<Config>{{1, 10, false}, {1, 10, true}, {1, 7, true}, {2, 10, true}, {2, 7, true}})
      for (const bool is_moving : {false, true}) {
        // The gaps to converged TV do not depend on the thread count: scored on 1 thread only.
        const bool check_gap = c.threads == 1;
        tv_rows.push_back(is_moving ? RunTv(moving, c.iterations, c.warm_duals, tv_outputs, c.threads, check_gap,
                                            &converged_moving)
                                    : RunTv(d, c.iterations, c.warm_duals, std::min(tv_outputs, frames - 3), c.threads,
                                            check_gap, &converged_static));
        TvRow& r = tv_rows.back();
        r.sequence = is_moving ? "moving" : "static";
        std::fprintf(stderr, "tv %s, %d iterations from %s, %d thread(s): median %.1f ms, mean/max gap %.2f/%.2f dB\n",
                     r.sequence.c_str(), c.iterations, c.warm_duals ? "the state" : "x", c.threads, r.median_ms,
                     r.mean_gap_db, r.max_gap_db);
      }
  }

  // ---- The floor and the parts ----
  aosr::SetDefaultThreads(1);
  bool wisdom_lr = false, wisdom_hr = false;
  double fftw_r2c_lr = 0, fftw_c2r_hr = 0, copy_hr = 0;
  {
    aosr::bench::FloorPlans p(static_cast<int>(lr), static_cast<int>(lr));
    wisdom_lr = p.from_wisdom;
    fftw_r2c_lr = BestSeconds([&] { fftw_execute(p.r2c); });
  }
  {
    aosr::bench::FloorPlans p(static_cast<int>(hr), static_cast<int>(hr));
    wisdom_hr = p.from_wisdom;
    fftw_execute(p.r2c);
    const std::size_t nh = std::size_t(hr) * std::size_t(hr / 2 + 1);
    fftw_complex* pristine = fftw_alloc_complex(nh);
    std::memcpy(pristine, p.X, sizeof(fftw_complex) * nh);
    copy_hr = BestSeconds([&] { std::memcpy(p.X, pristine, sizeof(fftw_complex) * nh); });
    fftw_c2r_hr = BestSeconds([&] {
                    std::memcpy(p.X, pristine, sizeof(fftw_complex) * nh);
                    fftw_execute(p.c2r);
                  }) -
                  copy_hr;
    fftw_free(pristine);
  }
  const Image frame = aosr::ReadFits((dir / "seq_frames.fits").string()).planes.at(0);
  double aosr_r2c[2], aosr_c2r[2], set_frame[2], output[2];
  {
    // A SlotFilter of the right shape (its weights do not change its cost).
    ImageStack responses(4, Image::Zero(hr, hr));
    for (Image& x : responses) x(0, 0) = 1.0;
    aosr::SlotFilter filter({lr, lr}, int(hr / lr), responses);
    for (int s = 0; s < 4; ++s) filter.SetFrame(s, frame);
    aosr::ComplexImage X;
    Image x;
    Image big = Image::Zero(hr, hr);
    aosr::ComplexImage Xh = aosr::FftR2C(big);
    for (int t : {1, 2}) {
      aosr::SetDefaultThreads(t);
      aosr_r2c[t - 1] = BestSeconds([&] { aosr::FftR2CInto(frame, &X); });
      aosr_c2r[t - 1] = BestSeconds([&] { aosr::FftC2RInto(Xh, hr, &x); });
      set_frame[t - 1] = BestSeconds([&] { filter.SetFrame(1, frame); });
      output[t - 1] = BestSeconds([&] { filter.Output(&x); });
    }
  }
  // TV's x-update on the same model (uniform weights: FourierXUpdate, total_variation.cpp): one exact solve of
  // (w AᵀA + ρ∇ᵀ∇) x = rhs, i.e. an HR r2c, the per-bin solves and an HR c2r.
  double x_update[2], hr_r2c[2];
  Index woodbury_bins = 0, solved_bins = 0;
  {
    const aosr::DatasetProblem dp = aosr::ProblemFromDataset(aosr::SelectFrames(d, {0, 1, 2, 3}));  // one window
    aosr::FourierNormalSystem system(*dp.problem.model, 1.0);
    system.Factorize(1.0, 0.0);
    woodbury_bins = system.woodbury_bins();
    solved_bins = system.bins();
    Image rhs = aosr::ReadFits((dir / "truth.fits").string()).planes.at(0);
    Image x;
    aosr::FourierNormalSystem::Workspace ws;
    aosr::ComplexImage X;
    for (int t : {1, 2}) {
      aosr::SetDefaultThreads(t);
      x_update[t - 1] = BestSeconds([&] { system.SolveInto(rhs, &x, &ws); });
      hr_r2c[t - 1] = BestSeconds([&] { aosr::FftR2CInto(rhs, &X); });
    }
  }
  if (keep.empty()) fs::remove_all(dir);

  std::ostringstream md;
  md << "# Streaming super-resolution (`aosr video`): outputs per second at 512²\n\n";
  md << "Command: `build/bench/video_bench --frames " << frames << " --check " << check << " --tv " << tv_outputs
     << (out.empty() ? std::string() : " --out " + out) << "` (Release). Machine: "
     << std::thread::hardware_concurrency() << " hardware threads, shared. Data: data/scenes/demo.json at r = 4 ("
     << lr << "² frames, " << hr << "² outputs, N = 4 phases), a sequence of " << frames
     << " frames (the noiseless frames of the 4 phases in turn plus fresh noise), through DatasetVideo as `aosr "
        "video` runs it, sliding window (one output per frame once each phase has one). The method's and the "
        "timing's details are at the top of bench/video_bench.cpp.\n\n";
  md << "| method | threads | outputs | paths | filter build (once) | per output, median | best 16-output batch | "
        "mean | outputs/s (1/median) | max dev / peak vs batch (checked outputs) | linear: vs the batch's own κ "
        "search (max κ difference) |\n";
  md << "|---|---|---|---|---|---|---|---|---|---|---|\n";
  for (const StreamRow& r : rows)
    md << "| " << r.method << (r.method == "tikhonov" ? " (λ fixed)" : "") << " | " << r.threads << " | " << r.outputs
       << " | " << r.paths << " | " << Fmt("%.2f", r.build_s) << " s | " << Fmt("%.3f", r.median_ms) << " ms | "
       << Fmt("%.3f", r.best_batch_ms) << " ms | " << Fmt("%.3f", r.mean_ms) << " ms | "
       << Fmt("%.0f", 1e3 / r.median_ms) << " | " << Fmt("%.1e", r.max_dev) << " (" << r.checked << ") | "
       << (r.max_dev_own >= 0 ? Fmt("%.1e", r.max_dev_own) + " (" + Fmt("%.2f", 100 * r.kappa_spread) + " %)" : "-")
       << " |\n";
  if (!tv_rows.empty()) {
    md << "\nTV warm-started (`-m tv`), 1 and 2 threads: the first window to convergence (automatic μ), then each output "
          "`tv_iterations` ADMM iterations from the previous one; PSNR against the truth (cropped by the trustworthy "
          "border) of the warm output and of TV to convergence on the same window (same μ, up to 3000 iterations, "
          "relative tolerance 1e-6). Static: the sequence above; moving: the simulator's own sequence of the demo "
          "scene with a companion crossing at 1 HR px per frame and a star varying by ±80 % every 0.4 s "
          "(MakeMovingSequence), each output scored against the truth at its newest frame:\n\n";
    md << "| sequence | tv_iterations | warm start | threads | outputs | first window | per warm output, median | outputs/s | gap to "
          "converged TV, mean / max | checked outputs |\n|---|---|---|---|---|---|---|---|---|---|\n";
    for (const TvRow& r : tv_rows) {
      std::string checks;
      for (const std::string& c : r.checks) checks += (checks.empty() ? "" : "; ") + c;
      const bool scored = !r.checks.empty();
      md << "| " << r.sequence << " | " << r.iterations << " | " << (r.warm_duals ? "state" : "x") << " | " << r.threads
         << " | " << r.outputs << " | "
         << Fmt("%.2f", r.first_s) << " s | " << Fmt("%.1f", r.median_ms) << " ms | " << Fmt("%.1f", 1e3 / r.median_ms)
         << " | " << (scored ? Fmt("%.2f", r.mean_gap_db) + " / " + Fmt("%.2f", r.max_gap_db) + " dB" : "as 1 thread")
         << " | " << (scored ? checks : "-") << " |\n";
    }
  }
  md << "\nThe floor and the parts, one call each (minimum over 15 batches of the batch mean), ms:\n\n";
  md << "| part | 1 thread | 2 threads |\n|---|---|---|\n";
  md << "| FFTW's own r2c " << lr << "² (floor; plan " << (wisdom_lr ? "from the shipped wisdom" : "FFTW_PATIENT")
     << ") | " << Fmt("%.4f", 1e3 * fftw_r2c_lr) << " | - |\n";
  md << "| FFTW's own c2r " << hr << "² (floor; plan " << (wisdom_hr ? "from the shipped wisdom" : "FFTW_PATIENT")
     << "; its input refreshed by a copy, " << Fmt("%.4f", 1e3 * copy_hr) << " ms, taken off) | "
     << Fmt("%.4f", 1e3 * fftw_c2r_hr) << " | - |\n";
  md << "| floor of one output: the two above | " << Fmt("%.4f", 1e3 * (fftw_r2c_lr + fftw_c2r_hr)) << " | - |\n";
  md << "| aosr FftR2CInto " << lr << "² | " << Fmt("%.4f", 1e3 * aosr_r2c[0]) << " | " << Fmt("%.4f", 1e3 * aosr_r2c[1])
     << " |\n";
  md << "| aosr FftC2RInto " << hr << "² | " << Fmt("%.4f", 1e3 * aosr_c2r[0]) << " | " << Fmt("%.4f", 1e3 * aosr_c2r[1])
     << " |\n";
  md << "| SlotFilter::SetFrame (r2c + the slot's spectrum) | " << Fmt("%.4f", 1e3 * set_frame[0]) << " | "
     << Fmt("%.4f", 1e3 * set_frame[1]) << " |\n";
  md << "| SlotFilter::Output (N-term sum + HR c2r) | " << Fmt("%.4f", 1e3 * output[0]) << " | "
     << Fmt("%.4f", 1e3 * output[1]) << " |\n";
  md << "| N-term sum alone (Output - FftC2RInto) | " << Fmt("%.4f", 1e3 * (output[0] - aosr_c2r[0])) << " | "
     << Fmt("%.4f", 1e3 * (output[1] - aosr_c2r[1])) << " |\n";
  md << "| aosr FftR2CInto " << hr << "² | " << Fmt("%.4f", 1e3 * hr_r2c[0]) << " | " << Fmt("%.4f", 1e3 * hr_r2c[1])
     << " |\n";
  md << "| TV x-update: FourierNormalSystem::SolveInto " << hr << "² (HR r2c, " << woodbury_bins << " of "
     << solved_bins << " bins in Woodbury form, HR c2r) | " << Fmt("%.4f", 1e3 * x_update[0]) << " | "
     << Fmt("%.4f", 1e3 * x_update[1]) << " |\n";
  md << "| its per-bin solves alone (SolveInto - FftR2CInto - FftC2RInto, " << hr << "²) | "
     << Fmt("%.4f", 1e3 * (x_update[0] - hr_r2c[0] - aosr_c2r[0])) << " | "
     << Fmt("%.4f", 1e3 * (x_update[1] - hr_r2c[1] - aosr_c2r[1])) << " |\n";
  std::printf("%s", md.str().c_str());
  if (!out.empty()) {
    std::ofstream f(out);
    f << md.str();
    if (!f) {
      std::fprintf(stderr, "cannot write %s\n", out.c_str());
      return 1;
    }
  }
  return 0;
}
