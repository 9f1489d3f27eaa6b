#include "aosr/calib/calibration_set.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <random>
#include <set>

#include "aosr/ao/random.hpp"
#include "aosr/core/error.hpp"
#include "aosr/core/memory.hpp"
#include "aosr/io/atomic_file.hpp"
#include "aosr/io/config.hpp"
#include "aosr/io/fits.hpp"
#include "aosr/io/image_io.hpp"
#include "aosr/optics/zernike.hpp"
#include "aosr/scene/detector.hpp"
#include "aosr/scene/telescope.hpp"

namespace aosr {
namespace fs = std::filesystem;

namespace {

std::string FrameName(const CalibrationSet& set, int i) {
  const CalibrationFrame& f = set.frames[i];
  return "frames[" + std::to_string(i) + "]" + (f.file.empty() ? "" : " (" + f.file + ")");
}

std::string ModeName(const CalibrationMode& m) { return m.noll > 0 ? "Z" + std::to_string(m.noll) : m.name; }

}  // namespace

std::vector<int> CalibrationSet::FramesOfMode(int m) const {
  std::vector<int> out;
  for (int i = 0; i < int(frames.size()); ++i)
    if (frames[i].mode == m || (frames[i].mode < 0 && frames[i].reference)) out.push_back(i);
  return out;
}

Image CalibrationSet::ModeShape(int m) const {
  CheckArgument(m >= 0 && m < int(modes.size()), "CalibrationSet::ModeShape", "mode", m,
                "0.." + std::to_string(int(modes.size()) - 1));
  const CalibrationMode& mode = modes[m];
  if (mode.noll > 0) return Zernike(mode.noll, optics.pupil_px, optics.obstruction);
  if (!dm) throw InvalidArgument("CalibrationSet::ModeShape: mode " + mode.name +
                                 " is an actuator pattern, but the telescope preset " + telescope + " has no DM");
  const DeformableMirror mirror(optics.pupil_px, PupilGeometry{diameter_m, optics.obstruction}, *dm);
  CheckArgument(Index(mode.actuator_pattern.size()) == mirror.n_active(), "CalibrationSet::ModeShape",
                "mode " + mode.name + " actuator pattern size", mode.actuator_pattern.size(),
                std::to_string(mirror.n_active()) + " (the DM's active actuators)");
  return mirror.Opd(Eigen::Map<const Vector>(mode.actuator_pattern.data(), Index(mode.actuator_pattern.size())));
}

void ValidateCalibrationSet(CalibrationSet* set) {
  const char* fn = "ValidateCalibrationSet";
  CheckArgument(set != nullptr, fn, "set", "null", "a set");
  std::string why;
  if (!set->optics.IsValid(&why)) throw InvalidArgument(std::string(fn) + ": invalid optics: " + why);
  CheckArgument(!set->frames.empty(), fn, "frames", "none", "at least one frame");
  CheckArgument(!set->modes.empty(), fn, "modes", "none", "at least one poked mode");
  const Shape shape = ShapeOf(set->frames[0].adu);
  CheckArgument(shape.rows >= 8 && shape.cols >= 8, fn, FrameName(*set, 0) + " shape", ToString(shape),
                "at least 8x8 pixels");
  set->masked_pixels = 0;
  for (int i = 0; i < int(set->frames.size()); ++i) {
    CalibrationFrame& f = set->frames[i];
    CheckArgument(ShapeOf(f.adu) == shape, fn, FrameName(*set, i) + " shape", ToString(ShapeOf(f.adu)),
                  ToString(shape) + ", the shape of " + FrameName(*set, 0) + " (all frames must match)");
    if (f.valid.size() == 0) f.valid = Image::Ones(shape.rows, shape.cols);
    CheckArgument(ShapeOf(f.valid) == shape, fn, FrameName(*set, i) + " valid mask shape", ToString(ShapeOf(f.valid)),
                  ToString(shape));
    CheckArgument(f.mode >= -1 && f.mode < int(set->modes.size()), fn, FrameName(*set, i) + " mode", f.mode,
                  "-1 (shared reference) or an index into modes");
    CheckArgument(f.mode >= 0 || f.reference, fn, FrameName(*set, i), "a poked frame without a mode",
                  "a mode, or \"reference\": true");
    CheckArgument(std::isfinite(f.amplitude_m), fn, FrameName(*set, i) + " amplitude", f.amplitude_m, "finite");
    if (f.reference) f.amplitude_m = 0.0;
    Index good = 0;
    for (Index p = 0; p < f.adu.size(); ++p) {
      if (!std::isfinite(f.adu.data()[p])) {
        if (f.valid.data()[p] != 0.0) ++set->masked_pixels;
        f.valid.data()[p] = 0.0;
        f.adu.data()[p] = 0.0;
      }
      f.valid.data()[p] = f.valid.data()[p] != 0.0 ? 1.0 : 0.0;
      if (f.valid.data()[p] != 0.0) ++good;
    }
    CheckArgument(good >= 16, fn, FrameName(*set, i), std::to_string(good) + " valid pixels",
                  "at least 16 valid (finite, not bad) pixels");
  }
  bool shared_reference = false;
  for (const CalibrationFrame& f : set->frames) shared_reference = shared_reference || (f.mode < 0 && f.reference);
  for (int m = 0; m < int(set->modes.size()); ++m) {
    const std::string name = "mode " + ModeName(set->modes[m]);
    int poked = 0, nonzero = 0, refs = 0;
    for (const CalibrationFrame& f : set->frames) {
      if (f.mode != m) continue;
      if (f.reference) ++refs;
      else ++poked, nonzero += f.amplitude_m != 0.0;
    }
    CheckArgument(poked > 0, fn, name, "no poked frames", "at least one frame with a commanded amplitude");
    CheckArgument(nonzero > 0, fn, name, "amplitudes all zero",
                  "at least one non-zero commanded amplitude (the gain is undetermined otherwise)");
    CheckArgument(refs > 0 || shared_reference, fn, name, "no reference (flat) frame",
                  "a reference frame of this mode or a shared one (\"reference\": true)");
    const CalibrationMode& mode = set->modes[m];
    CheckArgument(mode.noll >= 2 || (mode.noll == 0 && !mode.actuator_pattern.empty()), fn, name, mode.noll,
                  "a Noll index >= 2 or an actuator pattern");
    if (mode.noll == 0) (void)set->ModeShape(m);  // checks the DM and the pattern's size
  }
}

// ---------------------------------------------------------------------------------------------------------
// Reading and writing

namespace {

Image ReadFrame(const fs::path& dir, const std::string& file) {
  const fs::path p = fs::path(file).is_absolute() ? fs::path(file) : dir / file;
  return ReadImage(p.string());
}

}  // namespace

CalibrationSet LoadCalibrationSet(const std::string& path) {
  fs::path manifest = path;
  std::error_code ec;  // non-throwing checks: a path the OS refuses (name too long) is "no set here" too
  if (fs::is_directory(manifest, ec)) manifest /= kCalibrationSetFileName;
  const std::string src = manifest.string();
  if (!fs::exists(manifest, ec)) throw IoError(src, "no calibration set here (expected " + std::string(kCalibrationSetFileName) + ")");
  const nlohmann::json json = ReadJsonFile(src);
  const ConfigNode root(json, src);
  const fs::path dir = manifest.has_parent_path() ? manifest.parent_path() : fs::path(".");
  const std::string format = root.String("format");
  if (format != kCalibrationSetFormat) root.Fail("format", format, kCalibrationSetFormat);

  CalibrationSet set;
  set.source = src;
  set.telescope = root.String("telescope");
  std::string telescope_path = set.telescope;
  if (set.telescope.find('/') != std::string::npos && !fs::path(set.telescope).is_absolute() && fs::exists(dir / set.telescope, ec))
    telescope_path = (dir / set.telescope).string();
  const TelescopePreset preset = LoadTelescopePreset(telescope_path);
  set.diameter_m = preset.aperture.pupil.diameter_m;
  set.optics.obstruction = preset.aperture.pupil.obstruction;
  set.optics.wavelength_m = root.PositiveOr("wavelength_m", preset.science_wavelength_m);
  if (root.Has("pixel_lambda_over_d") == root.Has("pixel_rad"))
    root.Fail("pixel_lambda_over_d", "(both or neither of pixel_lambda_over_d and pixel_rad)", "exactly one of them");
  set.optics.pixel_lambda_over_d = root.Has("pixel_rad")
                                       ? root.Positive("pixel_rad") * set.diameter_m / set.optics.wavelength_m
                                       : root.Positive("pixel_lambda_over_d");
  set.optics.pupil_px = root.IntegerOr("pupil_px", 64, 16, 512);
  if (preset.ao) set.dm = preset.ao->dm;
  if (root.Has("detector")) {
    const ConfigNode d = root.Child("detector");
    set.noise.gain_e_per_adu = d.PositiveOr("gain_e_per_adu", 1.0);
    set.noise.read_noise_e = d.NumberOr("read_noise_e", 0.0, 0.0, 1e9);
    set.bias_adu = d.NumberOr("bias_adu", 0.0, -1e12, 1e12);
    d.CheckNoOtherFields();
  }
  Image dark, mask;
  if (root.Has("dark")) dark = ReadFrame(dir, root.String("dark"));
  if (root.Has("bad_pixel_mask")) {
    mask = ReadFrame(dir, root.String("bad_pixel_mask"));
    for (Index p = 0; p < mask.size(); ++p)
      if (mask.data()[p] != 0.0 && mask.data()[p] != 1.0)
        root.Fail("bad_pixel_mask", ToString(mask.data()[p]) + " at pixel " + std::to_string(p), "a mask of 0 (bad) and 1 (good) only");
  }
  std::map<std::string, int> pattern_modes;
  if (root.Has("modes"))
    for (const ConfigNode& m : root.Array("modes")) {
      CalibrationMode mode;
      mode.name = m.String("name");
      mode.actuator_pattern = m.Numbers("actuators", -1e6, 1e6, 1, 100000);
      m.CheckNoOtherFields();
      if (pattern_modes.count(mode.name)) m.Fail("name", mode.name, "a name not used by another mode");
      pattern_modes[mode.name] = int(set.modes.size());
      set.modes.push_back(mode);
    }
  std::map<int, int> zernike_modes;
  for (const ConfigNode& f : root.Array("frames")) {
    CalibrationFrame frame;
    frame.file = f.String("file");
    frame.reference = f.BoolOr("reference", false);
    if (f.Has("mode")) {
      if (f.json()["mode"].is_string()) {
        const std::string name = f.String("mode");
        if (!pattern_modes.count(name)) f.Fail("mode", name, "a Noll index >= 2 or the name of a pattern under \"modes\"");
        frame.mode = pattern_modes[name];
      } else {
        const int j = int(f.Integer("mode", 2, 10000));
        if (!zernike_modes.count(j)) {
          zernike_modes[j] = int(set.modes.size());
          CalibrationMode mode;
          mode.noll = j;
          mode.name = "Z" + std::to_string(j);
          set.modes.push_back(mode);
        }
        frame.mode = zernike_modes[j];
      }
    }
    if (frame.reference) {
      if (f.Has("amplitude_nm") && f.Number("amplitude_nm", -1e9, 1e9) != 0.0)
        f.Fail("amplitude_nm", f.json()["amplitude_nm"].dump(), "0 or absent for a reference frame");
    } else {
      if (!f.Has("mode")) f.Fail("mode", "(missing)", "a mode for a poked frame (or \"reference\": true)");
      frame.amplitude_m = f.Number("amplitude_nm", -1e9, 1e9) * 1e-9;
    }
    f.CheckNoOtherFields();
    frame.adu = ReadFrame(dir, frame.file);
    if (dark.size()) {
      if (ShapeOf(dark) != ShapeOf(frame.adu))
        throw InvalidArgument(src + ": dark is " + ToString(ShapeOf(dark)) + " but frame " + frame.file + " is " +
                              ToString(ShapeOf(frame.adu)) + "; allowed: the frames' shape");
      frame.adu -= dark;
    } else {
      frame.adu -= set.bias_adu;
    }
    if (mask.size()) {
      if (ShapeOf(mask) != ShapeOf(frame.adu))
        throw InvalidArgument(src + ": bad_pixel_mask is " + ToString(ShapeOf(mask)) + " but frame " + frame.file +
                              " is " + ToString(ShapeOf(frame.adu)) + "; allowed: the frames' shape");
      frame.valid = mask;
    }
    set.frames.push_back(std::move(frame));
  }
  if (root.Has("truth")) set.truth = root.json()["truth"], (void)root.Child("truth");
  root.CheckNoOtherFields();
  try {
    ValidateCalibrationSet(&set);
  } catch (const InvalidArgument& e) {
    throw InvalidArgument(src + ": " + e.what());
  }
  return set;
}

std::vector<std::string> CalibrationSetInputFiles(const CalibrationSet& set) {
  if (set.source.empty() || set.source == "<memory>") return {};
  std::vector<std::string> inputs = {set.source};
  const std::filesystem::path dir = std::filesystem::path(set.source).parent_path();
  for (const CalibrationFrame& f : set.frames)
    if (!f.file.empty()) inputs.push_back((dir / f.file).string());
  return inputs;
}

void WriteCalibrationSet(const std::string& dir, const CalibrationSet& set) {
  std::error_code ec;
  fs::create_directories(fs::path(dir) / "frames", ec);
  if (ec) throw IoError(dir, "cannot create the folder: " + ec.message());
  nlohmann::json j;
  j["format"] = kCalibrationSetFormat;
  j["telescope"] = set.telescope;
  j["wavelength_m"] = set.optics.wavelength_m;
  j["pixel_lambda_over_d"] = set.optics.pixel_lambda_over_d;
  j["pupil_px"] = set.optics.pupil_px;
  j["detector"] = {{"gain_e_per_adu", set.noise.gain_e_per_adu}, {"read_noise_e", set.noise.read_noise_e}, {"bias_adu", 0.0}};
  // Pixels masked in any frame go to one shared mask (the format has one mask for the set).
  Image valid = Image::Ones(set.shape().rows, set.shape().cols);
  bool any_masked = false;
  for (const CalibrationFrame& f : set.frames)
    if (f.valid.size()) valid = valid.min(f.valid), any_masked = any_masked || (f.valid == 0.0).any();
  if (any_masked) {
    WriteFits((fs::path(dir) / "valid.fits").string(), valid);
    j["bad_pixel_mask"] = "valid.fits";
  }
  nlohmann::json patterns = nlohmann::json::array();
  for (const CalibrationMode& m : set.modes)
    if (m.noll == 0) patterns.push_back({{"name", m.name}, {"actuators", m.actuator_pattern}});
  if (!patterns.empty()) j["modes"] = patterns;
  j["frames"] = nlohmann::json::array();
  for (int i = 0; i < int(set.frames.size()); ++i) {
    const CalibrationFrame& f = set.frames[i];
    char name[64];
    std::snprintf(name, sizeof name, "frames/%03d.fits", i);
    FitsHeader h;
    h.Set("BUNIT", "ADU", "dark/bias subtracted");
    if (f.mode >= 0) h.Set("CALMODE", ModeName(set.modes[f.mode]));
    h.Set("AMPNM", f.amplitude_m * 1e9, "commanded RMS OPD [nm]");
    Image adu = f.adu;
    if (f.valid.size())
      for (Index p = 0; p < adu.size(); ++p)
        if (f.valid.data()[p] == 0.0) adu.data()[p] = std::numeric_limits<double>::quiet_NaN();
    WriteFits((fs::path(dir) / name).string(), adu, h, FitsType::kFloat64);
    nlohmann::json fj = {{"file", name}};
    if (f.mode >= 0) {
      const CalibrationMode& m = set.modes[f.mode];
      fj["mode"] = m.noll > 0 ? nlohmann::json(m.noll) : nlohmann::json(m.name);
    }
    if (f.reference) fj["reference"] = true;
    else fj["amplitude_nm"] = f.amplitude_m * 1e9;
    j["frames"].push_back(fj);
  }
  if (!set.truth.is_null()) j["truth"] = set.truth;
  const std::string text = j.dump(2) + "\n";
  AtomicWrite((fs::path(dir) / kCalibrationSetFileName).string(), [&](const std::string& tmp) {
    std::ofstream out(tmp);
    out << text;
    if (!out) throw IoError(tmp, "write failed");
  });
}

// ---------------------------------------------------------------------------------------------------------
// Synthetic sets

bool SyntheticCalibrationOptions::IsValid(std::string* why) const {
  auto fail = [why](const std::string& m) {
    if (why) *why = m;
    return false;
  };
  if (!(std::isfinite(pixel_lambda_over_d) && pixel_lambda_over_d > 0)) return fail("pixel_lambda_over_d must be > 0");
  if (pupil_px < 16 || pupil_px > 512) return fail("pupil_px = " + ToString(pupil_px) + "; allowed: 16..512");
  if (window.rows < 8 || window.cols < 8 || window.rows > 1024 || window.cols > 1024)
    return fail("window = " + ToString(window) + "; allowed: sides in [8, 1024]");
  if (modes.empty() && patterns.empty())
    return fail("modes: none; allowed: at least one Noll index >= 2 or actuator pattern");
  std::set<int> seen;
  for (int j : modes) {
    if (j < 2 || j > 1000) return fail("modes: " + ToString(j) + "; allowed: Noll indices in 2..1000");
    if (!seen.insert(j).second) return fail("modes: " + ToString(j) + " twice; allowed: distinct modes");
  }
  std::set<std::string> names;
  for (const CalibrationMode& m : patterns) {
    if (m.noll != 0 || m.name.empty() || m.actuator_pattern.empty())
      return fail("patterns: '" + m.name + "'; allowed: noll 0, a name and a non-empty actuator pattern");
    if (m.name[0] == 'Z' || !names.insert(m.name).second)
      return fail("patterns: name '" + m.name + "'; allowed: distinct names not starting with 'Z'");
    for (double v : m.actuator_pattern)
      if (!std::isfinite(v)) return fail("patterns: " + m.name + " has a non-finite command");
  }
  const std::size_t all_modes = modes.size() + patterns.size();
  if (!gains.empty() && gains.size() != all_modes)
    return fail("gains: " + ToString(gains.size()) + " values; allowed: one per mode and pattern (" + ToString(all_modes) + ") or none");
  for (double g : gains)
    if (!(std::isfinite(g) && g > 0)) return fail("gains: " + ToString(g) + "; allowed: > 0");
  if (amplitudes_m.empty()) return fail("amplitudes: none; allowed: at least one level > 0");
  for (std::size_t k = 0; k < amplitudes_m.size(); ++k)
    if (!(std::isfinite(amplitudes_m[k]) && amplitudes_m[k] > 0 && (k == 0 || amplitudes_m[k] > amplitudes_m[k - 1])))
      return fail("amplitudes: " + ToString(amplitudes_m[k]) + "; allowed: increasing values > 0");
  if (references_per_mode < 0 || shared_references < 0 || references_per_mode + shared_references < 1)
    return fail("references_per_mode + shared_references must be >= 1 (each >= 0)");
  if (static_modes.size() != static_m.size()) return fail("static_modes and static_nm must have the same length");
  for (std::size_t k = 0; k < static_modes.size(); ++k) {
    if (static_modes[k] < 4 || static_modes[k] > 200) return fail("static_modes: " + ToString(static_modes[k]) + "; allowed: 4..200");
    if (!std::isfinite(static_m[k])) return fail("static_nm must be finite");
  }
  if (!(std::isfinite(source_sigma_px) && source_sigma_px >= 0)) return fail("source_sigma_px must be >= 0");
  if (!(std::isfinite(dy_px) && std::isfinite(dx_px) && std::abs(dy_px) < window.rows / 4.0 && std::abs(dx_px) < window.cols / 4.0))
    return fail("position_px must be finite and within a quarter of the window of its centre");
  if (!(std::isfinite(flux_e) && flux_e > 0)) return fail("flux_e must be > 0");
  if (!(std::isfinite(flux_jitter) && flux_jitter >= 0 && flux_jitter < 0.5)) return fail("flux_jitter must be in [0, 0.5)");
  if (!(std::isfinite(background_e) && background_e >= 0)) return fail("background_e must be >= 0");
  if (!(std::isfinite(gain_e_per_adu) && gain_e_per_adu > 0)) return fail("gain_e_per_adu must be > 0");
  if (!(std::isfinite(read_noise_e) && read_noise_e >= 0)) return fail("read_noise_e must be >= 0");
  if (!(std::isfinite(nonlinear_above_m) && nonlinear_above_m >= 0)) return fail("nonlinear_above_nm must be >= 0 (0: none)");
  if (!(std::isfinite(nonlinear_strength) && nonlinear_strength > 0 && nonlinear_strength <= 2))
    return fail("nonlinear_strength must be in (0, 2]");
  if (hot_pixels < 0) return fail("hot_pixels must be >= 0");
  if (oversampling < 0 || oversampling > 8 || padding_px < 0 || padding_px > 256)
    return fail("oversampling in 0..8 and padding_px in 0..256");
  return true;
}

double AppliedAmplitude(double commanded_m, double gain, double nonlinear_above_m, double nonlinear_strength) {
  const double a = std::abs(commanded_m), sign = commanded_m < 0 ? -1.0 : 1.0;
  if (nonlinear_above_m <= 0 || a <= nonlinear_above_m) return gain * commanded_m;
  const double excess = a - nonlinear_above_m;
  const double applied = nonlinear_strength <= 1 ? nonlinear_above_m + (1 - nonlinear_strength) * excess
                                                  : nonlinear_above_m - (nonlinear_strength - 1) * excess;
  return gain * sign * applied;
}

CalibrationSet SynthesizeCalibrationSet(const SyntheticCalibrationOptions& o) {
  std::string why;
  if (!o.IsValid(&why)) throw InvalidArgument("SynthesizeCalibrationSet: invalid options: " + why);
  {
    // Every frame is kept (ADU and its expected image) until the set is returned.
    const double modes = double(o.modes.size() + o.patterns.size());
    const double frames = modes * (2.0 * o.amplitudes_m.size() + o.references_per_mode) + o.shared_references;
    CheckMemory(3 * 8.0 * frames * double(o.window.rows) * double(o.window.cols),
                "SynthesizeCalibrationSet: " + ToString(frames) + " frames of " + ToString(o.window) + " pixels");
  }
  const TelescopePreset preset = LoadTelescopePreset(o.telescope);
  CalibrationSet set;
  set.source = "<memory>";
  set.telescope = o.telescope;
  set.diameter_m = preset.aperture.pupil.diameter_m;
  set.optics.wavelength_m = preset.science_wavelength_m;
  set.optics.pixel_lambda_over_d = o.pixel_lambda_over_d;
  set.optics.obstruction = preset.aperture.pupil.obstruction;
  set.optics.pupil_px = o.pupil_px;
  set.noise.gain_e_per_adu = o.gain_e_per_adu;
  set.noise.read_noise_e = o.read_noise_e;
  if (preset.ao) set.dm = preset.ao->dm;

  DetectorOptions det;
  det.gain_e_per_adu = o.gain_e_per_adu;
  det.enable_photon_noise = o.photon_noise;
  det.enable_read_noise = o.read_noise_e > 0;
  det.read_noise_e = o.read_noise_e;
  det.enable_background = false;  // the background is part of the rendered signal below
  det.enable_dark_current = false;
  det.enable_saturation = false;
  const Detector detector(det);

  NormalGenerator jitter(DeriveSeed(o.seed, 1000001));
  std::uint64_t frame_counter = 0;
  auto record = [&](const ModalImageModel& model, double applied_m, int mode) {
    ModalImageParameters p;
    p.amplitude_m = applied_m;
    p.dy_px = o.dy_px, p.dx_px = o.dx_px;
    p.static_m.assign(o.static_m.begin(), o.static_m.end());
    p.source_sigma_px = o.source_sigma_px;
    p.flux = o.flux_e * std::max(0.05, 1.0 + o.flux_jitter * jitter.Next());
    p.background = o.background_e;
    Image expected = model.Render(p).max(0.0);  // electrons; clip the tapered kernel's ~1e-6 ringing
    const std::uint64_t frame = frame_counter++;
    DetectorFrame rec = detector.Record(expected, o.seed, frame);
    CalibrationFrame f;
    f.mode = mode;
    f.adu = rec.adu;
    f.valid = Image::Ones(expected.rows(), expected.cols());
    if (o.hot_pixels > 0) {
      std::mt19937_64 rng(DeriveSeed(DeriveSeed(o.seed, frame), 7));
      for (int h = 0; h < o.hot_pixels; ++h) {
        const Index r = Index(rng() % std::uint64_t(expected.rows())), c = Index(rng() % std::uint64_t(expected.cols()));
        const double sd = std::sqrt(std::max(1.0, expected(r, c)) / (o.gain_e_per_adu * o.gain_e_per_adu) +
                                    std::pow(o.read_noise_e / o.gain_e_per_adu, 2));
        f.adu(r, c) += 50 * sd;
      }
    }
    return f;
  };

  nlohmann::json truth_modes = nlohmann::json::array();
  if (o.shared_references > 0) {
    const ModalImageModel model(set.optics, Zernike(2, o.pupil_px, set.optics.obstruction), o.static_modes, o.window,
                                o.padding_px, o.oversampling);
    for (int r = 0; r < o.shared_references; ++r) {
      CalibrationFrame f = record(model, 0.0, -1);
      f.reference = true;
      set.frames.push_back(std::move(f));
    }
  }
  for (int j : o.modes) {
    CalibrationMode mode;
    mode.noll = j;
    mode.name = "Z" + std::to_string(j);
    set.modes.push_back(mode);
  }
  set.modes.insert(set.modes.end(), o.patterns.begin(), o.patterns.end());
  for (std::size_t m = 0; m < set.modes.size(); ++m) {
    const CalibrationMode& mode = set.modes[m];
    const double g = o.gains.empty() ? 1.0 : o.gains[m];
    // The mode's OPD per unit amplitude as the fit will model it (Zernike, or the pattern through the DM).
    const ModalImageModel model(set.optics, set.ModeShape(int(m)), o.static_modes, o.window, o.padding_px,
                                o.oversampling);
    for (int r = 0; r < o.references_per_mode; ++r) {
      CalibrationFrame f = record(model, 0.0, int(m));
      f.reference = true;
      set.frames.push_back(std::move(f));
    }
    for (double a : o.amplitudes_m)
      for (double sign : {1.0, -1.0}) {
        const double commanded = sign * a;
        CalibrationFrame f = record(model, AppliedAmplitude(commanded, g, o.nonlinear_above_m, o.nonlinear_strength), int(m));
        f.amplitude_m = commanded;
        set.frames.push_back(std::move(f));
      }
    truth_modes.push_back({{"mode", mode.noll ? nlohmann::json(mode.noll) : nlohmann::json(mode.name)}, {"gain", g}});
  }
  nlohmann::json statics = nlohmann::json::object();
  for (std::size_t k = 0; k < o.static_modes.size(); ++k) statics[std::to_string(o.static_modes[k])] = o.static_m[k] * 1e9;
  set.truth = {{"modes", truth_modes},
               {"static_nm", statics},
               {"source_sigma_px", o.source_sigma_px},
               {"position_px", {o.dy_px, o.dx_px}},
               {"flux_e", o.flux_e},
               {"flux_jitter", o.flux_jitter},
               {"background_e", o.background_e},
               {"nonlinear_above_nm", o.nonlinear_above_m * 1e9},
               {"nonlinear_strength", o.nonlinear_strength},
               {"hot_pixels", o.hot_pixels},
               {"seed", o.seed}};
  ValidateCalibrationSet(&set);
  return set;
}

SyntheticCalibrationOptions LoadSyntheticCalibrationSpec(const std::string& name_or_path) {
  SyntheticCalibrationOptions o;
  const bool looks_like_path = name_or_path.find('/') != std::string::npos || fs::path(name_or_path).extension() == ".json";
  if (!looks_like_path) {
    o.telescope = name_or_path;
    (void)LoadTelescopePreset(o.telescope);  // fail now, naming it, if it does not exist
    return o;
  }
  const nlohmann::json json = ReadJsonFile(name_or_path);
  const ConfigNode root(json, name_or_path);
  if (!root.Has("calibration")) {  // a telescope preset file
    o.telescope = name_or_path;
    (void)LoadTelescopePreset(o.telescope);
    return o;
  }
  const fs::path dir = fs::path(name_or_path).has_parent_path() ? fs::path(name_or_path).parent_path() : fs::path(".");
  (void)root.StringOr("comment", "");
  o.telescope = root.String("telescope");
  if (o.telescope.find('/') != std::string::npos && !fs::path(o.telescope).is_absolute())
    o.telescope = (dir / o.telescope).string();
  const ConfigNode c = root.Child("calibration");
  for (const auto& [key, value] : c.json().items())
    if (key.rfind("comment", 0) == 0) (void)c.StringOr(key, "");
  o.pixel_lambda_over_d = c.PositiveOr("pixel_lambda_over_d", o.pixel_lambda_over_d);
  o.pupil_px = c.IntegerOr("pupil_px", o.pupil_px, 16, 512);
  if (c.Has("window_px")) {
    const auto w = c.Numbers("window_px", 8, 1024, 2, 2);
    o.window = {Index(w[0]), Index(w[1])};
  }
  if (c.Has("modes")) {
    o.modes.clear();
    for (double j : c.Numbers("modes", 2, 1000, 0, 1000)) o.modes.push_back(int(j));
  }
  if (c.Has("patterns")) {
    for (const ConfigNode& m : c.Array("patterns")) {
      CalibrationMode mode;
      mode.name = m.String("name");
      mode.actuator_pattern = m.Numbers("actuators", -1e6, 1e6, 1, 100000);
      m.CheckNoOtherFields();
      o.patterns.push_back(std::move(mode));
    }
  }
  if (c.Has("gains")) o.gains = c.Numbers("gains", 1e-6, 1e6, 1, 1000);
  if (c.Has("amplitudes_nm")) {
    o.amplitudes_m = c.Numbers("amplitudes_nm", 1e-6, 1e6, 1, 1000);
    for (double& a : o.amplitudes_m) a *= 1e-9;
  }
  o.references_per_mode = int(c.IntegerOr("references_per_mode", o.references_per_mode, 0, 1000));
  o.shared_references = int(c.IntegerOr("shared_references", o.shared_references, 0, 1000));
  if (c.Has("static_nm")) {
    const ConfigNode s = c.Child("static_nm");
    o.static_modes.clear();
    o.static_m.clear();
    for (const auto& [key, value] : s.json().items()) {
      int j = 0;
      try {
        j = std::stoi(key);
      } catch (const std::exception&) {
        s.Fail(key, key, "Noll indices (>= 4) as keys");
      }
      o.static_modes.push_back(j);
      o.static_m.push_back(s.Number(key, -1e6, 1e6) * 1e-9);
    }
    s.CheckNoOtherFields();
  }
  o.source_sigma_px = c.NumberOr("source_sigma_px", o.source_sigma_px, 0, 100);
  if (c.Has("position_px")) {
    const auto p = c.Numbers("position_px", -1000, 1000, 2, 2);
    o.dy_px = p[0], o.dx_px = p[1];
  }
  o.flux_e = c.PositiveOr("flux_e", o.flux_e);
  o.flux_jitter = c.NumberOr("flux_jitter", o.flux_jitter, 0, 0.499);
  o.background_e = c.NumberOr("background_e", o.background_e, 0, 1e12);
  o.gain_e_per_adu = c.PositiveOr("gain_e_per_adu", o.gain_e_per_adu);
  o.read_noise_e = c.NumberOr("read_noise_e", o.read_noise_e, 0, 1e9);
  o.photon_noise = c.BoolOr("photon_noise", o.photon_noise);
  o.nonlinear_above_m = c.NumberOr("nonlinear_above_nm", 0.0, 0, 1e9) * 1e-9;
  o.nonlinear_strength = c.NumberOr("nonlinear_strength", o.nonlinear_strength, 1e-6, 2);
  o.hot_pixels = int(c.IntegerOr("hot_pixels", o.hot_pixels, 0, 1000000));
  o.seed = std::uint64_t(c.IntegerOr("seed", std::int64_t(o.seed), 0, std::numeric_limits<std::int64_t>::max()));
  c.CheckNoOtherFields();
  root.CheckNoOtherFields();
  std::string why;
  if (!o.IsValid(&why)) throw InvalidArgument(name_or_path + ": calibration: " + why);
  return o;
}

}  // namespace aosr
