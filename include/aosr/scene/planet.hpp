// A rotating planet-like body (Io, Jupiter, an asteroid seen as a resolved disc): a textured, limb-darkened
// sphere in orthographic projection, rendered at any time so that the scene simulator can make test objects
// that change between exposures.
//
// Coordinates (image.hpp): continuous HR pixel coordinates (y, x), pixel (y, x) centred at integers and
// covering [y - 1/2, y + 1/2) x [x - 1/2, x + 1/2); row 0 is "up" on the image. Values are flux per HR pixel.
//
// ## Geometry: orthographic projection of a sphere
//
// The body is far compared with its size, so lines of sight are parallel and the disc is the orthographic
// projection of the sphere: a disc of radius R (radius_px) centred at (c_y, c_x). A point of the image maps
// to normalised disc coordinates dx = (x - c_x)/R, dy = (y - c_y)/R; it is on the disc when dx² + dy² < 1.
//
// The view frame (ξ, η, ζ) is right-handed: ζ toward the observer, η along the projected north pole, ξ to the
// right of η as the observer sees the image. The pole's position angle P (pole_angle_deg) is measured from up
// (−y) toward +x, i.e. clockwise on the displayed image, so the projected pole points along (x, y) =
// (sin P, −cos P) and ξ along (cos P, sin P):
//
//     ξ = dx cos P + dy sin P,      η = dx sin P − dy cos P,      ζ = sqrt(1 − ξ² − η²)   (= μ, see below).
//
// The sub-observer latitude B (sub_observer_latitude_deg) tilts the spin axis toward the observer: in the
// view frame the north pole is N = (0, cos B, sin B), so for B > 0 the north pole is on the visible
// hemisphere, at distance R cos B from the disc centre along the projected pole direction, and the disc
// centre (the sub-observer point) has latitude B. The surface point (ξ, η, ζ) has
//
//     latitude   φ  = asin(η cos B + ζ sin B)                                   (N · point),
//     longitude  λ  = λ_c(t) + atan2(ξ, ζ cos B − η sin B),
//
// the atan2 being the point's azimuth around N measured from the sub-observer meridian (the basis vector
// e1 = (0, −sin B, cos B)) toward e2 = N × e1 = (1, 0, 0) = +ξ. λ_c(t) is the central meridian: the longitude
// of the sub-observer point.
//
// ## Rotation
//
// A positive rotation_period_s T is prograde: the body turns counterclockwise as seen from above its north
// pole (right-hand rule about N, the IAU's convention for the north pole of a prograde body). Its near side
// then moves toward e2 = +ξ: with the pole up (P = 0) features cross the disc from the left limb (−x) to the
// right limb (+x), as the Earth does seen from space with north up; with P = 90° they travel toward +y.
// Negative T is retrograde (features travel toward −ξ); T = 0 does not rotate.
//
// Longitudes here are *east* longitudes: they increase in the direction of rotation (toward +ξ on the disc),
// so a texture map, whose longitude grows with its column index, looks like the disc with the pole up. As the
// surface moves toward +ξ the sub-observer point moves westward over it, so the central meridian *decreases*:
//
//     λ_c(t) = longitude0_deg − 360° t / T         (T != 0;  λ_c = longitude0_deg when T = 0)
//
// (in the west-longitude convention of planetary ephemerides, e.g. Jupiter's System III, the central meridian
// −λ_c increases at 360°/T, the same motion). A feature at longitude λ on the equator, seen with B = 0, is at
// ξ = sin(λ − λ_c(t)): one on the central meridian at t = 0 sits at x − c_x = R sin(2π t / T) for P = 0.
// The rotation phase t/T is reduced modulo 1 before use: t = kT gives exactly the image of t = 0, and t + kT
// that of t to rounding.
//
// ## Brightness
//
// The specific intensity of a surface point is texture(φ, λ) x I(μ), with μ = ζ the cosine of the angle
// between the surface normal and the line of sight and the linear limb-darkening law
//
//     I(μ) = 1 − u (1 − μ),        u = limb_darkening in [0, 1],
//
// so the disc-integrated flux of a uniform texture t0 is t0 π R² (1 − u/3) (∫ μ over the disc is 2πR²/3).
// Projected area is already accounted for by the orthographic map (each image pixel is an area on the sky),
// so no extra μ factor appears. A pixel's value is the mean of s x s point samples at its sub-pixel centres
// (y − 1/2 + (i + 1/2)/s, x − 1/2 + (j + 1/2)/s), each the surface intensity on the disc and 0 off it: a
// box-filtered image whose limb pixels hold the covered fraction to O(1/s). Only the disc's bounding box is
// visited: cost O(R² s²).
//
// ## Texture maps
//
// A texture is an equirectangular map (an Image of M rows x L columns, values >= 0) whose pixels cover the
// sphere once, with the project's pixel-centre convention: row i covers latitudes [90 − i Δφ, 90 − (i+1) Δφ],
// Δφ = 180°/M, centre 90° − (i + 1/2) Δφ (row 0 is the north polar cap); column j covers east longitudes
// [j Δλ, (j+1) Δλ), Δλ = 360°/L, centre (j + 1/2) Δλ. It is sampled bilinearly between pixel centres,
// wrapping in longitude (column L − 1 neighbours column 0) and clamped in latitude (within half a row of a
// pole the first or last row's values are used).
//
// Errors: aosr::InvalidArgument naming the function and the argument or field.
#pragma once

