// `aosr demo`: simulate the built-in scene, reconstruct it with each family of methods (Drizzle, Tikhonov, the
// target-PSF linear output, TV, MAP) through the library's one entry point, report quality and time, and draw
// a labelled montage.
#include <algorithm>
#include <cmath>
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
#include "aosr/io/plot.hpp"
#include "aosr/io/wcs.hpp"
#include "aosr/scene/demo.hpp"
#include "aosr/scene/objects.hpp"
#include "aosr/scene/usaf_contrast.hpp"
#include "aosr/core/operators.hpp"
#include "aosr/solvers/reconstruct.hpp"
#include "aosr/solvers/shift_and_add.hpp"
#include "cli_util.hpp"
#include "commands.hpp"

namespace aosr::cli {
namespace {

struct DemoArgs {
  DemoOptions scene;
  double lambda = -1;  // < 0: choose by GCV
  std::string prior = "gradient";
  bool map = true;     // --no-map leaves MAP out (the slowest method)
  int map_iterations = 40;  // L-BFGS cap for MAP (0: the library's default, to convergence)
  bool json = false;
  std::string out_dir;
  ExecutionArgs exec;
};

struct MethodResult {
  std::string method;  // file stem and JSON name
  std::string label;   // the montage's panel title
  Image estimate;
  ImageMetrics metrics;
  double seconds = 0;
  std::string note;
  bool in_montage = true;
  std::string panel_note;      // extra montage text (the linear output's score against its own PSF)
  int iterations = 0;          // iterative methods' iterations (0 for direct ones)
  std::string termination = "converged";
  UsafResolvingPower usaf;     // resolving power on the demo's USAF target (scene/usaf_contrast.hpp)
};

// The finest resolved element as "G.E" and its frequency per camera pixel and per λ/D ("-" when none).
struct DemoFinest {
  std::string element = "-";
  double per_camera_px = 0, per_lambda_over_d = 0;
  explicit DemoFinest(const UsafResolvingPower& p) {
    if (p.finest < 0) return;
    const UsafElementContrast& e = p.elements[std::size_t(p.finest)];
    element = "G" + std::to_string(e.group) + " E" + std::to_string(e.element);
    per_camera_px = e.cycles_per_camera_px;
    per_lambda_over_d = e.cycles_per_lambda_over_d;
  }
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

// Frame 0 as the camera saw it, on the HR grid: each camera pixel an r x r block of its flux / r² (flux per HR
// pixel, so it shares the truth's display range), as recorded (with its sub-pixel raster shift).
Image FrameAtCameraSampling(const DemoScene& s) {
  const int r = s.options.r;
  const Image& f = s.frames.front();
  Image out(f.rows() * r, f.cols() * r);
  for (Index y = 0; y < out.rows(); ++y)
    for (Index x = 0; x < out.cols(); ++x) out(y, x) = f(y / r, x / r) / double(r * r);
  return out;
}

// The montage (montage.png): for every block of up to four panels a row of whole images (HR grid, one screen
// pixel per HR pixel) and below it the same panels zoomed 4x on the finest USAF bars (the orange box), all
// on the truth's display range (linear, clipped). Each panel is labelled with the method and its scores.
void WriteMontage(const std::string& path, const DemoScene& s, const std::vector<MethodResult>& results) {
  const double lo = s.truth.minCoeff(), hi = s.truth.maxCoeff();
  auto display = [lo, hi](const Image& v) -> Image { return ((v - lo) / (hi - lo)).min(1.0).max(0.0); };
  // The inset: a square around the two finest USAF groups, clipped to the grid.
  const Shape hr = ShapeOf(s.truth);
  const PixelRect bars = DemoFinestBars(hr);
  // Magnified to about the whole panels' size (256 screen px at most): the largest integer zoom that shows the
  // bars with a margin, then as much field as that zoom fills.
  const Index screen = std::min<Index>({hr.rows, hr.cols, 256});
  const Index needed = Index(std::ceil(std::max(bars.height, bars.width))) + 8;
  const int zoom = int(std::max<Index>(1, screen / std::max<Index>(1, needed)));
  const Index side = std::min<Index>({screen / zoom, hr.rows, hr.cols});
  const Index cy = Index(std::lround(bars.top + bars.height / 2)), cx = Index(std::lround(bars.left + bars.width / 2));
  PanelBox box;
  box.height = box.width = side;
  box.top = std::clamp<Index>(cy - side / 2, 0, hr.rows - side);
  box.left = std::clamp<Index>(cx - side / 2, 0, hr.cols - side);
  auto score = [](const MethodResult& r) {
    char buf[96];
    std::snprintf(buf, sizeof buf, "PSNR %.1f dB  SSIM %.2f\n%.2f s", r.metrics.psnr, r.metrics.ssim, r.seconds);
    std::string out = buf;
    if (r.iterations > 0) out += ", " + std::to_string(r.iterations) + " iterations";
    if (!r.panel_note.empty()) out += "; " + r.panel_note;
    return out;
  };
  const int r = s.options.r;
  std::vector<ImagePanel> whole, zoomed;
  auto add = [&](const Image& img, const std::string& title, const std::string& subtitle) {
    ImagePanel p;
    p.image = display(img);
    p.title = title;
    p.subtitle = subtitle;
    p.boxes = {box};
    whole.push_back(p);
    ImagePanel z;
    z.image = p.image.block(box.top, box.left, box.height, box.width);
    z.title = title + ", zoom " + std::to_string(zoom) + "x";
    z.subtitle = "finest bars (orange box)";
    z.zoom = zoom;
    zoomed.push_back(z);
  };
  add(s.truth, "truth", std::to_string(hr.rows) + " x " + std::to_string(hr.cols) + " HR px\nthe object");
  add(FrameAtCameraSampling(s), "input frame 1 of " + std::to_string(s.options.frames),
      std::to_string(s.options.lr_size) + " x " + std::to_string(s.options.lr_size) + " camera px\neach shown as " +
          std::to_string(r) + " x " + std::to_string(r) + " HR px");
  for (const MethodResult& m : results)
    if (m.in_montage) add(m.estimate, m.label, score(m));
  const int columns = 4;
  std::vector<ImagePanel> cells;
  for (std::size_t start = 0; start < whole.size(); start += columns) {
    const std::size_t stop = std::min(whole.size(), start + columns);
    for (std::size_t i = start; i < stop; ++i) cells.push_back(whole[i]);
    for (std::size_t i = stop; i < start + columns && start > 0; ++i) cells.push_back({Image::Ones(1, 1), "", "", 1, {}});
    for (std::size_t i = start; i < stop; ++i) cells.push_back(zoomed[i]);
    for (std::size_t i = stop; i < start + columns && start > 0; ++i) cells.push_back({Image::Ones(1, 1), "", "", 1, {}});
  }
  PanelFigureOptions fo;
  fo.columns = int(std::min<std::size_t>(columns, whole.size()));
  fo.gap_px = 10;
  fo.text_scale = 0.5;
  char caption[512];
  std::snprintf(caption, sizeof caption,
                "aosr demo: %d sub-exposures dithered by the DM, camera pixels of %.3g lambda/D (%.3gx coarser than "
                "Nyquist), reconstructed on a %dx finer grid.\nPSNR/SSIM against the truth; all panels on the truth's "
                "grey scale (linear, clipped). Lower rows: the orange box zoomed %dx.",
                s.options.frames, s.options.camera_pixel_lambda_over_d, s.options.camera_pixel_lambda_over_d / 0.5, r,
                zoom);
  fo.caption = caption;
  WriteRgbImage(path, RenderImagePanels(cells, fo));
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
  for (const MethodResult& r : results)
    WriteFits(JoinPath(dir, r.method + ".fits"), r.estimate, SceneHeader(s, r.method, hr_wcs));
  WriteMontage(JoinPath(dir, "montage.png"), s, results);
}

void RunDemo(const DemoArgs& args) {
  const Progress progress(!args.json);
  Stopwatch total;
  ApplyExecution(args.exec);
  ReconstructOptions base;  // the library's defaults, as `aosr reconstruct` runs them
  if (args.lambda >= 0) {
    base.tikhonov.lambda_rule = TikhonovLambdaRule::kFixed;
    base.tikhonov.lambda = args.lambda;
  }
  base.tikhonov.prior = ParseTikhonovPrior(args.prior);
  base.drizzle.compute_context = false;
  std::string why;
  if (!base.tikhonov.IsValid(&why)) throw InvalidArgument("aosr demo: " + why);

  if (!args.out_dir.empty()) EnsureDirectory(args.out_dir);  // fail before any computation

  progress.Step("simulating " + std::to_string(args.scene.frames) + " frames of " +
                std::to_string(args.scene.lr_size) + "x" + std::to_string(args.scene.lr_size) + " pixels, r = " +
                std::to_string(args.scene.r));
  Stopwatch sim_clock;
  const DemoScene scene = MakeDemoScene(args.scene);
  const double sim_seconds = sim_clock.Seconds();

  // One problem for every method: the frames, the model that made them, the raster offsets (registration
  // methods), uniform weights (the demo's noise is white and the same in every pixel).
  ReconstructionProblem problem;
  problem.model = scene.model;
  problem.frames = scene.frames;
  problem.offsets = scene.offsets;
  base.linear.noise_sigma = scene.noise_sigma;  // weight-1 pixels have the frames' σ: noise figures absolute

  std::vector<MethodResult> results;
  {
    progress.Step("bicubic upsampling of frame 0");
    Stopwatch c;
    results.push_back({"bicubic", "bicubic (1 frame)", BicubicUpsample(scene.frames[0], scene.options.r), {}, 0,
                       "one frame", false, "", 0, "converged", {}});
    results.back().seconds = c.Seconds();
  }
  double tikhonov_lambda = 0, tv_mu = 0;
  std::optional<ImageMetrics> linear_through_psf;
  struct Run {
    ReconstructionMethod method;
    const char* name;
    const char* label;
    const char* step;
  };
  std::vector<Run> runs = {
      {ReconstructionMethod::kDrizzle, "drizzle", "Drizzle", "Drizzle (square drops, pixfrac 1)"},
      {ReconstructionMethod::kTikhonov, "tikhonov", "Tikhonov", "Tikhonov (exact Fourier solve)"},
      {ReconstructionMethod::kLinear, "linear", "linear (target PSF)", "linear with a target PSF (exact Fourier solve)"},
      {ReconstructionMethod::kTotalVariation, "tv", "TV", "total variation (ADMM, automatic weight)"}};
  const std::string map_label =
      args.map_iterations > 0 ? "MAP (" + std::to_string(args.map_iterations) + " iterations)" : std::string("MAP");
  if (args.map) runs.push_back({ReconstructionMethod::kMap, "map", map_label.c_str(), "MAP (L-BFGS, warm-started by Tikhonov)"});
  for (const Run& run : runs) {
    progress.Step(run.step);
    ReconstructOptions o = base;
    o.method = run.method;
    if (args.map_iterations > 0) o.map.max_iterations = args.map_iterations;
    Reconstruction rec = Reconstruct(problem, o);
    MethodResult m{run.name, run.label, std::move(rec.image), {}, rec.seconds_total, rec.summary.message, true,
                   "", rec.summary.iterations, ToString(rec.summary.termination), {}};
    if (run.method == ReconstructionMethod::kTikhonov) tikhonov_lambda = rec.regularisation;
    if (run.method == ReconstructionMethod::kTotalVariation) tv_mu = rec.regularisation;
    if (run.method == ReconstructionMethod::kLinear) {
      // A linear output estimates the truth seen through its effective PSF: score it against that as well.
      const Shape hr = ShapeOf(scene.truth);
      if (rec.effective_psf.size() && rec.effective_psf.rows() <= hr.rows && rec.effective_psf.cols() <= hr.cols) {
        linear_through_psf = CompareImages(
            ToImage(PeriodicConvolutionFromKernel(hr, rec.effective_psf)->Apply(AsVector(scene.truth)), hr), m.estimate, {});
        char buf[64];
        std::snprintf(buf, sizeof buf, "%.1f dB vs truth*PSF", linear_through_psf->psnr);
        m.panel_note = buf;
      }
    }
    results.push_back(std::move(m));
  }
  // Resolving power on the USAF target of the demo's truth (scene/objects.hpp DemoObject), at the Rayleigh
  // contrast 0.153, beside PSNR; the truth's own is the finest the HR grid represents.
  UsafContrastOptions uo;
  uo.r = scene.options.r;
  uo.hr_pixel_lambda_over_d = scene.options.camera_pixel_lambda_over_d / scene.options.r;
  const UsafOptions target = DemoUsafOptions(ShapeOf(scene.truth));
  const UsafResolvingPower truth_usaf = MeasureUsafResolvingPower(scene.truth, target, uo);
  for (MethodResult& r : results) {
    r.metrics = CompareImages(scene.truth, r.estimate, {});
    r.usaf = MeasureUsafResolvingPower(r.estimate, target, uo);
  }
  auto usaf_json = [&uo](const UsafResolvingPower& p) {
    const DemoFinest f(p);
    return nlohmann::json{{"threshold", uo.threshold},
                          {"finest_element", p.finest < 0 ? nlohmann::json(nullptr) : nlohmann::json(f.element)},
                          {"cycles_per_camera_px", p.finest < 0 ? nlohmann::json(nullptr) : nlohmann::json(f.per_camera_px)},
                          {"cycles_per_lambda_over_d", p.finest < 0 ? nlohmann::json(nullptr) : nlohmann::json(f.per_lambda_over_d)}};
  };

  if (!args.out_dir.empty()) {
    progress.Step("writing " + args.out_dir + " (FITS files, montage.png)");
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
                              {"label", r.label},
                              {"psnr_db", r.metrics.psnr},
                              {"ssim", r.metrics.ssim},
                              {"rmse", r.metrics.rmse},
                              {"seconds", r.seconds},
                              {"in_montage", r.in_montage},
                              {"iterations", r.iterations},
                              {"termination", r.termination},
                              {"usaf", usaf_json(r.usaf)},
                              {"note", r.note}});
    j["usaf_truth"] = usaf_json(truth_usaf);
    j["tikhonov"] = {{"lambda", tikhonov_lambda},
                     {"lambda_rule", args.lambda >= 0 ? "fixed" : "gcv"},
                     {"prior", ToString(base.tikhonov.prior)}};
    j["tv"] = {{"mu", tv_mu}, {"mu_rule", "automatic (include/aosr/solvers/reconstruct.hpp)"}};
    if (linear_through_psf)
      j["linear_against_truth_through_psf"] = {{"psnr_db", linear_through_psf->psnr}, {"ssim", linear_through_psf->ssim}};
    if (!args.out_dir.empty()) {
      j["output_dir"] = args.out_dir;
      j["montage"] = JoinPath(args.out_dir, "montage.png");
    }
    j["total_seconds"] = total.Seconds();
    std::printf("%s\n", j.dump(2).c_str());
    return;
  }
  std::printf("aosr demo: %lldx%lld camera frames, N = %d, r = %d, noise sigma = %.3g (%.2g%% of max)\n",
              static_cast<long long>(scene.options.lr_size), static_cast<long long>(scene.options.lr_size),
              scene.options.frames, scene.options.r, scene.noise_sigma, 100 * scene.options.noise_fraction);
  std::printf("%-10s %10s %8s %10s %9s  %-8s %9s %9s  %s\n", "method", "PSNR [dB]", "SSIM", "RMSE", "seconds", "USAF",
              "cyc/cpx", "cyc/(l/D)", "iterations");
  auto usaf_cols = [](const UsafResolvingPower& p) {
    const DemoFinest f(p);
    char b[64];
    if (p.finest < 0) std::snprintf(b, sizeof b, "%-8s %9s %9s", "-", "-", "-");
    else std::snprintf(b, sizeof b, "%-8s %9.3f %9.3f", f.element.c_str(), f.per_camera_px, f.per_lambda_over_d);
    return std::string(b);
  };
  for (const MethodResult& r : results)
    std::printf("%-10s %10.2f %8.4f %10.4g %9.3f  %s  %s\n", r.method.c_str(), r.metrics.psnr, r.metrics.ssim,
                r.metrics.rmse, r.seconds, usaf_cols(r.usaf).c_str(),
                r.iterations > 0 ? (std::to_string(r.iterations) + " (" + r.termination + ")").c_str() : "-");
  std::printf("USAF: the finest element (group G, element E) resolved at Michelson contrast >= %.3f (Rayleigh) in both "
              "orientations, in cycles per camera pixel and per lambda/D; the truth's: %s\n",
              uo.threshold, usaf_cols(truth_usaf).c_str());
  if (linear_through_psf)
    std::printf("linear against the truth seen through its effective PSF: PSNR %.2f dB, SSIM %.4f\n",
                linear_through_psf->psnr, linear_through_psf->ssim);
  std::printf("PSNR peak = max(truth) - min(truth); simulation %.3f s; total %.3f s\n", sim_seconds, total.Seconds());
  if (!args.out_dir.empty())
    std::printf("outputs written to %s (montage: %s)\n", args.out_dir.c_str(), JoinPath(args.out_dir, "montage.png").c_str());
}

}  // namespace

