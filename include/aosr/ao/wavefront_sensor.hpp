// The wavefront-sensor interface shared by the control loop (control.hpp, closed_loop.hpp), and the "ideal"
// sensor that sees the residual OPD projected onto the deformable mirror.
//
// Measurements, references and offsets. A sensor turns the pupil OPD w [m] (pupil.hpp's n x n grid) into a
// raw measurement vector m_raw(w) (slopes in radians for a Shack-Hartmann, metres of DM command for the ideal
// sensor). What it reports to the controller is
//     m(w) = m_raw(w) - (r + o),
// with r the REFERENCE, measured once on a flat wavefront (w = 0) without noise when the sensor is built,
// and o the reference OFFSET (zero until SetReferenceOffset is called). A closed loop drives m to zero, i.e.
// it holds the residual at the wavefront whose raw measurement is r + o. That is how designed DM offsets
// w_dm,i are applied (DESIGN.md §1): set o = ReferenceOffsetForOpd(w_dm,i) = m_raw(w_dm,i) - r (noise-free),
// and the loop settles where the residual, as the sensor sees it, equals w_dm,i: the DM then holds the
// turbulence correction PLUS the offset shape, exactly as a real-time computer does when its "flat" (its
// reference slopes) changes. Only what the sensor sees can be held: components of w_dm,i in the sensor's or
// the reconstructor's null space (piston, Fried-geometry waffle, modes cut from the control matrix) are not.
//
// Noise: Measure() adds the sensor's noise (if it has any), drawing from its own deterministic generator;
// MeasureNoiseless() never does (calibration, references, offsets). Both subtract r + o.
//
// API rules for every sensor: the OPD must be n x n and finite where the pupil transmits; a wrong shape or a
// measurement that comes out non-finite throws InvalidArgument. Sensors keep scratch buffers and a random
// generator: they are NOT thread-safe (use one per thread) and Measure* are non-const.
#pragma once

#include <memory>
#include <string>

#include "aosr/core/image.hpp"
#include "aosr/optics/deformable_mirror.hpp"

namespace aosr {

class WavefrontSensor {
 public:
  virtual ~WavefrontSensor() = default;
  WavefrontSensor(const WavefrontSensor&) = delete;
  WavefrontSensor& operator=(const WavefrontSensor&) = delete;

  // The pupil grid size n (the OPD is n x n) and the length of a measurement vector.
  Index pupil_n() const { return pupil_n_; }
  Index n_measurements() const { return n_measurements_; }
  // One line describing the sensor and its sampling (for reports and benchmarks).
  virtual std::string Describe() const = 0;

  // m(w) = m_raw(w) - (reference + offset), with the sensor's noise. `measurement` must have
  // n_measurements() entries. Throws InvalidArgument for a wrong OPD shape or output size, or non-finite
  // results (non-finite OPD where the pupil transmits).
  void Measure(const Image& opd_m, Eigen::Ref<Vector> measurement);
  Vector Measure(const Image& opd_m);
  // The same without noise (the generator does not advance).
  void MeasureNoiseless(const Image& opd_m, Eigen::Ref<Vector> measurement);
  Vector MeasureNoiseless(const Image& opd_m);

  // r: the noise-free raw measurement of a flat wavefront, taken at construction.
  const Vector& reference() const { return reference_; }
  // o: the current reference offset (zeros by default).
  const Vector& reference_offset() const { return offset_; }
  // Sets o (n_measurements() finite values). Throws InvalidArgument otherwise.
  void SetReferenceOffset(const Eigen::Ref<const Vector>& offset);
  void ClearReferenceOffset() { offset_.setZero(); }
  // The offset that makes a closed loop hold the OPD w: m_raw(w) - r, noise-free (for a linear sensor, the
  // sensor applied to w). Same argument checks as Measure.
  Vector ReferenceOffsetForOpd(const Image& opd_m);

 protected:
  WavefrontSensor(Index pupil_n, Index n_measurements);
  // Measures the flat-wavefront reference; derived constructors call it once they are fully built.
  void CalibrateReference();

 private:
  // m_raw(w) into `raw` (n_measurements() entries, already sized), with noise when `noisy`.
  virtual void MeasureRaw(const Image& opd_m, bool noisy, Eigen::Ref<Vector> raw) = 0;
  void MeasureChecked(const Image& opd_m, bool noisy, Eigen::Ref<Vector> out, const char* function);

  Index pupil_n_;
  Index n_measurements_;
  Vector reference_;
  Vector offset_;
};

// The "ideal" wavefront sensor: the controller sees the true residual OPD projected onto the DM,
//     m_raw(w) = c*(w) = argmin_c  sum_pixels A (H c - w)^2 + mu |c|^2      (DmFitter,
//     deformable_mirror.hpp),
// i.e. the least-squares DM commands [m] of the residual, noise-free and with no delay of its own. Its
// interaction matrix is the identity up to the fitter's tiny regularisation, so an integrator on it drives
// the DM to the least-squares fit of the turbulence, lagging by the loop delay: the closed loop's residual is
// then the DM fitting error plus the servo-lag error, with no aliasing and no noise, which is what the
// analytic model of analytic_ao.hpp describes with `aliasing = false` and `wfs_noise_rad2 = 0`. (A noiseless
// geometric Shack-Hartmann is also "ideal" in being linear and noise-free, but it does alias: the mean
// gradient over a subaperture folds the turbulence beyond the control radius into the measurement, which is
// exactly the aliasing term of the analytic model.) The fit projects, it does not band-limit: the Gaussian
// influence functions are not band-limited, so a little of the out-of-band turbulence still moves the DM (the
// fitter's a_F = 0.256 against ~0.23 for an ideal square band, deformable_mirror.hpp).
//
// Cost: one DmFitter::Fit per measurement (~0.1 - 0.2 ms for 17 x 17 actuators on a 128-pixel pupil).
class IdealWavefrontSensor final : public WavefrontSensor {
 public:
  // dm: the mirror (non-null); amplitude: the pupil weights A (dm's n x n grid, finite, >= 0, some > 0);
  // fit: the fitter's options. Throws InvalidArgument naming the bad argument.
  IdealWavefrontSensor(DeformableMirrorPtr dm, const Image& amplitude,
                       const DmFitOptions& fit = DmFitOptions());

  std::string Describe() const override;
  const DmFitter& fitter() const { return fitter_; }

 private:
  void MeasureRaw(const Image& opd_m, bool noisy, Eigen::Ref<Vector> raw) override;

  DmFitter fitter_;
};

}  // namespace aosr
