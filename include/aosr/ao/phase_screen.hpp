// Random von Kármán phase screens by the FFT method with low-frequency (subharmonic) compensation.
//
// What is computed. An n x n screen phi(y, x) [rad, at the wavelength of r0] of pixel pitch dx [m], pixel
// (i, k) at position (y, x) = (i dx, k dx) (image.hpp: row-major, pixel centres at integers), whose
// statistics approximate a stationary Gaussian field with the von Kármán spectrum Phi(f) of von_karman.hpp:
//     phi(r) = Re sum_j c_j exp(2 pi i f_j . r),   c_j = a_j (g_j + i g'_j),   g, g' ~ N(0, 1) independent,
// so that <phi(r) phi(r')> = sum_j a_j^2 cos(2 pi f_j . (r - r')): frequency f_j carries variance P_j =
// a_j^2. The imaginary part is a second screen with the same statistics, independent of the first (the
// frequency set is symmetric under f -> -f with equal weights, so the Re/Im cross-covariance vanishes):
// GeneratePair() returns both for the price of one.
//
// The frequencies and their variances (df = 1/(n dx), the grid's fundamental frequency):
//  1. FFT bins f_k = k df, k in [-n/2, n/2)^2, evaluated with one n x n complex FFT (Lane et al. 1992,
//     "Simulation of a Kolmogorov phase screen", Waves in Random Media 2, 209; McGlamery 1976). The point
//     value P_k = Phi(f_k) df^2 is the classical choice.
//  2. Aliasing. A pixel samples the continuous phase at a point, so the sampled field's spectrum is the
//     aliased one, sum_m Phi(f_k + m/dx). We add the aliases |m|_inf <= 2 exactly and the rest as the
//     integral of Phi outside the square of half-width 2.5/dx per lattice cell (a white floor). Without this
//     the screen lacks the power above Nyquist and D(dx) is 8-10% low; with it D at 1-8 pixels is within
//     ~0.5% of the continuous von Kármán D (the sampled field then has the continuous field's statistics at
//     the sample points, which is what the PSF and WFS models read).
//  3. Low frequencies. A periodic FFT screen has no power below df and the wrong power near it: its D
//     falls 10-30% short at a quarter of the screen (worse as L0/(n dx) grows). Following Lane et al. (1992)
//     and Johansson & Gavel (1994, SPIE 2200, 372: three levels of 3 x 3 subharmonics), the low frequencies
//     are added by direct summation at frequencies that need not be grid frequencies (so the screen is no
//     longer periodic). Our variant, chosen by computing the exact expected structure function and Zernike
//     variances of each candidate design against the closed forms of von_karman.hpp:
//       - the 9 x 9 innermost FFT bins (|k|_inf <= 4) are removed from the FFT and their area
//         [-4.5 df, 4.5 df]^2 is re-sampled on a 27 x 27 grid of spacing df/3 (Lane's first subharmonic
//         level, extended from 3 x 3 cells to the whole block where a bin-sized cell is too coarse for the
//         low-order statistics: with only the 5 x 5 block, coma/trefoil variances over a pupil of 2/3 of the
//         screen came out 2% low);
//       - its central cell is split recursively into 3 x 3 cells of spacing df/3^p, p = 2 .. levels (Lane's
//         subharmonics), the last central cell (piston) being dropped;
//       - every cell of the re-sampled block, every subharmonic cell and the FFT ring |k|_inf = 5 get the
//         weight that preserves the cell's second moment,
//             P = integral_cell Phi(f) |f|^2 d^2f / |f_c|^2   (Gauss-Legendre on sub-cells),
//         because these cells enter D(r) = sum P 2 (1 - cos(2 pi f . r)) ~ sum P (2 pi f . r)^2 at the
//         separations of interest (and tilt, whose |Q|^2 ~ f^2 likewise); the point value underweights them
//         (Phi is convex) and the cell's total power overweights them by up to 30% (Phi is steep, so the
//         power sits at the inner edge).
//     Measured bias of the expectation (ExpectedStructureFunction vs the closed form, n = 128, auto levels,
//     L0 from 0.4 to 4000 screen widths): |bias| <= 0.35% for separations of 1 .. n/4 pixels along rows,
//     columns and diagonals, <= 1.1% at n/2. Expected Zernike variances over a pupil of 2/3 of the screen
//     (L0 = 5 D): Z2-Z11 within 0.7%. Classical Lane (point weights, 3 levels, no aliasing) is 2-6% low over
//     the same range, and a plain periodic FFT screen 11% low at n/4 for L0 = 2 n dx (27% for L0 = 4 n dx).
//     Levels: automatic = 3 + ceil(log3(max(L0 / (n dx), 1))): the lowest retained frequency must reach
//     below ~1/L0, where the von Kármán spectrum flattens (e.g. 5 levels for L0 = 4 n dx, 10 for 1000 n dx).
// The mean of each generated screen is subtracted (piston is not a turbulence observable).
//
// Cost: one n x n complex FFT, 2 n^2 normal deviates and ~(27 + 3 levels) complex multiply-adds per pixel:
// ~2 ms for 128 x 128, ~14 ms for 256 x 256, ~45 ms for 512 x 512 (one core; the first call of a size also
// plans its FFT, ~0.15 s with the default FFTW_MEASURE planner).
// Construction evaluates Phi ~25 n^2 times (aliases) plus ~10^5 (cell integrals): ~7 ms for n = 128, ~85 ms
// for n = 512.
// Determinism: a seed fixes the screen (random.hpp's NormalGenerator); the FFT bins draw their deviates in
// row-major order, then the low-frequency cells in order of level.
#pragma once

