// The classic sub-pixel tip/tilt dither raster (the astronomers' baseline phase design).
//
// N frames are placed on a regular lattice that tiles one camera pixel (r HR pixels): N = q_y·q_x with
// q_y <= q_x the most nearly square factorisation, steps r/q_y and r/q_x HR pixels, and the pattern centred
// on zero mean so the average pointing is unchanged. N = r² gives every HR phase once (the "half-pixel"
// raster at r = 2: offsets ±0.5 HR px = ±¼ camera pixel about the centre, i.e. half-pixel steps). N = 2 is
// the exception to the lattice rule: the diagonal pair (0,0), (r/2, r/2) - then centred - which samples
// both axes, as the classic two-point dither does.
#pragma once

#include <vector>

#include "aosr/core/forward_model.hpp"

namespace aosr {

// Throws InvalidArgument for n < 1 or r < 1.
std::vector<FrameOffset> ClassicRaster(int n, int r);

}  // namespace aosr
