// Time of the analytic AO long-exposure PSF path (include/aosr/ao/analytic_ao.hpp) for the paper's system
// (8 m, actuator pitch 0.5 m, 800 Hz, integrator gain 0.35, 1 frame of delay, r0 = 0.15 m at 550 nm,
// L0 = 30 m, layers at 0/4/10 km with Cn^2 fractions 0.70/0.25/0.05 and winds 5/10/25 m/s toward 0/60/120
// degrees, bright guide star, K band 2.2 um), PSF 128 x 128 at lambda/(2D), clear binary pupil, no DM offset.
// Set up as tests/ao/analytic_ao_physics_test.cpp's PaperSystem().
//
// Per pupil grid n it prints
//  * build: the AnalyticAoPsfCalculator constructor (residual PSD on (K n)^2 cells, one R2C FFT of it, the
//    structure function, the MFT matrices), median of several constructions after a warm-up construction
//    that makes the FFTW plans (the first, cold one is printed too);
//  * PSF: median over --reps calls of Compute();
//  * the floor of one Compute(): reading src/ao/analytic_ao.cpp, each PSF performs two complex FFTs of
//    2n x 2n (FftForward of the zero-padded field, FftInverse of |spectrum|^2) and one MFT
//    (2n-1)^2 -> 128 x 128. The FFT floor is 2 x the median time of one aosr::FftForward on 2n x 2n (the
//    path's own entry point: cached FFTW plan, allocation of the output included); the MFT floor is the
//    median time of one MatrixFourierTransform::Apply of the path's geometry. Floor = FFT + MFT; the rest of
//    the PSF time is the field set-up (polar per pupil pixel), the |.|^2 and the lattice weighting loops.
//  * the long-exposure Strehl.
//
// Usage: analytic_psf_bench [--reps N] [--pupil N]   (default: reps 15, pupils 64, 128 and 256)
// FFT settings are the library defaults (FFTW_MEASURE, one thread per transform).
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <thread>
#include <vector>

#include "aosr/core/image.hpp"  // kPi
#include "aosr/core/memory.hpp"
#include "aosr/ao/analytic_ao.hpp"
#include "aosr/core/fft.hpp"
#include "aosr/core/parallel.hpp"
#include "aosr/optics/mft.hpp"
#include "aosr/optics/psf.hpp"
#include "aosr/optics/pupil.hpp"

namespace {

using namespace aosr;
using Clock = std::chrono::steady_clock;

constexpr double kD = 8.0;
constexpr double kLambda = 2.2e-6;
constexpr Index kPsfSize = 128;

double Ms(Clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

double Median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  const std::size_t h = v.size() / 2;
  return v.size() % 2 ? v[h] : 0.5 * (v[h - 1] + v[h]);
}

AnalyticAoOptions PaperSystem() {
  AnalyticAoOptions o;
  o.diameter_m = kD;
  o.actuator_pitch_m = 0.5;
  o.r0_m = 0.15;
  o.reference_wavelength_m = 0.55e-6;
  o.outer_scale_m = 30.0;
  o.layers = {{0.0, 0.70, 5.0, 0.0}, {4000.0, 0.25, 10.0, kPi / 3.0}, {10000.0, 0.05, 25.0, 2.0 * kPi / 3.0}};
  o.loop_rate_hz = 800.0;
  o.loop_gain = 0.35;
  o.loop_delay_frames = 1.0;
  o.wfs_noise_rad2 = 0.0;
  o.aliasing = true;
  o.science_wavelength_m = kLambda;
  return o;
}

struct Timing {
  double median_ms = 0.0;
  double min_ms = 0.0;
};

// Median and minimum time [ms] of one call of f over `reps` calls (after one untimed warm-up call).
template <class F>
Timing TimeMs(int reps, F&& f) {
  f();
  std::vector<double> t;
  for (int r = 0; r < reps; ++r) {
    const auto t0 = Clock::now();
    f();
    t.push_back(Ms(t0));
  }
  return {Median(t), *std::min_element(t.begin(), t.end())};
}

template <class F>
double MedianMs(int reps, F&& f) {
  return TimeMs(reps, f).median_ms;
}

}  // namespace

