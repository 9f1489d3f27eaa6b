// What reproducible FFTs cost against FFTW's own 2-D plans, timed in the same run.
//
// For each shape: one forward r2c + inverse c2r pair (what every convolution and solver does) through
//  * FFTW's own 2-D plans on fftw_malloc'd buffers, one thread: FFTW_PATIENT's plan from the wisdom aosr ships
//    (bench/fft_floor.hpp: the floor every other benchmark quotes, the same plan in every run), FFTW_ESTIMATE,
//    and FFTW_MEASURE planned afresh in this run; and FFTW_ESTIMATE with FFTW's threads on 2 threads;
//  * aosr's fft.hpp (reproducible plans: the shipped wisdom, FFTW_ESTIMATE's heuristics where it has no plan;
//    fixed blocks) on 1 and 2 threads, through the buffer-reusing FftR2CInto/FftC2RInto (the hot loops' form)
//    and through the allocating FftR2C/FftC2R; and on 1 thread with the heuristic plans alone
//    (--fft-planner heuristic), which is what aosr ran before the wisdom.
// Timing: the machine is shared and its speed drifts, so every variant is timed in interleaved rounds
// (each round times one batch of every variant, one after another) and each variant's figure is its
// minimum over rounds of the batch mean. The minimum is the least disturbed estimate of the cost and is
// stable from run to run; ratios are taken within the same run.
//
//   build/bench/fft_bench [--quick] [--rounds K] [--out bench/results/fft.md]
#include <fftw3.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <functional>
#include <random>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "aosr/core/memory.hpp"
#include "aosr/core/fft.hpp"
#include "aosr/core/parallel.hpp"
#include "fft_floor.hpp"

namespace {

using Clock = std::chrono::steady_clock;

// A timed variant: `setup` runs before its batch (thread count, planner), `run` is one pair.
struct Variant {
  std::string name;
  std::function<void()> setup, run;
  double best = 1e300;
};

// FFTW's own 2-D r2c/c2r plans on its own aligned buffers.
struct RawPair {
  double* x = nullptr;
  fftw_complex* X = nullptr;
  fftw_plan f = nullptr, b = nullptr;
  RawPair(int rows, int cols, unsigned flags, int threads) {
    const std::size_t n = std::size_t(rows) * cols, nh = std::size_t(rows) * (cols / 2 + 1);
    x = fftw_alloc_real(n);
    X = fftw_alloc_complex(nh);
    // fftw_plan_with_nthreads only after fftw_init_threads: called before it, FFTW 3.3.10 runs fftw_cleanup,
    // which frees the planner's solvers under every live plan.
    if (threads > 1) fftw_plan_with_nthreads(threads);
    f = fftw_plan_dft_r2c_2d(rows, cols, x, X, flags);
    b = fftw_plan_dft_c2r_2d(rows, cols, X, x, flags);
    if (threads > 1) fftw_plan_with_nthreads(1);
    for (std::size_t i = 0; i < n; ++i) x[i] = double(i % 17);
  }
  ~RawPair() {
    fftw_destroy_plan(f);
    fftw_destroy_plan(b);
    fftw_free(x);
    fftw_free(X);
  }
  void Run() {
    fftw_execute(f);
    fftw_execute(b);
  }
};

}  // namespace

