// Drizzle: variable-pixel linear reconstruction (Fruchter & Hook 2002, PASP 114, 144), following the
// conventions of the STScI `drizzle` package (its C core, "cdrizzle"), for pure translations.
//
// The idea. Each camera pixel p of frame i is shrunk about its centre to a "drop" (side pixfrac of the
// pixel), the drop is placed on the HR grid at the frame's registered position, and every HR pixel o
// takes the weighted mean of the drops that land on it:
//
//     W[o] = Σ_{i,p} a_{ip}(o) · w_i[p]                       (output weight map)
//     I[o] = Σ_{i,p} a_{ip}(o) · w_i[p] · d_i[p]  /  W[o]     (output image; fill_value where W[o] <= 0)
//     d_i[p] = y_i[p] / r²                                    (flux per LR pixel -> flux per HR pixel)
//
// w_i[p] is the problem's inverse-variance weight (problem.hpp; 0 for a bad pixel, which is then never
// read). a_{ip}(o) is the kernel: how much of drop (i, p) falls on HR pixel o (below).
//
// Geometry (image.hpp, forward_model.hpp). Pixel centres are at integers; camera pixel (Y, X) integrates
// HR pixels rY .. rY+r-1, so its centre sits at HR (rY + (r-1)/2, rX + (r-1)/2) in the frame's own HR
// frame. FrameOffset (dy, dx) says the scene was moved by +dx toward +x before exposure i, so a point at
// scene position q appears at q + dx: the pixel's centre therefore maps to the reference (scene) grid at
//
//     c_i(Y, X) = ( rY + (r-1)/2 - dy_i ,  rX + (r-1)/2 - dx_i )          (HR pixels)
//
// the same mapping ShiftAndAdd (shift_and_add.hpp) applies when it moves each upsampled frame by
// (-dy_i, -dx_i). Output and input pixel axes are parallel and all frames share the HR pitch, so every
// drop is an axis-aligned square of side pixfrac·r HR pixels; in cdrizzle's terms the pixel map is
// pixmap = c_i, iscale = 1/r² and pixel_scale_ratio = 1/r.
//
// Kernels, a_{ip}(o) for a drop centred at c, with Δ = o - c per axis (HR pixels), s = pixfrac · r:
//   kSquare    overlap area of the square [c - s/2, c + s/2]² with pixel o's cell [o - ½, o + ½]²,
//              divided by the drop area s². cdrizzle clips a general quadrilateral; for a translation
//              the quadrilateral is this square and the overlap is exact.
//   kTurbo     cdrizzle's fast kernel: the same axis-aligned rectangle and the same area fraction. It is
//              an approximation only when the map rotates or distorts pixels; here it is exact and gives
//              results bit-identical to kSquare.
//   kPoint     the whole drop on the one pixel whose half-open cell [o - ½, o + ½) contains c, a = 1.
//              pixfrac is ignored. (cdrizzle rounds with Fortran NINT; the two agree for every centre
//              on the grid and differ only at exactly -½, where ours is translation invariant.)
//   kGaussian  a = exp(-|Δ|²/(2σ²)) / (2πσ²), σ = s / (2√(2 ln 2)) (FWHM = pixfrac LR pixels), summed
//              over the pixels with |Δ_y|, |Δ_x| <= pfo + ½, pfo = max(2.5σ, 1.2 r) (cdrizzle: 2.5σ,
//              never below 1.2 LR pixels so there are no holes). A density sampled at pixel centres.
//   kLanczos3  a = L3(Δ_y / s) · L3(Δ_x / s), L3(t) = sinc(t) sinc(t/3) for |t| < 3 and 0 beyond,
//              sinc(t) = sin(πt)/(πt): peak 1, unnormalised, with negative lobes.
//
// Conservation. Write F_i = Σ_p y_i[p] for frame i's flux, Σ_o for the sum over the HR grid, and
// K_ip = Σ_o a_{ip}(o) for the total of one drop's kernel.
//  * Weighted flux (cdrizzle's bookkeeping): Σ_o W[o] I[o] = Σ_{i,p} K_ip w_i[p] d_i[p]. It equals the
//    input Σ_{i,p} w_i[p] y_i[p] / r² exactly when every K_ip = 1: kSquare, kTurbo and kPoint, with
//    periodic boundaries (with clipping, while no drop leaves the grid). kGaussian and kLanczos3 do not
//    conserve it (cdrizzle warns the same): the Gaussian is a unit-integral density sampled at pixel
//    centres and truncated at pfo, so K differs from 1 (by ~1e-3 at r = 2, pixfrac 1; by a few per
//    cent once σ < 1 HR pixel; and with the drop's sub-pixel phase). Lanczos is not normalised at all
//    (K ≈ s²) and has negative lobes, so W can even be <= 0 where only negative lobes reach (those
//    pixels take fill_value).
//  * Image flux, Σ_o I[o] · (1 HR pixel). With a pure translation all drops of a frame share one
//    sub-pixel phase, so frame i's coverage A_i(o) = Σ_p a_{ip}(o) is r-periodic. With periodic
//    boundaries, no hole (W > 0 everywhere) and weights uniform within each frame (w_i[p] = w̄_i, so
//    W = Σ_i w̄_i A_i), for every kernel
//        Σ_o I = Σ_i λ_i F_i,   λ_i = (w̄_i / r²) Σ_φ A_i(φ) / W(φ)   (φ: the r x r phases),
//    and the λ_i sum to one: the weighted mean divides each kernel's total out. λ_i = w̄_i / Σ w̄ when W
//    is uniform or all frames share one phase. Noise-free frames of one scene (equal F_i) therefore give
//    Σ_o I = F exactly, whatever the kernel; a flat field is reproduced exactly by every kernel.
//  * Masks or weights that vary within a frame break image-flux conservation for every kernel: the
//    weighted mean then re-weights drops by their neighbours' weights. Only Σ W I stays exact.
// The summary reports Σ w d and Σ W I so a caller can see how far a run is from conserving.
//
// What differs from cdrizzle, and why:
//  * Boundaries: cdrizzle drops any part of a drop that falls off the output. aosr's forward model is
//    periodic (forward_model.hpp), so frames near an edge really do see wrapped scene; kPeriodic (the
//    default) wraps drops the same way. kClip reproduces cdrizzle, and counts input pixels that miss.
//  * Output grid: always the model's HR grid (flux per HR pixel, comparable with the truth and the other
//    reconstructors); cdrizzle resamples to any WCS.
//  * Arithmetic: double precision, Σ a w d / Σ a w formed at the end, instead of cdrizzle's float32
//    running mean. Input
//    data are scaled by iscale = 1/r² (d above); weights are used as given (cdrizzle's wht_scale = 1).
//  * Lanczos is evaluated exactly on its symmetric support |Δ| < 3s. cdrizzle reads a 512-entry
//    table at step 0.01 (with a one-entry index offset) over a window shifted by one pixel; we do not
//    reproduce those artefacts. The Gaussian uses 2√(2 ln 2) = 2.35482..., cdrizzle 2.3548.
//  * Context: unsigned 32-bit planes (cdrizzle: int32 with the same bit layout).
//  * Not implemented: cdrizzle's "tophat" and "lanczos2" kernels, distortion (general pixel maps),
//    exposure-time and units handling (wt_scl, in_units), the squared-weight variance image.
// The STScI package is Python + C from PyPI and cannot be installed here (only Debian packages; it is
// not packaged), so the tests check hand-computed overlaps of a two-frame case instead of comparing
// against it.
//
// The weight map is not the inverse variance of I: drops overlap several output pixels, so the noise
// of neighbouring output pixels is correlated (Fruchter & Hook's noise ratio R).
//
// Choosing pixfrac. Smaller drops blur less but leave the output coverage uneven, and with too few
// dithers leave holes (W = 0, fill_value). With a complete r x r raster of dithers pixfrac can go down
// to 1/r (kSquare then reproduces the interlaced image exactly); otherwise Fruchter & Hook suggest the
// smallest pixfrac for which the weight map's RMS stays below ~20% of its median.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "aosr/core/image.hpp"
#include "aosr/solvers/problem.hpp"
#include "aosr/solvers/summary.hpp"

