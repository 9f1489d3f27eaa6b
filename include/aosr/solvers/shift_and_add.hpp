// The astronomers' baselines that need no deconvolution.
//
// Shift-and-add (Elad & Hel-Or 2001): each frame is brought to the HR grid by the adjoint of the camera
// divided by r² (every HR pixel takes its LR pixel's flux per HR pixel), moved back by the frame's known
// pointing offset, and the frames are combined by mean or median per HR pixel. Averaged over a complete
// sub-pixel raster this equals x blurred by the PSF and a symmetric triangle of half-width r: no bias in
// position, but no deblurring either.
//
// Bicubic upsampling of a single frame (OpenCV INTER_CUBIC, Keys a = -0.75), whose half-pixel convention
// places LR pixel centres at HR coordinate rY + (r-1)/2, matching image.hpp; values are divided by r² so
// the result is flux per HR pixel.
#pragma once

#include <vector>

#include "aosr/core/forward_model.hpp"
#include "aosr/solvers/summary.hpp"

namespace aosr {

enum class Combine { kMean, kMedian };

// frames: N LR frames; offsets: their known pointing offsets; r: the SR factor.
Image ShiftAndAdd(const ImageStack& frames, const std::vector<FrameOffset>& offsets, int r, Combine combine,
                  SolverSummary* summary = nullptr);

// One LR frame to the HR grid by bicubic interpolation, in flux per HR pixel.
Image BicubicUpsample(const Image& frame, int r);

}  // namespace aosr