void RegisterDemo(CLI::App& app) {
  auto args = std::make_shared<DemoArgs>();
  CLI::App* cmd = app.add_subcommand(
      "demo",
      "Simulate the built-in scene (USAF target and stars, 8 m telescope, K band, N tip/tilt-dithered "
      "sub-exposures on a camera 2x coarser than Nyquist), reconstruct it by Drizzle, Tikhonov, the target-PSF "
      "linear output, TV and MAP (and a single-frame bicubic baseline), and print PSNR, SSIM and time per method; "
      "-o also writes a labelled montage.");
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
  cmd->add_flag("!--no-map", args->map, "leave MAP (the slowest method) out");
  cmd->add_option("--map-iterations", args->map_iterations,
                  "MAP: L-BFGS iteration cap (0: to convergence, ~9x slower and no better on the default scene)")
      ->capture_default_str()->check(CLI::Range(0, 100000));
  AddExecutionOptions(cmd, &args->exec);
  cmd->add_flag("--json", args->json, "print the results as JSON (no progress messages)");
  cmd->add_option("-o,--output", args->out_dir,
                  "write truth.fits, frames.fits (cube), psfs.fits, one FITS per method and montage.png (labelled panels and "
                  "zoomed insets of the finest bars) here");
  cmd->callback([args] { RunDemo(*args); });
}

}  // namespace aosr::cli
