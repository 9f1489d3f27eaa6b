// Viewable images (PNG, TIFF) and reading any image file as a grayscale double array.
//
// API rules for this header (stated once):
//  * Row 0 of an Image is the *top* row of a PNG/TIFF/JPEG, the convention of image files (and of
//    matplotlib's imshow). FITS is the exception, see fits.hpp: DS9 shows row 0 at the bottom.
//  * Files are grayscale, one channel. Writes are atomic (AtomicWrite) and chosen by extension.
//  * Errors: InvalidArgument for bad options or an unknown extension; IoError naming the path and
//    OpenImageIO's (or cfitsio's) message for anything the file system or the library refuses.
//
// Display stretch. With lo, hi the low/high percentiles of the finite pixels (linear interpolation
// between order statistics: rank p/100 * (n-1) of the sorted values, as numpy's default):
//   t      = clip((v - lo) / (hi - lo), 0, 1)               linear
//   log    = log10(1 + 1000 t) / log10(1001)                 compresses highlights ~3 decades;
//                                                            0 -> 0, 1 -> 1, t = 0.5 -> 0.8999
//   asinh  = asinh(t / s) / asinh(1 / s), s = softening      linear below t ~ s, logarithmic above
//                                                            (Lupton et al. 1999); 0 -> 0, 1 -> 1
// NaN pixels map to 0 (black); +Inf to 1 and -Inf to 0 (they are excluded from the percentiles).
// When hi <= lo (a constant image, or all pixels non-finite) every pixel maps to 0.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "aosr/core/image.hpp"

namespace aosr {

enum class Stretch { kLinear, kLog, kAsinh };

struct ViewOptions {
  // Mapping from the clipped linear value t in [0, 1] to display value (formulas above).
  Stretch stretch = Stretch::kLinear;
  // Percentiles (in %) of the finite pixel values mapped to black and white. 0 and 100 are the
  // minimum and maximum (no clipping); e.g. 1 and 99.5 keep a few hot pixels from washing out the
  // display. Valid: 0 <= low < high <= 100.
  double low_percentile = 0.0;
  double high_percentile = 100.0;
  // Bits per sample in the file: 8 or 16 (PNG and TIFF, integer, rounded to nearest), or 32 (TIFF
  // only: IEEE float holding the stretched value in [0, 1] exactly, no quantisation).
  int bits = 8;
  // asinh softening s, in units of the (hi - lo) range: the linear-to-log transition point.
  // Valid: finite and > 0. 0.1 shows faint structure without saturating bright cores.
  double asinh_softening = 0.1;
  // PNG only: zlib's compression level, 0 (none) .. 9 (smallest); -1: OpenImageIO's default (6). Level 1 encodes
  // a 512² 8-bit image several times faster than 6 for a somewhat larger file (the live quick-look uses it).
  int png_compression = -1;

  // False (and the offending field in *why, if why is non-null) when a field is out of range.
  bool IsValid(std::string* why) const;
};

// Maps img to [0, 1] for display (formulas above). InvalidArgument if !options.IsValid().
Image ApplyStretch(const Image& img, const ViewOptions& options);

// Writes ApplyStretch(img, options) as a grayscale PNG (.png) or TIFF (.tif, .tiff), case-insensitive
// extension; InvalidArgument naming any other extension, or bits = 32 for PNG, or an empty image.
void WriteViewImage(const std::string& path, const Image& img, const ViewOptions& options = {});

// An 8-bit colour raster for figures (plots, annotated pictures): rows x cols pixels, row 0 at the top, each
// pixel three bytes R, G, B, row-major and interleaved: pixel (y, x) channel c is rgb[3 * (y * cols + x) + c].
struct RgbImage {
  Index rows = 0;
  Index cols = 0;
  std::vector<std::uint8_t> rgb;
};

// Writes an RgbImage as an 8-bit RGB PNG (.png) or TIFF (.tif, .tiff), atomically. InvalidArgument for another
// extension, an empty image or rgb.size() != 3 * rows * cols.
void WriteRgbImage(const std::string& path, const RgbImage& img);

// Reads any image file OpenImageIO can read as 8-bit RGB (grayscale is replicated to the three channels; an
// alpha channel and channels past the third are dropped). For checking figures; ReadImage is the science reader.
RgbImage ReadRgbImage(const std::string& path);

// Reads a FITS file (.fits/.fit/.fts or a file starting with "SIMPLE  =") with ReadFitsImage, and
// anything else OpenImageIO can read (PNG, TIFF, JPEG, PNM, ...) as grayscale double:
//  * integer samples become [0, 1] (OIIO's conversion to float: v / (2^bits - 1));
//  * several channels -> the mean of the colour channels; an alpha channel is ignored;
//  * only the first subimage and full-resolution level are read.
Image ReadImage(const std::string& path);

// Tiles images left to right, top to bottom, in `columns` columns (fewer if there are fewer tiles).
// Each cell has the size of the largest tile (max rows x max cols); a smaller tile sits centred in
// its cell (offset (cell - tile) / 2, rounded down). Cells are separated by gap_px pixels of
// gap_value (no outer border); padding and unused cells are also gap_value.
// Values are copied as they are: normalise each tile first (e.g. ApplyStretch) if the tiles have
// different ranges, or normalise them together if they must be compared (truth vs reconstruction).
// InvalidArgument for no tiles, an empty tile, columns < 1 or gap_px < 0.
Image Montage(const std::vector<Image>& tiles, int columns, int gap_px, double gap_value);

}  // namespace aosr
