// A randomised end-to-end campaign (issue 24 item 6): random valid scenes and option sets through
// simulate -> reconstruct -> evaluate, using the library directly (scene_spec.hpp ParseScene, pipeline.hpp,
// dataset_memory.hpp DatasetFromSimulation, dataset_problem.hpp, reconstruct.hpp, evaluation.hpp), checking
// the invariants every run must keep, plus a share of deliberately invalid option sets that must be refused.
//
// Each run draws from its own seed (the campaign seed and the run index), so any run is reproduced alone with
// `aosr_campaign --seed S --run K`. A run draws: HR frame 32..96 px per side, r in {1..4}, N in {1..r²+2},
// telescope, AO mode (none / analytic), offsets (none / raster / inline random shifts), PSF window, 1-2 object
// components (stars, galaxies, dead-leaves, usaf, demo), detector noise (physical / peak-fraction / none),
// background, read noise, fill factor, bad pixels, saturation, gain and bias; dataset weights (auto / dataset /
// mask, optionally scaled per frame); the method (every ReconstructionMethod) with its options and small
// iteration caps; evaluation options.
//
// Invariants of a valid run (a failure prints the run's seed and options and makes the exit status 1):
//  * nothing but aosr::InvalidArgument escapes (counted as "refused", grouped by message); no other type;
//  * the simulated frames, the reconstruction and its aux map are finite, of the documented shapes;
//  * the evaluation's RMSE and SSIM are finite and its PSNR is not NaN;
//  * flux, only where the method's header promises it:
//      drizzle (drizzle.hpp "Conservation"): square / turbo / point kernels with periodic boundaries conserve
//        the weighted flux, summary.weighted_flux_out = weighted_flux_in; and with weights uniform within
//        each frame, no hole and a non-negative kernel, Σ I is a convex combination of the frame fluxes;
//      linear (target_psf.hpp "Flux"): on the Fourier-exact path with a 100 % fill factor the effective PSF
//        sums to 1, so Σ x̂ is the mean frame flux (every frame sees the DC bin the same way);
//      shift-add (shift_and_add.hpp): the mean of the frames brought to the HR grid by Dᵀ/r² and shifted
//        (Fourier shifts keep the DC): with no masked pixel Σ x̂ is the mean frame flux;
//  * determinism (DESIGN.md §4): rerunning the run (simulation included) gives the same bytes of image and
//    aux; every third run is rerun on 2 threads instead of 1.
// Invalid runs: one field of an otherwise valid run is broken (scene, problem, method or evaluation options);
// the run must end in aosr::InvalidArgument whose message names the field. Accepted or another exception
// type is a failure.
//
// Usage: aosr_campaign [--seed S] [--runs N] [--run K] [--verbose]
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <functional>
#include <limits>
#include <map>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "aosr/core/error.hpp"
#include "aosr/core/parallel.hpp"
#include "aosr/scene/dataset_memory.hpp"
#include "aosr/scene/evaluation.hpp"
#include "aosr/scene/pipeline.hpp"
#include "aosr/scene/scene_spec.hpp"
#include "aosr/solvers/dataset_problem.hpp"
#include "aosr/solvers/reconstruct.hpp"

namespace {

using aosr::Image;
using aosr::ImageStack;
using nlohmann::json;

std::uint64_t SplitMix(std::uint64_t x) {
  x += 0x9E3779B97F4A7C15ull;
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ull;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBull;
  return x ^ (x >> 31);
}

// A small deterministic generator (the same draws with every standard library).
class Rng {
 public:
  explicit Rng(std::uint64_t seed) : s_(seed) {}
  std::uint64_t Next() { return s_ = SplitMix(s_); }
  double Uniform(double a, double b) { return a + (b - a) * double(Next() >> 11) * 0x1.0p-53; }
  double LogUniform(double a, double b) { return std::exp(Uniform(std::log(a), std::log(b))); }
  int Int(int a, int b) { return a + int(Next() % std::uint64_t(b - a + 1)); }  // [a, b]
  bool Chance(double p) { return Uniform(0, 1) < p; }
  template <class T>
  T Pick(std::initializer_list<T> list) { return list.begin()[Int(0, int(list.size()) - 1)]; }

