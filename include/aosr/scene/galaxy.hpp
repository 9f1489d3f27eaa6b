// Sérsic galaxies: elliptical Sérsic profiles rendered as pixel-integrated flux, and seeded galaxy fields.
//
// ## The profile (Sérsic 1963; the review of Graham & Driver 2005, PASA 22, 118)
//
//     I(R) = I_e exp( -b_n [ (R / R_e)^(1/n) - 1 ] ),
//
// n the Sérsic index (0.5: Gaussian, 1: exponential disc, 4: de Vaucouleurs bulge), R_e the half-light
// radius, I_e the surface brightness at R_e, and b_n the constant that makes R_e enclose half the light:
// γ(2n, b_n) = Γ(2n) / 2, i.e. P(2n, b_n) = 1/2 with P the regularised lower incomplete gamma function.
// Ciotti & Bertin (1999, A&A 352, 447) give the asymptotic expansion
//
//     b_n ≈ 2n - 1/3 + 4/(405 n) + 46/(25515 n²) + 131/(1148175 n³) - 2194697/(30690717750 n⁴),
//
// whose error (measured against the exact root, galaxy_physics_test) is +2.5e-4 at n = 0.5, +4.2e-5 at n = 1,
// +4.7e-6 at n = 2, +5.4e-7 at n = 4 and +3.3e-8 at n = 10, and which degrades below n ~ 0.36 (-3.5e-3 at
// n = 0.25, where b_n = 0.2275). SersicBn() solves P(2n, b) = 1/2
// exactly (safeguarded Newton from a bracket, to ~1e-14 relative), which costs microseconds; the renderer
// uses it. SersicBnCiottiBertin() is the expansion, kept to document and test it.
//
// Ellipse. With the centre (y_c, x_c), position angle θ (the major axis' angle from +x toward +y, i.e. toward
// larger row index: clockwise on a display whose row 0 is at the top) and axis ratio q = b/a in (0, 1],
//     u =  (x - x_c) cos θ + (y - y_c) sin θ,   v = -(x - x_c) sin θ + (y - y_c) cos θ,   R² = u² + (v / q)²,
// so R_e is measured along the major axis and the half-light isophote is the ellipse of semi-axes R_e, q R_e.
//
// Total flux (Graham & Driver 2005, sect. 2, with the ellipse's area factor q):
//     F_tot = 2π n q R_e² I_e e^{b_n} b_n^(-2n) Γ(2n),
// and the fraction of the light inside the isophote R is P(2n, b_n (R / R_e)^(1/n)) (SersicEnclosedFraction).
// Galaxies are parametrised by F_tot; I_e follows.
//
// ## Rendering
//
// A pixel's value is the integral of I over the pixel's square (flux per HR pixel, image.hpp), computed by
// adaptive cubature: a 2x2 Gauss-Legendre rule on the pixel is compared with its midpoint value; where they
// disagree by more than the tolerance (near the centre, where n > 1 profiles have a cusp with infinite
// slope: I ≈ I_0 (1 - b_n (R / R_e)^(1/n))), the cell is split into four and each quarter's 2x2 rule compared
// with the parent's, recursively, down to max_depth levels. The acceptance test for a cell of area A (px²) is
//     |fine - coarse| <= relative_tolerance (|fine| + F_tot A / field_area),
// so the summed error is about relative_tolerance of the pixel values plus of the total flux. Pixels beyond
// the isophote R_cut enclosing 1 - 1e-12 of the light are set to 0 (for n <= 1 this skips most of the field;
// for n = 4 R_cut ~ 10^3 R_e, i.e. everything is computed). The field clips the profile: light falling
// outside the grid is lost, as for a real detector. There is no wrap-around.
//
// Errors: aosr::InvalidArgument naming the function and the argument or field.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "aosr/core/image.hpp"
#include "aosr/scene/star_field.hpp"

