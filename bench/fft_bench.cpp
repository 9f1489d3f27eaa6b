// What reproducible FFTs cost against FFTW's own 2-D plans, timed in the same run.
//
// For each shape: one forward r2c + inverse c2r pair (what every convolution and solver does) through
//  * FFTW's own 2-D plans on fftw_malloc'd buffers: FFTW_ESTIMATE on 1 thread (the floor every other
//    benchmark quotes), FFTW_MEASURE on 1 thread, and FFTW_ESTIMATE with FFTW's threads on 2 threads;
//  * aosr's fft.hpp (reproducible kEstimate plans, fixed blocks) on 1 and 2 threads, through the
//    buffer-reusing FftR2CInto/FftC2RInto (the hot loops' form) and through the allocating FftR2C/FftC2R.
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
    fftw_plan_with_nthreads(threads);
    f = fftw_plan_dft_r2c_2d(rows, cols, x, X, flags);
    b = fftw_plan_dft_c2r_2d(rows, cols, X, x, flags);
    fftw_plan_with_nthreads(1);
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
  fftw_init_threads();
  const std::vector<int> sizes =
      quick ? std::vector<int>{128, 512} : std::vector<int>{64, 128, 192, 256, 384, 512, 768, 1000, 1024, 2048};
  std::ostringstream md;
  md << "# FFT cost: aosr's reproducible transforms against FFTW's own 2-D plans\n\n"
     << "Command: `build/bench/fft_bench" << (quick ? " --quick" : "") << "` (Release), " << rounds
     << " interleaved rounds. Machine: " << std::thread::hardware_concurrency()
     << " hardware threads. One r2c + c2r pair of a random n x n image, in ms: the minimum over rounds of the "
        "batch mean. `FFTW est` is one FFTW 2-D plan pair made with FFTW_ESTIMATE on aligned buffers, one thread: "
        "the floor the other benchmarks quote. `FFTW meas` the same with FFTW_MEASURE; `FFTW 2 thr` FFTW_ESTIMATE "
        "with FFTW's own threads on 2 threads. `aosr` is fft.hpp with the reproducible default (FFTW_ESTIMATE "
        "plans, fixed blocks: one 2-D plan below 192 x 192, blocked row-column from there), through the "
        "buffer-reusing FftR2CInto/FftC2RInto; `aosr alloc` through FftR2C/FftC2R, which return new arrays.\n\n"
     << "| shape | FFTW est (floor) | FFTW meas | FFTW 2 thr | aosr 1 thr | aosr 2 thr | aosr alloc 1 thr | "
        "aosr 1 thr / floor | aosr 2 thr / FFTW 2 thr | aosr speed-up 2 thr |\n"
        "|---|---|---|---|---|---|---|---|---|---|\n";
  for (int n : sizes) {
    aosr::Image x(n, n);
    std::mt19937_64 rng(1);
    std::normal_distribution<double> n01;
    for (aosr::Index i = 0; i < x.size(); ++i) x.data()[i] = n01(rng);
    aosr::ComplexImage X;
    aosr::Image back;
    RawPair est(n, n, FFTW_ESTIMATE, 1), meas(n, n, FFTW_MEASURE, 1), est2(n, n, FFTW_ESTIMATE, 2);
    auto threads = [](int t) { return [t] { aosr::SetDefaultThreads(t); }; };
    auto none = [] {};
    auto aosr_pair = [&] {
      aosr::FftR2CInto(x, &X);
      aosr::FftC2RInto(X, n, &back);
    };
    auto aosr_alloc = [&] { back = aosr::FftC2R(aosr::FftR2C(x), n); };
    std::vector<Variant> v = {{"est", none, [&] { est.Run(); }},
                              {"meas", none, [&] { meas.Run(); }},
                              {"est2", none, [&] { est2.Run(); }},
                              {"aosr1", threads(1), aosr_pair},
                              {"aosr2", threads(2), aosr_pair},
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
    char line[320];
    std::snprintf(line, sizeof line, "| %dx%d | %.3f | %.3f | %.3f | %.3f | %.3f | %.3f | %.2f | %.2f | %.2f |\n", n,
                  n, 1e3 * v[0].best, 1e3 * v[1].best, 1e3 * v[2].best, 1e3 * v[3].best, 1e3 * v[4].best,
                  1e3 * v[5].best, v[3].best / v[0].best, v[4].best / v[2].best, v[3].best / v[4].best);
    md << line;
    std::fputs(line, stdout);
    std::fflush(stdout);
  }
  std::fputs(md.str().c_str(), stdout);
  if (!out.empty()) std::ofstream(out) << md.str();
  fftw_cleanup_threads();
  return 0;
}
