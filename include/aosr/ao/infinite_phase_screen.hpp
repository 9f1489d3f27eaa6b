// An infinitely extrudable von Kármán phase screen (Assémat, Wilson & Gendron 2006, "Method for simulating
// infinitely long and non stationary phase screens with optimized memory storage", Opt. Express 14, 988).
//
// The screen is a window of `length` rows by `width` columns [rad at r0's wavelength, pitch dx]. Extrude()
// appends new rows at the end (larger row index) and drops the oldest, so a frozen-flow layer can move
// through it for ever: the sequence never repeats and keeps the von Kármán statistics.
//
// Maths. Stack the new row in X (width values) and a "stencil" of already generated pixels in Z. For a
// zero-mean stationary Gaussian field with covariance B(r) (von_karman.hpp, closed form with K_{5/6}),
//     X | Z  ~  N(A Z, B B^T),   A = C_XZ C_ZZ^-1,   B B^T = C_XX - A C_ZX,
// with C_UV the covariance matrices between the pixel sets. So new = A z + B g, g ~ N(0, I). A and B depend
// only on the geometry (dx, L0, the stencil; A not even on r0, B as r0^(-5/6)); they are computed once (C_ZZ
// by Cholesky, B B^T by a symmetric eigendecomposition with its round-off negative eigenvalues clipped to 0).
//
// Stencil (our choice; Assémat et al. use the nearest columns plus sparse points further away, their Fig. 2).
// Exact conditioning on every earlier pixel is impossible (the past is unbounded), and conditioning on the
// nearest row alone loses the large scales. We condition on every row at distance d = 1 .. length, rows 1-2
// whole and row d >= 3 at column stride s(d) = 2^ceil(log2 d) (4 for d = 3-4, 8 for d = 5-8, ...) plus the
// last column: dense where the new row is most correlated, sparse (stride ~ d, Nyquist for the scales ~d that
// a distant row still informs) further away. |Z| ~ 2 width + (width/2) log2(length/2) + length: 350 for a
// 64 x 64 window, 1200 for 184 x 188.
//
// Markov property. Because s(d) is a power of two that never decreases with d, the stencil of the next row
// lies inside {the new row} + {the current stencil}. If the stencil's pixels have the exact joint law, so do
// (new row, stencil) by construction, hence so does the next stencil: the exactness of the retained state is
// preserved for ever, and no error accumulates however long the run (a stencil of rows 1, 2, 4, 8, ... only
// is not nested and lacks this property). The initial state comes from an FFT screen (bias <= 0.35%, see
// phase_screen.hpp); the only approximation of the recursion is that a new row ignores the non-stencil
// pixels of distant rows.
//
// Accuracy (physics test: width 64, length 64, dx = 4 cm, L0 = 10 m, 4 x 80000 rows after a burn-in of 10
// window lengths): the structure function along and across the extrusion is within 0.7% of the von Kármán
// law from 1 to 16 pixels (standard errors 0.2-0.7%), and within 1.3% at 32 pixels.
//
// Cost: set-up O(|Z|^3), ~25 ms for width 64, ~120 ms for 135, ~250 ms for 184 (one core); each row costs
// width x (|Z| + width) multiply-adds, ~0.005 ms for width 64, ~0.05 ms for 184.
//
// Numerics. The covariance entries are ~sigma^2 = 0.086 (L0/r0)^(5/3) while the conditional variance is
// ~D(dx) = 6.88 (dx/r0)^(5/3): the B B^T subtraction cancels ~log10(0.17 (L0/dx)^(5/3)) digits (4 for
// L0/dx = 400, 8 for L0/dx = 10^5), acceptable in double precision; L0/dx > 10^6 is rejected.
//
// The initial window is an FFT screen with subharmonics (phase_screen.hpp) of side >= 2 max(length, width),
// cropped; extruded rows then follow the exact conditional law given their stencil.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "aosr/ao/random.hpp"
#include "aosr/core/image.hpp"

namespace aosr {

struct InfinitePhaseScreenOptions {
  // Columns of the screen (across the extrusion direction) [pixels]; 4 .. 2048. The stencil and the matrix
  // B grow with it: set-up is O(width^3) (~0.25 s for 184 columns), once per process for the same options (the
  // stencil is shared). 128: a 128-pixel pupil with wind along an axis needs ~134.
  Index width = 128;
  // Rows kept in the window [pixels]; 4 .. 2048. Also the depth of the stencil (how far back a new row is
  // conditioned), so it should be about the width for isotropic large scales. The buffer holds 2 x length
  // rows (the window is compacted every `length` extrusions).
  Index length = 128;
  // Pixel pitch dx [m]; > 0 and finite. No default (0 is invalid).
  double pixel_scale_m = 0.0;
  // Fried parameter r0 [m] at the wavelength of the phase; > 0 and finite. No default (0 is invalid).
  double r0_m = 0.0;
  // Outer scale L0 [m]; > 0, finite and at most 10^6 dx (see Numerics). Default 25 m as in phase_screen.hpp.
  double L0_m = 25.0;

  // True when every field is in range; otherwise false and `why` (if non-null) names the bad field.
  bool IsValid(std::string* why) const;
};

// Not thread-safe: Extrude() advances the noise generator and the buffer.
class InfinitePhaseScreen {
 public:
  // Builds A and B and the initial window from `seed` (the FFT screen uses DeriveSeed(seed, 0), the extrusion
  // noise a NormalGenerator seeded with DeriveSeed(seed, 1)). Throws InvalidArgument naming a bad option.
  InfinitePhaseScreen(const InfinitePhaseScreenOptions& options, std::uint64_t seed);

  // Appends `rows` >= 0 new rows (row index increasing) and drops as many of the oldest.
  void Extrude(Index rows);

  // The current window, length x width, row 0 the oldest. Valid until the next Extrude().
  Eigen::Map<const Image> Window() const {
    return Eigen::Map<const Image>(buffer_.data() + start_ * options_.width, options_.length, options_.width);
  }
  // Pointer to window row `row` (0 .. length-1), width contiguous values. Valid until the next Extrude().
  const double* Row(Index row) const { return buffer_.data() + (start_ + row) * options_.width; }

  // Number of rows extruded since construction: window row 0 is absolute row rows_extruded() of the
  // infinite strip whose rows 0 .. length-1 were the initial window.
  std::int64_t rows_extruded() const { return rows_extruded_; }
  // Stencil size |Z| (for reports).
  Index stencil_size() const;
  const InfinitePhaseScreenOptions& options() const { return options_; }

 private:
  // The stencil and the matrices A (width x |Z|) and B (width x width): they depend on the options only, not
  // on the seed, and screens with the same options share one read-only copy (infinite_phase_screen.cpp).
  struct Stencil;

  InfinitePhaseScreenOptions options_;
  std::shared_ptr<const Stencil> stencil_;
  Image buffer_;       // capacity rows x width; the window is rows [start_, start_ + length)
  Index start_ = 0;
  std::int64_t rows_extruded_ = 0;
  NormalGenerator noise_;
  Vector z_, g_;  // work space
};

}  // namespace aosr
