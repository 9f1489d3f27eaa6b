// Phase-design benchmark: the cost of objective A (design_objective.hpp) on the paper's system, against the
// floor of the transforms it must do, and one OptimizeDesign run per parameterisation.
//
// System: data/scenes/paper-sim-r2.json (paper-8m: 8 m pupil on n px, K band, camera pixel λ/D, analytic AO
// model of its 17x17 DM) through DesignOpticsFromScene, N = 4; and the same scene with "r": 4 set in its JSON
// before parsing (as `aosr simulate --set r=4` does, so the PSF window keeps its angular size and the design
// grid M doubles).
//
// Table 1, one evaluation with gradient, for R ∈ {0, 1, 2} realisations × L ∈ {1, 4} screens × threads {1, 2}
// (R = 0 ignores L: the nominal model only; such rows are printed once per thread count):
//   time        median of repeated Evaluate(opds, &grad) at the classic raster (>= 3 runs and >= 1 s), after
//               an untimed warm-up that makes the FFTW plans
//   FFTs        FftExecutionCount() difference over one evaluation (every aosr transform)
//   props       field propagations N (1 + R L) (and as many adjoints): the header's "N (1 + R L) MFTs"; on the
//               periodic path (design_psf.hpp: the PSF period Q = n λ/(D θ_hr) is a multiple of M) each is a
//               Q x Q complex FFT and its inverse instead of an MFT onto M x M and its adjoint
//   MxM pairs   OTF transforms: one forward (h -> H) and one inverse (Γ_H -> ∂J/∂h) per PSF, N (1 + R)
//   floor       props x t_prop + MxM pairs x t_pair (single thread), with t_prop the raw cost of one
//               propagation pair on the path in use and t_pair of one M x M pair, both measured here with
//               FFTW (FFTW_MEASURE plans) or Eigen's dense products for the MFT
//   ratio       time / (floor / threads): how far the evaluation is from doing only its transforms
// Table 2: OptimizeDesign with 1 start and max_iterations 30 for raster, tiptilt, zernike (20 modes) and
// actuators on the r = 2 system with the objective's defaults (R = 2, L = 4, gradient prior, λ = 1e-2),
// threads 2.
//
// Usage: build/bench/design_bench [--quick] [--out FILE]
//   --quick  r = 2 only, threads 1, 10 iterations (~20 s): a smoke run
//   --out    also write the Markdown report to FILE (e.g. bench/results/design.md)
#include <fftw3.h>

#include <Eigen/Core>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <complex>
#include <cstdio>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "aosr/core/memory.hpp"
#include "aosr/core/fft.hpp"
#include "aosr/design/design_objective.hpp"
#include "aosr/design/design_optimizer.hpp"
#include "aosr/design/design_parameterisation.hpp"
#include "aosr/io/config.hpp"
#include "aosr/scene/scene_spec.hpp"
#include "aosr/scene/telescope.hpp"

namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;
using aosr::Image;
using aosr::Index;

double Since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

std::string Fmt(const char* f, double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, f, v);
  return buf;
}

// Median seconds of fn() over batches (each >= 0.2 s or 1 run), at least 5 batches.
template <typename F>
double MedianSeconds(F fn) {
  fn();  // warm-up
  int reps = 1;
  for (;;) {
    const auto t0 = Clock::now();
    for (int k = 0; k < reps; ++k) fn();
    if (Since(t0) > 0.05 || reps > 1 << 20) break;
    reps *= 2;
  }
  std::vector<double> batches;
  for (int b = 0; b < 5; ++b) {
    const auto t0 = Clock::now();
    for (int k = 0; k < reps; ++k) fn();
    batches.push_back(Since(t0) / reps);
  }
  std::sort(batches.begin(), batches.end());
  return batches[2];
}

// One M x M out-of-place r2c + c2r FFTW pair.
double FftPairSeconds(int m) {
  double* in = fftw_alloc_real(std::size_t(m) * m);
  fftw_complex* out = fftw_alloc_complex(std::size_t(m) * (m / 2 + 1));
  fftw_plan f = fftw_plan_dft_r2c_2d(m, m, in, out, FFTW_MEASURE);
  fftw_plan b = fftw_plan_dft_c2r_2d(m, m, out, in, FFTW_MEASURE);
  for (int i = 0; i < m * m; ++i) in[i] = (i % 7) * 0.1;
  const double t = MedianSeconds([&] {
    fftw_execute(f);
    fftw_execute(b);
  });
  fftw_destroy_plan(f);
  fftw_destroy_plan(b);
  fftw_free(in);
  fftw_free(out);
  return t;
}

