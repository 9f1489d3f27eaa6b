#include "aosr/solvers/dataset_problem.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <functional>
#include <memory>
#include <mutex>

#include "aosr/core/error.hpp"
#include "aosr/core/memory.hpp"
#include "aosr/io/config.hpp"
#include "aosr/optics/psf.hpp"
#include "aosr/scene/telescope.hpp"

namespace aosr {
namespace {

constexpr const char* kDatasetProblemFn = "ProblemFromDataset";

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

double MedianOf(std::vector<double> v) {
  const std::size_t h = v.size() / 2;
  std::nth_element(v.begin(), v.begin() + h, v.end());
  const double upper = v[h];
  if (v.size() % 2) return upper;
  return 0.5 * (upper + *std::max_element(v.begin(), v.begin() + h));
}

// σ² (e⁻²) of the frames' background noise from the detector model a simulation's manifest records ("noise",
// dataset.cpp), or nothing when the manifest has none. -1: the model has no noise at all.
std::optional<double> DetectorModelVariance(const Dataset& d) {
  if (!d.manifest.is_object() || !d.manifest.contains("noise") || !d.manifest.at("noise").is_object()) return std::nullopt;
  const nlohmann::json& n = d.manifest.at("noise");
  auto number = [&n](const char* key) {
    return n.contains(key) && n.at(key).is_number() ? n.at(key).get<double>() : 0.0;
  };
  const std::string model = n.contains("model") && n.at("model").is_string() ? n.at("model").get<std::string>() : "";
  double var = 0;
  if (model == "peak-fraction") {
    var = number("sigma_e") * number("sigma_e");
  } else if (model == "physical") {
    const bool photon = n.contains("photon_noise") && n.at("photon_noise").is_boolean() && n.at("photon_noise").get<bool>();
    var = number("read_noise_e") * number("read_noise_e") +
          (photon ? (number("background_e_per_s") + number("dark_current_e_per_s")) * number("frame_time_s") : 0.0);
  } else if (model != "none") {
    return std::nullopt;  // an unknown model: estimate from the frames instead
  }
  if (n.contains("quantize") && n.at("quantize").is_boolean() && n.at("quantize").get<bool>())
    var += d.gain_e_per_adu * d.gain_e_per_adu / 12.0;
  if (!(var > 0) || !std::isfinite(var)) return -1.0;
  return var;
}

}  // namespace

double EstimateBackgroundSigma(const Image& y, const Image& valid, double* se_relative) {
  CheckArgument(ShapeOf(y) == ShapeOf(valid), "EstimateBackgroundSigma", "valid", ToString(ShapeOf(valid)),
                "the frame's shape " + ToString(ShapeOf(y)));
  std::vector<double> d;
  d.reserve(std::size_t(y.size()));
  for (Index r = 0; r < y.rows(); ++r)
    for (Index c = 0; c + 1 < y.cols(); ++c)
      if (valid(r, c) != 0 && valid(r, c + 1) != 0 && std::isfinite(y(r, c)) && std::isfinite(y(r, c + 1)))
        d.push_back(y(r, c + 1) - y(r, c));
  if (se_relative) *se_relative = 0;
  if (d.size() < 8) return 0.0;
  const double med = MedianOf(d);
  for (double& v : d) v = std::abs(v - med);
  const double sigma = 1.4826 * MedianOf(d) / std::sqrt(2.0);
  // Var(MAD σ̂) ≈ 1.36 σ²/n (efficiency 0.37 of the sample SD's σ²/2n): SE(σ̂²)/σ̂² ≈ 2·1.17/√n.
  if (se_relative) *se_relative = 2.33 / std::sqrt(double(d.size()));
  return sigma;
}

DatasetWeights AutoWeights(ReconstructionMethod method) {
  return IsLinearMethod(method) ? DatasetWeights::kBackground : DatasetWeights::kAuto;
}

bool IsLinearMethod(ReconstructionMethod m) {
  return m == ReconstructionMethod::kDrizzle || m == ReconstructionMethod::kLinear ||
         m == ReconstructionMethod::kShiftAddMean || m == ReconstructionMethod::kShiftAddMedian ||
         m == ReconstructionMethod::kTikhonov;
}

Image DiffractionTargetPsf(const Dataset& d) {
  constexpr const char* kDiffFn = "DiffractionTargetPsf";
  namespace fs = std::filesystem;
  // The scene: the manifest's instrument scene file, or the scene a simulation recorded.
  nlohmann::json tel;
  std::string source;
  const nlohmann::json& m = d.manifest;
  if (m.is_object() && m.contains("scene") && m.at("scene").is_string()) {
    const fs::path base = fs::path(d.manifest_path).parent_path();
    fs::path p = m.at("scene").get<std::string>();
    if (p.is_relative()) p = base / p;
    source = p.string();
    const nlohmann::json scene = ReadJsonFile(source);
    if (scene.contains("telescope")) tel = scene.at("telescope");
  } else if (m.is_object() && m.contains("simulation") && m.at("simulation").is_object() &&
             m.at("simulation").contains("scene") && m.at("simulation").at("scene").is_object()) {
    const nlohmann::json& sc = m.at("simulation").at("scene");
    source = sc.contains("source") && sc.at("source").is_string() ? sc.at("source").get<std::string>() : d.manifest_path;
    if (sc.contains("json") && sc.at("json").is_object() && sc.at("json").contains("telescope"))
      tel = sc.at("json").at("telescope");
  }
  if (tel.is_null())
    throw InvalidArgument(kDiffFn, "dataset", d.manifest_path,
                          "a manifest naming its scene (\"scene\") or a simulation's (its telescope gives the pupil)");
  TelescopePreset preset;
  if (tel.is_string()) {
    const std::string name = tel.get<std::string>();
    const bool is_path = name.find('/') != std::string::npos || fs::path(name).extension() == ".json";
    fs::path p = name;
    if (is_path && p.is_relative()) p = fs::path(source).parent_path() / p;
    preset = LoadTelescopePreset(is_path ? p.string() : name);
  } else {
    preset = ParseTelescopePreset(tel, source + " (telescope)");
  }
  PsfSampling sampling;
  sampling.wavelength_m = d.wavelength_m > 0 ? d.wavelength_m : preset.science_wavelength_m;
  sampling.pixel_scale_rad = (d.camera_pixel_rad > 0 ? d.camera_pixel_rad : preset.camera_pixel_rad) / d.r;
  const double diameter = preset.aperture.pupil.diameter_m;
  // The field must fit in the pupil grid's period (pupil_px λ/D) to show no aliased copies.
  const Index alias_free = Index(double(preset.pupil_px) / sampling.PixelScaleLambdaOverD(diameter));
  Index k = std::min<Index>({64, d.hr_frame.rows, d.hr_frame.cols, alias_free});
  k -= k % 2;
  CheckArgument(k >= 8, kDiffFn, "PSF side", k, ">= 8 HR px (HR grid, pupil sampling)");
  sampling.rows = sampling.cols = k;
  const PsfCalculator calc(preset.pupil_px, diameter, sampling);
  return NormaliseToUnitSum(calc.Compute(preset.PupilAmplitude(), Image::Zero(preset.pupil_px, preset.pupil_px)));
}

DatasetWeights ParseDatasetWeights(const std::string& name) {
  if (name == "auto") return DatasetWeights::kAuto;
  if (name == "dataset" || name == "poisson") return DatasetWeights::kDataset;
  if (name == "mask") return DatasetWeights::kMask;
  if (name == "background") return DatasetWeights::kBackground;
  throw InvalidArgument("ParseDatasetWeights", "weights", name, "auto | background | dataset | poisson | mask");
}

DatasetPsfField ParseDatasetPsfField(const std::string& name) {
  if (name == "auto") return DatasetPsfField::kAuto;
  if (name == "none") return DatasetPsfField::kNone;
  if (name == "tiles") return DatasetPsfField::kTiles;
  if (name == "operator") return DatasetPsfField::kOperator;
  throw InvalidArgument("ParseDatasetPsfField", "psf_field", name, "auto | none | tiles | operator");
}

const char* ToString(DatasetPsfField f) {
  switch (f) {
    case DatasetPsfField::kAuto: return "auto";
    case DatasetPsfField::kNone: return "none";
    case DatasetPsfField::kTiles: return "tiles";
    case DatasetPsfField::kOperator: return "operator";
  }
  return "?";
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

bool WeightsRule::Uniform() const {
  if (kind == Kind::kUniform) return true;
  if (kind != Kind::kBackground || any_invalid || variance_e2.empty()) return false;
  return std::all_of(variance_e2.begin(), variance_e2.end(), [&](double v) { return v == variance_e2.front(); });
}

ImageStack ApplyWeightsRule(const WeightsRule& rule, const ImageStack& valid, const std::optional<ImageStack>& weights_adu) {
  const std::size_t n = valid.size();
  ImageStack out;
  switch (rule.kind) {
    case WeightsRule::Kind::kUniform:
      break;
    case WeightsRule::Kind::kValid:
      out = valid;
      break;
    case WeightsRule::Kind::kBackground:
      CheckArgument(rule.variance_e2.size() == n, "ApplyWeightsRule", "rule.variance_e2", rule.variance_e2.size(),
                    "one per frame (" + std::to_string(n) + ")");
      for (std::size_t i = 0; i < n; ++i) out.push_back(valid[i] / rule.variance_e2[i]);
      break;
    case WeightsRule::Kind::kDataset:
      CheckArgument(weights_adu && weights_adu->size() == n, "ApplyWeightsRule", "weights_adu",
                    weights_adu ? std::to_string(weights_adu->size()) + " maps" : std::string("none"),
                    "the dataset's inverse variances, one per frame (" + std::to_string(n) + ")");
      for (std::size_t i = 0; i < n; ++i) out.push_back((*weights_adu)[i] * valid[i] / rule.gain2);
      break;
  }
  return out;
}

namespace {

// The weights' rule from what it depends on: the dataset's metadata, whether any pixel is invalid, and (background
// weights without a detector model) each frame's background variance and its relative standard error, given by
// `estimate` on demand. One rule for frames held whole and for frames read by sections.
DatasetFrameWeights ChooseWeightsRule(const Dataset& d, const DatasetProblemOptions& options, bool any_invalid,
                                      const std::function<void(std::vector<double>*, std::vector<double>*)>& estimate) {
  const std::size_t n = std::size_t(d.size());
  DatasetFrameWeights out;
  WeightsRule& rule = out.rule;
  DatasetWeights choice = options.weights;
  if (choice == DatasetWeights::kAuto && options.method) choice = AutoWeights(*options.method);
  const bool has_weights = d.weights || (d.pixel_files && !d.pixel_files->weights.empty());
  const bool use_dataset = choice == DatasetWeights::kDataset || (choice == DatasetWeights::kAuto && has_weights);
  rule.any_invalid = any_invalid;
  auto use_mask = [&] {
    rule.kind = rule.any_invalid ? WeightsRule::Kind::kValid : WeightsRule::Kind::kUniform;
    out.source = "validity mask";
  };
  if (use_dataset) {
    CheckArgument(has_weights, kDatasetProblemFn, "weights", "dataset", "a dataset whose manifest gives `weights`");
    rule.kind = WeightsRule::Kind::kDataset;
    rule.gain2 = d.gain_e_per_adu * d.gain_e_per_adu;
    out.source = "dataset inverse variances (e-^-2)";
    if (options.method && IsLinearMethod(*options.method))
      out.warning = std::string("the dataset's inverse variances (source photon noise included) with ") +
                    ToString(*options.method) +
                    ": source-dependent weights make the output flux-dependent and bias bright sources low "
                    "(bench/results/science.md: -12 % for linear, -16 % for tikhonov, -42 % for drizzle at K 14-15 on "
                    "crowded-stars); "
                    "weights 'auto' or 'background' do not depend on the sources";
  } else if (choice == DatasetWeights::kBackground) {
    std::vector<double> var(n, 0.0);
    const std::optional<double> model = DetectorModelVariance(d);
    if (model) {
      var.assign(n, *model);
      out.source = "background variances from the detector model (e-^-2)";
    } else {
      std::vector<double> se(n, 0.0);
      estimate(&var, &se);
      // Pool the frames' estimates when they agree within 5 standard errors: one exposure sequence, one
      // noise level, and uniform weights keep the problem Fourier-exact.
      const double lo = *std::min_element(var.begin(), var.end()), hi = *std::max_element(var.begin(), var.end());
      const double se_max = *std::max_element(se.begin(), se.end());
      if (lo > 0 && hi - lo <= 5.0 * se_max * lo) {
        double mean = 0;
        for (double v : var) mean += v / double(n);
        var.assign(n, mean);
      }
      out.source = "background variances estimated from the frames (e-^-2)";
    }
    const bool none = std::any_of(var.begin(), var.end(), [](double v) { return !(v > 0) || !std::isfinite(v); });
    if (none) {
      use_mask();  // no noise model (or a frame without a usable background): uniform on the valid pixels
    } else {
      rule.kind = WeightsRule::Kind::kBackground;
      rule.variance_e2 = var;
      for (std::size_t i = 0; i < n; ++i) out.background_sigma_e.push_back(std::sqrt(var[i]));
    }
  } else {
    use_mask();
  }
  return out;
}

// The frames' background variances and their relative standard errors (EstimateBackgroundSigma, frame by frame).
void EstimateBackgroundVariances(const ImageStack& frames_e, const ImageStack& valid, std::vector<double>* var,
                                 std::vector<double>* se) {
  for (std::size_t i = 0; i < frames_e.size(); ++i) {
    const double sigma = EstimateBackgroundSigma(frames_e[i], valid[i], &(*se)[i]);
    (*var)[i] = sigma * sigma;
  }
}

// The rule of a dataset loaded by sections, decided as WeightsFromDataset decides it on the held frames (the same
// rule, bit for bit), with the frames read in bands of rows: a plan that never holds a whole detector's frames.
// Also counts the pixels of weight 0 (DatasetProblem::masked_pixels). Background weights without a detector model
// need each frame's whole background estimate: only then are the frames read whole, once.
DatasetFrameWeights WeightsRuleBySections(const Dataset& d, const DatasetProblemOptions& options, Index* masked) {
  const Index rows = d.frame.rows, cols = d.frame.cols;
  // 2^22 pixels of each file a read (32 MB as doubles).
  const Index band = std::max<Index>(1, (Index(1) << 22) / std::max<Index>(1, cols * d.size()));
  bool any_invalid = false;
  Index invalid = 0, zero_weight = 0;
  for (Index y0 = 0; y0 < rows; y0 += band) {
    const DatasetSection s = ReadDatasetSection(d, y0, 0, std::min(band, rows - y0), cols);
    for (std::size_t i = 0; i < s.valid.size(); ++i) {
      const Index bad = (s.valid[i] == 0).count();
      invalid += bad;
      any_invalid = any_invalid || bad > 0;
      if (s.weights) zero_weight += ((*s.weights)[i] * s.valid[i] == 0).count();
    }
  }
  auto estimate = [&](std::vector<double>* var, std::vector<double>* se) {
    const DatasetSection s = ReadDatasetSection(d, 0, 0, rows, cols);
    ImageStack frames_e;
    for (const Image& f : s.frames) frames_e.push_back((f - d.bias_adu) * d.gain_e_per_adu);
    EstimateBackgroundVariances(frames_e, s.valid, var, se);
  };
  DatasetFrameWeights out = ChooseWeightsRule(d, options, any_invalid, estimate);
  // As ProblemFromDataset counts them on held weights: w == 0, w the rule's weights (the mask without any).
  *masked = out.rule.kind == WeightsRule::Kind::kDataset ? zero_weight : invalid;
  return out;
}

}  // namespace

DatasetFrameWeights WeightsFromDataset(const Dataset& d, const ImageStack& frames_e, const DatasetProblemOptions& options) {
  const std::size_t n = d.frames.size();
  CheckArgument(frames_e.size() == n, "WeightsFromDataset", "frames_e", std::to_string(frames_e.size()) + " frames",
                "the dataset's " + std::to_string(n) + " frames in electrons");
  bool any_invalid = false;
  for (const Image& v : d.valid) any_invalid = any_invalid || (v == 0).any();
  auto estimate = [&](std::vector<double>* var, std::vector<double>* se) {
    EstimateBackgroundVariances(frames_e, d.valid, var, se);
  };
  DatasetFrameWeights out = ChooseWeightsRule(d, options, any_invalid, estimate);
  out.weights = ApplyWeightsRule(out.rule, d.valid, d.weights);
  return out;
}

DatasetProblem ProblemFromDataset(const Dataset& d, const DatasetProblemOptions& options) {
  const std::size_t n = std::size_t(d.size());
  CheckArgument(n > 0, kDatasetProblemFn, "dataset frames", 0, "at least one frame");
  if (d.pixel_files) {
    // Only the tiles' windows will be read: nothing here may need the whole frames.
    CheckArgument(!options.whole_grid_model, kDatasetProblemFn, "dataset", "one loaded by sections",
                  "with whole_grid_model false (a tiled run without a whole-grid model)");
    CheckArgument(!options.stars_psfs, kDatasetProblemFn, "stars_psfs", "true for a dataset loaded by sections",
                  "PSFs that need no whole frame (the dataset's, nominal or given)");
  }
  DatasetProblem out;

  // ---- PSFs of the model. ---------------------------------------------------------------------------------
  ImageStack psfs = d.psfs;
  CheckArgument(!(options.nominal_psfs && !options.model_psfs.empty()), kDatasetProblemFn, "nominal_psfs", "true with model_psfs",
                "one of nominal_psfs and model_psfs");
  if (options.nominal_psfs) {
    CheckArgument(d.nominal_psfs.size() == n, kDatasetProblemFn, "nominal_psfs", "true",
                  "a dataset whose manifest gives nominal_psfs (closed-loop simulations write them)");
    psfs = d.nominal_psfs;
    out.model_psfs_replaced = true;
  }
  CheckArgument(!(options.stars_psfs && (options.nominal_psfs || !options.model_psfs.empty())), kDatasetProblemFn, "stars_psfs",
                "true with nominal_psfs or model_psfs", "one source of model PSFs");
  if (options.stars_psfs) {
    out.stars_psf = EstimateStarsPsf(d, options.stars);
    psfs = out.stars_psf->psfs;
    out.model_psfs_replaced = true;
  }
  if (!options.model_psfs.empty()) {
    const ImageStack& m = options.model_psfs;
    CheckArgument(m.size() == n || m.size() == 1, kDatasetProblemFn, "model_psfs count", m.size(),
                  "1 or one per frame (" + std::to_string(n) + ")");
    psfs.clear();
    for (std::size_t i = 0; i < n; ++i) {
      const Image& k = m[m.size() == 1 ? 0 : i];
      const double s = k.size() > 0 && AllFinite(k) ? k.sum() : 0.0;
      CheckArgument(s > 0, kDatasetProblemFn, "model_psfs[" + std::to_string(i) + "]",
                    k.size() == 0 ? std::string("empty") : "sum " + ToString(s), "finite values with a positive sum");
      psfs.push_back(k / s);
    }
    out.model_psfs_replaced = true;
  }
  // ---- The field-varying model. ---------------------------------------------------------------------------
  const bool model_based = !options.method || (*options.method != ReconstructionMethod::kShiftAddMean &&
                                               *options.method != ReconstructionMethod::kShiftAddMedian &&
                                               *options.method != ReconstructionMethod::kDrizzle);
  const bool own_psfs = !options.stars_psfs && options.model_psfs.empty();
  // A stars PSF fitted over a field grid (StarsPsfOptions::grid_ny x grid_nx > 1) is a field model of its own.
  const bool stars_field = out.stars_psf && out.stars_psf->grid.nodes() > 1;
  if (options.psf_field == DatasetPsfField::kTiles || options.psf_field == DatasetPsfField::kOperator) {
    const std::string asked = ToString(options.psf_field);
    CheckArgument(bool(d.psf_field) || stars_field, kDatasetProblemFn, "psf_field", asked,
                  "a dataset with a psf_field (simulations of a scene with psf_field write it), or stars PSFs fitted "
                  "over a field grid (stars grid_ny x grid_nx > 1)");
    CheckArgument(own_psfs || stars_field, kDatasetProblemFn, "psf_field", asked + " with model_psfs or single stars PSFs",
                  "the dataset's own (or nominal) PSFs, or stars PSFs over a field grid: the field model's PSFs are "
                  "the dataset's psf_field or the stars' grid");
    CheckArgument(model_based, kDatasetProblemFn, "psf_field", asked,
                  std::string("a method that models the PSF (tikhonov, linear, tv, map), not ") +
                      ToString(*options.method));
    CheckArgument(!(options.psf_field == DatasetPsfField::kOperator && options.method &&
                    *options.method == ReconstructionMethod::kLinear),
                  kDatasetProblemFn, "psf_field", asked + " with the linear method",
                  "tiles: the target-PSF output is a per-frequency design, made tile by tile with local PSFs");
  }
  if (((d.psf_field && own_psfs) || stars_field) && model_based && options.psf_field != DatasetPsfField::kNone) {
    // Registration shifts the model's PSFs by each frame's estimated correction; the nodes' PSFs would keep the
    // commanded offsets, and the two models would disagree.
    CheckArgument(options.offsets != DatasetOffsets::kEstimate, kDatasetProblemFn, "offsets",
                  std::string("estimate with psf_field ") + ToString(options.psf_field),
                  "dm, centroids or auto with a field model (registration does not move the field's PSFs yet), or "
                  "psf_field none");
    DatasetProblem::Field f;
    f.approach = options.psf_field == DatasetPsfField::kOperator ? DatasetPsfField::kOperator : DatasetPsfField::kTiles;
    if (stars_field) {
      f.grid = out.stars_psf->grid;
      f.psfs = out.stars_psf->field_psfs;
    } else {
      f.grid = d.psf_field->grid;
      if (options.nominal_psfs) {
        CheckArgument(!d.psf_field->nominal_psfs.empty(), kDatasetProblemFn, "nominal_psfs", "true with a psf_field",
                      "a dataset whose psf_field gives nominal_psfs (closed-loop simulations write them), or psf_field none");
        f.psfs = d.psf_field->nominal_psfs;
      } else {
        f.psfs = d.psf_field->psfs;
      }
    }
    CheckArgument(f.psfs.size() == std::size_t(f.grid.nodes()) && !f.psfs.empty() && f.psfs.front().size() == n,
                  kDatasetProblemFn, "psf_field psfs", f.psfs.size(), "one stack of N PSFs per node");
    // The whole field's model: the PSFs at its centre (the regularisation is chosen with it).
    psfs.clear();
    for (std::size_t i = 0; i < n; ++i) {
      ImageStack node;
      for (const ImageStack& p : f.psfs) node.push_back(p[i]);
      psfs.push_back(f.grid.Interpolate(node, 0.5 * double(d.hr_frame.rows - 1), 0.5 * double(d.hr_frame.cols - 1)));
    }
    out.psf_field = std::move(f);
    out.model_psfs_replaced = true;
  }
  std::vector<FrameOffset> centroids;  // of the kernels as given: folding moves their first moments
  for (const Image& k : psfs) centroids.push_back(KernelCentroid(k));
  // Tiles with local PSFs need no whole-grid model either: each tile builds its own from the field's PSFs, the
  // regularisation is chosen on a window and the residuals come from the tiles (psf_field_model.hpp). Its
  // transfer functions would cost a field's run a fifth of its time.
  const bool whole_grid_model =
      options.whole_grid_model && !(out.psf_field && out.psf_field->approach == DatasetPsfField::kTiles);
  if (!whole_grid_model) {
    CheckArgument(options.offsets != DatasetOffsets::kEstimate, kDatasetProblemFn, "offsets",
                  "estimate without a whole-grid model", "dm, centroids or auto (registration needs the whole grid)");
    CheckArgument(!(out.psf_field && out.psf_field->approach == DatasetPsfField::kOperator), kDatasetProblemFn,
                  "psf_field", "operator without a whole-grid model", "tiles (the operator spans the whole grid)");
    out.field = FieldData();
    out.field->lr = d.frame;
    out.field->r = d.r;
    out.field->kernels = psfs;  // as the whole-grid model takes them (not renormalised), not folded
  }
  for (Image& k : psfs)
    if (k.rows() > d.hr_frame.rows || k.cols() > d.hr_frame.cols) {
      k = FoldOnto(k, d.hr_frame);
      ++out.psf_folded;
    }
  // The model holds one HR transfer function per frame (complex, half spectrum) and builds each from a padded
  // real kernel: refuse a dataset whose r and frame count cannot fit before building them.
  if (!out.field) {
  const double hr_pixels = double(d.hr_frame.rows) * double(d.hr_frame.cols);
  CheckMemory(double(n) * 16.0 * hr_pixels / 2 + 16.0 * hr_pixels,
              std::string(kDatasetProblemFn) + ": the model of " + std::to_string(n) + " frames on the HR grid " + ToString(d.hr_frame) +
                  " (r = " + std::to_string(d.r) + ")");
  out.problem.model = std::make_shared<const MultiFrameModel>(MultiFrameModel::FromKernels(d.hr_frame, d.r, psfs));
  if (out.psf_field && out.psf_field->approach == DatasetPsfField::kOperator) {
    // The space-variant operator around the centre's model (forward_model.hpp), the nodes' kernels folded onto
    // the grid as the model's are.
    std::vector<ImageStack> nodes = out.psf_field->psfs;
    for (ImageStack& node : nodes)
      for (Image& k : node)
        if (k.rows() > d.hr_frame.rows || k.cols() > d.hr_frame.cols) k = FoldOnto(k, d.hr_frame);
    CheckMemory(double(nodes.size()) * double(n) * 16.0 * hr_pixels / 2,
                std::string(kDatasetProblemFn) + ": the space-variant model of " + std::to_string(nodes.size()) +
                    " field points x " + std::to_string(n) + " frames on the HR grid " + ToString(d.hr_frame));
    out.problem.model =
        std::make_shared<const MultiFrameModel>(out.problem.model->WithPsfField(out.psf_field->grid, nodes));
  }
  }

  // ---- Frames (e⁻) and weights. ---------------------------------------------------------------------------
  if (d.pixel_files) {
    // By sections: each window's frames in electrons and its weights under the plan's rule, the bytes the held
    // frames would give there (FramesElectrons and ApplyWeightsRule pixel by pixel).
    // The rule: the plan's (a job's tile), or decided here by reading the frames in bands (the plan itself).
    if (options.weights_rule) {
      out.weights_rule = *options.weights_rule;
      const WeightsRule& rule = out.weights_rule;
      out.weights_source = rule.kind == WeightsRule::Kind::kDataset      ? "dataset inverse variances (e-^-2)"
                           : rule.kind == WeightsRule::Kind::kBackground ? "background variances (e-^-2), the plan's"
                                                                         : "validity mask";
      for (double v : rule.variance_e2) out.background_sigma_e.push_back(std::sqrt(v));
    } else {
      DatasetFrameWeights fw = WeightsRuleBySections(d, options, &out.masked_pixels);
      out.weights_rule = std::move(fw.rule);
      out.weights_source = std::move(fw.source);
      out.background_sigma_e = std::move(fw.background_sigma_e);
      out.warning = std::move(fw.warning);
    }
    const WeightsRule rule = out.weights_rule;
    auto sections = std::make_shared<FieldData::Sections>();
    sections->frames = int(n);
    sections->uniform_weights = rule.Uniform();
    const auto dataset = std::make_shared<const Dataset>(d);
    // One read at a time: cfitsio need not be built reentrant, and a read is short beside a tile's solve.
    const auto io = std::make_shared<std::mutex>();
    sections->read = [dataset, rule, io](Index y0, Index x0, Index rows, Index cols, ImageStack* frames,
                                         ImageStack* weights) {
      DatasetSection s;
      {
        const std::lock_guard<std::mutex> lock(*io);
        s = ReadDatasetSection(*dataset, y0, x0, rows, cols);
      }
      frames->clear();
      for (const Image& f : s.frames) frames->push_back((f - dataset->bias_adu) * dataset->gain_e_per_adu);
      *weights = ApplyWeightsRule(rule, s.valid, s.weights);
    };
    out.field->sections = std::move(sections);
  }
  if (!d.pixel_files) {
  out.problem.frames = d.FramesElectrons();
  {
    DatasetFrameWeights fw = WeightsFromDataset(d, out.problem.frames, options);
    out.problem.weights = std::move(fw.weights);
    out.weights_source = std::move(fw.source);
    out.background_sigma_e = std::move(fw.background_sigma_e);
    out.warning = std::move(fw.warning);
    out.weights_rule = std::move(fw.rule);
  }
  for (std::size_t i = 0; i < n; ++i) {
    const Image w = out.problem.weights.empty() ? d.valid[i] : out.problem.weights[i];
    out.masked_pixels += (w == 0).count();
  }
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
  if (out.field) {
    out.field->frames = std::move(out.problem.frames);
    out.field->weights = std::move(out.problem.weights);
    out.field->offsets = std::move(out.problem.offsets);
    out.problem = {};
    out.field->Validate(kDatasetProblemFn);
    return out;
  }
  out.problem.Validate(kDatasetProblemFn);
  if (options.offsets == DatasetOffsets::kEstimate) {
    RegistrationResult reg = RegisterFrames(out.problem, options.registration);
    out.problem = reg.problem;
    reg.problem = {};  // the problem is out.problem; do not keep the frames twice
    out.offsets_source = "estimated from the frames (commanded: " + out.offsets_source + ")";
    out.registration = std::move(reg);
  }
  return out;
}

bool WholeGridFits(const Dataset& d, ReconstructionMethod method, double limit_bytes, double* need) {
  const double hr_pixels = double(d.hr_frame.rows) * double(d.hr_frame.cols);
  const double lr_pixels = double(d.frame.rows) * double(d.frame.cols);
  const int n = d.size();
  // The model (N half spectra), the data in electrons and the weights, and the solve.
  const double bytes = 8.0 * n * hr_pixels + 16.0 * n * lr_pixels + EstimateSolveBytes(method, n, hr_pixels, true);
  if (need) *need = bytes;
  return bytes <= limit_bytes;
}

}  // namespace aosr
