// The closed-loop Monte-Carlo AO simulator: atmosphere -> DM -> wavefront sensor -> controller, frame by
// frame, with the science camera's long-exposure PSF as the average of instantaneous PSFs (DESIGN.md §1).
//
// Time. Frame n (n = 0, 1, ... counted from construction, across calls) lasts T = 1 / loop_rate_hz and is
// represented by its centre t_n = start_time_s + (n + 1/2) T. During frame n:
//   1. atmosphere:  phi_n = Atmosphere::Opd(t_n)  (frozen flow evolving continuously with t; zero if none)
//                   + common_static_opd_m (a static aberration seen by sensor and science alike);
//   2. DM:          the mirror holds c_n = Controller::applied_commands() (clipped to the stroke when
//                   clip_to_stroke), so the residual is w_n = phi_n + g_dm H c_n (the DM's OPD adds,
//                   control.hpp; g_dm = dm_gain, 1 unless the mirror's stroke calibration is wrong);
//   3. WFS:         m_n = WavefrontSensor::Measure(w_n), noise included;
//   4. control:     Controller::Update(m_n) computes c_{n+1} (delay line, control.hpp);
//   5. science:     the science camera sees w_n + science_static_opd_m (non-common-path aberration) at
//                   science.wavelength_m: instantaneous Strehl and, every psf_every_steps frames, the
//                   instantaneous PSF added to the long-exposure average.
// Off axis (options.science_direction = theta != 0): steps 1-4 are unchanged (the guide star's loop, on its
// axis), and the science camera of step 5 sees instead
//     w_n(theta) = Atmosphere::Opd(t_n, theta) + common_static_opd_m + g_dm H c_n,
// the same layered frozen flow with each layer displaced by h_l theta (atmosphere.hpp, "Field directions"),
// corrected by the guide star's commands: anisoplanatism. The atmosphere must have been built for that
// direction (AtmosphereOptions::max_field_angle_rad >= |theta|; checked by the constructor). residual_rms_m,
// strehl and the PSF are then the science direction's; residual_opd_m() stays the sensor's. Cost: one more
// Atmosphere::Opd per recorded frame (~0.17 ms for the paper's system). Any number of directions: one loop
// per direction with the same atmosphere seed and sensor gives the same commands (the loop does not depend on
// theta), so the directions of a field grid see the same correction. One loop records them all more cheaply
// (ClosedLoopOptions::extra_science_directions: per direction and recorded frame, only its Atmosphere::Opd and its
// science stage), with the same bytes per direction.
// On axis (theta = 0, the default) nothing of this runs and the results are the same bytes as before.
//
// The sensor sees the residual of the same instant the science camera sees; the lag from a measurement to
// the frame its correction starts is (k + 1) T with k = delay_frames, analytic_ao.hpp's convention (the
// simulation samples each frame at its centre where the analytic model averages over it).
//
// Ideal WFS. Pass an IdealWavefrontSensor (wavefront_sensor.hpp): the controller then sees the true residual
// projected onto the DM, so the residual is fitting + servo-lag error only, the analytic model with
// aliasing = false. A noiseless geometric ShackHartmann is linear and noise-free too, but aliases.
//
// Long-exposure PSF. With the science field E_n = A exp(i 2 pi (w_n + w_ncp) / lambda) on the n x n pupil
// grid, the PSF of psf.hpp (PsfCalculator) is PSF_n(alpha) = s^2 / sum A^2 (1/n^2) sum_k Gamma_n(k)
// exp(-2 pi i (k D / n) . alpha / lambda), Gamma_n(k) = sum_u E_n(u + k) E_n*(u) (lags |k| <= n - 1, the
// pupil's autocorrelation). Averaging is linear, so the long exposure needs only the average of Gamma_n, and
// Gamma_n is the inverse DFT of |DFT E_n|^2 on a 2n x 2n grid (zero-padded: no wrap-around). Per PSF frame
// the cost is therefore ONE 2n x 2n FFT (256^2 for n = 128, ~0.2 ms) and |.|^2 accumulation; at the end of
// the exposure one inverse FFT and one MFT of the (2n-1)^2 lag lattice onto the requested grid (the
// construction of analytic_ao.hpp, without the attenuation). This is exactly (to rounding) the average of
// PsfCalculator::Compute over the same frames at any pixel scale and window (tested to 1e-10), at a fraction
// of the cost of one MFT per frame (~2 ms for 128 x 128 outputs). The instantaneous Strehl
// S_n = |sum A exp(i phi_n)|^2 / (sum A)^2 (psf.hpp's StrehlFromPupil) is the DFT's zero bin, computed every
// frame; the long-exposure Strehl (the on-axis value of the average PSF over the unaberrated one) is the
// mean of S_n.
//
// Sub-exposures (RunSubExposures). One continuous run: for exposure i the sensor's reference offset is set
// to ReferenceOffsetForOpd(w_dm,i) (wavefront_sensor.hpp), so the loop holds the turbulence correction plus
// the DM offset w_dm,i, as a real-time computer does when its reference slopes change; the atmosphere keeps
// evolving; the first settling_s of each exposure (the loop's response to the offset step: ~4 / (g f_loop)
// for an integrator, e.g. 4 / (0.35 * 800 Hz) = 14 ms) are run but not averaged. On return the sensor keeps
// the last exposure's offset. A sensor whose gain depends on its spots (the diffractive SH in closed loop)
// would hold an offset's tilt divided by that gain; with OffsetCalibration::kOnSky (default) the first half
// of the settling measures the tip/tilt gain and the offset is rescaled, so the image lands where it was
// commanded (tests/ao/closed_loop_physics_test.cpp).
//
// Cost per frame (paper's system: 128-pixel pupil, 3 layers, 16 x 16 SH, 241 actuators, K-band PSF 128 x 128
// every frame; one core, Release; bench/closed_loop_bench.cpp): atmosphere 0.17 ms, DM and residual 0.04 ms,
// WFS 0.005 ms (geometric) / 0.24 ms (diffractive: 208 FFTs of 16 x 16) / 0.19 ms (ideal: a DmFitter fit),
// control 0.02 ms, science 0.32 ms; in total 0.54 ms (geometric) and 0.79 ms (diffractive), against an FFT
// floor of 0.20 / 0.26 ms (one 256^2 FFT, plus the lenslets' FFTs). Per-frame complex exponentials use a
// vectorised sin/cos (src/ao/fast_trig.hpp, 2e-16 absolute error).
//
// Measured on the paper's system (noiseless, integrator g = 0.35, k = 1; tests/ao/closed_loop_*_test.cpp):
// long-exposure K-band Strehl 0.889 - 0.898 over three 1 s runs with the ideal sensor against 0.892 from
// AnalyticAoPsfCalculator without aliasing; 0.847 with the geometric SH against 0.862 with aliasing; with
// the diffractive SH 0.73 - 0.80 (Nyquist pixels, 16 x 16 px = 8 lambda/d, plain centroid), 0.83 with
// 2x Nyquist pixels (32 px, same field), 0.82 with Nyquist pixels and a 10% threshold: the centroid of a
// spot broadened by the residual at 640 nm (d / r0 = 2.8) loses more to the wrapped wings (shack_hartmann.hpp).
//
// Ownership: the loop keeps pointers to the atmosphere, sensor and controller, which must outlive it and are
// advanced by it (they are stateful); the mirror is shared. Not thread-safe.
#pragma once

