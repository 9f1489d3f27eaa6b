// Monochromatic point-spread functions from a pupil amplitude and optical path difference (OPD).
//
// Maths (DESIGN.md §1). On pupil.hpp's n x n grid spanning the diameter D [m],
//     E(u)       = A(u) exp(i 2 pi w(u) / lambda)      (A: amplitude, w: OPD [m], lambda [m]),
//     PSF(alpha) = s^2 |E^(alpha)|^2 / integral |A|^2 d^2u,
// with E^ the Fourier transform of mft.hpp (kernel exp(-2 pi i u.alpha), u in D, alpha in lambda/D) and s the
// pixel pitch in lambda/D (s = pixel_scale_rad D / lambda), evaluated by the MFT at the pixel centres of the
// requested grid. The optical axis is pixel (rows/2, cols/2), image.hpp's centred-kernel rule. A positive
// x-slope of w moves the PSF toward +x (larger column); see zernike.hpp for tip/tilt coefficients.
//
// Normalisation: the PSF is point-sampled intensity times the pixel solid angle, scaled so that the light
// falling on the whole focal plane is 1. Hence
//  * the sum over an unbounded grid of pitch <= lambda/D is 1 (the OTF vanishes beyond D/lambda, so the
//    lattice sum equals the integral); the sampled pupil's PSF is periodic with period n lambda/D, and the
//    sum over exactly one period is 1 to rounding;
//  * the sum over a finite window is the fraction of light inside it (< 1). It is NOT renormalised to 1 in
//    the window: the light scattered outside is physics (it is what Strehl and encircled energy measure).
//    A convolution kernel that must conserve flux in the window is made with NormaliseToUnitSum();
//  * the value at the optical axis of an unaberrated pupil is (sum A)^2 / (n^2 sum A^2) s^2 (for a binary
//    pupil: its area, ~pi/4 in D^2, times s^2), and it scales by the Strehl ratio under aberrations;
//  * the energy is that of the *sampled* field, sum A^2 / n^2 (exact discrete Parseval, right for amplitude
//    masks such as apodisers). A grey edge pixel from CircularPupil(supersample > 1) holds a covered fraction
//    A, which transmits A of the light in reality but A^2 in the sampled field: the difference is what the
//    sharp sub-pixel edge scatters beyond the band the grid represents (|alpha| > n/2 lambda/D). So with grey
//    edges the in-band PSF is larger by ~ (sum A - sum A^2) / sum A (0.25% for n = 256, ~0.5% for n = 128)
//    than the continuous aperture's; binary pupils do not have this offset (the Airy test measures both).
// The detector's pixel response is not included here: it is the decimation operator's job (DESIGN.md §1).
#pragma once

#include <string>

#include "aosr/core/image.hpp"
#include "aosr/optics/mft.hpp"

namespace aosr {

struct PsfSampling {
  // Wavelength lambda [m]; > 0 and finite. (OPDs are achromatic; the phase is 2 pi OPD / lambda.)
  double wavelength_m = 0.0;
  // Angular pitch of the output pixels [rad]; > 0 and finite. For the HR grid this is theta_pix / r.
  // lambda/(2D) is Nyquist; flux normalisation is exact on unbounded grids for pitch <= lambda/D.
  double pixel_scale_rad = 0.0;
  // Output size (rows x cols), both >= 1. The optical axis is pixel (rows/2, cols/2).
  Index rows = 0;
  Index cols = 0;

  // Output pitch in lambda/D for a telescope of diameter `diameter_m`: pixel_scale_rad * D / lambda.
  double PixelScaleLambdaOverD(double diameter_m) const {
    return pixel_scale_rad * diameter_m / wavelength_m;
  }

  // True when all fields are in range; otherwise false and `why` (if non-null) names the bad field.
  bool IsValid(std::string* why) const;
};

// A PSF generator for one pupil grid size, diameter and sampling: the MFT matrices are built once, so each
// PSF costs two complex matrix products (~50 ms on one core for a 256-pixel pupil onto 256 x 256 outputs)
// plus one complex exponential per pupil pixel. Immutable and thread-safe after construction.
class PsfCalculator {
 public:
  // pupil_n: the pupil grid size n (>= 1); diameter_m: D [m] spanned by the grid (> 0). Throws
  // InvalidArgument naming the bad argument or sampling field.
  PsfCalculator(Index pupil_n, double diameter_m, const PsfSampling& sampling);

  // The PSF of amplitude A and OPD w (both pupil_n x pupil_n; w in metres, read only where A > 0).
  // A must be finite, >= 0 and not all zero. Throws InvalidArgument otherwise.
  Image Compute(const Image& amplitude, const Image& opd_m) const;

  Index pupil_n() const { return pupil_n_; }
  double diameter_m() const { return diameter_m_; }
  const PsfSampling& sampling() const { return sampling_; }

 private:
  Index pupil_n_;
  double diameter_m_;
  PsfSampling sampling_;
  MatrixFourierTransform mft_;
};

// One-shot PsfCalculator(amplitude.rows(), diameter_m, sampling).Compute(amplitude, opd_m). The amplitude
// and OPD must be square, of the same shape, on pupil.hpp's grid spanning `diameter_m`.
Image PsfFromPupil(const Image& amplitude, const Image& opd_m, double diameter_m,
                   const PsfSampling& sampling);

// kernel / sum(kernel): a flux-conserving convolution kernel from a windowed PSF. Throws InvalidArgument if
// the image is empty, not finite or its sum is not > 0.
Image NormaliseToUnitSum(const Image& kernel);

// Strehl ratio from the pupil: the on-axis intensity relative to the same amplitude without aberration,
//     S = |sum A exp(i 2 pi w / lambda)|^2 / (sum A)^2 = |<A e^{i phi}>|^2 / <A>^2,
// exact for the sampled pupil (no PSF sampling involved). For small phase variance sigma^2 [rad^2] over the
// pupil, S ~ exp(-sigma^2) (extended Marechal approximation). Note that the PSF peak may move off-axis
// (tilt); this is the on-axis value. Shapes must match; A finite, >= 0, not all zero; wavelength_m > 0.
double StrehlFromPupil(const Image& amplitude, const Image& opd_m, double wavelength_m);

// Peak Strehl: max(psf) / max(reference_psf), for two PSFs with the same sampling and the absolute
// normalisation of PsfCalculator (not renormalised in their windows), the reference unaberrated. The sampled
// maximum underestimates a peak that falls between pixels: use fine sampling (<= lambda/(4D)) or
// StrehlFromPupil when the exact on-axis value is wanted. Throws InvalidArgument for empty or non-finite
// images or a reference whose maximum is not > 0.
double PeakStrehl(const Image& psf, const Image& reference_psf);

}  // namespace aosr
