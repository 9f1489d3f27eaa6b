// Telescope pupils sampled on the square pupil grid that every optics module shares.
//
// The pupil grid (one statement, used by pupil, Zernike, PSF and later DM/turbulence/WFS code):
//  * An n x n image spans exactly the telescope diameter D: pixel pitch D/n, and pixel (i, k)
//    (row i = y, column k = x, image.hpp) has its centre at
//        y = (i - (n-1)/2) * D/n,   x = (k - (n-1)/2) * D/n      [metres from the pupil centre],
//    so the pupil centre falls between pixels for even n and on the middle pixel for odd n. The grid
//    is symmetric under y -> -y and x -> -x, which keeps unaberrated PSFs exactly centro-symmetric.
//  * Normalised coordinates divide by the radius R = D/2:  x_n = (2k - (n-1))/n in (-1, 1), likewise y_n;
//    rho = sqrt(x_n^2 + y_n^2) is 1 on the rim and theta = atan2(y_n, x_n) (radians, from +x toward +y,
//    i.e. toward larger row index). Zernike polynomials are functions of (rho, theta).
//  * Amplitudes are dimensionless transmissions in [0, 1]; optical path differences (OPD) are metres.
//
// A pixel belongs to the pupil when its centre does (supersample = 1): this is the rule Zernike() uses
// for its masks, so a binary pupil and a Zernike mode of the same n have identical supports. With
// supersample s > 1 each pixel instead holds the fraction of its area covered by the aperture, estimated
// on an s x s sub-grid of sub-pixel centres (error O(1/s) per edge pixel, and the errors of neighbouring
// edge pixels largely cancel): grey, anti-aliased edges whose sum is the aperture area to ~1e-5 and which
// vary smoothly as the geometry changes (no pixel popping in or out). Caveat: a grey value A transmits A^2 of
// the energy in the sampled field, not A; psf.hpp explains the resulting ~1/n normalisation offset.
//
// The geometry is a plain struct so later apertures (spiders, segments) extend it without changing the
// grid convention.
#pragma once

#include <string>

#include "aosr/core/image.hpp"

namespace aosr {

struct PupilGeometry {
  // Outer diameter D of the aperture [m]; > 0 and finite. The pupil grid spans exactly D.
  double diameter_m = 0.0;
  // Central obstruction: diameter of the (circular) obstruction divided by D, in [0, 1).
  // 0 is an unobstructed disk; e.g. 0.14 for a VLT UT, ~0.3 for many Cassegrain telescopes.
  double obstruction = 0.0;

  // True when every field is in range; otherwise false and, if `why` is non-null, a message naming the
  // bad field, its value and the allowed range.
  bool IsValid(std::string* why) const;
};

// Normalised coordinate (in units of the radius D/2) of the centre of pixel index i on an n-pixel pupil
// grid: (2i - (n-1))/n. Applies to rows (y) and columns (x) alike.
inline double NormalisedPupilPosition(Index i, Index n) {
  return (2.0 * static_cast<double>(i) - static_cast<double>(n - 1)) / static_cast<double>(n);
}

// Polar coordinates of the pixel centres of an n x n pupil grid (see the top of this header).
struct PolarCoordinates {
  Image rho;    // normalised radius, 1 on the rim of the pupil (values up to ~sqrt(2) in the corners)
  Image theta;  // azimuth [rad] in (-pi, pi], atan2(y, x); 0 at the centre pixel of an odd grid
};

// rho/theta images of the n x n pupil grid; n >= 1.
PolarCoordinates PupilCoordinates(Index n);

// Circular (optionally centrally obstructed) pupil amplitude on the n x n pupil grid: 1 inside, 0 outside,
// grey covered fractions on the edges when supersample > 1. Requires n >= 1, a valid geometry and
// 1 <= supersample <= 64. Throws InvalidArgument otherwise.
Image CircularPupil(Index n, const PupilGeometry& geometry, int supersample = 1);

// Validates a pupil amplitude grid and its diameter for `function`'s messages: square n x n with n >= 2,
// finite values >= 0, an open aperture (some value > 0), and a finite diameter > 0. Throws InvalidArgument.
void CheckPupilAmplitude(const Image& amplitude, double diameter_m, const std::string& function);

}  // namespace aosr