#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "aosr/core/image.hpp"

namespace aosr {

struct PhaseScreenOptions {
  // Screen side n [pixels]; 16 <= n <= 16384. Any size works; FFTW is fastest for 2^a 3^b 5^c 7^d. 256:
  // twice a 128-pixel pupil, so the pupil sits well inside the screen.
  Index size = 256;
  // Pixel pitch dx [m]; > 0 and finite. For a pupil of diameter D sampled by N pixels, D/N. No default: the
  // value 0 is invalid and must be set.
  double pixel_scale_m = 0.0;
  // Fried parameter r0 [m] at the wavelength at which the phase is wanted (phases are in radians at that
  // wavelength; OPD = phase * lambda / 2 pi is achromatic); > 0 and finite.
  double r0_m = 0.0;
  // Outer scale L0 [m]; > 0 and finite. The default 25 m is a typical median at good sites (e.g. ~22 m at
  // Paranal, Ziad et al. 2004); near-Kolmogorov screens use L0 >> n dx, with more subharmonic levels.
  double L0_m = 25.0;
  // Low-frequency compensation (see the top of the header): -1 chooses the number of levels from L0 / (n dx);
  // 0 gives a plain periodic FFT screen (point weights, no subharmonics; aliasing still added), useful only
  // to compare; 1 .. 20 uses that many levels (1: the 27 x 27 re-sampled block only).
  int subharmonic_levels = -1;

  // True when every field is in range; otherwise false and, if `why` is non-null, a message naming the
  // bad field, its value and the allowed range.
  bool IsValid(std::string* why) const;
};

// Number of screens (or screen pairs) generated by any PhaseScreenGenerator since the program started, all
// threads (the infinite screens of atmosphere.hpp start from one each). Tests use it to prove that a scene
// without an atmosphere never makes a phase screen.
std::uint64_t PhaseScreensGenerated();

// Generator of independent screens with fixed options. Construction precomputes every frequency's
// variance; Generate() then costs one FFT. Immutable and thread-safe after construction.
class PhaseScreenGenerator {
 public:
  // Throws InvalidArgument naming the bad option field.
  explicit PhaseScreenGenerator(const PhaseScreenOptions& options);

  // One screen [rad at r0's wavelength], size x size, zero mean, determined by `seed`.
  Image Generate(std::uint64_t seed) const;
  // Two independent screens from one seed (the real and imaginary parts); .first == Generate(seed).
  std::pair<Image, Image> GeneratePair(std::uint64_t seed) const;

  // Exact expectation <(phi(r + s) - phi(r))^2> [rad^2] of the generated screens at a separation of
  // s = (dy_px, dx_px) pixels (any real values): sum_j P_j 2 (1 - cos(2 pi f_j . s dx)). Compare with
  // VonKarmanStructureFunction(|s| dx, r0, L0) to see the discretisation bias without sampling noise.
  // Cost O(n^2).
  double ExpectedStructureFunction(double dy_px, double dx_px) const;

  // The number of subharmonic levels in use (resolved when the option was -1).
  int subharmonic_levels() const { return levels_; }
  const PhaseScreenOptions& options() const { return options_; }

 private:
  // A square grid of directly summed frequencies f = (b, a) * spacing, a, b in [-half, half] (a along x),
  // with per-frequency amplitude sqrt(P) (row-major over (b, a); the centre is 0).
  struct FrequencyGrid {
    double spacing = 0.0;
    int half = 0;
    std::vector<double> amplitude;
  };

  ComplexImage GenerateComplex(std::uint64_t seed) const;

  PhaseScreenOptions options_;
  int levels_ = 0;
  Image bin_amplitude_;  // sqrt(P_k) in FFT order (bin (i, k) has frequency (SignedFrequency(i), ...) df)
  std::vector<FrequencyGrid> grids_;
};

}  // namespace aosr
