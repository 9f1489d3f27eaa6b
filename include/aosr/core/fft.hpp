// 2-D discrete Fourier transforms over FFTW, with plans cached by shape.
//
// Conventions:
//  * Forward transforms are unnormalised:  X(u, v) = sum_{y,x} x(y, x) exp(-2 pi i (u y / R + v x / C)).
//  * Inverse transforms divide by R*C, so Inverse(Forward(x)) == x.
//  * Real transforms store the non-redundant half spectrum: R x (C/2 + 1), FFTW's layout.
//
// Execution (DESIGN.md §3, "execution is not maths"):
//  * Plans are made once per (kind, length, batch, planner) under a global lock, because only
//    fftw_execute* is thread-safe; executing a cached plan needs no lock.
//  * A transform of at least 128 x 128 pixels is computed row-column: blocks of whole rows, then blocks of
//    whole columns, each block one batched 1-D plan run on an aligned per-thread scratch copy. The blocks
//    are the tasks of ParallelFor (parallel.hpp) on DefaultThreads() threads. Smaller transforms are one
//    2-D plan on an aligned scratch copy. Either way every block of a given shape meets the same plan on
//    a buffer of the same alignment, so
//  * Reproducibility: with the default planner (kEstimate) the output bytes depend only on the input
//    bytes: not on the run, the thread count, or the arrays' addresses (tested bit for bit). kMeasure and
//    kPatient time candidate algorithms, so the chosen plan, and with it the last bits of every result,
//    may change from run to run; they are opt-in for benchmarks (bench/results/fft.md measures the cost).
#pragma once

#include <cstddef>
#include <cstdint>

#include "aosr/core/image.hpp"

namespace aosr {

struct FftSettings {
  // How hard FFTW searches for a fast plan. kEstimate picks by FFTW's deterministic heuristics: instant,
  // and the same plan in every run, which is what makes outputs bit-reproducible (the default). kMeasure
  // times candidates once per shape and kPatient more thoroughly: sometimes faster, never reproducible.
  enum class Planner { kEstimate, kMeasure, kPatient };
  Planner planner = Planner::kEstimate;
};

// Global FFT settings. Thread-safe. Changing them affects plans made afterwards.
void SetFftSettings(const FftSettings& settings);
FftSettings GetFftSettings();

// Real-to-complex forward transform: R x C -> R x (C/2+1), unnormalised.
ComplexImage FftR2C(const Image& x);
// Complex-to-real inverse: R x (C/2+1) -> R x `cols`, divided by R*cols. `cols` must be
// 2*(X.cols()-1) or 2*(X.cols()-1)+1.
Image FftC2R(const ComplexImage& X, Index cols);
// Full complex transforms; Forward unnormalised, Inverse divided by R*C.
ComplexImage FftForward(const ComplexImage& x);
ComplexImage FftInverse(const ComplexImage& X);

// Number of distinct plans made so far (for tests and benchmarks of the cache).
std::size_t FftPlanCount();
// Number of transforms executed through this file since the program started (all threads; a relaxed
// atomic counter). Tests use it to prove a disabled stage does no FFT work; benchmarks to count the FFT
// floor of an algorithm. Every FFT in aosr goes through this file, so the count is complete.
std::uint64_t FftExecutionCount();

// The smallest even n' >= n (n >= 1) whose prime factors are all in {2, 3, 5, 7}: sizes FFTW transforms
// fastest (a padded grid rounded up this way costs a few percent more pixels instead of a slow prime).
Index NextFastFftSize(Index n);
// Expands a half spectrum (R x (C/2+1)) of a real signal to the full R x C spectrum using
// Hermitian symmetry X(-u, -v) = conj X(u, v).
ComplexImage ExpandHalfSpectrum(const ComplexImage& half, Index cols);

// Projects a half spectrum onto the spectra of real signals: on the columns that FFTW's c2r reads as
// self-conjugate (v = 0 and, for even `cols`, v = cols/2) it enforces X(-u, v) = conj X(u, v) by
// averaging each pair. A transfer function that is not Hermitian (e.g. a fractional phase ramp at the
// Nyquist bin) would otherwise be applied differently by c2r and by an explicit Fourier-domain solver.
ComplexImage HermitianProjection(const ComplexImage& half, Index cols);

// Signed DFT frequency index of bin k in a transform of length n: k for k <= n/2, else k - n.
inline Index SignedFrequency(Index k, Index n) { return k <= n / 2 ? k : k - n; }

}  // namespace aosr