namespace aosr {

enum class DrizzleKernel { kSquare, kTurbo, kPoint, kGaussian, kLanczos3 };
// "square" | "turbo" | "point" | "gaussian" | "lanczos3" (cdrizzle's names).
const char* ToString(DrizzleKernel kernel);
// Inverse of ToString; InvalidArgument naming `kernel` and the allowed names otherwise.
DrizzleKernel ParseDrizzleKernel(const std::string& name);

// What happens to the part of a drop that falls outside the HR grid.
enum class DrizzleBoundary {
  kPeriodic,  // wraps around, like the forward model (every drop lands in full)
  kClip,      // is lost, like cdrizzle
};

struct DrizzleOptions {
  // How a drop's flux is spread over the HR pixels (see the top of the file). kSquare is cdrizzle's
  // default; it (like kTurbo here, and kPoint) conserves the weighted flux exactly. kPoint leaves holes
  // unless the dithers put a pixel centre in every HR cell.
  DrizzleKernel kernel = DrizzleKernel::kSquare;
  // Linear size of a drop as a fraction of the camera pixel, in (0, 1]. 1 (cdrizzle's default) never
  // leaves holes whatever the dither pattern and, for whole-HR-pixel offsets and equal weights, equals
  // mean shift-and-add; smaller values sharpen but need more, well-spread dithers. Ignored by kPoint.
  double pixfrac = 1.0;
  // Value of output pixels that no drop reaches with positive total weight (W <= 0). Finite, or NaN
  // for the astronomers' "INDEF" convention if asked for explicitly. Default 0: flux per HR pixel of an
  // empty sky, so the image can be compared with the truth directly.
  double fill_value = 0.0;
  DrizzleBoundary boundary = DrizzleBoundary::kPeriodic;
  // Build the context map (which frames reached each HR pixel). Costs ceil(N/32) x 4 bytes per HR pixel.
  bool compute_context = true;

