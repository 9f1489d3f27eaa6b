// The built-in default scene of `aosr demo`: the first end-to-end slice of the mission.
//
// A USAF bar target with point sources is imaged by an 8 m telescope in K band through N sub-exposures.
// The DM adds a different tip/tilt to each (the classic sub-pixel raster, scene/raster.hpp), realised
// physically: the raster offset becomes Zernike Z2/Z3 coefficients (optics/zernike.hpp) and the PSF of
// each exposure is computed from the tilted pupil field by MFT at HR sampling (optics/psf.hpp). The
// camera integrates r x r HR pixels (core/forward_model.hpp), and white Gaussian noise of a stated
// fraction of the brightest pixel is added (scene/noise.hpp). No atmosphere: the AO residual enters with
// the optics/AO issue. Boundaries are periodic in this first slice, the same model the reconstructors
// invert; the padded, cropped rendering arrives with the scenes issue.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "aosr/core/forward_model.hpp"

namespace aosr {

struct DemoOptions {
  // Camera frame side in pixels (>= 16). The HR grid is r·lr_size.
  Index lr_size = 128;
  // Super-resolution factor r (1..8).
  int r = 2;
  // Sub-exposures N (1..64).
  int frames = 4;
  // Telescope diameter D [m] (> 0) and central obstruction ratio in [0, 1): an 8 m class telescope.
  double diameter_m = 8.0;
  double obstruction = 0.14;
  // Science wavelength [m] (> 0): K band, 2.2 µm.
  double wavelength_m = 2.2e-6;
  // Camera pixel in λ/D (> 0). 1.0 is twice coarser than Nyquist (0.5): the undersampling the mission
  // is about. The HR pixel is this divided by r.
  double camera_pixel_lambda_over_d = 1.0;
  // Pupil grid across D (>= 32) and PSF kernel side in HR pixels (>= 8, <= HR grid).
  Index pupil_px = 128;
  Index psf_px = 64;
  // Gaussian noise sigma as a fraction of the brightest noiseless pixel (>= 0): the paper's "1% of max".
  double noise_fraction = 0.01;
  std::uint64_t seed = 1;

  bool IsValid(std::string* why) const;
};

struct DemoScene {
  DemoOptions options;
  Image truth;                        // HR object, flux per HR pixel
  ImageStack frames;                  // N noisy camera frames
  ImageStack psfs;                    // N centred PSF kernels at HR sampling, unit sum
  std::vector<FrameOffset> offsets;   // the raster, HR pixels
  std::vector<double> tilt_coefficients_m;  // Z2, Z3 per frame, metres of OPD (interleaved: x0, y0, x1, ...)
  double hr_pixel_rad = 0.0;
  double noise_sigma = 0.0;
  std::shared_ptr<const MultiFrameModel> model;  // the forward model the frames were rendered with
};

// Builds the scene (throws InvalidArgument naming a bad option).
DemoScene MakeDemoScene(const DemoOptions& options);

}  // namespace aosr
