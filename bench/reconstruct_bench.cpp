// Reconstruction benchmark: accuracy against wall time for every method of Reconstruct() (reconstruct.hpp)
// on the shipped scenes, simulated in-process, beside the FFT floor of each run, and OpenCV's superres
// BTV-L1 on the same frames as an off-the-shelf comparison.
//
// For each configuration (scene, HR size, r, N) the scene file is read, its fields overridden as
// `aosr simulate --set` would (frames, detector.frame_px), simulated (ScenePipeline::Run), written to a
// scratch folder and read back (WriteSimulation / LoadDataset: the path real data takes), and turned into
// a ReconstructionProblem by ProblemFromDataset with its defaults (dataset inverse-variance weights, DM
// offsets). Every method then runs through Reconstruct() with its defaults (Tikhonov: GCV; TV and MAP:
// the automatic weight rule, warm-started by Tikhonov), TV and MAP at several iteration caps.
//
// Columns:
//   PSNR, SSIM   against the simulated truth (e⁻ per HR pixel), cropped by the scene's trustworthy border
//                (core/metrics.hpp; L = the cropped truth's range)
//   time         Reconstruction::seconds_total (TV and MAP include their Tikhonov pilot), one thread
//   FFTs         FftExecutionCount() after minus before: every transform aosr executed for the run
//   floor        FFTs x the time of one out-of-place real-to-complex FFTW transform of the HR grid
//                (FFTW_PATIENT's plan from the shipped wisdom, minimum over 15 batches, measured here). The solvers also do LR-size and
//                complex HR transforms, so this is the floor in units of "one HR real FFT": LR transforms
//                cost ~r² less, complex ones ~2x more.
//   time/floor   how far the run is from spending all its time in FFTs
//
// OpenCV BTV-L1 (cv::superres::createSuperResolution_BTVL1, Farsiu et al. 2004 / Mitzel et al. 2009),
// when the build found OpenCV's superres module (AOSR_HAVE_OPENCV_SUPERRES): the same N frames, in
// electrons, fed from memory as 8-bit images (its flow and its output are 8-bit: the frames are scaled by
// 255/max and clipped at 0), temporal radius N-1 so that the first output uses all N frames, its own
// Farneback optical-flow registration, its fixed Gaussian blur (5x5, σ 1.1 HR px) as the only PSF model,
// nearest-neighbour sampling as its camera model, an L1 data term and no noise model. Its output is on
// frame 0's grid without a btvKernelSize (7 HR px) border; we move it back by frame 0's known offset
// (Fourier shift), rescale to e⁻ per HR pixel (÷ scale ÷ r²) and score it on the same crop (at least the
// 7 px it drops). Integer scale only: it runs at every r here.
//
// Usage: build/bench/reconstruct_bench [--quick] [--scene NAME] [--frames N] [--methods LIST] [--out FILE]
//   --quick   small grids and short sweeps (~1 minute): a smoke run
//   --scene   only the configurations of that scene file (e.g. paper-sim-r8)
//   --frames  only the configurations that set N frames (e.g. 4; crowded-stars keeps its scene's own N and is
//             left out)
//   --methods only these methods, comma-separated names of ToString(ReconstructionMethod) (e.g. tv or
//             tikhonov,map); the Tikhonov rows stay out unless named (TV and MAP still run their own pilot),
//             OpenCV BTV-L1 is `opencv-btvl1`. Each row also prints its process CPU time on stderr.
//   --out     also write the Markdown table to FILE (e.g. bench/results/reconstruct.md) and, next to it, the
//             picture FILE's stem + ".png" (e.g. bench/results/reconstruct.png): per configuration, PSNR and
//             SSIM against wall time (log axis), one curve per method over its iteration caps (io/plot.hpp,
//             the plot `aosr tradeoff` draws)
#include <fftw3.h>
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "fft_floor.hpp"
#include "aosr/core/fft.hpp"
#include "aosr/core/memory.hpp"
#include "aosr/core/metrics.hpp"
#include "aosr/core/parallel.hpp"
#include "aosr/core/operators.hpp"
#include "aosr/io/config.hpp"
#include "aosr/io/plot.hpp"
#include "aosr/scene/dataset.hpp"
#include "aosr/scene/pipeline.hpp"
#include "aosr/scene/scene_spec.hpp"
#include "aosr/scene/telescope.hpp"
#include "aosr/solvers/dataset_problem.hpp"
#include "aosr/solvers/reconstruct.hpp"