int main(int argc, char** argv) {
  aosr::TuneAllocatorForLargeArrays();  // as the CLI does (memory.hpp)
  bool quick = false;
  int rounds = 7;
  std::string out;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--quick") quick = true;
    else if (a == "--rounds" && i + 1 < argc) rounds = std::max(1, std::atoi(argv[++i]));
    else if (a == "--out" && i + 1 < argc) out = argv[++i];
    else {
      std::fprintf(stderr, "usage: fft_bench [--quick] [--rounds K] [--out FILE]\n");
      return 1;
    }
  }
  const std::vector<int> sizes =
      quick ? std::vector<int>{128, 512} : std::vector<int>{64, 128, 192, 256, 384, 512, 768, 1000, 1024, 2048};
  std::ostringstream md;
  md << "# FFT cost: aosr's reproducible transforms against FFTW's own 2-D plans\n\n"
     << "Command: `build/bench/fft_bench" << (quick ? " --quick" : "") << "` (Release), " << rounds
     << " interleaved rounds. Machine: " << std::thread::hardware_concurrency()
     << " hardware threads. One r2c + c2r pair of a random n x n image, in ms: the minimum over rounds of the "
        "batch mean. FFTW's own 2-D plan pairs on aligned buffers, one thread: `FFTW patient` is FFTW_PATIENT's "
        "plan, taken from the wisdom aosr ships (data/fftw_wisdom.txt; bench/fft_floor.hpp), the floor the other "
        "benchmarks quote and the same plan in every run; `FFTW est` FFTW_ESTIMATE's; `FFTW meas` FFTW_MEASURE's, "
        "planned afresh in this run (its choice varies from run to run); `FFTW 2 thr` FFTW_ESTIMATE with FFTW's "
        "own threads on 2 threads, timed after all the others (FFTW refuses the shipped wisdom once its threads are "
        "initialised). `aosr` is fft.hpp's reproducible default (plans from the shipped wisdom, "
        "FFTW_ESTIMATE's heuristics where it has none; one 2-D plan below 192 x 192, blocked row-column from "
        "there), through the buffer-reusing FftR2CInto/FftC2RInto; `aosr heur` the same with the heuristic plans "
        "alone (`--fft-planner heuristic`, what aosr ran before the wisdom); `aosr alloc` through FftR2C/FftC2R, "
        "which return new arrays.\n\n"
     << "| shape | FFTW patient (floor) | FFTW est | FFTW meas | FFTW 2 thr | aosr 1 thr | aosr 2 thr | aosr heur 1 thr "
        "| aosr alloc 1 thr | aosr 1 thr / floor | aosr 1 thr / FFTW est | aosr 2 thr / FFTW 2 thr | aosr speed-up "
        "2 thr | floor plan |\n"
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n";
  // Per shape: patient (floor), est, meas, FFTW 2 thr, aosr 1 thr, aosr 2 thr, aosr heuristic, aosr alloc.
  struct Row {
    int n;
    double t[8];
    bool from_wisdom;
  };
  std::vector<Row> rows;
  for (int n : sizes) {
    aosr::Image x(n, n);
    std::mt19937_64 rng(1);
    std::normal_distribution<double> n01;
    for (aosr::Index i = 0; i < x.size(); ++i) x.data()[i] = n01(rng);
    aosr::ComplexImage X;
    aosr::Image back;
    aosr::bench::FloorPlans floor(n, n);
    // The raw ESTIMATE and MEASURE plans are planned from an empty store: the floor's import would otherwise
    // answer them with the shipped PATIENT plans (aosr re-imports the wisdom itself before each of its plans).
    fftw_forget_wisdom();
    RawPair est(n, n, FFTW_ESTIMATE, 1), meas(n, n, FFTW_MEASURE, 1);
    auto threads = [](int t) { return [t] { aosr::SetDefaultThreads(t); }; };
    auto none = [] {};
    aosr::FftSettings shipped = aosr::GetFftSettings(), heuristic = shipped;
    heuristic.shipped_wisdom = false;
    auto aosr_pair = [&] {
      aosr::FftR2CInto(x, &X);
      aosr::FftC2RInto(X, n, &back);
    };
    auto heuristic_pair = [&] {
      aosr::SetFftSettings(heuristic);
      aosr_pair();
      aosr::SetFftSettings(shipped);
    };
    auto aosr_alloc = [&] { back = aosr::FftC2R(aosr::FftR2C(x), n); };
    std::vector<Variant> v = {{"patient", none, [&] {
                                 fftw_execute(floor.r2c);
                                 fftw_execute(floor.c2r);
                               }},
                              {"est", none, [&] { est.Run(); }},
                              {"meas", none, [&] { meas.Run(); }},
                              {"aosr1", threads(1), aosr_pair},
                              {"aosr2", threads(2), aosr_pair},
                              {"heur1", threads(1), heuristic_pair},
                              {"alloc1", threads(1), aosr_alloc}};
    // A batch lasts about 20 ms (at least 3 pairs), so that timer and wake-up noise stay small.
    const double flops = 5.0 * double(n) * n * std::log2(double(n));
    const int batch = std::max(3, int(2e8 / flops));
    for (Variant& var : v) {  // warm-up: plans made, caches and pages touched
      var.setup();
      var.run();
    }
    for (int r = 0; r < rounds; ++r)
      for (Variant& var : v) {
        var.setup();
        const auto a = Clock::now();
        for (int k = 0; k < batch; ++k) var.run();
        var.best = std::min(var.best, std::chrono::duration<double>(Clock::now() - a).count() / batch);
      }
    aosr::SetDefaultThreads(1);
    rows.push_back({n, {v[0].best, v[1].best, v[2].best, 0.0, v[3].best, v[4].best, v[5].best, v[6].best},
                    floor.from_wisdom});
    std::fprintf(stderr, "%d^2 done\n", n);
  }
  // FFTW's own threads last: fftw_init_threads adds solvers to FFTW's planner, after which FFTW refuses the
  // shipped wisdom (made without them), so aosr's plans would fall back to the heuristic ones. The threaded
  // FFTW pairs are therefore timed after everything else, in rounds of their own.
  fftw_init_threads();
  for (Row& row : rows) {
    const int n = row.n;
    RawPair est2(n, n, FFTW_ESTIMATE, 2);
    const double flops = 5.0 * double(n) * n * std::log2(double(n));
    const int batch = std::max(3, int(2e8 / flops));
    est2.Run();
    double best = 1e300;
    for (int r = 0; r < rounds; ++r) {
      const auto a = Clock::now();
      for (int k = 0; k < batch; ++k) est2.Run();
      best = std::min(best, std::chrono::duration<double>(Clock::now() - a).count() / batch);
    }
    row.t[3] = best;
    const double* t = row.t;
    char line[400];
    std::snprintf(line, sizeof line,
                  "| %dx%d | %.3f | %.3f | %.3f | %.3f | %.3f | %.3f | %.3f | %.3f | %.2f | %.2f | %.2f | %.2f | %s |\n",
                  n, n, 1e3 * t[0], 1e3 * t[1], 1e3 * t[2], 1e3 * t[3], 1e3 * t[4], 1e3 * t[5], 1e3 * t[6],
                  1e3 * t[7], t[4] / t[0], t[4] / t[1], t[5] / t[3], t[4] / t[5],
                  row.from_wisdom ? "shipped wisdom" : "FFTW_PATIENT, this run");
    md << line;
  }
  std::fputs(md.str().c_str(), stdout);
  if (!out.empty()) std::ofstream(out) << md.str();
  fftw_cleanup_threads();
  return 0;
}
