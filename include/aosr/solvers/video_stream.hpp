// Super-resolved video: one HR output for every new frame (a sliding window over the last frame of each DM
// phase) or one per full cycle of the phases, from a camera stream in which the DM cycles through N phases
// (slots). Frame j of the stream was taken through phase s_j; the model of slot s is the dataset's PSF of that
// phase (scene/dataset.hpp "sequence").
//
// ## Linear methods: the slot filter
//
// Tikhonov with a fixed λ and the target-PSF linear output are, on the periodic model with uniform weights,
// linear in the frames and equivariant under a shift of every frame by one camera pixel (which shifts the
// estimate by r HR pixels: the per-bin systems of core/forward_model.hpp only pick up a phase). Such a map from
// N real LR images to a real HR image is a sum of "upsampling convolutions",
//
//     x̂(p) = Σ_i Σ_q k_i(p − r q) y_i(q)     ⇔     X̂(f) = Σ_i K_i(f) Y_i(f mod m),                      (1)
//
// with K_i the HR spectrum of k_i, and k_i is the estimator's own output for frames that are all zero except
// a unit impulse at pixel (0, 0) of frame i (whose spectrum is 1 at every LR frequency). So the per-slot
// Fourier weights K_i are computed ONCE, by N runs of the batch estimator itself (no second implementation of
// either estimator's per-bin algebra, so the two cannot drift apart), and then each output costs
//   * one LR r2c FFT of the new frame (the other slots' spectra are cached),
//   * an N-term complex sum per HR frequency of the half spectrum, (1),
//   * one HR c2r FFT.
// Every output equals the batch Reconstruct of the same window to rounding (tested to 1e-10 of the peak:
// video_stream_test.cpp), and does not depend on the thread count (each HR row of (1) is one task). The sum
// reads the weights and the cached spectra slot-minor (both contiguous per bin); at 512², N = 4 it streams 8 MB
// of weights per output, which bounds its speed (bench/results/video.md).
//
// Where (1) does not hold the batch solver runs on the window instead (VideoFrame::path says which):
//   * weights that are not uniform over the window (a masked pixel, per-frame noise levels that differ,
//     source-dependent inverse variances): the estimator is then the weighted (CG) one, neither
//     shift-equivariant nor the same for every window;
//   * Tikhonov with a zero-padded boundary or the conjugate-gradient method asked for;
//   * VideoOptions::slot_filter = false.
// λ: with lambda_rule kFixed it is as given. Any other rule runs once, on the first complete window (by the
// batch, so that output is the batch's), and is then fixed as λ' = λ/w̄ (w̄ the window's mean positive weight):
// the filter of the unweighted frames, the same for every window, which is the λ the batch uses for a window of
// weight w̄ when given λ = λ' w̄ (VideoReconstructor::BatchOptions). A prior fitted to the frames (kFitted) or
// the Wiener rule would make the filter data-dependent and are refused. The linear output's κ comes from the
// model alone (target_psf.hpp): it is searched once, on the slot model (frames in slot order), and fixed;
// BatchOptions gives it to the batch. The batch's own search on a window whose frames come in another order
// lands up to ~1 % away in κ (~1e-3 of the peak in the image) on the 512² bench: its U_min counts Gram
// eigenvalues at rounding level as seen directions (target_psf.cpp kNullFloor), so it depends on the order of
// the frames (docs/video.md).
//
// ## TV: warm-started
//
// The first window is reconstructed as Reconstruct does (automatic μ from the Tikhonov pilot unless
// auto_regularisation is off, ADMM to tv.max_iterations / its tolerance). μ is then fixed, and every later
// output is TotalVariationAdmm on its window started from the previous output's whole ADMM state (x, the splits,
// their scaled duals and ρ: TotalVariationState; the second output, after the batch first window, from its x
// alone), stopped after tv_iterations ADMM iterations (or its tolerance). A static scene converges across frames; a changing one
// lags by about the frames the budget needs to follow it (bench/results/video.md measures the gap to TV run to
// convergence on the same window).
//
// API rules: options are validated (IsValid names the field) and frames checked on Push (shape, finiteness on
// weighted pixels: problem.hpp's rules); InvalidArgument names the function and argument. Nothing returns NaN.
#pragma once