#ifdef AOSR_HAVE_OPENCV_SUPERRES
#include <opencv2/core.hpp>
#include <opencv2/superres.hpp>
#endif

namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;
using aosr::Image;
using aosr::ImageStack;
using aosr::Index;

double Since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

// CPU seconds of the whole process (all threads) so far: on a shared machine, less disturbed than wall time.
double ProcessCpuSeconds() {
  timespec ts{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return double(ts.tv_sec) + 1e-9 * double(ts.tv_nsec);
}

// The --methods filter: empty runs everything.
std::vector<std::string> g_methods;
bool Wanted(const std::string& method) {
  return g_methods.empty() || std::find(g_methods.begin(), g_methods.end(), method) != g_methods.end();
}

struct Config {
  std::string scene;  // file name in data/scenes
  int frame_px = 0;   // 0: the scene's
  int frames = 0;     // 0: the scene's (the --frames filter then matches nothing but 0)
  std::vector<int> caps;  // iteration caps for tv and map
};

struct Row {
  std::string scene, method, termination;
  Index hr = 0;
  int r = 0, n = 0, cap = 0, iterations = 0;
  double psnr = 0, ssim = 0, seconds = 0, floor = 0, regularisation = 0;
  std::uint64_t ffts = 0;
  std::string note;
};

// The FFT floor: bench/fft_floor.hpp, on wall time.
double FftSeconds(int rows, int cols) {
  const Clock::time_point origin = Clock::now();
  return aosr::bench::R2cFloorSeconds(rows, cols, [origin] { return Since(origin); });
}

std::string Fmt(const char* f, double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, f, v);
  return buf;
}

#ifdef AOSR_HAVE_OPENCV_SUPERRES
// Feeds a fixed list of 8-bit frames to cv::superres, then reports the end of the stream (an empty frame).
class MemoryFrameSource final : public cv::superres::FrameSource {
 public:
  explicit MemoryFrameSource(std::vector<cv::Mat> frames) : frames_(std::move(frames)) {}
  void nextFrame(cv::OutputArray frame) override {
    if (next_ < frames_.size()) frames_[next_++].copyTo(frame);
    else frame.release();
  }
  void reset() override { next_ = 0; }

 private:
  std::vector<cv::Mat> frames_;
  std::size_t next_ = 0;
};

// BTV-L1 on the problem's frames; fills `row` and returns false (with a note) if it produced nothing.
bool RunBtvL1(const aosr::ReconstructionProblem& p, const Image& truth, const aosr::MetricOptions& metric,
              int iterations, Row* row) {
  const int r = p.model->r();
  const aosr::Shape hr = p.model->hr_shape();
  double peak = 0;
  for (const Image& f : p.frames) peak = std::max(peak, f.maxCoeff());
  const double scale = 255.0 / peak;
  std::vector<cv::Mat> frames;
  for (const Image& f : p.frames) {
    cv::Mat m(int(f.rows()), int(f.cols()), CV_8UC1);
    for (int y = 0; y < m.rows; ++y)
      for (int x = 0; x < m.cols; ++x) m.at<unsigned char>(y, x) = cv::saturate_cast<unsigned char>(f(y, x) * scale);
    frames.push_back(m);
  }
  const std::uint64_t f0 = aosr::FftExecutionCount();
  const auto t0 = Clock::now();
  cv::Ptr<cv::superres::SuperResolution> sr = cv::superres::createSuperResolution_BTVL1();
  sr->setScale(r);
  sr->setIterations(iterations);
  sr->setTemporalAreaRadius(std::max(1, p.frame_count() - 1));
  sr->setInput(cv::makePtr<MemoryFrameSource>(frames));
  cv::Mat out;
  sr->nextFrame(out);  // frame 0's reconstruction, from frames 0 .. N-1
  const double seconds = Since(t0);
  row->ffts = aosr::FftExecutionCount() - f0;
  row->seconds = seconds;
  row->iterations = iterations;
  row->cap = iterations;
  if (out.empty()) {
    row->note = "no output";
    return false;
  }
  const int border = sr->getKernelSize();  // BTV-L1 drops btvKernelSize HR px on each side
  Image est = Image::Zero(hr.rows, hr.cols);
  for (int y = 0; y < out.rows && y + border < hr.rows; ++y)
    for (int x = 0; x < out.cols && x + border < hr.cols; ++x)
      est(y + border, x + border) = double(out.at<unsigned char>(y, x)) / scale / double(r * r);
  std::fprintf(stderr, "  (btvl1 before the frame-0 shift: %.2f dB)\n", aosr::CompareImages(truth, est, metric).psnr);
  // Its grid is frame 0's: undo frame 0's known pointing offset (the scene moved by +offset).
  if (!p.offsets.empty()) {
    const aosr::ComplexImage shifted =
        aosr::FftR2C(est) * aosr::ShiftTransfer(hr, -p.offsets[0].dy, -p.offsets[0].dx);
    est = aosr::FftC2R(shifted, hr.cols);
  }
  aosr::MetricOptions m = metric;
  m.crop_px = std::max(metric.crop_px, border + int(std::ceil(std::max(std::abs(p.offsets.empty() ? 0.0 : p.offsets[0].dy),
                                                                        std::abs(p.offsets.empty() ? 0.0 : p.offsets[0].dx)))));
  const aosr::ImageMetrics q = aosr::CompareImages(truth, est, m);
  row->psnr = q.psnr;
  row->ssim = q.ssim;
  row->termination = "-";
  row->note = "8-bit in/out, scale " + Fmt("%.3g", scale) + "/e-, crop " + std::to_string(m.crop_px) + " px";
  return true;
}
#endif

