// Figures of merit of a sampled PSF, as an AO scientist reports them.
//
//  * FWHM: the equivalent-area full width at half maximum, 2·sqrt(A/π), with A the area (in pixels) where
//    the PSF's bilinear interpolant is >= half its peak (8 x 8 sub-pixels per pixel). Equals the true FWHM
//    for a circular core; for cores only ~2 pixels wide the interpolation error is a few per cent.
//  * Elongation: the same half-maximum region's second moments. For an elliptical core, the region is an
//    ellipse of semi-axes a >= b whose moments along its axes are a^2/4 and b^2/4, so the major and minor
//    FWHM are 4 sqrt(eigenvalues) of the region's covariance, and the major axis' angle is that of the
//    leading eigenvector, from +x (columns) toward +y (rows), in (-90, 90] degrees. A round core gives a ratio
//    of 1 (to the sub-pixel grid's ~1%) and an arbitrary angle. Meant for a single core: a PSF with several
//    separate peaks above half maximum gets the moments of them all.
//  * Encircled energy EE(ρ): the PSF's sum inside a circle of radius ρ pixels around the peak pixel,
//    divided by the sum over the whole window (so it is relative to the light in the window).
//  * Centroid: first moment of the window, pixel coordinates (image.hpp conventions).
//  * Core centroid: the first moment inside a disk of radius ρ pixels centred on the centroid itself, found
//    by iteration from the peak pixel (10 passes, or until it moves < 1e-6 px): where the core lands,
//    insensitive to the halo and to the window's edges (an AO PSF's halo holds much of the light but not the
//    image's position). ρ = 2 λ/D is what ComputePresetPsf uses. Pixel coordinates; subtract
//    (rows/2, cols/2) for the offset from the optical axis.
#pragma once

#include <utility>
#include <vector>

#include "aosr/core/image.hpp"

namespace aosr {

struct PsfStats {
  double peak = 0;
  Index peak_y = 0, peak_x = 0;
  double centroid_y = 0, centroid_x = 0;
  double fwhm_px = 0;
  double fwhm_major_px = 0, fwhm_minor_px = 0;  // elongation (above)
  double major_axis_angle_rad = 0;               // from +x toward +y, in (-pi/2, pi/2]
  double window_sum = 0;
  // fwhm_major_px / fwhm_minor_px (>= 1).
  double Elongation() const { return fwhm_minor_px > 0 ? fwhm_major_px / fwhm_minor_px : 1.0; }
};

// Throws InvalidArgument for an empty, non-finite or non-positive-sum image.
PsfStats MeasurePsf(const Image& psf);

// The core centroid (y, x) in pixels (above). Throws InvalidArgument for a bad image (as MeasurePsf) or a
// radius below 0.5 px or non-finite.
std::pair<double, double> CoreCentroid(const Image& psf, double radius_px);

// EE(ρ) for each radius (pixels, >= 0), around the peak pixel.
std::vector<double> EncircledEnergy(const Image& psf, const std::vector<double>& radii_px);

}  // namespace aosr
