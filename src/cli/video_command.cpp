// `aosr video DATASET -o DIR`: a super-resolved movie from a dataset whose frames cycle through the DM's phases
// (solvers/video_stream.hpp): one output per new frame (sliding window) or per cycle, written as a FITS cube with
// the output times and the HR grid's WCS, and as a video file (io/video_file.hpp) with an asinh/log stretch and a
// time stamp on every frame.
#include <algorithm>
#include <array>
#include <map>
#include <optional>
#include <set>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "aosr/core/error.hpp"
#include "aosr/core/memory.hpp"
#include "aosr/core/metrics.hpp"
#include "aosr/io/fits.hpp"
#include "aosr/io/video_file.hpp"
#include "aosr/scene/dataset.hpp"
#include "aosr/solvers/dataset_problem.hpp"
#include "aosr/solvers/video_stream.hpp"
#include "cli_util.hpp"
#include "commands.hpp"
#include "stream_options.hpp"

namespace aosr::cli {
namespace {

namespace fs = std::filesystem;
constexpr const char* kVideoCmd = "aosr video";

struct VideoArgs {
  std::string dataset, out;
  StreamArgs stream;
  double frame_rate = 1.0;
  double fps = 10.0;
  std::string codec = "MJPG";
  std::string video_name = "video.avi";
  bool no_video = false;
  std::string stretch = "asinh";
  int zoom = 1;
  int limit = 0;
  bool force = false;
  bool json = false;
  ExecutionArgs exec;
};

// The black and white levels of the video: the 0.5 and 99.8 percentiles of the first output (fixed afterwards,
// so that the scene's brightness changes stay visible).
std::pair<double, double> VideoLevels(const Image& x) {
  std::vector<double> v;
  for (Index i = 0; i < x.size(); ++i)
    if (std::isfinite(x.data()[i])) v.push_back(x.data()[i]);
  if (v.empty()) return {0.0, 1.0};
  std::sort(v.begin(), v.end());
  const double lo = v[std::size_t(0.005 * double(v.size() - 1))], hi = v[std::size_t(0.998 * double(v.size() - 1))];
  return {lo, hi > lo ? hi : lo + 1.0};
}

std::string TimeLabel(double t) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "t = %.3f s", t);
  return buf;
}

