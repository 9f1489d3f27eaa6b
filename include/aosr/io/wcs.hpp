// Sky coordinates of images: the celestial FITS World Coordinate System for the gnomonic (TAN) projection.
//
// References (the formulas below are theirs; the code is ours):
//   [I]  E. W. Greisen, M. R. Calabretta 2002, "Representations of world coordinates in FITS",
//        A&A 395, 1061 (CRPIX, CRVAL, CD, PC, CDELT, CROTA, CTYPE, RADESYS, EQUINOX; §2 and §6.1).
//   [II] M. R. Calabretta, E. W. Greisen 2002, "Representations of celestial coordinates in FITS",
//        A&A 395, 1077 (the spherical rotation, eqs. 2 and 5; the TAN projection, §5.1.3; LONPOLE, §2.4).
//
// ## The maths, pixel to sky
//
//  1. FITS pixel p = (p1, p2), 1-based, p1 along NAXIS1 (x, columns), p2 along NAXIS2 (y, rows).
//     aosr's 0-based array element (y, x) is FITS pixel (x + 1, y + 1) (io/fits.hpp), so pixel *centres* at
//     integer aosr coordinates are pixel centres at integer FITS coordinates.
//  2. Intermediate world coordinates, degrees ([I] eq. 3 with CD = diag(CDELT)·PC):
//         (x, y) = CD · (p − CRPIX).
//  3. Native spherical coordinates of TAN ([II] eqs. 54-55 with θ0 = 90°):
//         R_θ = √(x² + y²),   φ = arg(−y, x),   θ = atan(180° / (π R_θ)).
//  4. Celestial coordinates ([II] eq. 2), with the reference point (α0, δ0) = (CRVAL1, CRVAL2) at the
//     native pole (zenithal projection: α_p = α0, δ_p = δ0) and φ_p = LONPOLE = 180° (its default when
//     δ0 < 90°; 0° when δ0 = 90°, [II] §2.4):
//         α = α_p + arg(sin θ cos δ_p − cos θ sin δ_p cos(φ − φ_p), −cos θ sin(φ − φ_p))
//         δ = asin(sin θ sin δ_p + cos θ cos δ_p cos(φ − φ_p)),
//     where arg(a, b) is the angle of the point (a, b), atan2(b, a).
//  Sky to pixel runs the same steps backwards ([II] eq. 5, then x = R_θ sin φ, y = −R_θ cos φ with
//  R_θ = (180°/π) cot θ, then p = CRPIX + CD⁻¹ (x, y)). Points at 90° or more from the reference point
//  (θ ≤ 0) have no TAN image: SkyToPixel throws InvalidArgument for them.
//
// ## Reading a header (WcsFromHeader), what is accepted
//
//  * CTYPE1 = 'RA---TAN', CTYPE2 = 'DEC--TAN' (any other projection or axis order, and the SIP and TPV
//    distortions, 'RA---TAN-SIP' / A_ORDER / B_ORDER / PVi_m / distortion tables, are refused with a message
//    saying they are not supported rather than silently ignored). CUNITi, when present, must be 'deg'.
//  * The linear part in one of three forms ([I] §2.1.2): a CDi_j matrix (missing elements are 0; CDELTi and
//    CROTA2 are then ignored, as wcslib does); or PCi_j (missing elements: the identity) with CDELTi;
//    or CDELTi alone, optionally rotated by CROTA2 ([II] eq. 189: CD = [[CDELT1 cos ρ, −CDELT2 sin ρ],
//    [CDELT1 sin ρ, CDELT2 cos ρ]]). CD with PC, and PC with CROTA2, are inconsistent ([I] §2.1.2) and refused.
//    The matrix must be invertible.
//  * LONPOLE only at its default (see 4. above); LATPOLE is irrelevant for a zenithal projection.
//  * RADESYS (or the older RADECSYS) and EQUINOX (or the older EPOCH) are kept when present.
//  * Errors: InvalidArgument "WcsFromHeader: invalid <KEYWORD> = <value>; allowed: ..." naming the keyword.
//
// ## Super-resolved images
//
// Camera pixel c (0-based, along one axis) spans the r HR pixels c·r .. c·r + r − 1, so its centre is HR
// coordinate (c + ½)·r − ½ (scene/dataset.hpp, "stars"). A frame whose image is displaced by d HR pixels
// (forward_model.hpp's FrameOffset: +dx moves the scene toward +x) shows the scene's HR position p at camera
// position c with (c + ½)·r − ½ = p + d. So the HR grid's WCS, from the frame's, is per axis
//     CD_HR = CD / r,    CRPIX_HR = (CRPIX − ½)·r + ½ − d          (HrWcs; LrWcs is its exact inverse).
#pragma once

