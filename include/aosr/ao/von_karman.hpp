// Statistics of atmospheric phase: the von Kármán / Kolmogorov spectrum, its covariance and structure
// function, the lambda^(6/5) scaling of r0, and the Zernike-mode variances (Noll 1976) with their outer-scale
// correction.
//
// Units and conventions (for every function here):
//  * Lengths in metres, spatial frequencies f in cycles per metre, phases in radians *at the wavelength at
//    which r0 is given* (r0 ~ lambda^(6/5), phase ~ 1/lambda, so the optical path difference OPD = phase *
//    lambda / (2 pi) is achromatic: convert to OPD at that wavelength, never mix r0 and lambda).
//  * L0 (outer scale) may be +infinity, which gives the Kolmogorov limit wherever that limit is finite
//    (the Kolmogorov phase variance, covariance and piston variance are infinite).
//  * Arguments are validated: r0 > 0 and finite, L0 > 0 (finite or +inf), D > 0 and finite, r and f >= 0
//    and finite; violations throw aosr::InvalidArgument naming the function and argument.
//
// Power spectrum (Roddier 1981, Prog. Opt. 19, 281, eq. 3.14 with the Kolmogorov index; von Kármán form
// e.g. Conan 2000, Sasiela 1994):
//     Phi(f) = c_Phi r0^(-5/3) (f^2 + 1/L0^2)^(-11/6)                     [rad^2 m^2],
//     c_Phi = Gamma(11/6)^2 / (2 pi^(11/3)) * [24/5 Gamma(6/5)]^(5/6) = 0.0228955...  ("0.023"),
// normalised so that the phase variance is integral Phi d^2f. The constant is written exactly (not 0.023)
// so that the L0 -> infinity limit of the structure function is exactly Fried's 6.8839 (r/r0)^(5/3).
//
// Covariance and structure function. Phi is isotropic, so B(r) = 2 pi int_0^inf Phi(f) J0(2 pi f r) f df, and
// with int_0^inf J0(b f) f (f^2 + a^2)^(-(nu+1)) df = (b/a)^nu K_nu(a b) / (2^nu Gamma(nu+1))
// (Gradshteyn & Ryzhik 6.565.4), nu = 5/6, a = 1/L0, b = 2 pi r, x = 2 pi r / L0:
//     B(r) = sigma^2 x^(5/6) K_{5/6}(x) / (2^(-1/6) Gamma(5/6)),      B(0) = sigma^2,
//     sigma^2 = (6/5) pi c_Phi (L0/r0)^(5/3) = 0.0863 (L0/r0)^(5/3)    [rad^2, phase variance],
//     D(r) = 2 (B(0) - B(r))
//          = 0.17253 (L0/r0)^(5/3) [1 - (2 pi^(5/6) / Gamma(5/6)) (r/L0)^(5/6) K_{5/6}(2 pi r / L0)]
// (2^(1/6) x^(5/6) = 2 pi^(5/6) (r/L0)^(5/6), so the two forms agree). Kolmogorov limit: from the series
// x^nu K_nu(x) = 2^(nu-1) Gamma(nu) [1 - Gamma(1-nu)/Gamma(1+nu) (x/2)^(2 nu) + O(x^2)],
//     D(r) -> 0.17253 Gamma(1/6)/Gamma(11/6) pi^(5/3) (r/r0)^(5/3) = 2 [24/5 Gamma(6/5)]^(5/6) (r/r0)^(5/3)
//           = 6.8839 (r/r0)^(5/3)                                                      (Fried 1966).
// Numerics: D uses that series (summed to convergence, no cancellation) for x <= 2 and K_{5/6} for x > 2,
// so it is accurate to ~1e-14 relative for every r from 1e-12 L0 to 1e3 L0; a direct Hankel quadrature of Phi
// agrees to 4e-9 (unit test). The von Kármán D saturates at 2 sigma^2 for r >> L0; for r << L0 the next
// term of the same series gives
//     D_vK / D_Kolmogorov = 1 - (Gamma(11/6) / Gamma(7/6)) (pi r / L0)^(1/3) + ... = 1 - 1.485 (r/L0)^(1/3),
// already -32% at r = L0/100.
//
// r0 scaling (Roddier 1981): r0(lambda) = r0(lambda_ref) (lambda / lambda_ref)^(6/5); the turbulence strength
// of one layer carrying a fraction w of the integrated Cn^2 is r0_layer = r0 w^(-3/5) (r0^(-5/3) is linear in
// Cn^2 dh).
//
// Zernike variances (Noll 1976, J. Opt. Soc. Am. 66, 207). For a circular pupil of diameter D and Noll's
// orthonormal modes (aosr/optics/zernike.hpp) the coefficient a_j of mode j = (n, m) has
//     <a_j^2> = integral Phi(f) |Q_j(f)|^2 d^2f,
//     |Q_j(f)|^2 = (n+1) [2 J_{n+1}(pi D f) / (pi D f)]^2 ang_j,
// with ang_j = 2 cos^2(m phi), 2 sin^2(m phi) or 1 (m = 0), whose azimuthal mean is 1. With u = pi D f:
//     <a_j^2> = 8 pi^(8/3) c_Phi (n+1) (D/r0)^(5/3) int_0^inf (u^2 + u0^2)^(-11/6) J_{n+1}(u)^2 u^(-1) du,
//     u0 = pi D / L0.
// Kolmogorov (u0 = 0) has the closed form (Weber-Schafheitlin integral; Noll 1976 eq. 25 on the diagonal)
//     <a_j^2> = K_z (n+1) Gamma(n - 5/6) / Gamma(n + 23/6) (D/r0)^(5/3),
//     K_z = 8 pi^(8/3) c_Phi Gamma(14/3) / (2^(14/3) Gamma(17/6)^2) = 0.7552,
// e.g. 0.4489 (D/r0)^(5/3) for EACH tilt mode (the two tilts together carry 0.8978; Noll's table gives
// Delta_1 - Delta_3 = 0.896), 0.0232 for defocus and each astigmatism (Noll: Delta_3 - Delta_4 = 0.023).
// Finite L0 reduces the low orders most: tilt is cut by 28% even at L0 = 125 D, by 86% at L0 = 3 D (8 m
// telescope, L0 = 25 m), defocus by 33% there; that correction is the numerical integral of
// VonKarmanZernikeVariance (geometric panels near u = 0, Gauss-Legendre panels of width 1/2 up to
// u = max(400, 8 (n+1) + 200), analytic tail; ~1e-10 relative, checked against the closed form).
// Noll's residual after removing modes 1..J (Kolmogorov): Delta_J = sum_{j > J} <a_j^2>, from the closed form
// summed to n = 20000 plus its n^(-8/3) tail. With the exact constants, Delta_1 = 1.0324 (also obtained by
// integrating 6.8839 r^(5/3) against the pupil's autocorrelation), Delta_2 = 0.5835, Delta_3 = 0.1347,
// Delta_4 = 0.1114: Noll's table (1.0299, 0.582, 0.134, 0.111, ...) is 0.24-0.45% lower, from his rounded
// prefactor. Noll's large-J fit 0.2944 J^(-sqrt(3)/2) holds to 2% for 10 <= J <= 100 (the exact residual
// decays as J^(-5/6), so the fit drifts: +8% at J = 1000).
#pragma once

