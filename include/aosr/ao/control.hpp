// AO control: calibration (interaction matrix), reconstruction (control matrix by SVD) and the temporal
// controller (integrator or pseudo-open-loop integrator, with a pure loop delay).
//
// Sign convention. The DM's OPD ADDS to the turbulence: the sensor sees the residual r = phi + H c (phi: the
// turbulent/static OPD, H: DeformableMirror, c: the command on the mirror), so the loop must drive c toward
// -fit(phi). Measurements m are what WavefrontSensor::Measure returns (reference and offset removed).
//
// 1. Interaction matrix (push-pull). Column j of D (n_meas x n_act) is
//        D e_j = (m0(H (+a e_j)) - m0(H (-a e_j))) / (2 a),
//    m0 the sensor's noise-free measurement, a = poke_amplitude_m. Push-pull cancels the even orders of a
//    non-linear sensor (and any reference offset) exactly; for a linear sensor (the geometric SH) D equals
//    the product G H to rounding (tested).
//
// 2. Control matrix. With the SVD D = U S V^T (singular values s_1 >= s_2 >= ...), the reconstructor is
//        M = V F(S) U^T   (n_act x n_meas),   F: s -> 1/s on kept modes, 0 on cut ones        (kTruncatedSvd)
//                                             F: s -> s / (s^2 + (alpha s_1)^2)            (kTikhonov)
//    Truncation cuts either every mode with s_i < relative_threshold s_1, or exactly the modes_to_cut
//    smallest modes when modes_to_cut >= 0. In Fried geometry the SH cannot see piston or the waffle mode
//    (the checkerboard of actuators, whose mean gradients cancel in every subaperture): their singular values
//    are ~1e-3 .. 1e-6 of s_1 and must be cut, or they would be driven by noise without bound. The report
//    gives the modes cut and the condition number s_1 / s_min over the modes kept (for Tikhonov: over the
//    modes with s >= alpha s_1, which the filter passes at more than half gain).
//
// 3. Controller (discrete time; frame period T = 1 / loop_rate_hz). Frame n: the mirror holds c_n; the
//    sensor measures m_n of the residual phi_n + H c_n; at the end of the frame the controller updates its
//    state u (the "integrator", kept SEPARATE from what is on the mirror) and pushes it into a delay line of
//    k = delay_frames frames:
//        kIntegrator:      u_{n+1} = (1 - leak) u_n - g M m_n
//        kPseudoOpenLoop:  m_ol,n  = m_n - D c_n                 (pseudo-open-loop measurement: the sensor's
//                                                                 view of phi_n alone, since m_n = D(phi_n) +
//                                                                 D c_n for a linear sensor)
//                          u_{n+1} = (1 - g) u_n + g (-M m_ol,n)  (an integrator on the POL error: a
//                          first-order
//                                                                 low-pass of the open-loop reconstruction)
//        delay line:       c_{n+1+k} = u_{n+1}                   (c_1 .. c_k: zero, or the state at Reset)
//    so the command computed from frame n is on the mirror during frame n + k + 1: k = 0 means "applied in
//    the next frame", the fastest a sampled loop can be. Measuring at the frame centre, the lag from
//    measurement to correction is (k + 1) T on average, the convention of analytic_ao.hpp's
//    loop_delay_frames (its WFS averages over the frame and the DM holds for one: T/2 + k T + T/2); use the
//    same k in both to compare. Stability of the integrator with a perfect model (M D = I, leak 0): the
//    modes obey u_{n+1} = u_n - g u_{n-k} + (disturbance), whose poles are the roots of z^(k+1) - z^k + g,
//    those of AnalyticAoLoopSpectralRadius(g, k) (g < 1 for k = 1, g < 2 for k = 0);
//    ControllerOptions::IsValid rejects gains outside. POL with an exact D has no feedback at all (D c_n
//    cancels the mirror's own contribution), so it is stable for 0 <= g < 2 whatever k: it low-pass filters
//    an open-loop estimate.
//    With M D = I and k = 0 the POL law reduces to u_{n+1} = u_n - g M m_n: the plain integrator. The two
//    differ with delay (POL corrects for the k commands in flight, so it tolerates larger gains) and on the
//    modes the reconstructor cuts. The paper's "integrator/POL gain 0.35" is either law with g = 0.35.
//
// Cost (241 actuators, 416 slopes): Update ~0.03 ms (integrator, one n_act x n_meas product), ~0.06 ms (POL,
// two products). Calibration: 2 n_act sensor measurements; the SVD ~30 ms.
#pragma once

