// A layered, frozen-flow atmosphere: the turbulent optical path difference (OPD) over the pupil at time t.
//
// Model. Each layer i is a thin von Kármán phase screen carrying a fraction w_i of the integrated turbulence
// (sum w_i = 1) that moves rigidly with its wind (Taylor's frozen-flow hypothesis):
//     OPD(p, t) = sum_i lambda_ref / (2 pi) * phi_i(p - v_i t u_i),      u_i = (cos theta_i, sin theta_i),
// with p the pupil position [m] (pupil.hpp's grid: n pixels across D, pitch D/n, centred), v_i [m/s] the wind
// speed and theta_i the direction the turbulence moves toward, measured from +x toward +y (pupil.hpp's
// azimuth). phi_i is in radians at lambda_ref = r0_wavelength_m with Fried parameter
//     r0_i = r0 w_i^(-3/5)          (r0^(-5/3) is proportional to the integrated Cn^2, Roddier 1981),
// so the layers' phase structure functions add up to that of r0: D(r) = sum_i D_i(r). OPD is achromatic: the
// phase at another wavelength lambda is 2 pi OPD / lambda, whose statistics are those of r0(lambda) =
// r0 (lambda/lambda_ref)^(6/5) (von_karman.hpp, ScaleR0). Layers are seen on axis (zenith, no field angle):
// the altitude is recorded for later anisoplanatism work but does not change the on-axis OPD.
//
// Screens. Each layer has an InfinitePhaseScreen (infinite_phase_screen.hpp; Assémat et al. 2006) whose rows
// run against the wind: as t grows the footprint of the pupil slides along it and new rows are extruded on
// demand, so a run of any length never repeats and keeps the von Kármán statistics. Its pitch is the pupil
// pitch D/n; its width covers the pupil's footprint across the wind, (n - 1)(|cos theta| + |sin theta|) + 6
// pixels, and it keeps 4 rows more (so calls may step back in time by ~3 pixels of travel). Seeds: layer i
// uses DeriveSeed(seed, i) (random.hpp), so adding a layer does not change the others.
//
// Sampling and its error (the design choice). The layer value at a pupil pixel is ONE interpolation of the
// pristine screen samples at the exact shifted position: each call interpolates from the stored screen, never
// from a previously interpolated one, so there is no cumulative smoothing however long the run (shifting an
// interpolated screen by a sub-pixel amount at every step would low-pass it a little more each time). The
// interpolation itself is the only error. Its size follows from the structure function alone (for weights
// w_j summing to 1, Var(sum w_j phi_j - phi) = sum w_j D(x_j - x) - 1/2 sum w_j w_k D(x_j - x_k)): for
// bilinear interpolation of a Kolmogorov field the error variance is
//     0.065 D(dx) at a half-pixel offset along one axis (0.038 D(dx) averaged over offsets),
//     0.089 D(dx) at the worst point (1/2, 1/2),                   D(dx) = 6.88 (dx/r0)^(5/3),
// i.e. an RMS of at most 0.30 sqrt(D(dx)) = 0.78 (dx/r0)^(5/6) rad. Its visible effect is smoothing: averaged
// over sub-pixel offsets, the sampled OPD's structure function is low by ~23% at 1 pixel, 11% at 2, 5% at 4
// and 1.6% at 8 pixels with bilinear weights, and by ~12%, 4%, 1%, 0.1% with Keys' cubic convolution
// (AtmosphereOptions::interpolation; ~3x the sampling cost). The deficit concerns the smallest scales the
// grid represents (the PSF halo near the grid's Nyquist angle n lambda/(2D)); it recurs at the pixel-crossing
// frequency v/dx, and below one pixel of travel the temporal structure function grows as (v tau/dx)^2 instead
// of (v tau/dx)^(5/3). The physics tests compare the simulator with the exact expectation of "von Kármán
// screen + one interpolation" (to <3%) as well as with the continuous law. Whole-pixel moves are exact: for
// wind along an axis the pupil pixel centres fall on screen pixel centres, and for any direction whose shift
// v t u is a whole number of pixels in x and y, OPD(t) is OPD(0) translated by that many pixels (to ~1e-15
// relative).
//
// Cost per Opd() call: n^2 interpolations per layer (~0.05 ms per layer for n = 128 bilinear, ~0.18 ms
// cubic), plus the extrusion of ~v dt/dx new rows per layer (~0.03-0.05 ms per row for n = 128). Measured for
// n = 128, 3 layers at 8-25 m/s and 1 kHz: 0.18 ms per call (bilinear), 0.58 ms (cubic), one core.
// Construction builds each layer's extrusion matrices (O(width^3): ~0.12 s for a wind along an axis, ~0.25 s
// diagonal, n = 128) and an initial FFT screen: ~1 s for 3 layers including the FFT plans.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "aosr/ao/infinite_phase_screen.hpp"
#include "aosr/core/image.hpp"

