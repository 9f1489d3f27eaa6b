// How close a reconstruction is to the truth, as `aosr evaluate` and the Python aosr.evaluate() report it: PSNR,
// SSIM and RMSE (core/metrics.hpp) over the image less a border, and for a star field the aperture photometry and
// centroid errors of the brightest stars (star_metrics.hpp) with a background annulus 2..5 HR px beyond the
// aperture.
#pragma once

#include <vector>

#include "aosr/core/image.hpp"
#include "aosr/core/metrics.hpp"
#include "aosr/scene/objects.hpp"
#include "aosr/scene/star_metrics.hpp"

namespace aosr {

struct EvaluationOptions {
  int crop_px = 0;            // pixels ignored at each border, >= 0 and < half the smaller side
  double peak = 0.0;          // PSNR/SSIM dynamic range L, >= 0 (0: max − min of the cropped truth)
  int stars = 20;             // brightest stars measured, >= 1 (with a catalogue)
  double aperture_px = 3.0;   // star aperture radius [HR px], in [0.5, 1000]
};

struct Evaluation {
  ImageMetrics metrics;
  bool measured_stars = false;  // a catalogue was given
  StarMetrics stars;
};

// The crop a dataset's own trustworthy border gives (camera px × r, in HR px).
inline int DatasetCrop(Index trustworthy_border_px, int r) { return int(trustworthy_border_px * r); }

// InvalidArgument ("EvaluateReconstruction: invalid <what> ...") for a shape mismatch, a non-finite estimate, or an
// option out of range.
Evaluation EvaluateReconstruction(const Image& truth, const Image& estimate, const std::vector<PointSource>& stars,
                                  const EvaluationOptions& options);

}  // namespace aosr
