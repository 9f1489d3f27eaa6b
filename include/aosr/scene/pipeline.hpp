// The simulator: a scene (scene_spec.hpp) compiled into the ordered stages of DESIGN.md §1,
//
//     y_i = D_r( h_i ⊛ x ) + n_i ,
//
// building only the stages the scene enables and computing what is identical across exposures once.
//
// ## Stages (in order; a stage the scene does not enable is absent from the plan and never runs)
//
//   object             each component rendered on the HR frame (r·rows × r·cols) in electrons per frame;
//                      stars stay a catalogue (no image is gridded for the frames)
//   static-aberrations w_static = Σ a_j Z_j on the pupil (only if the scene lists any)
//   dm-offsets         w_dm,i per exposure: tip/tilt for the shift, Zernike terms, actuator commands
//                      (only if some exposure has a non-zero offset)
//   ao-loop            closed-loop Monte-Carlo (atmosphere phase screens, WFS, controller, DM) producing
//                      each exposure's long-exposure PSF (only for ao.mode = closed-loop)
//   psf                h_i at HR sampling, psf_size² window, normalised to unit sum: diffraction, or the
//                      analytic AO residual model, or the loop's average; computed once per *distinct*
//                      pupil OPD (a static PSF is computed once and shared by all exposures)
//   convolution        extended components: one r2c FFT of the padded object, then per distinct PSF one
//                      product and one c2r FFT (only if the scene has an extended component)
//   point-sources      stars: the exact sub-pixel-shifted PSF of each star, summed in the Fourier domain
//                      (point_sources.hpp); a stars-only scene does no r2c FFT of an object image
//   pixel-integration  crop of the padded grid to the frame, then D_r with the fill factor
//   detector           photon/read/peak-fraction noise, background, dark current, ADU conversion,
//                      saturation, bad pixels, quantisation (Detector::Plan lists the enabled ones)
//
// ## A sky finer than the HR grid (SceneSpec::sky_oversampling = s > 1)
//
// The stages above then run on a grid s times finer than the HR grid (r·s per camera pixel): the object is
// rendered there (flux normalisations apply to the sky integrated over HR pixels, so `peak_e` means the same
// as at s = 1), the PSFs are sampled at θ_hr/s over the same angular window, and each camera pixel integrates
// its (r·s)² fine pixels. Everything a caller sees is on the HR grid again: Simulation::truth is the fine sky
// summed over each HR pixel (stars: deposited bilinearly on the fine grid, then summed), the stars are in HR
// coordinates, and psfs (nominal_psfs) are the fine PSFs' samples at the HR pixel centres (every s-th sample,
// the centred-kernel convention of image.hpp puts them there), renormalised to unit sum: the same numbers
// ComputePsfs gives, to rounding. The frames then differ from an s = 1 simulation only by the sky's and the
// image's structure between HR samples, which is what this option is for: the HR model y = D_r(h ⊛ x) is
// exact for a sky that is a grid of HR pixels, not for a continuous one. With a PSF band-limited at the HR
// grid (HR pixel <= λ/2D) and a sky smooth at the HR pitch the two agree (tests/scene/pipeline_physics_test.cpp).
//
// ## Boundaries
//
// The object lives on the HR frame and is dark outside it. Convolution runs on that frame padded by at least
// half the PSF window on every side (rounded up to a size FFTW likes), so the frames carry no periodic
// wrap-around: a noiseless frame is exactly D_r(Crop(h_i * x)) with * the linear (zero-padded) convolution of
// the windowed PSF. Light of objects within half a PSF window of the frame edge spills out of the frame and
// is lost, as on a real detector; a reconstructor that assumes periodic boundaries is wrong there.
// SceneGeometry::trustworthy_border_px states that band (camera pixels, ceil(psf_size / 2 / r)).
//
// ## Flux
//
// Unit-sum PSF kernels conserve flux through the convolution; the crop loses only the light that leaves the
// frame; D_r and the detector's conversion conserve it (tests/scene/pipeline_physics_test.cpp: 1e-10). The
// PSF's light beyond its window is folded into the window by the unit-sum normalisation; Simulation reports
// how much that was (psf_window_fraction).
//
// ## Cost
//
// Compiling (the ScenePipeline constructor) loads files and builds nothing expensive: no PSF, FFT plan or
// phase screen. PipelineStage::estimated_s is a model (flop counts at nominal rates, stated in pipeline.cpp),
// compared with measured times in bench/simulate_bench.cpp.
#pragma once

