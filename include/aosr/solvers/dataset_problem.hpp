// From a dataset on disk (scene/dataset.hpp) to the ReconstructionProblem every reconstructor reads.
//
// Units. Frames are converted to electrons, y = (ADU − bias) · gain, so that an estimate is in e⁻ per HR
// pixel per frame, the units of the simulated truth. Inverse-variance weights given in ADU⁻² become e⁻⁻²:
// var_e = gain² var_ADU, so w_e = w_ADU / gain².
//
// Weights (DatasetWeights):
//   kAuto       the method's safe default (DatasetProblemOptions::method): kBackground for the methods whose
//               output is linear in the data (drizzle, linear, shift-add, shift-add-median, tikhonov: the ones
//               bench/results/science.md shows biased by source-dependent weights, bright stars -12 % to -42 %);
//               for tv and map (non-linear: their bias is the regulariser's, and inverse variances help their
//               fit) and when no method is given, the dataset's inverse-variance weights when it has them
//               (simulations write them), else the validity mask.
//   kDataset    the dataset's weights ("dataset", also named "poisson": for a simulation they are the inverse
//               variances at the expected signal, the sources' own photon noise included); an error if it has
//               none. Source-dependent weights make any weighted combination flux-dependent: bright stars come
//               out low (bench/results/science.md: -12 % for linear, -16 % for Tikhonov, -42 % for Drizzle at
//               K 14-15 on crowded-stars); DatasetProblem::warning says so when they meet a linear method.
//   kMask       the validity mask only (uniform weights on usable pixels). With no bad pixel this makes the
//               problem Fourier-exact (ReconstructionProblem::HasUniformWeights), the fastest path, at the
//               cost of treating bright and faint pixels alike.
//   kBackground inverse variances that do not depend on the sources: one noise variance σ_i² per frame, of the
//               sky, dark current and read noise, on the valid pixels (w_i = valid_i / σ_i², e⁻⁻²). σ_i² comes
//               from the detector model when the manifest carries one (simulations' "noise" section:
//               read² + (sky + dark)·t_frame + g²/12 with quantisation, or the peak-fraction σ²), else it is
//               estimated from the frame itself: σ̂ = 1.4826 · MAD(d) / √2 of the differences d of
//               horizontally adjacent valid pixels (a smooth background cancels in d; sources, a minority of
//               the pixels, do not move a median). Estimated values of the frames that agree within 5 standard
//               errors of the estimate (SE(σ̂²)/σ̂² ≈ 2.3/√n_pairs, the MAD's 37 % efficiency) are pooled to
//               their mean, so frames of one exposure sequence get one weight and, with no pixel masked, the
//               problem stays Fourier-exact. With no noise at all (noise model "none") it is the mask.
// Pixels the dataset marks invalid (bad, saturated, non-finite in the file) always get weight 0.
//
// The model. MultiFrameModel::FromKernels on the frames' HR footprint with the dataset's PSFs (the nominal
// model PSFs of the manifest), or with `model_psfs` when given: that is how a reconstruction is run with
// PSFs other than those that made the data (e.g. nominal PSFs for frames made with sampled ones). A PSF
// kernel larger than the HR grid is folded onto it (summed modulo the grid): under the periodic model this is
// exact, since the convolution only ever sees the kernel modulo the grid.
//
// Offsets (FrameOffset, HR pixels) for the registration methods (shift-and-add, Drizzle):
//   kAuto           the DM offsets' tip/tilt shifts (shift_px · r) when any is non-zero, else the PSF
//                   centroids (for designs that move the image without a commanded shift, e.g. Zernike
//                   modes with a tilt component, or no offsets at all: zero shifts up to the PSF's asymmetry).
//   kDmShifts       the commanded shifts only.
//   kPsfCentroids   the first moment of each model PSF about its centre (image.hpp: pixel (K/2, K/2)).
//   kEstimate       measured from the frames (solvers/registration.hpp): starting from kAuto's offsets (the
//                   commanded pointing, which the model PSFs carry), each frame's correction is estimated
//                   against a reconstruction and the model PSFs are shifted by it; `registration` holds the
//                   per-frame commanded and estimated offsets. Every method then uses them: the model-based
//                   ones through the shifted PSFs, shift-and-add and Drizzle through the offsets.
// Otherwise model-based methods ignore offsets: the PSFs carry them.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include <optional>