 private:
  std::uint64_t s_;
};

// What breaks an invalid run, and the substring its refusal must name.
struct Breakage {
  std::string name;    // the group in the report
  std::string expect;  // substring of the InvalidArgument message
};

struct RunConfig {
  std::uint64_t seed = 0;
  json scene;
  aosr::DatasetWeights weights = aosr::DatasetWeights::kAuto;
  std::vector<double> frame_weight_scale;  // empty: none
  aosr::ReconstructOptions options;
  aosr::EvaluationOptions evaluation;
  std::string method_detail;  // the drawn method options, for the reproduction line
  bool two_threads = false;
  // Invalid runs: which stage is broken (applied by the run).
  std::string break_stage;  // "" (valid) | "scene" | "problem" | "options" | "evaluation"
  std::function<void(aosr::ReconstructionProblem*)> break_problem;
  Breakage breakage;
};

const char* WeightsName(aosr::DatasetWeights w) {
  switch (w) {
    case aosr::DatasetWeights::kAuto: return "auto";
    case aosr::DatasetWeights::kDataset: return "dataset";
    case aosr::DatasetWeights::kMask: return "mask";
    case aosr::DatasetWeights::kBackground: return "background";
  }
  return "?";
}

json DrawScene(Rng& g, int* r_out) {
  // (The demo object needs an HR frame of at least 64 x 64: it is drawn only then.)
  const int r = g.Int(1, 4);
  *r_out = r;
  const int lo = (32 + r - 1) / r, hi = 96 / r;
  // The detector needs frames of at least 8 camera pixels (scene README).
  const int rows = std::max(8, g.Int(lo, hi)), cols = std::max(8, g.Int(lo, hi));
  const int n = g.Int(1, r * r + 2);
  json s;
  s["name"] = "campaign";
  s["seed"] = g.Int(1, 1000000);
  // paper-bench's camera pixel is 3.74 λ/D: it needs r = 4 (scene README, geometry checks).
  s["telescope"] = (r == 4 && g.Chance(0.3)) ? "paper-bench" : "paper-8m";
  s["frames"] = n;
  s["r"] = r;
  // paper-bench has no atmosphere: no analytic AO there.
  s["ao"] = {{"mode", g.Chance(0.4) && s["telescope"] == "paper-8m" ? "analytic" : "none"}};
  const int offsets = g.Int(0, 2);
  if (offsets == 1) {
    s["offsets"] = {{"type", "raster"}};
  } else if (offsets == 2) {
    json frames = json::array();
    for (int i = 0; i < n; ++i) {
      if (g.Chance(0.15)) {
        frames.push_back(json::object());
      } else {
        frames.push_back({{"shift_px", {g.Uniform(-1.5, 1.5), g.Uniform(-1.5, 1.5)}}});
      }
    }
    s["offsets"] = {{"type", "design"}, {"frames", frames}};
  }
  s["psf"] = {{"size_px", 2 * g.Int(3, 16)}};
  json objects = json::array();
  const int components = g.Int(1, 2);
  for (int c = 0; c < components; ++c) {
    json o;
    const bool demo_fits = r * rows >= 64 && r * cols >= 64;
    switch (g.Int(0, demo_fits ? 4 : 3)) {
      case 0:
        o = {{"type", "stars"}, {"count", g.Int(1, 20)}};
        break;
      case 1:
        o = {{"type", "galaxies"}, {"count", g.Int(1, 3)}};
        break;
      case 2:
        o = {{"type", "dead-leaves"}};
        break;
      case 3:
        o = {{"type", "usaf"}};
        break;
      default:
        o = {{"type", "demo"}};
        break;
    }
    if (g.Chance(0.5)) {
      o["flux"] = {{"peak_e", g.LogUniform(10, 1e5)}};
    } else {
      o["flux"] = {{"total_e", g.LogUniform(1e3, 1e7)}};
    }
    objects.push_back(o);
  }
  s["objects"] = objects;
  json d;
  d["frame_px"] = {rows, cols};
  const int noise = g.Int(0, 2);
  if (noise == 0) {
    d["noise"] = "physical";
    d["read_noise_e"] = g.Uniform(0, 10);
    d["photon_noise"] = g.Chance(0.8);
  } else if (noise == 1) {
    d["noise"] = "peak-fraction";
    d["peak_noise_fraction"] = g.LogUniform(1e-4, 0.1);
  } else {
    d["noise"] = "none";
  }
  if (g.Chance(0.5)) d["background_e_per_s"] = g.LogUniform(1, 1e4);
  if (g.Chance(0.3)) d["fill_factor"] = g.Uniform(0.3, 1.0);
  const double gain = g.Chance(0.5) ? 1.0 : g.Uniform(0.5, 4);
  const double bias = g.Chance(0.5) ? 0.0 : g.Uniform(0, 1000);
  d["gain_e_per_adu"] = gain;
  d["bias_adu"] = bias;
  d["saturation"] = g.Chance(0.2);
  if (d["saturation"].get<bool>()) d["saturation_adu"] = bias + g.LogUniform(100, 1e6);
  d["quantize"] = g.Chance(0.2);
  if (g.Chance(0.4)) d["bad_pixels"] = {{"fraction", g.Uniform(0, 0.05)}, {"seed", g.Int(0, 1000)}};
  s["detector"] = d;
  return s;
}

std::string DrawMethod(Rng& g, int r, aosr::ReconstructOptions* o) {
  using M = aosr::ReconstructionMethod;
  std::ostringstream detail;
  o->method = g.Pick({M::kShiftAddMean, M::kShiftAddMedian, M::kDrizzle, M::kTikhonov, M::kLinear,
                      M::kTotalVariation, M::kMap});
  detail << aosr::ToString(o->method);
  switch (o->method) {
    case M::kDrizzle: {
      using K = aosr::DrizzleKernel;
      o->drizzle.kernel = g.Pick({K::kSquare, K::kTurbo, K::kPoint, K::kGaussian, K::kLanczos3});
      o->drizzle.pixfrac = g.Chance(0.5) ? 1.0 : g.Uniform(0.2, 1.0);
      o->drizzle.boundary = g.Chance(0.7) ? aosr::DrizzleBoundary::kPeriodic : aosr::DrizzleBoundary::kClip;
      o->drizzle.compute_context = g.Chance(0.5);
      detail << " kernel=" << aosr::ToString(o->drizzle.kernel) << " pixfrac=" << o->drizzle.pixfrac
             << " boundary=" << (o->drizzle.boundary == aosr::DrizzleBoundary::kPeriodic ? "periodic" : "clip");
      break;
    }
    case M::kTikhonov: {
      using P = aosr::TikhonovPrior;
      using L = aosr::TikhonovLambdaRule;
      using T = aosr::TikhonovMethod;
      o->tikhonov.prior = g.Pick({P::kIdentity, P::kGradient, P::kLaplacian});
      o->tikhonov.lambda_rule = g.Pick({L::kFixed, L::kGcv, L::kLcurve});
      o->tikhonov.lambda = g.LogUniform(1e-5, 1);
      // (kFourier with weighted data, or GCV / L-curve on the CG path, is refused: a few such draws stay.)
      o->tikhonov.method = g.Pick({T::kAuto, T::kAuto, T::kAuto, T::kFourier, T::kConjugateGradient});
      o->tikhonov.cg = {g.Int(5, 60), 1e-8};
      o->tikhonov.boundary = g.Chance(0.8) ? aosr::TikhonovBoundary::kPeriodic : aosr::TikhonovBoundary::kZeroPadded;
      o->tikhonov.compute_std = g.Chance(0.3);
      if (o->tikhonov.compute_std) o->tikhonov.noise_sigma = 1.0;  // the std map needs σ (tikhonov.hpp)
      o->tikhonov.std_samples = 4;
      detail << " prior=" << int(o->tikhonov.prior) << " rule=" << int(o->tikhonov.lambda_rule)
             << " lambda=" << o->tikhonov.lambda << " solver=" << int(o->tikhonov.method)
             << " cg_max=" << o->tikhonov.cg.max_iterations << " boundary=" << int(o->tikhonov.boundary)
             << " std=" << o->tikhonov.compute_std;
      break;
    }
    case M::kLinear: {
      if (g.Chance(0.5)) {
        o->linear.kind = aosr::TargetPsfKind::kGaussian;
        o->linear.fwhm_hr_px = g.Uniform(std::max(1.0, double(r)), 6.0);
      }
      o->linear.leakage = g.Pick({1e-3, 1e-2, 0.1});
      o->linear.compute_noise = g.Chance(0.5);
      o->linear.noise_probes = 2;
      o->linear.cg = {g.Int(10, 100), 1e-8};
      detail << " target=" << int(o->linear.kind) << " fwhm=" << o->linear.fwhm_hr_px
             << " leakage=" << o->linear.leakage << " noise=" << o->linear.compute_noise
             << " cg_max=" << o->linear.cg.max_iterations;
      break;
    }
    case M::kTotalVariation: {
      o->tv.max_iterations = g.Int(3, 25);
      o->tv.positivity = g.Chance(0.5);
      o->tv.cg_max_iterations = 20;
      o->auto_regularisation = g.Chance(0.8);
      o->tv.mu = g.LogUniform(1e-4, 1);
      detail << " iterations=" << o->tv.max_iterations << " positivity=" << o->tv.positivity
             << " auto=" << o->auto_regularisation << " mu=" << o->tv.mu;
      break;
    }
    case M::kMap: {
      using P = aosr::MapPrior;
      o->map.prior = g.Pick({P::kTikhonov, P::kCharbonnierTv, P::kHuberTv});
      o->map.positivity = g.Chance(0.5) ? aosr::MapPositivity::kSoftplus : aosr::MapPositivity::kNone;
      o->map.max_iterations = g.Int(2, 15);
      o->auto_regularisation = g.Chance(0.8);
      o->map.lambda = g.LogUniform(1e-4, 1);
      detail << " prior=" << int(o->map.prior) << " positivity=" << int(o->map.positivity)
             << " iterations=" << o->map.max_iterations << " auto=" << o->auto_regularisation
             << " lambda=" << o->map.lambda;
      break;
    }
    default:
      break;
  }
  return detail.str();
}

// One field of a valid run broken, with the substring its refusal must contain.
void DrawBreakage(Rng& g, RunConfig* c) {
  using M = aosr::ReconstructionMethod;
  const double nan = std::nan("");
  switch (g.Int(0, 16)) {
    case 0:
      c->break_stage = "scene";
      c->scene["r"] = g.Pick({0, -1, 17});
      c->breakage = {"scene r out of range", "r"};
      break;
    case 1:
      c->break_stage = "scene";
      c->scene["frames"] = g.Pick({0, -3});
      c->breakage = {"scene frames out of range", "frames"};
      break;
    case 2:
      c->break_stage = "scene";
      c->scene["psf"]["size_px"] = 2 * g.Int(2, 8) + 1;
      c->breakage = {"scene psf size odd", "size_px"};
      break;
    case 3:
      c->break_stage = "scene";
      c->scene["detector"]["noise"] = "loud";
      c->breakage = {"scene noise model unknown", "noise"};
      break;
    case 4:
      c->break_stage = "options";
      c->options.method = M::kDrizzle;
      c->options.drizzle.pixfrac = g.Pick({0.0, -0.5, 1.5, nan});
      c->breakage = {"drizzle pixfrac out of (0, 1]", "pixfrac"};
      break;
    case 5:
      c->break_stage = "options";
      c->options.method = M::kTikhonov;
      c->options.tikhonov.lambda_rule = aosr::TikhonovLambdaRule::kFixed;
      c->options.tikhonov.lambda = g.Pick({-1.0, nan, std::numeric_limits<double>::infinity()});
      c->breakage = {"tikhonov lambda not finite > 0", "lambda"};
      break;
    case 6:
      c->break_stage = "options";
      c->options.method = M::kLinear;
      c->options.linear.leakage = g.Pick({0.0, 1.0, -0.1, nan});
      c->breakage = {"linear leakage out of (0, 1)", "leakage"};
      break;
    case 7:
      c->break_stage = "options";
      c->options.method = M::kLinear;
      c->options.linear.noise_sigma = g.Pick({0.0, -1.0, nan});
      c->breakage = {"linear noise_sigma not > 0", "noise_sigma"};
      break;
    case 8:
      c->break_stage = "options";
      c->options.method = M::kTotalVariation;
      c->options.tv.max_iterations = g.Pick({0, -5});
      c->breakage = {"tv max_iterations < 1", "max_iterations"};
      break;
    case 9:
      c->break_stage = "options";
      c->options.method = M::kMap;
      c->options.auto_regularisation = false;
      c->options.map.lambda = g.Pick({-1.0, nan});
      c->breakage = {"map lambda negative or NaN", "lambda"};
      break;
    case 10:
      c->break_stage = "problem";
      c->break_problem = [](aosr::ReconstructionProblem* p) {
        p->weights.assign(p->frames.size(), Image::Ones(p->frames[0].rows(), p->frames[0].cols()));
        p->weights.back()(0, 0) = -1.0;
      };
      c->breakage = {"problem weight negative", "weight"};
      break;
    case 11:
      c->break_stage = "problem";
      c->break_problem = [](aosr::ReconstructionProblem* p) {
        p->weights.assign(p->frames.size(), Image::Ones(p->frames[0].rows(), p->frames[0].cols()));
        p->frames.back()(1, 1) = std::nan("");
      };
      c->breakage = {"problem weighted frame pixel NaN", "frame"};
      break;
    case 12:
      c->break_stage = "problem";
      c->break_problem = [](aosr::ReconstructionProblem* p) {
        p->frames.push_back(Image::Zero(p->frames[0].rows() + 1, p->frames[0].cols()));
      };
      c->breakage = {"problem frame of the wrong shape", "frame"};
      break;
    case 13:
      c->break_stage = "evaluation";
      c->evaluation.crop_px = g.Pick({-1, 1000});
      c->breakage = {"evaluation crop_px out of range", "crop"};
      break;
    case 15:
      c->break_stage = "evaluation";
      c->evaluation.peak = g.Pick({-1.0, nan});
      c->breakage = {"evaluation peak negative or NaN", "peak"};
      break;
    case 16:
      c->break_stage = "evaluation";
      c->evaluation.stars = g.Pick({0, -2});
      c->breakage = {"evaluation stars < 1", "stars"};
      break;
    default:
      c->break_stage = "evaluation";
      c->evaluation.aperture_px = g.Pick({0.0, 2000.0, nan});
      c->breakage = {"evaluation aperture_px out of range", "aperture"};
      break;
  }
}

// The breakage is drawn last, so DrawRun(seed, run, false) is the same run unbroken.
RunConfig DrawRun(std::uint64_t campaign_seed, long run, bool allow_break = true) {
  RunConfig c;
  c.seed = SplitMix(campaign_seed * 0x100000001B3ull + std::uint64_t(run));
  Rng g(c.seed);
  int r = 1;
  c.scene = DrawScene(g, &r);
  c.weights = g.Pick({aosr::DatasetWeights::kAuto, aosr::DatasetWeights::kDataset, aosr::DatasetWeights::kMask});
  if (g.Chance(0.2)) {
    for (int i = 0; i < c.scene["frames"].get<int>(); ++i) c.frame_weight_scale.push_back(g.LogUniform(0.1, 10));
  }
  c.method_detail = DrawMethod(g, r, &c.options);
  c.evaluation.crop_px = g.Int(0, 3);
  c.evaluation.stars = g.Int(1, 20);
  c.evaluation.aperture_px = g.Uniform(1, 4);
  c.two_threads = run % 3 == 2;
  if (g.Chance(0.15) && allow_break) DrawBreakage(g, &c);
  return c;
}

std::string Describe(const RunConfig& c) {
  std::ostringstream s;
  s << "  scene: " << c.scene.dump() << "\n  weights: " << WeightsName(c.weights);
  if (!c.frame_weight_scale.empty()) s << " scaled per frame";
  s << "\n  method: " << c.method_detail << "\n  evaluation: crop_px=" << c.evaluation.crop_px
    << " stars=" << c.evaluation.stars << " aperture_px=" << c.evaluation.aperture_px;
  if (!c.break_stage.empty()) s << "\n  broken: " << c.breakage.name << " (stage " << c.break_stage << ")";
  return s.str();
}

bool AllFinite(const Image& x) { return x.size() == 0 || x.allFinite(); }

bool SameBytes(const Image& a, const Image& b) {
  return a.rows() == b.rows() && a.cols() == b.cols() &&
         (a.size() == 0 || std::memcmp(a.data(), b.data(), sizeof(double) * std::size_t(a.size())) == 0);
}

struct Outcome {
  aosr::Reconstruction rec;
  aosr::ReconstructionProblem problem;
  double fill_factor = 1.0;
};

// simulate -> reconstruct -> evaluate; throws whatever the library throws; pushes invariant failures.
Outcome RunOnce(const RunConfig& c, int threads, std::vector<std::string>* failures) {
  aosr::SetDefaultThreads(threads);
  const aosr::SceneSpec scene = aosr::ParseScene(c.scene, "<campaign>");
  const aosr::ScenePipeline pipeline(scene);
  const aosr::Simulation sim = pipeline.Run();
  const aosr::Dataset dataset = aosr::DatasetFromSimulation(scene, sim);
  for (const Image& f : dataset.frames)
    if (!f.allFinite()) failures->push_back("a simulated frame is not finite");
  aosr::DatasetProblemOptions dpo;
  dpo.weights = c.weights;
  Outcome out;
  out.fill_factor = scene.detector.fill_factor;
  aosr::DatasetProblem dp = aosr::ProblemFromDataset(dataset, dpo);
  out.problem = dp.problem;
  if (!c.frame_weight_scale.empty()) {
    ImageStack scaled;
    for (int i = 0; i < out.problem.frame_count(); ++i)
      scaled.push_back(out.problem.Weight(i) * c.frame_weight_scale[std::size_t(i)]);
    out.problem.weights = scaled;
  }
  if (c.break_problem) c.break_problem(&out.problem);
  out.rec = aosr::Reconstruct(out.problem, c.options);
  const aosr::Shape hr = out.problem.model->hr_shape();
  if (out.rec.image.rows() != hr.rows || out.rec.image.cols() != hr.cols)
    failures->push_back("reconstruction is not of the HR shape");
  if (!AllFinite(out.rec.image)) failures->push_back("reconstruction image is not finite");
  if (!AllFinite(out.rec.aux)) failures->push_back("reconstruction aux map (" + out.rec.aux_name + ") is not finite");
  const aosr::Evaluation ev = aosr::EvaluateReconstruction(sim.truth, out.rec.image, sim.stars, c.evaluation);
  if (!std::isfinite(ev.metrics.rmse) || !std::isfinite(ev.metrics.ssim) || std::isnan(ev.metrics.psnr) ||
      !std::isfinite(ev.aligned.rmse) || std::isnan(ev.aligned.psnr))
    failures->push_back("evaluation metrics are not finite (rmse " + std::to_string(ev.metrics.rmse) + ", ssim " +
                        std::to_string(ev.metrics.ssim) + ", psnr " + std::to_string(ev.metrics.psnr) + ")");
  return out;
}

// The flux promises of the method headers (see the top of the file).
void CheckFlux(const RunConfig& c, const Outcome& o, std::map<std::string, long>* checked,
               std::vector<std::string>* failures) {
  using M = aosr::ReconstructionMethod;
  const aosr::ReconstructionProblem& p = o.problem;
  const int n = p.frame_count();
  std::vector<double> flux(std::size_t(n), 0.0);
  double abs_scale = 0.0;  // Σ |y| over weighted pixels, for tolerances
  bool any_masked = false, uniform_within_frames = true;
  for (int i = 0; i < n; ++i) {
    const Image w = p.Weight(i);
    for (aosr::Index k = 0; k < w.size(); ++k) {
      if (w.data()[k] > 0) {
        flux[std::size_t(i)] += p.frames[std::size_t(i)].data()[k];
        abs_scale += std::abs(p.frames[std::size_t(i)].data()[k]);
      } else {
        any_masked = true;
      }
      if (w.data()[k] != w.data()[0]) uniform_within_frames = false;
    }
  }
  double mean_flux = 0, min_flux = flux[0], max_flux = flux[0];
  for (double f : flux) mean_flux += f / n, min_flux = std::min(min_flux, f), max_flux = std::max(max_flux, f);
  const double image_sum = o.rec.image.sum();
  const double tol = 1e-8 * (abs_scale / n + 1e-300);
  char buf[256];
  const bool all_direct = !any_masked && std::abs(o.fill_factor - 1.0) < 1e-15;
  if (c.options.method == M::kShiftAddMean && !any_masked) {
    ++(*checked)["shift-add sum = mean frame flux"];
    if (std::abs(image_sum - mean_flux) > tol) {
      std::snprintf(buf, sizeof buf, "shift-add: sum %.17g != mean frame flux %.17g (tol %.3g)", image_sum, mean_flux, tol);
      failures->push_back(buf);
    }
  }
  if (c.options.method == M::kLinear && o.rec.linear && o.rec.linear->fourier_exact && all_direct) {
    ++(*checked)["linear (Fourier-exact) sum = mean frame flux"];
    if (std::abs(image_sum - mean_flux) > tol) {
      std::snprintf(buf, sizeof buf, "linear (Fourier-exact): sum %.17g != mean frame flux %.17g (tol %.3g)", image_sum,
                    mean_flux, tol);
      failures->push_back(buf);
    }
  }
  if (c.options.method == M::kDrizzle) {
    // Reconstruct returns the weight map W as aux; recompute Σ W I and Σ w y / r² from the problem.
    const int r = p.model->r();
    double in = 0, in_abs = 0;
    for (int i = 0; i < n; ++i) {
      const Image w = p.Weight(i);
      for (aosr::Index k = 0; k < w.size(); ++k)
        if (w.data()[k] > 0) {
          in += w.data()[k] * p.frames[std::size_t(i)].data()[k] / (r * r);
          in_abs += std::abs(w.data()[k] * p.frames[std::size_t(i)].data()[k] / (r * r));
        }
    }
    const Image& W = o.rec.aux;
    double out = 0;
    aosr::Index holes = 0;
    for (aosr::Index k = 0; k < W.size(); ++k) {
      if (W.data()[k] > 0) out += W.data()[k] * o.rec.image.data()[k];
      else ++holes;
    }
    using K = aosr::DrizzleKernel;
    const K kernel = c.options.drizzle.kernel;
    const bool periodic = c.options.drizzle.boundary == aosr::DrizzleBoundary::kPeriodic;
    const bool conserving_kernel = kernel == K::kSquare || kernel == K::kTurbo || kernel == K::kPoint;
    if (periodic && conserving_kernel) ++(*checked)["drizzle weighted flux out = in"];
    if (periodic && conserving_kernel && std::abs(out - in) > 1e-9 * (in_abs + 1e-300)) {
      std::snprintf(buf, sizeof buf, "drizzle: weighted flux out %.17g != in %.17g", out, in);
      failures->push_back(buf);
    }
    const bool convex = periodic && kernel != K::kLanczos3 && holes == 0 && uniform_within_frames;
    if (convex) ++(*checked)["drizzle image flux within the frame fluxes"];
    if (convex && (image_sum < min_flux - tol || image_sum > max_flux + tol)) {
      std::snprintf(buf, sizeof buf, "drizzle: image flux %.17g outside the frame fluxes [%.17g, %.17g]", image_sum,
                    min_flux, max_flux);
      failures->push_back(buf);
    }
  }
}

struct Tally {
  long runs = 0, passed = 0, failed = 0, valid = 0, invalid = 0;
  std::map<std::string, long> refused_valid;    // valid runs refused, by message (up to the first ';')
  std::map<std::string, long> refused_invalid;  // invalid runs refused, by breakage
  std::map<std::string, long> methods;
  std::map<std::string, long> flux_checked;
  long reruns = 0;
};

std::string Group(const std::string& message) {
  std::string g = message.substr(0, message.find(';'));
  // Drop values so that one rule is one group: cut at the first '=' or digit run after the field name.
  const auto eq = g.find(" = ");
  if (eq != std::string::npos) g = g.substr(0, eq);
  return g.size() > 110 ? g.substr(0, 110) : g;
}

// Returns true if the run passed.
bool DoRun(std::uint64_t campaign_seed, long run, bool verbose, Tally* t) {
  const RunConfig c = DrawRun(campaign_seed, run);
  ++t->runs;
  std::vector<std::string> failures;
  const bool invalid = !c.break_stage.empty();
  invalid ? ++t->invalid : ++t->valid;
  std::string refused;
  Outcome first;
  try {
    first = RunOnce(c, 1, &failures);
  } catch (const aosr::InvalidArgument& e) {
    refused = e.what();
  } catch (const std::exception& e) {
    failures.push_back(std::string("unexpected exception (not aosr::InvalidArgument): ") + e.what());
  } catch (...) {
    failures.push_back("unexpected exception of a non-std type");
  }
  if (failures.empty() && invalid) {
    if (refused.empty()) {
      failures.push_back("accepted an invalid input (" + c.breakage.name + ")");
    } else if (refused.find(c.breakage.expect) == std::string::npos) {
      // Refused for another reason: fine if the unbroken run is refused with the same message (the broken
      // field is never reached); otherwise the refusal names the wrong field.
      std::string unbroken_refusal;
      std::vector<std::string> ignored;
      try {
        (void)RunOnce(DrawRun(campaign_seed, run, false), 1, &ignored);
      } catch (const aosr::InvalidArgument& e) {
        unbroken_refusal = e.what();
      } catch (const std::exception&) {
      }
      if (unbroken_refusal == refused) {
        ++t->refused_valid[Group(refused)];
      } else {
        failures.push_back("refusal does not name '" + c.breakage.expect + "': " + refused);
      }
    } else {
      ++t->refused_invalid[c.breakage.name];
    }
  } else if (failures.empty() && !refused.empty()) {
    ++t->refused_valid[Group(refused)];
    if (verbose) std::printf("run %ld refused: %s\n", run, refused.c_str());
  } else if (failures.empty()) {
    ++t->methods[aosr::ToString(c.options.method)];
    CheckFlux(c, first, &t->flux_checked, &failures);
    // Determinism: the same bytes on a rerun (simulation included), on 2 threads for every third run.
    std::vector<std::string> rerun_failures;
    try {
      const Outcome again = RunOnce(c, c.two_threads ? 2 : 1, &rerun_failures);
      ++t->reruns;
      if (!SameBytes(first.rec.image, again.rec.image) || !SameBytes(first.rec.aux, again.rec.aux))
        failures.push_back(std::string("rerun") + (c.two_threads ? " on 2 threads" : "") +
                           " gave different bytes (max |diff| " +
                           (first.rec.image.rows() == again.rec.image.rows() && first.rec.image.cols() == again.rec.image.cols()
                                ? std::to_string((first.rec.image - again.rec.image).cwiseAbs().maxCoeff())
                                : std::string("shape")) +
                           ")");
    } catch (const std::exception& e) {
      failures.push_back(std::string("rerun threw: ") + e.what());
    }
    aosr::SetDefaultThreads(1);
  }
  if (!failures.empty()) {
    ++t->failed;
    std::printf("FAILED run %ld: reproduce with: aosr_campaign --seed %llu --run %ld\n%s\n", run,
                static_cast<unsigned long long>(campaign_seed), run, Describe(c).c_str());
    for (const std::string& f : failures) std::printf("  failure: %s\n", f.c_str());
    std::fflush(stdout);
    return false;
  }
  ++t->passed;
  if (verbose) std::printf("run %ld ok: %s\n", run, c.method_detail.c_str());
  return true;
}

}  // namespace

