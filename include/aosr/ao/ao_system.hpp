// One place that assembles and calibrates a closed-loop AO system from its parts' options:
// pupil, deformable mirror, atmosphere (optional), wavefront sensor (ideal or Shack-Hartmann), interaction
// matrix, control matrix and controller. Tests, benchmarks and the CLI all build their loops here, so
// "the paper's system" means the same thing everywhere.
#pragma once

#include <memory>
#include <optional>

#include "aosr/ao/atmosphere.hpp"
#include "aosr/ao/closed_loop.hpp"
#include "aosr/ao/control.hpp"
#include "aosr/ao/shack_hartmann.hpp"
#include "aosr/ao/wavefront_sensor.hpp"
#include "aosr/optics/deformable_mirror.hpp"

namespace aosr {

enum class SensorKind {
  kIdeal,        // the residual least-squares fitted onto the DM (no aliasing, no noise): wavefront_sensor.hpp
  kGeometric,    // Shack-Hartmann, mean-gradient slopes
  kDiffractive,  // Shack-Hartmann, lenslet spot images and centre of gravity
};

struct AoSystemSpec {
  Image amplitude;                              // n x n pupil amplitude spanning diameter_m
  double diameter_m = 8.0;
  DeformableMirrorOptions dm;
  std::optional<AtmosphereOptions> atmosphere;  // none: no turbulence
  SensorKind sensor = SensorKind::kDiffractive;
  ShackHartmannOptions wfs;                     // used unless sensor == kIdeal (mode set from `sensor`)
  ControllerOptions control;
  ControlMatrixOptions control_matrix;
};

struct AoSystem {
  Image amplitude;
  double diameter_m = 0;
  DeformableMirrorPtr dm;
  std::unique_ptr<Atmosphere> atmosphere;  // null without turbulence
  std::unique_ptr<WavefrontSensor> wfs;
  Eigen::MatrixXd interaction_matrix;
  ControlMatrix control_matrix;
  std::unique_ptr<Controller> controller;

  // A closed loop over this system's parts (which must outlive it).
  std::unique_ptr<ClosedLoop> MakeLoop(const ClosedLoopOptions& options);
};

// Builds and calibrates (push-pull interaction matrix, SVD control matrix). Throws InvalidArgument naming the
// bad field of any part's options.
AoSystem BuildAoSystem(const AoSystemSpec& spec);

// The WFS noise as the loop's reconstructor sees it: the variance [rad² at wavelength_m] of the wavefront one
// frame's measurement noise alone puts on the DM, i.e. the noisy minus the noise-free measurement of the same
// wavefront, through the control matrix onto the mirror, piston removed, amplitude-weighted over the pupil and
// averaged over `samples` frames (>= 1). This is AnalyticAoOptions::wfs_noise_rad2 (analytic_ao.hpp): the
// analytic model's noise term for this very sensor, centroid algorithm and reconstructor, where a formula
// (e.g. Rousset's centroid variances times a noise-propagation coefficient) would only approximate them.
// 0 for a noiseless sensor. The wavefront: flat without turbulence (the system's atmosphere is null); with it,
// the atmosphere's fitting residual (what the mirror cannot fit) at a new time each sample, so that the spots
// have the width a closed loop leaves them. The loop's own servo, aliasing and noise residual widen them
// further, so at faint guide stars this stays a lower bound (bench/results/psf_knowledge.md). Checked against
// a closed loop's noise-driven residual in tests/ao/closed_loop_physics_test.cpp. Advances the sensor's noise
// generator and the atmosphere's screens.
double MeasureWfsNoiseRad2(AoSystem& system, double wavelength_m, int samples = 200);

}  // namespace aosr
