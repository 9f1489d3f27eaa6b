// Registration from the data: each frame's pointing offset measured from the frames themselves, for data
// whose applied offsets differ from the commanded ones (a DM gain error, a jitter per frame, a drift).
//
// The model. Frame i is y_i = D_r(S_{δ_i} h_i ⊛ x) + n_i, with h_i the model PSF (it already carries the
// commanded offset c_i) and δ_i the unknown correction [HR px], S_δ the periodic (Fourier) shift
// (+dx toward +x, image.hpp). The frames are undersampled, so a frame is never correlated against another
// frame directly: each is compared with its prediction from a reconstruction built at HR from all frames.
//
// The algorithm (alternating; `outer_iterations` rounds, stopping early when no δ moves by more than
// `tolerance_camera_px`):
//   1. x̂ = Tikhonov reconstruction (`reconstruction`, λ by its rule) with the current model S_{δ_i} h_i.
//   2. For every frame, p_i(δ) = D_r(S_δ (S_{δ_i} h_i ⊛ x̂)) its prediction.
//      a. Coarse: the upsampled cross-correlation of y_i against p_i(0) on the camera grid (MeasureImageOffset:
//         Guizar-Sicairos, Thurman & Fienup, Opt. Lett. 33, 156 (2008)). It catches a gross shift; on
//         undersampled frames its sub-pixel part is biased by aliasing, so it only starts step b.
//      b. Refined against the reconstruction: Gauss-Newton on the weighted model residual
//         ‖√w_i (y_i − p_i(δ))‖² over δ ∈ R², the Jacobian by central Fourier-shift differences.
//   3. The corrections are anchored (`anchor`): the absolute position of the scene is not in the data (a
//      common shift of all frames is a shift of x), so by default the corrections have zero mean (the
//      estimated set keeps the commanded set's mean), or frame 0 keeps its commanded offset.
//
// Precision. σ_i, the standard error of δ_i, is the Gauss-Newton covariance s² (JᵀWJ)⁻¹ with s² the residual
// variance per weighted pixel (so relative weights — a validity mask — are handled too); it is reported
// per frame (the larger axis).
//
// Errors, never a silent fallback: a frame whose offset the data cannot support (no structure: a singular
// or too-weak JᵀWJ, σ above the search range; a constant frame or reconstruction) or whose correction
// (coarse or refined) leaves ±`search_range_camera_px` gets InvalidArgument naming the frame and what is
// missing. Model-based methods then use the shifted model; registration methods (shift-and-add, Drizzle) the
// estimated offsets c_i + δ_i.
#pragma once

#include <string>
#include <vector>

#include "aosr/solvers/problem.hpp"
#include "aosr/solvers/tikhonov.hpp"

namespace aosr {

enum class RegistrationAnchor {
  kCommandedMean,  // Σ_i δ_i = 0: the estimated offsets keep the commanded set's mean
  kFrameZero,      // δ_0 = 0: frame 0 keeps its commanded offset
};
RegistrationAnchor ParseRegistrationAnchor(const std::string& name);  // "mean" | "frame0"
const char* ToString(RegistrationAnchor a);

struct RegistrationOptions {
  // Largest correction |δ| per axis [camera px] a frame may need. 0.5 camera px: beyond it the commanded
  // offsets are wrong by more than a raster step and the reconstruction the frames are compared with is a
  // blend of misplaced copies. Range (0, 4].
  double search_range_camera_px = 0.5;
  // Reconstruct-register rounds. Each round's reconstruction is sharper than the last, so the corrections
  // converge geometrically; 4 reach 0.001 camera px on the tests' ×1.1 gain error. Range [1, 50].
  int outer_iterations = 4;
  // Gauss-Newton steps per frame and round. Range [1, 100].
  int newton_iterations = 10;
  // Stop when no correction moves by more than this [camera px]. Range (0, 0.1].
  double tolerance_camera_px = 2e-4;
  RegistrationAnchor anchor = RegistrationAnchor::kCommandedMean;
  // The reconstruction x̂ the frames are compared with. Default: Tikhonov with the gradient prior, λ by GCV
  // (the `aosr reconstruct` default), no posterior std.
  TikhonovOptions reconstruction = [] {
    TikhonovOptions t;
    t.lambda_rule = TikhonovLambdaRule::kGcv;
    return t;
  }();

  bool IsValid(std::string* why) const;
};

struct RegistrationResult {
  std::vector<FrameOffset> commanded;   // the problem's offsets on input [HR px]
  std::vector<FrameOffset> correction;  // δ_i [HR px], anchored
  std::vector<FrameOffset> estimated;   // commanded + correction [HR px]
  std::vector<double> sigma_hr_px;      // standard error of δ_i (larger axis) [HR px]
  std::vector<double> residual_rms;     // frame residual RMS against the last reconstruction (frame units)
  int rounds = 0;                       // reconstruct-register rounds run
  bool converged = false;               // the last round moved no correction by more than the tolerance
  double seconds = 0.0;
  ReconstructionProblem problem;        // the input with the model PSFs shifted by δ_i and offsets = estimated
};

// Registers the frames of `problem` (model PSFs and offsets hold the commanded pointing; offsets may be empty,
// then zeros). Throws InvalidArgument for invalid options, a problem that fails Validate, and the frame
// errors above.
RegistrationResult RegisterFrames(const ReconstructionProblem& problem, const RegistrationOptions& options = {});

// The problem with frame i's model PSF moved by correction[i] (HR px; its transfer function times
// ShiftTransfer) and its offset by the same amount. Throws on a count mismatch or non-finite corrections.
ReconstructionProblem ShiftProblemFrames(const ReconstructionProblem& problem,
                                         const std::vector<FrameOffset>& correction);

}  // namespace aosr
