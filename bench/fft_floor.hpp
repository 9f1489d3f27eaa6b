// The FFT floor the reconstruction benches quote: seconds per out-of-place r2c FFTW transform of rows x cols
// with a FFTW_MEASURE plan, the minimum over 15 batches, the least disturbed estimate on a shared machine (a
// median moved 3.4 -> 5.0 ms between runs at 1024^2; the minimum is what FFTW costs when nothing else runs).
// `now` is the clock in seconds: wall time (reconstruct_bench) or process CPU time (tikhonov_bench). The plan
// itself is FFTW_MEASURE's choice, which can differ between runs (1.9 - 3.3 ms at 1024^2 across sessions).
#pragma once

#include <fftw3.h>

#include <algorithm>
#include <cstddef>

namespace aosr::bench {

template <class Now>
double R2cFloorSeconds(int rows, int cols, Now&& now) {
  double* in = fftw_alloc_real(std::size_t(rows) * cols);
  fftw_complex* out = fftw_alloc_complex(std::size_t(rows) * (cols / 2 + 1));
  fftw_plan plan = fftw_plan_dft_r2c_2d(rows, cols, in, out, FFTW_MEASURE);
  for (int i = 0; i < rows * cols; ++i) in[i] = (i % 7) * 0.1;
  const int reps = std::max(5, int(2e7 / (double(rows) * cols * 8)));
  double best = 1e300;
  for (int b = 0; b < 15; ++b) {
    const double t0 = now();
    for (int k = 0; k < reps; ++k) fftw_execute(plan);
    best = std::min(best, (now() - t0) / reps);
  }
  fftw_destroy_plan(plan);
  fftw_free(in);
  fftw_free(out);
  return best;
}

}  // namespace aosr::bench