void RunConfig(const Config& c, bool quick, std::vector<Row>* rows, std::vector<std::string>* log) {
  const std::string path = (fs::path(aosr::DataDirectory()) / "scenes" / c.scene).string();
  nlohmann::json j = aosr::ReadJsonFile(path);
  if (c.frames > 0) j["frames"] = c.frames;
  if (c.frame_px > 0) j["detector"]["frame_px"] = c.frame_px;
  const aosr::ScenePipeline pipeline(aosr::ParseScene(j, path));
  const auto t_sim = Clock::now();
  const aosr::Simulation sim = pipeline.Run();
  const double sim_s = Since(t_sim);
  const fs::path dir = fs::temp_directory_path() / ("aosr_reconstruct_bench_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  aosr::WriteSimulation(dir.string(), pipeline.scene(), pipeline, sim, &j);
  const aosr::Dataset d = aosr::LoadDataset(dir.string());
  fs::remove_all(dir);
  const aosr::DatasetProblem dp = aosr::ProblemFromDataset(d);
  const aosr::ReconstructionProblem& p = dp.problem;
  const Image& truth = *d.truth;
  const int r = d.r;
  const Index hr = d.hr_frame.rows;
  aosr::MetricOptions metric;
  metric.crop_px = int(d.trustworthy_border_px) * r;
  const double fft_s = FftSeconds(int(d.hr_frame.rows), int(d.hr_frame.cols));
  const std::string name = pipeline.scene().name;
  {
    std::ostringstream os;
    os << name << ": HR " << hr << ", r " << r << ", N " << p.frame_count() << ", simulated in " << Fmt("%.2f", sim_s)
       << " s; weights: " << dp.weights_source << " (uniform: " << (p.HasUniformWeights() ? "yes" : "no")
       << "); offsets: " << dp.offsets_source << "; metric crop " << metric.crop_px << " HR px; one r2c FFT of "
       << hr << "^2: " << Fmt("%.3g", fft_s * 1e3) << " ms";
    log->push_back(os.str());
    std::fprintf(stderr, "%s\n", os.str().c_str());
  }

  // Warm-up, untimed: plans are made for every shape on first use (about 1 ms each); the rows below time
  // the solvers with the plan cache filled, as a long-running program would see them.
  {
    using M = aosr::ReconstructionMethod;
    for (M m : {M::kShiftAddMean, M::kDrizzle, M::kTikhonov, M::kTotalVariation, M::kMap}) {
      aosr::ReconstructOptions o;
      o.method = m;
      o.tv.max_iterations = 1;
      o.map.max_iterations = 1;
      aosr::Reconstruct(p, o);
    }
  }
  double last_regularisation = 0;
  // One row: method m at iteration cap `cap` (0: none), optionally at a fixed λ, on problem `q` (default p),
  // with `threads` threads. Returns the image (to compare thread counts bit for bit).
  const auto run = [&](aosr::ReconstructionMethod m, int cap, double fixed_lambda, const aosr::ReconstructionProblem& q,
                       int threads, const std::string& suffix, const Image* reference) {
    aosr::SetDefaultThreads(threads);
    aosr::ReconstructOptions o;
    o.method = m;
    if (fixed_lambda > 0) {
      o.tikhonov.lambda_rule = aosr::TikhonovLambdaRule::kFixed;
      o.tikhonov.lambda = fixed_lambda;
    }
    if (cap > 0) {
      o.tv.max_iterations = cap;
      o.map.max_iterations = cap;
    }
    const std::uint64_t f0 = aosr::FftExecutionCount();
    const double cpu0 = ProcessCpuSeconds();
    const aosr::Reconstruction rec = aosr::Reconstruct(q, o);
    const double cpu = ProcessCpuSeconds() - cpu0;
    aosr::SetDefaultThreads(1);
    Row row;
    row.ffts = aosr::FftExecutionCount() - f0;
    row.scene = name;
    row.hr = hr;
    row.r = r;
    row.n = p.frame_count();
    row.method = std::string(aosr::ToString(m)) + (fixed_lambda > 0 ? " (λ fixed)" : "") + suffix;
    row.cap = cap;
    row.iterations = rec.summary.iterations;
    row.termination = aosr::ToString(rec.summary.termination);
    row.seconds = rec.seconds_total;
    row.floor = double(row.ffts) * fft_s;
    row.regularisation = rec.regularisation;
    row.note = rec.summary.method;
    if (reference)
      row.note += (rec.image.rows() == reference->rows() && (rec.image == *reference).all())
                      ? "; bit-identical to 1 thread"
                      : "; DIFFERS from 1 thread";
    if (rec.summary.message.find("GCV minimum at the") != std::string::npos)
      row.note += rec.summary.message.find("smallest") != std::string::npos ? " (GCV at the grid's smallest lambda)"
                                                                           : " (GCV at the grid's largest lambda)";
    const aosr::ImageMetrics score = aosr::CompareImages(truth, rec.image, metric);
    row.psnr = score.psnr;
    row.ssim = score.ssim;
    rows->push_back(row);
    last_regularisation = rec.regularisation;
    std::fprintf(stderr,
                 "  %-17s cap %4d: %6.2f dB  SSIM %.3f  %8.3f s (CPU %.3f s)  %7llu FFTs  floor %.3f s  x%.1f  "
                 "(%s, %d it)\n",
                 row.method.c_str(), cap, row.psnr, row.ssim, row.seconds, cpu, (unsigned long long)row.ffts,
                 row.floor, row.floor > 0 ? row.seconds / row.floor : 0.0, row.termination.c_str(), row.iterations);
    return rec.image;
  };
  const auto add = [&](aosr::ReconstructionMethod m, int cap, double fixed_lambda = 0) {
    return run(m, cap, fixed_lambda, p, 1, "", nullptr);
  };
  using M = aosr::ReconstructionMethod;
  const auto wanted = [](M m) { return Wanted(aosr::ToString(m)); };
  for (M m : {M::kShiftAddMean, M::kShiftAddMedian, M::kDrizzle})
    if (wanted(m)) add(m, 0);
  Image tikhonov_1;
  if (wanted(M::kTikhonov)) {
    tikhonov_1 = add(M::kTikhonov, 0);
    const double gcv_lambda = last_regularisation;
    add(M::kTikhonov, 0, gcv_lambda);  // the same λ without the GCV search: what the solve itself costs
  }
  Image tv_100;
  if (wanted(M::kTotalVariation))
    for (int cap : c.caps) {
      Image x = add(M::kTotalVariation, cap);
      if (cap == 100) tv_100 = x;
    }
  Image map_30;
  if (wanted(M::kMap))
    for (int cap : c.caps) {
      Image x = add(M::kMap, cap);
      if (cap == 30) map_30 = x;
    }
  // Two threads (the per-bin loops and the frames' FFTs in parallel): the speed-up, and the same bytes.
  if (hr >= 512 || quick) {
    if (tikhonov_1.size()) run(M::kTikhonov, 0, 0, p, 2, " (2 threads)", &tikhonov_1);
    if (tv_100.size()) run(M::kTotalVariation, 100, 0, p, 2, " (2 threads)", &tv_100);
    if (map_30.size()) run(M::kMap, 30, 0, p, 2, " (2 threads)", &map_30);
  }
  // Non-uniform weights (photon noise): the same frames with uniform weights on the valid pixels, the
  // comparison the weighted fast path is measured by (issue 15: weighted <= 2x uniform).
  if (!p.HasUniformWeights()) {
    aosr::DatasetProblemOptions uo;
    uo.weights = aosr::DatasetWeights::kMask;
    const aosr::DatasetProblem uniform = aosr::ProblemFromDataset(d, uo);
    if (wanted(M::kTikhonov)) run(M::kTikhonov, 0, 0, uniform.problem, 1, " (uniform weights)", nullptr);
    if (wanted(M::kTotalVariation))
      for (int cap : c.caps) run(M::kTotalVariation, cap, 0, uniform.problem, 1, " (uniform weights)", nullptr);
  }
  log->back() += "; peak RSS after this configuration " + Fmt("%.0f", aosr::PeakResidentBytes() / 1048576.0) + " MiB";
#ifdef AOSR_HAVE_OPENCV_SUPERRES
  // 10, 30, 100 iterations (the 100-iteration run only up to HR 256: at 1024² it takes ~1.5 min and gains nothing).
  if (Wanted("opencv-btvl1"))
  for (int it : quick ? std::vector<int>{10} : hr <= 256 ? std::vector<int>{10, 30, 100} : std::vector<int>{10, 30}) {
    Row row;
    row.scene = name;
    row.hr = hr;
    row.r = r;
    row.n = p.frame_count();
    row.method = "opencv-btvl1";
    if (RunBtvL1(p, truth, metric, it, &row)) {
      row.floor = 0;
      rows->push_back(row);
      std::fprintf(stderr, "  %-17s it  %4d: %6.2f dB  SSIM %.3f  %8.3f s\n", row.method.c_str(), it, row.psnr,
                   row.ssim, row.seconds);
    }
  }
#else
  (void)quick;
#endif
}

std::string Table(const std::vector<Row>& rows) {
  std::ostringstream os;
  os << "| scene | HR | r | N | method | iter cap | iters | termination | PSNR [dB] | SSIM | time [s] | FFTs | "
        "FFT floor [s] | time/floor | reg. | solver |\n"
     << "|---|---:|---:|---:|---|---:|---:|---|---:|---:|---:|---:|---:|---:|---:|---|\n";
  for (const Row& r : rows) {
    os << "| " << r.scene << " | " << r.hr << " | " << r.r << " | " << r.n << " | " << r.method << " | "
       << (r.cap > 0 ? std::to_string(r.cap) : "—") << " | " << r.iterations << " | " << r.termination << " | "
       << Fmt("%.2f", r.psnr) << " | " << Fmt("%.3f", r.ssim) << " | " << Fmt("%.3f", r.seconds) << " | " << r.ffts
       << " | " << (r.floor > 0 ? Fmt("%.4f", r.floor) : "—") << " | "
       << (r.floor > 0 ? Fmt("%.1f", r.seconds / r.floor) : "—") << " | "
       << (r.regularisation > 0 ? Fmt("%.3g", r.regularisation) : "—") << " | " << r.note << " |\n";
  }
  return os.str();
}

// Per configuration (scene, HR, r, N, in the order run) one row of two panels: PSNR and SSIM against time, one
// curve per method (colours fixed by the method's first appearance, so a method keeps its colour everywhere).
void WritePlot(const std::string& path, const std::vector<Row>& rows) {
  std::vector<std::string> methods, configs;
  const auto config_of = [](const Row& r) {
    return r.scene + ": HR " + std::to_string(r.hr) + ", r = " + std::to_string(r.r) + ", N = " + std::to_string(r.n);
  };
  for (const Row& r : rows) {
    if (std::find(methods.begin(), methods.end(), r.method) == methods.end()) methods.push_back(r.method);
    if (std::find(configs.begin(), configs.end(), config_of(r)) == configs.end()) configs.push_back(config_of(r));
  }
  std::vector<aosr::LinePlot> panels;
  for (const std::string& c : configs) {
    aosr::LinePlot psnr, ssim;
    psnr.title = c + ": PSNR";
    ssim.title = c + ": SSIM";
    psnr.x.label = ssim.x.label = "wall time [s]";
    psnr.x.log = ssim.x.log = true;
    psnr.y.label = "PSNR [dB]";
    ssim.y.label = "SSIM";
    for (const std::string& m : methods) {
      aosr::PlotSeries a{m, {}, {}}, b{m, {}, {}};
      for (const Row& r : rows) {
        if (r.method != m || config_of(r) != c) continue;
        const double t = std::max(r.seconds, 1e-6);  // log axis
        a.x.push_back(t);
        a.y.push_back(r.psnr);
        b.x.push_back(t);
        b.y.push_back(r.ssim);
      }
      psnr.series.push_back(a);
      ssim.series.push_back(b);
    }
    panels.push_back(psnr);
    panels.push_back(ssim);
  }
  if (panels.empty()) return;
  aosr::FigureOptions fo;
  fo.columns = 2;
  aosr::WriteFigure(path, panels, fo);
}

}  // namespace

