// Zernike polynomials in Noll's ordering and normalisation (R. J. Noll, "Zernike polynomials and
// atmospheric turbulence", J. Opt. Soc. Am. 66, 207-211 (1976)).
//
// Maths. On the unit disk (rho <= 1, theta measured from +x toward +y, see pupil.hpp):
//     Z_j(rho, theta) = N_n^m R_n^|m|(rho) * { cos(m theta)    m > 0
//                                             { sin(|m| theta)  m < 0
//                                             { 1               m = 0
//     N_n^m = sqrt(n + 1) for m = 0,  sqrt(2 (n + 1)) otherwise,
//     R_n^m(rho) = sum_{k=0}^{(n-m)/2} (-1)^k (n-k)! / (k! ((n+m)/2 - k)! ((n-m)/2 - k)!) rho^(n-2k),
// so that the modes are orthonormal over the disk:  (1/pi) * integral Z_i Z_j rho drho dtheta = delta_ij,
// i.e. each mode has RMS 1 and zero mean (j > 1). A phase (or OPD) sum_j a_j Z_j therefore has variance
// sum_{j>1} a_j^2 over the disk, with a_j in the phase's units (radians, or metres of OPD).
//
// Noll's index j >= 1 runs over radial orders n = 0, 1, 2, ...; within an order |m| increases (|m| = n mod 2,
// n mod 2 + 2, ..., n), and each m != 0 appears twice: the even j carries cos (m > 0), the odd j carries
// sin (m < 0). Examples: Z1 = 1 (piston); Z2 = 2 rho cos(theta) (x tilt); Z3 = 2 rho sin(theta) (y tilt);
// Z4 = sqrt(3) (2 rho^2 - 1) (defocus); Z5 = sqrt(6) rho^2 sin(2 theta); Z6 = sqrt(6) rho^2 cos(2 theta);
// Z11 = sqrt(5) (6 rho^4 - 6 rho^2 + 1) (spherical).
//
// Numerics. The factorial sum above cancels catastrophically near rho = 1: its largest term is 2e6 at n = 20,
// 5e13 at n = 40 and 3e17 at n = 50, so double precision keeps ~3 digits at n = 40 and none at n = 50
// (modes j ~ 1300). R_n^m is instead computed by Kintner's three-term recurrence in n at fixed m
// (E. C. Kintner, Optica Acta 23, 679-680 (1976)), a form of the Jacobi-polynomial recurrence that is
// forward-stable on [0, 1]:
//     K1 R_n^m = (K2 rho^2 + K3) R_{n-2}^m + K4 R_{n-4}^m,
//     K1 = (n+m)(n-m)(n-2)/2,  K2 = 2n(n-1)(n-2),  K3 = -m^2(n-1) - n(n-1)(n-2),  K4 = -n(n+m-2)(n-m-2)/2,
// started from R_m^m = rho^m and R_{m+2}^m = (m+2) rho^(m+2) - (m+1) rho^m. Cost O(n) per value. Values stay
// within |R| <= 1 on the disk (tested to n = 200) and the radial orthogonality holds to ~1e-13 up to n = 120
// (j ~ 7000); the test suite checks Z_1..Z_200 (n <= 19) to 1e-12 by exact quadrature.
//
// Sampling. Zernike()/ZernikeBasis() sample the modes at the pixel centres of pupil.hpp's n x n grid
// (rho = 1 at the rim of a grid that spans D) and set pixels whose centre lies outside the pupil to 0: the
// same rule as CircularPupil(n, geometry, 1), so a mode and the binary pupil share their support. With a
// central obstruction the modes are the *circular* Zernikes masked by the annulus: they are no longer exactly
// orthogonal there; ProjectOntoZernike() stays exact because it solves least squares rather than taking inner
// products, and OrthonormalZernikeBasis() builds modes that are orthonormal over any given pupil (below). For
// grey-edged pupils, whose edge pixels can have centres just beyond rho = 1, build OPDs with
// ZernikeUnmasked() so every transmitting pixel carries the mode.
//
// Tip/tilt and image motion. With the pupil field E = A exp(i 2 pi w / lambda) (w: OPD in metres) and
// PSF = |F{E}|^2 under the forward kernel exp(-2 pi i u.alpha) (psf.hpp, mft.hpp), an OPD w = s x of slope s
// moves the PSF by +s radians along +x (toward larger column index). For the x tilt mode,
//     w = a Z2 = a 2 rho cos(theta) = a 2 x / R = (4 a / D) x,      R = D/2,
// so a coefficient a [metres, RMS-normalised mode] moves the image by 4a/D radians, and conversely
// a = shift * D / 4. The same holds for a Z3 coefficient along +y (larger row index).
#pragma once

#include <Eigen/Core>

#include "aosr/core/image.hpp"