#include <cstdint>
#include <array>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "aosr/core/image.hpp"
#include "aosr/core/progress.hpp"
#include "aosr/optics/deformable_mirror.hpp"
#include "aosr/scene/detector.hpp"
#include "aosr/scene/objects.hpp"
#include "aosr/scene/scene_spec.hpp"

namespace aosr {

struct SceneGeometry {
  int r = 1;
  Shape frame;        // camera pixels
  Shape hr_frame;     // r·frame
  Shape padded;       // the convolution grid (HR), >= hr_frame + psf_size on each axis
  Index pad_top = 0;  // where hr_frame starts inside padded
  Index pad_left = 0;
  Index psf_size = 0;  // PSF window side, HR pixels (even)
  double camera_pixel_rad = 0.0;
  double hr_pixel_rad = 0.0;
  double hr_pixel_lambda_over_d = 0.0;
  double wavelength_m = 0.0;
  // Camera pixels from each frame edge within which a periodic model of the frame alone is not exact
  // (light from inside leaves the frame; see the top of the file).
  Index trustworthy_border_px = 0;
};

// One compiled stage.
struct PipelineStage {
  std::string name;          // one of the names at the top of the file
  std::string detail;        // what it does at this scene's sizes
  int count = 1;             // how many times it runs (e.g. distinct PSFs)
  double estimated_s = 0.0;  // cost model, seconds on one core
};

struct StageTiming {
  std::string name;
  double seconds = 0.0;
};

// What a run actually computed: tests use these to prove that disabled effects cost nothing.
struct SimulationCounters {
  int object_components = 0;     // components rendered
  int psfs_computed = 0;         // distinct PSFs (or loop sub-exposures) computed
  int object_transforms = 0;     // r2c FFTs of an object image (0 for stars-only scenes)
  int frame_transforms = 0;      // c2r FFTs producing convolved HR images (one per distinct PSF)
  int loop_steps = 0;            // closed-loop frames run (0 unless ao.mode = closed-loop)
  std::uint64_t fft_executions = 0;   // core/fft.hpp transforms during Run (FftExecutionCount delta)
  std::uint64_t phase_screens = 0;    // phase screens generated during Run (PhaseScreensGenerated delta)
  std::int64_t noise_draws = 0;       // random numbers drawn by the detector
};

struct Simulation {
  SceneGeometry geometry;
  Image truth;                     // the object on the HR frame, electrons per frame per HR pixel; stars are
                                   // deposited bilinearly (non-negative, flux and centroid kept)
  std::vector<PointSource> stars;  // stars in HR-frame pixel coordinates, electrons per frame: the exact truth
                                   // (a sequence's changing stars are only in truth_frames)
  // A sequence (scene_spec.hpp, SequenceSpec): each exposure's mid-time [s]; and when objects change, the
  // truth at each exposure (as `truth`, which is then their mean: what one reconstruction of the whole
  // sequence estimates). Empty otherwise.
  std::vector<double> times_s;
  ImageStack truth_frames;
  ImageStack psfs;                 // h_i, psf_size², centred (image.hpp), unit sum; one per exposure (M of a sequence)
  ImageStack nominal_psfs;         // closed loop only: NominalPsfs(scene), the model a reconstructor would use (one
                                   // per phase: N)
  std::vector<int> distinct_psf;   // exposure i used distinct PSF distinct_psf[i]
  std::vector<double> psf_window_fraction;  // light of h_i inside its window before normalisation
  // Strehl of h_i about its own centre: diffraction and analytic modes exclude the OPD's tip/tilt (a designed
  // shift is not a loss of quality; analytic: the residual's Strehl times the static OPD's); closed loop: the
  // loop's mean on-axis Strehl, which includes the offset's tilt.
  std::vector<double> strehl;
  // Closed loop with ao.offset_calibration "on-sky" only (else empty): per exposure, the (y, x) tip/tilt gain
  // of the wavefront sensor its offset was calibrated with (ClosedLoopResult::tilt_gain); provenance.
  std::vector<std::array<double, 2>> tilt_gain;
  // psf_field only (scene_spec.hpp, PsfFieldSpec; empty otherwise): the grid of field points on the HR frame,
  // each node's direction from the guide star, and per node k the exposures' PSFs field_psfs[k][i] (unit sum,
  // psfs' window), their Strehl ratios, and (closed loop) the nominal model's field_nominal_psfs[k][i]. The
  // frames are rendered through these (core/psf_field.hpp); psfs (and nominal_psfs) are then the guide
  // star's direction: the single-PSF model of a reconstructor that ignores the field.
  PsfFieldGrid field_grid;
  std::vector<FieldDirection> field_directions;
  std::vector<ImageStack> field_psfs;
  std::vector<ImageStack> field_nominal_psfs;
  std::vector<std::vector<double>> field_strehl;
  ImageStack expected_e;           // noiseless frames, electrons
  std::vector<DetectorFrame> frames;
  std::vector<StageTiming> timings;
  SimulationCounters counters;
  double seconds = 0.0;
  // Run's progress callback asked to stop: the simulation is incomplete (the stages after the report are
  // missing, e.g. no frames) and must not be used as a dataset.
  bool cancelled = false;
};

class ScenePipeline {
 public:
  // Compiles `scene` (already validated by the parser). Throws InvalidArgument for what only the built
  // optics can check (e.g. a design's actuator count against the DM).
  explicit ScenePipeline(SceneSpec scene);

