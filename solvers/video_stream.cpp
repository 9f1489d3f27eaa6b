// Streaming super-resolution (video_stream.hpp): the slot filter from the batch estimator's impulse responses,
// the window bookkeeping, the batch fallback, warm-started TV, and a dataset as a stream.
#include "aosr/solvers/video_stream.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>

#include "aosr/core/error.hpp"
#include "aosr/core/fft.hpp"
#include "aosr/core/parallel.hpp"
#include "aosr/solvers/target_psf.hpp"
#include "aosr/solvers/tikhonov.hpp"
#include "aosr/solvers/total_variation.hpp"

namespace aosr {
namespace {

constexpr const char* kVideoPushFn = "VideoReconstructor::Push";

double VideoSecondsSince(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

// The common value of a weight map when it is constant and positive, else NaN.
double VideoUniformValue(const Image& w) {
  if (w.size() == 0) return 1.0;
  const double v = w(0, 0);
  if (!(v > 0) || !std::isfinite(v) || !(w == v).all()) return std::numeric_limits<double>::quiet_NaN();
  return v;
}

double VideoMeanPositiveWeight(const ReconstructionProblem& p) {
  if (p.weights.empty()) return 1.0;
  double sum = 0;
  Index count = 0;
  for (const Image& w : p.weights) {
    sum += (w > 0).select(w, 0.0).sum();
    count += (w > 0).count();
  }
  return count > 0 ? sum / double(count) : 1.0;
}

}  // namespace

const char* ToString(VideoWindow w) { return w == VideoWindow::kSliding ? "sliding" : "cycle"; }

VideoWindow ParseVideoWindow(const std::string& name) {
  if (name == "sliding") return VideoWindow::kSliding;
  if (name == "cycle") return VideoWindow::kCycle;
  throw InvalidArgument("ParseVideoWindow", "window", name, "sliding | cycle");
}

bool VideoOptions::IsValid(std::string* why) const {
  auto fail = [why](const std::string& m) {
    if (why) *why = m;
    return false;
  };
  if (method != ReconstructionMethod::kTikhonov && method != ReconstructionMethod::kLinear &&
      method != ReconstructionMethod::kTotalVariation)
    return fail(std::string("method = ") + ToString(method) + "; allowed: tikhonov | linear | tv");
  if (tv_iterations < 1) return fail("tv_iterations = " + std::to_string(tv_iterations) + "; allowed: >= 1");
  std::string w;
  if (!reconstruct.tikhonov.IsValid(&w)) return fail("reconstruct.tikhonov." + w);
  if (method == ReconstructionMethod::kTikhonov) {
    if (reconstruct.tikhonov.prior == TikhonovPrior::kFitted || reconstruct.tikhonov.lambda_rule == TikhonovLambdaRule::kWiener)
      return fail("reconstruct.tikhonov: prior fitted / λ rule wiener fit the spectrum to each window's frames, which "
                  "makes the filter data-dependent; allowed: a fixed prior (gradient, laplacian, identity, power-spectrum)");
    if (reconstruct.tikhonov.compute_std)
      return fail("reconstruct.tikhonov.compute_std = true; allowed: false (a video has no posterior std map)");
  }
  if (method == ReconstructionMethod::kLinear && !reconstruct.linear.IsValid(&w)) return fail("reconstruct.linear." + w);
  if (method == ReconstructionMethod::kTotalVariation && !reconstruct.tv.IsValid(&w)) return fail("reconstruct.tv." + w);
  return true;
}

// ---- SlotFilter ---------------------------------------------------------------------------------------------

SlotFilter::SlotFilter(Shape lr, int r, const ImageStack& responses)
    : lr_(lr), hr_{lr.rows * r, lr.cols * r}, n_(int(responses.size())) {
  constexpr const char* kFn = "SlotFilter";
  CheckArgument(r >= 1 && lr.rows > 0 && lr.cols > 0, kFn, "lr, r", ToString(lr) + ", " + std::to_string(r),
                "a non-empty LR shape and r >= 1");
  CheckArgument(n_ > 0, kFn, "responses", 0, "one impulse response per slot");
  hr_half_cols_ = hr_.cols / 2 + 1;
  weights_.resize(std::size_t(hr_.rows) * std::size_t(hr_half_cols_) * std::size_t(n_));
  for (int i = 0; i < n_; ++i) {
    CheckArgument(ShapeOf(responses[i]) == hr_ && AllFinite(responses[i]), kFn,
                  "responses[" + std::to_string(i) + "]", ToString(ShapeOf(responses[i])),
                  "a finite image of the HR shape " + ToString(hr_));
    const ComplexImage k = FftR2C(responses[i]);
    for (Index fy = 0; fy < hr_.rows; ++fy)
      for (Index fx = 0; fx < hr_half_cols_; ++fx)
        weights_[(std::size_t(fy) * std::size_t(hr_half_cols_) + std::size_t(fx)) * std::size_t(n_) + std::size_t(i)] =
            k(fy, fx);
  }
  spectra_.assign(std::size_t(lr.rows) * std::size_t(lr.cols) * std::size_t(n_), Complex(0, 0));
  set_.assign(std::size_t(n_), 0);
  hr_half_.resize(hr_.rows, hr_half_cols_);
}

void SlotFilter::SetFrame(int slot, const Image& frame) {
  CheckArgument(slot >= 0 && slot < n_, "SlotFilter::SetFrame", "slot", slot, "0.." + std::to_string(n_ - 1));
  CheckArgument(ShapeOf(frame) == lr_, "SlotFilter::SetFrame", "frame", ToString(ShapeOf(frame)),
                "the LR shape " + ToString(lr_));
  FftR2CInto(frame, &lr_half_);
  // The full spectrum from the half one (Hermitian symmetry of a real frame), so that (1) reads Y(f mod m) with
  // no conjugation test in its loop; stored slot-minor (spectra_ below), beside the other slots' values.
  const Index hc = lr_half_.cols();
  const std::size_t n = std::size_t(n_);
  Complex* full = spectra_.data() + std::size_t(slot);
  for (Index uy = 0; uy < lr_.rows; ++uy) {
    const Index my = (lr_.rows - uy) % lr_.rows;
    Complex* row = full + std::size_t(uy) * std::size_t(lr_.cols) * n;
    for (Index ux = 0; ux < lr_.cols; ++ux)
      row[std::size_t(ux) * n] = ux < hc ? lr_half_(uy, ux) : std::conj(lr_half_(my, lr_.cols - ux));
  }
  set_[std::size_t(slot)] = 1;
}

void SlotFilter::Output(Image* out) {
  for (int i = 0; i < n_; ++i)
    CheckArgument(set_[std::size_t(i)] != 0, "SlotFilter::Output", "slot " + std::to_string(i), "no frame",
                  "a frame for every slot (SetFrame)");
  const std::size_t n = std::size_t(n_);
  // (1), one HR row per task. Both operands are slot-minor, so the N-term sum reads two contiguous runs; the
  // complex products are written out in real arithmetic (std::complex's operator* calls __muldc3 for its
  // C99 Annex G infinity rules, several times slower, and the operands here are finite). The order of the
  // additions is fixed (slot 0 first), so the bytes do not depend on the thread count.
  ParallelFor(hr_.rows, [&](Index fy) {
    const Index uy = fy % lr_.rows;
    const double* w = reinterpret_cast<const double*>(weights_.data() + std::size_t(fy) * std::size_t(hr_half_cols_) * n);
    const double* srow = reinterpret_cast<const double*>(spectra_.data() + std::size_t(uy) * std::size_t(lr_.cols) * n);
    Complex* o = &hr_half_(fy, 0);
    for (Index fx0 = 0; fx0 < hr_half_cols_; fx0 += lr_.cols) {
      // HR columns fx0 .. fx0 + run - 1 read LR columns 0 .. run - 1 (f mod m).
      const Index run = std::min<Index>(lr_.cols, hr_half_cols_ - fx0);
      const double* wk = w + 2 * std::size_t(fx0) * n;
      for (Index ux = 0; ux < run; ++ux) {
        const double* a = wk + 2 * std::size_t(ux) * n;
        const double* b = srow + 2 * std::size_t(ux) * n;
        double re = 0, im = 0;
        for (std::size_t i = 0; i < 2 * n; i += 2) {
          re += a[i] * b[i] - a[i + 1] * b[i + 1];
          im += a[i] * b[i + 1] + a[i + 1] * b[i];
        }
        o[fx0 + ux] = Complex(re, im);
      }
    }
  });
  FftC2RInto(hr_half_, hr_.cols, out);
}

// ---- VideoReconstructor -------------------------------------------------------------------------------------

struct VideoReconstructor::Slot {
  bool present = false;
  bool fresh = false;  // a frame since the last output (cycle windows)
  bool spectrum_current = false;
  int index = -1;
  double time_s = 0;
  Image frame, weight;
  double uniform = 1.0;  // the weight map's common value, or NaN
};

VideoReconstructor::VideoReconstructor(std::shared_ptr<const MultiFrameModel> slot_model, const VideoOptions& options)
    : model_(std::move(slot_model)), options_(options) {
  constexpr const char* kFn = "VideoReconstructor";
  CheckArgument(model_ != nullptr, kFn, "slot_model", "null", "the model of the N phases");
  CheckArgument(!model_->space_variant(), kFn, "slot_model", "space-variant",
                "an isoplanatic model (one PSF per slot): the slot filter is per-frequency over the whole field");
  std::string why;
  if (!options_.IsValid(&why)) throw InvalidArgument(std::string(kFn) + ": options." + why);
  slots_.resize(std::size_t(model_->frames()));
}

VideoReconstructor::~VideoReconstructor() = default;

bool VideoReconstructor::WindowUniform(double* w0) const {
  const double v = slots_.front().uniform;
  for (const Slot& s : slots_)
    if (!(s.uniform == v)) return false;  // NaN compares false
  *w0 = v;
  return true;
}

bool VideoReconstructor::FilterEligible() const {
  if (!options_.slot_filter) return false;
  if (options_.method == ReconstructionMethod::kLinear) return true;
  if (options_.method != ReconstructionMethod::kTikhonov) return false;
  const TikhonovOptions& t = options_.reconstruct.tikhonov;
  return t.boundary == TikhonovBoundary::kPeriodic && t.method != TikhonovMethod::kConjugateGradient;
}

ReconstructionProblem VideoReconstructor::WindowProblem() const {
  ReconstructionProblem p;
  if (outputs_ == 0) return p;
  p.model = model_;
  bool any_weight = false;
  for (const Slot& s : slots_) any_weight = any_weight || s.weight.size() > 0;
  for (const Slot& s : slots_) {
    p.frames.push_back(s.frame);
    if (any_weight) p.weights.push_back(s.weight.size() ? s.weight : Image::Ones(s.frame.rows(), s.frame.cols()));
  }
  return p;
}

ReconstructOptions VideoReconstructor::BatchOptions(const ReconstructionProblem& window) const {
  ReconstructOptions o = options_.reconstruct;
  o.method = options_.method;
  if (options_.method == ReconstructionMethod::kTikhonov && setup_.lambda_unweighted >= 0) {
    o.tikhonov.lambda_rule = TikhonovLambdaRule::kFixed;
    o.tikhonov.lambda = setup_.lambda_unweighted * VideoMeanPositiveWeight(window);
  }
  // The linear output's κ as the stream fixed it (the search on the model in slot order): the batch's own search
  // on the same frames in another order lands up to ~1 % away (video.md), so "the same output" needs it given.
  if (options_.method == ReconstructionMethod::kLinear && setup_.kappa > 0) o.linear.kappa = setup_.kappa;
  if (options_.method == ReconstructionMethod::kTotalVariation && setup_.mu >= 0) {
    o.auto_regularisation = false;
    o.tv.mu = setup_.mu;
  }
  return o;
}

void VideoReconstructor::BuildFilter() {
  const auto t0 = std::chrono::steady_clock::now();
  const Shape lr = model_->lr_shape();
  const int n = model_->frames();
  ImageStack responses;
  for (int i = 0; i < n; ++i) {
    ImageStack frames(std::size_t(n), Image::Zero(lr.rows, lr.cols));
    frames[std::size_t(i)](0, 0) = 1.0;
    if (options_.method == ReconstructionMethod::kTikhonov) {
      TikhonovOptions t = options_.reconstruct.tikhonov;
      t.lambda_rule = TikhonovLambdaRule::kFixed;
      t.lambda = setup_.lambda_unweighted;
      t.compute_std = false;
      t.count_unconstrained = false;
      t.progress = nullptr;
      responses.push_back(TikhonovFourier(*model_, frames, t));
    } else {
      ReconstructionProblem p;
      p.model = model_;
      p.frames = std::move(frames);
      TargetPsfOptions t = options_.reconstruct.linear;
      t.compute_noise = false;
      if (setup_.kappa > 0) t.kappa = setup_.kappa;  // κ of the first impulse: the search is the same each time
      TargetPsfResult r = ReconstructTargetPsf(p, t);
      if (r.summary.termination == Termination::kFailed)
        throw InvalidArgument("VideoReconstructor: the linear output's impulse response failed: " + r.summary.message);
      setup_.kappa = r.summary.kappa;
      responses.push_back(std::move(r.image));
    }
  }
  filter_ = std::make_unique<SlotFilter>(lr, model_->r(), responses);
  for (Slot& s : slots_) s.spectrum_current = false;
  setup_.filter_built = true;
  setup_.filter_seconds = VideoSecondsSince(t0);
}

std::optional<VideoFrame> VideoReconstructor::Push(int slot, int index, double time_s, const Image& frame,
                                                   const Image& weight) {
  const auto t0 = std::chrono::steady_clock::now();
  const int n = model_->frames();
  const Shape lr = model_->lr_shape();
  CheckArgument(slot >= 0 && slot < n, kVideoPushFn, "slot", slot, "0.." + std::to_string(n - 1) + " (the model's phases)");
  CheckArgument(std::isfinite(time_s), kVideoPushFn, "time_s", time_s, "a finite time");
  CheckArgument(ShapeOf(frame) == lr, kVideoPushFn, "frame", ToString(ShapeOf(frame)), "the LR shape " + ToString(lr));
  if (weight.size()) {
    CheckArgument(ShapeOf(weight) == lr, kVideoPushFn, "weight", ToString(ShapeOf(weight)),
                  "empty (uniform) or the LR shape " + ToString(lr));
    CheckArgument(AllFinite(weight) && (weight >= 0).all(), kVideoPushFn, "weight", "non-finite or negative values",
                  "finite and >= 0");
    CheckArgument(((weight == 0) || frame.isFinite()).all(), kVideoPushFn, "frame " + std::to_string(index),
                  "a non-finite pixel of positive weight", "finite values where the weight is > 0");
  } else {
    CheckArgument(AllFinite(frame), kVideoPushFn, "frame " + std::to_string(index), "non-finite values",
                  "finite values (or a weight map of 0 where they are not)");
  }
  Slot& s = slots_[std::size_t(slot)];
  s.present = s.fresh = true;
  s.spectrum_current = false;
  s.index = index;
  s.time_s = time_s;
  s.frame = frame;
  s.weight = weight;
  s.uniform = VideoUniformValue(weight);
  for (const Slot& o : slots_)
    if (!(options_.window == VideoWindow::kSliding ? o.present : o.fresh)) return std::nullopt;
  VideoFrame out = Compute();
  if (options_.window == VideoWindow::kCycle)
    for (Slot& o : slots_) o.fresh = false;
  out.seconds = VideoSecondsSince(t0);
  return out;
}

VideoFrame VideoReconstructor::Compute() {
  VideoFrame out;
  out.index = outputs_++;
  out.time_s = -std::numeric_limits<double>::infinity();
  out.window_start_s = std::numeric_limits<double>::infinity();
  for (const Slot& s : slots_) {
    out.frames.push_back(s.index);
    out.time_s = std::max(out.time_s, s.time_s);
    out.window_start_s = std::min(out.window_start_s, s.time_s);
  }
  double w0 = 1.0;
  const bool uniform = WindowUniform(&w0);

  // The window as a batch problem (copies of its frames and weights) only where a batch solver runs: the slot
  // filter reads the cached spectra alone.
  if (options_.method == ReconstructionMethod::kTotalVariation) {
    const ReconstructionProblem window = WindowProblem();
    if (setup_.mu < 0) {
      ReconstructOptions o = BatchOptions(window);
      Reconstruction r = Reconstruct(window, o);
      setup_.mu = r.regularisation;
      out.image = std::move(r.image);
      out.summary = r.summary;
      out.iterations = r.summary.iterations;
      out.path = "tv";
    } else {
      TotalVariationOptions tv = options_.reconstruct.tv;
      tv.mu = setup_.mu;
      tv.max_iterations = options_.tv_iterations;
      if (options_.reconstruct.progress) tv.progress = options_.reconstruct.progress;
      TotalVariationSummary s;
      const bool resume = options_.tv_warm_duals && !tv_state_.empty();
      out.image = TotalVariationAdmm(window, tv, &s, resume ? nullptr : &previous_,
                                     options_.tv_warm_duals ? &tv_state_ : nullptr);
      out.summary = s;
      out.iterations = s.iterations;
      out.path = "tv-warm";
    }
    previous_ = out.image;
    ++setup_.batch_outputs;
    return out;
  }

  const bool need_lambda = options_.method == ReconstructionMethod::kTikhonov && setup_.lambda_unweighted < 0;
  if (need_lambda && options_.reconstruct.tikhonov.lambda_rule == TikhonovLambdaRule::kFixed)
    setup_.lambda_unweighted = options_.reconstruct.tikhonov.lambda / VideoMeanPositiveWeight(WindowProblem());
  if ((need_lambda && setup_.lambda_unweighted < 0) || !uniform || !FilterEligible()) {
    // The batch solver: the first window's λ choice, or a window (1) does not hold for.
    const ReconstructionProblem window = WindowProblem();
    Reconstruction r = Reconstruct(window, BatchOptions(window));
    if (options_.method == ReconstructionMethod::kTikhonov && setup_.lambda_unweighted < 0)
      setup_.lambda_unweighted = r.regularisation / VideoMeanPositiveWeight(window);
    if (options_.method == ReconstructionMethod::kLinear && setup_.kappa == 0) setup_.kappa = r.regularisation;
    out.image = std::move(r.image);
    out.summary = r.summary;
    out.iterations = r.summary.iterations;
    out.path = "batch";
    ++setup_.batch_outputs;
    return out;
  }
  if (!filter_) BuildFilter();
  for (int i = 0; i < int(slots_.size()); ++i) {
    Slot& s = slots_[std::size_t(i)];
    if (!s.spectrum_current) {
      filter_->SetFrame(i, s.frame);
      s.spectrum_current = true;
    }
  }
  filter_->Output(&out.image);
  out.summary.method = "slot-filter";
  out.summary.termination = Termination::kConverged;
  out.path = "slot-filter";
  ++setup_.filter_outputs;
  return out;
}

// ---- DatasetVideo -------------------------------------------------------------------------------------------

DatasetVideo::DatasetVideo(const Dataset& d, const VideoOptions& options, DatasetProblemOptions problem,
                           double frame_rate_hz) {
  constexpr const char* kFn = "DatasetVideo";
  std::string why;
  if (!options.IsValid(&why)) throw InvalidArgument(std::string(kFn) + ": options." + why);
  CheckArgument(!d.frames.empty(), kFn, "dataset", d.manifest_path, "a dataset with frames");
  CheckArgument(d.times_s.size() == d.frames.size() || (std::isfinite(frame_rate_hz) && frame_rate_hz > 0), kFn,
                "frame_rate_hz", frame_rate_hz, "> 0 (the dataset has no frame times)");
  CheckArgument(!problem.stars_psfs, kFn, "problem.stars_psfs", "true",
                "false: a video's model is the dataset's PSFs, made once (not fitted to each window's frames)");
  CheckArgument(problem.offsets != DatasetOffsets::kEstimate, kFn, "problem.offsets", "estimate",
                "auto, dm or centroids: registration would fit the model to each window's frames");
  CheckArgument(problem.psf_field == DatasetPsfField::kAuto || problem.psf_field == DatasetPsfField::kNone, kFn,
                "problem.psf_field", ToString(problem.psf_field),
                "auto or none: a video reconstructs with one PSF per phase over the whole field (the slot filter is "
                "per-frequency); a dataset's psf_field is not used");
  problem.psf_field = DatasetPsfField::kNone;
  problem.method = options.method;
  const int n = d.slot_count > 0 ? d.slot_count : d.size();
  slots_ = d.slots.size() == d.frames.size() ? d.slots : std::vector<int>();
  if (slots_.empty())
    for (int i = 0; i < d.size(); ++i) slots_.push_back(i % n);
  // The model of the N phases: the batch problem of one frame of each slot (its PSFs as ProblemFromDataset makes
  // them: nominal, given model PSFs, folded onto the grid).
  std::vector<int> representative(std::size_t(n), -1);
  for (int i = int(slots_.size()) - 1; i >= 0; --i) representative[std::size_t(slots_[std::size_t(i)])] = i;
  for (int s = 0; s < n; ++s)
    CheckArgument(representative[std::size_t(s)] >= 0, kFn, "dataset slots", "no frame of slot " + std::to_string(s),
                  "every one of the " + std::to_string(n) + " phases in the sequence");
  DatasetProblemOptions model_options = problem;
  if (!model_options.model_psfs.empty() && model_options.model_psfs.size() != 1) {
    CheckArgument(model_options.model_psfs.size() == std::size_t(n), kFn, "problem.model_psfs",
                  model_options.model_psfs.size(), "1 or one per phase (" + std::to_string(n) + ")");
  }
  const DatasetProblem slot_problem = ProblemFromDataset(SelectFrames(d, representative), model_options);
  engine_ = std::make_unique<VideoReconstructor>(slot_problem.problem.model, options);
  // Frames in electrons and the weights, resolved once over the whole sequence.
  frames_e_ = d.FramesElectrons();
  DatasetFrameWeights fw = WeightsFromDataset(d, frames_e_, problem);
  weights_ = std::move(fw.weights);
  weights_source_ = std::move(fw.source);
  warning_ = std::move(fw.warning);
  slot_weight_ = representative;
  gain_e_per_adu_ = d.gain_e_per_adu;
  bias_adu_ = d.bias_adu;
  times_.resize(d.frames.size());
  for (std::size_t i = 0; i < d.frames.size(); ++i)
    times_[i] = d.times_s.size() == d.frames.size() ? d.times_s[i] : double(i) / frame_rate_hz;
}

double DatasetVideo::FrameTime(int frame) const {
  CheckArgument(frame >= 0 && frame < frames_total(), "DatasetVideo::FrameTime", "frame", frame,
                "0.." + std::to_string(frames_total() - 1));
  return times_[std::size_t(frame)];
}

std::optional<VideoFrame> DatasetVideo::Next() {
  while (next_ < frames_total()) {
    const int i = next_++;
    const Image empty;
    std::optional<VideoFrame> f = engine_->Push(slots_[std::size_t(i)], i, times_[std::size_t(i)],
                                                frames_e_[std::size_t(i)],
                                                weights_.empty() ? empty : weights_[std::size_t(i)]);
    if (f) return f;
  }
  return std::nullopt;
}

std::optional<VideoFrame> DatasetVideo::PushFrame(int slot, int index, double time_s, const Image& frame_adu) {
  CheckArgument(slot >= 0 && slot < slot_count(), "DatasetVideo::PushFrame", "slot", slot,
                "0.." + std::to_string(slot_count() - 1) + " (the dataset's phases)");
  const Image empty;
  const Image& w = weights_.empty() ? empty : weights_[std::size_t(slot_weight_[std::size_t(slot)])];
  return engine_->Push(slot, index, time_s, (frame_adu - bias_adu_) * gain_e_per_adu_, w);
}

Shape DatasetVideo::frame_shape() const { return engine_->model()->lr_shape(); }

}  // namespace aosr
