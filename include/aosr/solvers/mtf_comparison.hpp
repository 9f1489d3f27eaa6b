// The MTF of several outputs on one plot and in one table: each image's slanted-edge curve (core/slanted_edge.hpp)
// read in the same region, beside the exact transfer (linear_transfer.hpp) where the method is linear and its
// model is known. What `aosr mtf A.fits B.fits ...` and Python's aosr.compare_mtf draw.
//
// Per output, by method (MtfSubject::method):
//   tikhonov  exact curve from the model of `problem` (its PSFs and per-frame weights: the dataset's problem as
//             the reconstruction used it), the prior of `tikhonov` and the output's λ (MtfSubject::
//             regularisation; `aosr reconstruct` writes it as REGUL). "exact", or "approximate" when some frame's
//             weights vary over its pixels (masked or photon-noise weights: the curve is then that of the
//             per-frame mean weights), or "unavailable" (no problem or λ given).
//   linear    |DTFT| of its effective PSF (the PSF extension of the file `aosr reconstruct -m linear` writes):
//             "exact" (of the uniform-weight system when the data were weighted, target_psf.hpp).
//   tv, map   "signal-dependent": their response depends on the edge's contrast and the noise; the measured curve
//             at the scene's contrast and noise is the answer (said on the plot).
//   others    (bicubic, drizzle, shift-add, a truth, unknown) "measured only": drizzle, shift-and-add and bicubic are
//             linear too but not shift-invariant, so they have no single transfer function; a truth's curve is the
//             edge object's own (the HR pixel box for a scene's slanted edge).
// The exact curves follow each image's measured edge normal (SetDirectionFromEdge; the first measured edge's for
// an output whose own edge was refused) at the edge curve's frequencies up to the HR Nyquist 0.5, and include
// the HR pixel box (linear_transfer.hpp: what an edge area-sampled on the HR grid reads).
//
// An output whose edge is refused (core/slanted_edge.hpp's reasons) gets no measured curve; its refusal is kept
// in `refusal`. CompareMtf throws (the first refusal) only when no output has a usable edge.
#pragma once

#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "aosr/core/slanted_edge.hpp"
#include "aosr/io/plot.hpp"
#include "aosr/solvers/linear_transfer.hpp"
#include "aosr/solvers/problem.hpp"
#include "aosr/solvers/tikhonov.hpp"

namespace aosr {

struct MtfSubject {
  std::string label;   // legend and table column; empty: the method, else "image <i>"
  Image image;         // the HR image (all subjects on the same grid when a region is given)
  std::string method;  // a ReconstructionMethod name, "bicubic", "truth", or "" (unknown)
  double regularisation = std::numeric_limits<double>::quiet_NaN();  // tikhonov: the λ used
  Image effective_psf;  // linear: the effective PSF (centred, unit sum)
};

// A subject from a FITS file aosr wrote: METHOD (and AOSRDATA "truth" -> "truth"), REGUL, the PSF extension of a
// linear output; the label is the method, else the file's stem. IoError / InvalidArgument as ReadFits.
MtfSubject MtfSubjectFromFits(const std::string& path);

struct MtfComparisonOptions {
  SlantedEdgeOptions edge;  // the region and the reading, the same for every subject
  bool exact = true;        // compute the exact curves where possible
  // Tikhonov's exact curves: the reconstruction's problem (model PSFs, weights; frames are not used) and prior
  // (its `prior` and spectrum fields; the λ is each subject's). Null: tikhonov subjects get "unavailable".
  std::shared_ptr<const ReconstructionProblem> problem;
  TikhonovOptions tikhonov;
};

struct MtfComparisonEntry {
  std::string label;
  std::string method;
  bool measured = false;
  std::string refusal;           // why the edge was refused (measured false)
  SlantedEdgeMtf edge;           // measured true
  // "exact" | "approximate: ..." | "signal-dependent" | "measured only" | "unavailable: ..." | "off"
  std::string exact_status;
  std::optional<TransferCurve> exact;
};

struct MtfComparison {
  std::vector<MtfComparisonEntry> entries;
  // One line per entry: "tikhonov: MTF50 0.312 cyc/px (exact 0.315), MTF at 1/(2r) 0.71 (exact 0.71)".
  std::string BriefReport() const;
};

MtfComparison CompareMtf(const std::vector<MtfSubject>& subjects, const MtfComparisonOptions& options);

// The region to read the subjects in when none is given (`aosr mtf` and aosr.mtf / compare_mtf without a roi):
// the whole image if it holds one edge, else the first straight edge found that measures
// (core/edge_search.hpp), in the first subject that has one; the default PixelRoi for the whole image. `source`,
// when given, says which ("whole image", or "found automatically in <label>: ..."). InvalidArgument saying why
// ("no image has a usable edge", with the first subject's reasons) when none has one.
PixelRoi FindMtfRegion(const std::vector<MtfSubject>& subjects, const SlantedEdgeOptions& options,
                       std::string* source = nullptr);

// The table as CSV: a header line, then one row per frequency of the measured curves (cycles/px): a column per
// measured curve ("<label> edge") and per exact curve ("<label> exact"; empty past the HR Nyquist).
std::string MtfComparisonCsv(const MtfComparison& comparison);

// The plot: measured curves first (in subject order), then the exact ones, labelled "<label> (edge)",
// "<label> (exact)", "<label> (edge, signal-dep.)" (and the title says that TV/MAP have no exact curve); the
// camera's Nyquist 1/(2r) when the edge options gave r. Empty title: that default title.
LinePlot MtfComparisonPlot(const MtfComparison& comparison, const std::string& title = "");

}  // namespace aosr
