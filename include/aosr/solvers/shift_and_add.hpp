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
#include "aosr/solvers/problem.hpp"
#include "aosr/solvers/summary.hpp"

namespace aosr {

enum class Combine { kMean, kMedian };

// frames: N LR frames; offsets: their known pointing offsets; r: the SR factor.
Image ShiftAndAdd(const ImageStack& frames, const std::vector<FrameOffset>& offsets, int r, Combine combine,
                  SolverSummary* summary = nullptr);

// One LR frame to the HR grid by bicubic interpolation, in flux per HR pixel.
// The same for a ReconstructionProblem (its offsets are required): pixels of weight 0 are left out. Weights
// act as a mask only (the astronomers' shift-and-add is an unweighted combination). Mean: normalised
// convolution, Σ_i S_i(m_i·u_i) / Σ_i S_i(m_i) with u_i the upsampled frame, m_i its upsampled mask and S_i
// the registration shift (exact for whole HR-pixel shifts, Fourier-interpolated otherwise). Median: over the
// frames whose shifted mask exceeds ½ at the pixel. HR pixels no valid frame reaches are 0; the summary
// message counts them.
Image ShiftAndAdd(const ReconstructionProblem& problem, Combine combine, SolverSummary* summary = nullptr);

Image BicubicUpsample(const Image& frame, int r);

}  // namespace aosr
