// Makes data/fftw_wisdom.txt, the FFTW wisdom aosr ships (src/core/fft.cpp, fft.hpp "Plans come from
// wisdom"): FFTW_PATIENT's plans for every FFTW problem aosr's transforms (r2c, c2r, forward, inverse: the
// 2-D plans below 192^2 and the blocked row-column passes from there) pose for the square sizes below, and
// the benches' floor plans (bench/fft_floor.hpp). Run once per FFTW version (wisdom from another FFTW build
// is refused, and aosr then plans with FFTW_ESTIMATE's heuristics), on a quiet machine, one thread:
//
//   build/bench/fft_wisdom --out data/fftw_wisdom.txt      (about 5 minutes on the 2-core machine)
//
// then rebuild (CMake compiles the file in). The plans change the last bits of results, not their values.
#include <fftw3.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>
#include <vector>

#include "aosr/core/fft.hpp"
#include "aosr/core/memory.hpp"
#include "aosr/core/parallel.hpp"
#include "fft_floor.hpp"

int main(int argc, char** argv) {
  aosr::TuneAllocatorForLargeArrays();
  std::string out;
  bool quick = false;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--out" && i + 1 < argc)
      out = argv[++i];
    else if (a == "--quick")
      quick = true;
    else {
      std::fprintf(stderr, "usage: fft_wisdom --out FILE [--quick]\n");
      return 1;
    }
  }
  if (out.empty()) {
    std::fprintf(stderr, "fft_wisdom: --out FILE is required\n");
    return 1;
  }
  // The sizes aosr's scenes, solvers and optics transform (HR grids r * m, padded PSF grids, LR frames,
  // Shack- Hartmann spots), and the fast sizes between them.
  const std::vector<int> sizes =
      quick ? std::vector<int>{16, 256}
            : std::vector<int>{8,   16,  24,  32,  48,  64,  96,  128, 160, 168,  192,  200,  256,  288, 320,
                               375, 384, 400, 480, 500, 512, 640, 768, 800, 1000, 1024, 1280, 1536, 2048};
  const std::vector<int> floor_sizes =
      quick ? std::vector<int>{256} : std::vector<int>{64, 128, 192, 256, 384, 512, 768, 1000, 1024, 2048};
  aosr::SetDefaultThreads(1);
  aosr::FftSettings settings;
  settings.planner = aosr::FftSettings::Planner::kPatient;
  settings.shipped_wisdom = false;
  aosr::FftResetPlansForTesting();  // starts from an empty store
  aosr::SetFftSettings(settings);
  using Clock = std::chrono::steady_clock;
  const auto start = Clock::now();
  for (int n : sizes) {
    const auto t0 = Clock::now();
    aosr::Image x(n, n);
    std::mt19937_64 rng(1);
    std::normal_distribution<double> n01;
    for (aosr::Index i = 0; i < x.size(); ++i) x.data()[i] = n01(rng);
    aosr::ComplexImage X, Z, W;
    aosr::Image back;
    aosr::FftR2CInto(x, &X);
    aosr::FftC2RInto(X, n, &back);
    const aosr::ComplexImage c = x.cast<aosr::Complex>();
    aosr::FftForwardInto(c, &Z);
    aosr::FftInverseInto(Z, &W);
    std::printf("%5d^2: aosr's plans %.1f s\n", n, std::chrono::duration<double>(Clock::now() - t0).count());
    std::fflush(stdout);
  }
  for (int n : floor_sizes) {
    const auto t0 = Clock::now();
    aosr::bench::FloorPlans p(n, n, FFTW_PATIENT, /*use_wisdom=*/false);
    std::printf("%5d^2: floor plans %.1f s\n", n, std::chrono::duration<double>(Clock::now() - t0).count());
    std::fflush(stdout);
  }
  char* text = fftw_export_wisdom_to_string();
  if (text == nullptr) {
    std::fprintf(stderr, "fft_wisdom: FFTW exported no wisdom\n");
    return 2;
  }
  const std::string tmp = out + ".tmp";
  {
    std::ofstream f(tmp, std::ios::binary);
    f << text;
    if (!f) {
      std::fprintf(stderr, "fft_wisdom: cannot write %s\n", tmp.c_str());
      return 2;
    }
  }
  std::filesystem::rename(tmp, out);
  std::printf("wrote %s (%zu bytes) in %.0f s\n", out.c_str(), std::string(text).size(),
              std::chrono::duration<double>(Clock::now() - start).count());
  std::free(text);
  return 0;
}