#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "aosr/ao/atmosphere.hpp"
#include "aosr/ao/control.hpp"
#include "aosr/ao/wavefront_sensor.hpp"
#include "aosr/core/image.hpp"
#include "aosr/optics/deformable_mirror.hpp"
#include "aosr/optics/mft.hpp"
#include "aosr/optics/psf.hpp"

namespace aosr {

// How RunSubExposures turns a DM offset into the sensor's reference offset (header, "Sub-exposures").
enum class OffsetCalibration {
  // o = m_raw(w_dm) - r on a flat wavefront: exact for a linear sensor, but a sensor whose gain depends on
  // its spots then holds the offset's tilt divided by that gain. The paper's diffractive SH in closed loop
  // (turbulence-broadened spots whose wings wrap in the lenslet field) has a tip/tilt gain of 0.86 - 0.89,
  // and its images land 9 - 19 % (mean 14 %) further from the centre than commanded
  // (bench/results/psf_offsets.md). The uncalibrated effect, for scenes that want it.
  kFlat,
  // The flat offset with its tip/tilt content rescaled by the sensor's tip/tilt gain G (2 x 2) measured at the
  // loop's operating point (noise-free central differences of the sensor about the residual, averaged over
  // the first half of the settling, at least one frame), as a real-time computer calibrates its optical
  // gain with a small tip/tilt probe: holding P o' = G P o makes the loop hold the commanded tilt. The
  // diffractive SH's images then land within -5..+5 % of the commanded offsets, as a linear sensor's do.
  // Default. (A linear sensor has G = I: nothing changes but the probe's cost, four noise-free
  // measurements per probe frame.)
  kOnSky,
};

struct ClosedLoopOptions {
  // The science camera: wavelength [m], pixel pitch [rad] (the HR grid's theta_pix / r), window rows x cols
  // (optical axis at (rows/2, cols/2)); PsfSampling's ranges. Default: K band 2.2 um, Nyquist for 8 m
  // (lambda / (2 D) = 1.375e-7 rad = 28.4 mas), 128 x 128 (64 lambda/D, beyond the 8 lambda/D control
  // radius of a 17 x 17 DM).
  PsfSampling science = {2.2e-6, 2.2e-6 / 16.0, 128, 128};
  // Compute the instantaneous PSF every psf_every_steps-th recorded frame (>= 1; frames 0, k, 2k, ... of each
  // exposure). Default 1: every frame. The Strehl history is computed every frame regardless.
  int psf_every_steps = 1;
  // Accumulate the long-exposure PSF at all. false skips the FFT (Strehl and residuals only). Default true.
  bool compute_psf = true;
  // Clamp the commands to the mirror's stroke (DeformableMirror::Clip) before they are applied; the result
  // counts the frames that clipped. Default true: a real mirror saturates.
  bool clip_to_stroke = true;
  // Static OPD [m] seen by the sensor and the science camera (empty: none; else n x n, finite where the
  // pupil transmits), e.g. a static aberration for a loop without turbulence.
  Image common_static_opd_m;
  // Static OPD [m] seen by the science camera only (non-common-path aberration; empty: none; else n x n).
  Image science_static_opd_m;
  // Time [s] at the start of frame 0, finite and >= 0 (Atmosphere times must be >= 0). Default 0.
  double start_time_s = 0.0;
  // The mirror's actual response per commanded metre, in [0.5, 2]: the DM applies dm_gain * H c_n where the
  // controller (its interaction model, POL reconstruction, integrator gain) assumes H c_n. A calibration
  // error of the mirror's stroke (an influence-function amplitude wrong by dm_gain - 1) that nothing in the
  // loop knows about; stroke clipping still acts on the commands. Default 1: the mirror does what it is told.
  double dm_gain = 1.0;
  // RunSubExposures' reference offsets (OffsetCalibration). Default kOnSky.
  OffsetCalibration offset_calibration = OffsetCalibration::kOnSky;
  // Direction of the science camera from the guide star [rad] (header, "Off axis"); finite, and within the
  // atmosphere's max_field_angle_rad. Default (0, 0): on axis.
  FieldDirection science_direction;
  // Further science directions [rad] recorded by the same run, each within the atmosphere's
  // max_field_angle_rad (a field of directions: one loop for all of them, header "Off axis"). Each gets its
  // residual, Strehl series and PSF in ClosedLoopResult::extra_directions, the same bytes as a loop whose
  // science_direction it is. Default none.
  std::vector<FieldDirection> extra_science_directions;

