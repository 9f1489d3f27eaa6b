#include "aosr/ao/closed_loop.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <utility>

#include <Eigen/Dense>

#include "aosr/ao/shack_hartmann.hpp"
#include "aosr/core/error.hpp"
#include "aosr/optics/pupil.hpp"
#include "aosr/core/fft.hpp"
#include "aosr/core/parallel.hpp"
#include "fast_trig.hpp"

namespace aosr {
namespace {


using Clock = std::chrono::steady_clock;

double Seconds(Clock::time_point a, Clock::time_point b) {
  return std::chrono::duration<double>(b - a).count();
}


void CheckStaticOpd(const Image& opd, const Image& amplitude, const char* name) {
  if (opd.size() == 0) return;
  const Index n = amplitude.rows();
  CheckArgument(opd.rows() == n && opd.cols() == n, "ClosedLoop", std::string("options.") + name + " shape",
                ToString(ShapeOf(opd)), "empty or " + ToString(Shape{n, n}) + " (the pupil grid)");
  for (Index p = 0; p < opd.size(); ++p) {
    if (amplitude.data()[p] > 0.0 && !std::isfinite(opd.data()[p])) {
      throw InvalidArgument("ClosedLoop", std::string("options.") + name, ToString(opd.data()[p]),
                            "finite values where the pupil transmits");
    }
  }
}

// Validates everything before any member is built; returns the options.
const ClosedLoopOptions& CheckedLoopOptions(const Image& amplitude, double diameter_m, Atmosphere* atmosphere,
                                            const DeformableMirrorPtr& dm, WavefrontSensor* wfs,
                                            Controller* controller, const ClosedLoopOptions& options) {
  const char* fn = "ClosedLoop";
  std::string why;
  if (!options.IsValid(&why)) throw InvalidArgument(std::string(fn) + ": invalid options." + why);
  CheckPupilAmplitude(amplitude, diameter_m, fn);
  const Index n = amplitude.rows();
  const std::string grid = std::to_string(n) + " (the amplitude's grid)";
  CheckArgument(dm != nullptr, fn, "dm", "null", "a deformable mirror");
  CheckArgument(wfs != nullptr, fn, "wfs", "null", "a wavefront sensor");
  CheckArgument(controller != nullptr, fn, "controller", "null", "a controller");
  CheckArgument(dm->pupil_n() == n, fn, "dm pupil grid", dm->pupil_n(), grid);
  CheckArgument(std::abs(dm->pupil().diameter_m - diameter_m) <= 1e-9 * diameter_m, fn, "dm diameter",
                dm->pupil().diameter_m, ToString(diameter_m) + " [m] (diameter_m)");
  CheckArgument(wfs->pupil_n() == n, fn, "wfs pupil grid", wfs->pupil_n(), grid);
  if (atmosphere != nullptr) {
    CheckArgument(atmosphere->pupil_n() == n, fn, "atmosphere pupil grid", atmosphere->pupil_n(), grid);
    CheckArgument(std::abs(atmosphere->diameter_m() - diameter_m) <= 1e-9 * diameter_m, fn,
                  "atmosphere diameter", atmosphere->diameter_m(),
                  ToString(diameter_m) + " [m] (diameter_m)");
  }
  CheckArgument(controller->n_actuators() == dm->n_active(), fn, "controller actuators",
                controller->n_actuators(),
                std::to_string(dm->n_active()) + " (the mirror's active actuators)");
  CheckArgument(controller->n_measurements() == wfs->n_measurements(), fn, "controller measurements",
                controller->n_measurements(), std::to_string(wfs->n_measurements()) + " (the sensor's)");
  if (const auto* sh = dynamic_cast<const ShackHartmann*>(wfs)) {
    const ShackHartmannNoise& noise = sh->options().noise;
    const double t = controller->frame_time_s();
    if ((noise.photon_noise || noise.read_noise_e > 0.0) && std::abs(noise.frame_time_s - t) > 1e-6 * t) {
      throw InvalidArgument(
          fn, "wfs noise.frame_time_s", ToString(noise.frame_time_s),
          ToString(t) + " [s] (1 / the controller's loop_rate_hz) when the sensor has noise");
    }
  }
  if (!options.science_direction.IsZero() && atmosphere != nullptr) {
    atmosphere->CheckFieldDirection(options.science_direction, "ClosedLoop (options.science_direction)");
  }
  if (atmosphere != nullptr)
    for (const FieldDirection& d : options.extra_science_directions)
      if (!d.IsZero()) atmosphere->CheckFieldDirection(d, "ClosedLoop (options.extra_science_directions)");
  CheckStaticOpd(options.common_static_opd_m, amplitude, "common_static_opd_m");
  CheckStaticOpd(options.science_static_opd_m, amplitude, "science_static_opd_m");
  return options;
}

}  // namespace

bool ClosedLoopOptions::IsValid(std::string* why) const {
  std::string sub;
  if (!science.IsValid(&sub)) return Fail(why, "science." + sub);
  if (psf_every_steps < 1) {
    return Fail(why, "psf_every_steps = " + ToString(psf_every_steps) + "; allowed: >= 1 [frames]");
  }
  if (!(std::isfinite(start_time_s) && start_time_s >= 0.0)) {
    return Fail(why, "start_time_s = " + ToString(start_time_s) + "; allowed: >= 0 and finite [s]");
  }
  if (!(std::isfinite(science_direction.x_rad) && std::isfinite(science_direction.y_rad))) {
    return Fail(why, "science_direction = (" + ToString(science_direction.x_rad) + ", " +
                         ToString(science_direction.y_rad) + "); allowed: finite [rad]");
  }
  for (std::size_t k = 0; k < extra_science_directions.size(); ++k) {
    const FieldDirection& d = extra_science_directions[k];
    if (!(std::isfinite(d.x_rad) && std::isfinite(d.y_rad)))
      return Fail(why, "extra_science_directions[" + std::to_string(k) + "] = (" + ToString(d.x_rad) + ", " +
                           ToString(d.y_rad) + "); allowed: finite [rad]");
  }
  if (!(std::isfinite(dm_gain) && dm_gain >= 0.5 && dm_gain <= 2.0)) {
    return Fail(why, "dm_gain = " + ToString(dm_gain) + "; allowed: [0.5, 2] (the mirror's response per commanded metre)");
  }
  return true;
}

double ClosedLoopResult::RmsResidualM() const {
  if (residual_rms_m.empty()) return 0.0;
  double sum2 = 0.0;
  for (double r : residual_rms_m) sum2 += r * r;
  return std::sqrt(sum2 / static_cast<double>(residual_rms_m.size()));
}

std::string ClosedLoopResult::BriefReport() const {
  char buf[320];
  std::snprintf(buf, sizeof(buf),
                "%d frames (+%d settling) at %.6g Hz: residual %.4g nm RMS, LE Strehl %.4f, PSF of %d frames "
                "(Strehl %.4f), %d frames clipped",
                steps, settling_steps, frame_time_s > 0.0 ? 1.0 / frame_time_s : 0.0, RmsResidualM() * 1e9,
                long_exposure_strehl, psf_frames, psf_strehl, clipped_frames);
  return buf;
}

// Per-exposure accumulators of one science direction.
struct ClosedLoop::Track {
  std::vector<double> residual_rms_m;
  std::vector<double> strehl;
  int psf_frames = 0;
  double psf_strehl_sum = 0.0;
  Image accumulator;  // sum of |DFT E|^2 over PSF frames (2n x 2n)
};

// Per-exposure accumulators: tracks[0] the science_direction, then the extra_science_directions.
struct ClosedLoop::Recorder {
  std::vector<Track> tracks;
  int steps = 0;
  int clipped_frames = 0;
};

ClosedLoop::ClosedLoop(const Image& amplitude, double diameter_m, Atmosphere* atmosphere,
                       DeformableMirrorPtr dm, WavefrontSensor* wfs, Controller* controller,
                       const ClosedLoopOptions& options)
    : options_(CheckedLoopOptions(amplitude, diameter_m, atmosphere, dm, wfs, controller, options)),
      amplitude_(amplitude),
      diameter_m_(diameter_m),
      atmosphere_(atmosphere),
      dm_(std::move(dm)),
      wfs_(wfs),
      controller_(controller) {
  const Index n = amplitude_.rows();
  turbulence_ = Image::Zero(n, n);
  dm_opd_ = Image::Zero(n, n);
  residual_ = Image::Zero(n, n);
  measurement_ = Vector::Zero(wfs_->n_measurements());
  clipped_ = Vector::Zero(dm_->n_active());
  const Index m = 2 * n;
  for (Index i = 0; i < n; ++i) {
    for (Index k = 0; k < n; ++k) {
      const double a = amplitude_(i, k);
      if (a <= 0.0) continue;
      lit_pupil_.push_back(i * n + k);
      lit_field_.push_back(i * m + k);
      lit_amp_.push_back(a);
      sum_amplitude_ += a;
      energy_ += a * a;
    }
  }
  // The recorded directions (science_direction, then the extra ones) that are off axis, read from the atmosphere
  // together each frame.
  for (std::size_t k = 0; k <= options_.extra_science_directions.size(); ++k) {
    const FieldDirection& d = k == 0 ? options_.science_direction : options_.extra_science_directions[k - 1];
    turbulence_of_.push_back(d.IsZero() ? -1 : static_cast<Index>(off_axis_.size()));
    if (!d.IsZero()) off_axis_.push_back(d);
  }
  if (options_.compute_psf) {
    // The (2n-1)^2 lag lattice k D/n, centred at (n-1, n-1), onto the science grid (analytic_ao.hpp).
    MftGeometry g;
    g.input = {2 * n - 1, 2 * n - 1};
    g.pupil_span_px = static_cast<double>(n);
    g.output = {options_.science.rows, options_.science.cols};
    g.pixel_scale_lod = options_.science.PixelScaleLambdaOverD(diameter_m_);
    lattice_mft_ = std::make_unique<MatrixFourierTransform>(g);
  }
}

ClosedLoop::~ClosedLoop() = default;

void ClosedLoop::CalibrateTiltResponse() {
  // The sensor's response A = [a_y a_x] to a pure tip and tilt (central differences about a flat wavefront),
  // then P = (A^T A)^-1 A^T.
  const Index n = amplitude_.rows();
  const double pitch = diameter_m_ / static_cast<double>(n);
  auto coord = [&](Index i) { return (static_cast<double>(i) + 0.5 - 0.5 * static_cast<double>(n)) * pitch; };
  Eigen::Matrix<double, Eigen::Dynamic, 2> response(wfs_->n_measurements(), 2);
  for (int axis = 0; axis < 2; ++axis) {
    tilt_opd_[axis] = Image(n, n);
    for (Index i = 0; i < n; ++i)
      for (Index k = 0; k < n; ++k) tilt_opd_[axis](i, k) = axis == 0 ? coord(i) : coord(k);
    response.col(axis) = TiltDerivative(Image::Zero(n, n), axis);
  }
  const Eigen::Matrix2d gram = response.transpose() * response;
  CheckArgument(gram.determinant() > 1e-12 * gram.trace() * gram.trace(), "ClosedLoop::RunSubExposures", "wfs",
                wfs_->Describe(), "a sensor that sees tip and tilt (offset_calibration on-sky), or kFlat");
  tilt_projector_ = gram.inverse() * response.transpose();
  tilt_response_ = response;
}

Vector ClosedLoop::TiltDerivative(const Image& opd_m, int axis) {
  // rad (20 micro-arcseconds): inside any sensor's linear range, and a centroid change ~1e-4 of a pixel, far
  // above rounding. Central differences cancel the quadratic part of a diffractive centroid.
  const double s = 1e-10;
  probe_ = opd_m + s * tilt_opd_[axis];
  Vector plus = wfs_->MeasureNoiseless(probe_);
  probe_ = opd_m - s * tilt_opd_[axis];
  return (plus - wfs_->MeasureNoiseless(probe_)) / (2.0 * s);
}

Eigen::Matrix2d ClosedLoop::TiltGain(const Image& opd_m) {
  Eigen::Matrix2d g;
  for (int axis = 0; axis < 2; ++axis) g.col(axis) = tilt_projector_ * TiltDerivative(opd_m, axis);
  return g;
}

double ClosedLoop::time_s() const {
  return options_.start_time_s + (static_cast<double>(frame_) + 0.5) * controller_->frame_time_s();
}

void ClosedLoop::Step(bool record) {
  const Index n = amplitude_.rows();
  const double t = time_s();
  const auto t0 = Clock::now();
  // 1. Atmosphere.
  if (atmosphere_ != nullptr) {
    atmosphere_->Opd(t, &turbulence_);
  }
  const auto t1 = Clock::now();
  // 2. DM: the command of this frame, the mirror's OPD and the residual.
  const Vector& applied = controller_->applied_commands();
  dm_->Apply(applied, Eigen::Map<Vector>(dm_opd_.data(), n * n));
  if (options_.dm_gain != 1.0) dm_opd_ *= options_.dm_gain;  // a stroke calibration error the loop ignores
  residual_ = dm_opd_;
  if (atmosphere_ != nullptr) residual_ += turbulence_;
  if (options_.common_static_opd_m.size() > 0) residual_ += options_.common_static_opd_m;
  const auto t2 = Clock::now();
  // 3. WFS.
  wfs_->Measure(residual_, measurement_);
  const auto t3 = Clock::now();
  // 4. Control: c_{n+1}, clipped to the stroke before it reaches the mirror.
  const Vector& next = controller_->Update(measurement_);
  bool clipped = false;
  if (options_.clip_to_stroke) {
    const double stroke = dm_->options().stroke_m;
    if (next.cwiseAbs().maxCoeff() > stroke) {
      clipped_ = next;
      dm_->Clip(&clipped_);
      controller_->OverrideApplied(clipped_);
      clipped = true;
    }
  }
  const auto t4 = Clock::now();
  // 5. Science (off axis: the science direction's turbulence under the same DM, header "Off axis"), for each
  // direction recorded: the atmosphere read for every direction at once, then the directions' residuals and
  // science stages in parallel, in groups of consecutive directions, each group with its own work arrays and
  // each direction into its own accumulators: the bytes do not depend on the threads.
  if (record) {
    if (!recorder_) BeginRecording();
    Recorder& r = *recorder_;
    const bool psf_frame = options_.compute_psf && r.steps % options_.psf_every_steps == 0;
    const Index D = static_cast<Index>(r.tracks.size());
    if (atmosphere_ != nullptr && !off_axis_.empty()) atmosphere_->Opd(t, off_axis_, &science_turbulence_);
    science_residual_.resize(r.tracks.size());
    const Index groups = std::min<Index>(D, DefaultThreads());
    if (scratch_.size() < static_cast<std::size_t>(groups)) {
      const Index m = 2 * n;
      scratch_.resize(groups);
      for (Scratch& sc : scratch_) {
        if (sc.field.size() > 0) continue;
        sc.phase.assign(lit_pupil_.size(), 0.0);
        sc.cos.assign(lit_pupil_.size(), 0.0);
        sc.sin.assign(lit_pupil_.size(), 0.0);
        sc.field = ComplexImage::Zero(m, m);
      }
    }
    auto run_group = [&](Index g) {
      for (Index k = g * D / groups; k < (g + 1) * D / groups; ++k) {
        if (turbulence_of_[k] < 0) {
          ScienceStage(residual_.data(), psf_frame, &r.tracks[k], &scratch_[g]);
          continue;
        }
        Image& res = science_residual_[k];
        res = dm_opd_;
        if (atmosphere_ != nullptr) res += science_turbulence_[static_cast<std::size_t>(turbulence_of_[k])];
        if (options_.common_static_opd_m.size() > 0) res += options_.common_static_opd_m;
        ScienceStage(res.data(), psf_frame, &r.tracks[k], &scratch_[g]);
      }
    };
    if (groups == 1) run_group(0);
    else ParallelFor(groups, groups, run_group);
    if (clipped) ++r.clipped_frames;
    ++r.steps;
  }
  const auto t5 = Clock::now();
  times_.atmosphere_s += Seconds(t0, t1);
  times_.dm_s += Seconds(t1, t2);
  times_.wfs_s += Seconds(t2, t3);
  times_.control_s += Seconds(t3, t4);
  times_.science_s += Seconds(t4, t5);
  ++times_.frames;
  ++frame_;
}

void ClosedLoop::ScienceStage(const double* w, bool psf_frame, Track* track, Scratch* scratch) const {
  Track& r = *track;
  Scratch& sc = *scratch;
  // Residual RMS over the pupil, amplitude-weighted, piston removed (the science direction's).
  double s1 = 0.0, s2 = 0.0;
  for (std::size_t j = 0; j < lit_pupil_.size(); ++j) {
    const double v = w[lit_pupil_[j]], a = lit_amp_[j];
    s1 += a * v;
    s2 += a * v * v;
  }
  const double mean = s1 / sum_amplitude_;
  r.residual_rms_m.push_back(std::sqrt(std::max(0.0, s2 / sum_amplitude_ - mean * mean)));
  // Science field and its on-axis sum.
  const double k = kTwoPi / options_.science.wavelength_m;
  const bool ncp = options_.science_static_opd_m.size() > 0;
  const double* wn = ncp ? options_.science_static_opd_m.data() : nullptr;
  const long lit = static_cast<long>(lit_pupil_.size());
  if (ncp) {
    for (long j = 0; j < lit; ++j) sc.phase[j] = k * (w[lit_pupil_[j]] + wn[lit_pupil_[j]]);
  } else {
    for (long j = 0; j < lit; ++j) sc.phase[j] = k * w[lit_pupil_[j]];
  }
  internal::SinCosBatch(sc.phase.data(), lit, sc.cos.data(), sc.sin.data());
  Complex* field = sc.field.data();
  double re = 0.0, im = 0.0;
  for (long j = 0; j < lit; ++j) {
    const double er = lit_amp_[j] * sc.cos[j], ei = lit_amp_[j] * sc.sin[j];
    field[lit_field_[j]] = Complex(er, ei);
    re += er;
    im += ei;
  }
  const Complex on_axis(re, im);
  const double strehl = std::norm(on_axis) / (sum_amplitude_ * sum_amplitude_);
  r.strehl.push_back(strehl);
  if (psf_frame) {
    FftForwardInto(sc.field, &sc.spectrum);
    r.accumulator += sc.spectrum.abs2();
    ++r.psf_frames;
    r.psf_strehl_sum += strehl;
  }
}

void ClosedLoop::BeginRecording() {
  recorder_ = std::make_unique<Recorder>();
  const Index m = 2 * amplitude_.rows();
  recorder_->tracks.resize(1 + options_.extra_science_directions.size());
  for (Track& track : recorder_->tracks) track.accumulator = Image::Zero(m, m);
}

void ClosedLoop::FinishTrack(const Track& r, int steps, ClosedLoopResult* out) {
  out->psf_frames = r.psf_frames;
  double sum = 0.0;
  for (double s : r.strehl) sum += s;
  out->long_exposure_strehl = steps > 0 ? sum / steps : 0.0;
  out->psf_strehl = r.psf_frames > 0 ? r.psf_strehl_sum / r.psf_frames : 0.0;
  out->residual_rms_m = r.residual_rms_m;
  out->strehl = r.strehl;
  if (options_.compute_psf && r.psf_frames > 0) {
    // Gamma = IDFT(<|DFT E|^2>) on the 2n grid, gathered on the (2n-1)^2 lag lattice, then the MFT.
    const Index n = amplitude_.rows(), m = 2 * n;
    const ComplexImage gamma = FftInverse((r.accumulator / static_cast<double>(r.psf_frames)).cast<Complex>());
    ComplexImage lattice(2 * n - 1, 2 * n - 1);
    for (Index ky = -(n - 1); ky <= n - 1; ++ky) {
      for (Index kx = -(n - 1); kx <= n - 1; ++kx) {
        lattice(ky + n - 1, kx + n - 1) = gamma((ky + m) % m, (kx + m) % m);
      }
    }
    const double s = lattice_mft_->geometry().pixel_scale_lod;
    out->psf = lattice_mft_->Apply(lattice).real() * (s * s / energy_);
  }
}

ClosedLoopResult ClosedLoop::FinishRecording(int settling_steps, double start_time_s) {
  Recorder& r = *recorder_;
  ClosedLoopResult out;
  out.start_time_s = start_time_s;
  out.frame_time_s = controller_->frame_time_s();
  out.settling_steps = settling_steps;
  out.steps = r.steps;
  out.clipped_frames = r.clipped_frames;
  const ClosedLoopResult shared = out;  // the fields every direction has in common
  for (std::size_t k = 1; k < r.tracks.size(); ++k) {
    ClosedLoopResult extra = shared;
    FinishTrack(r.tracks[k], r.steps, &extra);
    out.extra_directions.push_back(std::move(extra));
  }
  FinishTrack(r.tracks[0], r.steps, &out);
  recorder_.reset();
  return out;
}

ClosedLoopResult ClosedLoop::Run(double duration_s, double settling_s) {
  const char* fn = "ClosedLoop::Run";
  const double t = controller_->frame_time_s();
  CheckArgument(std::isfinite(duration_s) && duration_s > 0.0 && std::llround(duration_s / t) >= 1, fn,
                "duration_s", duration_s, "finite and at least one frame (" + ToString(t) + " s)");
  CheckArgument(std::isfinite(settling_s) && settling_s >= 0.0, fn, "settling_s", settling_s,
                ">= 0 and finite [s]");
  const long steps = std::llround(duration_s / t);
  const long settle = std::llround(settling_s / t);
  for (long i = 0; i < settle; ++i) Step(false);
  return Record(steps, static_cast<int>(settle));
}

ClosedLoopResult ClosedLoop::Record(long steps, int settling_steps) {
  const double start = time_s();
  BeginRecording();
  for (long i = 0; i < steps; ++i) Step(true);
  return FinishRecording(settling_steps, start);
}

std::vector<ClosedLoopResult> ClosedLoop::RunSubExposures(const std::vector<Image>& dm_offsets_m,
                                                          double exposure_s, double settling_s,
                                                          const std::function<bool(int)>& after_each) {
  const char* fn = "ClosedLoop::RunSubExposures";
  CheckArgument(!dm_offsets_m.empty(), fn, "dm_offsets_m", "empty", "at least one DM offset");
  const double t = controller_->frame_time_s();
  CheckArgument(std::isfinite(exposure_s) && exposure_s > 0.0 && std::llround(exposure_s / t) >= 1, fn,
                "exposure_s", exposure_s, "finite and at least one frame (" + ToString(t) + " s)");
  CheckArgument(std::isfinite(settling_s) && settling_s >= 0.0, fn, "settling_s", settling_s,
                ">= 0 and finite [s]");
  const Index n = amplitude_.rows();
  // Compute every offset first, so bad input fails before the loop runs.
  std::vector<Vector> offsets;
  for (std::size_t i = 0; i < dm_offsets_m.size(); ++i) {
    const Image& w = dm_offsets_m[i];
    CheckArgument(w.rows() == n && w.cols() == n, fn, "dm_offsets_m[" + std::to_string(i) + "] shape",
                  ToString(ShapeOf(w)), ToString(Shape{n, n}) + " (the pupil grid)");
    try {
      offsets.push_back(wfs_->ReferenceOffsetForOpd(w));
    } catch (const InvalidArgument&) {
      throw InvalidArgument(fn, "dm_offsets_m[" + std::to_string(i) + "]", "non-finite values",
                            "finite values where the pupil transmits");
    }
  }
  const long steps = std::llround(exposure_s / t);
  const long settle = std::llround(settling_s / t);
  std::vector<ClosedLoopResult> results;
  for (const Vector& offset : offsets) {
    wfs_->SetReferenceOffset(offset);
    long remaining = settle;
    Eigen::Matrix2d gain = Eigen::Matrix2d::Identity();
    if (options_.offset_calibration == OffsetCalibration::kOnSky) {
      if (tilt_projector_.cols() == 0) CalibrateTiltResponse();
      // Probe the sensor's tip/tilt gain at the loop's operating point over the first half of the settling
      // (at least one frame), then rescale the offset's tip/tilt content so that the loop holds the
      // commanded tilt: with the measured tilt G T for a true tilt T, holding P o' = G P o gives T = P o.
      const long probe = std::max(1L, settle / 2);
      Eigen::Matrix2d sum = Eigen::Matrix2d::Zero();
      for (long k = 0; k < probe; ++k) {
        Step(false);
        sum += TiltGain(residual_);
      }
      gain = sum / static_cast<double>(probe);
      const Eigen::Vector2d tilt = tilt_projector_ * offset;
      wfs_->SetReferenceOffset(offset + tilt_response_ * ((gain - Eigen::Matrix2d::Identity()) * tilt));
      remaining = std::max(0L, settle - probe);
    }
    for (long k = 0; k < remaining; ++k) Step(false);
    // Settling frames run: `settle`, or the one probe frame when there was no settling.
    const bool probed_only = settle == 0 && options_.offset_calibration == OffsetCalibration::kOnSky;
    results.push_back(Record(steps, static_cast<int>(settle + (probed_only ? 1 : 0))));
    results.back().tilt_gain[0] = gain(0, 0);
    results.back().tilt_gain[1] = gain(1, 1);
    for (ClosedLoopResult& extra : results.back().extra_directions) {
      extra.tilt_gain[0] = gain(0, 0);
      extra.tilt_gain[1] = gain(1, 1);
    }
    if (after_each && !after_each(int(results.size()))) break;
  }
  return results;
}

}  // namespace aosr