// One Q x Q complex forward + backward FFTW pair (the periodic path's propagation and its adjoint).
double ComplexFftPairSeconds(int q) {
  fftw_complex* a = fftw_alloc_complex(std::size_t(q) * q);
  fftw_complex* b = fftw_alloc_complex(std::size_t(q) * q);
  fftw_plan f = fftw_plan_dft_2d(q, q, a, b, FFTW_FORWARD, FFTW_MEASURE);
  fftw_plan g = fftw_plan_dft_2d(q, q, b, a, FFTW_BACKWARD, FFTW_MEASURE);
  for (int i = 0; i < q * q; ++i) a[i][0] = (i % 7) * 0.1, a[i][1] = (i % 5) * 0.1;
  const double t = MedianSeconds([&] {
    fftw_execute(f);
    fftw_execute(g);
  });
  fftw_destroy_plan(f);
  fftw_destroy_plan(g);
  fftw_free(a);
  fftw_free(b);
  return t;
}

// One raw MFT of an n x n field onto M x M and its adjoint: Y = Wy E Wxᵀ, E' = Wyᴴ Y conj(Wx), dense Eigen
// products in the cheaper order (as mft.hpp does).
double MftPairSeconds(int n, int m) {
  Eigen::MatrixXcd wy(m, n), wxt(n, m), e(n, n);
  for (int p = 0; p < m; ++p)
    for (int k = 0; k < n; ++k) wy(p, k) = std::polar(1.0, -0.01 * p * k), wxt(k, p) = std::polar(1.0, -0.013 * p * k);
  for (int k = 0; k < n * n; ++k) e.data()[k] = std::polar(1.0, 0.1 * k);
  Eigen::MatrixXcd y(m, m), back(n, n);
  return MedianSeconds([&] {
    y.noalias() = (wy * e) * wxt;
    back.noalias() = (wy.adjoint() * y) * wxt.adjoint();
  });
}

std::string Shell(const std::string& cmd) {
  std::string out;
  if (FILE* p = popen(cmd.c_str(), "r")) {
    char buf[256];
    while (fgets(buf, sizeof buf, p)) out += buf;
    pclose(p);
  }
  while (!out.empty() && (out.back() == '\n' || out.back() == ' ')) out.pop_back();
  return out;
}

aosr::SceneSpec PaperScene(int r) {
  const std::string path = (fs::path(aosr::DataDirectory()) / "scenes" / "paper-sim-r2.json").string();
  nlohmann::json j = aosr::ReadJsonFile(path);
  j["r"] = r;
  return aosr::ParseScene(j, path);
}

struct EvalRow {
  int r = 0, realisations = 0, screens = 0, threads = 0;
  Index m = 0, q = 0;
  bool periodic = false;
  double j = 0, seconds = 0, floor = 0;
  long props = 0, pairs = 0;
  std::uint64_t ffts = 0;
};

struct System {
  int r = 0;
  Index n = 0, m = 0, q = 0;
  double t_mft = 0, t_pair = 0, t_qpair = 0;
  std::string note;
};

void RunEvaluations(const aosr::SceneSpec& scene, bool quick, std::vector<EvalRow>* rows, System* sys) {
  const aosr::DesignOptics optics = aosr::DesignOpticsFromScene(scene);
  const aosr::DesignParameterisation raster(aosr::DesignPupilFromScene(scene), scene.frames, scene.r,
                                            aosr::DesignParameterisationOptions{aosr::DesignParameterisationKind::kRaster});
  const std::vector<Image> opds = raster.RasterOpds();
  const Index n = optics.amplitude.rows(), m = optics.grid;
  const double qd = double(n) * optics.wavelength_m / (optics.diameter_m * optics.hr_pixel_rad);
  sys->r = scene.r;
  sys->n = n;
  sys->m = m;
  sys->q = Index(std::llround(qd));
  sys->t_mft = MftPairSeconds(int(n), int(m));
  sys->t_pair = FftPairSeconds(int(m));
  sys->t_qpair = ComplexFftPairSeconds(int(sys->q));
  const int frames = scene.frames;
  std::vector<int> threads = quick ? std::vector<int>{1} : std::vector<int>{1, 2};
  for (int th : threads)
    for (int rr : {0, 1, 2})
      for (int l : {1, 4}) {
        if (rr == 0 && l > 1) continue;  // L unused without realisations
        aosr::DesignObjectiveOptions o;
        o.realisations = rr;
        o.screens = l;
        o.threads = th;
        const aosr::DesignObjective f(optics, frames, o);
        EvalRow row;
        row.r = scene.r, row.realisations = rr, row.screens = l, row.threads = th, row.m = m;
        row.periodic = f.periodic();
        row.q = row.periodic ? sys->q : 0;
        std::vector<Image> grad;
        row.j = f.Evaluate(opds, &grad);  // warm-up: plans
        const std::uint64_t c0 = aosr::FftExecutionCount();
        f.Evaluate(opds, &grad);
        row.ffts = aosr::FftExecutionCount() - c0;
        row.seconds = MedianSeconds([&] { f.Evaluate(opds, &grad); });
        row.props = long(frames) * (1 + long(rr) * l);
        row.pairs = long(frames) * (1 + rr);
        row.floor = double(row.props) * (row.periodic ? sys->t_qpair : sys->t_mft) + double(row.pairs) * sys->t_pair;
        std::fprintf(stderr, "r %d R %d L %d threads %d: %.2f ms (J %.4g)\n", scene.r, rr, l, th, 1e3 * row.seconds, row.j);
        rows->push_back(row);
      }
}