#include <cstdint>
#include <limits>
#include <string>

#include "aosr/core/image.hpp"

namespace aosr {

struct PlanetOptions {
  // Disc centre [HR px]; NaN (default): the field centre ((rows − 1)/2, (cols − 1)/2). Finite values may lie
  // off the field (the disc is clipped); infinities are refused.
  double centre_y = std::numeric_limits<double>::quiet_NaN();
  double centre_x = std::numeric_limits<double>::quiet_NaN();
  // Disc radius [HR px], in (0, 10^5]. No default that could pass silently: 0 is refused.
  double radius_px = 0.0;
  // Sidereal rotation period [s], finite. 0 (default): the body does not rotate; > 0: prograde; < 0:
  // retrograde (see the top of the file).
  double rotation_period_s = 0.0;
  // Position angle of the projected north pole [deg], from up (−y) toward +x, in [−360, 360]. Default 0: up.
  double pole_angle_deg = 0.0;
  // Latitude of the disc centre [deg], in [−90, 90]: the tilt of the north pole toward the observer. Default
  // 0: the equator crosses the disc centre (equator-on view, as Io and Jupiter are from the Earth to ~3°).
  double sub_observer_latitude_deg = 0.0;
  // Central-meridian (east) longitude at t = 0 [deg], finite; any value (taken modulo 360).
  double longitude0_deg = 0.0;
  // Linear limb-darkening coefficient u in [0, 1]: I(μ) = 1 − u (1 − μ). Default 0: a uniform
  // disc, whose flux is texture x area. u = 1 is a Lambert surface seen at zero phase angle (I ∝ μ).
  double limb_darkening = 0.0;
  // Point samples per HR pixel side, in [1, 16]. Default 4: limb pixels within ~1/8 of their covered
  // fraction; over random sub-pixel centres the disc's flux was within 2.3e-3 of π R² and its centroid within
  // 0.02 px for R = 10 px (7e-4 and 0.01 px for R = 20; s = 16: 3e-4 and 2e-3 px for R = 10).
  int supersample = 4;

