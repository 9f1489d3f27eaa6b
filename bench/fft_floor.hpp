// The FFT floor the benches quote: FFTW's own 2-D r2c (and c2r) plan of rows x cols, out of place on
// fftw_malloc'd buffers, one thread, taken from the wisdom aosr ships (data/fftw_wisdom.txt: FFTW_PATIENT's
// choice, made once by build/bench/fft_wisdom), so that the floor is the same plan in every run and the best
// FFTW found for the shape. A floor planned afresh with FFTW_MEASURE moved 1.9 - 3.4 ms at 1024^2 between
// runs because MEASURE's choice itself varies; FFTW_PATIENT's choice varied 1.8 - 2.1 ms, and a fixed one
// varies only with the machine's load. Shapes the wisdom lacks are planned with FFTW_PATIENT here and say so.
// Timing: the minimum over 15 batches, the least disturbed estimate on a shared machine; `now` is the clock
// in seconds: wall time (reconstruct_bench, fft_bench) or process CPU time (tikhonov_bench).
#pragma once

#include <fftw3.h>

#include <algorithm>
#include <cstddef>

#include "aosr/core/fft.hpp"

namespace aosr::bench {

// FFTW's 2-D r2c and c2r plans of rows x cols on their own buffers, from the shipped wisdom where it has them
// (from_wisdom), else planned with `fallback_flags`. fft_wisdom uses it with FFTW_PATIENT to put these very
// problems in the wisdom.
struct FloorPlans {
  double* x = nullptr;
  fftw_complex* X = nullptr;
  fftw_plan r2c = nullptr, c2r = nullptr;
  bool from_wisdom = false;
  FloorPlans(int rows, int cols, unsigned fallback_flags = FFTW_PATIENT, bool use_wisdom = true) {
    const std::size_t n = std::size_t(rows) * cols, nh = std::size_t(rows) * (cols / 2 + 1);
    x = fftw_alloc_real(n);
    X = fftw_alloc_complex(nh);
    if (use_wisdom && fftw_import_wisdom_from_string(aosr::FftShippedWisdom()) == 1) {
      r2c = fftw_plan_dft_r2c_2d(rows, cols, x, X, FFTW_ESTIMATE | FFTW_WISDOM_ONLY);
      c2r = fftw_plan_dft_c2r_2d(rows, cols, X, x, FFTW_ESTIMATE | FFTW_WISDOM_ONLY);
    }
    from_wisdom = r2c != nullptr && c2r != nullptr;
    if (!r2c) r2c = fftw_plan_dft_r2c_2d(rows, cols, x, X, fallback_flags);
    if (!c2r) c2r = fftw_plan_dft_c2r_2d(rows, cols, X, x, fallback_flags);
    for (std::size_t i = 0; i < n; ++i) x[i] = double(i % 17);
  }
  ~FloorPlans() {
    fftw_destroy_plan(r2c);
    fftw_destroy_plan(c2r);
    fftw_free(x);
    fftw_free(X);
  }
  FloorPlans(const FloorPlans&) = delete;
  FloorPlans& operator=(const FloorPlans&) = delete;
};

// Seconds per r2c transform of the floor plan (the minimum over 15 batches). *from_wisdom, if given, says
// whether the plan came from the shipped wisdom.
template <class Now>
double R2cFloorSeconds(int rows, int cols, Now&& now, bool* from_wisdom = nullptr) {
  FloorPlans p(rows, cols);
  if (from_wisdom) *from_wisdom = p.from_wisdom;
  const int reps = std::max(5, int(2e7 / (double(rows) * cols * 8)));
  double best = 1e300;
  for (int b = 0; b < 15; ++b) {
    const double t0 = now();
    for (int k = 0; k < reps; ++k) fftw_execute(p.r2c);
    best = std::min(best, (now() - t0) / reps);
  }
  return best;
}

}  // namespace aosr::bench
