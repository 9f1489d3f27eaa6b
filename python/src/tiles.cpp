// Bindings of a whole detector's tiles as separate jobs (aosr.distributed.reconstruct_tiles,
// python/aosr/distributed.py): the plan, the tiles solved by the workers into a checkpoint folder, and the blend;
// what a plan carries between processes (the fixed regularisation, the weights' rule); and the dataset a worker
// keeps between its tiles.
#include <algorithm>
#include <filesystem>
#include <mutex>

#include "aosr/core/error.hpp"
#include "aosr/io/fits.hpp"
#include "aosr/solvers/dataset_problem.hpp"
#include "aosr/solvers/psf_field_model.hpp"
#include "aosr/solvers/reconstruction_header.hpp"
#include "aosr/solvers/target_psf.hpp"
#include "aosr/solvers/tiling.hpp"
#include "bindings.hpp"
#include "common.hpp"

namespace aosr::python {
namespace {

// The values FixRegularisation fixes (solvers/tiling.cpp), as a plan's dict for aosr.distributed.reconstruct_tiles:
// a worker applies them instead of choosing again, so every tile is solved with the client's options exactly.
py::dict RegularisationDict(const ReconstructOptions& o) {
  using namespace pybind11::literals;
  const TikhonovOptions& t = o.tikhonov;
  py::dict d("tikhonov"_a = py::dict("lambda_rule"_a = int(t.lambda_rule), "lambda"_a = t.lambda,
                                     "prior"_a = int(t.prior), "spectrum_slope"_a = t.spectrum_slope,
                                     "spectrum_corner"_a = t.spectrum_corner),
             "linear"_a = py::dict("kappa"_a = o.linear.kappa, "e_max"_a = o.linear.e_max, "kind"_a = int(o.linear.kind),
                                   "fwhm_hr_px"_a = o.linear.fwhm_hr_px));
  if (o.fixed_automatic)
    d["automatic"] = py::dict("pilot_lambda"_a = o.fixed_automatic->pilot_lambda, "mu"_a = o.fixed_automatic->mu,
                              "contrast"_a = o.fixed_automatic->contrast);
  return d;
}

void ApplyRegularisationDict(const py::dict& d, ReconstructOptions* o) {
  const py::dict t = d["tikhonov"].cast<py::dict>(), l = d["linear"].cast<py::dict>();
  o->tikhonov.lambda_rule = static_cast<TikhonovLambdaRule>(t["lambda_rule"].cast<int>());
  o->tikhonov.lambda = t["lambda"].cast<double>();
  o->tikhonov.prior = static_cast<TikhonovPrior>(t["prior"].cast<int>());
  o->tikhonov.spectrum_slope = t["spectrum_slope"].cast<double>();
  o->tikhonov.spectrum_corner = t["spectrum_corner"].cast<double>();
  o->linear.kappa = l["kappa"].cast<double>();
  o->linear.e_max = l["e_max"].cast<double>();
  o->linear.kind = static_cast<TargetPsfKind>(l["kind"].cast<int>());
  o->linear.fwhm_hr_px = l["fwhm_hr_px"].cast<double>();
  if (d.contains("automatic")) {
    const py::dict a = d["automatic"].cast<py::dict>();
    o->fixed_automatic = AutomaticRegularisation{a["pilot_lambda"].cast<double>(), a["mu"].cast<double>(),
                                                 a["contrast"].cast<double>()};
  }
}

// The weights rule of a plan (DatasetProblem::weights_rule) as a dict and back: the tasks that read sections of
// the frames apply the rule decided on the whole dataset. Doubles pass through Python floats exactly.
py::dict WeightsRuleDict(const WeightsRule& rule) {
  py::dict d;
  d["kind"] = int(rule.kind);
  d["variance_e2"] = rule.variance_e2;
  d["gain2"] = rule.gain2;
  d["any_invalid"] = rule.any_invalid;
  return d;
}

WeightsRule WeightsRuleFromDict(const py::dict& d) {
  WeightsRule rule;
  const int kind = d["kind"].cast<int>();
  if (kind < 0 || kind > int(WeightsRule::Kind::kDataset))
    throw InvalidArgument("aosr.distributed.reconstruct_tiles", "plan['weights_rule']['kind']", std::to_string(kind),
                          "0..3 (a plan's)");
  rule.kind = WeightsRule::Kind(kind);
  rule.variance_e2 = d["variance_e2"].cast<std::vector<double>>();
  rule.gain2 = d["gain2"].cast<double>();
  rule.any_invalid = d["any_invalid"].cast<bool>();
  return rule;
}

// What a Dask worker keeps between the tiles it solves of one dataset (aosr.distributed.reconstruct_tiles): the
// dataset and its FieldData, so that each further tile costs its solve, not a read of the frames and their
// kernels again. One dataset at a time, keyed by the path, the size and time of every file in its folder and the
// options that shape the problem; a changed file or other options make a new entry.
struct TileDataCache {
  std::mutex mutex;
  std::string key;
  std::shared_ptr<const Dataset> dataset;
  std::shared_ptr<const DatasetProblem> problem;
  std::shared_ptr<TileModelStore> models;
};

TileDataCache& WorkerTileData() {
  static TileDataCache cache;
  return cache;
}

std::string TileDataKey(const std::string& path, const std::string& options) {
  namespace fs = std::filesystem;
  const fs::path p = fs::absolute(path);
  const fs::path folder = fs::is_directory(p) ? p : p.parent_path();
  std::vector<std::string> files;
  for (const fs::directory_entry& e : fs::directory_iterator(folder)) {
    if (!e.is_regular_file()) continue;
    files.push_back(e.path().filename().string() + ":" + std::to_string(e.file_size()) + ":" +
                    std::to_string(e.last_write_time().time_since_epoch().count()));
  }
  std::sort(files.begin(), files.end());
  std::string key = p.string() + "|" + options;
  for (const std::string& f : files) key += "|" + f;
  return key;
}

}  // namespace

void BindTiles(py::module_& m) {
  // The tiles of one dataset as separate jobs, for aosr.distributed.reconstruct_tiles (python/aosr/distributed.py):
  // phase 'plan' (the client: tiles, overlap and the regularisation fixed once), 'solve' (a worker: the given
  // tiles into checkpoint_dir, from the plan) and 'blend' (the client: every tile resumed from checkpoint_dir).
  // Each phase opens the dataset itself (a path on shared storage) and builds its FieldData: no whole-grid model.
  m.def(
      "_tiles",
      [](py::object dataset, const std::string& method, const std::string& phase, py::dict plan,
         std::vector<int> tiles, const std::string& checkpoint_dir, int tile, int tile_overlap,
         py::object memory_limit, const std::string& weights, const std::string& offsets,
         py::dict options, bool keep, const std::string& output, const std::string& dtype,
         py::object await_tiles, const std::string& psf_field) -> py::object {
        const char* fn = "aosr.distributed.reconstruct_tiles";
        if (dtype != "float32" && dtype != "float64") throw InvalidArgument(fn, "dtype", dtype, "float32 | float64");
        if (!output.empty() && phase != "blend")
          throw InvalidArgument(fn, "output", output, "only with phase 'blend'");
        if (phase != "plan" && phase != "solve" && phase != "blend")
          throw InvalidArgument(fn, "phase", phase, "'plan' | 'solve' | 'blend'");
        if (!await_tiles.is_none() && (phase != "blend" || !PyCallable_Check(await_tiles.ptr())))
          throw InvalidArgument(fn, "await_tiles", py::str(py::repr(await_tiles)).cast<std::string>(),
                                "None, or a callable(first, last) with phase 'blend'");
        ReconstructOptions o;
        DatasetProblemOptions dpo;
        DatasetRunOptions(method, options, weights, offsets, &o, &dpo);
        dpo.whole_grid_model = false;
        // A field-varying PSF by tiles with local PSFs (psf_field_model.hpp), as aosr.reconstruct; the operator is
        // one solve over the whole field, not tiles.
        dpo.psf_field = ParseDatasetPsfField(psf_field);
        if (dpo.psf_field == DatasetPsfField::kOperator)
          throw InvalidArgument(fn, "psf_field", psf_field,
                                "auto | none | tiles (the operator is one solve over the whole field: aosr.reconstruct)");
        const MemoryLimit limit = MemoryLimitArgument(memory_limit, fn);
        TilingOptions tiling;
        // One tile per task, the task's threads inside it; the client's blend reads and checks the finished tiles
        // one per thread (then blends them in tile order: the same bytes).
        tiling.parallel_tiles = phase == "blend";
        tiling.checkpoint_key = "aosr.distributed.reconstruct_tiles " + method + " " + weights + " " + offsets;
        if (phase == "plan") {
          tiling.tile = tile;
          tiling.overlap = tile_overlap;
          if (tile != 0) {
            std::string why;
            if (!tiling.IsValid(&why)) throw InvalidArgument(fn, "tile / tile_overlap", why, "valid tiling");
          }
        } else {
          tiling.tile = plan["tile"].cast<int>();
          tiling.overlap = plan["tile_overlap"].cast<int>();
          tiling.regularisation_window = plan["regularisation_window"].cast<int>();
          ApplyRegularisationDict(plan["regularisation"].cast<py::dict>(), &o);
          tiling.checkpoint_dir = checkpoint_dir;
          // The blend beside the tasks: before taking tiles [first, last), wait (in Python) for their jobs.
          if (!await_tiles.is_none())
            tiling.await_tiles = [&await_tiles](int first, int last) {
              py::gil_scoped_acquire gil;
              await_tiles(first, last);
            };
          if (phase == "solve") {
            if (tiles.empty()) throw InvalidArgument(fn, "tiles", "[]", "at least one tile index");
            tiling.only_tiles = tiles;
          }
        }
        // keep (the tasks): the dataset and its FieldData stay in this process for the next tile.
        const bool by_path = py::isinstance<py::str>(dataset) || py::hasattr(dataset, "__fspath__");
        const std::string key =
            keep && by_path ? TileDataKey(PathString(dataset), method + " " + weights + " " + offsets + " " + psf_field)
                            : "";
        TileDataCache& cache = WorkerTileData();
        std::unique_lock<std::mutex> lock(cache.mutex, std::defer_lock);
        if (!key.empty()) lock.lock();
        std::shared_ptr<const Dataset> d;
        std::shared_ptr<const DatasetProblem> problem;
        if (!key.empty() && cache.key == key) {
          d = cache.dataset;
          problem = cache.problem;
        } else {
          if (!key.empty()) {  // free the previous dataset first
            cache.key.clear();
            cache.dataset.reset();
            cache.problem.reset();
            cache.models.reset();
          }
          if (by_path) {
            // Nothing holds the frames whole. The plan decides the weights' rule reading them in bands of rows (and
            // chooses the regularisation on its central window's section); a task reads only its tile's window of
            // the frames (shared storage) under the plan's rule, and the blend needs no pixel.
            if (phase != "plan" && plan.contains("weights_rule"))
              dpo.weights_rule = WeightsRuleFromDict(plan["weights_rule"].cast<py::dict>());
            const std::string path = PathString(dataset);
            d = std::make_shared<const Dataset>(WithoutGil([&] { return LoadDataset(path, DatasetPixels::kSections); }));
          } else {
            d = DatasetArgument(dataset, fn);
          }
        }
        auto out = std::make_shared<PyReconstruction>();
        TilingSummary ts;
        // The blend written by rows into `output` (the image is then not held), with the aux map beside it.
        std::unique_ptr<FitsRowWriter> image_writer, aux_writer;
        const FitsType fits_type = dtype == "float64" ? FitsType::kFloat64 : FitsType::kFloat32;
        const std::string aux_path = output.empty() ? "" : ReconstructionAuxPath(output, o.method);
        if (!output.empty()) {
          image_writer = std::make_unique<FitsRowWriter>(output, d->hr_frame, fits_type);
          tiling.rows = [&](Index y0, const Image& rows, const Image& aux_rows) {
            image_writer->WriteRows(y0, rows);
            if (aux_rows.size() == 0) return;
            if (!aux_writer) aux_writer = std::make_unique<FitsRowWriter>(aux_path, d->hr_frame, fits_type);
            aux_writer->WriteRows(y0, aux_rows);
          };
        }
        WithoutGil([&] {
          if (o.linear.kind == TargetPsfKind::kImage && o.linear.image.size() == 0) {  // target_psf='diffraction'
            if (o.method == ReconstructionMethod::kLinear) o.linear.image = DiffractionTargetPsf(*d);
            else o.linear.kind = TargetPsfKind::kAuto;
          }
          if (!problem) problem = std::make_shared<const DatasetProblem>(ProblemFromDataset(*d, dpo));
          if (!key.empty() && cache.key != key) {
            cache.key = key;
            cache.dataset = d;
            cache.problem = problem;
            cache.models = std::make_shared<TileModelStore>();
          }
          if (!key.empty() && phase == "solve") tiling.model_store = cache.models;
          const DatasetProblem& dp = *problem;
          if (phase == "plan") {
            // As aosr.reconstruct under a memory limit (a field model's own tiles where they are smaller).
            FitDatasetTilingToMemory(dp, o, limit.bytes, &tiling);
            tiling.plan_only = true;
          }
          out->rec = ReconstructDataset(dp, o, tiling, &ts);
          if (dp.psf_field) out->psf_field = ToString(dp.psf_field->approach);
          out->method = ToString(o.method);
          out->weights_source = dp.weights_source;
          out->offsets_source = dp.offsets_source;
          out->masked_pixels = dp.masked_pixels;
          out->r = d->r;
          if (image_writer) {
            FitsHeader h = ReconstructionHeader(*d, o.method, out->rec, problem.get(), &ts);
            const FitsHeader common = h;
            SetHrImageKeywords(*d, "electron", &h);
            image_writer->Finish(h);
            if (aux_writer) {
              FitsHeader a = common;
              a.Set("AOSRDATA", out->rec.aux_name, "content of this HDU");
              SetHrImageKeywords(*d, "electron", &a);
              aux_writer->Finish(a);
            }
          }
        });
        if (phase == "blend") return py::cast(out);
        py::dict result;
        if (phase == "plan") {
          result["tile"] = ts.tile;
          result["tile_overlap"] = ts.overlap;
          result["regularisation_window"] = tiling.regularisation_window;
          result["tiles"] = int(ts.tiles.size());
          result["tiles_y"] = ts.tiles_y;
          result["tiles_x"] = ts.tiles_x;
          result["regularisation"] = RegularisationDict(ts.options);
          result["regularisation_source"] = ts.regularisation_source;
          result["weights_rule"] = WeightsRuleDict(problem->weights_rule);
        } else {
          py::list terms;
          for (Termination t : ts.tile_terminations) terms.append(ToString(t));
          result["terminations"] = terms;
          result["resumed"] = ts.tiles_resumed;
          result["seconds"] = out->rec.seconds_total;
          result["message"] = out->rec.summary.message;
        }
        return std::move(result);
      },
      py::arg("dataset"), py::arg("method"), py::kw_only(), py::arg("phase"), py::arg("plan") = py::dict(),
      py::arg("tiles") = std::vector<int>{}, py::arg("checkpoint_dir") = "", py::arg("tile") = 0,
      py::arg("tile_overlap") = -1, py::arg("memory_limit") = py::none(), py::arg("weights") = "auto",
      py::arg("offsets") = "auto", py::arg("options") = py::dict(), py::arg("keep") = false,
      py::arg("output") = "", py::arg("dtype") = "float32", py::arg("await_tiles") = py::none(),
      py::arg("psf_field") = "auto",
      "Internal: the phases of aosr.distributed.reconstruct_tiles (plan, solve tiles, blend; await_tiles(first, "
      "last) is called before the blend takes those tiles).");
  m.def(
      "_tiles_forget",
      [] {
        TileDataCache& cache = WorkerTileData();
        const std::lock_guard<std::mutex> lock(cache.mutex);
        cache.key.clear();
        cache.dataset.reset();
        cache.problem.reset();
        cache.models.reset();
      },
      "Internal: frees the dataset aosr.distributed.reconstruct_tiles kept in this process.");

}

}  // namespace aosr::python
