// Photometric and astrometric errors of point sources in a reconstruction, for star-field scenes where PSNR
// says little: an astronomer asks whether each star's flux and position came back.
//
// For each of the `brightest` stars of the truth catalogue (HR-frame coordinates, electrons per frame):
//  * background b: the median of the estimate over the annulus r_in <= |p − p★| < r_out around the true
//    position (robust to neighbours);
//  * flux: the aperture sum Σ_{|p − p★| <= R} (v − b) over HR pixels whose centres lie within R. The same
//    aperture on the truth image gives the reference, so the error measures the reconstruction, not the
//    aperture's encircled energy: flux_error = (F_est − F_truth_aperture) / F_truth_aperture;
//  * position: the intensity-weighted centroid of max(v − b, 0) within R, iterated
//    `centroid_iterations` times with the aperture re-centred on the last centroid (starting at the true
//    position); the error is the centroid minus the truth image's centroid in the same aperture (so the
//    band-limited truth's own sub-pixel bias cancels), in HR pixels.
// Stars whose aperture or annulus leaves the image are skipped (counted in `skipped`).
//
// Errors: InvalidArgument naming the argument (shapes differ, non-finite images, bad radii).
#pragma once

#include <string>
#include <vector>

#include "aosr/core/image.hpp"
#include "aosr/scene/objects.hpp"

namespace aosr {

struct StarMetricsOptions {
  // Number of brightest stars measured, >= 1. Default 20.
  int brightest = 20;
  // Aperture radius R [HR px], > 0. Default 3: about 1.5 λ/D at the Nyquist-sampled HR grid of r = 2 with
  // λ/D camera pixels, the core of a reconstructed star.
  double aperture_px = 3.0;
  // Background annulus [HR px], aperture_px < inner < outer. Defaults 5 and 8.
  double annulus_inner_px = 5.0;
  double annulus_outer_px = 8.0;
  // Re-centring iterations of the centroid, >= 1. Default 3.
  int centroid_iterations = 3;
  bool IsValid(std::string* why) const;
};

struct StarMeasurement {
  PointSource truth;        // catalogue entry (HR px, electrons)
  double flux_truth = 0.0;  // aperture flux of the truth image
  double flux_estimate = 0.0;
  double flux_error = 0.0;  // relative, (estimate − truth) / truth
  double dy = 0.0;          // centroid error [HR px]
  double dx = 0.0;
};

struct StarMetrics {
  std::vector<StarMeasurement> stars;   // brightest first
  int skipped = 0;                      // too close to the edge
  double median_abs_flux_error = 0.0;   // median |flux_error|
  double rms_position_error_px = 0.0;   // sqrt(mean(dy² + dx²)) [HR px]
};

StarMetrics MeasureStars(const Image& truth, const Image& estimate, const std::vector<PointSource>& catalogue,
                         const StarMetricsOptions& options = {});

}  // namespace aosr
