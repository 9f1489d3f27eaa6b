// `aosr demo`: simulate the built-in scene, reconstruct it three ways, report quality and time.
#include <cstdio>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "aosr/core/error.hpp"
#include "aosr/core/fft.hpp"
#include "aosr/core/parallel.hpp"
#include "aosr/core/metrics.hpp"
#include "aosr/io/fits.hpp"
#include "aosr/io/image_io.hpp"
#include "aosr/io/wcs.hpp"
#include "aosr/scene/demo.hpp"
#include "aosr/core/operators.hpp"
#include "aosr/solvers/shift_and_add.hpp"
#include "aosr/solvers/target_psf.hpp"
#include "aosr/solvers/tikhonov.hpp"
#include "cli_util.hpp"
#include "commands.hpp"

namespace aosr::cli {
namespace {

struct DemoArgs {
  DemoOptions scene;
  double lambda = -1;  // < 0: choose by GCV
  std::string prior = "gradient";
  bool json = false;
  std::string out_dir;
  ExecutionArgs exec;
};

struct MethodResult {
  std::string method;
  Image estimate;
  ImageMetrics metrics;
  double seconds = 0;
  std::string note;
};

// Sky coordinates of the demo's HR grid (the truth's): a placeholder pointing, RA = Dec = 0 at the grid's
// centre, north up, HR pixel pitch (io/wcs.hpp); the frames carry frame 0's camera WCS derived from it.
Wcs DemoHrWcs(const DemoScene& s) {
  const PixelCoord centre{(s.truth.rows() - 1) / 2.0, (s.truth.cols() - 1) / 2.0};
  return TangentPlaneWcs(0.0, 0.0, s.hr_pixel_rad, 0.0, centre);
}

// `wcs`: the file's sky coordinates, none for the PSF kernels.
FitsHeader SceneHeader(const DemoScene& s, const std::string& what, const std::optional<Wcs>& wcs = std::nullopt) {
  FitsHeader h;
  h.Set("ORIGIN", std::string("aosr ") + AOSR_VERSION, "software that wrote this file");
  h.Set("AOSRDATA", what, "content of this HDU");
  h.Set("SRFACTOR", static_cast<long long>(s.options.r), "super-resolution factor r");
  h.Set("NFRAMES", static_cast<long long>(s.options.frames), "number of sub-exposures N");
  h.Set("WAVELEN", s.options.wavelength_m, "[m] science wavelength");
  h.Set("TELDIAM", s.options.diameter_m, "[m] telescope diameter");
  h.Set("HRPIXRAD", s.hr_pixel_rad, "[rad] HR pixel angular pitch");
  h.Set("LRPIXRAD", s.hr_pixel_rad * s.options.r, "[rad] camera pixel angular pitch");
  h.Set("NOISESIG", s.noise_sigma, "Gaussian noise sigma per camera pixel");
  h.Set("SEED", static_cast<long long>(s.options.seed), "noise seed");
  // Sky images only (not the PSF kernels): the WCS, and BUNIT saying that the demo's flux (per HR pixel for
  // the truth and estimates, per camera pixel for the frames) has no physical unit (truth values in [0.05, 1]).
  if (wcs) SetImageKeywords(wcs, "arbitrary", &h);
  return h;
}

void WriteOutputs(const std::string& dir, const DemoScene& s, const std::vector<MethodResult>& results) {
  EnsureDirectory(dir);
  const Wcs hr_wcs = DemoHrWcs(s);
  const FrameOffset first = s.offsets.empty() ? FrameOffset{} : s.offsets.front();
  WriteFits(JoinPath(dir, "truth.fits"), s.truth, SceneHeader(s, "truth", hr_wcs));
  FitsHeader fh = SceneHeader(s, "frames", LrWcs(hr_wcs, s.options.r, first.dy, first.dx));
  for (std::size_t i = 0; i < s.offsets.size(); ++i) {
    fh.Set("DY" + std::to_string(i), s.offsets[i].dy, "[HR px] pointing offset of frame " + std::to_string(i));
    fh.Set("DX" + std::to_string(i), s.offsets[i].dx, "[HR px] pointing offset of frame " + std::to_string(i));
  }
  WriteFitsCube(JoinPath(dir, "frames.fits"), s.frames, fh);
  WriteFitsCube(JoinPath(dir, "psfs.fits"), s.psfs, SceneHeader(s, "psfs"), FitsType::kFloat64);
  std::vector<Image> tiles = {s.truth};
  for (const MethodResult& r : results) {
    WriteFits(JoinPath(dir, r.method + ".fits"), r.estimate, SceneHeader(s, r.method, hr_wcs));
    tiles.push_back(r.estimate);
  }
  // Montage: truth, then each reconstruction, all on the truth's display range.
  const double lo = s.truth.minCoeff(), hi = s.truth.maxCoeff();
  for (Image& t : tiles) t = ((t - lo) / (hi - lo)).min(1.0).max(0.0);
  ViewOptions view;
  view.stretch = Stretch::kAsinh;
  WriteViewImage(JoinPath(dir, "montage.png"), Montage(tiles, int(tiles.size()), 4, 1.0), view);
}

void RunDemo(const DemoArgs& args) {
  const Progress progress(!args.json);
  Stopwatch total;
  ApplyExecution(args.exec);
  TikhonovOptions tik;
  if (args.lambda >= 0) {
    tik.lambda = args.lambda;
  } else {
    tik.lambda_rule = TikhonovLambdaRule::kGcv;
  }
  tik.prior = ParseTikhonovPrior(args.prior);
  std::string why;
  if (!tik.IsValid(&why)) throw InvalidArgument("aosr demo: " + why);

  if (!args.out_dir.empty()) EnsureDirectory(args.out_dir);  // fail before any computation

  progress.Step("simulating " + std::to_string(args.scene.frames) + " frames of " +
                std::to_string(args.scene.lr_size) + "x" + std::to_string(args.scene.lr_size) + " pixels, r = " +
                std::to_string(args.scene.r));
  Stopwatch sim_clock;
  const DemoScene scene = MakeDemoScene(args.scene);
  const double sim_seconds = sim_clock.Seconds();

  std::vector<MethodResult> results;
  {
    progress.Step("bicubic upsampling of frame 0");
    Stopwatch c;
    results.push_back({"bicubic", BicubicUpsample(scene.frames[0], scene.options.r), {}, 0, "one frame"});
    results.back().seconds = c.Seconds();
  }
  {
    progress.Step("shift-and-add");
    Stopwatch c;
    results.push_back({"shift-and-add", ShiftAndAdd(scene.frames, scene.offsets, scene.options.r, Combine::kMean), {}, 0,
                       "mean of registered frames"});
    results.back().seconds = c.Seconds();
  }
  {
    progress.Step("Tikhonov (exact Fourier solve)");
    Stopwatch c;
    TikhonovSummary summary;
    Image x = TikhonovFourier(*scene.model, scene.frames, tik, &summary);
    results.push_back({"tikhonov", std::move(x), {}, 0, summary.message});
    tik.lambda = summary.lambda;
    results.back().seconds = c.Seconds();
  }
  std::optional<ImageMetrics> linear_through_psf;
  {
    progress.Step("linear with a target PSF (exact Fourier solve)");
    Stopwatch c;
    ReconstructionProblem p;
    p.model = scene.model;
    p.frames = scene.frames;
    TargetPsfOptions lo;  // the automatic Gaussian target, leakage 1e-3
    lo.noise_sigma = scene.noise_sigma;
    TargetPsfResult lr = ReconstructTargetPsf(p, lo);
    // A linear output estimates the truth seen through its effective PSF: score it against that as well.
    const Shape hr = ShapeOf(scene.truth);
    if (lr.effective_psf.rows() <= hr.rows && lr.effective_psf.cols() <= hr.cols)
      linear_through_psf = CompareImages(
          ToImage(PeriodicConvolutionFromKernel(hr, lr.effective_psf)->Apply(AsVector(scene.truth)), hr), lr.image, {});
    results.push_back({"linear", std::move(lr.image), {}, 0, lr.summary.message});
    results.back().seconds = c.Seconds();
  }
  for (MethodResult& r : results) r.metrics = CompareImages(scene.truth, r.estimate, {});

  if (!args.out_dir.empty()) {
    progress.Step("writing " + args.out_dir);
    WriteOutputs(args.out_dir, scene, results);
  }

  if (args.json) {
    nlohmann::json j;
    j["scene"] = {{"lr_size", scene.options.lr_size},
                  {"r", scene.options.r},
                  {"frames", scene.options.frames},
                  {"wavelength_m", scene.options.wavelength_m},
                  {"diameter_m", scene.options.diameter_m},
                  {"camera_pixel_lambda_over_d", scene.options.camera_pixel_lambda_over_d},
                  {"noise_fraction", scene.options.noise_fraction},
                  {"noise_sigma", scene.noise_sigma},
                  {"seed", scene.options.seed},
                  {"simulate_seconds", sim_seconds}};
    j["psnr_peak"] = "max(truth) - min(truth)";
    for (const MethodResult& r : results)
      j["methods"].push_back({{"method", r.method},
                              {"psnr_db", r.metrics.psnr},
                              {"ssim", r.metrics.ssim},
                              {"rmse", r.metrics.rmse},
                              {"seconds", r.seconds},
                              {"note", r.note}});
    j["tikhonov"] = {{"lambda", tik.lambda},
                     {"lambda_rule", tik.lambda_rule == TikhonovLambdaRule::kGcv ? "gcv" : "fixed"},
                     {"prior", ToString(tik.prior)}};
    if (linear_through_psf)
      j["linear_against_truth_through_psf"] = {{"psnr_db", linear_through_psf->psnr}, {"ssim", linear_through_psf->ssim}};
    j["total_seconds"] = total.Seconds();
    std::printf("%s\n", j.dump(2).c_str());
    return;
  }
  std::printf("aosr demo: %lldx%lld camera frames, N = %d, r = %d, noise sigma = %.3g (%.2g%% of max)\n",
              static_cast<long long>(scene.options.lr_size), static_cast<long long>(scene.options.lr_size),
              scene.options.frames, scene.options.r, scene.noise_sigma, 100 * scene.options.noise_fraction);
  std::printf("%-16s %10s %8s %10s %10s\n", "method", "PSNR [dB]", "SSIM", "RMSE", "seconds");
  for (const MethodResult& r : results)
    std::printf("%-16s %10.2f %8.4f %10.4g %10.3f\n", r.method.c_str(), r.metrics.psnr, r.metrics.ssim,
                r.metrics.rmse, r.seconds);
  if (linear_through_psf)
    std::printf("linear against the truth seen through its effective PSF: PSNR %.2f dB, SSIM %.4f\n",
                linear_through_psf->psnr, linear_through_psf->ssim);
  std::printf("PSNR peak = max(truth) - min(truth); simulation %.3f s; total %.3f s\n", sim_seconds, total.Seconds());
  if (!args.out_dir.empty()) std::printf("outputs written to %s\n", args.out_dir.c_str());
}

}  // namespace

void RegisterDemo(CLI::App& app) {
  auto args = std::make_shared<DemoArgs>();
  CLI::App* cmd = app.add_subcommand(
      "demo",
      "Simulate the built-in scene (USAF target and stars, 8 m telescope, K band, N tip/tilt-dithered "
      "sub-exposures on a camera 2x coarser than Nyquist), reconstruct it by single-frame bicubic, "
      "shift-and-add and Fourier Tikhonov, and print PSNR, SSIM and time per method.");
  cmd->add_option("--lr-size", args->scene.lr_size, "camera frame side in pixels")->capture_default_str()->check(CLI::Range(16, 4096));
  cmd->add_option("-r,--factor", args->scene.r, "super-resolution factor r")->capture_default_str()->check(CLI::Range(1, 8));
  cmd->add_option("-n,--frames", args->scene.frames, "number of sub-exposures N")->capture_default_str()->check(CLI::Range(1, 64));
  cmd->add_option("--noise", args->scene.noise_fraction, "Gaussian noise sigma as a fraction of the brightest pixel")
      ->capture_default_str()->check(NonNegativeFinite());
  cmd->add_option("--seed", args->scene.seed, "noise seed")->capture_default_str();
  cmd->add_option("--lambda", args->lambda, "Tikhonov regularisation weight (default: chosen by GCV)")
      ->check(NonNegativeFinite());
  cmd->add_option("--prior", args->prior, "Tikhonov prior")->capture_default_str()
      ->check(CLI::IsMember({"identity", "gradient", "laplacian"}));
  AddExecutionOptions(cmd, &args->exec);
  cmd->add_flag("--json", args->json, "print the results as JSON (no progress messages)");
  cmd->add_option("-o,--output", args->out_dir,
                  "write truth.fits, frames.fits (cube), psfs.fits, one FITS per method and montage.png here");
  cmd->callback([args] { RunDemo(*args); });
}

}  // namespace aosr::cli
