// Detector benchmark: time to record a 1000 x 1000 frame (Poisson photon noise + Gaussian read noise, gain,
// bias, saturation check) at several mean signal levels, into a reused frame (as a simulation loop does)
// and into fresh buffers (first touch of the output images included).
//
// Usage: build/bench/detector_bench [repeats]     (default 7; the table shows the best and median)
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <thread>
#include <vector>

#include "aosr/core/memory.hpp"
#include "aosr/scene/detector.hpp"

int main(int argc, char** argv) {
  aosr::TuneAllocatorForLargeArrays();  // as the CLI does (memory.hpp)
  using Clock = std::chrono::steady_clock;
  const int repeats = argc > 1 ? std::max(1, std::atoi(argv[1])) : 7;
  aosr::DetectorOptions o;
  o.read_noise_e = 5.0;
  o.enable_saturation = false;
  const aosr::Detector detector(o);
  std::printf("# build/bench/detector_bench %d | hardware threads %u | 10^6 px, photon + read noise, one thread\n",
              repeats, std::thread::hardware_concurrency());
  std::printf("%12s %14s %14s %16s\n", "mean [e-]", "best [ms]", "median [ms]", "fresh bufs [ms]");
  for (double mean : {0.5, 5.0, 50.0, 5000.0}) {
    const aosr::Image expected = aosr::Image::Constant(1000, 1000, mean);
    auto t0 = Clock::now();
    aosr::DetectorFrame fresh = detector.Record(expected, 1, 0);
    const double fresh_ms = std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
    std::vector<double> ms;
    for (int k = 0; k < repeats; ++k) {
      t0 = Clock::now();
      detector.Record(expected, 2 + k, 0, &fresh);
      ms.push_back(std::chrono::duration<double, std::milli>(Clock::now() - t0).count());
    }
    std::sort(ms.begin(), ms.end());
    std::printf("%12g %14.1f %14.1f %16.1f\n", mean, ms.front(), ms[ms.size() / 2], fresh_ms);
  }
  return 0;
}