#include <string>
#include <vector>

#include "aosr/ao/wavefront_sensor.hpp"
#include "aosr/core/image.hpp"
#include "aosr/optics/deformable_mirror.hpp"

namespace aosr {

struct InteractionMatrixOptions {
  // Push-pull poke amplitude a [m of wavefront OPD at the actuator], > 0 and finite. Default 50 nm: a peak
  // phase of 0.5 rad at 640 nm, inside the linear range of a Nyquist-sampled diffractive SH yet far above
  // rounding (the geometric SH is linear and indifferent to it).
  double poke_amplitude_m = 50e-9;

  bool IsValid(std::string* why) const;
};

// Push-pull interaction matrix D (n_meas x n_act, measurement units per metre of command) of `dm` seen by
// `wfs` (noise-free; the sensor's reference offset cancels). The sensor's pupil grid must be the mirror's.
// Throws InvalidArgument naming the bad argument.
Eigen::MatrixXd MeasureInteractionMatrix(
    const DeformableMirror& dm, WavefrontSensor* wfs,
    const InteractionMatrixOptions& options = InteractionMatrixOptions());

struct ControlMatrixOptions {
  enum class Method {
    kTruncatedSvd,  // 1/s on kept modes, 0 on cut ones
    kTikhonov,      // s / (s^2 + (alpha s_1)^2) on all modes
  };
  // Default kTruncatedSvd: the usual choice for a well-conditioned SH/DM pair once the blind modes are cut.
  Method method = Method::kTruncatedSvd;
  // Truncation threshold relative to the largest singular value, in [0, 1). Used when modes_to_cut < 0.
  // Default 0.05: for the 16 x 16 SH / 17 x 17 Fried DM on 8 m it cuts exactly piston and waffle (s / s_1 =
  // 2.7e-3 and 1.5e-2; the next modes, weakly seen rim modes, sit at 7e-2; tests/ao/control_test.cpp).
  double relative_threshold = 0.05;
  // When >= 0, cut exactly this many of the smallest singular modes instead (0 .. min(n_meas, n_act) - 1).
  // Default -1: use relative_threshold.
  int modes_to_cut = -1;
  // Tikhonov weight alpha relative to s_1, >= 0 and finite (kTikhonov only). Default 0.05.
  double tikhonov_alpha = 0.05;

  bool IsValid(std::string* why) const;
};

struct ControlMatrix {
  Eigen::MatrixXd matrix;         // M, n_act x n_meas
  Vector singular_values;         // all singular values of D, descending
  int modes_kept = 0;             // modes passed (Tikhonov: s >= alpha s_1)
  int modes_cut = 0;              // min(n_meas, n_act) - modes_kept
  double condition_number = 0.0;  // s_1 / smallest kept s (over the kept modes)
  // e.g. "control matrix: 241 x 416, 239 modes kept, 2 cut, condition number 14.16 (s: 4.082 .. 0.01112)".
  std::string BriefReport() const;
};

// M from an interaction matrix (finite, non-empty). Throws InvalidArgument naming the bad argument or field.
ControlMatrix ComputeControlMatrix(const Eigen::MatrixXd& interaction_matrix,
                                   const ControlMatrixOptions& options = ControlMatrixOptions());

enum class ControlLaw {
  kIntegrator,      // u <- (1 - leak) u - g M m
  kPseudoOpenLoop,  // u <- (1 - g) u - g M (m - D c)
};

struct ControllerOptions {
  // Loop (frame) rate 1/T [Hz], > 0 and finite. Default 800 Hz, the paper's system.
  double loop_rate_hz = 800.0;
  // Gain g, >= 0 and finite; 0 freezes the commands (open loop). For kIntegrator the loop with a perfect
  // model must be stable for the delay (AnalyticAoLoopSpectralRadius < 1: g < 1 for k = 1); for
  // kPseudoOpenLoop g < 2. Default 0.35, the paper's integrator/POL gain.
  double gain = 0.35;
  // Integrator leak l in [0, 1) (kIntegrator only): u <- (1 - l) u - g M m. 0 (default) is a pure
  // integrator; ~1e-3 .. 1e-2 bleeds unseen modes away at the price of a small static error.
  double leak = 0.0;
  // Pure delay k [whole frames] between the end of a measurement frame and the frame in which its command
  // starts, 0 .. 100 (header section 3). Default 1: one frame of read-out and computation, i.e. a mean lag of
  // 2 T, analytic_ao.hpp's default.
  int delay_frames = 1;
  // Control law. Default kIntegrator.
  ControlLaw law = ControlLaw::kIntegrator;

