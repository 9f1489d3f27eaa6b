// 2-D discrete Fourier transforms over FFTW, with plans cached by shape.
//
// Conventions:
//  * Forward transforms are unnormalised:  X(u, v) = sum_{y,x} x(y, x) exp(-2 pi i (u y / R + v x / C)).
//  * Inverse transforms divide by R*C, so Inverse(Forward(x)) == x.
//  * Real transforms store the non-redundant half spectrum: R x (C/2 + 1), FFTW's layout.
//
// Execution (DESIGN.md §3, "execution is not maths"):
//  * Plans are made once per (kind, shape, batch, strides, planner) under a global lock, because only
//    fftw_execute* is thread-safe; executing a cached plan needs no lock.
//  * A transform smaller than 192 x 192 pixels is one FFTW 2-D plan run directly on the caller's arrays.
//    From 192 x 192 on it is FFTW's row-column algorithm cut into a fixed number of blocks (at most 8,
//    a function of the shape only): a row pass (each block a batched 1-D plan over contiguous rows) and
//    a column pass (each block a batched 1-D plan over a band of columns, strided, in place; or, where
//    the row stride would alias in the cache or the array is large, chunks of 8 columns gathered into a
//    contiguous buffer, transformed and scattered back). The blocks are the tasks of ParallelFor
//    (parallel.hpp) on DefaultThreads() threads. Which way is a function of the shape only.
//    bench/results/fft.md compares this with one FFTW 2-D plan on 1 and 2 threads.
//  * Plans come from wisdom the library ships (data/fftw_wisdom.txt: FFTW_PATIENT's choices for the
//    plans of the common square sizes, 8^2 to 2048^2, made once by build/bench/fft_wisdom and compiled in)
//    where it has them, and from FFTW_ESTIMATE's deterministic heuristics elsewhere. Either way no plan
//    is timed at run time, so the plan is a function of the shape. The wisdom's plans were measured
//    1.5-2x faster than FFTW_ESTIMATE's at 512^2-2048^2 (bench/results/fft.md). If this machine's FFTW
//    cannot read it (another FFTW version or build), FftWisdomLoaded() says so and plans are ESTIMATE's.
//  * Reproducibility: with the default planner (kEstimate: shipped wisdom, then FFTW's heuristics, no
//    timing) the output bytes depend only on the input bytes: not on the run, the thread count, or the
//    arrays' addresses, because every block is always computed by the same plan on arrays of the same
//    alignment (tested bit for bit for every size class: powers of two, odd, primes > 7, one-row
//    images). kMeasure and kPatient time candidate algorithms for shapes the wisdom lacks, so the chosen
//    plan, and with it the last bits of every result, may change from run to run; they are opt-in.
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
  // Plan from the wisdom the library ships where it has the shape (the default). False plans from FFTW's
  // planner alone: for benchmarks of the difference, and tests that results agree to rounding either way.
  bool shipped_wisdom = true;
};

// Global FFT settings. Thread-safe. Changing them affects plans made afterwards.
void SetFftSettings(const FftSettings& settings);
FftSettings GetFftSettings();

// Real-to-complex forward transform: R x C -> R x (C/2+1), unnormalised.
ComplexImage FftR2C(const Image& x);
// The same into *X, resized only when its shape differs (hot loops reuse one buffer).
void FftR2CInto(const Image& x, ComplexImage* X);
// Complex-to-real inverse: R x (C/2+1) -> R x `cols`, divided by R*cols. `cols` must be
// 2*(X.cols()-1) or 2*(X.cols()-1)+1.
Image FftC2R(const ComplexImage& X, Index cols);
// The same into *x, resized only when its shape differs. X is not modified.
void FftC2RInto(const ComplexImage& X, Index cols, Image* x);
// Full complex transforms; Forward unnormalised, Inverse divided by R*C.
ComplexImage FftForward(const ComplexImage& x);
ComplexImage FftInverse(const ComplexImage& X);
// The same into *X / *x (a separate array), resized only when its shape differs.
void FftForwardInto(const ComplexImage& x, ComplexImage* X);
void FftInverseInto(const ComplexImage& X, ComplexImage* x);

// Number of distinct plans made so far (for tests and benchmarks of the cache).
std::size_t FftPlanCount();
// Destroys every cached plan and FFTW's wisdom, so the next transforms plan as a fresh process would (the
// run-to-run reproducibility test). No transform may be running on any thread while it is called.
void FftResetPlansForTesting();
// Whether FFTW accepted the shipped wisdom when the last plan with shipped_wisdom on was made (false
// before any such plan, or when this FFTW cannot read it: another FFTW version or build).
bool FftWisdomLoaded();
// The shipped wisdom itself (FFTW's text format), for benchmarks that plan with FFTW directly.
const char* FftShippedWisdom();
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
// The same projection applied in place (no copy of the half spectrum).
void HermitianProjectInPlace(ComplexImage* half, Index cols);

// Signed DFT frequency index of bin k in a transform of length n: k for k <= n/2, else k - n.
inline Index SignedFrequency(Index k, Index n) { return k <= n / 2 ? k : k - n; }

}  // namespace aosr
