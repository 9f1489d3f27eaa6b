// Bindings of the solvers layer: aosr.reconstruct(dataset, method, **options) for every method of
// include/aosr/solvers/reconstruct.hpp, and the one table that maps keyword arguments onto
// ReconstructOptions (ReconstructTable below). A new method's options are a few lines there. The tiles of a
// whole detector as separate jobs (aosr.distributed.reconstruct_tiles) are bound in tiles.cpp.
#include <algorithm>
#include <cmath>
#include <fstream>

#include "aosr/core/error.hpp"
#include "aosr/core/memory.hpp"
#include "aosr/io/atomic_file.hpp"
#include "aosr/solvers/dataset_problem.hpp"
#include "aosr/solvers/frame_power_spectrum.hpp"
#include "aosr/solvers/mtf_comparison.hpp"
#include "aosr/solvers/reconstruct.hpp"
#include "aosr/io/fits.hpp"
#include "aosr/solvers/target_psf.hpp"
#include "aosr/solvers/psf_field_model.hpp"
#include "aosr/solvers/tiling.hpp"
#include "aosr/solvers/tradeoff.hpp"
#include "bindings.hpp"
#include "common.hpp"

namespace aosr::python {
namespace {

// ---- The option tables: one per options struct, nested into ReconstructOptions ----------------------------
// Names are the C++ field names; help(aosr.reconstruct) and aosr.reconstruct_options() list them with their
// defaults, and the headers (include/aosr/solvers/*.hpp) document each field's meaning, units and range.


OptionTable<DrizzleOptions> DrizzleTable() {
  OptionTable<DrizzleOptions> t;
  t.EnumParsed("kernel", &DrizzleOptions::kernel, &ParseDrizzleKernel, &ToString,
               "square | turbo | point | gaussian | lanczos3", "how a drop's flux is spread over the HR pixels")
      .Field("pixfrac", &DrizzleOptions::pixfrac, "drop size as a fraction of the camera pixel, (0, 1]")
      .Field("fill_value", &DrizzleOptions::fill_value, "value of HR pixels no drop reaches")
      .Enum("boundary", &DrizzleOptions::boundary,
            {{"periodic", DrizzleBoundary::kPeriodic}, {"clip", DrizzleBoundary::kClip}}, "drops beyond the edge");
  return t;
}

OptionTable<ConjugateGradientOptions> CgTable() {
  OptionTable<ConjugateGradientOptions> t;
  t.Field("max_iterations", &ConjugateGradientOptions::max_iterations, "CG iteration cap per solve, >= 1")
      .Field("tolerance", &ConjugateGradientOptions::tolerance, "relative residual stopping rule, (0, 1)");
  return t;
}

OptionTable<FramePowerSpectrumOptions> SpectrumFitTable() {
  OptionTable<FramePowerSpectrumOptions> t;
  t.Field("hann_window", &FramePowerSpectrumOptions::hann_window, "Hann-window the frames before the periodogram")
      .Field("min_radius", &FramePowerSpectrumOptions::min_radius, "lowest LR frequency radius fitted")
      .Field("noise_variance", &FramePowerSpectrumOptions::noise_variance, "noise floor held at this value, 0: fitted")
      .Field("max_iterations", &FramePowerSpectrumOptions::max_iterations, "Levenberg-Marquardt iterations")
      .Field("tolerance", &FramePowerSpectrumOptions::tolerance, "fit tolerance");
  return t;
}

OptionTable<TikhonovOptions> TikhonovTable() {
  OptionTable<TikhonovOptions> t;
  t.EnumParsed("prior", &TikhonovOptions::prior, &ParseTikhonovPrior, &ToString,
               "identity | gradient | laplacian | power-spectrum | fitted | ...", "the prior operator")
      .Field("spectrum_slope", &TikhonovOptions::spectrum_slope, "power-spectrum prior: slope beta, [0, 8]")
      .Field("spectrum_corner", &TikhonovOptions::spectrum_corner,
             "power-spectrum prior: corner f0 [cycles per HR pixel], (0, 0.5]")
      .Custom("object_power_spectrum", "array", "power-spectrum prior: S on the full HR FFT grid (unshifted)",
              [](TikhonovOptions& o, py::handle v) { o.object_power_spectrum = ImageFromArray(v, "tikhonov_object_power_spectrum"); },
              [](const TikhonovOptions&) { return py::none(); })
      .EnumParsed("lambda_rule", &TikhonovOptions::lambda_rule, &ParseTikhonovLambdaRule, &ToString,
                  "fixed | gcv | discrepancy | lcurve | upre | wiener | ...", "how lambda is chosen")
      .Field("lambda", &TikhonovOptions::lambda, "lambda >= 0 for lambda_rule 'fixed'")
      .Field("gcv_decades", &TikhonovOptions::gcv_decades, "GCV search span in decades")
      .Field("gcv_steps_per_decade", &TikhonovOptions::gcv_steps_per_decade, "GCV grid points per decade")
      .Field("noise_sigma", &TikhonovOptions::noise_sigma,
             "noise sigma of a weight-1 pixel (discrepancy, std); 1 for inverse-variance weights")
      .Field("discrepancy_factor", &TikhonovOptions::discrepancy_factor, "discrepancy tau, [0.1, 10]")
      .Field("discrepancy_tolerance", &TikhonovOptions::discrepancy_tolerance, "relative, (0, 0.1]")
      .Field("discrepancy_max_evaluations", &TikhonovOptions::discrepancy_max_evaluations, ">= 4")
      .Enum("method", &TikhonovOptions::method,
            {{"auto", TikhonovMethod::kAuto}, {"fourier", TikhonovMethod::kFourier},
             {"conjugate-gradient", TikhonovMethod::kConjugateGradient}},
            "exact Fourier path or PCG")
      .Enum("bin_solver", &TikhonovOptions::bin_solver,
            {{"auto", TikhonovBinSolver::kAuto}, {"normal-equations", TikhonovBinSolver::kNormalEquations},
             {"woodbury", TikhonovBinSolver::kWoodbury}},
            "per-frequency solver")
      .Enum("boundary", &TikhonovOptions::boundary,
            {{"periodic", TikhonovBoundary::kPeriodic}, {"padded", TikhonovBoundary::kZeroPadded}},
            "periodic model or zero-padded boundary")
      .Field("padding", &TikhonovOptions::padding, "padded boundary: camera pixels per side, -1: the PSFs' extent")
      .Nested("cg", &TikhonovOptions::cg, CgTable())
      .Field("precondition", &TikhonovOptions::precondition, "CG path: precondition by the Fourier inverse")
      .Field("compute_std", &TikhonovOptions::compute_std, "compute the posterior std map (needs noise_sigma > 0)")
      .Field("std_samples", &TikhonovOptions::std_samples,
             "posterior draws behind the std map where it has no closed form (weights, masks, padding), >= 2")
      .Field("std_seed", &TikhonovOptions::std_seed, "seed of those draws")
      .Nested("spectrum_fit", &TikhonovOptions::spectrum_fit, SpectrumFitTable())
      .Field("rank_tolerance", &TikhonovOptions::rank_tolerance, "relative singular-value floor, (0, 1)")
      .Field("count_unconstrained", &TikhonovOptions::count_unconstrained,
             "count the HR frequencies the frames leave unconstrained (summary message); costly where N is near r^2");
  return t;
}

OptionTable<TotalVariationOptions> TvTable() {
  OptionTable<TotalVariationOptions> t;
  t.Field("mu", &TotalVariationOptions::mu, "TV weight (set auto_regularisation=False, or use mu=, to keep it)")
      .Field("positivity", &TotalVariationOptions::positivity, "constrain x >= 0")
      .Field("rho", &TotalVariationOptions::rho, "initial ADMM penalty, 0: automatic")
      .Field("adaptive_rho", &TotalVariationOptions::adaptive_rho, "residual balancing")
      .Field("rho_balance", &TotalVariationOptions::rho_balance, "> 1")
      .Field("rho_factor", &TotalVariationOptions::rho_factor, "> 1")
      .Field("max_rho_updates", &TotalVariationOptions::max_rho_updates, ">= 0")
      .Field("relaxation", &TotalVariationOptions::relaxation, "over-relaxation alpha, [1, 1.9]")
      .Field("absolute_tolerance", &TotalVariationOptions::absolute_tolerance, ">= 0")
      .Field("relative_tolerance", &TotalVariationOptions::relative_tolerance, "(0, 1)")
      .Field("change_tolerance", &TotalVariationOptions::change_tolerance, "0: off")
      .Field("max_iterations", &TotalVariationOptions::max_iterations, ">= 1")
      .Enum("x_update", &TotalVariationOptions::x_update,
            {{"auto", TotalVariationXUpdate::kAuto}, {"fourier", TotalVariationXUpdate::kFourier},
             {"fourier-split", TotalVariationXUpdate::kFourierSplit},
             {"conjugate-gradient", TotalVariationXUpdate::kConjugateGradient}},
            "x-update path")
      .Field("cg_tolerance", &TotalVariationOptions::cg_tolerance, "(0, 1)")
      .Field("cg_max_iterations", &TotalVariationOptions::cg_max_iterations, ">= 1");
  return t;
}

OptionTable<MapOptions> MapTable() {
  OptionTable<MapOptions> t;
  t.EnumParsed("likelihood", &MapOptions::likelihood, &ParseMapLikelihood, &ToString, "gaussian | poisson",
               "data likelihood")
      .Field("read_noise", &MapOptions::read_noise, "poisson: read noise [e-], >= 0")
      .Field("background", &MapOptions::background, "background added to the model [frame units], >= 0")
      .EnumParsed("prior", &MapOptions::prior, &ParseMapPrior, &ToString, "tikhonov | charbonnier-tv | huber-tv",
                  "the prior")
      .EnumParsed("tikhonov_operator", &MapOptions::tikhonov_operator, &ParseTikhonovPrior, &ToString,
                  "identity | gradient | laplacian | power-spectrum", "prior 'tikhonov': its operator")
      .Field("lambda", &MapOptions::lambda, "regularisation weight (with auto_regularisation=False)")
      .Field("epsilon", &MapOptions::epsilon, "Charbonnier epsilon, > 0")
      .Field("delta", &MapOptions::delta, "Huber delta, > 0")
      .EnumParsed("positivity", &MapOptions::positivity, &ParseMapPositivity, &ToString, "none | softplus", "positivity")
      .Field("softplus_scale", &MapOptions::softplus_scale, "softplus scale, 0: automatic")
      .Field("max_iterations", &MapOptions::max_iterations, ">= 1")
      .Field("function_tolerance", &MapOptions::function_tolerance, "[0, 1)")
      .Field("gradient_tolerance", &MapOptions::gradient_tolerance, "[0, 1)")
      .Field("parameter_tolerance", &MapOptions::parameter_tolerance, "[0, 1)")
      .Field("lbfgs_memory", &MapOptions::lbfgs_memory, "1..1000")
      .Field("lbfgs_eigenvalue_scaling", &MapOptions::lbfgs_eigenvalue_scaling, "Oren's scaling")
      .Enum("preconditioner", &MapOptions::preconditioner,
            {{"none", MapPreconditioner::kNone}, {"fourier", MapPreconditioner::kFourier}}, "L-BFGS preconditioner");
  return t;
}

OptionTable<TargetPsfOptions> LinearTable() {
  OptionTable<TargetPsfOptions> t;
  t.Custom("target_psf", "'auto' | 'diffraction' | float FWHM [HR px] | (K, K) array",
           "the target PSF: automatic Gaussian, the telescope's diffraction-limited PSF at the dataset's wavelength, "
           "a Gaussian of this FWHM, or a kernel at HR sampling (the CLI's --target-psf)",
           [](TargetPsfOptions& o, py::handle v) {
             if (py::isinstance<py::str>(v)) {
               const std::string name = v.cast<std::string>();
               if (name != "auto" && name != "diffraction")
                 OptionError("target_psf", py::repr(v), "'auto', 'diffraction', a FWHM in HR px or a kernel");
               // 'diffraction': an image target whose kernel aosr.reconstruct computes from the dataset.
               o.kind = name == "auto" ? TargetPsfKind::kAuto : TargetPsfKind::kImage;
               o.image = Image();
             } else if (py::isinstance<py::float_>(v) || (py::isinstance<py::int_>(v) && !py::isinstance<py::bool_>(v))) {
               o.kind = TargetPsfKind::kGaussian;
               o.fwhm_hr_px = v.cast<double>();
             } else {
               o.kind = TargetPsfKind::kImage;
               o.image = ImageFromArray(v, "linear_target_psf");
             }
           },
           [](const TargetPsfOptions& o) -> py::object {
             if (o.kind == TargetPsfKind::kAuto) return py::str("auto");
             if (o.kind == TargetPsfKind::kImage && o.image.size() == 0) return py::str("diffraction");
             if (o.kind == TargetPsfKind::kGaussian) return py::cast(o.fwhm_hr_px);
             return py::str("(kernel)");
           })
      .Field("leakage", &TargetPsfOptions::leakage, "epsilon of the leakage bound U <= U_min + epsilon, (0, 1)")
      .Field("noise_sigma", &TargetPsfOptions::noise_sigma, "sigma of a weight-1 pixel (1 for inverse variances), > 0")
      .Field("compute_noise", &TargetPsfOptions::compute_noise, "compute the noise map, its kernel and RMS")
      .Field("noise_probes", &TargetPsfOptions::noise_probes, "weighted/masked path: noise probes, >= 2")
      .Field("seed", &TargetPsfOptions::seed, "seed of the noise probes")
      .Nested("cg", &TargetPsfOptions::cg, CgTable())
      .Field("psf_size", &TargetPsfOptions::psf_size, "side of the effective-PSF image (even, >= 4), 0: automatic")
      .Field("correlation_radius", &TargetPsfOptions::correlation_radius, "noise kernel half-width [HR px], -1: 2r");
  return t;
}

}  // namespace

// The whole table: the CLI's options of `aosr reconstruct` under its names (they may set several fields, as
// the CLI does), then every field of every method's options struct as <method>_<field>.
const OptionTable<ReconstructOptions>& ReconstructTable() {
  static const OptionTable<ReconstructOptions> table = [] {
    using O = ReconstructOptions;
    auto number = [](py::handle v, const char* name) {
      if (py::isinstance<py::bool_>(v) || !(py::isinstance<py::int_>(v) || py::isinstance<py::float_>(v)))
        OptionError(name, py::repr(v), "a number");
      return v.cast<double>();
    };
    OptionTable<O> t;
    // -- The CLI's names (aosr reconstruct --help). --
    auto set_lambda = [number](O& o, py::handle v) {
      o.tikhonov.lambda_rule = TikhonovLambdaRule::kFixed;
      o.tikhonov.lambda = number(v, "lambda");
    };
    auto get_lambda = [](const O& o) -> py::object {
      return o.tikhonov.lambda_rule == TikhonovLambdaRule::kFixed ? py::cast(o.tikhonov.lambda) : py::none();
    };
    t.Custom("lambda_", "float", "Tikhonov lambda (fixes lambda_rule); default: by GCV. Also accepted as 'lambda'",
             set_lambda, get_lambda)
        .Custom("lambda", "float", "= lambda_ (for **{'lambda': ...})", set_lambda, get_lambda)
        .Custom("lambda_rule", "gcv | discrepancy | lcurve | upre | wiener | fixed", "Tikhonov (and the tv/map pilot) lambda rule",
                [](O& o, py::handle v) { TikhonovTable().Find("lambda_rule")->set(o.tikhonov, v, "lambda_rule"); },
                [](const O& o) { return TikhonovTable().Find("lambda_rule")->get(o.tikhonov); })
        .Custom("prior", "identity | gradient | laplacian | power-spectrum | fitted", "Tikhonov prior",
                [](O& o, py::handle v) { TikhonovTable().Find("prior")->set(o.tikhonov, v, "prior"); },
                [](const O& o) { return TikhonovTable().Find("prior")->get(o.tikhonov); })
        .Custom("boundary", "periodic | padded", "Tikhonov boundary",
                [](O& o, py::handle v) { TikhonovTable().Find("boundary")->set(o.tikhonov, v, "boundary"); },
                [](const O& o) { return TikhonovTable().Find("boundary")->get(o.tikhonov); })
        .Custom("std", "bool", "Tikhonov: compute the posterior std map (returned as aux)",
                [](O& o, py::handle v) { TikhonovTable().Find("compute_std")->set(o.tikhonov, v, "std"); },
                [](const O& o) { return py::cast(o.tikhonov.compute_std); })
        .Custom("noise_sigma", "float", "Tikhonov std/discrepancy and linear: sigma of a weight-1 pixel (1 for inverse variances)",
                [number](O& o, py::handle v) { o.tikhonov.noise_sigma = o.linear.noise_sigma = number(v, "noise_sigma"); },
                [](const O& o) { return py::cast(o.tikhonov.noise_sigma); })
        .Custom("mu", "float", "TV weight mu (map: lambda = 2 mu); turns auto_regularisation off. Default automatic",
                [number](O& o, py::handle v) {
                  o.auto_regularisation = false;
                  o.tv.mu = number(v, "mu");
                  o.map.lambda = 2 * o.tv.mu;
                },
                [](const O& o) { return o.auto_regularisation ? py::none() : py::cast(o.tv.mu); })
        .Custom("iterations", "int", "iteration limit of tv and map",
                [](O& o, py::handle v) {
                  TvTable().Find("max_iterations")->set(o.tv, v, "iterations");
                  o.map.max_iterations = o.tv.max_iterations;
                },
                [](const O& o) { return py::cast(o.tv.max_iterations); })
        .Custom("positivity", "bool", "tv and map: constrain the image to be >= 0",
                [](O& o, py::handle v) {
                  TvTable().Find("positivity")->set(o.tv, v, "positivity");
                  o.map.positivity = o.tv.positivity ? MapPositivity::kSoftplus : MapPositivity::kNone;
                },
                [](const O& o) { return py::cast(o.tv.positivity); })
        .Custom("likelihood", "gaussian | poisson", "map likelihood",
                [](O& o, py::handle v) { MapTable().Find("likelihood")->set(o.map, v, "likelihood"); },
                [](const O& o) { return MapTable().Find("likelihood")->get(o.map); })
        .Custom("read_noise", "float", "map poisson: read noise [e-]",
                [](O& o, py::handle v) { MapTable().Find("read_noise")->set(o.map, v, "read_noise"); },
                [](const O& o) { return py::cast(o.map.read_noise); })
        .Custom("kernel", "square | turbo | point | gaussian | lanczos3", "drizzle kernel",
                [](O& o, py::handle v) { DrizzleTable().Find("kernel")->set(o.drizzle, v, "kernel"); },
                [](const O& o) { return DrizzleTable().Find("kernel")->get(o.drizzle); })
        .Custom("pixfrac", "float", "drizzle drop size, (0, 1]",
                [](O& o, py::handle v) { DrizzleTable().Find("pixfrac")->set(o.drizzle, v, "pixfrac"); },
                [](const O& o) { return py::cast(o.drizzle.pixfrac); })
        .Custom("target_psf", "'auto' | float | array", "linear: the target PSF (see linear_target_psf)",
                [](O& o, py::handle v) { LinearTable().Find("target_psf")->set(o.linear, v, "target_psf"); },
                [](const O& o) { return LinearTable().Find("target_psf")->get(o.linear); })
        .Custom("leakage", "float", "linear: epsilon of the leakage bound",
                [](O& o, py::handle v) { LinearTable().Find("leakage")->set(o.linear, v, "leakage"); },
                [](const O& o) { return py::cast(o.linear.leakage); })
        .Custom("noise_probes", "int", "linear, weighted/masked data: noise probes",
                [](O& o, py::handle v) { LinearTable().Find("noise_probes")->set(o.linear, v, "noise_probes"); },
                [](const O& o) { return py::cast(o.linear.noise_probes); })
        .Field("auto_regularisation", &O::auto_regularisation,
               "tv/map: weight from the data (reconstruct.hpp's rule), overriding tv_mu, map_lambda, map_epsilon");
    // -- Every field, per method. A new method adds its table here: .Nested("linear", &O::linear, LinearTable()).
    t.Nested("drizzle", &O::drizzle, DrizzleTable())
        .Nested("tikhonov", &O::tikhonov, TikhonovTable())
        .Nested("linear", &O::linear, LinearTable())
        .Nested("tv", &O::tv, TvTable())
        .Nested("map", &O::map, MapTable());
    return t;
  }();
  return table;
}

// The defaults of `aosr reconstruct` (where they differ from the library's, the CLI's win: the same call
// gives the same bits from the shell and from Python).
ReconstructOptions CliDefaults() {
  ReconstructOptions o;
  o.tikhonov.noise_sigma = 1.0;        // --noise-sigma default (weights are inverse variances)
  o.linear.noise_sigma = 1.0;
  o.drizzle.compute_context = false;   // the CLI never writes the context map
  return o;
}

void DatasetRunOptions(const std::string& method, const py::dict& kwargs, const std::string& weights,
                       const std::string& offsets, ReconstructOptions* o, DatasetProblemOptions* dpo) {
  *o = CliDefaults();
  o->method = ParseReconstructionMethod(method);
  ReconstructTable().Apply(*o, kwargs);
  dpo->weights = ParseDatasetWeights(weights);
  dpo->offsets = ParseDatasetOffsets(offsets);
  dpo->method = o->method;
}

py::dict SummaryDict(const SolverSummary& s) {
  py::dict d;
  d["method"] = s.method;
  d["termination"] = ToString(s.termination);
  d["message"] = s.message;
  d["iterations"] = s.iterations;
  d["final_cost"] = s.final_cost;
  d["seconds"] = s.seconds;
  d["frame_residual_rms"] = s.frame_residual_rms;
  return d;
}

namespace {


// StarsPsfOptions from keyword arguments (or a dict) under the fields' names; unknown names are errors.
StarsPsfOptions StarsOptionsFrom(py::handle kwargs, const char* fn) {
  StarsPsfOptions o;
  if (kwargs.is_none()) return o;
  for (auto item : kwargs.cast<py::dict>()) {
    const std::string key = item.first.cast<std::string>();
    py::handle v = item.second;
    if (key == "psf_size_hr_px") o.psf_size_hr_px = v.cast<int>();
    else if (key == "detection_sigma") o.detection_sigma = v.cast<double>();
    else if (key == "min_stars") o.min_stars = v.cast<int>();
    else if (key == "rounds") o.rounds = v.cast<int>();
    else if (key == "regularisation") o.regularisation = v.cast<double>();
    else if (key == "fit_radius_px") o.fit_radius_px = v.cast<int>();
    else if (key == "cg_iterations") o.cg_iterations = v.cast<int>();
    else if (key == "cg_tolerance") o.cg_tolerance = v.cast<double>();
    else if (key == "max_stars") o.max_stars = v.cast<int>();
    else if (key == "background_mesh_px") o.background_mesh_px = v.cast<int>();
    else if (key == "max_chi2_near_stars") o.max_chi2_near_stars = v.cast<double>();
    else if (key == "reject_extended") o.reject_extended = v.cast<bool>();
    else if (key == "grid_variation") o.grid_variation = v.cast<double>();
    else if (key == "grid_degree") o.grid_degree = v.cast<int>();
    else if (key == "grid_roughness") o.grid_roughness = v.cast<double>();
    else if (key == "grid") {
      // (ny, nx) nodes of the field grid, or one int for both.
      if (py::isinstance<py::int_>(v)) {
        o.grid_ny = o.grid_nx = v.cast<int>();
      } else {
        const py::sequence q = v.cast<py::sequence>();
        if (py::len(q) != 2) throw InvalidArgument(fn, "stars grid", py::str(v).cast<std::string>(), "(ny, nx) or one int");
        o.grid_ny = q[0].cast<int>();
        o.grid_nx = q[1].cast<int>();
      }
    } else
      throw InvalidArgument(fn, "stars option", key,
                            "psf_size_hr_px | detection_sigma | min_stars | rounds | regularisation | fit_radius_px | "
                            "cg_iterations | cg_tolerance | max_stars | background_mesh_px | max_chi2_near_stars | "
                            "reject_extended | grid | grid_variation | grid_degree | grid_roughness");
  }
  std::string why;
  if (!o.IsValid(&why)) throw InvalidArgument(fn, "stars options", why, "valid StarsPsfOptions");
  return o;
}

// The stars PSF estimate as a dict (arrays copied).
py::dict StarsPsfDict(const StarsPsfResult& s) {
  py::dict d;
  d["psf"] = MoveImage(Image(s.psf));
  d["psfs"] = StackToArray(s.psfs);
  py::list offsets;
  for (const FrameOffset& o : s.offsets) offsets.append(py::make_tuple(o.dy, o.dx));
  d["offsets_hr_px"] = offsets;
  Image stars(Index(s.stars.size()), 3);
  for (std::size_t j = 0; j < s.stars.size(); ++j) stars.row(Index(j)) << s.stars[j].y, s.stars[j].x, s.stars[j].flux;
  d["stars"] = MoveImage(std::move(stars));
  d["background_e"] = s.background_e;
  d["stars_used"] = s.used;
  d["detected"] = s.detected;
  d["saturated"] = s.saturated;
  d["dropped"] = s.dropped;
  d["rejected"] = s.rejected;
  d["background_mesh_px"] = s.background_mesh_px;
  d["min_required"] = s.min_required;
  d["chi2_per_dof"] = s.chi2_per_dof;
  d["chi2_near_stars"] = s.chi2_near_stars;
  d["dof"] = s.dof;
  d["rounds"] = s.rounds;
  d["cg_iterations_last"] = s.cg_iterations_last;
  d["cg_converged"] = s.cg_converged;
  d["cg_iterations_total"] = s.cg_iterations_total;
  d["seconds"] = s.seconds;
  d["report"] = s.BriefReport();
  if (s.grid.nodes() > 1) {
    d["grid"] = py::make_tuple(s.grid.ny(), s.grid.nx());
    py::list nodes;
    for (int g = 0; g < s.grid.nodes(); ++g) {
      const auto at = s.grid.Node(g);
      nodes.append(py::make_tuple(at[0], at[1]));
    }
    d["grid_nodes_hr_px"] = nodes;
    d["node_psfs"] = StackToArray(s.node_psfs);
    py::list field;
    for (const ImageStack& f : s.field_psfs) field.append(StackToArray(f));
    d["field_psfs"] = field;
    d["node_stars"] = s.node_stars;
    d["grid_degree"] = s.grid_degree;
    d["grid_roughness"] = s.grid_roughness;
  } else {
    d["grid"] = py::make_tuple(1, 1);
  }
  return d;
}


// One MtfSubject from what compare_mtf accepts: an aosr.Reconstruction, a FITS path, or (label, array).
MtfSubject MtfSubjectFrom(py::handle item, std::size_t i) {
  if (py::isinstance<PyReconstruction>(item)) {
    const PyReconstruction& r = item.cast<const PyReconstruction&>();
    MtfSubject s;
    s.image = r.rec.image;
    s.method = r.method;
    s.label = r.method;
    if (r.method == "tikhonov") s.regularisation = r.rec.regularisation;
    s.effective_psf = r.rec.effective_psf;
    return s;
  }
  if (py::isinstance<py::str>(item) || py::hasattr(item, "__fspath__")) return MtfSubjectFromFits(PathString(item));
  if (py::isinstance<py::tuple>(item) && py::len(item) == 2) {
    MtfSubject s;
    s.label = item.cast<py::tuple>()[0].cast<std::string>();
    s.image = ImageFromArray(item.cast<py::tuple>()[1], "images[" + std::to_string(i) + "]");
    return s;
  }
  throw InvalidArgument("aosr.compare_mtf", "images[" + std::to_string(i) + "]", py::str(py::type::of(item)).cast<std::string>(),
                        "an aosr.Reconstruction, a FITS path, or a (label, 2-D array) tuple");
}

py::array_t<double> MtfArray(const std::vector<double>& v) { return py::array_t<double>(py::ssize_t(v.size()), v.data()); }

}  // namespace

py::dict ReconstructOptionsHelp() { return ReconstructTable().Describe(CliDefaults()); }

// A memory limit argument: None (the process's), bytes, or '512M' / '8G'.
MemoryLimit MemoryLimitArgument(const py::object& memory_limit, const char* fn) {
  if (memory_limit.is_none()) return CurrentMemoryLimit();
  if (py::isinstance<py::str>(memory_limit))
    return {ParseByteSize(memory_limit.cast<std::string>(), std::string(fn) + ": memory_limit"), "memory_limit"};
  const double bytes = memory_limit.cast<double>();
  if (!(bytes > 0) || !std::isfinite(bytes))
    throw InvalidArgument(fn, "memory_limit", ToString(bytes), "bytes > 0, or '512M', '8G'");
  return {bytes, "memory_limit"};
}

void BindSolvers(py::module_& m) {
  py::class_<PyReconstruction, std::shared_ptr<PyReconstruction>>(
      m, "Reconstruction",
      "The result of aosr.reconstruct: the HR image (e- per HR pixel per frame), the method's second map, the\n"
      "solver summary. image and aux are views of memory this object owns (no copy).")
      .def_property_readonly(
          "image", [](py::object self) { return ViewImage(self.cast<PyReconstruction&>().rec.image, self, true); },
          "HR estimate, (r*rows, r*cols) float64, always finite")
      .def_property_readonly(
          "aux",
          [](py::object self) -> py::object {
            const PyReconstruction& r = self.cast<PyReconstruction&>();
            if (r.rec.aux.size() == 0) return py::none();
            return ViewImage(r.rec.aux, self, true);
          },
          "the method's second map (drizzle: weight; tikhonov with std=True: posterior std; linear: noise std), or None")
      .def_property_readonly("aux_name", [](const PyReconstruction& r) { return r.rec.aux_name; },
                             "'weight' | 'posterior-std' | 'noise-std' | ''")
      .def_property_readonly("summary", [](const PyReconstruction& r) { return SummaryDict(r.rec.summary); },
                             "{'method', 'termination', 'message', 'iterations', 'final_cost', 'seconds', "
                             "'frame_residual_rms'}")
      .def_property_readonly("regularisation", [](const PyReconstruction& r) { return r.rec.regularisation; },
                             "lambda (tikhonov, map) or mu (tv) used; 0 for the baselines")
      .def_property_readonly("seconds_total", [](const PyReconstruction& r) { return r.rec.seconds_total; },
                             "wall time including warm start and automatic regularisation")
      .def_property_readonly(
          "effective_psf",
          [](py::object self) -> py::object {
            const Image& p = self.cast<PyReconstruction&>().rec.effective_psf;
            return p.size() ? py::object(ViewImage(p, self, true)) : py::none();
          },
          "linear: the output's effective PSF (centred, unit sum), else None")
      .def_property_readonly(
          "noise_correlation",
          [](py::object self) -> py::object {
            const Image& p = self.cast<PyReconstruction&>().rec.noise_correlation;
            return p.size() ? py::object(ViewImage(p, self, true)) : py::none();
          },
          "linear: the noise covariance kernel xi(delta), else None")
      .def_property_readonly(
          "leakage_spectrum",
          [](py::object self) -> py::object {
            const Image& p = self.cast<PyReconstruction&>().rec.leakage_spectrum;
            return p.size() ? py::object(ViewImage(p, self, true)) : py::none();
          },
          "linear: leakage per HR frequency (zero frequency at (M/2, M/2)), else None")
      .def_property_readonly(
          "linear",
          [](const PyReconstruction& r) -> py::object {
            if (!r.rec.linear) return py::none();
            const TargetPsfSummary& l = *r.rec.linear;
            py::dict d = SummaryDict(l);
            d["target"] = l.target;
            d["target_fwhm_hr_px"] = l.target_fwhm_hr_px;
            d["effective_fwhm_hr_px"] = l.effective_fwhm_hr_px;
            d["effective_psf_window_fraction"] = l.effective_psf_window_fraction;
            d["kappa"] = l.kappa;
            d["leakage"] = l.leakage;
            d["leakage_unreachable"] = l.leakage_unreachable;
            d["leakage_met"] = l.leakage_met;
            d["leakage_max_in_band"] = l.leakage_max_in_band;
            d["band_cycles_per_hr_px"] = l.band_cycles_per_hr_px;
            d["unreachable_frequencies"] = l.unreachable_frequencies;
            d["dc_transfer"] = l.dc_transfer;
            d["noise_sigma"] = l.noise_sigma;
            d["noise_rms"] = l.noise_rms;
            d["noise_rms_error"] = l.noise_rms_error;
            d["noise_probes"] = l.noise_probes;
            d["fourier_exact"] = l.fourier_exact;
            return d;
          },
          "linear: the target-PSF summary (include/aosr/solvers/target_psf.hpp) as a dict, else None")
      .def_property_readonly("method", [](const PyReconstruction& r) { return r.method; })
      .def_property_readonly("weights_source", [](const PyReconstruction& r) { return r.weights_source; })
      .def_property_readonly("offsets_source", [](const PyReconstruction& r) { return r.offsets_source; })
      .def_property_readonly("model_psfs_replaced", [](const PyReconstruction& r) { return r.model_psfs_replaced; })
      .def_property_readonly("psf_field", [](const PyReconstruction& r) { return r.psf_field; },
                             "the field-varying model used: 'none' | 'tiles' | 'operator' (reconstruct's psf_field)")
      .def_property_readonly("masked_pixels", [](const PyReconstruction& r) { return r.masked_pixels; })
      .def_property_readonly(
          "memory_plan",
          [](const PyReconstruction& r) -> py::object {
            if (!r.by_tiles_for_memory) return py::none();
            py::dict d;
            d["whole_grid_bytes"] = r.whole_grid_bytes;
            d["memory_limit_bytes"] = r.memory_limit_bytes;
            d["tile"] = r.by_tiles_for_memory->tile;
            d["tile_overlap"] = r.by_tiles_for_memory->overlap;
            d["tile_overlap_max"] = r.by_tiles_for_memory->max_overlap;
            d["parallel_tiles"] = r.by_tiles_for_memory->parallel_tiles;
            d["regularisation_window"] = r.by_tiles_for_memory->regularisation_window;
            return std::move(d);
          },
          "None when the whole grid was reconstructed at once; else the whole grid did not fit memory_limit and the "
          "run went by tiles without a whole-grid model: dict(whole_grid_bytes, memory_limit_bytes, tile, "
          "tile_overlap (-1: measured once the regularisation is fixed, up to tile_overlap_max), tile_overlap_max, "
          "parallel_tiles, regularisation_window)")
      .def_property_readonly(
          "registration",
          [](const PyReconstruction& r) -> py::object {
            // offsets='estimate': per frame commanded and estimated offsets and the standard error, camera px.
            if (!r.registration) return py::none();
            const RegistrationResult& g = *r.registration;
            py::list frames;
            for (std::size_t i = 0; i < g.estimated.size(); ++i) {
              py::dict f;
              f["commanded_camera_px"] = py::make_tuple(g.commanded[i].dy / r.r, g.commanded[i].dx / r.r);
              f["estimated_camera_px"] = py::make_tuple(g.estimated[i].dy / r.r, g.estimated[i].dx / r.r);
              f["sigma_camera_px"] = g.sigma_hr_px[i] / r.r;
              frames.append(f);
            }
            py::dict d;
            d["frames"] = frames;
            d["rounds"] = g.rounds;
            d["converged"] = g.converged;
            d["seconds"] = g.seconds;
            return d;
          },
          "offsets='estimate': {'frames': [{'commanded_camera_px': (dy, dx), 'estimated_camera_px': (dy, dx), "
          "'sigma_camera_px': s}, ...], 'rounds', 'converged', 'seconds'}; else None")
      .def_property_readonly(
          "stars_psf",
          [](const PyReconstruction& r) -> py::object {
            if (!r.stars_psf) return py::none();
            return StarsPsfDict(*r.stars_psf);
          },
          "model_psfs='stars': the estimate as aosr.stars_psf returns it (psf, psfs, stars, stars_used, chi2_per_dof, "
          "...); else None")
      .def("__repr__", [](const PyReconstruction& r) {
        return "<aosr.Reconstruction " + r.method + " " + ToString(ShapeOf(r.rec.image)) + ": " +
               ToString(r.rec.summary.termination) + ", " + std::to_string(r.rec.summary.iterations) + " iterations, " +
               ToString(r.rec.seconds_total) + " s>";
      });

  m.def(
      "reconstruct",
      [](py::object dataset, const std::string& method, const std::string& weights, const std::string& offsets,
         py::object model_psfs, py::object progress, double registration_range, const std::string& registration_anchor,
         py::object stars, int tile, int tile_overlap, double tile_tolerance, const std::string& resume,
         const std::string& psf_field, py::object memory_limit, py::kwargs kwargs) {
        // Everything is parsed and checked before any work (as the CLI does).
        TilingOptions tiling;
        tiling.tile = tile;
        tiling.overlap = tile_overlap;
        tiling.tolerance = tile_tolerance;
        if (!(tile_tolerance > 0 && tile_tolerance < 1))
          throw InvalidArgument("aosr.reconstruct", "tile_tolerance", ToString(tile_tolerance), "in (0, 1)");
        if (tile == 0 && tile_overlap >= 0)
          throw InvalidArgument("aosr.reconstruct", "tile_overlap", std::to_string(tile_overlap), "only with tile > 0");
        if (tile != 0) {
          std::string why;
          if (!tiling.IsValid(&why)) throw InvalidArgument("aosr.reconstruct", "tile / tile_overlap", why, "valid tiling");
        }
        if (!resume.empty()) {
          if (tile <= 0) throw InvalidArgument("aosr.reconstruct", "resume", resume, "only with tile > 0");
          tiling.checkpoint_dir = resume;  // must exist; the fingerprint covers the data, model and main options
          tiling.checkpoint_key = py::str(kwargs).cast<std::string>();
        }
        ReconstructOptions o;
        DatasetProblemOptions dpo;
        DatasetRunOptions(method, kwargs, weights, offsets, &o, &dpo);
        dpo.registration.search_range_camera_px = registration_range;
        dpo.registration.anchor = ParseRegistrationAnchor(registration_anchor);
        std::string why;
        if (!dpo.registration.IsValid(&why))
          throw InvalidArgument("aosr.reconstruct", "registration_range", why, "(0, 4] camera px");
        dpo.stars = StarsOptionsFrom(stars, "aosr.reconstruct");
        dpo.psf_field = ParseDatasetPsfField(psf_field);
        if (py::isinstance<py::str>(model_psfs) && model_psfs.cast<std::string>() == "nominal")
          dpo.nominal_psfs = true;
        else if (py::isinstance<py::str>(model_psfs) && model_psfs.cast<std::string>() == "stars")
          dpo.stars_psfs = true;
        else if (py::isinstance<py::str>(model_psfs))
          throw InvalidArgument("aosr.reconstruct", "model_psfs", model_psfs.cast<std::string>(),
                                "'nominal' | 'stars' | an (N, K, K) array");
        else if (!model_psfs.is_none())
          dpo.model_psfs = StackFromArray(model_psfs, "model_psfs");
        const MemoryLimit limit = MemoryLimitArgument(memory_limit, "aosr.reconstruct");
        // A dataset path as `aosr reconstruct` opens it: a whole detector's frames are read by sections (each tile's
        // window), not held, unless the whole grid fits or the run needs the whole frames (stars PSFs, estimated
        // offsets).
        std::shared_ptr<const Dataset> d;
        if (py::isinstance<py::str>(dataset) || py::hasattr(dataset, "__fspath__")) {
          const std::string path = PathString(dataset);
          auto lazy = std::make_shared<const Dataset>(WithoutGil([&] { return LoadDataset(path, DatasetPixels::kSections); }));
          if (!WholeGridFits(*lazy, o.method, limit.bytes) && !dpo.stars_psfs && dpo.offsets != DatasetOffsets::kEstimate)
            d = std::move(lazy);
        }
        if (!d) d = DatasetArgument(dataset, "aosr.reconstruct");
        PythonProgress poll(progress);
        o.progress = poll.Callback();
        auto out = std::make_shared<PyReconstruction>();
        out->method = ToString(o.method);
        std::string warning;
        WithoutGil([&] {
          if (o.linear.kind == TargetPsfKind::kImage && o.linear.image.size() == 0) {  // target_psf='diffraction'
            if (o.method == ReconstructionMethod::kLinear) o.linear.image = DiffractionTargetPsf(*d);
            else o.linear.kind = TargetPsfKind::kAuto;  // only the linear method reads it
          }
          // A whole detector (solvers/tiling.hpp): when the whole-grid model and solve would pass the limit, the
          // run goes by tiles without a whole-grid model, chosen to fit, as `aosr reconstruct` does.
          if (!WholeGridFits(*d, o.method, limit.bytes, &out->whole_grid_bytes)) dpo.whole_grid_model = false;
          const DatasetProblem dp = ProblemFromDataset(*d, dpo);
          warning = dp.warning;
          if (!dpo.whole_grid_model) {  // (a field model by tiles has dp.field too, and fits)
            FitDatasetTilingToMemory(dp, o, limit.bytes, &tiling);
            out->by_tiles_for_memory = tiling;
            out->memory_limit_bytes = limit.bytes;
          }
          out->rec = ReconstructDataset(dp, o, tiling);
          if (dp.psf_field) out->psf_field = ToString(dp.psf_field->approach);
          out->weights_source = dp.weights_source;
          out->offsets_source = dp.offsets_source;
          out->model_psfs_replaced = dp.model_psfs_replaced;
          out->masked_pixels = dp.masked_pixels;
          out->registration = dp.registration;
          out->stars_psf = dp.stars_psf;
          out->r = d->r;
        });
        poll.RaiseIfPending();  // Ctrl-C (KeyboardInterrupt) or the progress callable's exception
        if (!warning.empty() && PyErr_WarnEx(PyExc_UserWarning, ("aosr.reconstruct: " + warning).c_str(), 1) != 0)
          throw py::error_already_set();
        return out;
      },
      py::arg("dataset"), py::arg("method") = "tikhonov", py::kw_only(), py::arg("weights") = "auto",
      py::arg("offsets") = "auto", py::arg("model_psfs") = py::none(), py::arg("progress") = py::none(),
      py::arg("registration_range") = 0.5, py::arg("registration_anchor") = "mean", py::arg("stars") = py::none(),
      py::arg("tile") = 0, py::arg("tile_overlap") = -1, py::arg("tile_tolerance") = 1e-6, py::arg("resume") = "",
      py::arg("psf_field") = "auto", py::arg("memory_limit") = py::none(),
      R"doc(Super-resolves a dataset with one method: the library's Reconstruct (include/aosr/solvers/reconstruct.hpp),
the call `aosr reconstruct DATASET -m METHOD` makes, with the same defaults and the same bits.

dataset     an aosr.Dataset (simulate, open_dataset, Dataset.from_arrays) or a dataset folder / manifest path
method      'shift-add' | 'shift-add-median' | 'drizzle' | 'tikhonov' (lambda by GCV) | 'linear' (target PSF)
            | 'tv' | 'map'
weights     'auto' ('background' for the linear methods shift-add, drizzle, tikhonov and linear; for tv and map the
            dataset's inverse variances when it has them, else 'mask') | 'background' (sky + read-noise inverse variances, one per
            frame, source-independent: from the detector model or estimated from the frames) | 'dataset' = 'poisson'
            (the dataset's inverse variances, source photon noise included; a UserWarning with a photometric
            method: they bias bright sources low) | 'mask'
offsets     'auto' | 'dm' | 'centroids': registration offsets for shift-add/drizzle; 'estimate': each frame's
            offset measured from the frames against a reconstruction (solvers/registration.hpp), the model PSFs
            shifted by it, for every method; Reconstruction.registration then lists commanded and estimated
            offsets per frame (camera px)
registration_range   offsets='estimate': largest correction to a commanded offset [camera px]; beyond is an error
registration_anchor  offsets='estimate': 'mean' (keep the commanded mean) | 'frame0' (frame 0 keeps its own)
model_psfs  PSFs the reconstructor uses instead of the dataset's: an (N, K, K) array, 'nominal', or 'stars'
            (estimated from the point sources in the frames, aosr.stars_psf; Reconstruction.stars_psf reports it)
stars       model_psfs='stars': a dict of aosr.stars_psf's options (psf_size_hr_px, detection_sigma, ...)
tile        > 0: reconstruct in overlapping tiles of at most tile x tile camera px, blended with no seam, one
            regularisation for the field chosen on the whole field (solvers/tiling.hpp; `aosr reconstruct --tile`);
            0: the whole grid at once. progress is not called for a tiled run
tile_overlap  tile > 0: camera px added on each side of a tile; -1: automatic (tikhonov and linear: measured
            from the method's response to hold the tiled error below tile_tolerance; others: from the PSF's extent
            and the method's reach; solvers/tiling.hpp "The overlap rule"); Reconstruction.tiling['overlap_rule']
            says how it was made
tile_tolerance  the automatic overlap's bound on the tiled error of tikhonov and linear, a fraction of the level
            (default 1e-6)
resume      tile > 0: an existing folder where finished tiles are kept; a rerun reuses them (same bytes)
psf_field   'auto' (a dataset with a psf_field, or stars={'grid': (ny, nx)} with model_psfs='stars', with a
            method that models the PSF: 'tiles') | 'none' (the guide
            star's PSF everywhere) | 'tiles' (overlapping tiles, each with the PSFs interpolated at its centre;
            tile sets their size, default half the grid spacing) | 'operator' (one space-variant operator over
            the whole field: exact for the interpolated PSF, slower; not for 'linear';
            include/aosr/solvers/psf_field_model.hpp). Reconstruction.psf_field says which was used
memory_limit  None (the process's limit: AOSR_MEMORY_LIMIT, else the machine) | bytes | '512M', '8G': when the
            whole-grid model and solve need more, the run goes by tiles without a whole-grid model, the tiles
            (unless tile is given) and the regularisation's window chosen to fit, as `aosr reconstruct` does for a
            whole detector; Reconstruction.memory_plan then says so. A dataset given by path then has each tile's
            window of the frames read by sections (never held whole)
progress    optional callable(dict) called during tikhonov, tv and map (stage, iteration, total, value,
            value_name, elapsed_seconds); returning False cancels (termination 'cancelled')
**options   the CLI's options under their names (lambda_, lambda_rule, prior, boundary, std, noise_sigma, mu,
            iterations, positivity, likelihood, read_noise, kernel, pixfrac, target_psf, leakage, noise_probes,
            auto_regularisation) and every field
            of the methods' options structs as <method>_<field> (tikhonov_gcv_decades=6, tv_relative_tolerance=1e-6,
            map_lbfgs_memory=10, ...) or as a dict per method (tv={'max_iterations': 50}).
            aosr.reconstruct_options() lists them all with their defaults.

Returns an aosr.Reconstruction (image, aux, aux_name, summary dict, regularisation, seconds_total).
The GIL is released during the solve; Ctrl-C stops tv/map (and tikhonov's CG path) after the current
iteration and raises KeyboardInterrupt. Errors: InvalidArgument (a ValueError) naming the option, IoError for unreadable files.)doc");

  m.def(
      "stars_psf",
      [](py::object dataset, py::kwargs kwargs) {
        const StarsPsfOptions o = StarsOptionsFrom(kwargs, "aosr.stars_psf");
        const std::shared_ptr<const Dataset> d = DatasetArgument(dataset, "aosr.stars_psf");
        StarsPsfResult r;
        WithoutGil([&] { r = EstimateStarsPsf(*d, o); });
        return StarsPsfDict(r);
      },
      py::arg("dataset"),
      R"doc(Model PSFs from the point sources in a dataset's frames: the library's EstimateStarsPsf
(include/aosr/solvers/stars_psf.hpp), what `aosr reconstruct --model-psfs stars` uses. One HR PSF (K x K, unit
sum, core centroid at (K/2, K/2)) shifted by each frame's DM tip/tilt offset; stars detected, fitted with their
neighbours subtracted, the PSF solved by weighted least squares over all their pixels.

dataset   an aosr.Dataset or a dataset folder / manifest path
options   psf_size_hr_px (0: 32 r), detection_sigma (5), min_stars (4), rounds (4), regularisation (1e-4),
          fit_radius_px (3), cg_iterations (300), cg_tolerance (1e-5), max_stars (5000), background_mesh_px (0),
          max_chi2_near_stars (5), reject_extended (False), grid ((1, 1): one PSF; (ny, nx): a PSF fitted at
          each node of a grid over the field, bilinear between them, each star seen through the PSF at its
          position; every node needs its own stars), grid_variation (0.3 of the peak: how far the nodes depart
          from their mean), grid_degree (2: the nodes follow a polynomial surface of degree d in [1, 4] in
          position, PSFEx's model, and depart from it by grid_roughness, 0.005 of the peak; 0: each node is tied
          to the nodes' mean instead)

Returns {'psf': (K, K), 'psfs': (N, K', K') per frame, 'offsets_hr_px', 'stars': (S, 3) y, x [HR px], flux [e-],
'background_e', 'stars_used', 'detected', 'saturated', 'dropped', 'rejected', 'min_required', 'chi2_per_dof',
'chi2_near_stars', 'dof', 'rounds', 'seconds', 'report', 'grid'}; with a grid also 'grid_nodes_hr_px' (y, x per
node), 'node_psfs' (G, K, K), 'field_psfs' (G arrays (N, K', K')), 'node_stars' (the stars' weights per node),
'grid_degree' and 'grid_roughness' (the nodes' prior),
and 'psf'/'psfs' are the field centre's. InvalidArgument (ValueError) when the frames cannot support an estimate (no
detection, too few or only saturated stars, offsets that change the PSF's shape), naming what is missing.)doc");

  m.def("reconstruct_options", &ReconstructOptionsHelp,
        "{option: {'type', 'default', 'doc'}} for every keyword option of aosr.reconstruct (defaults as the CLI's).");
  m.def(
      "methods",
      [] {
        std::vector<std::string> names;
        for (ReconstructionMethod mth : ReconstructionMethods()) names.push_back(ToString(mth));
        return names;
      },
      "The reconstruction methods aosr.reconstruct accepts: the library's list (solvers/reconstruct.hpp,\n"
      "ReconstructionMethods), the one ParseReconstructionMethod checks names against.");

  m.def(
      "tradeoff",
      [](py::object dataset, py::object methods, std::vector<int> iterations, std::vector<double> lambda_factors,
         std::vector<double> target_factors, const std::string& weights, py::object progress) {
        TradeoffOptions o;
        if (!methods.is_none()) o.methods = methods.cast<std::vector<std::string>>();
        o.iterations = std::move(iterations);
        o.lambda_factors = std::move(lambda_factors);
        o.target_factors = std::move(target_factors);
        o.weights = ParseDatasetWeights(weights);
        CheckTradeoffOptions(o, [](const char* f) { return std::string(f); }, "aosr.tradeoff");
        const std::shared_ptr<const Dataset> d = DatasetArgument(dataset, "aosr.tradeoff");
        PythonProgress poll(progress);
        const TradeoffSweep sweep = WithoutGil([&] { return RunTradeoffSweep(*d, o, {}, poll.Callback()); });
        poll.RaiseIfPending();
        nlohmann::json j = {{"methods", sweep.methods},
                            {"weights", sweep.weights_source},
                            {"weights_linear_methods", sweep.weights_source_linear},
                            {"has_truth", sweep.has_truth},
                            {"metric_crop_px", sweep.has_truth ? nlohmann::json(sweep.metric_crop_px) : nlohmann::json()},
                            {"cancelled", sweep.cancelled},
                            {"rows", nlohmann::json::array()}};
        for (const TradeoffRow& r : sweep.rows) j["rows"].push_back(TradeoffRowJson(r));
        return FromJson(j);
      },
      py::arg("dataset"), py::kw_only(), py::arg("methods") = py::none(),
      py::arg("iterations") = std::vector<int>{10, 30, 100, 300},
      py::arg("lambda_factors") = std::vector<double>{0.01, 0.1, 10, 100},
      py::arg("target_factors") = std::vector<double>{0.9, 1.25, 1.5, 2.0}, py::arg("weights") = "auto",
      py::arg("progress") = py::none(),
      R"doc(The accuracy/time trade-off of every reconstructor on a dataset, as `aosr tradeoff DATASET --json` gives
its rows (include/aosr/solvers/tradeoff.hpp: each method with the defaults of aosr.reconstruct over its knob:
tikhonov lambda = factor x GCV's, linear Gaussian targets of factor x the automatic FWHM, tv and map iteration
caps). dataset: a path or aosr.Dataset; methods: a list (None: all); weights as aosr.reconstruct. Returns
{"methods", "weights", "weights_linear_methods", "has_truth", "metric_crop_px", "cancelled", "rows": [{"method",
"knob", "seconds", "psnr_db", "ssim", "misfit", "change", ...}]} (PSNR/SSIM None without a truth). progress: an
optional callable(dict) per solver report; returning False stops the sweep after that run ("cancelled").
The GIL is released; Ctrl-C stops it and raises KeyboardInterrupt.)doc");
  m.def(
      "compare_mtf",
      [](py::sequence images, py::object dataset, py::object roi, int r, const std::string& weights, py::object model_psfs,
         const std::string& prior, bool exact, bool smooth_tails, double curve_max, double curve_step,
         double min_contrast_to_noise, const std::string& plot, const std::string& table) {
        MtfComparisonOptions co;
        if (!roi.is_none()) {
          const std::vector<long long> v = roi.cast<std::vector<long long>>();
          if (v.size() != 4 || v[2] <= 0 || v[3] <= 0)
            throw InvalidArgument("aosr.compare_mtf", "roi", py::str(roi).cast<std::string>(),
                                  "(x0, y0, width, height) with width, height >= 1");
          co.edge.roi = {Index(v[0]), Index(v[1]), Index(v[2]), Index(v[3])};
        }
        co.edge.r = r;
        co.edge.smooth_tails = smooth_tails;
        co.edge.curve_max = curve_max;
        co.edge.curve_step = curve_step;
        co.edge.min_contrast_to_noise = min_contrast_to_noise;
        std::string why;
        if (!co.edge.IsValid(&why)) throw InvalidArgument("aosr.compare_mtf: " + why);
        co.exact = exact;
        co.tikhonov.prior = ParseTikhonovPrior(prior);
        if (co.tikhonov.prior == TikhonovPrior::kFitted)
          throw InvalidArgument("aosr.compare_mtf", "prior", prior, "identity | gradient | laplacian | power-spectrum");
        DatasetProblemOptions dpo;
        dpo.method = ReconstructionMethod::kTikhonov;
        dpo.weights = ParseDatasetWeights(weights);
        if (py::isinstance<py::str>(model_psfs) && model_psfs.cast<std::string>() == "nominal")
          dpo.nominal_psfs = true;
        else if (py::isinstance<py::str>(model_psfs))
          throw InvalidArgument("aosr.compare_mtf", "model_psfs", model_psfs.cast<std::string>(), "'nominal' | an (N, K, K) array");
        else if (!model_psfs.is_none())
          dpo.model_psfs = StackFromArray(model_psfs, "model_psfs");
        std::vector<MtfSubject> subjects;
        for (std::size_t i = 0; i < py::len(images); ++i) subjects.push_back(MtfSubjectFrom(images[i], i));
        std::shared_ptr<const Dataset> d;
        if (!dataset.is_none()) d = DatasetArgument(dataset, "aosr.compare_mtf");
        MtfComparison c;
        WithoutGil([&] {
          if (roi.is_none()) co.edge.roi = FindMtfRegion(subjects, co.edge);  // as aosr mtf without --roi
          if (d) co.problem = std::make_shared<const ReconstructionProblem>(ProblemFromDataset(*d, dpo).problem);
          c = CompareMtf(subjects, co);
          if (!plot.empty()) WriteFigure(plot, {MtfComparisonPlot(c)});
          if (!table.empty()) {
            const std::string csv = MtfComparisonCsv(c);
            AtomicWrite(table, [&csv](const std::string& tmp) {
              std::ofstream f(tmp);
              f << csv;
              if (!f) throw IoError(tmp, "could not write the table");
            });
          }
        });
        py::list out;
        for (const MtfComparisonEntry& e : c.entries) {
          py::dict d2;
          d2["label"] = e.label;
          d2["method"] = e.method;
          d2["measured"] = e.measured;
          d2["refusal"] = e.refusal;
          if (e.measured) {
            d2["frequency"] = MtfArray(e.edge.frequency);
            d2["mtf"] = MtfArray(e.edge.mtf);
            d2["mtf50"] = e.edge.mtf50.reached ? py::object(py::float_(e.edge.mtf50.frequency)) : py::object(py::none());
            d2["nyquist"] = e.edge.has_nyquist ? py::object(py::dict(py::arg("frequency") = e.edge.nyquist.frequency,
                                                                      py::arg("mtf") = e.edge.nyquist.mtf))
                                               : py::object(py::none());
            d2["edge_angle_deg"] = e.edge.angle_deg;
            d2["contrast_to_noise"] = e.edge.contrast_to_noise;
          }
          d2["exact_status"] = e.exact_status;
          if (e.exact) {
            py::dict x;
            x["frequency"] = MtfArray(e.exact->frequency);
            x["mtf"] = MtfArray(e.exact->mtf);
            x["alias"] = MtfArray(e.exact->alias);
            x["direction"] = py::make_tuple(e.exact->direction_y, e.exact->direction_x);
            d2["exact"] = x;
          } else {
            d2["exact"] = py::none();
          }
          out.append(d2);
        }
        return out;
      },
      py::arg("images"), py::arg("dataset") = py::none(), py::kw_only(), py::arg("roi") = py::none(), py::arg("r") = 0,
      py::arg("weights") = "auto", py::arg("model_psfs") = py::none(), py::arg("prior") = "gradient",
      py::arg("exact") = true, py::arg("smooth_tails") = true, py::arg("curve_max") = 0.5, py::arg("curve_step") = 0.01,
      py::arg("min_contrast_to_noise") = 10.0, py::arg("plot") = "", py::arg("table") = "",
      R"doc(The slanted-edge MTF of several outputs read in one region, beside the exact transfer of the linear methods
(include/aosr/solvers/mtf_comparison.hpp; `aosr mtf A.fits B.fits ... --manifest DIR`).

images    a list of aosr.Reconstruction (method, lambda and effective PSF known), FITS paths aosr wrote (METHOD,
          REGUL, the PSF extension), or (label, 2-D array) tuples (measured only)
dataset   the dataset they were reconstructed from (aosr.Dataset or a path): gives tikhonov outputs their exact
          curve, with the weights / model_psfs the reconstruction used ('auto', 'nominal', an (N, K, K) array) and
          its prior; linear outputs carry theirs (the effective PSF)
roi, r, curve_max, curve_step, min_contrast_to_noise   the edge reading (aosr.mtf); smooth_tails=False for
          noise-free or ringing edges (reconstructions): the smoothing removes ringing tails
exact     False: measured curves only
plot, table   optional PNG and CSV paths (the CLI's -o and --table)

Returns one dict per image: label, method, measured, refusal (why its edge was refused, else ''), frequency, mtf,
mtf50, nyquist, edge_angle_deg, contrast_to_noise (when measured), exact_status ('exact' | 'approximate: ...' |
'signal-dependent' (tv, map) | 'measured only' | 'unavailable: ...' | 'off') and exact ({frequency, mtf, alias,
direction} or None). Raises aosr.InvalidArgument when no image has a usable edge.)doc");

  m.def(
      "bicubic",
      [](py::handle frame, int r) {
        const Image f = ImageFromArray(frame, "frame");
        if (r < 1 || r > 64) throw InvalidArgument("aosr.bicubic", "r", std::to_string(r), "1 .. 64");
        return MoveImage(WithoutGil([&] { return BicubicUpsample(f, r); }));
      },
      py::arg("frame"), py::arg("r"),
      "One camera frame upsampled r times by bicubic interpolation, in flux per HR pixel: the single-frame baseline of\n"
      "`aosr demo` (include/aosr/solvers/shift_and_add.hpp BicubicUpsample).");
}

}  // namespace aosr::python