  double frame_time_s() const { return 1.0 / loop_rate_hz; }
  bool IsValid(std::string* why) const;
};

// A first-in first-out line of `delay` command vectors: Push(u) returns the vector pushed `delay` calls ago
// (zeros, or the Reset value, until then); delay 0 returns u itself. Kept apart from the integrator state so
// that what is on the mirror and what the controller integrates are never confused.
class DelayLine {
 public:
  // size >= 0 entries per vector, delay >= 0 frames. Throws InvalidArgument otherwise.
  DelayLine(Index size, int delay);
  // Pushes u (size entries) and returns the vector that leaves the line now (a reference valid until the
  // next call). Throws InvalidArgument for a wrong size.
  const Vector& Push(const Eigen::Ref<const Vector>& u);
  // Fills the line with `value` (size entries).
  void Reset(const Eigen::Ref<const Vector>& value);
  int delay() const { return delay_; }
  Index size() const { return size_; }

 private:
  Index size_;
  int delay_;
  std::vector<Vector> slots_;  // ring buffer of delay_ + 1 vectors
  int head_ = 0;               // slot written by the next Push
};

class Controller {
 public:
  // control_matrix: M (n_act x n_meas, finite); interaction_matrix: D (n_meas x n_act, finite), required for
  // kPseudoOpenLoop and ignored (may be empty) for kIntegrator. Throws InvalidArgument naming the bad
  // argument or options field.
  Controller(const Eigen::MatrixXd& control_matrix, const Eigen::MatrixXd& interaction_matrix,
             const ControllerOptions& options);

  // End of frame n: takes m_n (measured while applied_commands() was on the mirror), updates the state and
  // the delay line, and returns c_{n+1}, the command for the next frame (which applied_commands() then
  // returns). Throws InvalidArgument for a wrong size or non-finite input.
  const Vector& Update(const Eigen::Ref<const Vector>& measurement);
  // c_n: the command on the mirror during the current frame.
  const Vector& applied_commands() const { return applied_; }
  // u: the integrator state (the newest command, not yet on the mirror when delay_frames > 0).
  const Vector& state() const { return state_; }
  // Sets the integrator state, the delay line and the applied command to `commands` (n_act values; zeros by
  // default), e.g. to start from a flat or a pre-shaped mirror.
  void Reset();
  void Reset(const Eigen::Ref<const Vector>& commands);

  Index n_actuators() const { return control_matrix_.rows(); }
  Index n_measurements() const { return control_matrix_.cols(); }
  const ControllerOptions& options() const { return options_; }
  double frame_time_s() const { return options_.frame_time_s(); }
  // Replaces the command on the mirror by its clipped version (closed_loop.hpp's stroke limit); the state
  // and the delay line are unchanged. `commands` must have n_actuators() entries.
  void OverrideApplied(const Eigen::Ref<const Vector>& commands);

 private:
  ControllerOptions options_;
  Eigen::MatrixXd control_matrix_;
  Eigen::MatrixXd interaction_matrix_;
  Vector state_;
  Vector applied_;
  Vector scratch_meas_;
  Vector scratch_cmd_;
  DelayLine delay_line_;
};

}  // namespace aosr
