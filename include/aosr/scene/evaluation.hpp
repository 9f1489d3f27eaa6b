// How close a reconstruction is to the truth, as `aosr evaluate` and the Python aosr.evaluate() report it: PSNR,
// SSIM and RMSE (core/metrics.hpp) over the image less a border, raw and after removing the global sub-pixel
// offset of the estimate against the truth (CompareImagesAligned: resolution judged apart from astrometry), the
// offset itself in HR px and, when the HR pixel scale is known, in mas; and for a star field the aperture
// photometry and centroid errors of the brightest stars (star_metrics.hpp) with a background annulus 2..5 HR px
// beyond the aperture.
//
// Across the field (EvaluationOptions::rings > 0): the same scores in concentric rings about a centre (the guide
// star, where the AO correction is best; default the image centre), each ring aligned on its own
// (CompareImagesInRings, core/metrics.hpp), and with a catalogue each ring's photometric bias: the median relative
// aperture-flux error of the brightest `stars` catalogue stars whose true position lies in the ring (the figure
// that matters for the linear output, whose promise is photometry that is the same everywhere).
#pragma once

#include <limits>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "aosr/core/image.hpp"
#include "aosr/core/metrics.hpp"
#include "aosr/scene/dataset.hpp"
#include "aosr/scene/objects.hpp"
#include "aosr/scene/star_metrics.hpp"

namespace aosr {

struct EvaluationOptions {
  int crop_px = 0;            // pixels ignored at each border, >= 0 and < half the smaller side
  double peak = 0.0;          // PSNR/SSIM dynamic range L, >= 0 (0: max − min of the cropped truth)
  int stars = 20;             // brightest stars measured, >= 1 (with a catalogue)
  double aperture_px = 3.0;   // star aperture radius [HR px], in [0.5, 1000]
  double hr_pixel_mas = 0.0;  // HR pixel pitch [mas], >= 0 and finite; 0: unknown (offset_mas stays 0)
  // Score estimate − s with s = SkyLevelDifference(truth, estimate, crop_px): for outputs that keep the frames'
  // sky (the linear method's target-PSF estimate), which a truth without sky would otherwise count as error.
  bool subtract_sky = false;
  // Rings across the field, >= 0; 0: none. See CompareImagesInRings for the geometry and the limits on K.
  int rings = 0;
  // The rings' centre [HR px, pixel-centre convention: pixel (y, x) covers [y−½, y+½)]; NaN: the image centre.
  double ring_centre_y = std::numeric_limits<double>::quiet_NaN();
  double ring_centre_x = std::numeric_limits<double>::quiet_NaN();
};

// The photometry of one ring: the brightest EvaluationOptions::stars catalogue stars whose true position lies in
// it (and in the crop), measured as MeasureStars does (aperture, local annulus background).
struct RingPhotometry {
  int stars = 0;                    // measured (stars whose aperture or annulus leaves the image are not)
  double flux_bias = 0.0;           // median of (F_est − F_truth)/F_truth; NaN when stars = 0
  double median_abs_flux_error = 0.0;  // median |(F_est − F_truth)/F_truth|; NaN when stars = 0
};

struct Evaluation {
  ImageMetrics metrics;          // raw: the estimate as it is
  ImageMetrics aligned;          // after moving the estimate back by `offset` (same crop and L)
  ImageOffset offset;            // of the estimate against the truth [HR px], as applied (core/metrics.hpp)
  ImageOffset measured_offset;   // what the correlation on the crop found [HR px]
  bool offset_applied = false;   // false: moving the estimate back would have lowered PSNR or SSIM (aligned = raw)
  bool offset_mas_known = false;  // options.hr_pixel_mas > 0
  double offset_mas[2] = {0, 0};  // (dy, dx) in mas when offset_mas_known, else 0
  double sky = 0.0;              // what subtract_sky removed (estimate's units); 0 without it
  bool measured_stars = false;  // a catalogue was given
  StarMetrics stars;
  bool measured_rings = false;  // options.rings > 0
  RingMetrics rings;            // the scores in each ring, innermost first
  std::vector<RingPhotometry> ring_stars;  // one per ring when a catalogue was given, else empty
};

// The HR pixel pitch [mas] for EvaluationOptions::hr_pixel_mas: a dataset's (camera pixel / r; 0 when the dataset
// does not know its pixel scale), or a FITS image's PIXSCALE keyword (what `aosr simulate` writes on truth.fits;
// 0 when absent, not a number or not > 0; IoError for an unreadable file).
double DatasetHrPixelMas(const Dataset& dataset);
double FitsPixelScaleMas(const std::string& path);

// The background level of `estimate` above `reference`: the difference of their medians over the image less
// `crop_px` at each border (a median, so that sources cover less than half the region without biasing it).
// InvalidArgument for a shape mismatch or a crop that leaves nothing.
double SkyLevelDifference(const Image& reference, const Image& estimate, int crop_px);

// Whether a reconstruction file's METHOD keyword names an output that keeps the sky (the linear method's),
// for `aosr evaluate --subtract-sky auto` and aosr.evaluate(subtract_sky=None). False without the keyword.
bool OutputKeepsSky(const std::string& fits_path);

// The crop a dataset's own trustworthy border gives (camera px × r, in HR px).
inline int DatasetCrop(Index trustworthy_border_px, int r) { return int(trustworthy_border_px * r); }

// InvalidArgument ("EvaluateReconstruction: invalid <what> ...") for a shape mismatch, a non-finite estimate, or an
// option out of range (rings < 0; for rings > 0 what CompareImagesInRings refuses: too many rings for the field, a
// centre off the image).
Evaluation EvaluateReconstruction(const Image& truth, const Image& estimate, const std::vector<PointSource>& stars,
                                  const EvaluationOptions& options);

// The rings of an evaluation as `aosr evaluate --json` and aosr.evaluate report them: {"count", "centre_hr_px" {x, y},
// "peak", "rings": [{inner_hr_px, outer_hr_px, pixels, area_hr_px2, ssim_positions, psnr_db, ssim, rmse, aligned
// {psnr_db, ssim, rmse}, offset_hr_px {dy, dx}, offset_measured_hr_px {dy, dx}, offset_applied, inner_arcsec and
// outer_arcsec when hr_pixel_mas > 0, stars {measured, flux_bias, median_abs_flux_error} with a catalogue (null
// figures for a ring without stars)}]}. Null when the evaluation has no rings.
nlohmann::json EvaluationRingsJson(const Evaluation& evaluation, double hr_pixel_mas);

}  // namespace aosr