  // True when every field is in range; otherwise false and `why` names the bad field. Image shapes are
  // checked by the ClosedLoop constructor (they depend on the pupil grid).
  bool IsValid(std::string* why) const;
};

// Accumulated wall-clock time per stage [s] (for benchmarks); reset with ClosedLoop::ResetStageTimes.
struct LoopStageTimes {
  double atmosphere_s = 0.0;  // Atmosphere::Opd
  double dm_s = 0.0;          // clipping, DM OPD and the residual sum
  double wfs_s = 0.0;         // WavefrontSensor::Measure
  double control_s = 0.0;     // Controller::Update
  double science_s = 0.0;     // science field, Strehl, residual RMS, PSF FFT and accumulation
  long frames = 0;            // frames timed
  double Total() const { return atmosphere_s + dm_s + wfs_s + control_s + science_s; }
};

struct ClosedLoopResult {
  double start_time_s = 0.0;  // centre time of the first recorded frame [s]
  double frame_time_s = 0.0;  // T [s]
  int settling_steps = 0;     // frames run before recording (not in any statistic)
  int steps = 0;              // recorded frames
  std::vector<double>
      residual_rms_m;                 // per recorded frame: piston-removed, amplitude-weighted RMS of w_n [m]
  std::vector<double> strehl;         // per recorded frame: S_n at the science wavelength (w_n + w_ncp)
  double long_exposure_strehl = 0.0;  // mean of strehl over the recorded frames
  Image psf;                          // long-exposure PSF (psf.hpp's normalisation); empty if !compute_psf
  int psf_frames = 0;                 // frames averaged into psf
  double psf_strehl = 0.0;            // mean of strehl over those frames: the psf's on-axis Strehl
  int clipped_frames = 0;             // frames in which some command hit the stroke
  // RunSubExposures with kOnSky: the diagonal (y, x) of the tip/tilt gain G the offset was calibrated with;
  // else 1.
  double tilt_gain[2] = {1.0, 1.0};
  // One per ClosedLoopOptions::extra_science_directions, in order: that direction's residual_rms_m, strehl,
  // long_exposure_strehl, psf and psf_strehl (the other fields as this result's; their extra_directions empty).
  std::vector<ClosedLoopResult> extra_directions;
  // RMS over the recorded frames of residual_rms_m [m].
  double RmsResidualM() const;
  // "1000 frames (+80 settling) at 800 Hz: residual 93.1 nm RMS, LE Strehl 0.871 at 2200 nm, PSF of 1000
  // frames".
  std::string BriefReport() const;
};

class ClosedLoop {
 public:
  // amplitude: the n x n pupil amplitude (finite, >= 0, some > 0); diameter_m: D of the grid; atmosphere:
  // may be null (no turbulence), else its grid must be n and D; dm: non-null, on the n grid; wfs and
  // controller: non-null, the controller's matrices sized for the mirror and the sensor. A noisy
  // ShackHartmann's frame time must equal the controller's (relative 1e-6). Throws InvalidArgument naming
  // the bad argument or options field.
  ClosedLoop(const Image& amplitude, double diameter_m, Atmosphere* atmosphere, DeformableMirrorPtr dm,
             WavefrontSensor* wfs, Controller* controller, const ClosedLoopOptions& options);
  ~ClosedLoop();

