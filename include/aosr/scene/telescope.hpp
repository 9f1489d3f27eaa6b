// Telescope presets: one JSON file per system in data/telescopes/ (documented in data/README.md).
//
// A preset says what the telescope, the science camera, the atmosphere (optional) and the AO system
// (optional) are. Everything is SI once loaded: metres, radians, seconds. Camera pixel scale may be given
// as `camera_pixel_lambda_over_d` (in units of λ/D at the science wavelength), `camera_pixel_mas`, or, for
// a bench, `camera_pixel_m` with the telescope's `focal_length_m`.
#pragma once

#include <cstdint>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>

#include "aosr/ao/analytic_ao.hpp"
#include "aosr/ao/ao_system.hpp"
#include "aosr/ao/atmosphere.hpp"
#include "aosr/optics/aperture.hpp"
#include "aosr/optics/deformable_mirror.hpp"

namespace aosr {

struct WfsPreset {
  int lenslets_across = 16;
  double wavelength_m = 640e-9;
  double guide_star_magnitude = 8.0;  // in the WFS band (Vega magnitudes)
  double throughput = 0.5;            // telescope + WFS optics + detector QE, in (0, 1]
  double pixel_scale_lod = 0.5;       // spot-image pixel in λ_wfs / d_sub (0.5 = Nyquist)
  int field_of_view_px = 16;          // spot-image side in pixels (16 px at Nyquist = 8 λ/d)
  bool photon_noise = false;          // Poisson noise from the guide-star flux
  double read_noise_e = 0.0;          // e- RMS per spot pixel
};

struct LoopPreset {
  double rate_hz = 800.0;
  double gain = 0.35;
  double delay_frames = 1.0;      // read-out + compute delay after WFS integration (analytic_ao.hpp)
  std::string control = "pol";    // "integrator" or "pol" (pseudo-open-loop)
};

struct AoPreset {
  DeformableMirrorOptions dm;  // pitch set from the diameter: D / (actuators_across - 1), Fried geometry
  WfsPreset wfs;
  LoopPreset loop;
};

struct TelescopePreset {
  std::string name;
  std::string source;           // the file it came from
  ApertureGeometry aperture;
  // Optional transmission mask file (FITS/PNG/TIFF, values in [0, 1], spanning the diameter), relative paths
  // resolved against the preset's folder. When set it replaces the geometric aperture.
  std::string mask_file;
  Index pupil_px = 128;
  double science_wavelength_m = 2.2e-6;
  double camera_pixel_rad = 0;  // angular pitch of one camera pixel
  std::optional<AtmosphereOptions> atmosphere;  // none: no turbulence
  std::optional<AoPreset> ao;                   // none: no AO

  // The pupil amplitude on the pupil_px grid: the mask file resampled (area-weighted), or the geometry.
  Image PupilAmplitude() const;
  double LambdaOverD() const { return science_wavelength_m / aperture.pupil.diameter_m; }
  // The analytic long-exposure AO model of this system (requires atmosphere and ao). When the WFS is noisy
  // (photon_noise or read_noise_e > 0) its noise term wfs_noise_rad2 is measured through the diffractive
  // Shack-Hartmann and the reconstructor of ToAoSystemSpec (MeasureWfsNoiseRad2, kWfsNoiseSamples frames of a
  // fixed seed: the same value every call; ~1 s); else 0 (a bright guide star).
  AnalyticAoOptions ToAnalyticAo() const;
  // 200 frames of ~250 independently noisy mirror modes: a relative sampling error of ~sqrt(2 / 5e4) = 0.6 %.
  static constexpr int kWfsNoiseSamples = 200;
  static constexpr std::uint64_t kWfsNoiseSeed = 1;
  // The closed-loop system of this preset (requires ao; the atmosphere is optional) with the given sensor
  // model and atmosphere seed.
  AoSystemSpec ToAoSystemSpec(SensorKind sensor, std::uint64_t seed) const;
};

// The data folder: $AOSR_DATA_DIR if set, else the default: the source tree's data/ (compiled in) unless
// SetDefaultDataDirectory changed it.
std::string DataDirectory();
// Replaces the default data folder (not $AOSR_DATA_DIR, which still wins): the installed Python package, which
// ships its own copy of data/, points the library at it. Thread-safe.
void SetDefaultDataDirectory(const std::string& dir);

// Loads `name_or_path`: a path to a .json file, or a preset name looked up as
// DataDirectory()/telescopes/<name>.json. Errors name the file and the field.
TelescopePreset LoadTelescopePreset(const std::string& name_or_path);

// Parses a preset from an already-read JSON object (`source` names it in messages).
TelescopePreset ParseTelescopePreset(const nlohmann::json& json, const std::string& source);

}  // namespace aosr
