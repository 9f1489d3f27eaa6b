// Objects from image files: any PNG/TIFF/FITS (io/image_io.hpp's ReadImage) placed on the HR grid by exact,
// flux-conserving area-weighted resampling, with optional background subtraction and flux normalisation.
//
// ## Area-weighted resampling
//
// A file pixel is taken to be a uniform square: source pixel (i, j) covers [i, i+1) x [j, j+1) in source
// edge coordinates. The source window W (the whole file, or a centred crop of it with the HR grid's aspect
// ratio, see ImageFit) is divided into the H x W' HR pixels, each covering a rectangle of size
// (h_W / H) x (w_W / W') source pixels. Then, exactly,
//
//     flux per pixel:      out(Y, X) = Σ_{i,j} a_Y(i) b_X(j) src(i, j),
//     surface brightness:  out(Y, X) = Σ_{i,j} a_Y(i) b_X(j) src(i, j) / (h_W/H · w_W/W'),
//
// where a_Y(i) is the length of the overlap of HR row Y's interval with source row i (b_X likewise for
// columns). The weights are separable, so out = A · src · Bᵀ with sparse A (H x h) and B (W' x w): O((h + H)
// w + H (w + W')) operations. Each fully windowed source pixel distributes exactly its whole area (Σ_Y a_Y(i)
// = 1), so in the flux-per-pixel reading Σ out = Σ src (to rounding) and in the surface-brightness reading a
// constant image stays the same constant. The two readings differ only by the constant factor (h_W w_W) / (H
// W'), which any flux normalisation removes.
//
// Upsampling (a file coarser than the HR grid) gives the piecewise-constant image of the uniform squares: it
// invents no detail and conserves flux exactly; smoother interpolants (bicubic) overshoot at edges and break
// positivity and flux conservation, and the PSF convolution smooths the squares anyway. Not provided.
//
// ## Pipeline of LoadImageObject / MakeImageObject
//
//   1. background: subtract an estimate computed on the source (ImageBackground);
//   2. resample onto the HR grid (ImageFit, PixelValues);
//   3. clip negative values to 0 if clip_negative (fluxes are non-negative; noise left after 1. is not);
//   4. normalise (FluxNormalisation): keep, scale to a total flux, or scale to a peak value.
//
// Row 0 of the result is the top row of a PNG/TIFF and the first row of a FITS array (image_io.hpp's rules).
//
// Errors: aosr::InvalidArgument naming the function and the argument or options field (a file with non-finite
// pixels, or with no positive flux to normalise, is an InvalidArgument naming the path); aosr::IoError naming
// the path for a file that cannot be read.
#pragma once

#include <string>

#include "aosr/core/image.hpp"

namespace aosr {

// How the source is fitted to a grid of a different aspect ratio.
enum class ImageFit {
  kCrop,  // the largest centred window of the source with the grid's aspect ratio (square pixels preserved;
          // its edges may cut source pixels, which then contribute their covered fraction)
  kStretch,  // the whole source, stretched independently along y and x
};

// What a source pixel value means (see the resampling formulas above).
enum class PixelValues {
  kSurfaceBrightness,  // per unit area: resampling averages (a constant stays constant)
  kFluxPerPixel,       // per pixel: resampling sums the covered fractions (Σ out = Σ src)
};

// Background estimate subtracted from the source before resampling.
enum class ImageBackground {
  kNone,
  kMedian,        // median of all pixels: right for sparse objects on a sky (stars, galaxies)
  kBorderMedian,  // median of the border ring, max(1, min(h, w) / 20) pixels wide: a sky estimate that
                  // ignores a central object covering most of the frame
  kMinimum,       // the minimum pixel: makes the darkest pixel 0 (for photographs)
};

enum class FluxNormalisation {
  kKeep,       // values as resampled
  kTotalFlux,  // scaled so that the image sums to total_flux
  kPeak,       // scaled so that the maximum pixel is peak_value
};

struct ImageObjectOptions {
  // Default kCrop: a square-pixel image keeps its geometry on any grid.
  ImageFit fit = ImageFit::kCrop;
  // Default kSurfaceBrightness: a PNG/TIFF photograph holds brightness in [0, 1], which then stays in [0, 1]
  // under kKeep. Use kFluxPerPixel for FITS count maps whose sum must be kept.
  PixelValues values = PixelValues::kSurfaceBrightness;
  // Default kNone: test images usually have a meaningful zero.
  ImageBackground background = ImageBackground::kNone;
  // Set negative values to 0 after resampling. Default true: an object is a non-negative flux.
  bool clip_negative = true;
  // Default kKeep.
  FluxNormalisation normalisation = FluxNormalisation::kKeep;
  // Target sum for kTotalFlux (image flux units), finite and > 0. Default 1.
  double total_flux = 1.0;
  // Target maximum for kPeak (flux per HR pixel), finite and > 0. Default 1.
  double peak_value = 1.0;

  // True if every field is in range; otherwise false and, if why != nullptr, *why names the field.
  bool IsValid(std::string* why) const;
};

// Area-weighted resampling of `source` (non-empty, finite) onto a grid of shape `out` (both sides >= 1), as
// above. With values = kFluxPerPixel and a window covering the whole source (kStretch, or kCrop with equal
// aspect ratios), the sum is conserved to rounding.
Image ResampleArea(const Image& source, Shape out, ImageFit fit = ImageFit::kCrop,
                   PixelValues values = PixelValues::kSurfaceBrightness);

// The pipeline above on an in-memory image (non-empty, finite) onto the HR grid `hr` (both sides >= 1).
Image MakeImageObject(const Image& source, Shape hr, const ImageObjectOptions& options = {});

// ReadImage(path) followed by MakeImageObject; every error message names the path.
Image LoadImageObject(const std::string& path, Shape hr, const ImageObjectOptions& options = {});

}  // namespace aosr
