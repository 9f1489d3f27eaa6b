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
#include <vector>

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

// ---------------------------------------------------------------------------------------------------------
// Band-integrated (polychromatic) PSFs.
//
// Maths. A source observed through a band with relative photon weights w_k at wavelengths lambda_k (weights
// normalised here to sum 1) forms the incoherent sum of monochromatic PSFs on the same angular pixels:
//     PSF_band(theta) = sum_k w_k PSF_{lambda_k}(theta),
// each PSF_{lambda_k} normalised to unit total light as above, so the band PSF is too. The OPD w is
// achromatic (DESIGN.md §1): the phase 2 pi w / lambda_k shrinks with wavelength while the pattern grows as
// lambda_k / D. In each wavelength's own lambda_k/D units the fixed angular pitch theta_pix is s_k =
// theta_pix D / lambda_k, and the MFT evaluates every wavelength exactly at those angles (one MFT plan per
// wavelength; no rescaling or interpolation). Sampling needs the shortest wavelength's Nyquist pitch,
// theta_pix <= lambda_min / (2 D), for the band PSF to be band-limited on the grid.
//
// Physics: a feature at radius r lambda/D of the central wavelength moves to r lambda_k / lambda_c, so a band
// of fractional width dlambda/lambda smears rings radially by ~ r dlambda/lambda: the Airy zeros fill in (the
// first one, 1.22 lambda/D, clearly so for dlambda/lambda >~ 10%) and the speckle of an AO halo stretches
// radially. Measured depth of the first dark ring relative to the peak (clear disk): 7e-5 monochromatic (the
// finite annuli of the profile), 2.2e-3 for a flat 20% band, 7.3e-3 for 40%, as the first-order estimate
// (0.2104 x0 b / 2)^2 / 3 predicts (tests/optics/psf_band_physics_test.cpp).
//
// Strehl per wavelength comes from the pupil (StrehlFromPupil), and the band Strehl is the on-axis ratio of
// the band PSF to the unaberrated band PSF; since the unaberrated on-axis value scales as (D / lambda_k)^2,
//     S_band = sum_k (w_k / lambda_k^2) S_k / sum_k (w_k / lambda_k^2).
struct SpectralBand {
  // Wavelengths lambda_k [m], at least one; each > 0 and finite. Order does not matter.
  std::vector<double> wavelengths_m;
  // Relative photon weights w_k (source spectrum x transmission x quantum efficiency, in detected photons per
  // sample), one per wavelength; each >= 0 and finite, sum > 0. Normalised to sum 1 internally.
  std::vector<double> weights;

  // True when all fields are in range; otherwise false and `why` (if non-null) names the bad field.
  bool IsValid(std::string* why) const;
};

// A flat band: `samples` wavelengths at the centres of equal sub-intervals of [centre - width/2,
// centre + width/2], equal weights (a top-hat filter on a flat photon spectrum). samples >= 1; centre_m > 0;
// 0 <= width_m < 2 centre_m. Throws InvalidArgument naming the bad argument.
SpectralBand UniformBand(double centre_m, double width_m, int samples);

struct BandPsf {
  Image psf;                   // sum_k w_k PSF_k on the requested grid (weights normalised to sum 1)
  std::vector<double> strehl;  // S_k = StrehlFromPupil at each wavelength, in the band's order
  double band_strehl = 0.0;    // on-axis band Strehl (formula above)
};

// Band PSFs for one pupil grid, diameter, band and angular sampling: one PsfCalculator (MFT plan) per
// wavelength, built once. Immutable and thread-safe after construction.
class BandPsfCalculator {
 public:
  // pupil_n >= 1, diameter_m > 0, a valid band, pixel_scale_rad > 0 [rad], rows, cols >= 1 (optical axis at
  // (rows/2, cols/2)). Throws InvalidArgument naming the bad argument or band field.
  BandPsfCalculator(Index pupil_n, double diameter_m, const SpectralBand& band, double pixel_scale_rad,
                    Index rows, Index cols);

  // The band PSF and Strehl ratios of amplitude A and achromatic OPD w [m] (both pupil_n x pupil_n), with
  // PsfCalculator::Compute's requirements. With a single wavelength the PSF is exactly PsfCalculator's.
  BandPsf Compute(const Image& amplitude, const Image& opd_m) const;

  const SpectralBand& band() const { return band_; }
  // Weights normalised to sum 1, in the band's order.
  const std::vector<double>& normalised_weights() const { return weights_; }

 private:
  SpectralBand band_;
  std::vector<double> weights_;
  std::vector<PsfCalculator> calculators_;
};

// Peak Strehl: max(psf) / max(reference_psf), for two PSFs with the same sampling and the absolute
// normalisation of PsfCalculator (not renormalised in their windows), the reference unaberrated. The sampled
// maximum underestimates a peak that falls between pixels: use fine sampling (<= lambda/(4D)) or
// StrehlFromPupil when the exact on-axis value is wanted. Throws InvalidArgument for empty or non-finite
// images or a reference whose maximum is not > 0.
double PeakStrehl(const Image& psf, const Image& reference_psf);

}  // namespace aosr
