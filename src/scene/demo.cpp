#include "aosr/scene/demo.hpp"

#include <cmath>

#include "aosr/core/error.hpp"
#include "aosr/optics/psf.hpp"
#include "aosr/optics/pupil.hpp"
#include "aosr/optics/zernike.hpp"
#include "aosr/scene/noise.hpp"
#include "aosr/scene/objects.hpp"
#include "aosr/scene/raster.hpp"

namespace aosr {

bool DemoOptions::IsValid(std::string* why) const {
  auto fail = [why](const std::string& m) {
    if (why) *why = m;
    return false;
  };
  if (lr_size < 16) return fail("lr_size must be >= 16, got " + std::to_string(lr_size));
  if (r < 1 || r > 8) return fail("r must be in 1..8, got " + std::to_string(r));
  if (frames < 1 || frames > 64) return fail("frames must be in 1..64, got " + std::to_string(frames));
  if (!(diameter_m > 0 && std::isfinite(diameter_m))) return fail("diameter_m must be > 0");
  if (!(obstruction >= 0 && obstruction < 1)) return fail("obstruction must be in [0, 1)");
  if (!(wavelength_m > 0 && std::isfinite(wavelength_m))) return fail("wavelength_m must be > 0");
  if (!(camera_pixel_lambda_over_d > 0 && std::isfinite(camera_pixel_lambda_over_d)))
    return fail("camera_pixel_lambda_over_d must be > 0");
  if (pupil_px < 32) return fail("pupil_px must be >= 32, got " + std::to_string(pupil_px));
  if (psf_px < 8 || psf_px > lr_size * r)
    return fail("psf_px must be in 8..r*lr_size = " + std::to_string(lr_size * r) + ", got " + std::to_string(psf_px));
  if (!(noise_fraction >= 0 && std::isfinite(noise_fraction))) return fail("noise_fraction must be >= 0");
  return true;
}

DemoScene MakeDemoScene(const DemoOptions& options) {
  std::string why;
  if (!options.IsValid(&why)) throw InvalidArgument("MakeDemoScene: " + why);
  DemoScene s;
  s.options = options;
  const Index n_hr = options.lr_size * options.r;
  const Shape hr{n_hr, n_hr};
  s.truth = DemoObject(hr);
  s.hr_pixel_rad = options.camera_pixel_lambda_over_d / options.r * options.wavelength_m / options.diameter_m;
  s.offsets = ClassicRaster(options.frames, options.r);

  PupilGeometry geometry;
  geometry.diameter_m = options.diameter_m;
  geometry.obstruction = options.obstruction;
  const Image pupil = CircularPupil(options.pupil_px, geometry);
  const Image z2 = Zernike(2, options.pupil_px, options.obstruction);
  const Image z3 = Zernike(3, options.pupil_px, options.obstruction);
  PsfSampling sampling;
  sampling.wavelength_m = options.wavelength_m;
  sampling.pixel_scale_rad = s.hr_pixel_rad;
  sampling.rows = sampling.cols = options.psf_px;
  const PsfCalculator psf(options.pupil_px, options.diameter_m, sampling);
  for (const FrameOffset& o : s.offsets) {
    // The DM's tip/tilt that moves the image by the raster offset (zernike.hpp: a = shift·D/4).
    const double ax = TiltCoefficientForShift(o.dx * s.hr_pixel_rad, options.diameter_m);
    const double ay = TiltCoefficientForShift(o.dy * s.hr_pixel_rad, options.diameter_m);
    s.tilt_coefficients_m.push_back(ax);
    s.tilt_coefficients_m.push_back(ay);
    s.psfs.push_back(NormaliseToUnitSum(psf.Compute(pupil, ax * z2 + ay * z3)));
  }
  s.model = std::make_shared<const MultiFrameModel>(MultiFrameModel::FromKernels(hr, options.r, s.psfs));
  s.frames = s.model->Render(s.truth);
  s.noise_sigma = NoiseSigmaFromPeakFraction(s.frames, options.noise_fraction);
  AddGaussianNoise(&s.frames, s.noise_sigma, options.seed);
  return s;
}

}  // namespace aosr