namespace aosr {

struct Layer {
  // Height above the telescope [m]; >= 0 and finite. Not used on axis; off axis the layer is seen displaced
  // by altitude * direction (header, "Field directions"). 0: a ground layer, the same in every direction.
  double altitude_m = 0.0;
  // Fraction of the integrated Cn^2 in this layer; in [0, 1]. The fractions of all layers sum to 1 (within
  // 1e-6). A layer with fraction 0 contributes nothing and gets no screen. 1: a single-layer atmosphere.
  double cn2_fraction = 1.0;
  // Wind speed [m/s]; >= 0 and finite. 0 (the default) is a static layer; ground layers blow at ~5-10 m/s,
  // the jet-stream layer (~10 km) at 20-40 m/s.
  double wind_speed_mps = 0.0;
  // Direction the turbulence moves toward [rad], from +x toward +y (pupil.hpp's azimuth); finite. 0 moves the
  // OPD pattern toward larger column index.
  double wind_direction_rad = 0.0;
};

// A direction in the field relative to the guide star [rad]: x along the pupil's columns, y along its rows
// (the image axes: a tilt of the pupil along +x moves the image along +x).
struct FieldDirection {
  double x_rad = 0.0;
  double y_rad = 0.0;
  double Norm() const;
  bool IsZero() const { return x_rad == 0.0 && y_rad == 0.0; }
};

struct AtmosphereOptions {
  // Fried parameter of the whole atmosphere [m] at r0_wavelength_m (and at the zenith angle of the
  // observation: r0 ~ cos(z)^(3/5)); > 0 and finite. 0.15 m at 500 nm is ~0.7" seeing, a good site's median.
  double r0_m = 0.15;
  // Wavelength at which r0_m is given [m]; > 0 and finite. 500 nm is the usual convention of seeing monitors
  // (DIMM); some site presets quote r0 at 550 nm: state it here rather than converting by hand.
  double r0_wavelength_m = 500e-9;
  // Outer scale [m], common to all layers; > 0 and finite. 25 m: a typical median (e.g. ~22 m at Paranal).
  double L0_m = 25.0;
  // The layers; at least one, fractions summing to 1. No default (empty is invalid): the profile is the
  // site's (e.g. a ground layer with half the turbulence plus one or two high layers).
  std::vector<Layer> layers;
  // Master seed; any value. Layer i's screen uses DeriveSeed(seed, i). 1: a fixed default, so that runs are
  // reproducible unless a seed is chosen.
  std::uint64_t seed = 1;
  // How a layer is sampled at the sub-pixel position of each pupil pixel (see "Sampling" above):
  // kBilinear (2 x 2 taps, the default: fastest, ~0.05 ms per layer for n = 128) or kCubic (Keys' cubic
  // convolution, a = -1/2, 4 x 4 taps: about half the small-scale loss for ~4x the sampling cost).
  enum class Interpolation { kBilinear, kCubic };
  Interpolation interpolation = Interpolation::kBilinear;
  // The antithetic partner of this seed's atmosphere: every layer's OPD negated. Gaussian zero-mean screens
  // make OPD and -OPD equally likely, so the pair is a valid sample; averaging a statistic over the pair
  // cancels its odd part exactly (antithetic variates). E.g. a closed loop whose every element is odd under
  // OPD -> -OPD (linear sensors and control; a diffractive SH with a window symmetric about the axis, whose
  // spot of -OPD is its spot of OPD inverted through the axis) turns -OPD into a PSF inverted through the
  // axis, so the pair's mean centroid is 0 unless the system holds a bias (tests/ao/closed_loop_physics_test).
  // Default false.
  bool antithetic = false;
  // Radius [rad] of the disk of field directions the screens must serve (header, "Field directions"); >= 0,
  // finite and <= 0.01 rad (34'). Default 0: the guide star's direction only, exactly the on-axis screens.
  double max_field_angle_rad = 0.0;

