// Anisoplanatism of a single-conjugate AO system: the isoplanatic angle, the effective turbulence altitude and
// the tip/tilt content of a residual phase spectrum (the differential tilt that elongates an off-axis PSF).
//
// Geometry (atmosphere.hpp, "Field directions"): a direction theta from the guide star sees layer l (altitude
// h_l, fraction w_l of the integrated Cn^2) displaced by h_l theta, so the phase difference between the two
// directions has the PSD Phi(f) sum_l w_l 2 (1 - cos 2 pi f.(h_l theta)) (analytic_ao.hpp, section 2, gives
// the part of it inside the DM's control region, with and without the servo-lag cross term).
//
// Isoplanatic angle (D. L. Fried, "Anisoplanatism in adaptive optics", JOSA 72, 52 (1982)): integrating that
// PSD over the whole plane for Kolmogorov turbulence gives the phase variance (theta/theta0)^(5/3) with
//     theta0 = [2.914 k^2 (sec zeta)^(8/3) integral Cn^2(h) h^(5/3) dh]^(-3/5),
// and with r0 = [0.423 k^2 sec zeta integral Cn^2 dh]^(-3/5) (both at the science wavelength, k = 2 pi/lambda)
//     theta0 = 6.8839^(-3/5) r0 / (h_bar sec zeta) = 0.3143 r0 / (h_bar sec zeta),
//     h_bar  = (sum_l w_l h_l^(5/3))^(3/5)                        (the effective turbulence altitude),
// where 6.8839 = 2 [24/5 Gamma(6/5)]^(5/6) is the constant of the phase structure function 6.88 (r/r0)^(5/3)
// (so that, for one layer, D(h theta) = (theta/theta0)^(5/3) exactly; 2.914/0.423 = 6.889 is the same number
// rounded). theta0 scales with r0, i.e. as lambda^(6/5).
//
// Tilt (Noll 1976; von_karman.hpp): the Zernike tilt coefficient a (rad RMS of phase, Noll's orthonormal
// 2 rho cos(phi - psi)) of a phase with PSD P has the variance int P(f) |Q(f)|^2 d^2f,
//     |Q(f)|^2 = 2 [2 J_2(pi D f) / (pi D f)]^2 2 cos^2(phi_f - psi),
// and moves the image by 2 a lambda / (pi D) [rad] along psi (phase 4 a x / D, OPD slope a lambda / (pi D/2)).
// A random differential tilt of variances s_par^2 (along theta) and s_perp^2 convolves the long-exposure PSF
// with that elliptical Gaussian: for a core close to a Gaussian of FWHM F, FWHM_par^2 ~ F^2 + 8 ln 2 s_par^2.
//
// Errors: arguments are validated and violations throw aosr::InvalidArgument naming the function and argument.
#pragma once

#include <vector>

#include "aosr/ao/atmosphere.hpp"
#include "aosr/core/image.hpp"

namespace aosr {

// h_bar = (sum_l w_l h_l^(5/3))^(3/5) [m] over layers whose fractions sum to 1 (within 1e-6), altitudes >= 0
// and finite. 0 for turbulence all at the ground.
double EffectiveTurbulenceAltitudeM(const std::vector<Layer>& layers);

// Fried's isoplanatic angle [rad] at `wavelength_m` for r0_m given at r0_wavelength_m (at the zenith) and the
// layers' profile, observed at zenith angle zenith_rad in [0, pi/2): 0.3143 r0(lambda) cos(zeta)^(3/5) /
// (h_bar sec zeta). +infinity when all the turbulence is at the ground.
double IsoplanaticAngleRad(double r0_m, double r0_wavelength_m, double wavelength_m,
                           const std::vector<Layer>& layers, double zenith_rad = 0.0);

// The full-band anisoplanatic phase variance (theta/theta0)^(5/3) [rad^2] (Kolmogorov, Fried 1982) for an
// angle theta_rad >= 0 and theta0_rad > 0 (+inf gives 0).
double FriedAnisoplanaticVarianceRad2(double theta_rad, double theta0_rad);

// Zernike tilt coefficient variances [rad^2 of phase] of a phase PSD [rad^2 m^2] on analytic_ao.hpp's centred
// P x P grid of pitch df [cycles/m] (ResidualPsd's layout), for a pupil of diameter D: along the axis at
// angle psi (from +x toward +y) and perpendicular to it.
struct TiltVariance {
  double parallel_rad2 = 0.0;
  double perpendicular_rad2 = 0.0;
};
TiltVariance ZernikeTiltVariance(const Image& psd, double df_per_m, double diameter_m, double axis_angle_rad);

// Image motion [rad] of a Zernike tilt coefficient [rad of phase] at `wavelength_m`: 2 a lambda / (pi D).
double TiltCoefficientToAngleRad(double coefficient_rad, double wavelength_m, double diameter_m);

}  // namespace aosr
