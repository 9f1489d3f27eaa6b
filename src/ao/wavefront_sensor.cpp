#include "aosr/ao/wavefront_sensor.hpp"

#include <utility>

#include "aosr/core/error.hpp"

namespace aosr {

WavefrontSensor::WavefrontSensor(Index pupil_n, Index n_measurements)
    : pupil_n_(pupil_n),
      n_measurements_(n_measurements),
      reference_(Vector::Zero(n_measurements)),
      offset_(Vector::Zero(n_measurements)) {}

void WavefrontSensor::CalibrateReference() {
  const Image flat = Image::Zero(pupil_n_, pupil_n_);
  Vector raw(n_measurements_);
  MeasureRaw(flat, /*noisy=*/false, raw);
  reference_ = raw;
}

void WavefrontSensor::MeasureChecked(const Image& opd_m, bool noisy, Eigen::Ref<Vector> out,
                                     const char* function) {
  CheckArgument(opd_m.rows() == pupil_n_ && opd_m.cols() == pupil_n_, function, "opd_m shape",
                ToString(ShapeOf(opd_m)), ToString(Shape{pupil_n_, pupil_n_}) + " (the sensor's pupil grid)");
  CheckArgument(out.size() == n_measurements_, function, "measurement size", out.size(),
                std::to_string(n_measurements_) + " (n_measurements())");
  MeasureRaw(opd_m, noisy, out);
  if (!out.allFinite()) {
    throw InvalidArgument(function, "opd_m", "a value that makes the measurement non-finite",
                          "finite values where the pupil transmits");
  }
  out -= reference_;
  out -= offset_;
}

void WavefrontSensor::Measure(const Image& opd_m, Eigen::Ref<Vector> measurement) {
  MeasureChecked(opd_m, /*noisy=*/true, measurement, "WavefrontSensor::Measure");
}

Vector WavefrontSensor::Measure(const Image& opd_m) {
  Vector m(n_measurements_);
  Measure(opd_m, m);
  return m;
}

void WavefrontSensor::MeasureNoiseless(const Image& opd_m, Eigen::Ref<Vector> measurement) {
  MeasureChecked(opd_m, /*noisy=*/false, measurement, "WavefrontSensor::MeasureNoiseless");
}

Vector WavefrontSensor::MeasureNoiseless(const Image& opd_m) {
  Vector m(n_measurements_);
  MeasureNoiseless(opd_m, m);
  return m;
}

void WavefrontSensor::SetReferenceOffset(const Eigen::Ref<const Vector>& offset) {
  CheckArgument(offset.size() == n_measurements_, "WavefrontSensor::SetReferenceOffset", "offset size",
                offset.size(), std::to_string(n_measurements_) + " (n_measurements())");
  CheckArgument(offset.allFinite(), "WavefrontSensor::SetReferenceOffset", "offset", "non-finite values",
                "finite values");
  offset_ = offset;
}

Vector WavefrontSensor::ReferenceOffsetForOpd(const Image& opd_m) {
  Vector raw(n_measurements_);
  const char* fn = "WavefrontSensor::ReferenceOffsetForOpd";
  CheckArgument(opd_m.rows() == pupil_n_ && opd_m.cols() == pupil_n_, fn, "opd_m shape",
                ToString(ShapeOf(opd_m)), ToString(Shape{pupil_n_, pupil_n_}) + " (the sensor's pupil grid)");
  MeasureRaw(opd_m, /*noisy=*/false, raw);
  if (!raw.allFinite()) {
    throw InvalidArgument(fn, "opd_m", "a value that makes the measurement non-finite",
                          "finite values where the pupil transmits");
  }
  return raw - reference_;
}

namespace {

DeformableMirrorPtr CheckedMirror(DeformableMirrorPtr dm, const Image& amplitude) {
  const char* fn = "IdealWavefrontSensor";
  CheckArgument(dm != nullptr, fn, "dm", "null", "a deformable mirror");
  CheckArgument(amplitude.rows() == dm->pupil_n() && amplitude.cols() == dm->pupil_n(), fn, "amplitude shape",
                ToString(ShapeOf(amplitude)),
                ToString(Shape{dm->pupil_n(), dm->pupil_n()}) + " (the mirror's pupil grid)");
  return dm;
}

}  // namespace

IdealWavefrontSensor::IdealWavefrontSensor(DeformableMirrorPtr dm, const Image& amplitude,
                                           const DmFitOptions& fit)
    : WavefrontSensor(CheckedMirror(dm, amplitude)->pupil_n(), CheckedMirror(dm, amplitude)->n_active()),
      fitter_(std::move(dm), amplitude, fit) {
  CalibrateReference();
}

std::string IdealWavefrontSensor::Describe() const {
  return "ideal WFS: least-squares projection of the residual onto " +
         std::to_string(fitter_.mirror().n_active()) + " DM actuators";
}

void IdealWavefrontSensor::MeasureRaw(const Image& opd_m, bool /*noisy*/, Eigen::Ref<Vector> raw) {
  raw = fitter_.Fit(opd_m);
}

}  // namespace aosr
