#include "aosr/ao/control.hpp"

#include <Eigen/SVD>
#include <cmath>
#include <cstdio>

#include "aosr/ao/analytic_ao.hpp"
#include "aosr/core/error.hpp"

namespace aosr {
namespace {


}  // namespace

bool InteractionMatrixOptions::IsValid(std::string* why) const {
  if (!(std::isfinite(poke_amplitude_m) && poke_amplitude_m > 0.0)) {
    return Fail(why, "poke_amplitude_m = " + ToString(poke_amplitude_m) + "; allowed: > 0 and finite [m]");
  }
  return true;
}

Eigen::MatrixXd MeasureInteractionMatrix(const DeformableMirror& dm, WavefrontSensor* wfs,
                                         const InteractionMatrixOptions& options) {
  const char* fn = "MeasureInteractionMatrix";
  std::string why;
  if (!options.IsValid(&why)) throw InvalidArgument(std::string(fn) + ": invalid options." + why);
  CheckArgument(wfs != nullptr, fn, "wfs", "null", "a wavefront sensor");
  CheckArgument(wfs->pupil_n() == dm.pupil_n(), fn, "wfs pupil grid", wfs->pupil_n(),
                "the mirror's pupil grid n = " + std::to_string(dm.pupil_n()));
  const Index n_act = dm.n_active();
  const Index n_meas = wfs->n_measurements();
  const double a = options.poke_amplitude_m;
  Eigen::MatrixXd im(n_meas, n_act);
  Vector commands = Vector::Zero(n_act);
  Image opd(dm.pupil_n(), dm.pupil_n());
  Vector plus(n_meas), minus(n_meas);
  for (Index j = 0; j < n_act; ++j) {
    commands[j] = a;
    dm.Apply(commands, AsVector(opd));
    wfs->MeasureNoiseless(opd, plus);
    commands[j] = -a;
    dm.Apply(commands, AsVector(opd));
    wfs->MeasureNoiseless(opd, minus);
    commands[j] = 0.0;
    im.col(j) = (plus - minus) / (2.0 * a);
  }
  return im;
}

bool ControlMatrixOptions::IsValid(std::string* why) const {
  if (method != Method::kTruncatedSvd && method != Method::kTikhonov) {
    return Fail(why,
                "method = " + ToString(static_cast<int>(method)) + "; allowed: kTruncatedSvd or kTikhonov");
  }
  if (!(relative_threshold >= 0.0 && relative_threshold < 1.0)) {
    return Fail(why, "relative_threshold = " + ToString(relative_threshold) +
                         "; allowed: [0, 1) (fraction of the largest singular value)");
  }
  if (modes_to_cut < -1) {
    return Fail(
        why, "modes_to_cut = " + ToString(modes_to_cut) + "; allowed: -1 (use relative_threshold) or >= 0");
  }
  if (!(std::isfinite(tikhonov_alpha) && tikhonov_alpha >= 0.0)) {
    return Fail(why, "tikhonov_alpha = " + ToString(tikhonov_alpha) + "; allowed: >= 0 and finite");
  }
  return true;
}

std::string ControlMatrix::BriefReport() const {
  char buf[256];
  const double s1 = singular_values.size() > 0 ? singular_values[0] : 0.0;
  const double smin = singular_values.size() > 0 ? singular_values[singular_values.size() - 1] : 0.0;
  std::snprintf(buf, sizeof(buf),
                "control matrix: %ld x %ld, %d modes kept, %d cut, condition number %.4g (s: %.4g .. %.4g)",
                static_cast<long>(matrix.rows()), static_cast<long>(matrix.cols()), modes_kept, modes_cut,
                condition_number, s1, smin);
  return buf;
}

ControlMatrix ComputeControlMatrix(const Eigen::MatrixXd& interaction_matrix,
                                   const ControlMatrixOptions& options) {
  const char* fn = "ComputeControlMatrix";
  std::string why;
  if (!options.IsValid(&why)) throw InvalidArgument(std::string(fn) + ": invalid options." + why);
  CheckArgument(interaction_matrix.size() > 0, fn, "interaction_matrix", "empty", "a non-empty matrix");
  CheckArgument(interaction_matrix.allFinite(), fn, "interaction_matrix", "non-finite values",
                "finite values");
  const Index rank_max = std::min(interaction_matrix.rows(), interaction_matrix.cols());
  if (options.modes_to_cut >= 0) {
    CheckArgument(options.modes_to_cut < rank_max, fn, "options.modes_to_cut", options.modes_to_cut,
                  "0 .. " + std::to_string(rank_max - 1) + " (min(n_meas, n_act) - 1)");
  }
  Eigen::BDCSVD<Eigen::MatrixXd> svd(interaction_matrix, Eigen::ComputeThinU | Eigen::ComputeThinV);
  const Vector& s = svd.singularValues();
  CheckArgument(s[0] > 0.0, fn, "interaction_matrix", "all zero", "a matrix with a non-zero singular value");
  Vector filter = Vector::Zero(rank_max);
  ControlMatrix out;
  out.singular_values = s;
  int kept = 0;
  double smallest_kept = s[0];
  if (options.method == ControlMatrixOptions::Method::kTruncatedSvd) {
    const Index keep = options.modes_to_cut >= 0 ? rank_max - options.modes_to_cut : rank_max;
    for (Index i = 0; i < keep; ++i) {
      if (options.modes_to_cut < 0 && s[i] < options.relative_threshold * s[0]) break;
      if (!(s[i] > 0.0)) break;  // an exactly singular mode cannot be inverted
      filter[i] = 1.0 / s[i];
      smallest_kept = s[i];
      ++kept;
    }
  } else {
    const double alpha2 = std::pow(options.tikhonov_alpha * s[0], 2);
    for (Index i = 0; i < rank_max; ++i) {
      filter[i] = s[i] / (s[i] * s[i] + alpha2);
      if (s[i] >= options.tikhonov_alpha * s[0]) {
        smallest_kept = s[i];
        ++kept;
      }
    }
  }
  out.matrix = svd.matrixV() * filter.asDiagonal() * svd.matrixU().transpose();
  out.modes_kept = kept;
  out.modes_cut = static_cast<int>(rank_max) - kept;
  out.condition_number = s[0] / smallest_kept;
  return out;
}

bool ControllerOptions::IsValid(std::string* why) const {
  if (!(std::isfinite(loop_rate_hz) && loop_rate_hz > 0.0)) {
    return Fail(why, "loop_rate_hz = " + ToString(loop_rate_hz) + "; allowed: > 0 and finite [Hz]");
  }
  if (delay_frames < 0 || delay_frames > 100) {
    return Fail(why, "delay_frames = " + ToString(delay_frames) + "; allowed: 0 .. 100 [frames]");
  }
  if (law != ControlLaw::kIntegrator && law != ControlLaw::kPseudoOpenLoop) {
    return Fail(why,
                "law = " + ToString(static_cast<int>(law)) + "; allowed: kIntegrator or kPseudoOpenLoop");
  }
  if (!(leak >= 0.0 && leak < 1.0)) {
    return Fail(why, "leak = " + ToString(leak) + "; allowed: [0, 1)");
  }
  if (!(std::isfinite(gain) && gain >= 0.0)) {
    return Fail(why, "gain = " + ToString(gain) + "; allowed: >= 0 and finite");
  }
  if (law == ControlLaw::kPseudoOpenLoop && !(gain < 2.0)) {
    return Fail(why, "gain = " + ToString(gain) + "; allowed: [0, 2) for kPseudoOpenLoop");
  }
  if (law == ControlLaw::kIntegrator && gain > 0.0 &&
      !(AnalyticAoLoopSpectralRadius(gain, static_cast<double>(delay_frames)) < 1.0)) {
    return Fail(why, "gain = " + ToString(gain) +
                         "; allowed: a gain for which the integrator with delay_frames = " +
                         std::to_string(delay_frames) +
                         " is stable (closed-loop poles inside the unit circle; g < 1 for one frame)");
  }
  return true;
}

DelayLine::DelayLine(Index size, int delay) : size_(size), delay_(delay) {
  CheckArgument(size >= 0, "DelayLine", "size", size, ">= 0");
  CheckArgument(delay >= 0, "DelayLine", "delay", delay, ">= 0 [frames]");
  slots_.assign(static_cast<std::size_t>(delay) + 1, Vector::Zero(size));
}

const Vector& DelayLine::Push(const Eigen::Ref<const Vector>& u) {
  CheckArgument(u.size() == size_, "DelayLine::Push", "u size", u.size(), std::to_string(size_));
  const int length = delay_ + 1;
  slots_[head_] = u;
  const int oldest = (head_ + 1) % length;  // written `delay_` pushes ago (== head_ when delay_ = 0)
  head_ = oldest;
  return slots_[oldest];
}

void DelayLine::Reset(const Eigen::Ref<const Vector>& value) {
  CheckArgument(value.size() == size_, "DelayLine::Reset", "value size", value.size(), std::to_string(size_));
  for (Vector& v : slots_) v = value;
  head_ = 0;
}

namespace {

const ControllerOptions& CheckedControllerOptions(const Eigen::MatrixXd& cm, const Eigen::MatrixXd& im,
                                                  const ControllerOptions& options) {
  const char* fn = "Controller";
  std::string why;
  if (!options.IsValid(&why)) throw InvalidArgument(std::string(fn) + ": invalid options." + why);
  CheckArgument(cm.size() > 0, fn, "control_matrix", "empty", "an n_act x n_meas matrix");
  CheckArgument(cm.allFinite(), fn, "control_matrix", "non-finite values", "finite values");
  if (options.law == ControlLaw::kPseudoOpenLoop) {
    CheckArgument(im.rows() == cm.cols() && im.cols() == cm.rows(), fn, "interaction_matrix shape",
                  ToString(Shape{im.rows(), im.cols()}),
                  ToString(Shape{cm.cols(), cm.rows()}) + " (n_meas x n_act) for kPseudoOpenLoop");
    CheckArgument(im.allFinite(), fn, "interaction_matrix", "non-finite values", "finite values");
  }
  return options;
}

}  // namespace

Controller::Controller(const Eigen::MatrixXd& control_matrix, const Eigen::MatrixXd& interaction_matrix,
                       const ControllerOptions& options)
    : options_(CheckedControllerOptions(control_matrix, interaction_matrix, options)),
      control_matrix_(control_matrix),
      interaction_matrix_(options.law == ControlLaw::kPseudoOpenLoop ? interaction_matrix
                                                                     : Eigen::MatrixXd()),
      state_(Vector::Zero(control_matrix.rows())),
      applied_(Vector::Zero(control_matrix.rows())),
      scratch_meas_(control_matrix.cols()),
      scratch_cmd_(control_matrix.rows()),
      delay_line_(control_matrix.rows(), options.delay_frames) {}

const Vector& Controller::Update(const Eigen::Ref<const Vector>& measurement) {
  const char* fn = "Controller::Update";
  CheckArgument(measurement.size() == n_measurements(), fn, "measurement size", measurement.size(),
                std::to_string(n_measurements()) + " (the control matrix's columns)");
  CheckArgument(measurement.allFinite(), fn, "measurement", "non-finite values", "finite values");
  const double g = options_.gain;
  if (options_.law == ControlLaw::kIntegrator) {
    scratch_cmd_.noalias() = control_matrix_ * measurement;
    state_ = (1.0 - options_.leak) * state_ - g * scratch_cmd_;
  } else {
    // m_ol = m - D c_n; u <- (1 - g) u + g (-M m_ol).
    scratch_meas_ = measurement;
    scratch_meas_.noalias() -= interaction_matrix_ * applied_;
    scratch_cmd_.noalias() = control_matrix_ * scratch_meas_;
    state_ = (1.0 - g) * state_ - g * scratch_cmd_;
  }
  applied_ = delay_line_.Push(state_);
  return applied_;
}

void Controller::Reset() { Reset(Vector::Zero(n_actuators())); }

void Controller::Reset(const Eigen::Ref<const Vector>& commands) {
  CheckArgument(commands.size() == n_actuators(), "Controller::Reset", "commands size", commands.size(),
                std::to_string(n_actuators()) + " (n_actuators())");
  CheckArgument(commands.allFinite(), "Controller::Reset", "commands", "non-finite values", "finite values");
  state_ = commands;
  applied_ = commands;
  delay_line_.Reset(commands);
}

void Controller::OverrideApplied(const Eigen::Ref<const Vector>& commands) {
  CheckArgument(commands.size() == n_actuators(), "Controller::OverrideApplied", "commands size",
                commands.size(), std::to_string(n_actuators()) + " (n_actuators())");
  applied_ = commands;
}

}  // namespace aosr