#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "aosr/core/forward_model.hpp"
#include "aosr/scene/dataset.hpp"
#include "aosr/solvers/dataset_problem.hpp"
#include "aosr/solvers/problem.hpp"
#include "aosr/solvers/reconstruct.hpp"
#include "aosr/solvers/total_variation.hpp"

namespace aosr {

enum class VideoWindow { kSliding, kCycle };
const char* ToString(VideoWindow w);
VideoWindow ParseVideoWindow(const std::string& name);  // "sliding" | "cycle"; InvalidArgument otherwise

struct VideoOptions {
  // tikhonov | linear | tv.
  ReconstructionMethod method = ReconstructionMethod::kTikhonov;
  // kSliding: an output after every frame once each slot has one (the latest frame of each slot: the last N
  // frames of a regular cycle). kCycle: an output each time every slot has a new frame since the last output.
  VideoWindow window = VideoWindow::kSliding;
  // The method's options as Reconstruct takes them (tikhonov, linear, tv, auto_regularisation, progress).
  // Default: Reconstruct's (GCV λ once on the first window; κ by the leakage bound; automatic μ).
  ReconstructOptions reconstruct;
  // tv: ADMM iterations of each output after the first, warm-started from the previous output. >= 1. Measured
  // (bench/results/video.md, from the state): 10 within 0.10 dB (static scene) and 0.16 dB (moving) of TV to
  // convergence, 7 within 0.14 and 0.24 dB at 1.3-1.5x the rate.
  int tv_iterations = 10;
  // tv: start each output from the previous one's whole ADMM state (true) or from its x alone, with the splits
  // consistent with it and the duals at 0 (false: what TotalVariationAdmm's `initial` does; kept to compare).
  bool tv_warm_duals = true;
  // Use the slot filter where it is exact (top of the file). false: the batch solver on every window.
  bool slot_filter = true;

  bool IsValid(std::string* why) const;
};

struct VideoFrame {
  Image image;                // HR estimate, units of the frames per HR pixel, finite
  int index = 0;              // output number, 0-based
  double time_s = 0;          // time of the window's newest frame (when the output could first exist)
  double window_start_s = 0;  // time of its oldest frame
  std::vector<int> frames;    // the input frame (index given to Push) used for each slot, by slot
  // "slot-filter" (1), "batch" (the batch solver: first window's λ choice, or (1) not exact), "tv" (the first
  // TV window), "tv-warm".
  std::string path;
  int iterations = 0;        // tv: ADMM iterations of this output
  double seconds = 0;        // wall time of this output's computation (Push to return)
  SolverSummary summary;     // batch and tv outputs: the solver's; slot-filter: method "slot-filter"
};

// What was chosen once for the whole stream.
struct VideoSetup {
  double lambda_unweighted = -1;  // tikhonov: λ' of the filter (λ/w̄ of the first window); -1 until chosen
  double kappa = 0;               // linear: κ of the filter (target_psf.hpp), 0 until built
  double mu = -1;                 // tv: μ fixed after the first window; -1 until chosen
  bool filter_built = false;
  double filter_seconds = 0;      // the N impulse solves that made the slot filter
  int filter_outputs = 0, batch_outputs = 0;
};

// The per-slot Fourier weights K_i of (1) and the cached spectra of the latest frame of each slot.
class SlotFilter {
 public:
  // responses[i]: the estimator's HR output for a unit impulse at pixel (0, 0) of frame i (others zero), each
  // of shape r·lr.
  SlotFilter(Shape lr, int r, const ImageStack& responses);
  int slots() const { return n_; }
  // Caches frame `slot`'s spectrum (one LR FFT). The frame must have the LR shape and be finite.
  void SetFrame(int slot, const Image& frame);
  // (1) and the HR inverse FFT into *out (resized if needed). Every slot must have been set.
  void Output(Image* out);

 private:
  Shape lr_, hr_;
  int n_ = 0;
  Index hr_half_cols_ = 0;
  std::vector<Complex> weights_;   // per HR half-spectrum bin, n_ values (bin-major, slot-minor)
  std::vector<Complex> spectra_;   // the slots' full LR spectra: per LR bin (row-major), n_ values (slot-minor)
  std::vector<char> set_;
  ComplexImage lr_half_, hr_half_;
};

// The streaming engine: frames pushed one at a time.
class VideoReconstructor {
 public:
  // slot_model: one model frame per slot (frame i of the model is slot i), isoplanatic.
  VideoReconstructor(std::shared_ptr<const MultiFrameModel> slot_model, const VideoOptions& options);
  ~VideoReconstructor();

