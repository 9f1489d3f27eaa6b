// Random star fields: unresolved sources with a power-law luminosity function, placed uniformly (Poisson)
// or with a hard-core minimum separation. Rendering through the PSF is point_sources.hpp's job.
//
// ## Luminosity function
//
// Fluxes follow the truncated power law
//
//     dN/dF ∝ F^(-alpha),   F_min <= F <= F_max,
//
// sampled by inverting its CDF: with u uniform on [0, 1) and e = 1 - alpha,
//
//     F = [F_min^e + u (F_max^e - F_min^e)]^(1/e)      (alpha != 1),    F = F_min (F_max/F_min)^u   (alpha =
//     1).
//
// Meaning of alpha. In magnitudes (F ∝ 10^(-0.4 m)) the law is dN/dm ∝ 10^(0.4 (alpha - 1) m): the number of
// stars per magnitude grows by a factor 10^(0.4 (alpha - 1)) per magnitude fainter. The flux carried per
// logarithmic flux interval is F² dN/dF ∝ F^(2 - alpha):
//   alpha < 2   bright stars carry most of the light (few dominant stars, the rest faint);
//   alpha = 2   every decade of flux carries the same total light;
//   alpha = 2.5 the Euclidean counts of uniformly distributed standard candles, N(>F) ∝ F^(-3/2)
//               (dN/dm ∝ 10^(0.6 m));
//   alpha > 2.5 steeper than any static Euclidean population; faint stars dominate the light.
// Galactic star counts are flatter than Euclidean because the Galaxy's density falls off along the line of
// sight (Bahcall & Soneira 1980, ApJS 44, 73), so real fields lie mostly between 1.5 and 2.5.
// Default alpha = 2: equal light per decade makes the field's dynamic range matter at every flux level (no
// single star dominates the frame's light and the faint end is not a negligible background), which is what
// a super-resolution test needs; it also sits inside the observed range.
//
// ## Positions and crowding
//
// Positions are continuous HR pixel coordinates (image.hpp: pixel centres at integers, the field covering
// [-1/2, rows - 1/2) x [-1/2, cols - 1/2)), uniform on the field shrunk by margin_px on every side.
//   * min_separation_px = 0: independent uniform positions, i.e. a binomial (fixed-count Poisson) field:
//     with density rho = count / area, the mean nearest-neighbour distance is 1 / (2 sqrt(rho)) and the
//     fraction of stars with a neighbour closer than d is 1 - exp(-pi rho d²). Crowding is then set by count.
//   * min_separation_px = s > 0: random sequential addition (RSA) with a hard core: each candidate is drawn
//     uniformly and rejected if it lies within s of an accepted star (planar distance; the rendering is
//     periodic, so use margin_px >= s/2 if wrapped neighbours must also be separated). RSA of discs of
//     diameter s jams at a covered fraction of ~0.547 (Feder 1980, J. Theor. Biol. 87, 237); we require the
//     packing fraction count · pi s²/4 / area <= 0.4 so that the draw terminates quickly.
//
// ## Determinism
//
// Positions use the stream DeriveSeed(seed, 0) and fluxes DeriveSeed(seed, 1) (ao/random.hpp), so changing
// the crowding options does not change the fluxes, and a seed gives the same field on every platform (up to
// the last-bit rounding of pow/log in libm).
//
// Errors: aosr::InvalidArgument naming the function and the argument (or the options field). A hard-core draw
// that cannot place every star within its attempt budget throws aosr::Error with the count placed.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "aosr/core/image.hpp"
#include "aosr/scene/objects.hpp"

namespace aosr {

// The truncated power-law luminosity function dN/dF ∝ F^(-alpha) on [flux_min, flux_max] (see top of file).
struct LuminosityFunction {
  // Power-law index alpha (dimensionless), finite, in [0, 5]. Default 2: equal light per decade (see above).
  double alpha = 2.0;
  // Flux range in the image's flux units (total flux of one star), 0 < flux_min < flux_max, finite.
  // Default 1 .. 1000: three decades, 7.5 magnitudes, a typical usable dynamic range of one exposure.
  double flux_min = 1.0;
  double flux_max = 1000.0;

  // Inverse CDF at u in [0, 1] (InvalidArgument outside). Quantile(0) = flux_min, Quantile(1) = flux_max.
  double Quantile(double u) const;
  // CDF at flux f (0 below flux_min, 1 above flux_max).
  double Cdf(double f) const;
  // Mean flux  ∫ F p(F) dF  (closed form; the alpha = 1 and alpha = 2 cases are logarithmic).
  double MeanFlux() const;

  // True if every field is in range; otherwise false and, if why != nullptr, *why names the field.
  bool IsValid(std::string* why) const;
};

struct StarFieldOptions {
  // Number of stars, in [0, 10^7].
  int count = 100;
  // Flux distribution of the stars.
  LuminosityFunction luminosity;
  // Hard-core minimum separation in HR pixels, >= 0 and finite; 0 (default) is an uncorrelated field whose
  // crowding is set by count alone. Needs count · pi s²/4 <= 0.4 · (available area) (see top of file).
  double min_separation_px = 0.0;
  // Distance in HR pixels kept free on every side of the field, >= 0 and finite, and smaller than half of
  // each side. 0 (default) uses the whole field; a margin of a few PSF widths keeps the wings of edge stars
  // from wrapping across the periodic boundary.
  double margin_px = 0.0;

  // True if every field is in range; otherwise false and, if why != nullptr, *why names the field.
  bool IsValid(std::string* why) const;
};

// A random star field on an HR grid of shape `hr` (both sides >= 1), deterministic per seed. Sources are in
// draw order (not sorted); positions in continuous HR pixel coordinates, fluxes from options.luminosity.
std::vector<PointSource> StarField(Shape hr, const StarFieldOptions& options, std::uint64_t seed);

// Given positions (the y, x of each element of `positions`; their flux is ignored), returns the sources with
// fluxes drawn from `luminosity` using the flux stream of `seed` (the same fluxes StarField would draw for as
// many stars). Positions must be finite.
std::vector<PointSource> AssignFluxes(const std::vector<PointSource>& positions,
                                      const LuminosityFunction& luminosity, std::uint64_t seed);

}  // namespace aosr
