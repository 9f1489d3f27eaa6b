#include "aosr/scene/dataset.hpp"

#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <system_error>

#include "aosr/core/error.hpp"
#include "aosr/io/atomic_file.hpp"
#include "aosr/io/config.hpp"
#include "aosr/io/fits.hpp"

namespace aosr {
namespace {

namespace fs = std::filesystem;
using OrderedJson = nlohmann::ordered_json;

constexpr double kNm = 1e-9;
constexpr double kRadPerMas = M_PI / 180.0 / 3600.0 / 1000.0;
// Relative tolerance of the consistency checks between a manifest's redundant numbers (pixel scales written
// in rad and mas): they are written with 17 significant digits, so anything beyond rounding is a mistake.
constexpr double kConsistency = 1e-9;

constexpr const char* kFramesFile = "frames.fits";
constexpr const char* kValidFile = "valid.fits";
constexpr const char* kWeightsFile = "weights.fits";
constexpr const char* kTruthFile = "truth.fits";
constexpr const char* kPsfsFile = "psfs.fits";
constexpr const char* kNominalPsfsFile = "nominal_psfs.fits";
constexpr const char* kFieldPsfsFile = "field_psfs.fits";
constexpr const char* kFieldNominalPsfsFile = "field_nominal_psfs.fits";
constexpr double kDatasetArcsecPerRad = 180.0 * 3600.0 / M_PI;
constexpr const char* kExpectedFile = "expected.fits";
constexpr const char* kTruthFramesFile = "truth_frames.fits";
constexpr const char* kExposurePsfsFile = "exposure_psfs.fits";

}  // namespace

ImageStack PerPhase(const SceneSpec& scene, const ImageStack& per_exposure) {
  CheckArgument(per_exposure.size() == std::size_t(scene.Exposures()), "PerPhase", "per_exposure",
                std::to_string(per_exposure.size()) + " images",
                "one per exposure of the scene (" + std::to_string(scene.Exposures()) + ")");
  if (!scene.sequence.enabled()) return per_exposure;
  ImageStack out(std::size_t(scene.frames));
  std::vector<int> count(std::size_t(scene.frames), 0);
  for (std::size_t j = 0; j < per_exposure.size(); ++j) {
    const std::size_t q = j % std::size_t(scene.frames);
    out[q] = count[q]++ == 0 ? per_exposure[j] : Image(out[q] + per_exposure[j]);
  }
  for (std::size_t q = 0; q < out.size(); ++q) out[q] /= double(count[q]);
  return out;
}

namespace {

std::string Join(const std::string& dir, const std::string& name) { return (fs::path(dir) / name).string(); }

bool IsRegularFile(const std::string& path) {
  std::error_code ec;
  return fs::is_regular_file(path, ec);
}

bool Close(double a, double b) { return std::abs(a - b) <= kConsistency * std::max(std::abs(a), std::abs(b)); }

// FITS header strings are printable ASCII; a scene name is free text.
std::string Printable(const std::string& s) {
  std::string out;
  for (char c : s) out += (c >= 32 && c < 127) ? c : '?';
  return out;
}

// ---- Writing ----------------------------------------------------------------------------------------------

const char* NoiseModelName(const DetectorOptions& d) {
  if (d.noise_model == NoiseModel::kPeakFraction) return d.peak_noise_fraction > 0 ? "peak-fraction" : "none";
  return d.enable_photon_noise || d.enable_read_noise ? "physical" : "none";
}

// The keywords every file of a simulation carries; `hr` selects the HR pixel scale (truth, PSFs); `wcs` is
// the file's sky coordinates (none for the PSFs).
FitsHeader SimulationHeader(const SceneSpec& scene, const SceneGeometry& g, const std::string& what,
                            const std::string& bunit, bool hr, const std::optional<Wcs>& wcs = std::nullopt) {
  FitsHeader h;
  h.Set("ORIGIN", std::string("aosr ") + AOSR_VERSION, "software that wrote this file");
  h.Set("AOSRDATA", what, "content of this HDU (see manifest.json)");
  h.Set("SCENE", Printable(scene.name), "scene name");
  if (!bunit.empty()) h.Set("BUNIT", bunit, "unit of the data values");
  h.Set("SRFACTOR", static_cast<long long>(g.r), "super-resolution factor r");
  h.Set("NFRAMES", static_cast<long long>(scene.frames), "number of sub-exposures N");
  h.Set("GAIN", scene.detector.gain_e_per_adu, "[e-/ADU] detector gain");
  h.Set("BIAS", scene.detector.bias_adu, "[ADU] detector bias");
  h.Set("EXPTIME", scene.detector.exposure_time_s, "[s] integration time of one frame");
  h.Set("PIXSCALE", (hr ? g.hr_pixel_rad : g.camera_pixel_rad) / kRadPerMas,
        hr ? "[mas] HR pixel pitch (camera pixel / r)" : "[mas] camera pixel pitch");
  h.Set("WAVELEN", g.wavelength_m, "[m] science wavelength");
  if (wcs) {
    WriteWcs(*wcs, &h);
    h.Set("SKYGIVEN", scene.sky.given, "F: the scene gave no sky pointing (placeholder RA, Dec)");
  }
  return h;
}

// The truth's (HR grid's) WCS: the scene's pointing at the centre of the HR grid, HR pixel pitch.
Wcs SimulationHrWcs(const SceneSpec& scene, const SceneGeometry& g) {
  const PixelCoord centre{(g.hr_frame.rows - 1) / 2.0, (g.hr_frame.cols - 1) / 2.0};
  return TangentPlaneWcs(scene.sky.ra_deg, scene.sky.dec_deg, g.hr_pixel_rad, scene.sky.position_angle_deg, centre);
}

// Frame i's image displacement from the HR grid, HR pixels (+x: toward larger column), from its DM shift.
double ShiftHrY(const DmOffset& o, int r) { return o.shift_y_px * r; }
double ShiftHrX(const DmOffset& o, int r) { return o.shift_x_px * r; }

OrderedJson Ordered(const nlohmann::json& j) { return OrderedJson::parse(j.dump()); }

OrderedJson ShapeJson(Shape s) { return OrderedJson::array({s.rows, s.cols}); }

// The scene's own JSON: the caller's copy, else the source file read again, else null (parsed from memory).
OrderedJson SceneJson(const SceneSpec& scene, const nlohmann::json* scene_json) {
  if (scene_json) return Ordered(*scene_json);
  if (IsRegularFile(scene.source)) {
    try {
      return Ordered(ReadJsonFile(scene.source));
    } catch (const Error&) {
      // The scene was parsed from this file a moment ago; if it is gone or changed, provenance says so.
    }
  }
  return OrderedJson();
}

// The manifest's "noise" section (provenance: the detector model of the simulation).
OrderedJson NoiseJson(const SceneSpec& scene, const Simulation& sim) {
  const DetectorOptions& d = scene.detector;
  OrderedJson noise;
  noise["model"] = NoiseModelName(d);
  noise["photon_noise"] = d.noise_model == NoiseModel::kPhysical && d.enable_photon_noise;
  noise["read_noise_e"] = d.noise_model == NoiseModel::kPhysical && d.enable_read_noise ? d.read_noise_e : 0.0;
  noise["peak_noise_fraction"] = d.noise_model == NoiseModel::kPeakFraction ? d.peak_noise_fraction : 0.0;
  // kPeakFraction: the σ actually drawn (p · the sequence's largest expected λ), electrons.
  noise["sigma_e"] = sim.frames.empty() ? 0.0 : sim.frames.front().noise_sigma_e;
  noise["background_e_per_s"] = d.enable_background ? d.background_e_per_s : 0.0;
  noise["dark_current_e_per_s"] = d.enable_dark_current ? d.dark_current_e_per_s : 0.0;
  noise["saturation"] = d.enable_saturation;
  noise["saturation_adu"] = d.saturation_adu;
  noise["quantize"] = d.enable_quantization;
  noise["fill_factor"] = d.fill_factor;
  noise["frame_time_s"] = d.exposure_time_s;
  noise["total_exposure_s"] = scene.total_exposure_s;
  if (d.enable_bad_pixels) {
    OrderedJson b;
    if (!scene.bad_pixel_file.empty()) b["file"] = scene.bad_pixel_file;
    else b["fraction"] = scene.bad_pixel_fraction;
    b["count"] = Index((d.bad_pixel_mask == 0).count());
    noise["bad_pixels"] = b;
  }
  return noise;
}

OrderedJson BuildManifest(const SceneSpec& scene, const ScenePipeline& pipeline, const Simulation& sim,
                          const nlohmann::json* scene_json) {
  const SceneGeometry& g = sim.geometry;
  const DetectorOptions& d = scene.detector;
  OrderedJson m;
  m["format"] = kManifestFormat;
  m["version"] = kManifestVersion;
  m["software"] = std::string("aosr ") + AOSR_VERSION;
  m["r"] = g.r;
  m["frame_shape"] = ShapeJson(g.frame);
  m["hr_shape"] = ShapeJson(g.hr_frame);
  m["psf_size_px"] = g.psf_size;
  m["frames"] = kFramesFile;
  m["valid"] = kValidFile;
  m["weights"] = kWeightsFile;
  m["psfs"] = kPsfsFile;
  if (!sim.nominal_psfs.empty()) m["nominal_psfs"] = kNominalPsfsFile;
  if (!sim.field_psfs.empty()) {
    // The PSF across the field (dataset.hpp): what a field-varying model reads.
    OrderedJson f;
    f["psfs"] = kFieldPsfsFile;
    if (!sim.field_nominal_psfs.empty()) f["nominal_psfs"] = kFieldNominalPsfsFile;
    f["grid"] = {sim.field_grid.ny(), sim.field_grid.nx()};
    f["interpolation"] = "bilinear";
    f["guide_star_arcsec"] = {scene.psf_field.guide_star_x_arcsec, scene.psf_field.guide_star_y_arcsec};
    m["psf_field"] = f;
  }
  m["truth"] = kTruthFile;
  if (!sim.truth_frames.empty()) m["truth_frames"] = kTruthFramesFile;
  if (scene.sequence.enabled()) {
    // The phase of each frame and its mid-exposure time (dataset.hpp); the PSFs above are per phase.
    std::vector<int> slots;
    for (int j = 0; j < scene.Exposures(); ++j) slots.push_back(j % scene.frames);
    m["sequence"] = {{"slots", slots}, {"times_s", sim.times_s}};
  }
  m["expected"] = kExpectedFile;
  m["gain_e_per_adu"] = d.gain_e_per_adu;
  m["bias_adu"] = d.bias_adu;
  m["trustworthy_border_px"] = g.trustworthy_border_px;
  m["pixel_scale"] = {{"camera_rad", g.camera_pixel_rad},
                      {"camera_mas", g.camera_pixel_rad / kRadPerMas},
                      {"camera_lambda_over_d", g.hr_pixel_lambda_over_d * g.r},
                      {"hr_rad", g.hr_pixel_rad},
                      {"hr_mas", g.hr_pixel_rad / kRadPerMas},
                      {"hr_lambda_over_d", g.hr_pixel_lambda_over_d}};
  m["wavelength_m"] = g.wavelength_m;
  OrderedJson offsets = OrderedJson::array();
  for (const DmOffset& o : scene.offsets.frames) offsets.push_back(Ordered(DmOffsetToJson(o)));
  m["offsets"] = offsets;
  if (!sim.stars.empty()) {
    // HR-frame coordinates; camera pixel c spans HR pixels c·r .. c·r + r − 1, so c = (y + ½)/r − ½.
    OrderedJson stars = OrderedJson::array();
    for (const PointSource& p : sim.stars)
      stars.push_back({{"y_hr_px", p.y},
                       {"x_hr_px", p.x},
                       {"y_px", (p.y + 0.5) / g.r - 0.5},
                       {"x_px", (p.x + 0.5) / g.r - 0.5},
                       {"flux_e", p.flux}});
    m["stars"] = stars;
  }

  m["noise"] = NoiseJson(scene, sim);

  OrderedJson s;
  s["scene"] = {{"name", scene.name}, {"source", scene.source}, {"json", SceneJson(scene, scene_json)}};
  OrderedJson objects = OrderedJson::array();
  for (const ObjectSpec& o : scene.objects) objects.push_back(o.seed);
  s["seeds"] = {{"scene", scene.seed},
                {"noise", scene.noise_seed},
                {"atmosphere", scene.ao.seed},
                {"bad_pixels", scene.bad_pixel_seed},
                {"objects", objects}};
  OrderedJson exposures = OrderedJson::array();
  for (std::size_t i = 0; i < sim.psfs.size(); ++i) {
    OrderedJson e;
    e["strehl"] = i < sim.strehl.size() ? sim.strehl[i] : 0.0;
    e["psf_window_fraction"] = i < sim.psf_window_fraction.size() ? sim.psf_window_fraction[i] : 0.0;
    e["distinct_psf"] = i < sim.distinct_psf.size() ? sim.distinct_psf[i] : int(i);
    if (i < sim.tilt_gain.size()) e["wfs_tilt_gain"] = {sim.tilt_gain[i][0], sim.tilt_gain[i][1]};
    exposures.push_back(e);
  }
  s["exposures"] = exposures;
  if (!sim.field_psfs.empty()) {
    // Provenance of the field grid: each node's position, direction from the guide star and Strehl ratios.
    OrderedJson nodes = OrderedJson::array();
    for (int k = 0; k < sim.field_grid.nodes(); ++k) {
      const auto node = sim.field_grid.Node(k);
      OrderedJson e;
      e["y_hr_px"] = node[0];
      e["x_hr_px"] = node[1];
      e["direction_arcsec"] = {sim.field_directions[k].x_rad * kDatasetArcsecPerRad,
                               sim.field_directions[k].y_rad * kDatasetArcsecPerRad};
      e["strehl"] = k < int(sim.field_strehl.size()) ? sim.field_strehl[k] : std::vector<double>();
      nodes.push_back(e);
    }
    s["psf_field"] = {{"nodes", nodes}};
  }
  OrderedJson plan = OrderedJson::array();
  for (const PipelineStage& st : pipeline.stages())
    plan.push_back({{"stage", st.name}, {"count", st.count}, {"estimated_s", st.estimated_s}, {"detail", st.detail}});
  s["plan"] = plan;
  // No wall times here: the manifest is part of the dataset, whose bytes depend only on the scene and seed
  // (the timings are in `aosr simulate --json`).
  const SimulationCounters& c = sim.counters;
  s["counters"] = {{"object_components", c.object_components}, {"psfs_computed", c.psfs_computed},
                   {"object_transforms", c.object_transforms}, {"frame_transforms", c.frame_transforms},
                   {"loop_steps", c.loop_steps},               {"fft_executions", c.fft_executions},
                   {"phase_screens", c.phase_screens},         {"noise_draws", c.noise_draws}};
  m["simulation"] = s;
  return m;
}

void WriteJsonAtomically(const std::string& path, const OrderedJson& j) {
  AtomicWrite(path, [&j](const std::string& tmp) {
    std::ofstream out(tmp, std::ios::binary);
    out << j.dump(2) << "\n";
    out.close();
    if (!out) throw IoError(tmp, "cannot write the manifest");
  });
}

void CheckSimulation(const SceneSpec& scene, const Simulation& sim) {
  const auto fail = [](const std::string& what, const std::string& value, const std::string& allowed) {
    throw InvalidArgument("WriteSimulation", what, value, allowed);
  };
  const std::size_t n = std::size_t(scene.Exposures());
  if (sim.geometry.frame != scene.frame || sim.geometry.r != scene.r)
    fail("sim.geometry", ToString(sim.geometry.frame) + ", r " + std::to_string(sim.geometry.r),
         "the scene's frame " + ToString(scene.frame) + " and r " + std::to_string(scene.r));
  if (sim.frames.size() != n || sim.psfs.size() != n || sim.expected_e.size() != n)
    fail("sim", std::to_string(sim.frames.size()) + " frames, " + std::to_string(sim.psfs.size()) + " PSFs, " +
                    std::to_string(sim.expected_e.size()) + " expected frames",
         "the scene's " + std::string(scene.sequence.enabled() ? "M = " : "N = ") + std::to_string(n) +
             " exposures of each (the result of ScenePipeline::Run)");
  if (!sim.truth_frames.empty() && sim.truth_frames.size() != n)
    fail("sim.truth_frames", std::to_string(sim.truth_frames.size()) + " images", "one per exposure (" + std::to_string(n) + ")");
  if (scene.sequence.enabled() && sim.times_s.size() != n)
    fail("sim.times_s", std::to_string(sim.times_s.size()) + " times", "one per exposure (" + std::to_string(n) + ")");
  if (ShapeOf(sim.truth) != sim.geometry.hr_frame)
    fail("sim.truth", ToString(ShapeOf(sim.truth)), "the HR frame " + ToString(sim.geometry.hr_frame));
  for (std::size_t i = 0; i < n; ++i) {
    const DetectorFrame& f = sim.frames[i];
    if (ShapeOf(f.adu) != scene.frame || ShapeOf(f.valid) != scene.frame ||
        ShapeOf(f.inverse_variance) != scene.frame || ShapeOf(sim.expected_e[i]) != scene.frame)
      fail("sim.frames[" + std::to_string(i) + "]", ToString(ShapeOf(f.adu)), "the frame " + ToString(scene.frame));
  }
}

// ---- Reading ----------------------------------------------------------------------------------------------

// A manifest's file field: resolved against the manifest's folder, required to exist.
std::string FileField(const ConfigNode& root, const std::string& key) {
  const std::string name = root.String(key);
  if (name.empty()) root.Fail(key, "\"\"", "a file name relative to the manifest's folder");
  const fs::path p(name);
  const std::string path = p.is_absolute() ? name : (fs::path(root.source()).parent_path() / p).string();
  if (!IsRegularFile(path)) root.Fail(key, "\"" + name + "\" (" + path + ": no such file)", "an existing file, relative to the manifest's folder");
  return path;
}

Shape ShapeField(const ConfigNode& n, const std::string& key) {
  const std::vector<double> v = n.Numbers(key, 1, 1e7, 2, 2);
  if (v[0] != std::floor(v[0]) || v[1] != std::floor(v[1])) n.Fail(key, n.json().at(key).dump(), "[rows, cols] in whole pixels");
  return {Index(v[0]), Index(v[1])};
}

// The inline-design form of scene files (scene_spec.cpp), which DmOffsetToJson writes.
DmOffset ParseOffset(const ConfigNode& n) {
  DmOffset o;
  if (n.Has("shift_px")) {
    const std::vector<double> s = n.Numbers("shift_px", -1e3, 1e3, 2, 2);
    o.shift_y_px = s[0];
    o.shift_x_px = s[1];
  }
  if (n.Has("zernike")) {
    for (const ConfigNode& t : n.Array("zernike")) {
      DmOffset::Term term;
      term.noll = int(t.Integer("noll", 2, 1000));
      term.rms_m = t.Number("rms_nm", -1e7, 1e7) * kNm;
      t.CheckNoOtherFields();
      o.zernike.push_back(term);
    }
  }
  if (n.Has("actuators_nm")) {
    o.actuators_m = n.Numbers("actuators_nm", -1e7, 1e7, 1, 100000);
    for (double& a : o.actuators_m) a *= kNm;
  }
  n.CheckNoOtherFields();
  return o;
}

PointSource ParseStar(const ConfigNode& n, int r) {
  PointSource p;
  const bool hr = n.Has("y_hr_px") || n.Has("x_hr_px");
  const bool camera = n.Has("y_px") || n.Has("x_px");
  if (!hr && !camera) n.Fail("", "(no position)", "y_hr_px and x_hr_px, or y_px and x_px (camera pixels)");
  if (hr) {
    p.y = n.Number("y_hr_px", -1e7, 1e7);
    p.x = n.Number("x_hr_px", -1e7, 1e7);
  }
  if (camera) {
    const double y = (n.Number("y_px", -1e7, 1e7) + 0.5) * r - 0.5;
    const double x = (n.Number("x_px", -1e7, 1e7) + 0.5) * r - 0.5;
    if (hr && !(std::abs(y - p.y) <= 1e-6 * std::max(1.0, std::abs(y)) && std::abs(x - p.x) <= 1e-6 * std::max(1.0, std::abs(x))))
      n.Fail("y_px", ToString(n.json().at("y_px").get<double>()) + ", x_px " + ToString(n.json().at("x_px").get<double>()),
             "the camera position of y_hr_px, x_hr_px: (y_hr + 0.5) / r - 0.5 = " + ToString((p.y + 0.5) / r - 0.5) + ", " +
                 ToString((p.x + 0.5) / r - 0.5));
    if (!hr) p.y = y, p.x = x;
  }
  p.flux = n.Number("flux_e", -1e30, 1e30);
  n.CheckNoOtherFields();
  return p;
}

// Reads a cube file of a manifest and checks its shape: `planes` of `shape` (planes 0: any count).
ImageStack ReadCube(const ConfigNode& root, const std::string& key, const std::string& path, std::size_t planes,
                    Shape shape, const std::string& what) {
  ImageStack cube = ReadFits(path).planes;
  if ((planes && cube.size() != planes) || ShapeOf(cube.front()) != shape)
    root.Fail(key, "a " + std::to_string(cube.size()) + " x " + ToString(ShapeOf(cube.front())) + " cube (" + path + ")",
              what + ": " + std::to_string(planes) + " x " + ToString(shape));
  for (std::size_t i = 0; i < cube.size(); ++i)
    if (!AllFinite(cube[i]))
      root.Fail(key, "non-finite values in plane " + std::to_string(i) + " (" + path + ")", what + " with finite values");
  return cube;
}

}  // namespace

std::vector<std::string> SceneInputFiles(const SceneSpec& scene) {
  std::vector<std::string> files;
  auto add = [&files](const std::string& f) {
    if (!f.empty() && IsRegularFile(f)) files.push_back(f);
  };
  add(scene.source);
  add(scene.telescope.source);
  add(scene.telescope.mask_file);
  if (scene.offsets.kind == OffsetsSpec::Kind::kDesign && scene.offsets.source != "inline") add(scene.offsets.source);
  for (const ObjectSpec& o : scene.objects)
    if (o.kind == ObjectSpec::Kind::kImage) add(o.image_path);
    else if (o.kind == ObjectSpec::Kind::kPlanet) add(o.texture_path);
  add(scene.bad_pixel_file);
  return files;
}

void PrepareSimulationOutput(const std::string& dir, const SceneSpec& scene) {
  CheckArgument(!dir.empty(), "PrepareSimulationOutput", "dir", "\"\"", "a folder name");
  const std::vector<std::string> outputs = {kFramesFile, kValidFile,    kWeightsFile,     kTruthFile,
                                            kPsfsFile,   kExpectedFile, kManifestFileName, kNominalPsfsFile,
                                            kFieldPsfsFile, kFieldNominalPsfsFile, kTruthFramesFile, kExposurePsfsFile};
  // Before touching the disk: no output may be an input of the scene.
  const std::vector<std::string> inputs = SceneInputFiles(scene);
  for (const std::string& o : outputs) CheckNotSameFile(Join(dir, o), inputs);
  std::error_code ec;
  if (fs::exists(dir, ec) && !fs::is_directory(dir, ec)) throw IoError(dir, "exists and is not a folder");
  if (!fs::exists(dir, ec) && (!fs::create_directories(dir, ec) || ec))
    throw IoError(dir, "cannot create the folder: " + (ec ? ec.message() : std::string("unknown reason")));
  if (::access(dir.c_str(), W_OK | X_OK) != 0) throw IoError(dir, "the folder is not writable");
}

nlohmann::json SimulationNoiseJson(const SceneSpec& scene, const Simulation& sim) {
  return nlohmann::json::parse(NoiseJson(scene, sim).dump());
}

void WriteSimulation(const std::string& dir, const SceneSpec& scene, const ScenePipeline& pipeline,
                     const Simulation& sim, const nlohmann::json* scene_json) {
  CheckArgument(pipeline.scene().name == scene.name && pipeline.scene().source == scene.source, "WriteSimulation",
                "pipeline", pipeline.scene().name, "the pipeline compiled from `scene` (" + scene.name + ")");
  CheckSimulation(scene, sim);
  PrepareSimulationOutput(dir, scene);
  std::error_code ec;
  // A folder holds a manifest only when every file it names is of the same run (top of dataset.hpp).
  const std::string manifest = Join(dir, kManifestFileName);
  if (fs::exists(manifest, ec) && !fs::remove(manifest, ec))
    throw IoError(manifest, "cannot remove the previous manifest: " + ec.message());

  const SceneGeometry& g = sim.geometry;
  const Wcs hr_wcs = SimulationHrWcs(scene, g);
  const DmOffset first = scene.offsets.frames.empty() ? DmOffset{} : scene.offsets.frames.front();
  const Wcs lr_wcs = LrWcs(hr_wcs, g.r, ShiftHrY(first, g.r), ShiftHrX(first, g.r));
  ImageStack adu, valid, weights;
  for (const DetectorFrame& f : sim.frames) {
    adu.push_back(f.adu);
    valid.push_back(f.valid);
    weights.push_back(f.inverse_variance);
  }
  WriteFitsCube(Join(dir, kFramesFile), adu, SimulationHeader(scene, g, "frames", "adu", false, lr_wcs),
                FitsType::kFloat64);
  WriteFitsCube(Join(dir, kValidFile), valid,
                SimulationHeader(scene, g, "valid: 1 usable, 0 bad or saturated", "", false, lr_wcs));
  WriteFitsCube(Join(dir, kWeightsFile), weights, SimulationHeader(scene, g, "inverse variance", "adu-2", false, lr_wcs),
                FitsType::kFloat64);
  WriteFits(Join(dir, kTruthFile), sim.truth, SimulationHeader(scene, g, "truth", "electron", true, hr_wcs),
            FitsType::kFloat64);
  FitsHeader psf = SimulationHeader(scene, g, "psfs: unit sum, HR sampling", "", true);
  WriteFitsCube(Join(dir, kPsfsFile), PerPhase(scene, sim.psfs), psf, FitsType::kFloat64);
  if (scene.sequence.enabled() && scene.ao.mode == AoSpec::Mode::kClosedLoop)  // provenance: each exposure's own
    WriteFitsCube(Join(dir, kExposurePsfsFile), sim.psfs,
                  SimulationHeader(scene, g, "each exposure's psf (closed loop): unit sum, HR sampling", "", true), FitsType::kFloat64);
  if (!sim.truth_frames.empty())
    WriteFitsCube(Join(dir, kTruthFramesFile), sim.truth_frames,
                  SimulationHeader(scene, g, "truth at each exposure's mid-time", "electron", true, hr_wcs), FitsType::kFloat64);
  if (!sim.nominal_psfs.empty())
    WriteFitsCube(Join(dir, kNominalPsfsFile), sim.nominal_psfs,
                  SimulationHeader(scene, g, "nominal psfs (analytic AO): unit sum, HR sampling", "", true), FitsType::kFloat64);
  if (!sim.field_psfs.empty()) {
    // Node-major planes (plane k·N + i: node k, exposure i), each node's position on the HR frame and its
    // direction from the guide star in the header.
    auto field_header = [&](const std::string& what) {
      FitsHeader h = SimulationHeader(scene, g, what, "", true);
      h.Set("FLDNY", static_cast<long long>(sim.field_grid.ny()), "field grid: nodes along y (rows)");
      h.Set("FLDNX", static_cast<long long>(sim.field_grid.nx()), "field grid: nodes along x (columns)");
      h.Set("FLDINTRP", "bilinear", "PSF between nodes (core/psf_field.hpp)");
      h.Set("GSX", scene.psf_field.guide_star_x_arcsec, "[arcsec] guide star x from the frame centre");
      h.Set("GSY", scene.psf_field.guide_star_y_arcsec, "[arcsec] guide star y from the frame centre");
      for (int k = 0; k < sim.field_grid.nodes(); ++k) {
        // Keys of at most 8 characters: a 4-digit node number (at most 33 x 33 = 1089 nodes).
        char digits[8];
        std::snprintf(digits, sizeof digits, "%04d", k % 10000);
        const auto node = sim.field_grid.Node(k);
        h.Set(std::string("FY") + digits, node[0], "[HR px] node y (planes " + std::to_string(k * scene.frames) + "..)");
        h.Set(std::string("FX") + digits, node[1], "[HR px] node x");
        h.Set(std::string("FTX") + digits, sim.field_directions[k].x_rad * kDatasetArcsecPerRad, "[arcsec] x from the guide star");
        h.Set(std::string("FTY") + digits, sim.field_directions[k].y_rad * kDatasetArcsecPerRad, "[arcsec] y from the guide star");
      }
      return h;
    };
    auto flat = [&scene](const std::vector<ImageStack>& nodes) {
      ImageStack planes;
      for (const ImageStack& node : nodes) {
        const ImageStack phases = PerPhase(scene, node);
        planes.insert(planes.end(), phases.begin(), phases.end());
      }
      return planes;
    };
    WriteFitsCube(Join(dir, kFieldPsfsFile), flat(sim.field_psfs),
                  field_header("field psfs: node-major, unit sum, HR sampling"), FitsType::kFloat64);
    if (!sim.field_nominal_psfs.empty())
      WriteFitsCube(Join(dir, kFieldNominalPsfsFile), flat(sim.field_nominal_psfs),
                    field_header("field nominal psfs (analytic AO): node-major, unit sum"), FitsType::kFloat64);
  }
  WriteFitsCube(Join(dir, kExpectedFile), sim.expected_e,
                SimulationHeader(scene, g, "noiseless frames", "electron", false, lr_wcs), FitsType::kFloat64);
  WriteJsonAtomically(manifest, BuildManifest(scene, pipeline, sim, scene_json));
}

std::optional<Wcs> Dataset::HrWcs() const {
  if (!wcs) return std::nullopt;
  const DmOffset first = offsets.empty() ? DmOffset{} : offsets.front();
  return aosr::HrWcs(*wcs, r, ShiftHrY(first, r), ShiftHrX(first, r));
}

void SetHrImageKeywords(const Dataset& dataset, const std::string& bunit, FitsHeader* header) {
  SetImageKeywords(dataset.HrWcs(), bunit, header);
}

ImageStack Dataset::FramesElectrons() const {
  ImageStack out;
  out.reserve(frames.size());
  for (const Image& f : frames) out.push_back((f - bias_adu) * gain_e_per_adu);
  return out;
}

namespace {

// The pixels as a reconstruction takes them, the same for a whole file and for a section: a mask holds 0 and 1
// only; a non-finite frame pixel is invalid and reads the bias (FITS marks bad pixels NaN; solvers multiply data
// by weights, so a NaN would poison them: detector.hpp's dead pixels read the bias for the same reason); weights
// are >= 0 and 0 where invalid. `fail(key, value, allowed)` reports a bad value and does not return.
template <class Fail>
void CleanPixels(double bias_adu, ImageStack* frames, ImageStack valid, std::optional<ImageStack> weights,
                 ImageStack* valid_out, std::optional<ImageStack>* weights_out, const Fail& fail) {
  const std::size_t n = frames->size();
  for (std::size_t i = 0; i < n; ++i)
    if (!((valid[i].array() == 0) || (valid[i].array() == 1)).all())
      fail("valid", "plane " + std::to_string(i) + " holds values other than 0 and 1", "1 (usable) or 0 (not)");
  for (std::size_t i = 0; i < n; ++i) {
    Image& f = (*frames)[i];
    const auto bad = !f.array().isFinite();
    valid[i] = bad.select(0.0, valid[i]);
    f = bad.select(bias_adu, f);
  }
  if (weights) {
    for (std::size_t i = 0; i < n; ++i) {
      if (((*weights)[i].array() < 0).any())
        fail("weights", "negative values in plane " + std::to_string(i), "inverse variances >= 0");
      (*weights)[i] *= valid[i];
    }
  }
  *valid_out = std::move(valid);
  *weights_out = std::move(weights);
}

}  // namespace

DatasetSection ReadDatasetSection(const Dataset& d, Index y0, Index x0, Index rows, Index cols) {
  const char* fn = "ReadDatasetSection";
  CheckArgument(y0 >= 0 && x0 >= 0 && rows >= 1 && cols >= 1 && y0 + rows <= d.frame.rows && x0 + cols <= d.frame.cols,
                fn, "section",
                "rows [" + std::to_string(y0) + ", " + std::to_string(y0 + rows) + ") x cols [" + std::to_string(x0) +
                    ", " + std::to_string(x0 + cols) + ")",
                "inside the frames' " + ToString(d.frame));
  DatasetSection out;
  if (!d.pixel_files) {  // held whole: cut
    auto cut = [&](const ImageStack& a) {
      ImageStack s;
      for (const Image& p : a) s.push_back(p.block(y0, x0, rows, cols));
      return s;
    };
    out.frames = cut(d.frames);
    out.valid = cut(d.valid);
    if (d.weights) out.weights = cut(*d.weights);
    return out;
  }
  const Dataset::PixelFiles& files = *d.pixel_files;
  out.frames = ReadFitsSection(files.frames, y0, x0, rows, cols).planes;
  const std::size_t n = out.frames.size();
  std::optional<ImageStack> weights;
  if (!files.weights.empty()) {
    weights = ReadFitsSection(files.weights, y0, x0, rows, cols).planes;
    for (std::size_t i = 0; i < n; ++i)
      if (!AllFinite((*weights)[i]))
        throw InvalidArgument(files.weights + " (weights of " + d.manifest_path + "): non-finite values in plane " +
                              std::to_string(i) + " of the section; allowed: inverse variances with finite values");
  }
  ImageStack valid = files.valid.empty() ? ImageStack(n, Image::Ones(rows, cols))
                                         : ReadFitsSection(files.valid, y0, x0, rows, cols).planes;
  CleanPixels(d.bias_adu, &out.frames, std::move(valid), std::move(weights), &out.valid, &out.weights,
              [&](const char* key, const std::string& value, const std::string& allowed) -> void {
                throw InvalidArgument(d.manifest_path + ": " + key + " = " + value + " (in the section rows " +
                                      std::to_string(y0) + ".." + std::to_string(y0 + rows - 1) + " x cols " +
                                      std::to_string(x0) + ".." + std::to_string(x0 + cols - 1) + "); allowed: " + allowed);
              });
  return out;
}

namespace {

std::set<fs::path> InputFilesOf(const std::string& manifest_path, const nlohmann::json& manifest) {
  const fs::path m = fs::weakly_canonical(manifest_path);
  std::set<fs::path> in{m};
  if (!manifest.is_object()) return in;
  for (const char* key :
       {"frames", "valid", "weights", "psfs", "nominal_psfs", "truth", "truth_frames", "expected", "scene"})
    if (manifest.contains(key) && manifest[key].is_string()) {
      fs::path p = manifest[key].get<std::string>();
      if (p.is_relative()) p = m.parent_path() / p;
      in.insert(fs::weakly_canonical(p));
    }
  return in;
}

}  // namespace

std::set<fs::path> DatasetInputFiles(const Dataset& d) { return InputFilesOf(d.manifest_path, d.manifest); }

std::set<fs::path> DatasetInputFiles(const std::string& manifest_or_dir) {
  std::error_code ec;
  const std::string path =
      fs::is_directory(manifest_or_dir, ec) ? Join(manifest_or_dir, kManifestFileName) : manifest_or_dir;
  try {
    return InputFilesOf(path, ReadJsonFile(path));
  } catch (const std::exception&) {
    return {};
  }
}

Dataset LoadDataset(const std::string& manifest_or_dir, DatasetPixels pixels) {
  CheckArgument(!manifest_or_dir.empty(), "LoadDataset", "manifest_or_dir", "\"\"", "a manifest.json or its folder");
  std::error_code ec;
  Dataset ds;
  ds.manifest_path = fs::is_directory(manifest_or_dir, ec) ? Join(manifest_or_dir, kManifestFileName) : manifest_or_dir;
  if (!IsRegularFile(ds.manifest_path))
    throw IoError(ds.manifest_path, fs::is_directory(manifest_or_dir, ec) ? "no manifest.json in this folder"
                                                                           : "no such manifest file");
  ds.manifest = ReadJsonFile(ds.manifest_path);
  const ConfigNode root(ds.manifest, ds.manifest_path);

  // ---- Every field first (cheap), so a typo is reported before any cube is read. ----------------------
  const std::string format = root.String("format");
  if (format != kManifestFormat) root.Fail("format", "\"" + format + "\"", std::string("\"") + kManifestFormat + "\"");
  const long long version = root.Integer("version", 0, 1000000);
  if (version != kManifestVersion)
    root.Fail("version", std::to_string(version), std::to_string(kManifestVersion) + " (the version this aosr reads)");
  root.StringOr("software", "");
  if (root.Has("noise")) root.Child("noise");            // provenance, not interpreted
  if (root.Has("simulation")) root.Child("simulation");  // provenance, not interpreted

  const std::string frames_path = FileField(root, "frames");
  const bool has_psfs = root.Has("psfs"), has_scene = root.Has("scene");
  if (has_psfs == has_scene)
    root.Fail(has_psfs ? "scene" : "psfs", has_psfs ? "(both psfs and scene given)" : "(missing)",
              "exactly one of psfs (a PSF cube at HR sampling) and scene (an instrument scene file)");
  const std::string psfs_path = has_psfs ? FileField(root, "psfs") : std::string();
  const std::string scene_path = has_scene ? FileField(root, "scene") : std::string();
  std::optional<SceneSpec> scene;
  if (has_scene) {
    scene = LoadScene(scene_path);  // errors name the scene file and its field
    if (root.Has("offsets"))
      root.Fail("offsets", "(given with scene)", "no offsets: with a scene they are its offsets section");
    ds.r = scene->r;
    if (root.Has("r") && root.Integer("r", 1, 16) != ds.r)
      root.Fail("r", root.json().at("r").dump(), "the scene's r = " + std::to_string(ds.r) + " (or no r)");
    ds.gain_e_per_adu = root.PositiveOr("gain_e_per_adu", scene->detector.gain_e_per_adu);
    ds.bias_adu = root.NumberOr("bias_adu", scene->detector.bias_adu, -1e15, 1e15);
  } else {
    ds.r = int(root.Integer("r", 1, 16));
    ds.gain_e_per_adu = root.Positive("gain_e_per_adu");
    ds.bias_adu = root.Number("bias_adu", -1e15, 1e15);
  }
  const std::string valid_path = root.Has("valid") ? FileField(root, "valid") : std::string();
  const std::string weights_path = root.Has("weights") ? FileField(root, "weights") : std::string();
  const std::string truth_path = root.Has("truth") ? FileField(root, "truth") : std::string();
  const std::string truth_frames_path = root.Has("truth_frames") ? FileField(root, "truth_frames") : std::string();
  const std::string nominal_path = root.Has("nominal_psfs") ? FileField(root, "nominal_psfs") : std::string();
  if (root.Has("expected")) ds.expected_file = FileField(root, "expected");
  std::optional<Shape> frame_shape, hr_shape;
  if (root.Has("frame_shape")) frame_shape = ShapeField(root, "frame_shape");
  if (root.Has("hr_shape")) hr_shape = ShapeField(root, "hr_shape");
  const long long psf_size = root.IntegerOr("psf_size_px", 0, 2, 1 << 20);
  const long long border = root.IntegerOr("trustworthy_border_px", -1, 0, 1 << 20);
  if (root.Has("offsets"))
    for (const ConfigNode& o : root.Array("offsets")) ds.offsets.push_back(ParseOffset(o));
  if (root.Has("stars"))
    for (const ConfigNode& s : root.Array("stars")) ds.stars.push_back(ParseStar(s, ds.r));
  ds.wavelength_m = root.PositiveOr("wavelength_m", scene ? scene->telescope.science_wavelength_m : 0.0);
  ds.camera_pixel_rad = scene ? scene->CameraPixelRad() : 0.0;
  if (root.Has("pixel_scale")) {
    const ConfigNode p = root.Child("pixel_scale");
    const double camera = p.Positive("camera_rad");
    if (scene && !Close(camera, ds.camera_pixel_rad))
      p.Fail("camera_rad", ToString(camera), "the scene's camera pixel, " + ToString(ds.camera_pixel_rad) + " rad");
    ds.camera_pixel_rad = camera;
    const auto check = [&p](const char* key, double expected, const std::string& rule) {
      if (!p.Has(key)) return;
      const double v = p.Positive(key);
      if (!Close(v, expected)) p.Fail(key, ToString(v), ToString(expected) + " (" + rule + ")");
    };
    check("hr_rad", camera / ds.r, "camera_rad / r");
    check("camera_mas", camera / kRadPerMas, "camera_rad in mas");
    check("hr_mas", camera / ds.r / kRadPerMas, "camera_rad / r in mas");
    p.PositiveOr("camera_lambda_over_d", 1.0);  // informational: λ/D needs the telescope
    p.PositiveOr("hr_lambda_over_d", 1.0);
    p.CheckNoOtherFields();
  }
  // The manifest's WCS: FITS keywords, read by the same rules as a header (io/wcs.hpp); null: none.
  const bool wcs_in_manifest = ds.manifest.contains("wcs");
  if (wcs_in_manifest) {
    const nlohmann::json& w = ds.manifest.at("wcs");
    if (w.is_null()) {
      root.StringOr("wcs", "");  // marks the field read: null is a valid value (no WCS)
    } else {
      if (!w.is_object()) root.Fail("wcs", w.dump(), "an object of FITS WCS keywords, or null");
      root.Child("wcs");
      FitsHeader h;
      for (const auto& [key, value] : w.items()) {
        if (key.rfind("comment", 0) == 0) continue;
        try {
          if (value.is_boolean()) h.Set(key, value.get<bool>());
          else if (value.is_number_integer()) h.Set(key, value.get<long long>());
          else if (value.is_number()) h.Set(key, value.get<double>());
          else if (value.is_string()) h.Set(key, value.get<std::string>());
          else root.Fail("wcs." + key, value.dump(), "a number, string or logical (a FITS keyword value)");
        } catch (const InvalidArgument& e) {
          if (std::string(e.what()).rfind("FitsHeader::Set", 0) != 0) throw;
          root.Fail("wcs." + key, value.dump(), std::string("a valid FITS keyword (") + e.what() + ")");
        }
      }
      try {
        ds.wcs = WcsFromHeader(h);
      } catch (const InvalidArgument& e) {
        throw InvalidArgument(ds.manifest_path + ": wcs: " + e.what());
      }
    }
  }
  // The PSF across the field (dataset.hpp): parsed now, its cubes read with the PSFs.
  std::string field_psfs_path, field_nominal_path;
  Shape field_grid{0, 0};
  std::optional<ConfigNode> field_node;
  if (root.Has("psf_field")) {
    field_node.emplace(root.Child("psf_field"));
    const ConfigNode& f = *field_node;
    field_psfs_path = FileField(f, "psfs");
    if (f.Has("nominal_psfs")) field_nominal_path = FileField(f, "nominal_psfs");
    field_grid = ShapeField(f, "grid");
    if (field_grid.rows > 64 || field_grid.cols > 64)
      f.Fail("grid", ToString(field_grid), "[ny, nx] with 1..64 nodes per axis");
    f.ChoiceOr("interpolation", "bilinear", {"bilinear"});
    ds.psf_field.emplace();
    if (f.Has("guide_star_arcsec")) {
      const std::vector<double> g = f.Numbers("guide_star_arcsec", -1e6, 1e6, 2, 2);
      ds.psf_field->guide_star_x_arcsec = g[0];
      ds.psf_field->guide_star_y_arcsec = g[1];
    }
    f.CheckNoOtherFields();
  }
  // A video's sequence (dataset.hpp): slots and times per frame, checked against the frame count below.
  std::vector<long long> seq_slots;
  std::vector<double> seq_times;
  bool has_slots = false;
  std::optional<ConfigNode> seq_node;
  if (root.Has("sequence")) {
    seq_node.emplace(root.Child("sequence"));
    const ConfigNode& q = *seq_node;
    if (q.Has("slots")) {
      has_slots = true;
      const nlohmann::json& a = q.json().at("slots");
      if (!a.is_array() || a.empty()) q.Fail("slots", a.dump(), "an array of one slot per frame");
      for (std::size_t i = 0; i < a.size(); ++i) {
        if (!a[i].is_number_integer() || a[i].get<long long>() < 0 || a[i].get<long long>() > (1 << 20))
          q.Fail("slots", "[" + std::to_string(i) + "] = " + a[i].dump(), "integers >= 0 (the DM phase of each frame)");
        seq_slots.push_back(a[i].get<long long>());
      }
      q.Numbers("slots", 0, double(1 << 20), 1, a.size());  // marks the field read
    }
    if (q.Has("times_s")) {
      seq_times = q.Numbers("times_s", -1e15, 1e15, 1, std::size_t(1) << 40);
      for (std::size_t i = 1; i < seq_times.size(); ++i)
        if (!(seq_times[i] >= seq_times[i - 1]))
          q.Fail("times_s", "[" + std::to_string(i) + "] = " + ToString(seq_times[i]) + " after " + ToString(seq_times[i - 1]),
                 "non-decreasing times (s), one per frame");
    }
    q.CheckNoOtherFields();
  }
  root.CheckNoOtherFields();

  // ---- The frames and the PSFs. --------------------------------------------------------------------------
  std::size_t n = 0;
  {
    // By sections: the header and the shape only (ReadDatasetSection reads the pixels a job needs).
    FitsData frames;
    if (pixels == DatasetPixels::kSections) {
      FitsImageInfo info = ReadFitsInfo(frames_path);
      frames.header = std::move(info.header);
      ds.frame = {info.rows, info.cols};
      n = std::size_t(info.planes);
    } else {
      frames = ReadFits(frames_path);
      ds.frames = std::move(frames.planes);
      ds.frame = ShapeOf(ds.frames.front());
      n = ds.frames.size();
    }
    if (!wcs_in_manifest && HasWcs(frames.header)) {
      try {
        ds.wcs = WcsFromHeader(frames.header);
      } catch (const InvalidArgument& e) {
        throw InvalidArgument(frames_path + " (frames of " + ds.manifest_path + "): " + e.what() +
                              " (a manifest \"wcs\" section replaces it, null ignores it)");
      }
    }
  }
  ds.hr_frame = {ds.frame.rows * ds.r, ds.frame.cols * ds.r};
  // np: the per-phase inputs' count (the slots' range with a sequence's slots, else one per frame).
  std::size_t np = n;
  if (has_slots) {
    if (seq_slots.size() != n)
      seq_node->Fail("slots", std::to_string(seq_slots.size()) + " entries",
                     "one per frame (" + std::to_string(n) + " in " + frames_path + ")");
    np = std::size_t(*std::max_element(seq_slots.begin(), seq_slots.end())) + 1;
    if (scene) np = std::size_t(scene->frames);
  }
  if (!seq_times.empty() && seq_times.size() != n)
    seq_node->Fail("times_s", std::to_string(seq_times.size()) + " entries",
                   "one per frame (" + std::to_string(n) + " in " + frames_path + ")");
  if (frame_shape && *frame_shape != ds.frame)
    root.Fail("frame_shape", ToString(*frame_shape), "the frames' shape " + ToString(ds.frame) + " (" + frames_path + ")");
  if (hr_shape && *hr_shape != ds.hr_frame)
    root.Fail("hr_shape", ToString(*hr_shape), "r x the frames' shape = " + ToString(ds.hr_frame));

  if (scene) {
    if ((!has_slots && scene->frames != int(n)) || scene->frame != ds.frame)
      root.Fail("frames", std::to_string(n) + " x " + ToString(ds.frame) + " (" + frames_path + ")",
                "the scene's frames x frame_px = " + std::to_string(scene->frames) + " x " + ToString(scene->frame) + " (" +
                    scene_path + ")");
    const ScenePipeline pipeline(*scene);
    // A closed-loop instrument cannot say which turbulence the frames saw: its model is the nominal
    // (analytic long-exposure) PSF, not one Monte-Carlo draw.
    ds.psfs = scene->ao.mode == AoSpec::Mode::kClosedLoop ? NominalPsfs(*scene)
                                                          : pipeline.ComputePsfs(nullptr, nullptr, nullptr);
    ds.offsets = scene->offsets.frames;
    ds.trustworthy_border_px = pipeline.geometry().trustworthy_border_px;
    if (scene->psf_field.enabled && !field_node) {
      // The instrument's field-varying model: the scene's PSFs at its field points (nominal for a closed loop).
      ds.psf_field.emplace();
      ds.psf_field->grid = pipeline.field_grid();
      ds.psf_field->psfs = scene->ao.mode == AoSpec::Mode::kClosedLoop ? NominalFieldPsfs(*scene)
                                                                        : pipeline.ComputeFieldPsfs(nullptr);
      ds.psf_field->guide_star_x_arcsec = scene->psf_field.guide_star_x_arcsec;
      ds.psf_field->guide_star_y_arcsec = scene->psf_field.guide_star_y_arcsec;
    }
  } else {
    ImageStack psfs = ReadFits(psfs_path).planes;
    const Shape k = ShapeOf(psfs.front());
    // With a sequence's slots a shared plane serves every slot; the slots may not exceed the planes given.
    if (has_slots && psfs.size() > 1) np = std::max(np, psfs.size());
    if ((psfs.size() != np && psfs.size() != 1) || k.rows != k.cols || k.rows % 2)
      root.Fail("psfs", std::to_string(psfs.size()) + " x " + ToString(k) + " (" + psfs_path + ")",
                std::to_string(np) + (has_slots ? " (one per slot)" : " (one per frame)") +
                    " or 1 (shared) square planes K x K with K even");
    if (psfs.size() == 1) psfs.assign(np, psfs.front());
    ds.psfs = std::move(psfs);
    if (root.Has("offsets") && ds.offsets.size() != np)
      root.Fail("offsets", std::to_string(ds.offsets.size()) + " entries",
                std::string(has_slots ? "one per slot (" : "one per frame (") + std::to_string(np) + ")");
    if (!root.Has("offsets")) ds.offsets.assign(np, DmOffset{});
    ds.trustworthy_border_px = (ds.psf_size() / 2 + ds.r - 1) / ds.r;
  }
  // Unit sum: the forward model conserves flux only with normalised kernels. Negative values (noise in a
  // measured PSF) are kept; a kernel without positive total light is meaningless.
  for (std::size_t i = 0; i < np; ++i) {
    const double sum = ds.psfs[i].sum();
    if (!AllFinite(ds.psfs[i]) || !(sum > 0))
      root.Fail(has_scene ? "scene" : "psfs", "plane " + std::to_string(i) + " with sum " + ToString(sum),
                "PSFs with finite values and a sum > 0");
    ds.psfs[i] /= sum;
  }
  if (!nominal_path.empty()) {
    ImageStack nominal = ReadFits(nominal_path).planes;
    if (nominal.size() != np || ShapeOf(nominal.front()) != ShapeOf(ds.psfs.front()))
      root.Fail("nominal_psfs", std::to_string(nominal.size()) + " x " + ToString(ShapeOf(nominal.front())) + " (" + nominal_path + ")",
                std::to_string(np) + " planes of the PSFs' shape " + ToString(ShapeOf(ds.psfs.front())));
    for (std::size_t i = 0; i < np; ++i) {
      const double sum = nominal[i].sum();
      if (!AllFinite(nominal[i]) || !(sum > 0))
        root.Fail("nominal_psfs", "plane " + std::to_string(i) + " with sum " + ToString(sum), "PSFs with finite values and a sum > 0");
      nominal[i] /= sum;
    }
    ds.nominal_psfs = std::move(nominal);
  }
  if (field_node) {
    // Node-major planes, k·N + i, each of the PSFs' shape, unit sum (as the PSFs).
    const ConfigNode& f = *field_node;
    ds.psf_field->grid = PsfFieldGrid(ds.hr_frame, int(field_grid.rows), int(field_grid.cols), "LoadDataset");
    const std::size_t nodes = std::size_t(ds.psf_field->grid.nodes());
    auto read = [&](const char* key, const std::string& path) {
      const ImageStack planes = ReadFits(path).planes;
      if (planes.size() != nodes * np || ShapeOf(planes.front()) != ShapeOf(ds.psfs.front()))
        f.Fail(key, std::to_string(planes.size()) + " x " + ToString(ShapeOf(planes.front())) + " (" + path + ")",
               std::to_string(nodes * np) + " planes (" + std::to_string(nodes) + " nodes x " + std::to_string(np) +
                   (has_slots ? " slots" : " frames") + ", node-major) of the PSFs' shape " + ToString(ShapeOf(ds.psfs.front())));
      std::vector<ImageStack> out(nodes);
      for (std::size_t p = 0; p < planes.size(); ++p) {
        const double sum = planes[p].sum();
        if (!AllFinite(planes[p]) || !(sum > 0))
          f.Fail(key, "plane " + std::to_string(p) + " with sum " + ToString(sum), "PSFs with finite values and a sum > 0");
        out[p / np].push_back(planes[p] / sum);
      }
      return out;
    };
    ds.psf_field->psfs = read("psfs", field_psfs_path);
    if (!field_nominal_path.empty()) ds.psf_field->nominal_psfs = read("nominal_psfs", field_nominal_path);
  }
  // Slots and times; with a sequence's slots the per-slot inputs become per-frame (frame i gets slot i's).
  if (has_slots) {
    for (std::size_t i = 0; i < n; ++i)
      if (std::size_t(seq_slots[i]) >= np)
        seq_node->Fail("slots", "[" + std::to_string(i) + "] = " + std::to_string(seq_slots[i]),
                       "a slot below the " + std::to_string(np) + " phases " +
                           (scene ? "of the scene (" + scene_path + ")" : "of the psfs (" + psfs_path + ")"));
    ds.slots.assign(seq_slots.begin(), seq_slots.end());
    ds.slot_count = int(np);
    auto expand = [&](auto& v) {
      auto per_slot = v;
      v.clear();
      for (std::size_t i = 0; i < n; ++i) v.push_back(per_slot[std::size_t(ds.slots[i])]);
    };
    expand(ds.psfs);
    expand(ds.offsets);
    if (!ds.nominal_psfs.empty()) expand(ds.nominal_psfs);
    if (ds.psf_field) {
      for (ImageStack& node : ds.psf_field->psfs) expand(node);
      for (ImageStack& node : ds.psf_field->nominal_psfs) expand(node);
    }
  } else {
    for (std::size_t i = 0; i < n; ++i) ds.slots.push_back(int(i));
    ds.slot_count = int(n);
  }
  ds.times_s = seq_times;
  if (psf_size && psf_size != ds.psf_size())
    root.Fail("psf_size_px", std::to_string(psf_size), "the PSFs' side " + std::to_string(ds.psf_size()));
  if (border >= 0) ds.trustworthy_border_px = border;

  // ---- Masks, weights, truth. ----------------------------------------------------------------------------
  if (pixels == DatasetPixels::kSections) {
    // Only that the files are there and of the frames' shape; their values are checked section by section.
    auto check = [&](const char* key, const std::string& path, const char* what) {
      if (path.empty()) return;
      const FitsImageInfo info = ReadFitsInfo(path);
      if (std::size_t(info.planes) != n || info.rows != ds.frame.rows || info.cols != ds.frame.cols)
        root.Fail(key, "a " + std::to_string(info.planes) + " x " + std::to_string(info.rows) + "x" +
                           std::to_string(info.cols) + " cube (" + path + ")",
                  std::string(what) + ": " + std::to_string(n) + " x " + ToString(ds.frame));
    };
    check("valid", valid_path, "masks of the frames' shape");
    check("weights", weights_path, "inverse variances of the frames' shape");
    ds.pixel_files = Dataset::PixelFiles{frames_path, valid_path, weights_path, int(n)};
    if (ds.camera_pixel_rad == 0.0 && scene) ds.camera_pixel_rad = scene->CameraPixelRad();
    return ds;
  }
  {
    std::optional<ImageStack> weights;
    if (!weights_path.empty()) weights = ReadCube(root, "weights", weights_path, n, ds.frame, "inverse variances of the frames' shape");
    CleanPixels(ds.bias_adu, &ds.frames,
                valid_path.empty() ? ImageStack(n, Image::Ones(ds.frame.rows, ds.frame.cols))
                                   : ReadCube(root, "valid", valid_path, n, ds.frame, "masks of the frames' shape"),
                std::move(weights), &ds.valid, &ds.weights,
                [&](const char* key, const std::string& value, const std::string& allowed) { root.Fail(key, value, allowed); });
  }
  if (!truth_path.empty()) ds.truth = ReadCube(root, "truth", truth_path, 1, ds.hr_frame, "one HR image").front();
  if (!truth_frames_path.empty())
    ds.truth_frames = ReadCube(root, "truth_frames", truth_frames_path, n, ds.hr_frame, "one HR image per frame");
  if (ds.camera_pixel_rad == 0.0 && scene) ds.camera_pixel_rad = scene->CameraPixelRad();
  return ds;
}

}  // namespace aosr