#include <optional>
#include <string>

#include "aosr/io/fits.hpp"

namespace aosr {

struct Wcs {
  // FITS reference pixel, 1-based: crpix[0] = CRPIX1 (x), crpix[1] = CRPIX2 (y).
  double crpix[2] = {1.0, 1.0};
  // Sky position of the reference pixel [deg]: crval[0] = CRVAL1 (RA), crval[1] = CRVAL2 (Dec).
  double crval[2] = {0.0, 0.0};
  // Linear transformation [deg per pixel]: cd[i][j] = CD(i+1)_(j+1), (x, y) = CD · (p − CRPIX).
  double cd[2][2] = {{1.0, 0.0}, {0.0, 1.0}};
  // Celestial reference system (e.g. "ICRS", "FK5"); empty: not stated (the FITS default applies).
  std::string radesys = "ICRS";
  // Equinox [Julian years] of FK4/FK5 systems; absent for ICRS.
  std::optional<double> equinox;

  // Pixel scale along each axis [deg per pixel]: the norm of CD's columns.
  double PixelScaleDeg(int axis) const;
};

// Sky coordinates [deg]: right ascension in [0, 360), declination in [−90, 90].
struct SkyCoord {
  double ra_deg = 0.0;
  double dec_deg = 0.0;
};

// An aosr pixel position, 0-based array coordinates (pixel centres at integers; FITS pixel (x+1, y+1)).
struct PixelCoord {
  double y = 0.0;
  double x = 0.0;
};

// A tangent-plane WCS with north and east in the standard orientation rotated by a position angle:
//   `pixel_rad`           pixel pitch [rad] (> 0), the same on both axes;
//   `position_angle_deg`  position angle of the image's +y axis, from north through east [deg]; 0: north
//                         along +y and east along −x (the sky as seen: RA grows to the left in DS9);
//   `reference`           the aosr pixel (0-based) at which the sky position is (`ra_deg`, `dec_deg`).
// CD = s·[[−cos PA, sin PA], [sin PA, cos PA]] with s the pitch in degrees. InvalidArgument naming the bad
// argument (non-finite values, dec outside [−90, 90], pixel_rad <= 0).
Wcs TangentPlaneWcs(double ra_deg, double dec_deg, double pixel_rad, double position_angle_deg,
                    PixelCoord reference);

// aosr pixel (0-based) -> sky and back (top of the file). SkyToPixel: InvalidArgument for a point 90° or
// more from the reference point, which the TAN projection cannot show.
SkyCoord PixelToSky(const Wcs& wcs, PixelCoord pixel);
PixelCoord SkyToPixel(const Wcs& wcs, SkyCoord sky);

// Great-circle distance between two sky positions [deg] (haversine form: accurate at small separations).
double AngularSeparationDeg(SkyCoord a, SkyCoord b);

// True when the header states a celestial WCS (CTYPE1 or CTYPE2 present).
bool HasWcs(const FitsHeader& header);
// Reads the WCS of a header (rules at the top of the file); InvalidArgument naming the keyword otherwise,
// including when the header has no WCS (CTYPE1 missing).
Wcs WcsFromHeader(const FitsHeader& header);
// Writes WCSAXES = 2, CTYPE1/2, CUNIT1/2, CRPIX1/2, CRVAL1/2, CD1_1..CD2_2, LONPOLE, RADESYS and EQUINOX
// (when set) into `header`, replacing those already there. Checks the WCS (finite, invertible CD, dec in
// [−90, 90]): InvalidArgument naming the field.
void WriteWcs(const Wcs& wcs, FitsHeader* header);
// WriteWcs (when `wcs` is given) and BUNIT (when `bunit` is not empty): what every output image carries.
void SetImageKeywords(const std::optional<Wcs>& wcs, const std::string& bunit, FitsHeader* header);

// The WCS of the HR grid (r times finer) of a frame with WCS `lr` whose image is displaced by
// (offset_y_hr, offset_x_hr) HR pixels (top of the file), and its exact inverse. r >= 1.
Wcs HrWcs(const Wcs& lr, int r, double offset_y_hr = 0.0, double offset_x_hr = 0.0);
Wcs LrWcs(const Wcs& hr, int r, double offset_y_hr = 0.0, double offset_x_hr = 0.0);

}  // namespace aosr