#include "aosr/scene/dataset.hpp"
#include "aosr/solvers/problem.hpp"
#include "aosr/solvers/reconstruct.hpp"
#include "aosr/solvers/registration.hpp"
#include "aosr/solvers/stars_psf.hpp"
#include "aosr/solvers/tiling.hpp"

namespace aosr {

enum class DatasetWeights { kAuto, kDataset, kMask, kBackground };
// Whether the model varies over the field (Dataset::psf_field; solvers/psf_field_model.hpp):
//   kAuto   kTiles when the method models PSFs (tikhonov, linear, tv, map) and either the dataset has a psf_field
//           and the model PSFs are the dataset's (or nominal_psfs), or the model PSFs are stars PSFs fitted over a
//           field grid (stars.grid_ny x grid_nx > 1: their grid and nodes are the field model); else kNone
//   kNone   the single PSF per frame (the dataset's psfs: the guide star's direction; the stars grid's PSF at the
//           field's centre), as without a field
//   kTiles     the field model by tiles with local PSFs; InvalidArgument without a field model (a dataset without
//              a psf_field and no stars grid; model_psfs or single stars PSFs), or for a method that uses no PSF
//   (Not with DatasetOffsets::kEstimate: registration would shift the centre's PSFs and not the field's.)
//   kOperator  the field model as one space-variant operator over the whole field (MultiFrameModel::
//              WithPsfField): exact for the interpolated PSF, solved by the operator paths (Tikhonov's PCG, TV's
//              CG x-update, MAP); the same refusals as kTiles, and the linear method (a per-frequency design)
//              refuses it
enum class DatasetPsfField { kAuto, kNone, kTiles, kOperator };
DatasetPsfField ParseDatasetPsfField(const std::string& name);  // "auto" | "none" | "tiles" | "operator"
const char* ToString(DatasetPsfField f);
enum class DatasetOffsets { kAuto, kDmShifts, kPsfCentroids, kEstimate };
// "auto" | "dataset" | "poisson" (= dataset) | "mask" | "background"
DatasetWeights ParseDatasetWeights(const std::string& name);
DatasetOffsets ParseDatasetOffsets(const std::string& name);  // "auto" | "dm" | "centroids" | "estimate"

// What kAuto means for `method` (top of the file): kBackground for the linear methods (IsLinearMethod),
// kAuto's dataset-or-mask rule (returned as kAuto) for tv and map.
DatasetWeights AutoWeights(ReconstructionMethod method);
// True for the methods whose output is a linear combination of the frames (drizzle, linear, shift-add,
// shift-add-median, tikhonov): the ones source-dependent weights turn flux-dependent.
bool IsLinearMethod(ReconstructionMethod method);

// What each pixel's weight is made of, decided once on the whole dataset (the pooled background variance, whether
// any pixel is invalid): a job that reads the frames by sections (FieldData::sections) takes the rule of the plan
// and applies it to its section, with the bytes of the whole field's weights.
struct WeightsRule {
  enum class Kind {
    kUniform,     // no weights (uniform 1: no invalid pixel anywhere)
    kValid,       // the validity mask
    kBackground,  // valid / σ_i² (variance_e2)
    kDataset,     // the dataset's inverse variances · valid / gain²
  };
  Kind kind = Kind::kUniform;
  std::vector<double> variance_e2;  // kBackground: σ_i² per frame (e⁻²)
  double gain2 = 1.0;               // kDataset: gain² (ADU⁻² → e⁻⁻²)
  bool any_invalid = false;         // some pixel of the dataset has weight 0 (masked, bad or non-finite)
  // Whether the weights are one positive value everywhere (the Fourier path; EstimateTiledBytes).
  bool Uniform() const;
};
// The weights of frames (or a section of them) under `rule`: `valid` their masks, `weights_adu` the dataset's
// inverse variances there (kDataset). Empty for kUniform. InvalidArgument for kDataset without weights_adu or
// counts that do not match.
ImageStack ApplyWeightsRule(const WeightsRule& rule, const ImageStack& valid, const std::optional<ImageStack>& weights_adu);

struct DatasetProblemOptions {
  DatasetWeights weights = DatasetWeights::kAuto;
  // The method the problem is for: resolves kAuto (top of the file) and sets DatasetProblem::warning. Empty:
  // kAuto is the dataset-or-mask rule and nothing is warned.
  std::optional<ReconstructionMethod> method;
  DatasetOffsets offsets = DatasetOffsets::kAuto;
  // Empty: the dataset's PSFs. Else N PSFs (or one shared), centred, at HR sampling, each of positive
  // finite sum (renormalised to unit sum), of any even or odd size.
  ImageStack model_psfs;
  // Use the dataset's nominal_psfs as the model (an error if it has none; not with model_psfs).
  bool nominal_psfs = false;
  // Build the model PSFs from the point sources in the frames (stars_psf.hpp: one shared HR PSF shifted by
  // each frame's DM tip/tilt offset, or one per node of a field grid: stars.grid_ny/grid_nx, psf_field above);
  // not with nominal_psfs or model_psfs. Errors when the frames cannot
  // support it (no detection, too few or only saturated stars, offsets that change the PSF's shape).
  bool stars_psfs = false;
  StarsPsfOptions stars;  // with stars_psfs: detection, size and fit settings
  // kEstimate: how (search range, rounds, anchor, the reconstruction registered against).
  RegistrationOptions registration;
  // The field-varying model (DatasetPsfField above); with nominal_psfs the field's nominal PSFs.
  DatasetPsfField psf_field = DatasetPsfField::kAuto;
  // false: no whole-grid model; DatasetProblem::field holds the data and the model's kernels instead, for a
  // reconstruction by tiles (solvers/tiling.hpp, "A whole detector") of a field whose whole-grid model does
  // not fit in memory (WholeGridFits). Not with offsets kEstimate or psf_field operator (both need the
  // whole-grid model).
  bool whole_grid_model = true;
  // A dataset loaded by sections (LoadDataset(..., DatasetPixels::kSections), whole_grid_model false): the weights'
  // rule decided on the whole dataset (DatasetProblem::weights_rule of the plan of
  // aosr.distributed.reconstruct_tiles, given to each tile's job). Without it the rule is decided here by reading
  // the frames in bands of rows (the same rule as on the frames held whole; the frames are read whole only for
  // background weights without a detector model), and masked_pixels is counted. The problem's FieldData then
  // reads each window's frames and weights by sections (FieldData::sections).
  std::optional<WeightsRule> weights_rule;
};

struct DatasetProblem {
  ReconstructionProblem problem;
  // "dataset inverse variances (e-^-2)" | "validity mask" | "background variances from the detector model
  // (e-^-2)" | "background variances estimated from the frames (e-^-2)"
  std::string weights_source;
  std::vector<double> background_sigma_e;  // kBackground: σ_i per frame (e⁻) behind the weights; else empty
  std::string warning;         // non-empty: a caution about the choice (source-dependent weights, photometry)
  std::string offsets_source;  // "dm shifts" | "psf centroids" | "estimated from the frames (from dm shifts)" ...
  std::optional<RegistrationResult> registration;  // kEstimate: commanded and estimated offsets per frame
  bool model_psfs_replaced = false;
  std::optional<StarsPsfResult> stars_psf;  // stars_psfs: the estimate (stars used, chi2/dof, the PSF itself)
  Index masked_pixels = 0;     // pixels of weight 0 over all frames
  Index psf_folded = 0;        // number of PSFs folded onto the HR grid (larger than it)
  // The field-varying model when used (DatasetProblemOptions::psf_field): the approach (kTiles or kOperator),
  // the grid and the nodes' PSFs psfs[k][i]. problem.model holds the PSFs interpolated at the field's centre
  // (what the regularisation is chosen with), made space-variant by kOperator; ReconstructDataset
  // (solvers/psf_field_model.hpp) reconstructs by tiles or with the operator.
  struct Field {
    DatasetPsfField approach = DatasetPsfField::kTiles;
    PsfFieldGrid grid;
    std::vector<ImageStack> psfs;
  };
  std::optional<Field> psf_field;
  WeightsRule weights_rule;    // how the weights were made (the rule a job reading sections is given)
  // DatasetProblemOptions::whole_grid_model false, or a field model by tiles (psf_field kTiles: each tile
  // builds its own model): the frames, weights and offsets (moved out of `problem`, whose model is then null)
  // with the model's PSFs as centred kernels (as the model takes them, not folded).
  std::optional<FieldData> field;
};

// Whether a whole-grid reconstruction of `dataset` by `method` fits under `limit_bytes`: the model's transfer
// functions and the method's solve (EstimateSolveBytes, weighted), next to the frames and weights. *need gets
// the estimate.
bool WholeGridFits(const Dataset& dataset, ReconstructionMethod method, double limit_bytes, double* need = nullptr);

// Throws InvalidArgument naming the option for an inconsistent request (kDataset without weights, a PSF
// stack of the wrong count or with a non-positive sum).
DatasetProblem ProblemFromDataset(const Dataset& dataset, const DatasetProblemOptions& options = {});

// The weights ProblemFromDataset gives the dataset's frames (the Weights rules at the top of the file), from the
// frames in electrons (d.FramesElectrons()): what a caller that does not need the model (solvers/video_stream.hpp,
// which makes the model of the N phases once for M frames) uses. `weights` is empty for uniform weights of 1.
struct DatasetFrameWeights {
  WeightsRule rule;                        // what `weights` were made by
  ImageStack weights;
  std::string source;                      // as DatasetProblem::weights_source
  std::vector<double> background_sigma_e;  // as DatasetProblem::background_sigma_e
  std::string warning;                     // as DatasetProblem::warning (source-dependent weights)
};
DatasetFrameWeights WeightsFromDataset(const Dataset& d, const ImageStack& frames_e,
                                       const DatasetProblemOptions& options = {});

// The first moments of a centred kernel about its centre pixel (K/2, K/2), in its pixels. The kernel must
// have a positive sum.
FrameOffset KernelCentroid(const Image& centred_kernel);

// The background noise σ (e⁻) of one frame in electrons, estimated from the data as kBackground does (top of
// the file): 1.4826 · MAD / √2 of the differences of horizontally adjacent pixels whose `valid` is non-zero.
// 0 when fewer than 8 such pairs exist. `se_relative`, when non-null, gets the relative standard error of σ̂².
double EstimateBackgroundSigma(const Image& frame_e, const Image& valid, double* se_relative = nullptr);

// The diffraction-limited PSF of the dataset's telescope at its wavelength, sampled on the HR grid (pitch
// camera pixel / r), centred at (K/2, K/2), unit sum, K = min(64, HR side) rounded down to even and limited by
// the pupil grid's alias-free field: the target of `--target-psf diffraction`. The telescope (aperture,
// obstruction, spiders, pupil sampling) comes from the scene the manifest names, or from a simulation's
// provenance (manifest "simulation"/"scene"/"json"); the wavelength and camera pixel from the dataset when it
// states them, else from the telescope preset. InvalidArgument naming the manifest when it carries no scene.
Image DiffractionTargetPsf(const Dataset& dataset);

}  // namespace aosr