  // Frame `index` (the caller's numbering, reported back in VideoFrame::frames) of slot `slot` at time_s, in
  // the units the outputs take (e⁻ for datasets), with its inverse-variance weight map (empty: every pixel
  // weight 1; problem.hpp's rules: finite, >= 0, a pixel of weight 0 may hold NaN). Returns the output this
  // frame completes, if any.
  std::optional<VideoFrame> Push(int slot, int index, double time_s, const Image& frame, const Image& weight = {});

  // The problem of the last complete window (frames and weights by slot, the slot model): what the batch
  // reconstructs; and the options under which Reconstruct of it gives the same output (λ, κ, μ fixed as chosen;
  // for tv the iteration budget is not included: TV to convergence). Empty problem before the first output.
  ReconstructionProblem WindowProblem() const;
  ReconstructOptions BatchOptions(const ReconstructionProblem& window) const;

  const VideoSetup& setup() const { return setup_; }
  const VideoOptions& options() const { return options_; }
  const std::shared_ptr<const MultiFrameModel>& model() const { return model_; }

 private:
  struct Slot;
  VideoFrame Compute();
  bool WindowUniform(double* w0) const;
  bool FilterEligible() const;
  void BuildFilter();

  std::shared_ptr<const MultiFrameModel> model_;
  VideoOptions options_;
  std::vector<Slot> slots_;
  std::unique_ptr<SlotFilter> filter_;
  VideoSetup setup_;
  Image previous_;  // tv: the last output
  TotalVariationState tv_state_;  // tv: the last output's ADMM state (tv_warm_duals)
  int outputs_ = 0;
};

// A dataset with a sequence (or any dataset: its N frames are one cycle) as a stream of outputs.
class DatasetVideo {
 public:
  // problem: how frames become a problem (weights, nominal_psfs, model_psfs), as for ProblemFromDataset, with
  // these refused: stars_psfs and offsets kEstimate (models fitted to the frames), psf_field tiles/operator
  // (the slot filter is per-frequency over the whole field; the model is the dataset's single PSF per slot).
  // The weights are resolved once over all frames (WeightsFromDataset: e.g. the background variance pooled over
  // the sequence). frame_rate_hz (> 0) gives times index / rate when the dataset has no times.
  DatasetVideo(const Dataset& dataset, const VideoOptions& options, DatasetProblemOptions problem = {},
               double frame_rate_hz = 1.0);
  // The next output, or nothing when the frames are used up.
  std::optional<VideoFrame> Next();
  // A frame from outside the dataset, e.g. a live camera's (solvers/quick_look.hpp): raw counts (ADU) of phase
  // `slot`, converted as the dataset's frames are ((ADU − bias) · gain) and weighted as the dataset's first frame
  // of that phase is (its valid mask and the noise level resolved from the dataset's frames: the same detector).
  // `index` is the caller's frame number (VideoFrame::frames). InvalidArgument for a slot out of range or a
  // frame of another shape (VideoReconstructor::Push's checks).
  std::optional<VideoFrame> PushFrame(int slot, int index, double time_s, const Image& frame_adu);

  int slot_count() const { return int(slot_weight_.size()); }
  Shape frame_shape() const;

  int frames_total() const { return int(frames_e_.size()); }
  int frames_read() const { return next_; }
  double FrameTime(int frame) const;
  const std::string& weights_source() const { return weights_source_; }
  const std::string& warning() const { return warning_; }
  VideoReconstructor& engine() { return *engine_; }
  const VideoReconstructor& engine() const { return *engine_; }

 private:
  std::unique_ptr<VideoReconstructor> engine_;
  ImageStack frames_e_, weights_;
  std::vector<int> slots_;
  std::vector<double> times_;
  std::vector<int> slot_weight_;  // per slot: the frame whose weight map PushFrame uses
  double gain_e_per_adu_ = 1, bias_adu_ = 0;
  std::string weights_source_, warning_;
  int next_ = 0;
};

}  // namespace aosr