namespace aosr {

Dataset SelectFrames(const Dataset& d, const std::vector<int>& frames) {
  constexpr const char* kFn = "SelectFrames";
  CheckArgument(!frames.empty(), kFn, "frames", "[]", "at least one frame index");
  CheckArgument(!d.pixel_files, kFn, "d", "a dataset loaded by sections", "one whose pixels are held (LoadDataset kAll)");
  std::vector<char> seen(d.frames.size(), 0);
  for (int f : frames) {
    CheckArgument(f >= 0 && std::size_t(f) < d.frames.size(), kFn, "frames", f,
                  "an index below the dataset's " + std::to_string(d.frames.size()) + " frames");
    CheckArgument(!seen[std::size_t(f)], kFn, "frames", f, "each frame once");
    seen[std::size_t(f)] = 1;
  }
  Dataset w;
  w.manifest_path = d.manifest_path;
  w.manifest = d.manifest;
  w.r = d.r;
  w.frame = d.frame;
  w.hr_frame = d.hr_frame;
  w.gain_e_per_adu = d.gain_e_per_adu;
  w.bias_adu = d.bias_adu;
  w.truth = d.truth;
  for (int f : frames)
    if (!d.truth_frames.empty()) w.truth_frames.push_back(d.truth_frames[std::size_t(f)]);
  w.expected_file = d.expected_file;
  w.stars = d.stars;
  w.trustworthy_border_px = d.trustworthy_border_px;
  w.camera_pixel_rad = d.camera_pixel_rad;
  w.wavelength_m = d.wavelength_m;
  if (d.weights) w.weights.emplace();
  if (d.psf_field) {
    w.psf_field.emplace(*d.psf_field);
    for (ImageStack& node : w.psf_field->psfs) node.clear();
    for (ImageStack& node : w.psf_field->nominal_psfs) node.clear();
  }
  for (int f : frames) {
    const std::size_t i = std::size_t(f);
    w.frames.push_back(d.frames[i]);
    w.valid.push_back(d.valid[i]);
    if (d.weights) w.weights->push_back((*d.weights)[i]);
    w.psfs.push_back(d.psfs[i]);
    if (!d.nominal_psfs.empty()) w.nominal_psfs.push_back(d.nominal_psfs[i]);
    w.offsets.push_back(i < d.offsets.size() ? d.offsets[i] : DmOffset{});
    if (d.psf_field) {
      for (std::size_t k = 0; k < d.psf_field->psfs.size(); ++k) w.psf_field->psfs[k].push_back(d.psf_field->psfs[k][i]);
      for (std::size_t k = 0; k < d.psf_field->nominal_psfs.size(); ++k)
        w.psf_field->nominal_psfs[k].push_back(d.psf_field->nominal_psfs[k][i]);
    }
    if (!d.times_s.empty()) w.times_s.push_back(d.times_s[i]);
    w.slots.push_back(int(w.slots.size()));
  }
  w.slot_count = int(frames.size());
  // The HR grid stays the dataset's: the camera WCS is re-anchored on the window's first frame, whose DM shift
  // HrWcs takes out again.
  if (const std::optional<Wcs> hr = d.HrWcs()) {
    const DmOffset first = w.offsets.front();
    w.wcs = LrWcs(*hr, d.r, ShiftHrY(first, d.r), ShiftHrX(first, d.r));
  }
  return w;
}

}  // namespace aosr
