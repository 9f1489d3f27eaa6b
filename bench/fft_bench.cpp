// What reproducible FFTs cost. For each shape, one forward r2c + inverse c2r pair through aosr's fft.hpp
// with the reproducible planner (kEstimate, the default) and with kMeasure, on 1 and 2 threads, against
// raw FFTW 2-D plans made with FFTW_MEASURE on aligned buffers (the fastest single-threaded FFTW can do;
// the "floor" of the other benchmarks). Prints a markdown table; --out FILE also writes it there.
//
//   build/bench/fft_bench [--quick] [--out bench/results/fft.md]
#include <fftw3.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <random>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "aosr/core/fft.hpp"
#include "aosr/core/parallel.hpp"

namespace {

using Clock = std::chrono::steady_clock;

// Median of `reps` timings of fn (seconds), after one warm-up call.
template <typename F>
double Median(int reps, F fn) {
  fn();
  std::vector<double> t;
  for (int k = 0; k < reps; ++k) {
    const auto a = Clock::now();
    fn();
    t.push_back(std::chrono::duration<double>(Clock::now() - a).count());
  }
  std::sort(t.begin(), t.end());
  return t[t.size() / 2];
}

double RawFftwPair(int rows, int cols, int reps) {
  const std::size_t n = std::size_t(rows) * cols, nh = std::size_t(rows) * (cols / 2 + 1);
  double* x = fftw_alloc_real(n);
  fftw_complex* X = fftw_alloc_complex(nh);
  const fftw_plan f = fftw_plan_dft_r2c_2d(rows, cols, x, X, FFTW_MEASURE);
  const fftw_plan b = fftw_plan_dft_c2r_2d(rows, cols, X, x, FFTW_MEASURE);
  for (std::size_t i = 0; i < n; ++i) x[i] = double(i % 17);
  const double t = Median(reps, [&] {
    fftw_execute(f);
    fftw_execute(b);
  });
  fftw_destroy_plan(f);
  fftw_destroy_plan(b);
  fftw_free(x);
  fftw_free(X);
  return t;
}

double AosrPair(const aosr::Image& x, aosr::FftSettings::Planner planner, int threads, int reps) {
  aosr::FftSettings s;
  s.planner = planner;
  aosr::SetFftSettings(s);
  aosr::SetDefaultThreads(threads);
  aosr::Image back;
  return Median(reps, [&] { back = aosr::FftC2R(aosr::FftR2C(x), x.cols()); });
}

}  // namespace

int main(int argc, char** argv) {
  bool quick = false;
  std::string out;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--quick") quick = true;
    else if (a == "--out" && i + 1 < argc) out = argv[++i];
    else {
      std::fprintf(stderr, "usage: fft_bench [--quick] [--out FILE]\n");
      return 1;
    }
  }
  std::vector<int> sizes = quick ? std::vector<int>{128, 512} : std::vector<int>{128, 256, 512, 768, 1000, 1024, 2048};
  std::ostringstream md;
  md << "# FFT cost: reproducible (kEstimate, blocked row-column) against FFTW_MEASURE\n\n"
     << "Command: `build/bench/fft_bench" << (quick ? " --quick" : "") << "` (Release). Machine: "
     << std::thread::hardware_concurrency()
     << " hardware threads. One r2c + c2r pair, median of repeats, in ms. `raw FFTW` is a 2-D plan made with "
        "FFTW_MEASURE on aligned buffers, single-threaded: the floor the other benchmarks quote. aosr's transforms "
        "below 128x128 are one 2-D plan, from 128x128 on blocked row-column (fft.hpp).\n\n"
     << "| shape | raw FFTW (measure) | aosr estimate, 1 thr | aosr measure, 1 thr | aosr estimate, 2 thr | "
        "estimate 1 thr / raw | speed-up 2 thr |\n|---|---|---|---|---|---|---|\n";
  for (int n : sizes) {
    const int reps = std::max(5, int(2e7 / (double(n) * n * std::log2(double(n)))));
    aosr::Image x(n, n);
    std::mt19937_64 rng(1);
    std::normal_distribution<double> n01;
    for (aosr::Index i = 0; i < x.size(); ++i) x.data()[i] = n01(rng);
    const double raw = RawFftwPair(n, n, reps);
    const double e1 = AosrPair(x, aosr::FftSettings::Planner::kEstimate, 1, reps);
    const double m1 = AosrPair(x, aosr::FftSettings::Planner::kMeasure, 1, reps);
    const double e2 = AosrPair(x, aosr::FftSettings::Planner::kEstimate, 2, reps);
    char line[256];
    std::snprintf(line, sizeof line, "| %dx%d | %.3f | %.3f | %.3f | %.3f | %.2f | %.2f |\n", n, n, 1e3 * raw, 1e3 * e1,
                  1e3 * m1, 1e3 * e2, e1 / raw, e1 / e2);
    md << line;
    std::fputs(line, stdout);
    std::fflush(stdout);
  }
  aosr::SetFftSettings({});
  aosr::SetDefaultThreads(1);
  std::fputs(md.str().c_str(), stdout);
  if (!out.empty()) std::ofstream(out) << md.str();
  return 0;
}