int main(int argc, char** argv) {
  aosr::TuneAllocatorForLargeArrays();  // as the CLI does (memory.hpp)
  bool quick = false;
  std::string out_file, only;
  int frames_only = 0;
  std::string command = "build/bench/reconstruct_bench";
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    command += " " + a;
    if (a == "--quick") {
      quick = true;
    } else if (a == "--scene" && i + 1 < argc) {
      only = argv[++i];
      command += std::string(" ") + only;
    } else if (a == "--frames" && i + 1 < argc) {
      frames_only = std::atoi(argv[++i]);
      command += " " + std::to_string(frames_only);
    } else if (a == "--methods" && i + 1 < argc) {
      const std::string list = argv[++i];
      command += " " + list;
      std::stringstream ss(list);
      for (std::string m; std::getline(ss, m, ',');)
        if (!m.empty()) g_methods.push_back(m);
    } else if (a == "--out" && i + 1 < argc) {
      out_file = argv[++i];
      command += " " + out_file;
    } else {
      std::fprintf(stderr,
                   "usage: reconstruct_bench [--quick] [--scene NAME] [--frames N] [--methods LIST] [--out FILE]\n");
      return 2;
    }
  }
#ifdef AOSR_HAVE_OPENCV_SUPERRES
  cv::setNumThreads(1);  // one thread, like the aosr solvers here