namespace aosr {

// c_Phi = Gamma(11/6)^2 / (2 pi^(11/3)) [24/5 Gamma(6/5)]^(5/6) = 0.0228955 (dimensionless).
double VonKarmanPsdConstant();
// Fried's constant 2 [24/5 Gamma(6/5)]^(5/6) = 6.88388 in D(r) = 6.88 (r/r0)^(5/3).
double KolmogorovStructureConstant();

// Phi(f) [rad^2 m^2] at spatial frequency f >= 0 [cycles/m]; L0 = +inf gives Kolmogorov (infinite at f = 0).
double VonKarmanPsd(double f_cycles_per_m, double r0_m, double L0_m);

// Phase variance sigma^2 = B(0) = 0.0863 (L0/r0)^(5/3) [rad^2]; L0 must be finite.
double VonKarmanPhaseVariance(double r0_m, double L0_m);
// Phase covariance B(r) [rad^2] at separation r >= 0 [m]; L0 must be finite.
double VonKarmanCovariance(double r_m, double r0_m, double L0_m);
// Structure function D(r) = <(phi(x + r) - phi(x))^2> [rad^2]; L0 = +inf gives KolmogorovStructureFunction.
double VonKarmanStructureFunction(double r_m, double r0_m, double L0_m);
// 6.8839 (r/r0)^(5/3) [rad^2].
double KolmogorovStructureFunction(double r_m, double r0_m);

// r0 at `wavelength_m` given r0 at `reference_wavelength_m`: r0 (lambda/lambda_ref)^(6/5). All > 0, finite.
double ScaleR0(double r0_m, double reference_wavelength_m, double wavelength_m);

// Modified Bessel function of the second kind K_nu(x) for real nu and x > 0, from its integral
// representation K_nu(x) = int_0^inf exp(-x cosh t) cosh(nu t) dt summed by the trapezoidal rule with step
// 1/16 until the terms fall below 1e-18 of the sum (the integrand is analytic in |Im t| < pi/2, so the rule
// converges like exp(-pi^2 / h): ~1e-15 relative for all x in [1e-8, 700]). Agrees with std::cyl_bessel_k to
// < 1e-13 relative (tested). Throws InvalidArgument for x <= 0 or non-finite arguments.
double ModifiedBesselK(double nu, double x);

// Variance <a_j^2> [rad^2] of Noll mode j's coefficient over a pupil of diameter D for Kolmogorov
// turbulence (closed form above). j >= 2 (piston is infinite for Kolmogorov and returns +inf for j = 1).
double KolmogorovZernikeVariance(int j, double diameter_m, double r0_m);
// Same for von Kármán with outer scale L0 (numerical integral; +inf gives the Kolmogorov value, up to
// ~1e-10 relative). j >= 1 (piston is finite for finite L0). Cost ~10 ms per call.
double VonKarmanZernikeVariance(int j, double diameter_m, double r0_m, double L0_m);
// Noll's Delta_J coefficient (dimensionless): residual phase variance after removing modes 1..J, in units
// of (D/r0)^(5/3) rad^2, Kolmogorov. J >= 1.
double NollResidualCoefficient(int J);
// Delta_J (D/r0)^(5/3) [rad^2].
double NollResidualVariance(int J, double diameter_m, double r0_m);

}  // namespace aosr
