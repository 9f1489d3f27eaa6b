// `aosr reconstruct DIR --method M -o OUT.fits`: a super-resolved image from a dataset (simulated or
// measured, scene/dataset.hpp) by any reconstructor (solvers/reconstruct.hpp), with its summary, and the
// method's second map (Drizzle weight, Tikhonov posterior std) beside it.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <optional>
#include <vector>
#include <nlohmann/json.hpp>
#include <set>
#include <string>

#include "aosr/core/error.hpp"
#include "aosr/core/memory.hpp"
#include "aosr/core/metrics.hpp"
#include "aosr/core/parallel.hpp"
#include "aosr/core/operators.hpp"
#include "aosr/io/fits.hpp"
#include "aosr/scene/dataset.hpp"
#include "aosr/scene/evaluation.hpp"
#include "aosr/solvers/dataset_problem.hpp"
#include "aosr/solvers/reconstruct.hpp"
#include "aosr/solvers/reconstruction_header.hpp"
#include "aosr/solvers/psf_field_model.hpp"
#include "aosr/solvers/tiling.hpp"
#include "cli_util.hpp"
#include "commands.hpp"
#include "progress_bar.hpp"

namespace aosr::cli {
namespace {

namespace fs = std::filesystem;

struct ReconstructArgs {
  std::string dataset;
  std::string method = "tikhonov";
  std::string out;
  bool json = false;
  bool progress = false;  // --progress: progress on stderr even under --json or without a terminal
  int rings = 0;            // --rings: scores against the truth in rings (0: none)
  std::string ring_centre;  // --ring-centre X,Y [HR px]; empty: the image centre
  std::string weights = "auto";
  std::string offsets = "auto";
  double registration_range = 0.5;           // --registration-range [camera px]
  std::string registration_anchor = "mean";  // --registration-anchor
  int registration_rounds = 4;               // --registration-rounds
  std::string model_psfs;
  // --model-psfs stars: the PSF estimated from the point sources in the frames (solvers/stars_psf.hpp)
  std::string stars_psf_out;     // --stars-psf-out: the per-frame model PSFs as a FITS cube
  int stars_psf_size = 0;        // --stars-psf-size [HR px], 0 auto
  double stars_threshold = 5.0;  // --stars-threshold [background sigma]
  int stars_min = 4;             // --stars-min
  int stars_rounds = 4;          // --stars-rounds
  int stars_background_mesh = 0;   // --stars-background-mesh
  double stars_max_chi2 = 5.0;     // --stars-max-chi2
  bool stars_reject_extended = false;  // --stars-reject-extended
  std::string stars_grid = "1x1";      // --stars-grid NYxNX: a stars PSF varying over the field
  int stars_grid_degree = StarsPsfOptions{}.grid_degree;          // --stars-grid-degree: nodes on a polynomial
  double stars_grid_roughness = StarsPsfOptions{}.grid_roughness;  // --stars-grid-roughness: how far from it
  // Tikhonov
  double lambda = -1;  // < 0: by the rule
  std::string lambda_rule = "gcv";
  std::string prior = "gradient";
  std::string boundary = "periodic";
  bool std_map = false;
  bool count_unconstrained = false;  // --count-unconstrained
  double noise_sigma = 1.0;
  CLI::Option* noise_sigma_option = nullptr;  // to tell a given --noise-sigma from the default
  // TV / MAP
  double mu = -1;  // < 0: automatic
  int iterations = -1;
  bool positivity = false;
  std::string likelihood = "gaussian";
  std::string map_prior = "charbonnier-tv";
  double read_noise = 0;
  // linear (target PSF)
  std::string target_psf = "auto";
  double leakage = 1e-3;
  int noise_probes = 32;
  // Drizzle
  std::string kernel = "square";
  double pixfrac = 1.0;
  // Tiling (solvers/tiling.hpp): 0 = the whole grid at once
  std::string psf_field = "auto";  // --psf-field auto|none|tiles|operator (solvers/dataset_problem.hpp)
  int tile = 0;           // --tile [camera px]
  int tile_overlap = -1;  // --tile-overlap [camera px], -1 = the rule
  double tile_tolerance = 1e-6;  // --tile-tolerance: the measured overlap's bound on the tiled error
  std::string resume;     // --resume DIR: finished tiles kept there, reused by a rerun
  ExecutionArgs exec;
};

// --target-psf: "auto" | "diffraction" | "gaussian:<FWHM in HR pixels>" | a FITS file holding the kernel at HR
// sampling. "diffraction" is resolved once the dataset is read (DiffractionTargetPsf).
void ParseTargetPsf(const std::string& spec, TargetPsfOptions* o) {
  constexpr const char* kAllowed =
      "auto | diffraction | gaussian:<FWHM in HR px> | <kernel>.fits (HR sampling, centred)";
  if (spec == "auto") {
    o->kind = TargetPsfKind::kAuto;
  } else if (spec == "diffraction") {
    o->kind = TargetPsfKind::kImage;  // the kernel comes from the dataset's telescope
  } else if (spec.rfind("gaussian:", 0) == 0) {
    o->kind = TargetPsfKind::kGaussian;
    std::size_t used = 0;
    const std::string v = spec.substr(9);
    try {
      o->fwhm_hr_px = std::stod(v, &used);
    } catch (const std::exception&) {
      used = 0;
    }
    if (used == 0 || used != v.size() || !(o->fwhm_hr_px >= 0.5) || !std::isfinite(o->fwhm_hr_px))
      throw InvalidArgument("aosr reconstruct", "--target-psf", spec, "gaussian:<FWHM >= 0.5 HR px>");
  } else if (spec.size() > 5 && (spec.substr(spec.size() - 5) == ".fits" || spec.substr(spec.size() - 4) == ".fit")) {
    o->kind = TargetPsfKind::kImage;
    o->image = ReadFitsImage(spec);
  } else {
    throw InvalidArgument("aosr reconstruct", "--target-psf", spec, kAllowed);
  }
}

void RunReconstruct(const ReconstructArgs& a) {
  ApplyExecution(a.exec);
  const Progress progress(!a.json, a.progress);
  ProgressBar bar(ProgressBar::Choose(a.json, a.progress));
  ReconstructOptions o;
  o.method = ParseReconstructionMethod(a.method);
  DatasetProblemOptions dpo;
  dpo.weights = ParseDatasetWeights(a.weights);
  dpo.offsets = ParseDatasetOffsets(a.offsets);
  dpo.registration.search_range_camera_px = a.registration_range;
  dpo.registration.anchor = ParseRegistrationAnchor(a.registration_anchor);
  dpo.registration.outer_iterations = a.registration_rounds;
  // Options, checked before anything is read or computed.
  o.tikhonov.prior = ParseTikhonovPrior(a.prior);
  if (a.lambda >= 0) {
    o.tikhonov.lambda_rule = TikhonovLambdaRule::kFixed;
    o.tikhonov.lambda = a.lambda;
  } else {
    // discrepancy and upre use --noise-sigma: with inverse-variance weights (the default for simulated
    // datasets) a weight-1 pixel has σ = 1. wiener (with --prior fitted) too, or the fitted floor with 0.
    if (a.lambda_rule != "gcv" && a.lambda_rule != "discrepancy" && a.lambda_rule != "lcurve" &&
        a.lambda_rule != "upre" && a.lambda_rule != "wiener")
      throw InvalidArgument("aosr reconstruct", "--lambda-rule", a.lambda_rule,
                            "gcv | discrepancy | lcurve | upre | wiener");
    o.tikhonov.lambda_rule = ParseTikhonovLambdaRule(a.lambda_rule);
  }
  if (a.boundary == "padded") {
    o.tikhonov.boundary = TikhonovBoundary::kZeroPadded;
  } else if (a.boundary != "periodic") {
    throw InvalidArgument("aosr reconstruct", "--boundary", a.boundary, "periodic | padded");
  }
  o.tikhonov.compute_std = a.std_map;
  o.tikhonov.count_unconstrained = a.count_unconstrained;
  o.tikhonov.noise_sigma = a.noise_sigma;
  ParseTargetPsf(a.target_psf, &o.linear);
  o.linear.leakage = a.leakage;
  o.linear.noise_probes = a.noise_probes;
  o.linear.noise_sigma = a.noise_sigma;
  o.drizzle.kernel = ParseDrizzleKernel(a.kernel);
  o.drizzle.pixfrac = a.pixfrac;
  o.drizzle.compute_context = false;
  if (a.mu >= 0) {
    o.auto_regularisation = false;
    o.tv.mu = a.mu;
    o.map.lambda = 2 * a.mu;
  }
  if (a.iterations > 0) o.tv.max_iterations = o.map.max_iterations = a.iterations;
  o.tv.positivity = a.positivity;
  o.map.positivity = a.positivity ? MapPositivity::kSoftplus : MapPositivity::kNone;
  o.map.likelihood = ParseMapLikelihood(a.likelihood);
  o.map.prior = ParseMapPrior(a.map_prior);
  o.map.read_noise = a.read_noise;
  TilingOptions tiling;
  tiling.tile = a.tile;
  tiling.overlap = a.tile_overlap;
  tiling.tolerance = a.tile_tolerance;
  if (!(a.tile_tolerance > 0 && a.tile_tolerance < 1))
    throw InvalidArgument("aosr reconstruct", "--tile-tolerance", ToString(a.tile_tolerance), "in (0, 1)");
  if (a.tile == 0 && a.tile_overlap >= 0)
    throw InvalidArgument("aosr reconstruct", "--tile-overlap", std::to_string(a.tile_overlap), "only with --tile");
  if (a.tile != 0) {
    std::string why;
    if (!tiling.IsValid(&why)) throw InvalidArgument("aosr reconstruct", "--tile / --tile-overlap", why, "valid tiling");
  }
  if (!a.resume.empty()) {
    std::error_code ec;
    fs::create_directories(a.resume, ec);
    if (!fs::is_directory(a.resume))
      throw InvalidArgument("aosr reconstruct", "--resume", a.resume, "a folder that exists or can be created");
    tiling.checkpoint_dir = a.resume;
    // The options the library's fingerprint does not see by itself (it hashes the data, the model, the tiles and
    // the method's main options): every argument that changes the image.
    tiling.checkpoint_key = a.method + "|" + a.weights + "|" + a.offsets + "|" + a.model_psfs + "|" +
                            ToString(a.lambda) + "|" + a.lambda_rule + "|" + a.prior + "|" + a.boundary + "|" +
                            ToString(a.std_map) + "|" + ToString(a.noise_sigma) + "|" + ToString(a.mu) + "|" +
                            ToString(a.iterations) + "|" + ToString(a.positivity) + "|" + a.likelihood + "|" +
                            a.map_prior + "|" + ToString(a.read_noise) + "|" + a.target_psf + "|" +
                            ToString(a.leakage) + "|" + ToString(a.noise_probes) + "|" + a.kernel + "|" +
                            ToString(a.pixfrac) + "|" + ToString(a.registration_range) + "|" +
                            a.registration_anchor + "|" + ToString(a.registration_rounds) + "|" +
                            ToString(a.stars_psf_size) + "|" + ToString(a.stars_threshold) + "|" +
                            ToString(a.stars_min) + "|" + ToString(a.stars_rounds) + "|" +
                            ToString(a.stars_background_mesh) + "|" + ToString(a.stars_max_chi2) + "|" +
                            ToString(int(a.stars_reject_extended)) + "|" + a.stars_grid + "|" +
                            ToString(a.stars_grid_degree) + "|" + ToString(a.stars_grid_roughness);
  }
  CheckWritableFile(a.out);
  if (!a.stars_psf_out.empty()) {
    if (a.model_psfs != "stars")
      throw InvalidArgument("aosr reconstruct", "--stars-psf-out", a.stars_psf_out, "only with --model-psfs stars");
    CheckWritableFile(a.stars_psf_out);
  }
  dpo.stars.psf_size_hr_px = a.stars_psf_size;
  dpo.stars.detection_sigma = a.stars_threshold;
  dpo.stars.min_stars = a.stars_min;
  dpo.stars.rounds = a.stars_rounds;
  dpo.stars.background_mesh_px = a.stars_background_mesh;
  dpo.stars.max_chi2_near_stars = a.stars_max_chi2;
  dpo.stars.reject_extended = a.stars_reject_extended;
  dpo.stars.grid_degree = a.stars_grid_degree;
  dpo.stars.grid_roughness = a.stars_grid_roughness;
  {
    int ny = 0, nx = 0;
    char tail = 0;
    if (std::sscanf(a.stars_grid.c_str(), "%dx%d%c", &ny, &nx, &tail) != 2)
      throw InvalidArgument("aosr reconstruct", "--stars-grid", a.stars_grid, "NYxNX, e.g. 3x3 (1x1: one PSF for the field)");
    dpo.stars.grid_ny = ny;
    dpo.stars.grid_nx = nx;
    if (a.model_psfs != "stars" && (ny != 1 || nx != 1))
      throw InvalidArgument("aosr reconstruct", "--stars-grid", a.stars_grid, "only with --model-psfs stars");
  }
  {
    std::string why;
    if (!dpo.stars.IsValid(&why)) throw InvalidArgument("aosr reconstruct", "--stars-*", why, "valid stars PSF settings");
  }

  if (a.rings == 0 && !a.ring_centre.empty())
    throw InvalidArgument("aosr reconstruct", "--ring-centre", a.ring_centre, "only with --rings K (K >= 1)");
  double ring_y = 0, ring_x = 0;
  if (!a.ring_centre.empty()) ParseRingCentre("aosr reconstruct", a.ring_centre, &ring_y, &ring_x);

  progress.Step("reading " + a.dataset);
  // A whole detector: when the whole-grid model and solve would pass the memory limit, the reconstruction runs
  // by tiles without a whole-grid model (solvers/tiling.hpp, "A whole detector"), its output written by rows, and
  // its frames are not held either: each tile's window is read by sections (as aosr.distributed's tasks read
  // them; the weights' rule decided reading the frames in bands). The frames are read whole when the whole grid
  // fits, or when the run needs them whole (stars PSFs, estimated offsets).
  Dataset d = LoadDataset(a.dataset, DatasetPixels::kSections);
  const MemoryLimit limit = CurrentMemoryLimit();
  double whole_need = 0;
  const bool whole_fits = WholeGridFits(d, o.method, limit.bytes, &whole_need);
  if (whole_fits || a.model_psfs == "stars" || dpo.offsets == DatasetOffsets::kEstimate) d = LoadDataset(a.dataset);
  const bool has_truth = d.truth.has_value() || d.manifest.contains("truth");
  if (a.rings > 0 && !has_truth)
    throw InvalidArgument("aosr reconstruct", "--rings", std::to_string(a.rings),
                          "a dataset with a truth image (the rings score the reconstruction against it)");
  if (!a.ring_centre.empty() && !(ring_y >= -0.5 && ring_y <= d.hr_frame.rows - 0.5 && ring_x >= -0.5 &&
                                  ring_x <= d.hr_frame.cols - 0.5))
    throw InvalidArgument("aosr reconstruct", "--ring-centre", a.ring_centre,
                          "a point on the " + ToString(d.hr_frame) + " HR image: -0.5 <= X <= " +
                              ToString(d.hr_frame.cols - 0.5) + ", -0.5 <= Y <= " + ToString(d.hr_frame.rows - 0.5));
  if (a.rings > 0) {
    // The crop the scores use (below), and the most rings it holds: refused now, not after the reconstruction.
    int crop = int(d.trustworthy_border_px * d.r);
    if (2 * crop + 11 > std::min(d.hr_frame.rows, d.hr_frame.cols)) crop = 0;
    RingOptions ro;
    if (!a.ring_centre.empty()) ro.centre_y = ring_y, ro.centre_x = ring_x;
    const int most = MaxRings(d.hr_frame, crop, ro);
    if (a.rings > most)
      throw InvalidArgument("aosr reconstruct", "--rings", std::to_string(a.rings),
                            "1 .. " + std::to_string(most) + " for this dataset, crop and centre (rings at least " +
                                ToString(kMinRingWidthPx) + " HR px wide, the SSIM window)");
  }
  if (!whole_fits) {
    if (a.rings > 0)
      throw InvalidArgument("aosr reconstruct", "--rings", std::to_string(a.rings),
                            "a dataset whose whole-grid reconstruction fits in memory (this one needs about " +
                                FormatBytes(whole_need) + ", the limit is " + FormatBytes(limit.bytes) +
                                "): score the written image with aosr evaluate");
    dpo.whole_grid_model = false;
  }
  const fs::path out_canonical = fs::weakly_canonical(a.out);
  const std::set<fs::path> inputs = DatasetInputFiles(d);
  for (const std::string& p : {a.out, ReconstructionAuxPath(a.out, ReconstructionMethod::kDrizzle),
                               ReconstructionAuxPath(a.out, ReconstructionMethod::kTikhonov), a.stars_psf_out})
    if (!p.empty() && inputs.count(fs::weakly_canonical(p)))
      throw InvalidArgument("aosr reconstruct", "-o", a.out, "a path that is not one of the dataset's input files (" + p + ")");
  if (a.model_psfs == "nominal") {
    dpo.nominal_psfs = true;
  } else if (a.model_psfs == "stars") {
    dpo.stars_psfs = true;
  } else if (!a.model_psfs.empty()) {
    dpo.model_psfs = ReadFits(a.model_psfs).planes;
  }
  if (a.target_psf == "diffraction") {
    if (o.method == ReconstructionMethod::kLinear) o.linear.image = DiffractionTargetPsf(d);
    else o.linear.kind = TargetPsfKind::kAuto;  // only the linear method reads it
  }
  dpo.method = o.method;
  dpo.psf_field = ParseDatasetPsfField(a.psf_field);
  if (dpo.stars_psfs) progress.Step("estimating the model PSF from the stars in the frames");
  if (dpo.offsets == DatasetOffsets::kEstimate) progress.Step("estimating the frames' offsets (registration)");
  const DatasetProblem dp = ProblemFromDataset(d, dpo);
  if (dp.stars_psf && !a.stars_psf_out.empty()) {
    FitsHeader ph;
    ph.Set("ORIGIN", std::string("aosr ") + AOSR_VERSION, "software that wrote this file");
    ph.Set("AOSRDATA", "stars model PSFs", "per frame, HR sampling, unit sum, centred at (K/2, K/2)");
    ph.Set("SRFACTOR", static_cast<long long>(d.r), "super-resolution factor r");
    ph.Set("NSTARS", static_cast<long long>(dp.stars_psf->used), "stars in the fit");
    ph.Set("CHI2DOF", dp.stars_psf->chi2_per_dof, "chi2 per degree of freedom of the fit");
    const StarsPsfResult& st = *dp.stars_psf;
    if (st.grid.nodes() > 1) {
      // The field model beside the centre's PSFs: node-major planes (plane g·N + i: node g, frame i), each node's
      // position on the HR frame in the header, as a simulation's field_psfs.fits.
      FitsExtension field;
      field.name = "FIELD";
      field.type = FitsType::kFloat64;
      field.header.Set("FLDNY", static_cast<long long>(st.grid.ny()), "field grid: nodes along y (rows)");
      field.header.Set("FLDNX", static_cast<long long>(st.grid.nx()), "field grid: nodes along x (columns)");
      field.header.Set("FLDINTRP", "bilinear", "PSF between nodes (core/psf_field.hpp)");
      field.header.Set("FLDDEG", static_cast<long long>(st.grid_degree), "nodes' prior: polynomial degree in position");
      field.header.Set("FLDROUGH", st.grid_roughness, "nodes' prior: departure from it (fraction of the peak)");
      for (int g = 0; g < st.grid.nodes(); ++g) {
        char digits[8];
        std::snprintf(digits, sizeof digits, "%04d", g % 10000);
        const auto node = st.grid.Node(g);
        field.header.Set(std::string("FY") + digits, node[0], "[HR px] node y");
        field.header.Set(std::string("FX") + digits, node[1], "[HR px] node x");
        field.header.Set(std::string("FN") + digits, st.node_stars[std::size_t(g)], "stars at the node (weights)");
        for (const Image& p : st.field_psfs[std::size_t(g)]) field.planes.push_back(p);
      }
      ph.Set("AOSRDATA", "stars model PSFs at the field centre", "per frame; extension FIELD: the grid's nodes");
      WriteFitsCubeWithExtensions(a.stars_psf_out, st.psfs, ph, {field}, FitsType::kFloat64);
    } else {
      WriteFitsCube(a.stars_psf_out, st.psfs, ph, FitsType::kFloat64);
    }
  }
  // The caution about the weights: on stderr, or under --json in the JSON's "warning" (stdout stays JSON).
  if (!dp.warning.empty() && !a.json) std::fprintf(stderr, "aosr reconstruct: warning: %s\n", dp.warning.c_str());

  progress.Step(std::string("reconstructing with ") + ToString(o.method) + " (" + std::to_string(d.size()) +
                " frames of " + ToString(d.frame) + ", r = " + std::to_string(d.r) + ")");
  o.progress = bar.Callback();
  // Without a whole-grid model: tiles chosen under the memory limit (unless given), the regularisation on the
  // largest central window that fits (512 camera px at most), and the output written by rows as tiles finish.
  // (A field model by tiles also comes without a whole-grid model, dp.field, but fits: it is not streamed.)
  const bool streamed = !whole_fits;
  std::unique_ptr<FitsRowWriter> image_writer, aux_writer;
  const std::string streamed_aux_path = ReconstructionAuxPath(a.out, o.method);
  if (streamed) {
    // The tiles chosen to fit (a field model's own where they are smaller).
    FitDatasetTilingToMemory(dp, o, limit.bytes, &tiling);
    if (!a.json)
      std::fprintf(stderr,
                   "aosr reconstruct: the whole grid (%s) needs about %s, more than the memory limit %s (%s): "
                   "tiles of %d camera px, the output written by rows\n",
                   ToString(d.hr_frame).c_str(), FormatBytes(whole_need).c_str(), FormatBytes(limit.bytes).c_str(),
                   limit.source.c_str(), tiling.tile);
    image_writer = std::make_unique<FitsRowWriter>(a.out, d.hr_frame);
    tiling.rows = [&](Index y0, const Image& rows, const Image& aux_rows) {
      image_writer->WriteRows(y0, rows);
      if (aux_rows.size() == 0) return;
      if (!aux_writer) aux_writer = std::make_unique<FitsRowWriter>(streamed_aux_path, d.hr_frame);
      aux_writer->WriteRows(y0, aux_rows);
    };
  } else if (a.tile == 0 && !a.resume.empty() && !dp.psf_field) {
    throw InvalidArgument("aosr reconstruct", "--resume", a.resume,
                          "only with --tile, a field model or a dataset reconstructed by tiles for its size");
  }
  // Ctrl-C in a tiled run stops it cleanly: the tiles in progress stop at their next iteration, the finished
  // ones stay in --resume's folder, and nothing is written. A second Ctrl-C ends the process at once.
  const bool tiled_run = tiling.tile > 0 || dp.psf_field.has_value();
  InterruptFlag interrupt(tiled_run);
  if (tiled_run) tiling.stop = [&interrupt] { return interrupt.raised(); };
  TilingSummary ts;
  const Reconstruction rec = ReconstructDataset(dp, o, tiling, &ts);
  const bool tiled = !ts.tiles.empty();
  bar.Clear();
  if (interrupt.raised()) {
    std::fprintf(stderr, "aosr reconstruct: interrupted: %s; nothing written%s\n", rec.summary.message.c_str(),
                 a.resume.empty() ? " (with --resume DIR a rerun continues from the finished tiles)"
                                  : ("; rerun the same command to continue from the tiles in " + a.resume).c_str());
    std::exit(130);
  }

  FitsHeader h = ReconstructionHeader(d, o.method, rec, &dp, tiled ? &ts : nullptr);
  const FitsHeader common = h;  // the aux map sets its own unit
  SetHrImageKeywords(d, "electron", &h);  // BUNIT (e- per HR pixel per frame) and the HR grid's WCS
  progress.Step("writing " + a.out);
  if (rec.linear) {
    // The linear method's output carries what photometry on it needs: its effective PSF, the target, the
    // noise covariance kernel and the per-frequency leakage (target_psf.hpp), as named extensions.
    const TargetPsfSummary& ls = *rec.linear;
    h.Set("TARGET", ls.target, "target PSF");
    h.Set("TGTFWHM", ls.target_fwhm_hr_px, "[HR px] target PSF FWHM");
    h.Set("EFFFWHM", ls.effective_fwhm_hr_px, "[HR px] effective PSF FWHM");
    h.Set("PSFFRAC", ls.effective_psf_window_fraction, "part of the effective PSF inside extension PSF");
    h.Set("KAPPA", ls.kappa, "ridge kappa of Q = T (A^H A + kappa I)^-1 A^H");
    h.Set("LEAKAGE", ls.leakage, "U: PSF error power / target power");
    h.Set("LEAKMIN", ls.leakage_unreachable, "U_min: part no estimator reaches");
    h.Set("LEAKBAND", ls.band_cycles_per_hr_px, "[cyc/HR px] leakage <= 1e-3 inside");
    h.Set("NOISERMS", ls.noise_rms, "[electron] output noise RMS per HR pixel");
    h.Set("NOISEERR", ls.noise_rms_error, "[electron] its standard error (probes)");
    h.Set("NPROBES", static_cast<long long>(ls.noise_probes), "noise probes (0: exact)");
    std::vector<FitsExtension> ext;
    auto add = [&ext](const char* name, const Image& img, const char* what, FitsType type) {
      if (img.size() == 0) return;
      FitsExtension e;
      e.name = name;
      e.planes = {img};
      e.header.Set("AOSRDATA", what, "content of this HDU");
      e.type = type;
      ext.push_back(std::move(e));
    };
    // The kernels in double precision (photometry sums them); the HR-sized leakage map in single (it is for
    // looking at, and a 2048² grid would otherwise add 32 MB).
    add("PSF", rec.effective_psf, "effective PSF of the image, unit sum, centred at (K/2, K/2)", FitsType::kFloat64);
    add("NOISE_CORR", rec.noise_correlation, "noise covariance xi(dy, dx) [electron^2], lag 0 at the centre",
        FitsType::kFloat64);
    add("LEAKAGE", rec.leakage_spectrum, "leakage per HR frequency, zero frequency at (M/2, M/2)", FitsType::kFloat32);
    if (streamed) image_writer->Finish(h, ext);
    else WriteFitsWithExtensions(a.out, rec.image, h, ext, FitsType::kFloat32);
  } else {
    if (streamed) image_writer->Finish(h);
    else WriteFits(a.out, rec.image, h, FitsType::kFloat32);
  }
  std::string aux_path;
  if (!rec.aux_name.empty()) {
    aux_path = ReconstructionAuxPath(a.out, o.method);
    FitsHeader ha = common;
    ha.Set("AOSRDATA", rec.aux_name, "content of this HDU");
    // std: electrons, as the image; Drizzle's weight: summed input weights, no unit of its own.
    SetHrImageKeywords(d, rec.aux_name == "weight" ? "" : "electron", &ha);
    if (streamed && aux_writer) aux_writer->Finish(ha);
    else if (!streamed) WriteFits(aux_path, rec.aux, ha, FitsType::kFloat32);
  }

  nlohmann::json j = {{"method", ToString(o.method)},
                      {"dataset", a.dataset},
                      {"output", a.out},
                      {"frames", d.size()},
                      {"r", d.r},
                      {"weights", dp.weights_source},
                      {"weights_option", a.weights},
                      {"offsets", dp.offsets_source},
                      {"model_psfs_replaced", dp.model_psfs_replaced},
                      {"masked_pixels", dp.masked_pixels},
                      {"regularisation", rec.regularisation},
                      {"summary",
                       {{"method", rec.summary.method},
                        {"termination", ToString(rec.summary.termination)},
                        {"message", rec.summary.message},
                        {"iterations", rec.summary.iterations},
                        {"final_cost", rec.summary.final_cost},
                        {"seconds", rec.summary.seconds},
                        {"frame_residual_rms", rec.summary.frame_residual_rms}}},
                      {"seconds_total", rec.seconds_total}};
  if (dp.registration) {
    // Per frame, in camera px (HR px / r): the commanded offset, the estimated one and its standard error.
    const RegistrationResult& reg = *dp.registration;
    nlohmann::json frames = nlohmann::json::array();
    for (std::size_t i = 0; i < reg.estimated.size(); ++i)
      frames.push_back({{"commanded_camera_px", {reg.commanded[i].dy / d.r, reg.commanded[i].dx / d.r}},
                        {"estimated_camera_px", {reg.estimated[i].dy / d.r, reg.estimated[i].dx / d.r}},
                        {"sigma_camera_px", reg.sigma_hr_px[i] / d.r}});
    j["registration"] = {{"frames", frames},
                         {"anchor", ToString(dpo.registration.anchor)},
                         {"search_range_camera_px", dpo.registration.search_range_camera_px},
                         {"rounds", reg.rounds},
                         {"converged", reg.converged},
                         {"seconds", reg.seconds}};
  }
  if (!aux_path.empty()) j["aux"] = {{"name", rec.aux_name}, {"path", aux_path}};
  if (dp.psf_field)
    j["psf_field"] = {{"model", ToString(dp.psf_field->approach)},
                      {"grid", {dp.psf_field->grid.ny(), dp.psf_field->grid.nx()}},
                      {"psfs", dpo.nominal_psfs ? "nominal" : "dataset"}};
  if (tiled)
    j["tiling"] = {{"tile", ts.tile},
                   {"overlap", ts.overlap},
                   {"overlap_rule", ts.overlap_rule},
                   {"tiles", {ts.tiles_y, ts.tiles_x}},
                   {"regularisation_source", ts.regularisation_source},
                   {"tiles_resumed", ts.tiles_resumed}};
  if (dp.stars_psf) {
    const StarsPsfResult& st = *dp.stars_psf;
    j["stars_psf"] = {{"stars_used", st.used},
                      {"detected", st.detected},
                      {"saturated", st.saturated},
                      {"dropped", st.dropped},
                      {"rejected", st.rejected},
                      {"background_mesh_px", st.background_mesh_px},
                      {"min_required", st.min_required},
                      {"psf_size_hr_px", st.psf.rows()},
                      {"chi2_per_dof", st.chi2_per_dof},
                      {"chi2_near_stars", st.chi2_near_stars},
                      {"dof", st.dof},
                      {"rounds", st.rounds},
                      {"cg_converged", st.cg_converged},
                      {"cg_iterations_last", st.cg_iterations_last},
                      {"cg_iterations_total", st.cg_iterations_total},
                      {"background_e", st.background_e},
                      {"seconds", st.seconds}};
    if (st.grid.nodes() > 1)
      j["stars_psf"]["grid"] = {{"ny", st.grid.ny()}, {"nx", st.grid.nx()}, {"node_stars", st.node_stars},
                                     {"degree", st.grid_degree}, {"roughness", st.grid_roughness}};
    if (!a.stars_psf_out.empty()) j["stars_psf"]["path"] = a.stars_psf_out;
  }
  if (!dp.background_sigma_e.empty()) j["background_sigma_e"] = dp.background_sigma_e;
  if (!dp.warning.empty()) j["warning"] = dp.warning;
  // Noise figures need absolute weights: a validity mask is relative (every pixel weight 1, σ = --noise-sigma).
  const bool noise_unscaled = rec.linear && dp.weights_source == "validity mask" &&
                              !(a.noise_sigma_option && a.noise_sigma_option->count() > 0);
  if (rec.linear) {
    const TargetPsfSummary& ls = *rec.linear;
    j["linear"] = {{"target", ls.target},
                   {"target_fwhm_hr_px", ls.target_fwhm_hr_px},
                   {"effective_fwhm_hr_px", ls.effective_fwhm_hr_px},
                   {"effective_psf_window_fraction", ls.effective_psf_window_fraction},
                   {"kappa", ls.kappa},
                   {"leakage", ls.leakage},
                   {"leakage_unreachable", ls.leakage_unreachable},
                   {"leakage_met", ls.leakage_met},
                   {"band_cycles_per_hr_px", ls.band_cycles_per_hr_px},
                   {"unreachable_frequencies", ls.unreachable_frequencies},
                   {"noise_sigma", ls.noise_sigma},
                   {"noise_rms", ls.noise_rms},
                   {"noise_rms_error", ls.noise_rms_error},
                   {"noise_probes", ls.noise_probes},
                   {"fourier_exact", ls.fourier_exact},
                   {"extensions", {"PSF", "NOISE_CORR", "LEAKAGE"}}};
    if (noise_unscaled)
      j["linear"]["noise_note"] = "weights are a validity mask: noise figures assume sigma = 1 e- per pixel; pass --noise-sigma";
  }
  if (streamed) {
    j["output_by_rows"] = {{"whole_grid_bytes", whole_need}, {"memory_limit_bytes", limit.bytes},
                           {"memory_limit_source", limit.source}, {"peak_resident_bytes", PeakResidentBytes()}};
    if (has_truth) j["metrics_note"] = "not computed: the image was never held whole; score it with aosr evaluate";
  }
  std::string aligned_line, rings_table;
  if (d.truth && !streamed) {
    MetricOptions mo;
    mo.crop_px = int(d.trustworthy_border_px * d.r);
    if (2 * mo.crop_px + 11 > std::min(d.hr_frame.rows, d.hr_frame.cols)) mo.crop_px = 0;
    Image estimate = rec.image;
    std::optional<Image> seen;
    if (rec.linear && rec.effective_psf.size() && rec.effective_psf.rows() <= d.hr_frame.rows &&
        rec.effective_psf.cols() <= d.hr_frame.cols)
      seen = ToImage(PeriodicConvolutionFromKernel(d.hr_frame, rec.effective_psf)->Apply(AsVector(*d.truth)), d.hr_frame);
    if (rec.linear) {
      // A linear output keeps the sky the truth has not: estimate it as the difference of the two images'
      // background levels (medians over the scored region) and subtract it before scoring.
      const Image& ref = seen ? *seen : *d.truth;
      const double sky = SkyLevelDifference(ref, estimate, mo.crop_px);
      estimate -= sky;
      j["sky_subtracted_e"] = sky;
    }
    EvaluationOptions eo;
    eo.crop_px = mo.crop_px;
    eo.hr_pixel_mas = DatasetHrPixelMas(d);
    eo.rings = a.rings;
    if (!a.ring_centre.empty()) ParseRingCentre("aosr reconstruct", a.ring_centre, &eo.ring_centre_y, &eo.ring_centre_x);
    Evaluation ev;
    try {
      // The dataset's star list only for the rings' photometry (the summary reports no other star figures).
      ev = EvaluateReconstruction(*d.truth, estimate, a.rings > 0 ? d.stars : std::vector<PointSource>{}, eo);
    } catch (const InvalidArgument& e) {
      const std::string what = e.what();
      if (a.rings > 0 && (what.find("rings") != std::string::npos || what.find("centre") != std::string::npos))
        throw InvalidArgument("aosr reconstruct: --rings " + std::to_string(a.rings) +
                              (a.ring_centre.empty() ? "" : " --ring-centre " + a.ring_centre) + ": " + what);
      throw;
    }
    const ImageMetrics& m = ev.metrics;
    j["against_truth"] = {{"psnr_db", m.psnr}, {"ssim", m.ssim}, {"rmse", m.rmse}, {"crop_px", mo.crop_px}};
    AddAlignedScores(ev, &j["against_truth"]);
    aligned_line = AlignedScoresLine(ev);
    if (ev.measured_rings) {
      j["against_truth"]["rings"] = EvaluationRingsJson(ev, eo.hr_pixel_mas);
      rings_table = RingsTable(ev, eo.hr_pixel_mas, "    ");
    }
    if (seen) {
      // A linear output with a known PSF estimates the truth seen through that PSF: compare with that too.
      const ImageMetrics t = CompareImages(*seen, estimate, mo);
      j["against_truth_through_psf"] = {{"psnr_db", t.psnr}, {"ssim", t.ssim}, {"rmse", t.rmse}};
    }
  }
  if (a.json) {
    std::printf("%s\n", j.dump(2).c_str());
    return;
  }
  std::printf("%s: %s, %d iterations, %.3f s (total %.3f s)\n", ToString(o.method),
              ToString(rec.summary.termination), rec.summary.iterations, rec.summary.seconds, rec.seconds_total);
  std::printf("  %s\n", rec.summary.message.c_str());
  if (noise_unscaled)
    std::printf("  note: the weights are a validity mask, so the noise figures assume sigma = 1 e- per pixel: pass "
                "--noise-sigma (the frames' noise in e-)\n");
  std::printf("  weights: %s; offsets: %s%s\n", dp.weights_source.c_str(), dp.offsets_source.c_str(),
              dp.model_psfs_replaced ? ("; model PSFs replaced by " + a.model_psfs).c_str() : "");
  if (j.contains("sky_subtracted_e"))
    std::printf("  sky subtracted before scoring: %.4g e- per HR pixel (output's median level minus the truth's)\n",
                j["sky_subtracted_e"].get<double>());
  if (dp.stars_psf) {
    const StarsPsfResult& st = *dp.stars_psf;
    std::printf("  %s (%.2f s)%s%s\n", st.BriefReport().c_str(), st.seconds, a.stars_psf_out.empty() ? "" : "; wrote ",
                a.stars_psf_out.c_str());
  }
  if (dp.registration) {
    const RegistrationResult& reg = *dp.registration;
    std::printf("  registration (%d rounds%s, anchor %s, %.2f s), camera px (dy, dx):\n", reg.rounds,
                reg.converged ? ", converged" : ", NOT converged", ToString(dpo.registration.anchor), reg.seconds);
    for (std::size_t i = 0; i < reg.estimated.size(); ++i)
      std::printf("    frame %zu: commanded (%+.4f, %+.4f)  estimated (%+.4f, %+.4f) +- %.4f\n", i,
                  reg.commanded[i].dy / d.r, reg.commanded[i].dx / d.r, reg.estimated[i].dy / d.r,
                  reg.estimated[i].dx / d.r, reg.sigma_hr_px[i] / d.r);
  }
  if (j.contains("against_truth"))
    std::printf("  against the truth (crop %d HR px): PSNR %.2f dB, SSIM %.4f\n", j["against_truth"]["crop_px"].get<int>(),
                j["against_truth"]["psnr_db"].get<double>(), j["against_truth"]["ssim"].get<double>());
  if (!aligned_line.empty()) std::printf("    %s\n", aligned_line.c_str());
  if (!rings_table.empty()) std::printf("%s", rings_table.c_str());
  if (j.contains("against_truth_through_psf"))
    std::printf("  against the truth seen through the output's effective PSF: PSNR %.2f dB, SSIM %.4f\n",
                j["against_truth_through_psf"]["psnr_db"].get<double>(),
                j["against_truth_through_psf"]["ssim"].get<double>());
  std::printf("  wrote %s%s\n", a.out.c_str(), aux_path.empty() ? "" : (" and " + aux_path).c_str());
}

}  // namespace

void RegisterReconstruct(CLI::App& app) {
  auto a = std::make_shared<ReconstructArgs>();
  CLI::App* cmd = app.add_subcommand(
      "reconstruct",
      "Super-resolve a dataset (folder or manifest.json from `aosr simulate`, or measured frames) with one "
      "method. Writes OUT.fits (e- per HR pixel per frame) and, for drizzle/tikhonov --std, OUT_weight.fits / "
      "OUT_std.fits. If the dataset has a truth, reports PSNR/SSIM against it.");
  cmd->add_option("dataset", a->dataset, "dataset folder or manifest")->required();
  cmd->add_option("-m,--method", a->method, "shift-add | shift-add-median | drizzle | tikhonov | linear | tv | map")
      ->capture_default_str();
  cmd->add_option("-o,--output", a->out, "output FITS image")->required();
  cmd->add_flag("--json", a->json, "print the summary as JSON");
  cmd->add_option("--rings", a->rings,
                  "with a truth: also score K concentric rings about --ring-centre, each aligned on its own, and on a "
                  "star field each ring's photometric bias (as aosr evaluate --rings)")
      ->check(CLI::Range(1, 100000));
  cmd->add_option("--ring-centre", a->ring_centre,
                  "X,Y: the rings' centre in HR pixels, column then row (e.g. the guide star); default the image centre");
  cmd->add_flag(
      "--progress", a->progress,
      "show progress on stderr even with --json or when stderr is not a terminal (then as lines, at most "
      "one a second; by default it shows only on a terminal without --json)");
  cmd->add_option("--weights", a->weights, "auto (background for the linear methods shift-add, drizzle, tikhonov, linear; dataset for tv, map) | background (sky + read-noise "
                  "inverse variances, source-independent: detector model or estimated per frame) | dataset = poisson (the "
                  "dataset's inverse variances, source photon noise included) | mask (uniform on valid pixels)")
      ->capture_default_str();
  cmd->add_option("--offsets", a->offsets,
                  "frame offsets: auto | dm | centroids (for shift-add/drizzle; model-based methods use the PSFs) | "
                  "estimate (every method: each frame's offset measured from the frames against a reconstruction, "
                  "the model PSFs shifted by it; reported per frame beside the commanded one)")
      ->capture_default_str();
  cmd->add_option("--registration-range", a->registration_range,
                  "--offsets estimate: largest correction to a commanded offset [camera px]; a frame beyond is an error")
      ->capture_default_str()
      ->check(CLI::Range(1e-3, 4.0));
  cmd->add_option("--registration-rounds", a->registration_rounds,
                  "--offsets estimate: reconstruct-register rounds at most (stops earlier when converged)")
      ->capture_default_str()
      ->check(CLI::Range(1, 50));
  cmd->add_option("--registration-anchor", a->registration_anchor,
                  "--offsets estimate: mean (the estimated set keeps the commanded mean) | frame0 (frame 0 keeps its "
                  "commanded offset)")
      ->capture_default_str();
  cmd->add_option("--psf-field", a->psf_field,
                  "the PSF across the field, for a dataset with a psf_field (simulations of a scene with one) or "
                  "with --model-psfs stars --stars-grid over a grid: auto (tiles when there is a field model and the "
                  "method models the PSF) | none (the guide star's PSF "
                  "everywhere) | tiles (overlapping tiles, each with the PSFs interpolated at its centre; --tile "
                  "sets their size, default half the grid spacing) | operator (one space-variant operator over the "
                  "whole field, the interpolated PSF at every pixel: exact, slower; not for linear)")
      ->capture_default_str()
      ->check(CLI::IsMember({"auto", "none", "tiles", "operator"}));
  cmd->add_option("--model-psfs", a->model_psfs,
                  "PSFs the reconstructor uses instead of the dataset's: a FITS cube (HR sampling, centred), `nominal` for "
                  "the dataset's nominal_psfs (closed-loop simulations: the analytic-AO model), or `stars` for a PSF "
                  "estimated from the point sources in the frames (one HR PSF shifted by each frame's DM offset; "
                  "detection, position/flux fits with neighbours subtracted, joint least squares)");
  cmd->add_option("--stars-psf-out", a->stars_psf_out,
                  "--model-psfs stars: write the estimated per-frame model PSFs (HR sampling, centred) as a FITS cube");
  cmd->add_option("--stars-psf-size", a->stars_psf_size,
                  "--model-psfs stars: side of the estimated PSF [HR px, even]; 0: 32 r (16 camera px each side), "
                  "at most the HR frame")
      ->capture_default_str()
      ->check(CLI::Range(0, 4096));
  cmd->add_option("--stars-threshold", a->stars_threshold,
                  "--model-psfs stars: detection threshold [background sigma per camera pixel]")
      ->capture_default_str()
      ->check(CLI::Range(0.5, 1e6));
  cmd->add_option("--stars-min", a->stars_min,
                  "--model-psfs stars: least number of usable stars (the floor is also ceil(r^2/N))")
      ->capture_default_str()
      ->check(CLI::Range(1, 100000));
  cmd->add_option("--stars-rounds", a->stars_rounds,
                  "--model-psfs stars: rounds of (PSF solve, star position/flux fits)")
      ->capture_default_str()
      ->check(CLI::Range(1, 50));
  cmd->add_option("--stars-background-mesh", a->stars_background_mesh,
                  "--model-psfs stars: box size [camera px] of the mesh on which a structured background (nebula, galaxy "
                  "disc) is estimated and removed first; 0: a constant per frame")
      ->capture_default_str()
      ->check(CLI::Range(0, 4096));
  cmd->add_option("--stars-max-chi2", a->stars_max_chi2,
                  "--model-psfs stars: refuse the estimate when the chi2 per pixel near the stars exceeds this (the "
                  "frames are then not point sources on a smooth background); 0: no check")
      ->capture_default_str()
      ->check(NonNegativeFinite());
  cmd->add_flag("--stars-reject-extended", a->stars_reject_extended,
                "--model-psfs stars: reject and mask fitted sources whose residual is not a point source's (nebular "
                "knots, galaxies); off by default: on real star fields it also drops blended and halo-mismatched stars");
  cmd->add_option("--stars-grid", a->stars_grid,
                  "--model-psfs stars: NYxNX nodes of a grid over the field at which the PSF is fitted (bilinear between "
                  "them, each star through the PSF at its position; the result is the field model, --psf-field); each "
                  "node needs its own stars. 1x1: one PSF for the field")
      ->capture_default_str();
  cmd->add_option("--stars-grid-degree", a->stars_grid_degree,
                  "--stars-grid: the nodes follow a polynomial surface of this degree in position (PSFEx's model of the "
                  "variation, as a prior on the grid) and depart from it by --stars-grid-roughness; 0: each node is "
                  "tied to the nodes' mean instead. Without a grid (1x1) it has no effect")
      ->capture_default_str()
      ->check(CLI::Range(0, 4));
  cmd->add_option("--stars-grid-roughness", a->stars_grid_roughness,
                  "--stars-grid-degree: how far a node may depart from the polynomial surface, a fraction of the PSF's "
                  "peak")
      ->capture_default_str()
      ->check(CLI::PositiveNumber);
  cmd->add_option("--lambda", a->lambda, "Tikhonov lambda (default: GCV)")->check(NonNegativeFinite());
  cmd->add_option("--lambda-rule", a->lambda_rule,
                  "Tikhonov (and the TV/MAP pilot) lambda without --lambda: gcv | discrepancy (Morozov, residual = "
                  "noise) | lcurve (Hansen's corner) | upre (unbiased predictive risk) | wiener (sigma^2/s(0) of "
                  "--prior fitted); discrepancy, upre and wiener use --noise-sigma (1 for inverse-variance weights; "
                  "wiener: 0 fits it)")
      ->capture_default_str();
  cmd->add_option("--prior", a->prior,
                  "Tikhonov prior: identity | gradient | laplacian | power-spectrum | fitted (a power spectrum "
                  "fitted to the frames themselves)")
      ->capture_default_str();
  cmd->add_option("--boundary", a->boundary, "Tikhonov boundary: periodic | padded")->capture_default_str();
  cmd->add_flag("--std", a->std_map, "Tikhonov: write the posterior standard deviation map (closed form for uniform weights, else from posterior draws)");
  cmd->add_flag("--count-unconstrained", a->count_unconstrained,
                "Tikhonov: count the HR frequencies the frames leave unconstrained (the rank of every Fourier bin's "
                "system; costly where N is near r^2) and report them in the summary message");
  a->noise_sigma_option = cmd->add_option("--noise-sigma", a->noise_sigma,
                  "Tikhonov --std, discrepancy, upre, wiener, and linear: noise sigma of a weight-1 pixel (1 for "
                  "inverse-variance weights)")
      ->capture_default_str()
      ->check(NonNegativeFinite());
  cmd->add_option("--target-psf", a->target_psf,
                  "linear: output PSF: auto (Gaussian, FWHM max(PSF FWHM, 1 camera px)) | diffraction (the telescope's "
                  "diffraction-limited PSF at the dataset's wavelength, HR sampling) | gaussian:<FWHM HR px> | <kernel>.fits")
      ->capture_default_str();
  cmd->add_option("--leakage", a->leakage, "linear: leakage bound epsilon, U <= U_min + epsilon, in (0, 1)")
      ->capture_default_str()
      ->check(CLI::Range(1e-12, 0.999));
  cmd->add_option("--noise-probes", a->noise_probes, "linear, weighted data: noise probes for the noise map")
      ->capture_default_str()
      ->check(CLI::Range(2, 100000));
  cmd->add_option("--mu", a->mu, "TV weight mu (MAP: lambda = 2 mu); default automatic (reconstruct.hpp)")
      ->check(NonNegativeFinite());
  cmd->add_option("--iterations", a->iterations, "iteration limit of tv / map")->check(CLI::Range(1, 1000000));
  cmd->add_flag("--positivity", a->positivity, "tv / map: constrain the image to be >= 0");
  cmd->add_option("--likelihood", a->likelihood, "map: gaussian | poisson")->capture_default_str();
  cmd->add_option("--map-prior", a->map_prior, "map: tikhonov | charbonnier-tv | huber-tv")->capture_default_str();
  cmd->add_option("--read-noise", a->read_noise, "map poisson: read noise [e-]")->check(NonNegativeFinite());
  cmd->add_option("--kernel", a->kernel, "drizzle: square | turbo | point | gaussian | lanczos3")->capture_default_str();
  cmd->add_option("--pixfrac", a->pixfrac, "drizzle: drop size as a fraction of the camera pixel, (0, 1]")
      ->capture_default_str();
  AddExecutionOptions(cmd, &a->exec);
  cmd->add_option("--tile", a->tile,
                  "reconstruct in overlapping tiles of at most T x T camera px, blended with no seam, one "
                  "regularisation for the field (chosen on the whole field); 0: the whole grid at once");
  cmd->add_option("--tile-overlap", a->tile_overlap,
                  "--tile: camera px added on each side of a tile; default: tikhonov and linear measure it from "
                  "their response (the tiled error below --tile-tolerance), the others from the PSF's extent and "
                  "the method's reach (solvers/tiling.hpp, \"The overlap rule\"; the JSON's tiling.overlap_rule)");
  cmd->add_option("--tile-tolerance", a->tile_tolerance,
                  "the automatic overlap's bound on the tiled error of tikhonov and linear, a fraction of the level")
      ->capture_default_str();
  cmd->add_option("--resume", a->resume,
                  "--tile: keep each finished tile in this folder (created if missing) and reuse the tiles a killed "
                  "run of the same command left there; the output is byte-identical to an uninterrupted run");
  cmd->callback([a] { RunReconstruct(*a); });
}

}  // namespace aosr::cli