namespace aosr {

// Radial order n >= 0 and signed azimuthal frequency m (|m| <= n, n - |m| even); m > 0: cos, m < 0: sin.
struct ZernikeNM {
  int n = 0;
  int m = 0;
  bool operator==(const ZernikeNM& o) const { return n == o.n && m == o.m; }
};

// Noll index j (>= 1) to (n, m) following Noll (1976) Table 1, and its inverse. Throw InvalidArgument for
// j < 1, or for (n, m) that is not a Zernike mode.
ZernikeNM NollToNM(int j);
int NMToNoll(int n, int m);

// Radial polynomial R_n^m(rho) for n >= 0, 0 <= m <= n, n - m even, by Kintner's recurrence. Defined for
// any rho >= 0 (the polynomial continues outside the disk; |R| <= 1 on [0, 1]).
double ZernikeRadial(int n, int m, double rho);

// Z_j(rho, theta), orthonormal (RMS 1) on the unit disk. rho >= 0 (the polynomial is evaluated as is for
// rho > 1), theta in radians. Throws InvalidArgument for j < 1 or rho < 0.
double ZernikeValue(int j, double rho, double theta);

// Mode j sampled on the n_pix x n_pix pupil grid (pupil.hpp), 0 where the pixel centre is outside the
// (annular) pupil obstruction <= rho <= 1. Dimensionless; multiply by a coefficient in radians or metres.
Image Zernike(int j, Index n_pix, double obstruction = 0.0);

// Mode j at every pixel centre of the n_pix x n_pix grid, without a mask: the polynomial continues beyond
// rho = 1 (corners reach rho = sqrt(2)). Use it for OPDs on grey-edged pupils (CircularPupil with
// supersample > 1), whose edge pixels with centres just outside the rim still transmit light: with the masked
// Zernike() those pixels would carry zero OPD, which e.g. spoils a tilt's pure image shift at the ~1% level.
Image ZernikeUnmasked(int j, Index n_pix);

// Modes j = 1..J (element j-1 is Z_j) on the same grid and mask. Memory: J * n_pix^2 doubles.
ImageStack ZernikeBasis(int J, Index n_pix, double obstruction = 0.0);

// Least-squares Zernike coefficients c (c[j-1] for Z_j, j = 1..J) of `phase` over the pupil:
//     minimise  sum_pixels pupil * (phase - sum_j c_j Z_j)^2,
// over the pixels where pupil > 0 (the pupil value weights grey edge pixels; binary pupils weight uniformly).
// Both images are the same n x n pupil grid; modes are evaluated at every pixel centre with pupil > 0, also
// beyond rho = 1 on grey edges. Exact (to rounding) for a phase that is a combination of Z_1..Z_J on the
// pupil, whatever the obstruction. Units of c are those of `phase`. Cost O(P J^2) for P pupil pixels.
// Throws InvalidArgument for J < 1, shape mismatch, non-square or empty images, negative or non-finite
// pupil values, non-finite phase on the pupil, or too few pupil pixels to determine J modes.
Vector ProjectOntoZernike(const Image& phase, const Image& pupil, int J);

// Zernike modes orthonormalised over an arbitrary pupil (obstructed, with spiders, segmented, grey-edged).
//
// Maths. With the pupil-weighted inner product and its RMS
//     <f, g>_A = sum_p A_p f_p g_p / sum_p A_p,        RMS_A(f) = sqrt(<f, f>_A),
// (A: the pupil amplitude, or any weights >= 0) the circular Z_1..Z_J are no longer orthogonal on an annulus
// or a cut pupil. Gram-Schmidt in Noll order gives modes
//     M_j = sum_{i <= j} Z_i T(i, j),     <M_i, M_j>_A = delta_ij,     T upper triangular, T(j, j) > 0,
// so M_1 is the constant 1 (piston) over the pupil, every M_j (j > 1) has zero weighted mean and RMS 1, and
// M_j differs from Z_j only by what Z_j shares with Z_1..Z_{j-1} on this pupil: on an unobstructed disk the
// M_j are the Z_j up to the grid's discretisation (tested), on an annulus they are the sampled analogue of
// annular Zernikes (V. N. Mahajan, "Zernike annular polynomials for imaging systems with annular pupils",
// J. Opt. Soc. Am. 71, 75-85 (1981)) up to sign conventions and discretisation.
// Numerics: Householder QR of diag(sqrt(A / sum A)) Z (P pupil pixels x J) gives that matrix = Q R, so
// M = Z R^-1 (with R's diagonal made positive); a second QR pass on the result removes the rounding left by
// the conditioning of Z (cond(Z) grows with the obstruction), giving orthonormality to ~1e-14.
//
// Zernike polynomials are evaluated unmasked at every pixel centre with A > 0 (like ProjectOntoZernike) and
// the modes are 0 where A = 0.
//
// Returns the J mode images (element j-1 is M_j) on the pupil's grid; if `zernike_to_mode` is non-null it
// receives T (J x J), so a combination sum_j b_j M_j equals sum_i (T b)_i Z_i. Cost O(P J^2).
// Throws InvalidArgument for J < 1, a non-square or empty pupil, negative or non-finite weights, or modes
// that are linearly dependent on the pupil (too few pixels for J modes).
ImageStack OrthonormalZernikeBasis(const Image& pupil, int J, Eigen::MatrixXd* zernike_to_mode = nullptr);

// Z2 (or Z3) coefficient [m of OPD, RMS-normalised mode] that moves the image by `shift_rad` [rad] along +x
// (or +y) for a telescope of diameter `diameter_m` [m]: a = shift * D / 4 (derivation above).
double TiltCoefficientForShift(double shift_rad, double diameter_m);
// Inverse: image motion [rad] of a Z2/Z3 coefficient [m]: shift = 4 a / D.
double ShiftForTiltCoefficient(double coefficient_m, double diameter_m);

}  // namespace aosr