void RunVideo(const VideoArgs& a) {
  ApplyExecution(a.exec);
  const Progress progress(!a.json);
  const VideoOptions vo = StreamVideoOptions(a.stream, kVideoCmd);
  VideoFileOptions fo;
  fo.fps = a.fps;
  fo.codec = a.codec;
  fo.zoom = a.zoom;
  fo.stretch = a.stretch == "log" ? Stretch::kLog : a.stretch == "linear" ? Stretch::kLinear : Stretch::kAsinh;
  {
    std::string why;
    if (!fo.IsValid(&why)) throw InvalidArgument(std::string(kVideoCmd) + ": video " + why);
  }
  const DatasetProblemOptions po = StreamProblemOptions(a.stream);

  progress.Step("reading " + a.dataset);
  const Dataset d = LoadDataset(a.dataset);
  const std::string cube_path = JoinPath(a.out, "video.fits");
  const std::string video_path = JoinPath(a.out, a.video_name);
  std::vector<std::string> targets = {cube_path};
  if (!a.no_video) targets.push_back(video_path);
  const std::set<fs::path> inputs = DatasetInputFiles(d);
  for (const std::string& p : targets) {
    if (inputs.count(fs::weakly_canonical(p)))
      throw InvalidArgument(kVideoCmd, "-o", a.out, "a folder where no output overwrites an input of the dataset (" + p + ")");
    std::error_code ec;
    if (fs::exists(p, ec) && !a.force) throw IoError(p, "exists; pass --force to overwrite it");
  }
  // The cube is written plane by plane as the outputs come (FitsCubeWriter): its memory does not grow with the
  // movie, and no output lands on fresh pages (a page fault per 4 KB: on this project's VMs holding each 512²
  // output cost ~8 ms, six times its computation; docs/video.md). Sized for the expected count up front.
  const int expected = vo.window == VideoWindow::kSliding ? d.size() - d.slot_count + 1 : d.size() / std::max(1, d.slot_count);
  const int outputs_cap = a.limit > 0 ? std::min(a.limit, std::max(0, expected)) : std::max(0, expected);

  Stopwatch setup_clock;
  DatasetVideo video(d, vo, po, a.frame_rate);
  const double setup_seconds = setup_clock.Seconds();
  // Everything is checked (options, dataset, the model of the phases): only now is the folder made.
  EnsureDirectory(a.out);
  progress.Step(std::to_string(d.size()) + " frames, " + std::to_string(d.slot_count) + " phases, " +
                ToString(vo.method) + ", " + ToString(vo.window) + " window, weights: " + video.weights_source());
  if (!video.warning().empty()) std::fprintf(stderr, "warning: %s\n", video.warning().c_str());

  // A simulated sequence whose objects change carries the truth at each frame's time: every output is scored
  // against the truth at its newest frame (what a viewer sees then), on the trustworthy crop, with one dynamic
  // range for the whole movie (the largest of the truths'), so that the scores compare across time.
  const bool scored = d.truth_frames.size() == d.frames.size();
  MetricOptions mo;
  if (scored) {
    mo.crop_px = int(d.trustworthy_border_px * d.r);
    if (2 * mo.crop_px + 11 > std::min(d.hr_frame.rows, d.hr_frame.cols)) mo.crop_px = 0;
    const Index c = mo.crop_px;
    for (const Image& t : d.truth_frames) {
      const auto inner = t.block(c, c, t.rows() - 2 * c, t.cols() - 2 * c);
      mo.peak = std::max(mo.peak, inner.maxCoeff() - inner.minCoeff());
    }
    if (!(mo.peak > 0)) mo.peak = 1.0;
  }
  std::vector<std::array<double, 2>> scores;  // per output: PSNR [dB], SSIM

  std::unique_ptr<VideoFileWriter> writer;
  std::unique_ptr<FitsCubeWriter> cube;
  int outputs = 0;
  Image times;  // per output: time, window start, first and last input frame
  std::vector<std::array<double, 4>> rows;
  std::map<std::string, int> paths;
  double compute_seconds = 0, filter_seconds = 0;
  int filter_outputs = 0;
  Stopwatch run_clock;
  double first_done_s = 0;  // run_clock when the first output was written (the filter build is in it)
  while (a.limit <= 0 || outputs < a.limit) {
    std::optional<VideoFrame> f = video.Next();
    if (!f) break;
    compute_seconds += f->seconds;
    ++paths[f->path];
    if (f->path == "slot-filter") {
      filter_seconds += f->seconds;
      ++filter_outputs;
    }
    if (!a.no_video) {
      if (!writer) {
        const auto [lo, hi] = VideoLevels(f->image);
        fo.black = lo;
        fo.white = hi;
        writer = std::make_unique<VideoFileWriter>(video_path, ShapeOf(f->image), fo);
      }
      writer->Write(f->image, TimeLabel(f->time_s));
    }
    const int first = *std::min_element(f->frames.begin(), f->frames.end());
    const int last = *std::max_element(f->frames.begin(), f->frames.end());
    rows.push_back({f->time_s, f->window_start_s, double(first), double(last)});
    if (scored) {
      const ImageMetrics m = CompareImages(d.truth_frames[std::size_t(last)], f->image, mo);
      scores.push_back({m.psnr, m.ssim});
    }
    if (!cube) cube = std::make_unique<FitsCubeWriter>(cube_path, ShapeOf(f->image), outputs_cap, FitsType::kFloat32);
    cube->Append(f->image);
    if (++outputs == 1) first_done_s = run_clock.Seconds();
  }
  // Steady state end to end: compute, video frame and cube plane of every output after the first.
  const double wall_per_output_ms = outputs > 1 ? 1e3 * (run_clock.Seconds() - first_done_s) / (outputs - 1) : 0.0;
  if (!cube)
    throw InvalidArgument(kVideoCmd, "dataset", a.dataset,
                          "at least one frame of each of the " + std::to_string(d.slot_count) + " phases");
  times.resize(Index(rows.size()), scored ? 6 : 4);
  for (std::size_t k = 0; k < rows.size(); ++k) {
    for (int c = 0; c < 4; ++c) times(Index(k), c) = rows[k][std::size_t(c)];
    if (scored) times(Index(k), 4) = scores[k][0], times(Index(k), 5) = scores[k][1];
  }
  double psnr_mean = 0, psnr_min = 0, psnr_max = 0, ssim_mean = 0;
  if (scored) {
    psnr_min = psnr_max = scores.front()[0];
    for (const auto& sc : scores) {
      psnr_mean += sc[0] / double(scores.size());
      ssim_mean += sc[1] / double(scores.size());
      psnr_min = std::min(psnr_min, sc[0]);
      psnr_max = std::max(psnr_max, sc[0]);
    }
  }

  const VideoSetup& s = video.engine().setup();
  FitsHeader h;
  SetHrImageKeywords(d, "electron", &h);
  h.Set("METHOD", std::string(ToString(vo.method)), "reconstruction method of every output");
  h.Set("WINDOW", std::string(ToString(vo.window)), "sliding: one output per frame; cycle: per cycle");
  h.Set("NPHASES", (long long)d.slot_count, "DM phases (slots) per window");
  h.Set("NOUTPUT", (long long)outputs, "outputs (planes); times in extension TIMES");
  h.Set("TSTART", rows.front()[0], "[s] time of the first output (its newest frame)");
  h.Set("TSTOP", rows.back()[0], "[s] time of the last output");
  if (s.lambda_unweighted >= 0) h.Set("LAMBDAU", s.lambda_unweighted, "Tikhonov lambda of unit-weight frames");
  if (s.kappa > 0) h.Set("KAPPA", s.kappa, "target-PSF kappa (target_psf.hpp)");
  if (s.mu >= 0) h.Set("TVMU", s.mu, "TV weight mu");
  h.Set("ORIGIN", std::string("aosr ") + AOSR_VERSION);
  FitsExtension te;
  te.name = "TIMES";
  te.planes = {times};
  te.type = FitsType::kFloat64;
  te.header.Set("COL1", std::string("TIME_S"), "row k: output k; time of its newest frame [s]");
  te.header.Set("COL2", std::string("START_S"), "time of its oldest frame [s]");
  te.header.Set("COL3", std::string("FIRST"), "index of its oldest input frame");
  te.header.Set("COL4", std::string("LAST"), "index of its newest input frame");
  if (scored) {
    te.header.Set("COL5", std::string("PSNR_DB"), "against the truth at its newest frame's time [dB]");
    te.header.Set("COL6", std::string("SSIM"), "against the same truth");
    te.header.Set("CROP", (long long)mo.crop_px, "[HR px] border left out of the scores");
    te.header.Set("PEAK", mo.peak, "[e-] PSNR dynamic range: the truths' largest");
  }
  cube->Finish(h, {te});
  if (writer) writer->Close();

  const double wall = run_clock.Seconds();
  // Steady state: the output that built the filter is counted without the build.
  const double per_filter_ms = filter_outputs ? 1e3 * (filter_seconds - s.filter_seconds) / filter_outputs : 0.0;
  if (a.json) {
    nlohmann::json j;
    j["outputs"] = outputs;
    j["frames_read"] = video.frames_read();
    j["phases"] = d.slot_count;
    j["method"] = ToString(vo.method);
    j["window"] = ToString(vo.window);
    j["paths"] = paths;
    j["setup_s"] = setup_seconds;
    j["filter_build_s"] = s.filter_seconds;
    j["compute_s"] = compute_seconds;
    j["wall_s"] = wall;
    j["slot_filter_ms_per_output"] = per_filter_ms;
    j["wall_ms_per_output"] = wall_per_output_ms;
    j["lambda_unweighted"] = s.lambda_unweighted;
    j["kappa"] = s.kappa;
    j["mu"] = s.mu;
    j["weights"] = video.weights_source();
    if (scored) {
      std::vector<double> psnr, ssim;
      for (const auto& sc : scores) psnr.push_back(sc[0]), ssim.push_back(sc[1]);
      j["truth_scores"] = {{"psnr_db", psnr}, {"ssim", ssim}, {"psnr_mean_db", psnr_mean}, {"ssim_mean", ssim_mean},
                           {"crop_px", mo.crop_px}, {"peak", mo.peak}};
    }
    j["cube"] = cube_path;
    j["video"] = writer ? video_path : "";
    std::printf("%s\n", j.dump(2).c_str());
    return;
  }
  std::printf("aosr video: %d outputs from %d frames (%d phases, %s window, %s)\n", outputs, video.frames_read(),
              d.slot_count, ToString(vo.window), ToString(vo.method));
  for (const auto& [p, n] : paths) std::printf("  %-12s %d outputs\n", p.c_str(), n);
  if (s.filter_built)
    std::printf("  slot filter built once in %.3f s; %.2f ms per output (%.0f outputs/s)\n", s.filter_seconds, per_filter_ms,
                per_filter_ms > 0 ? 1e3 / per_filter_ms : 0.0);
  if (s.lambda_unweighted >= 0) std::printf("  lambda (unit-weight frames) %.4g\n", s.lambda_unweighted);
  if (s.kappa > 0) std::printf("  kappa %.4g\n", s.kappa);
  if (s.mu >= 0) std::printf("  TV mu %.4g, %d iterations per warm-started output\n", s.mu, vo.tv_iterations);
  std::printf("  compute %.3f s (setup %.3f s), wall %.3f s; %.2f ms per output after the first, writing included\n",
              compute_seconds, setup_seconds, wall, wall_per_output_ms);
  if (scored)
    std::printf("  against the truth at each output's newest frame: PSNR %.2f dB mean (%.2f .. %.2f), SSIM %.4f mean\n",
                psnr_mean, psnr_min, psnr_max, ssim_mean);
  std::printf("wrote %s (times in extension TIMES)%s%s\n", cube_path.c_str(), writer ? " and " : "",
              writer ? video_path.c_str() : "");
}

}  // namespace

