#include "aosr/ao/ao_system.hpp"

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

}  // namespace aosr