  // True if every field is in range; otherwise false and, if why != nullptr, *why names the field.
  bool IsValid(std::string* why) const;
};

// The central-meridian (east) longitude λ_c(t) [deg] at time_s (finite), reduced to [0, 360): longitude0_deg
// − 360° (t/T mod 1) (see the top of the file). Options must be valid.
double PlanetCentralMeridianDeg(const PlanetOptions& options, double time_s);

// What lies under one image point: on_disc false (and the rest 0) off the disc.
struct PlanetSurfacePoint {
  bool on_disc = false;
  double latitude_deg = 0.0;   // [−90, 90]
  double longitude_deg = 0.0;  // east longitude, [0, 360)
  double mu = 0.0;             // cosine of the viewing angle, (0, 1]; 1 at the disc centre
};

// The surface point seen at continuous HR pixel coordinates (y, x) (finite) at time_s (finite), on a field of
// shape hr (both sides >= 1; it only places a NaN centre). The same geometry RenderPlanet samples.
PlanetSurfacePoint PlanetSurfaceAt(Shape hr, const PlanetOptions& options, double y, double x, double time_s);

// Renders the body at time_s (finite, seconds) on an HR field of shape hr (both sides >= 1): each pixel is
// the mean over its s x s sub-samples of texture(φ, λ) x I(μ) on the disc, 0 off it (see the top of the
// file). texture: an equirectangular map (top of the file) of at least 1 x 1 pixels, finite and >= 0.
Image RenderPlanet(Shape hr, const PlanetOptions& options, const Image& texture, double time_s);

// ## Procedural surface maps
//
// PlanetTexture(options, seed) is an equirectangular map (rows x cols, layout above) of
//
//     T(φ, λ) = Bands(φ, λ) / <Bands> + spot_contrast Σ_k g(d_k(φ, λ) / r_s),
//
//   * Bands = 1 + band_contrast cos(2π bands (φ' + 90°) / 180°), with φ' = φ + band_wobble_deg sin(3λ + ψ):
//     `bands` cycles of a bright zone and a dark belt between the poles (Jupiter-like), symmetric about the
//     equator, whose boundaries, with band_wobble_deg > 0, undulate in latitude three times around the body
//     (ψ drawn from the seed) so that the bands alone show the rotation. <Bands> is their area-weighted
//     (cos φ) mean over the map's pixels, so the bands average exactly 1 over the sphere;
//   * `spots` round bright spots (Io-like hot spots), centres uniform on the sphere, of angular radius
//     r_s = spot_radius_deg: d_k is the great-circle angle to spot k's centre and g(q) = (1 − q²)² for q < 1,
//     0 beyond (peak 1, half maximum at q = 0.54, smooth at the edge). Overlapping spots add.
// The equator is in a bright zone for even `bands`. Values are finite and > 0 (the bands' minimum is at least
// (1 − band_contrast) / (1 + band_contrast)); the mean over the sphere is 1 plus the spots' share, about
// spots x spot_contrast x r_s² / 12 (r_s in radians; 0.0065 for the defaults).
//
// Determinism: one stream, DeriveSeed(seed, 4) (ao/random.hpp), uniforms from its top 53 bits: ψ first, then
// (sin latitude, longitude) per spot. Same options and seed give the same bytes on every platform up to
// libm's last-bit rounding.
struct PlanetTextureOptions {
  // Map size [pixels], rows (latitude) and cols (longitude) in [2, 65536]. Default 90 x 180: 2° pixels, about
  // what a disc of radius 30 px resolves at its centre (one HR pixel spans 1/R rad there); larger discs want
  // finer maps, or the map's bilinear facets show.
  int rows = 90;
  int cols = 180;
  // Zone-belt cycles between the poles, in [0, 1000]. Default 6: 12 stripes of 15°, roughly Jupiter's.
  int bands = 6;
  // Band amplitude relative to the mean, in [0, 1) (1 would make dark belts 0). Default 0.3.
  double band_contrast = 0.3;
  // Latitude undulation of the bands [deg], in [0, 45]. Default 0: bands depend on latitude only.
  double band_wobble_deg = 0.0;
  // Number of spots, in [0, 100000]. Default 4.
  int spots = 4;
  // Spot angular radius [deg] (where g falls to 0), in (0, 90]. Default 8°: ~9 px across at the centre of a
  // disc of radius 32 px.
  double spot_radius_deg = 8.0;
  // Spot peak brightness relative to the bands' mean, finite and in [0, 10^6]. Default 1 (peak ~2x the mean).
  double spot_contrast = 1.0;

  // True if every field is in range; otherwise false and, if why != nullptr, *why names the field.
  bool IsValid(std::string* why) const;
};

// The procedural map above, deterministic in `seed`.
Image PlanetTexture(const PlanetTextureOptions& options, std::uint64_t seed);

}  // namespace aosr
