// From a dataset on disk (scene/dataset.hpp) to the ReconstructionProblem every reconstructor reads.
//
// Units. Frames are converted to electrons, y = (ADU − bias) · gain, so that an estimate is in e⁻ per HR
// pixel per frame, the units of the simulated truth. Inverse-variance weights given in ADU⁻² become e⁻⁻²:
// var_e = gain² var_ADU, so w_e = w_ADU / gain².
//
// Weights (DatasetWeights):
//   kAuto       the dataset's inverse-variance weights when it has them (simulations write them), else the
//               validity mask (1 usable, 0 not: relative weights, frame noise assumed uniform).
//   kDataset    the dataset's weights; an error if it has none.
//   kMask       the validity mask only (uniform weights on usable pixels). With no bad pixel this makes the
//               problem Fourier-exact (ReconstructionProblem::HasUniformWeights), the fastest path, at the
//               cost of treating bright and faint pixels alike.
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

#include "aosr/scene/dataset.hpp"
#include "aosr/solvers/problem.hpp"
#include "aosr/solvers/registration.hpp"

namespace aosr {

enum class DatasetWeights { kAuto, kDataset, kMask };
enum class DatasetOffsets { kAuto, kDmShifts, kPsfCentroids, kEstimate };
DatasetWeights ParseDatasetWeights(const std::string& name);  // "auto" | "dataset" | "mask"
DatasetOffsets ParseDatasetOffsets(const std::string& name);  // "auto" | "dm" | "centroids" | "estimate"

struct DatasetProblemOptions {
  DatasetWeights weights = DatasetWeights::kAuto;
  DatasetOffsets offsets = DatasetOffsets::kAuto;
  // Empty: the dataset's PSFs. Else N PSFs (or one shared), centred, at HR sampling, each of positive
  // finite sum (renormalised to unit sum), of any even or odd size.
  ImageStack model_psfs;
  // Use the dataset's nominal_psfs as the model (an error if it has none; not with model_psfs).
  bool nominal_psfs = false;
  // kEstimate: how (search range, rounds, anchor, the reconstruction registered against).
  RegistrationOptions registration;
};

struct DatasetProblem {
  ReconstructionProblem problem;
  std::string weights_source;  // "dataset inverse variances (e-^-2)" | "validity mask"
  std::string offsets_source;  // "dm shifts" | "psf centroids" | "estimated from the frames (from dm shifts)" ...
  std::optional<RegistrationResult> registration;  // kEstimate: commanded and estimated offsets per frame
  bool model_psfs_replaced = false;
  Index masked_pixels = 0;     // pixels of weight 0 over all frames
  Index psf_folded = 0;        // number of PSFs folded onto the HR grid (larger than it)
};

// Throws InvalidArgument naming the option for an inconsistent request (kDataset without weights, a PSF
// stack of the wrong count or with a non-positive sum).
DatasetProblem ProblemFromDataset(const Dataset& dataset, const DatasetProblemOptions& options = {});

// The first moments of a centred kernel about its centre pixel (K/2, K/2), in its pixels. The kernel must
// have a positive sum.
FrameOffset KernelCentroid(const Image& centred_kernel);

}  // namespace aosr