  // Runs settling_s of loop time without recording, then duration_s recorded (round(x / T) frames each;
  // duration_s must give at least one frame). Throws InvalidArgument for non-finite or negative times.
  ClosedLoopResult Run(double duration_s, double settling_s = 0.0);

  // One continuous run over the DM offsets w_dm,i (each n x n [m], finite where the pupil transmits): for
  // each, set the sensor's reference offset, run settling_s unrecorded and exposure_s recorded. Returns one
  // result (and PSF) per offset. Throws InvalidArgument for an empty list, wrong shapes or bad times.
  // `after_each`, when set, is called with the number of exposures done after each one; returning false stops
  // the run there (the results then hold only the exposures done): how a caller cancels a long loop.
  std::vector<ClosedLoopResult> RunSubExposures(const std::vector<Image>& dm_offsets_m, double exposure_s,
                                                double settling_s,
                                                const std::function<bool(int)>& after_each = {});

  // Advances one frame (steps 1-5 of the header); record = false skips the science stage. Run() manages the
  // recording; frames recorded by direct calls are discarded by the next Run().
  void Step(bool record);

  long frame() const { return frame_; }
  // Centre time of the next frame [s].
  double time_s() const;
  // The residual w_n of the last frame (n x n, metres; the WFS-path OPD, without the science-only OPD).
  const Image& residual_opd_m() const { return residual_; }
  const ClosedLoopOptions& options() const { return options_; }
  const LoopStageTimes& stage_times() const { return times_; }
  void ResetStageTimes() { times_ = LoopStageTimes(); }

