// Resolving power read from the 1951 USAF target (objects.hpp): for each group and element of an image of the
// target (a truth, a frame upsampled to the HR grid, a reconstruction), the Michelson contrast of its three bars
// along both orientations, and the finest element resolved at a stated threshold.
//
// Contrast of a triplet. For the vertical bars (long along y, resolving detail along x) the image is averaged
// over the rows whose centres lie in the middle three fifths of the bars' length (the nearest row when none
// does), giving a profile P(x) at integer columns; P is interpolated (Keys' cubic, a = −1/2: linear
// interpolation flattens a blurred bar's rounded peak and reads ~0.1 low) at the three bar centres and the two
// gap centres (continuous pixel coordinates, image.hpp), and
//     C = (I_max − I_min) / (I_max + I_min),   I_max = mean of the three bar values, I_min = mean of the two gaps.
// The horizontal bars likewise with rows and columns exchanged. An element's contrast is the smaller of the two
// orientations'. C depends on the background: the target rendered at its own sampling (UsafTarget, background b,
// bars v) reads about (v − b)/(v + b) where its bars are wide; `transfer` is C divided by the contrast measured
// the same way on that rendered target, the modulation the imaging kept (1 for the truth itself).
//
// Resolved: C >= threshold in both orientations. The default threshold 0.153 is the Rayleigh criterion's: two
// peaks with a dip to 73.5 % between them. The finest resolved element is the last one, in order of increasing
// frequency, before the first element that is not resolved (an element past the limit can read a spurious
// contrast by aliasing, so later ones do not count). Frequencies: cycles per HR pixel 1/(2w) for a bar width of
// w HR pixels; per camera pixel r/(2w) when r is given; per λ/D, (λ/D in HR px)/(2w), when the HR pixel's size
// in λ/D is given.
//
// Elements whose bars leave the image, or whose bars are narrower than half a pixel (not representable), are
// listed with measured = false and skipped. Errors: InvalidArgument for an empty or non-finite image, invalid
// target options or invalid options.
#pragma once

#include <string>
#include <vector>

#include "aosr/core/image.hpp"
#include "aosr/scene/objects.hpp"
#include "aosr/scene/scene_spec.hpp"

namespace aosr {

struct UsafContrastOptions {
  // Michelson contrast at which an element counts as resolved, in (0, 1). Default 0.153 (Rayleigh, top of file).
  double threshold = 0.153;
  // Super-resolution factor of the HR image, 0 (not given) or in [1, 64]: frequencies also per camera pixel.
  int r = 0;
  // The HR pixel's size in λ/D, 0 (not given) or > 0: frequencies also in cycles per λ/D.
  double hr_pixel_lambda_over_d = 0.0;

  bool IsValid(std::string* why) const;
};

struct UsafElementContrast {
  int group = 0;
  int element = 0;
  double bar_width_px = 0.0;             // HR px
  double cycles_per_px = 0.0;            // 1/(2w), cycles per HR pixel
  double cycles_per_camera_px = 0.0;     // r/(2w); 0 when r is not given
  double cycles_per_lambda_over_d = 0.0;  // 0 when the pixel scale is not given
  bool measured = false;                 // inside the image and representable
  double contrast_x = 0.0;               // Michelson contrast of the vertical bars (detail along x)
  double contrast_y = 0.0;               // of the horizontal bars (detail along y)
  double contrast = 0.0;                 // min(contrast_x, contrast_y)
  double transfer = 0.0;                 // contrast / the rendered target's (top of file)
  bool resolved = false;                 // measured and contrast >= threshold
};

struct UsafResolvingPower {
  double threshold = 0.0;
  std::vector<UsafElementContrast> elements;  // by increasing frequency (group, then element)
  int finest = -1;  // index into elements of the finest resolved element (top of file); -1: none resolved
};

// The contrast table of `image`, an image of the target rendered with `target` on a grid of the image's shape
// (the placement of UsafBars(ShapeOf(image), target)).
UsafResolvingPower MeasureUsafResolvingPower(const Image& image, const UsafOptions& target,
                                             const UsafContrastOptions& options = {});

// The same for an HR image of a scene (a truth, a reconstruction): the target is the scene's first usaf or demo
// object as the scene renders it on its HR frame, r and the HR pixel's λ/D are the scene's. InvalidArgument when
// the scene has no such object or the image is not of the HR frame's shape.
UsafResolvingPower MeasureSceneUsafResolvingPower(const Image& hr_image, const SceneSpec& scene, double threshold = 0.153);

}  // namespace aosr
