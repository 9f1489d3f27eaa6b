#include "aosr/ao/ao_system.hpp"

#include <algorithm>
#include <cmath>

#include "aosr/core/error.hpp"

namespace aosr {

std::unique_ptr<ClosedLoop> AoSystem::MakeLoop(const ClosedLoopOptions& options) {
  return std::make_unique<ClosedLoop>(amplitude, diameter_m, atmosphere.get(), dm, wfs.get(), controller.get(),
                                      options);
}

AoSystem BuildAoSystem(const AoSystemSpec& spec) {
  CheckArgument(spec.amplitude.rows() == spec.amplitude.cols() && spec.amplitude.size() > 0, "BuildAoSystem",
                "spec.amplitude shape", ToString(ShapeOf(spec.amplitude)), "a non-empty square pupil grid");
  const Index n = spec.amplitude.rows();
  AoSystem s;
  s.amplitude = spec.amplitude;
  s.diameter_m = spec.diameter_m;
  // The mirror is centred on the pupil; its active actuators are selected by the circular outline.
  const PupilGeometry outline{spec.diameter_m, 0.0};
  s.dm = std::make_shared<const DeformableMirror>(n, outline, spec.dm);
  if (spec.atmosphere) s.atmosphere = std::make_unique<Atmosphere>(*spec.atmosphere, n, spec.diameter_m);
  if (spec.sensor == SensorKind::kIdeal) {
    s.wfs = std::make_unique<IdealWavefrontSensor>(s.dm, s.amplitude);
  } else {
    ShackHartmannOptions wfs = spec.wfs;
    wfs.mode = spec.sensor == SensorKind::kGeometric ? ShackHartmannMode::kGeometric : ShackHartmannMode::kDiffractive;
    wfs.noise.frame_time_s = spec.control.frame_time_s();
    s.wfs = std::make_unique<ShackHartmann>(s.amplitude, spec.diameter_m, wfs);
  }
  s.interaction_matrix = MeasureInteractionMatrix(*s.dm, s.wfs.get());
  s.control_matrix = ComputeControlMatrix(s.interaction_matrix, spec.control_matrix);
  s.controller = std::make_unique<Controller>(s.control_matrix.matrix, s.interaction_matrix, spec.control);
  return s;
}

namespace {
// Time between the turbulence samples [s]: 10 to 50 cm of frozen flow at 5 to 25 m/s, about a lenslet.
constexpr double kWfsNoiseSampleSpacingS = 0.02;
}  // namespace

double MeasureWfsNoiseRad2(AoSystem& system, double wavelength_m, int samples) {
  CheckArgument(system.wfs && system.dm, "MeasureWfsNoiseRad2", "system", std::string("(incomplete)"),
                "a built AoSystem");
  CheckArgument(wavelength_m > 0 && std::isfinite(wavelength_m), "MeasureWfsNoiseRad2", "wavelength_m", wavelength_m,
                "> 0 and finite");
  CheckArgument(samples >= 1, "MeasureWfsNoiseRad2", "samples", samples, ">= 1");
  const Index n = system.amplitude.rows();
  // The wavefronts the sensor sees: flat, or with turbulence what the mirror cannot fit (the fitting
  // residual, which sets the spots' width), a new stretch of the frozen flow for every sample.
  std::unique_ptr<DmFitter> fitter;
  if (system.atmosphere) fitter = std::make_unique<DmFitter>(system.dm, system.amplitude);
  Image wavefront = Image::Zero(n, n);
  Vector clean(system.wfs->n_measurements()), noisy(system.wfs->n_measurements());
  const double sum_a = system.amplitude.sum();
  const double k = 2.0 * M_PI / wavelength_m;
  double variance = 0.0;
  for (int i = 0; i < samples; ++i) {
    if (fitter) wavefront = fitter->Residual(system.atmosphere->Opd(kWfsNoiseSampleSpacingS * i));
    if (fitter || i == 0) system.wfs->MeasureNoiseless(wavefront, clean);  // the flat's once
    system.wfs->Measure(wavefront, noisy);
    const Vector commands = system.control_matrix.matrix * (noisy - clean);
    const Image opd = system.dm->Opd(commands);
    // Amplitude-weighted, piston removed: as the closed loop's residual (closed_loop.cpp).
    const double mean = (system.amplitude.array() * opd.array()).sum() / sum_a;
    const double s2 = (system.amplitude.array() * opd.array().square()).sum() / sum_a;
    variance += std::max(0.0, s2 - mean * mean);
  }
  return k * k * variance / samples;
}

}  // namespace aosr