 private:
  struct Recorder;
  struct Track;
  // The science stage's work arrays: one per group of directions that runs in parallel.
  struct Scratch {
    std::vector<double> phase, cos, sin;  // per lit pixel
    ComplexImage field;                    // 2n x 2n, zero outside the lit pixels
    ComplexImage spectrum;                 // its DFT
  };
  // Step 5 for one science direction: w its residual OPD (n x n [m]), into `track`, with `scratch`.
  void ScienceStage(const double* w, bool psf_frame, Track* track, Scratch* scratch) const;
  // The recorded statistics and PSF of one direction.
  void FinishTrack(const Track& track, int steps, ClosedLoopResult* out);
  void BeginRecording();
  ClosedLoopResult FinishRecording(int settling_steps, double start_time_s);
  // Records `steps` frames from now (BeginRecording, Step(true), FinishRecording); `settling_steps` is what the
  // result reports as run before them.
  ClosedLoopResult Record(long steps, int settling_steps);

  ClosedLoopOptions options_;
  Image amplitude_;
  double diameter_m_;
  Atmosphere* atmosphere_;
  DeformableMirrorPtr dm_;
  WavefrontSensor* wfs_;
  Controller* controller_;
  long frame_ = 0;
  Image turbulence_, dm_opd_, residual_;
  // Off axis only (header, "Off axis"): the recorded directions that are not the guide star's, each recorded
  // direction's index among them (-1: on axis), their turbulence and (per recorded direction) their residual of
  // this frame.
  std::vector<FieldDirection> off_axis_;
  std::vector<Index> turbulence_of_;
  std::vector<Image> science_turbulence_, science_residual_;
  Vector measurement_, clipped_;
  // Science path.
  std::vector<Index> lit_pupil_, lit_field_;  // lit pupil pixels and their index in the 2n x 2n field
  std::vector<double> lit_amp_;
  double sum_amplitude_ = 0.0, energy_ = 0.0;
  std::vector<Scratch> scratch_;  // one per parallel group of directions (made on first use)
  std::unique_ptr<MatrixFourierTransform> lattice_mft_;
  std::unique_ptr<Recorder> recorder_;
  // Offset calibration (OffsetCalibration): P = (A^T A)^-1 A^T, 2 x n_measurements, rows (y, x), the
  // least-squares tilt [rad] of a measurement in the sensor's flat-wavefront units.
  Eigen::Matrix<double, 2, Eigen::Dynamic> tilt_projector_;
  Eigen::Matrix<double, Eigen::Dynamic, 2> tilt_response_;  // A: the sensor's flat response to unit tilts
  Image tilt_opd_[2];                                        // OPD [m] of a 1 rad tilt along y, x
  Image probe_;                                              // scratch
  // Fills tilt_opd_, tilt_response_ and tilt_projector_ (on first use). Throws InvalidArgument for a sensor
  // blind to tip or tilt.
  void CalibrateTiltResponse();
  // d m / d t_axis at opd_m (noise-free central differences), and G = P [d m/d t_y, d m/d t_x].
  Vector TiltDerivative(const Image& opd_m, int axis);
  Eigen::Matrix2d TiltGain(const Image& opd_m);
  LoopStageTimes times_;
};

}  // namespace aosr
