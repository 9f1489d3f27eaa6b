// The isotropic object power-spectrum model shared by the Wiener prior fitted to the frames
// (frame_power_spectrum.hpp, solvers) and the fit to training images (design/power_spectrum_fit.hpp):
//
//     s(f) = a / (f0² + |f|²)^(β/2)  +  w,
//
// s(f) = E|X(f)|² / M² for an object on a periodic M_y x M_x HR grid (X its unnormalised DFT), so the mean of
// s over the grid is the expected variance per HR pixel; f in cycles per HR pixel. With w = 0 it is
// tikhonov.hpp's kPowerSpectrum prior S(f) = (1 + |f|²/f0²)^(−β/2) scaled by s(0) = a / f0^β: the Wiener λ
// for noise σ per LR pixel is σ² / s(0) = σ² f0^β / a (tikhonov.hpp, "Bayesian reading").
#pragma once

#include <string>

#include "aosr/core/image.hpp"

namespace aosr {

// s(f) = a / (f0² + |f|²)^(β/2) + w.
struct PowerSpectrumModel {
  double amplitude = 1.0;  // a > 0, in (flux per HR pixel)² · (cycles per HR pixel)^β
  double corner = 0.05;    // f0 > 0, cycles per HR pixel
  double slope = 2.0;      // β, finite, in [−2, 12] (natural images: 2..3)
  double floor = 0.0;      // w >= 0, (flux per HR pixel)²

  // s at spatial frequency magnitude f (cycles per HR pixel).
  double operator()(double f) const;
  bool IsValid(std::string* why) const;
};

// The model on the full M_y x M_x HR DFT grid (unshifted, bin (0,0) = zero frequency, |f|² =
// (SignedFrequency(ky)/M_y)² + (SignedFrequency(kx)/M_x)²): finite, > 0 and symmetric, as
// TikhonovOptions::object_power_spectrum and DesignObjectiveOptions::object_power_spectrum want. Both sides >= 1.
Image PowerSpectrumGrid(const PowerSpectrumModel& model, Shape grid);

// A periodogram of Hann-windowed data estimates the spectrum circularly convolved with the window's |Ŵ|², which
// on the DFT grid is [1/6, 2/3, 1/6] per axis: this applies that kernel (periodic) to a spectrum on the grid, so
// a model can be compared with such a periodogram. Shared by both fits above.
Image HannWindowSmooth(const Image& spectrum);

}  // namespace aosr