  // False (with the offending field and value in *why) unless every field is in range.
  bool IsValid(std::string* why) const;
};

// One plane of the context map: bit b of plane k is set at an HR pixel when frame 32k + b put a drop
// with positive weight a · w > 0 there.
using ContextPlane = Eigen::Array<std::uint32_t, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

struct DrizzleSummary : SolverSummary {
  // method "drizzle", termination kConverged (kFailed when no HR pixel gets positive weight),
  // iterations 0. final_cost is 0 and frame_residual_rms is left empty: drizzle minimises no misfit,
  // and y_i - A_i I mostly measures the blur drizzle keeps (PSF, pixel and drop), not a fit error; call
  // WeightedDataMisfit(problem, result.image) for it. The message states kernel, pixfrac and coverage.
  Index covered_pixels = 0;        // HR pixels with W > 0
  Index filled_pixels = 0;         // HR pixels with W <= 0, set to fill_value
  Index weighted_inputs = 0;       // input pixels with w > 0 (the others are never read)
  Index missed_inputs = 0;         // weighted input pixels whose drop missed the grid (kClip only)
  double weighted_flux_in = 0.0;   // Σ_{i,p} w_i[p] y_i[p] / r²
  double weighted_flux_out = 0.0;  // Σ_o W[o] I[o] over covered pixels; equals the above for
                                   // square/turbo/point when no drop is clipped
};

struct DrizzleResult {
  Image image;   // HR grid, flux per HR pixel; fill_value where weight <= 0
  Image weight;  // W on the HR grid: Σ a · w, in units of the input weights (frame units⁻²)
  // ceil(N / 32) planes of the HR shape (empty when options.compute_context is false). There is no
  // limit on N besides memory: 4 bytes per HR pixel per 32 frames.
  std::vector<ContextPlane> context;
  int frame_count = 0;  // N, the number of frames drizzled
  DrizzleSummary summary;

  // True when frame `frame` contributed (a · w > 0) to HR pixel (y, x). Requires a context map.
  bool Contributed(int frame, Index y, Index x) const;
};

// Drizzles problem.frames onto problem.model's HR grid using problem.weights (empty: all 1) and
// problem.offsets, which are required (one per frame, finite). problem.model supplies r and the HR
// shape only; the PSFs are not used. Throws InvalidArgument (naming the argument) when the problem
// fails ReconstructionProblem::Validate, an offset is missing or not finite, or options are invalid.
DrizzleResult Drizzle(const ReconstructionProblem& problem, const DrizzleOptions& options = {});

}  // namespace aosr
