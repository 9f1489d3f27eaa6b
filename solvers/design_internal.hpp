// Helpers shared by the phase-design sources (not installed: solvers/ only).
#pragma once

#include <algorithm>
#include <complex>
#include <exception>
#include <mutex>
#include <thread>
#include <vector>

#include "aosr/core/image.hpp"

namespace aosr::design_internal {

constexpr double kTwoPi = 6.283185307179586476925286766559;

// Σ_{k=0}^{r-1} exp(+2πi f k / n) for every bin f of an axis of length n (forward_model.hpp's B).
inline std::vector<Complex> BoxTransfer(Index n, int r) {
  std::vector<Complex> b(n);
  for (Index f = 0; f < n; ++f) {
    Complex s = 0;
    for (int k = 0; k < r; ++k) s += std::polar(1.0, kTwoPi * double(f) * k / double(n));
    b[f] = s;
  }
  return b;
}

// Runs fn(0..count-1) on up to `threads` threads; rethrows the first exception.
template <typename F>
void ParallelFor(int count, int threads, F fn) {
  threads = std::max(1, std::min(threads, count));
  if (threads == 1) {
    for (int k = 0; k < count; ++k) fn(k);
    return;
  }
  std::vector<std::thread> pool;
  std::exception_ptr error;
  std::mutex m;
  for (int t = 0; t < threads; ++t)
    pool.emplace_back([&, t] {
      try {
        for (int k = t; k < count; k += threads) fn(k);
      } catch (...) {
        std::lock_guard<std::mutex> lock(m);
        if (!error) error = std::current_exception();
      }
    });
  for (std::thread& th : pool) th.join();
  if (error) std::rethrow_exception(error);
}

}  // namespace aosr::design_internal