#endif
  std::vector<Config> configs;
  if (quick) {
    configs = {{"demo.json", 64, 4, {10, 30}}, {"paper-sim-r4.json", 64, 4, {10, 30}}};
  } else {
    const std::vector<int> caps = {10, 30, 100, 300}, caps_1024 = {10, 30, 100};
    configs = {{"demo.json", 0, 2, caps},          {"demo.json", 0, 4, caps},
               {"demo.json", 0, 8, caps},          {"paper-sim-r2.json", 0, 4, caps},
               {"paper-sim-r4.json", 0, 2, caps},  {"paper-sim-r4.json", 0, 4, caps},
               {"paper-sim-r4.json", 0, 8, caps},  {"paper-sim-r8.json", 0, 4, caps_1024},
               {"crowded-stars.json", 0, 0, caps}};
  }
  std::vector<Row> rows;
  std::vector<std::string> log;
  const auto t0 = Clock::now();
  for (const Config& c : configs)
    if ((only.empty() || c.scene == only || c.scene == only + ".json") && (frames_only == 0 || c.frames == frames_only))
      RunConfig(c, quick, &rows, &log);
  const double total = Since(t0);

  std::ostringstream md;
  double load[3] = {0, 0, 0};
  if (std::FILE* f = std::fopen("/proc/loadavg", "r")) {
    if (std::fscanf(f, "%lf %lf %lf", &load[0], &load[1], &load[2]) != 3) load[0] = load[1] = load[2] = 0;
    std::fclose(f);
  }
  md << "<!-- produced by: " << command << " -->\n"
     << "# Reconstruction: accuracy against wall time\n\n"
     << "Command: `" << command << "` (Release build). Machine: " << std::thread::hardware_concurrency()
     << " hardware threads; one thread per solver except the (2 threads) rows (FFTW single-threaded"