int main(int argc, char** argv) {
  aosr::TuneAllocatorForLargeArrays();  // as the CLI does (memory.hpp)
  int reps = 15;
  std::vector<Index> pupils = {64, 128, 256};
  for (int i = 1; i < argc; ++i) {
    const std::string key = argv[i];
    if (i + 1 >= argc) {
      std::fprintf(stderr, "usage: analytic_psf_bench [--reps N] [--pupil N]\n");
      return 2;
    }
    if (key == "--reps") {
      reps = std::max(1, std::atoi(argv[++i]));
    } else if (key == "--pupil") {
      pupils = {static_cast<Index>(std::atol(argv[++i]))};
    } else {
      std::fprintf(stderr, "usage: analytic_psf_bench [--reps N] [--pupil N]\n");
      return 2;
    }
  }
  std::string command;
  for (int i = 0; i < argc; ++i) command += (i ? " " : "") + std::string(argv[i]);
  std::printf(
      "# %s | hardware threads: %u | FFT threads %d | paper system, K band, PSF %ldx%ld at "
      "lambda/(2D), median (min) of %d PSFs; times in ms; load-sensitive\n",
      command.c_str(), std::thread::hardware_concurrency(), DefaultThreads(),
      static_cast<long>(kPsfSize), static_cast<long>(kPsfSize), reps);
  std::printf("%7s %11s %11s %10s %9s %11s %12s %9s %9s %8s\n", "pupil_n", "build cold", "build warm",
              "PSF med", "PSF min", "FFT(2n)^2", "2 FFT floor", "MFT", "floor", "Strehl");

  const AnalyticAoOptions options = PaperSystem();
  const PsfSampling sampling{kLambda, 0.5 * kLambda / kD, kPsfSize, kPsfSize};
  for (const Index n : pupils) {
    const Image pupil = CircularPupil(n, PupilGeometry{kD, 0.0});
    const Image opd = Image::Zero(n, n);

    auto t0 = Clock::now();
    { const AnalyticAoPsfCalculator cold(options, n, sampling); }
    const double build_cold = Ms(t0);
    const int build_reps = n >= 256 ? 3 : 5;
    const double build = MedianMs(build_reps, [&] { const AnalyticAoPsfCalculator c(options, n, sampling); });

    const AnalyticAoPsfCalculator calc(options, n, sampling);
    double strehl = 0.0;
    const Timing psf = TimeMs(reps, [&] { strehl = calc.Compute(pupil, opd).strehl; });

    // One FftForward of the path's 2n x 2n padded field (same plan cache as Compute).
    ComplexImage field = ComplexImage::Zero(2 * n, 2 * n);
    field.topLeftCorner(n, n) = pupil.cast<Complex>();
    double sink = 0.0;
    const double fft = MedianMs(std::max(reps, 20), [&] { sink += std::abs(FftForward(field)(0, 0)); });

    // One MFT of the path's geometry: (2n-1)^2 lattice, span n, onto 128 x 128 at 0.5 lambda/D.
    MftGeometry g;
    g.input = {2 * n - 1, 2 * n - 1};
    g.pupil_span_px = static_cast<double>(n);
    g.output = {kPsfSize, kPsfSize};
    g.pixel_scale_lod = 0.5;
    const MatrixFourierTransform mft(g);
    const ComplexImage lattice = ComplexImage::Constant(2 * n - 1, 2 * n - 1, Complex(1.0, 0.0));
    const double mft_ms = MedianMs(reps, [&] { sink += std::abs(mft.Apply(lattice)(0, 0)); });

    std::printf("%7ld %11.1f %11.1f %10.2f %9.2f %11.3f %12.3f %9.2f %9.2f %8.4f\n", static_cast<long>(n),
                build_cold, build, psf.median_ms, psf.min_ms, fft, 2.0 * fft, mft_ms, 2.0 * fft + mft_ms,
                strehl);
    if (sink < 0.0) std::printf("unreachable\n");
  }
  return 0;
}