  const SceneSpec& scene() const { return scene_; }
  const SceneGeometry& geometry() const { return geometry_; }
  // The enabled stages in order.
  const std::vector<PipelineStage>& stages() const { return stages_; }
  // One line per stage: name, count, estimated time, detail; then the total and the peak memory.
  std::string PlanReport() const;
  // The peak memory of Run() in bytes, estimated from the sizes alone (pipeline.cpp, EstimatePeakBytes). The
  // constructor refuses (ResourceError) a scene whose estimate exceeds the memory limit (core/memory.hpp).
  double estimated_peak_bytes() const { return estimated_peak_bytes_; }

  // Runs every stage. Deterministic for a given scene (seeds in the scene). `progress` (core/progress.hpp),
  // when set, is called with stage "simulate" after the object, after each distinct PSF (for the closed loop:
  // each sub-exposure), and after each later stage (iteration k of `total` steps; no value); returning false
  // stops the run there with Simulation::cancelled set. It never changes the result.
  Simulation Run(const ProgressCallback& progress = {}) const;

  // The stages before the detector, for callers that need only part of the chain (real data needs the
  // PSFs; tests need the noiseless frames).
  // The object on the HR frame (stars deposited bilinearly) and the star catalogue.
  Image RenderTruth(std::vector<PointSource>* stars) const;
  // h_i of every exposure (unit sum), with the distinct-PSF map, window fractions and Strehl ratios. With a
  // psf_field these are the guide star's direction (on axis).
  ImageStack ComputePsfs(std::vector<int>* distinct, std::vector<double>* window_fraction,
                         std::vector<double>* strehl, SimulationCounters* counters = nullptr) const;
  // psf_field only: the exposures' PSFs at every node of the grid (result[k][i]), with their Strehl ratios.
  std::vector<ImageStack> ComputeFieldPsfs(std::vector<std::vector<double>>* strehl,
                                           SimulationCounters* counters = nullptr) const;
  // psf_field only: the grid and its nodes' directions from the guide star (those of the HR grid also when
  // the scene renders on a finer sky).
  const PsfFieldGrid& field_grid() const { return field_grid_; }
  const std::vector<FieldDirection>& field_directions() const { return field_directions_; }

