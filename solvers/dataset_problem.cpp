#include "aosr/solvers/dataset_problem.hpp"

#include <cmath>
#include <memory>

#include "aosr/core/error.hpp"
#include "aosr/core/memory.hpp"

namespace aosr {
namespace {

constexpr const char* kFn = "ProblemFromDataset";

// Folds a centred kernel onto a periodic grid of shape s (sums the entries that land on the same pixel
// modulo s) and returns it centred on a grid of shape s: the periodic model cannot tell the two apart.
Image FoldOnto(const Image& k, Shape s) {
  Image periodic = Image::Zero(s.rows, s.cols);
  const Index cy = k.rows() / 2, cx = k.cols() / 2;
  for (Index y = 0; y < k.rows(); ++y)
    for (Index x = 0; x < k.cols(); ++x) {
      const Index py = (((y - cy) % s.rows) + s.rows) % s.rows, px = (((x - cx) % s.cols) + s.cols) % s.cols;
      periodic(py, px) += k(y, x);
    }
  return OriginToCentred(periodic, s);
}

}  // namespace

DatasetWeights ParseDatasetWeights(const std::string& name) {
  if (name == "auto") return DatasetWeights::kAuto;
  if (name == "dataset") return DatasetWeights::kDataset;
  if (name == "mask") return DatasetWeights::kMask;
  throw InvalidArgument("ParseDatasetWeights", "weights", name, "auto | dataset | mask");
}

DatasetOffsets ParseDatasetOffsets(const std::string& name) {
  if (name == "auto") return DatasetOffsets::kAuto;
  if (name == "dm") return DatasetOffsets::kDmShifts;
  if (name == "centroids") return DatasetOffsets::kPsfCentroids;
  if (name == "estimate") return DatasetOffsets::kEstimate;
  throw InvalidArgument("ParseDatasetOffsets", "offsets", name, "auto | dm | centroids | estimate");
}

FrameOffset KernelCentroid(const Image& k) {
  const double sum = k.sum();
  CheckArgument(std::isfinite(sum) && sum > 0, "KernelCentroid", "kernel sum", sum, "finite and > 0");
  double my = 0, mx = 0;
  for (Index y = 0; y < k.rows(); ++y)
    for (Index x = 0; x < k.cols(); ++x) {
      my += k(y, x) * double(y - k.rows() / 2);
      mx += k(y, x) * double(x - k.cols() / 2);
    }
  return {my / sum, mx / sum};
}

DatasetProblem ProblemFromDataset(const Dataset& d, const DatasetProblemOptions& options) {
  const std::size_t n = d.frames.size();
  CheckArgument(n > 0, kFn, "dataset frames", 0, "at least one frame");
  DatasetProblem out;

  // ---- PSFs of the model. ---------------------------------------------------------------------------------
  ImageStack psfs = d.psfs;
  CheckArgument(!(options.nominal_psfs && !options.model_psfs.empty()), kFn, "nominal_psfs", "true with model_psfs",
                "one of nominal_psfs and model_psfs");
  if (options.nominal_psfs) {
    CheckArgument(d.nominal_psfs.size() == n, kFn, "nominal_psfs", "true",
                  "a dataset whose manifest gives nominal_psfs (closed-loop simulations write them)");
    psfs = d.nominal_psfs;
    out.model_psfs_replaced = true;
  }
  if (!options.model_psfs.empty()) {
    const ImageStack& m = options.model_psfs;
    CheckArgument(m.size() == n || m.size() == 1, kFn, "model_psfs count", m.size(),
                  "1 or one per frame (" + std::to_string(n) + ")");
    psfs.clear();
    for (std::size_t i = 0; i < n; ++i) {
      const Image& k = m[m.size() == 1 ? 0 : i];
      const double s = k.size() > 0 && AllFinite(k) ? k.sum() : 0.0;
      CheckArgument(s > 0, kFn, "model_psfs[" + std::to_string(i) + "]",
                    k.size() == 0 ? std::string("empty") : "sum " + ToString(s), "finite values with a positive sum");
      psfs.push_back(k / s);
    }
    out.model_psfs_replaced = true;
  }
  std::vector<FrameOffset> centroids;  // of the kernels as given: folding moves their first moments
  for (const Image& k : psfs) centroids.push_back(KernelCentroid(k));
  for (Image& k : psfs)
    if (k.rows() > d.hr_frame.rows || k.cols() > d.hr_frame.cols) {
      k = FoldOnto(k, d.hr_frame);
      ++out.psf_folded;
    }
  // The model holds one HR transfer function per frame (complex, half spectrum) and builds each from a padded
  // real kernel: refuse a dataset whose r and frame count cannot fit before building them.
  const double hr_pixels = double(d.hr_frame.rows) * double(d.hr_frame.cols);
  CheckMemory(double(n) * 16.0 * hr_pixels / 2 + 16.0 * hr_pixels,
              std::string(kFn) + ": the model of " + std::to_string(n) + " frames on the HR grid " + ToString(d.hr_frame) +
                  " (r = " + std::to_string(d.r) + ")");
  out.problem.model = std::make_shared<const MultiFrameModel>(MultiFrameModel::FromKernels(d.hr_frame, d.r, psfs));

  // ---- Frames (e⁻) and weights. ---------------------------------------------------------------------------
  out.problem.frames = d.FramesElectrons();
  const bool use_dataset =
      options.weights == DatasetWeights::kDataset || (options.weights == DatasetWeights::kAuto && d.weights);
  if (use_dataset) {
    CheckArgument(bool(d.weights), kFn, "weights", "dataset", "a dataset whose manifest gives `weights`");
    const double g2 = d.gain_e_per_adu * d.gain_e_per_adu;
    for (std::size_t i = 0; i < n; ++i) out.problem.weights.push_back((*d.weights)[i] * d.valid[i] / g2);
    out.weights_source = "dataset inverse variances (e-^-2)";
  } else {
    bool any_invalid = false;
    for (const Image& v : d.valid) any_invalid = any_invalid || (v == 0).any();
    if (any_invalid) out.problem.weights = d.valid;
    out.weights_source = "validity mask";
  }
  for (std::size_t i = 0; i < n; ++i) {
    const Image w = out.problem.weights.empty() ? d.valid[i] : out.problem.weights[i];
    out.masked_pixels += (w == 0).count();
  }

  // ---- Offsets. ---------------------------------------------------------------------------------------------
  bool any_shift = false;
  for (const DmOffset& o : d.offsets) any_shift = any_shift || o.shift_y_px != 0 || o.shift_x_px != 0;
  const bool automatic = options.offsets == DatasetOffsets::kAuto || options.offsets == DatasetOffsets::kEstimate;
  const bool dm = options.offsets == DatasetOffsets::kDmShifts || (automatic && any_shift);
  for (std::size_t i = 0; i < n; ++i) {
    if (dm) {
      const DmOffset o = i < d.offsets.size() ? d.offsets[i] : DmOffset{};
      out.problem.offsets.push_back({o.shift_y_px * d.r, o.shift_x_px * d.r});
    } else {
      out.problem.offsets.push_back(centroids[i]);
    }
  }
  out.offsets_source = dm ? "dm shifts" : "psf centroids";
  out.problem.Validate(kFn);
  if (options.offsets == DatasetOffsets::kEstimate) {
    RegistrationResult reg = RegisterFrames(out.problem, options.registration);
    out.problem = reg.problem;
    reg.problem = {};  // the problem is out.problem; do not keep the frames twice
    out.offsets_source = "estimated from the frames (commanded: " + out.offsets_source + ")";
    out.registration = std::move(reg);
  }
  return out;
}

}  // namespace aosr