#ifdef AOSR_HAVE_OPENCV_SUPERRES
     << ", cv::setNumThreads(1)"
#endif
     << "); load average at the end " << Fmt("%.2f", load[0]) << " / " << Fmt("%.2f", load[1]) << " / "
     << Fmt("%.2f", load[2]) << " (1/5/15 min). Total " << Fmt("%.0f", total) << " s.\n\n"
     << "Configurations:\n\n";
  for (const std::string& l : log) md << "- " << l << "\n";
  md << "\nReading the table. PSNR/SSIM against the simulated truth (e- per HR pixel), cropped by the scene's "
        "trustworthy border; L = the cropped truth's range. Time = Reconstruction::seconds_total on one thread, "
        "FFTW plans cached by an untimed warm-up; tv and map include their Tikhonov (GCV) pilot, which also sets "
        "their weight (reconstruct.hpp). The iteration cap is the knob of tv (ADMM) and map (L-BFGS); "
        "termination max-iterations means the cap stopped it. FFTs = FftExecutionCount() difference; floor = "
        "FFTs x one out-of-place r2c FFTW transform of the HR grid (FFTW_PATIENT's plan from the shipped wisdom (bench/fft_floor.hpp), minimum over 15 batches in the same run), so LR-size transforms are "
        "over-counted (~r^2 cheaper) and complex HR ones under-counted (~2x dearer). `tikhonov (λ fixed)` reruns "
        "the GCV λ without the search: the difference is the λ search (one SVD per bin, then sums over singular "
        "values). Rows marked (2 threads) rerun a configuration's tikhonov, tv-100 and map-30 on 2 threads and say "
        "whether the image is bit-identical to the 1-thread one; rows marked (uniform weights) rerun a dataset "
        "with photon-noise weights with uniform weights on its valid pixels. The model PSFs are "
        "the simulation's own (the dataset's psfs: an oracle model; see `aosr reconstruct --model-psfs nominal` "
        "for a mismatched one).\n\n"
        "OpenCV BTV-L1 (`cv::superres::createSuperResolution_BTVL1`, OpenCV 4.6 from Debian 12's "
        "libopencv-superres-dev; Farsiu et al. 2004, Mitzel et al. 2009), default parameters (lambda 0.03, "
        "tau 1.3, alpha 0.7, btvKernelSize 7, Farneback flow), on the same N frames, and its limits: integer "
        "scale only; 8-bit input and output (frames scaled by 255/max and clipped at 0: its CPU path returns "
        "CV_8U); it registers the frames itself by dense optical flow (Farneback) instead of using the known "
        "offsets; no PSF model (a fixed 5x5 Gaussian, sigma 1.1 HR px, whatever the telescope), "
        "nearest-neighbour decimation instead of pixel integration, an L1 data term and no noise model or "
        "weights; its output is frame 0's grid minus a 7 HR px border (we undo frame 0's known offset by a "
        "Fourier shift and rescale to e- per HR pixel before scoring). It runs no aosr FFT (floor: —).\n\n";
  std::string png_file;
  if (!out_file.empty()) {
    png_file = (fs::path(out_file).parent_path() / (fs::path(out_file).stem().string() + ".png")).string();
    md << "PSNR and SSIM against wall time, per configuration (one curve per method over its iteration caps): "
       << "`" << fs::path(png_file).filename().string() << "`.\n\n![accuracy against wall time]("
       << fs::path(png_file).filename().string() << ")\n\n";
  }
  md << Table(rows);
#ifndef AOSR_HAVE_OPENCV_SUPERRES
  md << "\nOpenCV superres (BTV-L1) was not found at build time (Debian 12: libopencv-superres-dev); not run.\n";
#endif
  std::printf("%s", md.str().c_str());
  if (!out_file.empty()) {
    std::ofstream f(out_file);
    f << md.str();
    if (!f) {
      std::fprintf(stderr, "reconstruct_bench: cannot write %s\n", out_file.c_str());
      return 1;
    }
    try {
      WritePlot(png_file, rows);
    } catch (const std::exception& e) {
      std::fprintf(stderr, "reconstruct_bench: %s\n", e.what());
      return 1;
    }
  }
  return 0;
}