int main(int argc, char** argv) {
  std::uint64_t seed = 1;
  long runs = 300, only = -1;
  bool verbose = false;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--seed" && i + 1 < argc) {
      seed = std::strtoull(argv[++i], nullptr, 10);
    } else if (a == "--runs" && i + 1 < argc) {
      runs = std::strtol(argv[++i], nullptr, 10);
    } else if (a == "--run" && i + 1 < argc) {
      only = std::strtol(argv[++i], nullptr, 10);
    } else if (a == "--verbose") {
      verbose = true;
    } else {
      std::fprintf(stderr, "usage: %s [--seed S] [--runs N] [--run K] [--verbose]\n", argv[0]);
      return 2;
    }
  }
  Tally t;
  if (only >= 0) {
    verbose = true;
    std::printf("%s\n", Describe(DrawRun(seed, only)).c_str());
    DoRun(seed, only, verbose, &t);
  } else {
    for (long k = 0; k < runs; ++k) DoRun(seed, k, verbose, &t);
  }
  long refused_valid = 0, refused_invalid = 0;
  for (const auto& [k, v] : t.refused_valid) refused_valid += v;
  for (const auto& [k, v] : t.refused_invalid) refused_invalid += v;
  std::printf("campaign seed %llu: %ld runs (%ld valid, %ld deliberately invalid)\n",
              static_cast<unsigned long long>(seed), t.runs, t.valid, t.invalid);
  std::printf("completed valid runs by method:");
  for (const auto& [k, v] : t.methods) std::printf(" %s %ld", k.c_str(), v);
  std::printf("\nrefused: %ld (%ld of the valid draws, %ld of the invalid ones)\n", refused_valid + refused_invalid,
              refused_valid, refused_invalid);
  for (const auto& [k, v] : t.refused_valid) std::printf("  %4ld  valid draw: %s\n", v, k.c_str());
  for (const auto& [k, v] : t.refused_invalid) std::printf("  %4ld  invalid: %s\n", v, k.c_str());
  std::printf("flux checks:");
  for (const auto& [k, v] : t.flux_checked) std::printf(" [%s] %ld;", k.c_str(), v);
  std::printf("\nreruns compared byte for byte: %ld (on 2 threads: every third)\n", t.reruns);
  std::printf("%ld passed, %ld failed\n", t.passed, t.failed);
  return t.failed == 0 ? 0 : 1;
}
