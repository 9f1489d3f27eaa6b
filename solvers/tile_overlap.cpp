// The overlap rule of the tile engine (tiling.hpp, "The overlap rule"): the PSF-and-reach rule, and for the
// linear estimators the overlap measured from their response to a point source.
#include "tile_overlap.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>
#include <string>
#include <vector>

#include "aosr/core/error.hpp"
#include "aosr/solvers/padded_model.hpp"
#include "aosr/solvers/reconstruct.hpp"

namespace aosr {

using tiling_internal::CutModel;
using tiling_internal::CutModelFromCentred;
using tiling_internal::LargestMeasuredOverlap;
using tiling_internal::OriginKernels;
using tiling_internal::WrapIndex;

namespace {

// The overlap rule's reach (camera px, before doubling) of the method's regulariser and support.
int RegulariserReach(const std::vector<FrameOffset>& offsets, int r, ReconstructionMethod method) {
  switch (method) {
    case ReconstructionMethod::kTotalVariation:
    case ReconstructionMethod::kMap:
      return 2;
    case ReconstructionMethod::kTikhonov:
    case ReconstructionMethod::kLinear:
      return 3;
    default: {
      double off = 0;
      for (const FrameOffset& o : offsets) off = std::max({off, std::abs(o.dy), std::abs(o.dx)});
      return 1 + int(std::ceil(off / r));
    }
  }
}

std::string Sci(double v) {
  char b[32];
  std::snprintf(b, sizeof b, "%.2g", v);
  return b;
}

// The blend weight of a tile at distance d (camera px) from its window's edge, overlap P: 0 up to P/2, the
// raised-cosine ramp to 1 at 3P/2 (tiling.hpp, "Blending").
double RampWeight(double d, double p) {
  if (d <= 0.5 * p) return 0.0;
  if (d >= 1.5 * p) return 1.0;
  const double s = std::sin(0.5 * kPi * (d - 0.5 * p) / p);
  return s * s;
}

// The measured overlap: the response x of the method (its regularisation fixed) to a point source rendered
// through the model at the centre of a periodic probe of the model's kernels, i.e. the method's resolution
// kernel. A source beyond a tile's window is missing from its solve and one wrapped in from the other side is
// added, each worth its kernel's value at the distance; so with tail(d) = Σ|x| beyond Chebyshev distance d
// (camera px) / |Σx| (the flux), and w_P(d) the tile's blend weight at distance d from its window's edge,
// E(P) = 2 max_d w_P(d) tail(d) estimates the tiled error as a fraction of the level. P is the smallest overlap
// with kMargin E(P) <= tolerance, up to a third of the probe (the tail is read to 3P/2 <= half the probe).
// Measured on tiling_test's 288² scene: the error was 1.5x E(P) for Tikhonov and 1.4x for the linear output
// (noise of 1 % and sources cut at the windows' edges add to it), hence the margin.
constexpr double kMargin = 4.0;
int MeasuredOverlap(std::shared_ptr<const MultiFrameModel> model, const std::vector<FrameOffset>& offsets,
                    const ReconstructOptions& options, double tolerance, std::string* rule) {
  const Shape hr = model->hr_shape(), lr = model->lr_shape();
  const int r = model->r();
  ReconstructionProblem probe;
  probe.model = model;
  Image point = Image::Zero(hr.rows, hr.cols);
  point(hr.rows / 2, hr.cols / 2) = 1.0;
  probe.frames = model->Render(point);
  if (offsets.size() == probe.frames.size()) probe.offsets = offsets;
  ReconstructOptions o = options;
  o.progress = nullptr;
  o.tikhonov.compute_std = false;
  o.linear.compute_noise = false;
  const Image x = Reconstruct(probe, o).image;
  Index py = 0, px = 0;
  x.abs().maxCoeff(&py, &px);
  // Σ|x| by Chebyshev distance in HR px (periodic), then the tail beyond each distance.
  const Index half = std::min(hr.rows, hr.cols) / 2;
  std::vector<double> ring(std::size_t(half) + 1, 0.0);
  const double flux = std::abs(x.sum());
  for (Index y = 0; y < hr.rows; ++y) {
    const Index dy = std::min(WrapIndex(y - py, hr.rows), WrapIndex(py - y, hr.rows));
    for (Index xx = 0; xx < hr.cols; ++xx) {
      const Index dx = std::min(WrapIndex(xx - px, hr.cols), WrapIndex(px - xx, hr.cols));
      const double v = std::abs(x(y, xx));
      ring[std::size_t(std::min(std::max(dy, dx), half))] += v;
    }
  }
  std::vector<double> tail(ring.size(), 0.0);  // tail[j]: beyond j HR px
  for (Index j = half - 1; j >= 0; --j) tail[std::size_t(j)] = tail[std::size_t(j) + 1] + ring[std::size_t(j) + 1];
  auto estimate = [&](int p) {
    double e = 0;
    for (Index j = 0; j <= half; ++j) e = std::max(e, RampWeight(double(j) / r, p) * tail[std::size_t(j)]);
    return flux > 0 ? 2.0 * e / flux : 1.0;
  };
  const int p_max = LargestMeasuredOverlap(lr);
  int p = 1;
  while (p < p_max && kMargin * estimate(p) > tolerance) ++p;
  const double e = estimate(p);
  const bool met = kMargin * e <= tolerance;
  if (rule)
    *rule = std::string("measured: ") + ToString(options.method) + "'s response to a point source, bound on the tiled " +
            "error " + Sci(e) + " x " + Sci(kMargin) + (met ? " <= " : " > ") + Sci(tolerance) + " at " +
            std::to_string(p) + " camera px" + (met ? " (probe " : " (the probe's largest, ") +
            std::to_string(lr.rows) + " x " + std::to_string(lr.cols) + " camera px)";
  return p;
}

// The probe's camera side: the field's, up to 128 camera px (a reach to 42).
Shape ProbeShape(Shape lr) { return {std::min<Index>(lr.rows, 128), std::min<Index>(lr.cols, 128)}; }

}  // namespace

namespace tiling_internal {

bool OverlapIsMeasured(const ReconstructOptions& options) {
  return (options.method == ReconstructionMethod::kTikhonov || options.method == ReconstructionMethod::kLinear) &&
         RegularisationIsFixed(options);
}

int LargestMeasuredOverlap(Shape lr) {
  const Shape probe = ProbeShape(lr);
  return std::max<int>(1, int(std::min(probe.rows, probe.cols) / 3));
}

int OverlapRule(const ReconstructionProblem& problem, const ReconstructOptions& options, const TilingOptions& tiling,
                std::string* rule, bool measure) {
  if (measure && OverlapIsMeasured(options)) {
    const int r = problem.model->r();
    const Shape probe = ProbeShape(problem.model->lr_shape());
    const Shape window{probe.rows * r, probe.cols * r};
    const auto model = probe == problem.model->lr_shape()
                           ? problem.model
                           : CutModel(OriginKernels(*problem.model), problem.model->hr_shape(), window, r);
    return MeasuredOverlap(model, problem.offsets, options, tiling.tolerance, rule);
  }
  const bool uses_psf = options.method == ReconstructionMethod::kTikhonov ||
                        options.method == ReconstructionMethod::kLinear ||
                        options.method == ReconstructionMethod::kTotalVariation ||
                        options.method == ReconstructionMethod::kMap;
  const int psf = uses_psf ? PaddedModel::SuggestPadding(*problem.model, tiling.psf_tail) : 0;
  const int reg = RegulariserReach(problem.offsets, problem.model->r(), options.method);
  const std::string sum = "psf " + std::to_string(psf) + " + " + ToString(options.method) + " reach " + std::to_string(reg);
  if (tiling.local_psfs) {
    // Not doubled: a tile's PSF is right only near its centre, and the window's model error, not its truncation,
    // sets the error (tiling.hpp, "The overlap rule").
    if (rule) *rule = sum + " (local PSFs)";
    return psf + reg;
  }
  if (rule) *rule = "2 x (" + sum + ")";
  return 2 * (psf + reg);
}

int OverlapRule(const FieldData& field, const ReconstructOptions& options, const TilingOptions& tiling,
                std::string* rule, bool measure) {
  if (measure && OverlapIsMeasured(options)) {
    const Shape probe = ProbeShape(field.lr);
    return MeasuredOverlap(CutModelFromCentred(field.kernels, {probe.rows * field.r, probe.cols * field.r}, field.r),
                           field.offsets, options, tiling.tolerance, rule);
  }
  // The kernels' reach, from a model on a grid just large enough to hold them (the rule's cap, half the LR
  // side, is then never below it).
  Index side = 1;
  for (const Image& k : field.kernels) side = std::max({side, Index(k.rows()), Index(k.cols())});
  side = (side + field.r - 1) / field.r * field.r;
  ReconstructionProblem probe;
  probe.model =
      std::make_shared<const MultiFrameModel>(MultiFrameModel::FromKernels({side, side}, field.r, field.kernels));
  probe.frames.assign(field.kernels.size(), Image::Zero(side / field.r, side / field.r));
  probe.offsets = field.offsets;
  return OverlapRule(probe, options, tiling, rule, false);
}

}  // namespace tiling_internal

using tiling_internal::OverlapRule;

int SuggestTileOverlap(const ReconstructionProblem& problem, const ReconstructOptions& options,
                       const TilingOptions& tiling, std::string* rule) {
  return OverlapRule(problem, options, tiling, rule, true);
}

int SuggestTileOverlap(const FieldData& field, const ReconstructOptions& options, const TilingOptions& tiling,
                       std::string* rule) {
  return OverlapRule(field, options, tiling, rule, true);
}

}  // namespace aosr
