// The science PSF of a telescope preset with optional Zernike DM offsets: diffraction-limited, long-exposure
// through the analytic AO residual (ao/analytic_ao.hpp), or from a closed-loop Monte-Carlo run
// (ao/closed_loop.hpp, the offset held through the WFS reference slopes), with its Strehl ratio, FWHM and
// encircled energy. What `aosr psf` prints and the Python aosr.psf() returns: one library call for both.
//
// Field direction (anisoplanatism): the PSF of a science target at `field_direction` from the guide star
// (which defines the AO axis), through the same atmosphere corrected by the guide star's loop. Analytic: the
// anisoplanatism term of ao/analytic_ao.hpp (with the servo-lag cross term), the PSD grid's padding raised when
// the direction needs it (h |theta| <= K D / 4); closed loop: the science camera off axis in the loop
// (ao/closed_loop.hpp, "Off axis"), the screens built for |theta|; diffraction: no atmosphere, so the same PSF
// everywhere. This is the one call that a field grid (scene layer) makes per field point. The default (on
// axis) gives the same bytes as before field directions existed.
//
// Normalisation: the whole focal plane sums to 1, so the window's sum is the light inside it.
// Strehl: the PSF's peak over the diffraction-limited peak of the same sampling (offsets included, so a
// designed tilt lowers it only by the window's discretisation).
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "aosr/ao/analytic_ao.hpp"
#include "aosr/ao/ao_system.hpp"
#include "aosr/core/image.hpp"
#include "aosr/optics/psf.hpp"
#include "aosr/scene/telescope.hpp"

namespace aosr {

struct PresetPsfOptions {
  // "analytic" | "diffraction" | "closed-loop"; empty: analytic when the preset has an atmosphere and AO,
  // else diffraction. analytic needs both; closed-loop needs AO.
  std::string mode;
  // DM offsets: (Noll index j in 2..1000, wavefront OPD RMS in nm, finite) per term.
  struct Offset {
    int noll = 4;
    double rms_nm = 0.0;
  };
  std::vector<Offset> offsets;
  // Pixel = camera pixel / r (r in 1..16), unless pixel_lod > 0 gives the pitch in λ/D.
  int r = 2;
  double pixel_lod = 0.0;
  // PSF side in pixels, 8..4096; the field must fit in the pupil grid's period of pupil_px λ/D.
  int size = 128;
  // Closed loop only: the wavefront sensor, the recorded time and the unrecorded settling time before it
  // [s], and the atmosphere and noise seed.
  SensorKind sensor = SensorKind::kDiffractive;
  double exposure_s = 0.5;
  double settling_s = 0.1;
  std::uint64_t seed = 1;
  // Closed loop only: run the loop on the atmosphere and on its negation (same seed) and average the two PSFs,
  // as a scene does by default (scene_spec.hpp, AoSpec::antithetic). The stretch's random tip/tilt is odd in
  // the atmosphere and cancels, so the core centroid shows the sensor's and the offsets' own tilt; Strehl and
  // halo are even and stay. false: one realisation (half the time).
  bool antithetic = true;
  // Direction of the science target from the guide star [rad] (x along columns, y along rows); finite, |theta|
  // <= 0.01 rad (34'). Default on axis. `aosr psf --field-angle A` is (A arcsec, 0).
  FieldDirection field_direction;

  bool IsValid(std::string* why) const;
};

struct PresetPsf {
  Image psf;               // size x size, centred (image.hpp), the whole focal plane sums to 1
  std::string mode;        // the mode used
  PsfSampling sampling;    // wavelength, pixel pitch, size
  double lambda_over_d_px = 0.0;  // λ/D in pixels
  double strehl = 0.0;
  double fwhm_px = 0.0;
  // The core's elongation (optics/psf_metrics.hpp): major and minor FWHM [px], their ratio (>= 1) and the
  // major axis' angle from +x toward +y [deg, (-90, 90]]; off axis the core stretches along the line to the
  // guide star.
  double fwhm_major_px = 0.0, fwhm_minor_px = 0.0, elongation = 1.0, major_axis_angle_deg = 0.0;
  FieldDirection field_direction;  // as requested [rad]
  // Fried's isoplanatic angle at the science wavelength (ao/anisoplanatism.hpp) [rad]; 0 without atmosphere,
  // +inf with all the turbulence at the ground.
  double isoplanatic_angle_rad = 0.0;
  double window_sum = 0.0;        // light inside the window
  double residual_rms_nm = 0.0;   // AO residual (analytic, closed loop); 0 for diffraction
  std::vector<double> encircled_energy;  // at 1, 2 and 5 λ/D, fraction of the window
  // Where the core lands: the core centroid (optics/psf_metrics.hpp, radius 2 λ/D) from the optical axis
  // (pixel (size/2, size/2)), in λ/D, (y, x). 0 for an aberration-free PSF; a closed loop whose sensor holds a
  // tilt shows it here (issue 23's Shack-Hartmann bias was 0.13, 0.17).
  double core_centroid_lod[2] = {0.0, 0.0};
  std::string loop_report;        // closed loop: the loop's BriefReport (each run's, antithetic)
};

// InvalidArgument (naming the option) for a bad option or a mode the preset cannot run; NumericalError if the
// PSF comes out empty or non-finite. `progress`, when set, gets one line per long step.
PresetPsf ComputePresetPsf(const TelescopePreset& preset, const PresetPsfOptions& options,
                           const std::function<void(const std::string&)>& progress = {});

// The largest PSF side whose field fits in the pupil grid's period (n λ/D for an n-pixel pupil) at the
// options' pixel pitch: larger `size` would show aliased copies of the PSF.
int MaxPresetPsfSize(const TelescopePreset& preset, const PresetPsfOptions& options);

// Whether a PSF at `direction` from the guide star can be computed in `mode` ("analytic" | "closed-loop" |
// "diffraction"): "" when it can, else the allowed range ("at most ... arcsec from the guide star in analytic
// mode (...)"), for an error message naming the caller's field. Analytic: the PSD grid's largest padding must
// resolve the anisoplanatism filter of the highest layer; closed loop: the phase screens' margin.
std::string FieldDirectionLimit(const TelescopePreset& preset, const std::string& mode, FieldDirection direction);

// The preset's analytic AO options (TelescopePreset::ToAnalyticAo) for a science target at `direction` from
// the guide star: field_direction set and the PSD grid's padding raised so that it resolves the
// anisoplanatism filter (h |θ| <= K D / 4, analytic_ao.hpp). InvalidArgument naming `function` and `field`
// when FieldDirectionLimit refuses the direction. On axis: ToAnalyticAo() unchanged.
AnalyticAoOptions AnalyticAoAt(const TelescopePreset& preset, FieldDirection direction, const char* function,
                               const std::string& field);

// "ideal" | "geometric" | "diffractive"; InvalidArgument otherwise.
SensorKind ParseSensorKind(const std::string& name);

}  // namespace aosr