void RegisterVideo(CLI::App& app) {
  auto a = std::make_shared<VideoArgs>();
  CLI::App* cmd = app.add_subcommand(
      "video",
      "A super-resolved movie from a dataset whose frames cycle through the DM's phases (a manifest `sequence`, or "
      "any dataset as one cycle): one output per new frame from the last frame of each phase (--window sliding) or "
      "one per full cycle. Linear methods apply per-phase Fourier weights computed once (each output equals the "
      "batch reconstruction of its window); tv is warm-started from the previous output. Writes DIR/video.fits (a "
      "cube, e- per HR pixel per frame, HR WCS, output times in extension TIMES) and DIR/video.avi; existing ones only with "
      "--force.");
  cmd->add_option("dataset", a->dataset, "dataset folder or manifest")->required();
  cmd->add_option("-o,--output", a->out, "output folder (created if needed)")->required();
  AddStreamOptions(cmd, &a->stream);
  cmd->add_option("--frame-rate", a->frame_rate, "frames per second, for times index/rate when the dataset has none")
      ->capture_default_str()
      ->check(CLI::Range(1e-9, 1e9));
  cmd->add_option("--fps", a->fps, "playback frames per second of the video file")->capture_default_str();
  cmd->add_option("--codec", a->codec, "four-character codec (MJPG in .avi is built into OpenCV)")->capture_default_str();
  cmd->add_option("--video-name", a->video_name, "the video file's name in DIR (its extension sets the container)")
      ->capture_default_str();
  cmd->add_flag("--no-video", a->no_video, "write the FITS cube only");
  cmd->add_option("--stretch", a->stretch, "video display stretch: asinh | log | linear")
      ->capture_default_str()
      ->check(CLI::IsMember({"asinh", "log", "linear"}));
  cmd->add_option("--zoom", a->zoom, "video: integer enlargement")->capture_default_str()->check(CLI::Range(1, 16));
  cmd->add_option("--limit", a->limit, "stop after this many outputs (0: all)")->capture_default_str()->check(CLI::Range(0, 1 << 30));
  cmd->add_flag("--force", a->force, "overwrite video.fits and the video file in DIR if they exist");
  cmd->add_flag("--json", a->json, "print the summary as JSON");
  AddExecutionOptions(cmd, &a->exec);
  cmd->callback([a] { RunVideo(*a); });
}

}  // namespace aosr::cli