  // True when every field is in range; otherwise false and `why` (if non-null) names the bad field, e.g.
  // "layers[2].wind_speed_mps = nan; allowed: >= 0 and finite [m/s]".
  bool IsValid(std::string* why) const;
};

// Not thread-safe (Opd() extrudes the screens); use one Atmosphere per thread.
class Atmosphere {
 public:
  // pupil_n: pupil grid size n (2 .. 2000); diameter_m: D spanned by the grid (> 0). Throws InvalidArgument
  // naming the bad argument or option field (e.g. "Atmosphere: invalid options.r0_m = -1; ...").
  Atmosphere(const AtmosphereOptions& options, Index pupil_n, double diameter_m);
  ~Atmosphere();
  Atmosphere(Atmosphere&&) noexcept;
  Atmosphere& operator=(Atmosphere&&) noexcept;

  // Total OPD [m] on the n x n pupil grid at time t_s [s]. t_s must be finite and >= 0; calls may go back in
  // time only as far as the screens still hold (~3 pixels of wind travel); typically t increases. Throws
  // InvalidArgument otherwise. A jump forward by dt extrudes v dt / dx rows per layer (~0.05 ms each for
  // n = 128), so jumping hours ahead is slow: build a new Atmosphere (another seed) for an unrelated epoch.
  Image Opd(double t_s);
  // Same into `opd` (resized to n x n if needed; no allocation when already that size).
  void Opd(double t_s, Image* opd);
  // OPD [m] seen from field direction `direction` (header, "Field directions"); the zero direction gives
  // exactly Opd(t_s). Throws InvalidArgument for a non-finite direction or one outside the disk the screens
  // were built for (CheckFieldDirection), and as Opd(t_s) for a bad time.
  void Opd(double t_s, const FieldDirection& direction, Image* opd);
  Image Opd(double t_s, const FieldDirection& direction);
  // The OPDs seen from several directions at one time, into (*opds)[k] (resized): each the bytes of
  // Opd(t_s, directions[k], ...). The screens are advanced once, then the directions are read in parallel
  // (DefaultThreads()). Throws as Opd for a bad time or direction (naming its index).
  void Opd(double t_s, const std::vector<FieldDirection>& directions, std::vector<Image>* opds);
  // OPD [m] of layer `layer` alone (0-based) at t_s; zero for a layer with cn2_fraction 0.
  Image LayerOpd(int layer, double t_s);
  // Throws InvalidArgument (as `function`, argument `direction`) unless the direction is finite and every
  // layer above the ground can be read there: |theta| <= options().max_field_angle_rad.
  void CheckFieldDirection(const FieldDirection& direction, const char* function) const;

  // r0_i = r0 w_i^(-3/5) of layer i at r0_wavelength_m [m] (+inf for a fraction of 0).
  double LayerR0(int layer) const;
  // r0 of the whole atmosphere at `wavelength_m` [m]: ScaleR0(r0, r0_wavelength, wavelength).
  double R0At(double wavelength_m) const;

  Index pupil_n() const { return pupil_n_; }
  double diameter_m() const { return diameter_m_; }
  const AtmosphereOptions& options() const { return options_; }

 private:
  struct LayerState;
  // shift_x_px, shift_y_px: the layer's footprint displacement h theta / dx [pupil pixels] (0 on axis).
  void Accumulate(LayerState& layer, double t_s, double shift_x_px, double shift_y_px, double* out) const;
  void Prepare(LayerState& layer, double t_s, double row_shift_px, const char* function);

  AtmosphereOptions options_;
  Index pupil_n_ = 0;
  double diameter_m_ = 0.0;
  std::vector<std::unique_ptr<LayerState>> layers_;
};

}  // namespace aosr