struct OptRow {
  std::string kind, termination;
  int parameters = 0, iterations = 0, evaluations = 0;
  double raster = 0, before = 0, after = 0, seconds = 0;
};

}  // namespace

int main(int argc, char** argv) {
  aosr::TuneAllocatorForLargeArrays();  // as the CLI does (memory.hpp)
  bool quick = false;
  std::string out_file, command = "build/bench/design_bench";
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--quick") {
      quick = true;
      command += " --quick";
    } else if (a == "--out" && i + 1 < argc) {
      out_file = argv[++i];
      command += " --out " + out_file;
    } else {
      std::fprintf(stderr, "usage: design_bench [--quick] [--out FILE]\n");
      return 2;
    }
  }
  const auto t_start = Clock::now();
  std::vector<EvalRow> evals;
  std::vector<System> systems;
  for (int r : quick ? std::vector<int>{2} : std::vector<int>{2, 4}) {
    System sys;
    RunEvaluations(PaperScene(r), quick, &evals, &sys);
    systems.push_back(sys);
  }

  // OptimizeDesign per parameterisation on the r = 2 system.
  const aosr::SceneSpec scene = PaperScene(2);
  const aosr::DesignOptics optics = aosr::DesignOpticsFromScene(scene);
  aosr::DesignObjectiveOptions oo;
  oo.threads = quick ? 1 : 2;
  const aosr::DesignObjective objective(optics, scene.frames, oo);
  const int cap = quick ? 10 : 30;
  std::vector<OptRow> opts;
  for (const char* kind : {"raster", "tiptilt", "zernike", "actuators"}) {
    aosr::DesignParameterisationOptions po;
    po.kind = aosr::ParseDesignParameterisation(kind);
    po.zernike_modes = 20;
    const aosr::DesignParameterisation param(aosr::DesignPupilFromScene(scene), scene.frames, scene.r, po);
    aosr::DesignOptimizerOptions d;
    d.starts = 1;
    d.max_iterations = cap;
    const aosr::DesignResult res = aosr::OptimizeDesign(objective, param, d);
    OptRow row;
    row.kind = kind;
    row.parameters = res.summary.parameters;
    row.raster = res.summary.raster_objective;
    row.before = res.summary.initial_objective;
    row.after = res.summary.final_objective;
    row.iterations = res.summary.iterations;
    row.evaluations = res.summary.evaluations;
    row.seconds = res.summary.seconds;
    row.termination = aosr::ToString(res.summary.termination);
    std::fprintf(stderr, "%s\n", res.summary.FullReport().c_str());
    opts.push_back(row);
  }
  const double total = Since(t_start);

  double load[3] = {0, 0, 0};
  if (std::FILE* f = std::fopen("/proc/loadavg", "r")) {
    if (std::fscanf(f, "%lf %lf %lf", &load[0], &load[1], &load[2]) != 3) load[0] = load[1] = load[2] = 0;
    std::fclose(f);
  }
  std::string cpu = Shell("grep -m1 'model name' /proc/cpuinfo | sed 's/.*: //'");
  const std::string rev = Shell("git -C " + std::string(AOSR_SOURCE_DIR) + " rev-parse --short HEAD 2>/dev/null");
  const std::string dirty =
      Shell("git -C " + std::string(AOSR_SOURCE_DIR) + " status --porcelain --untracked-files=no 2>/dev/null | head -1");
  char date[64];
  const std::time_t now = std::time(nullptr);
  std::strftime(date, sizeof date, "%Y-%m-%d %H:%M UTC", std::gmtime(&now));

  std::ostringstream md;
  md << "<!-- produced by: " << command << " -->\n"
     << "# Phase design: cost of objective A and of the optimiser\n\n"
     << "Command: `" << command << "` (Release build), " << date << ", git " << (rev.empty() ? "unknown" : rev)
     << (dirty.empty() ? "" : " (with uncommitted changes in the tree)") << ". Machine: " << (cpu.empty() ? "?" : cpu)
     << ", " << std::thread::hardware_concurrency() << " hardware threads; FFTW single-threaded per transform; "
     << "load average at the end " << Fmt("%.2f", load[0]) << " / " << Fmt("%.2f", load[1]) << " / "
     << Fmt("%.2f", load[2]) << " (1/5/15 min). Total " << Fmt("%.0f", total) << " s.\n\n";
  if (load[1] > 0.75 * double(std::thread::hardware_concurrency()))
    md << "**Caveat: the machine was busy** (5-min load " << Fmt("%.1f", load[1]) << " on "
       << std::thread::hardware_concurrency() << " hardware threads): other processes shared the cores, so the "
       << "times are upper bounds and the threads = 2 rows measure contention rather than speed-up. Rerun on an "
       << "idle machine for the scaling.\n\n";
  md
     << "System: `data/scenes/paper-sim-r2.json` through `DesignOpticsFromScene` (paper-8m, K band, camera pixel "
        "λ/D, analytic AO model), N = 4, and the same scene with `\"r\": 4` set before parsing. Objective A with "
        "its defaults (gradient prior, λ = 1e-2, σ = 1), evaluated with its gradient at the classic raster.\n\n"
     << "Raw transform times measured here (median of 5 batches, FFTW_MEASURE plans / Eigen dense products):\n\n";
  for (const System& s : systems)
    md << "- r = " << s.r << ": pupil n = " << s.n << ", design grid M = " << s.m << ", PSF period Q = " << s.q
       << ": MFT n→M×M + adjoint " << Fmt("%.3f", 1e3 * s.t_mft) << " ms; M×M r2c + c2r pair "
       << Fmt("%.4f", 1e3 * s.t_pair) << " ms; Q×Q complex forward + backward pair " << Fmt("%.3f", 1e3 * s.t_qpair)
       << " ms\n";
  md << "\nReading table 1. `props` = N(1+RL) field propagations, each with its adjoint (the header's cost model "
        "counts them as MFTs; on the periodic path, used whenever Q is a multiple of M, each is a Q×Q complex FFT "
        "pair). `M×M pairs` = N(1+R) OTF transforms and their adjoints: one per PSF, not per screen (the header's "
        "\"N(1+RL) FFT pairs of M×M\" over-counts for L > 1). `FFTs` = aosr's own count over one evaluation "
        "(FftExecutionCount), which should be 2·props + 2·pairs on the periodic path. `floor` = props × t_prop + "
        "pairs × t_pair on one thread (t_prop: the Q×Q pair on the periodic path, else the MFT pair). `ratio` = "
        "time / (floor / threads). R = 0 uses the nominal model only (L is then unused).\n\n"
     << "| r | M | path | R | L | threads | J | eval+grad [ms] | props | M×M pairs | FFTs | floor [ms] | ratio |\n"
     << "|---:|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n";
  for (const EvalRow& e : evals)
    md << "| " << e.r << " | " << e.m << " | " << (e.periodic ? "periodic Q=" + std::to_string(e.q) : std::string("MFT"))
       << " | " << e.realisations << " | " << (e.realisations ? std::to_string(e.screens) : std::string("—")) << " | "
       << e.threads << " | " << Fmt("%.5g", e.j) << " | " << Fmt("%.1f", 1e3 * e.seconds) << " | " << e.props << " | "
       << e.pairs << " | " << e.ffts << " | " << Fmt("%.1f", 1e3 * e.floor) << " | "
       << Fmt("%.2f", e.seconds / (e.floor / e.threads)) << " |\n";
  md << "\nTable 2: `OptimizeDesign`, 1 start (the raster), at most " << cap << " L-BFGS iterations, on the r = 2 "
     << "system with R = 2, L = 4, threads " << oo.threads << ". J before = at the start (the raster in that "
     << "parameterisation; for actuators a DM fit of it), after = the returned design; change relative to before.\n\n"
     << "| parameterisation | parameters | J raster | J before | J after | change | iterations | evaluations | time [s] | "
        "termination |\n|---|---:|---:|---:|---:|---:|---:|---:|---:|---|\n";
  for (const OptRow& o : opts)
    md << "| " << o.kind << " | " << o.parameters << " | " << Fmt("%.6g", o.raster) << " | " << Fmt("%.6g", o.before)
       << " | " << Fmt("%.6g", o.after) << " | " << Fmt("%+.2f %%", 100.0 * (o.after - o.before) / o.before) << " | "
       << o.iterations << " | " << o.evaluations << " | " << Fmt("%.1f", o.seconds) << " | " << o.termination << " |\n";
  std::printf("%s", md.str().c_str());
  if (!out_file.empty()) {
    std::ofstream f(out_file);
    f << md.str();
    if (!f) {
      std::fprintf(stderr, "cannot write %s\n", out_file.c_str());
      return 1;
    }
  }
  return 0;
}