namespace aosr {

// Regularised lower incomplete gamma P(a, x) = γ(a, x) / Γ(a) for a > 0, x >= 0 (series for x < a + 1,
// Legendre's continued fraction for Q = 1 - P otherwise; ~1e-15 absolute). InvalidArgument otherwise.
double RegularisedGammaP(double a, double x);

// b_n with P(2n, b_n) = 1/2, for n in (0.2, 20] (the valid range of SersicGalaxy::n).
double SersicBn(double n);
// The Ciotti & Bertin (1999) asymptotic expansion of b_n (top of file), n in (0.2, 20].
double SersicBnCiottiBertin(double n);
// Fraction of the total light inside the isophote R = radius_over_re · R_e: P(2n, b_n radius_over_re^(1/n)).
// n in (0.2, 20], radius_over_re >= 0.
double SersicEnclosedFraction(double n, double radius_over_re);

struct SersicGalaxy {
  // Centre in continuous HR pixel coordinates (image.hpp), finite; it may lie off the field.
  double y = 0.0;
  double x = 0.0;
  // Total flux F_tot over the whole plane (image flux units), finite and >= 0.
  double flux = 1.0;
  // Sérsic index n in (0.2, 20]. Default 1: an exponential disc.
  double n = 1.0;
  // Half-light radius R_e along the major axis [HR px], finite and > 0.
  double half_light_radius_px = 5.0;
  // Axis ratio q = b/a in (0, 1]; 1 is round.
  double axis_ratio = 1.0;
  // Position angle θ of the major axis [rad] from +x toward +y, finite (any value; period π).
  double position_angle_rad = 0.0;

  // Surface brightness at R_e, I_e = F_tot / (2π n q R_e² e^{b_n} b_n^(-2n) Γ(2n)) [flux / px²].
  double EffectiveIntensity() const;
  // Surface brightness I at the continuous point (y, x) [flux / px²].
  double Intensity(double y, double x) const;

  // True if every field is in range; otherwise false and, if why != nullptr, *why names the field.
  bool IsValid(std::string* why) const;
};

struct SersicRenderOptions {
  // Target relative accuracy of the pixel integrals (see Rendering above), in [1e-12, 1e-2]. Default 1e-6:
  // far below any photon noise, and the cusp of an n = 4 galaxy still converges in ~20 levels.
  double relative_tolerance = 1e-6;
  // Maximum subdivision depth of a pixel (cells of 2^-depth px), in [0, 40]. Default 30: deep enough that
  // the tolerance, not the depth, ends the refinement even at an n = 10 cusp.
  int max_depth = 30;

  bool IsValid(std::string* why) const;
};

// Pixel-integrated image of one galaxy on an HR grid of shape hr (both sides >= 1).
Image RenderSersic(Shape hr, const SersicGalaxy& galaxy, const SersicRenderOptions& options = {});
// Sum of the pixel-integrated images of the galaxies (each validated; the error names its index).
Image RenderGalaxies(Shape hr, const std::vector<SersicGalaxy>& galaxies,
                     const SersicRenderOptions& options = {});

struct GalaxyFieldOptions {
  // Number of galaxies, in [0, 100000].
  int count = 10;
  // Sérsic index, uniform on [n_min, n_max] within (0.2, 20]. Default 0.5..4: from Gaussian-like through
  // discs to de Vaucouleurs bulges, the range of most observed galaxies.
  double n_min = 0.5;
  double n_max = 4.0;
  // Half-light radius [HR px], log-uniform on [re_min_px, re_max_px], 0 < re_min_px <= re_max_px.
  // Default 1..8: from barely resolved on a camera of r = 2..4 up to clearly extended.
  double re_min_px = 1.0;
  double re_max_px = 8.0;
  // Axis ratio q, uniform on [q_min, q_max] within (0, 1]. Default 0.3..1: thin discs seen inclined to round.
  double q_min = 0.3;
  double q_max = 1.0;
  // Total fluxes from this power law (star_field.hpp). Default alpha = 2 on 10 .. 10^4.
  LuminosityFunction flux{2.0, 10.0, 1.0e4};
  // Centres are uniform on the field shrunk by margin_px on every side, >= 0 and < half the smaller side.
  double margin_px = 0.0;

  bool IsValid(std::string* why) const;
};

// A seeded random galaxy field (hr both sides >= 1): centres uniform, n uniform, R_e log-uniform, q uniform,
// θ uniform on [0, π), flux from the power law. Deterministic per seed (DeriveSeed(seed, 2) stream).
std::vector<SersicGalaxy> GalaxyField(Shape hr, const GalaxyFieldOptions& options, std::uint64_t seed);

}  // namespace aosr
