// Test support for the closed-loop tests: the paper's AO system (8 m, 16 x 16 SH at 640 nm, 17 x 17 Fried DM,
// 800 Hz, three layers at 0 / 4 / 10 km with 0.70 / 0.25 / 0.05 of the turbulence, r0 = 0.15 m at 550 nm,
// L0 = 30 m, winds 5 / 10 / 25 m/s, K-band science) built and calibrated in one call, and the matching
// analytic-AO options.
#pragma once

#include <cstdint>
#include <memory>

#include "aosr/core/image.hpp"  // kPi
#include "aosr/ao/analytic_ao.hpp"
#include "aosr/ao/ao_system.hpp"
#include "aosr/ao/atmosphere.hpp"
#include "aosr/ao/closed_loop.hpp"
#include "aosr/ao/control.hpp"
#include "aosr/ao/shack_hartmann.hpp"
#include "aosr/ao/wavefront_sensor.hpp"
#include "aosr/optics/deformable_mirror.hpp"
#include "aosr/optics/pupil.hpp"

namespace aosr::test {

constexpr double kPaperDiameter = 8.0;


inline AtmosphereOptions PaperAtmosphere(std::uint64_t seed) {
  AtmosphereOptions o;
  o.r0_m = 0.15;
  o.r0_wavelength_m = 550e-9;
  o.L0_m = 30.0;
  o.seed = seed;
  o.layers = {{0.0, 0.70, 5.0, 0.0}, {4000.0, 0.25, 10.0, 0.5 * kPi}, {10000.0, 0.05, 25.0, 0.25 * kPi}};
  return o;
}

inline AnalyticAoOptions PaperAnalytic(const ControllerOptions& control, bool aliasing) {
  AnalyticAoOptions a;
  a.diameter_m = kPaperDiameter;
  a.actuator_pitch_m = 0.5;
  a.control_domain = ControlDomain::kSquare;
  const AtmosphereOptions atm = PaperAtmosphere(1);
  a.r0_m = atm.r0_m;
  a.reference_wavelength_m = atm.r0_wavelength_m;
  a.outer_scale_m = atm.L0_m;
  a.layers = atm.layers;
  a.loop_rate_hz = control.loop_rate_hz;
  a.loop_gain = control.gain;
  a.loop_delay_frames = control.delay_frames;
  a.wfs_noise_rad2 = 0.0;
  a.aliasing = aliasing;
  a.science_wavelength_m = 2.2e-6;
  return a;
}

inline ShackHartmannOptions PaperSensor(ShackHartmannMode mode) {
  ShackHartmannOptions o;
  o.subapertures_across = 16;
  o.mode = mode;
  o.wavelength_m = 640e-9;
  o.pixel_scale_lod = 0.5;
  o.field_of_view_px = 16;
  return o;
}

using LoopSystem = AoSystem;
using aosr::SensorKind;

// The paper's system on an n-pixel pupil (n divisible by 16), calibrated; turbulence when `turbulence`.
inline LoopSystem MakePaperSystem(SensorKind kind, bool turbulence, std::uint64_t seed,
                                  const ControllerOptions& control, Index n = 128) {
  AoSystemSpec spec;
  spec.amplitude = CircularPupil(n, PupilGeometry{kPaperDiameter, 0.0});
  spec.diameter_m = kPaperDiameter;
  spec.dm.actuators_across = 17;
  spec.dm.pitch_m = 0.5;
  if (turbulence) spec.atmosphere = PaperAtmosphere(seed);
  spec.sensor = kind;
  spec.wfs = PaperSensor(kind == SensorKind::kGeometric ? ShackHartmannMode::kGeometric : ShackHartmannMode::kDiffractive);
  spec.control = control;
  return BuildAoSystem(spec);
}

inline ClosedLoopOptions KBandScience(int psf_every = 1) {
  ClosedLoopOptions o;
  o.science = {2.2e-6, 2.2e-6 / (2.0 * kPaperDiameter), 128, 128};
  o.psf_every_steps = psf_every;
  return o;
}

}  // namespace aosr::test