 private:
  // ComputePsfs for each of `directions`: out[k] and (*strehl)[k] direction k's (window_fraction and tilt_gain
  // are directions[0]'s). The closed loop records them all in one run (closed_loop.hpp, "Off axis"); the
  // analytic and diffraction PSFs are computed per direction. Calls `step` after each distinct PSF (with the
  // number of directions after each sub-exposure of the closed loop); a `step` that returns false stops it
  // early (then it returns no PSFs).
  std::vector<ImageStack> ComputeDirectionPsfs(const std::vector<FieldDirection>& directions, std::vector<int>* distinct,
                                               std::vector<double>* window_fraction,
                                               std::vector<std::vector<double>>* strehl, SimulationCounters* counters,
                                               const std::function<bool(int)>& step,
                                               std::vector<std::array<double, 2>>* tilt_gain) const;
  std::vector<ImageStack> ComputeFieldPsfs(std::vector<std::vector<double>>* strehl, SimulationCounters* counters,
                                           const std::function<bool(int)>& step) const;
  void Compile();
  // The extended components summed on the HR frame, and the stars (HR-frame coordinates), flux-scaled.
  Image RenderObject(std::vector<PointSource>* stars) const;

  SceneSpec scene_;
  SceneGeometry geometry_;
  // sky_oversampling > 1: the same scene at r·s (PSF window s times the samples), which renders the frames;
  // Run maps its outputs back to the HR grid.
  std::shared_ptr<const ScenePipeline> fine_;
  // Set on fine_ only: component flux normalisations use the sky summed over flux_binning_² pixels (the HR
  // pixels), so a peak normalisation means the same as on the HR grid.
  int flux_binning_ = 1;
  std::vector<PipelineStage> stages_;
  std::vector<int> distinct_;  // exposure -> distinct OPD group (all 0..N-1 for the closed loop)
  int distinct_count_ = 0;
  double estimated_peak_bytes_ = 0.0;
  bool has_extended_ = false;
  bool has_stars_ = false;
  // psf_field: the HR grid (a fine_ pipeline gets its parent's, field_scale_ = sky_oversampling: its frame is
  // field_scale_ times finer than the grid's), the nodes' directions, and the largest |direction| (the closed
  // loop's screens are built for it in every run, so that all directions see one atmosphere).
  PsfFieldGrid field_grid_;
  std::vector<FieldDirection> field_directions_;
  int field_scale_ = 1;
  double field_max_angle_rad_ = 0.0;
};

// The psf_field's nominal model PSFs of a closed-loop scene, per node (NominalPsfs at each node's direction);
// empty for other modes or without psf_field.
std::vector<ImageStack> NominalFieldPsfs(const SceneSpec& scene);

// The nominal model PSFs of a closed-loop scene's exposures: those of the same scene with the Monte-Carlo loop
// replaced by the analytic long-exposure AO residual (same telescope, AO system, atmosphere, static
// aberrations and offsets), unit sum, the scene's PSF window. Empty for any other AO mode (the simulated PSFs
// are then the model). Reconstructing closed-loop frames with these measures the cost of PSF mismatch. The
// scene's ao.dm_gain (a hardware stroke error) is not modelled: the nominal model assumes the DM does what it
// is told. Static aberrations are modelled: a non-common-path aberration unknown to the observer is one that
// the truth's scene lists and the model's does not (bench/psf_knowledge.py). A noisy guide-star WFS (the
// preset's photon_noise / read_noise_e, with the diffractive sensor) is modelled too: the analytic noise term is
// measured through that sensor and reconstructor (TelescopePreset::ToAnalyticAo).
ImageStack NominalPsfs(const SceneSpec& scene);

// The pupil OPD [m] of one exposure: tip/tilt for the offset's shift (zernike.hpp, a = shift·D/4), its
// Zernike terms, the DM commands through `dm` (may be null when the offset has none), plus w_static
// (empty for none). On the telescope's pupil_px grid.
Image ExposureOpd(const SceneSpec& scene, const DmOffset& offset, const Image& static_opd_m,
                  const DeformableMirror* dm);

}  // namespace aosr
