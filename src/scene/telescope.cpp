#include "aosr/scene/telescope.hpp"

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <mutex>

#include "aosr/core/error.hpp"
#include "aosr/io/config.hpp"
#include "aosr/io/image_io.hpp"

namespace aosr {
namespace {

constexpr double kDeg = M_PI / 180.0;
constexpr double kMas = M_PI / 180.0 / 3600.0 / 1000.0;

AtmosphereOptions ParseAtmosphere(const ConfigNode& n) {
  AtmosphereOptions a;
  a.r0_m = n.Positive("r0_m");
  a.r0_wavelength_m = n.PositiveOr("r0_wavelength_m", 500e-9);
  a.L0_m = n.Positive("L0_m");
  a.seed = static_cast<std::uint64_t>(n.IntegerOr("seed", 1, 0, (1LL << 62)));
  for (const ConfigNode& l : n.Array("layers")) {
    Layer layer;
    layer.altitude_m = l.NumberOr("altitude_m", 0.0, 0.0, 1e5);
    layer.cn2_fraction = l.Number("cn2_fraction", 0.0, 1.0);
    layer.wind_speed_mps = l.NumberOr("wind_speed_mps", 0.0, 0.0, 200.0);
    layer.wind_direction_rad = l.NumberOr("wind_direction_deg", 0.0, -360.0, 360.0) * kDeg;
    l.CheckNoOtherFields();
    a.layers.push_back(layer);
  }
  n.CheckNoOtherFields();
  std::string why;
  if (!a.IsValid(&why)) n.Fail("", "(inconsistent)", why);
  return a;
}

AoPreset ParseAo(const ConfigNode& n, double diameter_m) {
  AoPreset ao;
  const ConfigNode dm = n.Child("dm");
  ao.dm.actuators_across = int(dm.Integer("actuators_across", 2, 200));
  ao.dm.pitch_m = dm.PositiveOr("pitch_m", diameter_m / (ao.dm.actuators_across - 1));
  ao.dm.coupling = dm.NumberOr("coupling", ao.dm.coupling, 1e-6, 0.9);
  ao.dm.stroke_m = dm.PositiveOr("stroke_m", ao.dm.stroke_m);
  dm.CheckNoOtherFields();
  const ConfigNode wfs = n.Child("wfs");
  ao.wfs.lenslets_across = int(wfs.Integer("lenslets_across", 1, 200));
  ao.wfs.wavelength_m = wfs.Positive("wavelength_m");
  ao.wfs.guide_star_magnitude = wfs.NumberOr("guide_star_magnitude", ao.wfs.guide_star_magnitude, -5.0, 25.0);
  ao.wfs.throughput = wfs.NumberOr("throughput", ao.wfs.throughput, 1e-6, 1.0);
  ao.wfs.pixel_scale_lod = wfs.NumberOr("pixel_scale_lod", ao.wfs.pixel_scale_lod, 0.05, 5.0);
  ao.wfs.field_of_view_px = int(wfs.IntegerOr("field_of_view_px", ao.wfs.field_of_view_px, 4, 256));
  ao.wfs.photon_noise = wfs.BoolOr("photon_noise", ao.wfs.photon_noise);
  ao.wfs.read_noise_e = wfs.NumberOr("read_noise_e", ao.wfs.read_noise_e, 0.0, 1000.0);
  wfs.CheckNoOtherFields();
  const ConfigNode loop = n.Child("loop");
  ao.loop.rate_hz = loop.Positive("rate_hz");
  ao.loop.gain = loop.Number("gain", 0.0, 2.0);
  ao.loop.delay_frames = loop.NumberOr("delay_frames", ao.loop.delay_frames, 0.0, 10.0);
  ao.loop.control = loop.ChoiceOr("control", ao.loop.control, {"integrator", "pol"});
  loop.CheckNoOtherFields();
  n.CheckNoOtherFields();
  std::string why;
  if (!ao.dm.IsValid(&why)) dm.Fail("", "(inconsistent)", why);
  return ao;
}

}  // namespace

AnalyticAoOptions TelescopePreset::ToAnalyticAo() const {
  if (!atmosphere || !ao)
    throw InvalidArgument(source + ": the analytic AO model needs both \"atmosphere\" and \"ao\" sections");
  AnalyticAoOptions o;
  o.diameter_m = aperture.pupil.diameter_m;
  o.actuator_pitch_m = ao->dm.pitch_m;
  o.r0_m = atmosphere->r0_m;
  o.reference_wavelength_m = atmosphere->r0_wavelength_m;
  o.outer_scale_m = atmosphere->L0_m;
  o.layers = atmosphere->layers;
  o.loop_rate_hz = ao->loop.rate_hz;
  o.loop_gain = ao->loop.gain;
  o.loop_delay_frames = ao->loop.delay_frames;
  o.science_wavelength_m = science_wavelength_m;
  if (ao->wfs.photon_noise || ao->wfs.read_noise_e > 0) {
    // A noisy (diffractive) Shack-Hartmann: the noise term measured through this very sensor, centroiding and
    // reconstructor (ao_system.hpp MeasureWfsNoiseRad2), on spots as wide as the turbulence's fitting residual
    // makes them. The loop's delay plays no part in it, so a fractional delay (which only the analytic model
    // takes) is rounded for the build.
    TelescopePreset noise_system = *this;
    noise_system.ao->loop.delay_frames = std::round(ao->loop.delay_frames);
    AoSystemSpec spec = noise_system.ToAoSystemSpec(SensorKind::kDiffractive, kWfsNoiseSeed);
    AoSystem system = BuildAoSystem(spec);
    o.wfs_noise_rad2 = MeasureWfsNoiseRad2(system, o.reference_wavelength_m, kWfsNoiseSamples);
  }
  return o;
}

Image TelescopePreset::PupilAmplitude() const {
  if (mask_file.empty()) return Aperture(pupil_px, aperture);
  return ResampleMask(ReadImage(mask_file), pupil_px);
}

AoSystemSpec TelescopePreset::ToAoSystemSpec(SensorKind sensor, std::uint64_t seed) const {
  if (!ao) throw InvalidArgument(source + ": a closed loop needs an \"ao\" section");
  AoSystemSpec s;
  s.amplitude = PupilAmplitude();
  s.diameter_m = aperture.pupil.diameter_m;
  s.dm = ao->dm;
  if (atmosphere) {
    s.atmosphere = *atmosphere;
    s.atmosphere->seed = seed;
  }
  s.sensor = sensor;
  s.wfs.subapertures_across = ao->wfs.lenslets_across;
  s.wfs.wavelength_m = ao->wfs.wavelength_m;
  s.wfs.pixel_scale_lod = ao->wfs.pixel_scale_lod;
  s.wfs.field_of_view_px = ao->wfs.field_of_view_px;
  s.wfs.noise.photon_noise = ao->wfs.photon_noise;
  s.wfs.noise.guide_star_magnitude = ao->wfs.guide_star_magnitude;
  s.wfs.noise.throughput = ao->wfs.throughput;
  s.wfs.noise.read_noise_e = ao->wfs.read_noise_e;
  s.wfs.noise.seed = seed;
  s.control.loop_rate_hz = ao->loop.rate_hz;
  s.control.gain = ao->loop.gain;
  const double whole = std::round(ao->loop.delay_frames);
  if (std::abs(whole - ao->loop.delay_frames) > 1e-9)
    throw InvalidArgument(source + ": ao.loop.delay_frames = " + ToString(ao->loop.delay_frames) +
                          "; allowed: a whole number of frames for the closed loop (the analytic model takes fractions)");
  s.control.delay_frames = int(whole);
  s.control.law = ao->loop.control == "pol" ? ControlLaw::kPseudoOpenLoop : ControlLaw::kIntegrator;
  return s;
}

namespace {

std::mutex& DataDirectoryMutex() {
  static std::mutex m;
  return m;
}
std::string& DefaultDataDirectory() {
  static std::string dir = AOSR_DEFAULT_DATA_DIR;
  return dir;
}

}  // namespace

std::string DataDirectory() {
  if (const char* env = std::getenv("AOSR_DATA_DIR"); env && *env) return env;
  std::lock_guard<std::mutex> lock(DataDirectoryMutex());
  return DefaultDataDirectory();
}

void SetDefaultDataDirectory(const std::string& dir) {
  CheckArgument(!dir.empty(), "SetDefaultDataDirectory", "dir", "(empty)", "a folder path");
  std::lock_guard<std::mutex> lock(DataDirectoryMutex());
  DefaultDataDirectory() = dir;
}

TelescopePreset ParseTelescopePreset(const nlohmann::json& json, const std::string& source) {
  const ConfigNode root(json, source);
  TelescopePreset p;
  p.source = source;
  p.name = root.String("name");
  const ConfigNode tel = root.Child("telescope");
  p.aperture.pupil.diameter_m = tel.Positive("diameter_m");
  p.aperture.pupil.obstruction = tel.NumberOr("obstruction", 0.0, 0.0, 0.95);
  p.pupil_px = tel.IntegerOr("pupil_px", 128, 32, 2048);
  const double focal_length = tel.PositiveOr("focal_length_m", 0.0);
  if (tel.Has("spiders")) {
    const ConfigNode s = tel.Child("spiders");
    p.aperture.spiders.count = int(s.Integer("count", 0, 12));
    p.aperture.spiders.width_m = s.Positive("width_m");
    p.aperture.spiders.angle_offset_rad = s.NumberOr("angle_deg", 0.0, -360.0, 360.0) * kDeg;
    s.CheckNoOtherFields();
  }
  if (tel.Has("segments")) {
    const ConfigNode g = tel.Child("segments");
    p.aperture.outline = ApertureOutline::kHexSegments;
    p.aperture.segments.rings = int(g.Integer("rings", 1, 20));
    p.aperture.segments.flat_to_flat_m = g.Positive("flat_to_flat_m");
    p.aperture.segments.gap_m = g.NumberOr("gap_m", 0.0, 0.0, 1.0);
    p.aperture.segments.central_segment = g.BoolOr("central_segment", true);
    p.aperture.segments.rotation_rad = g.NumberOr("rotation_deg", 0.0, -360.0, 360.0) * kDeg;
    g.CheckNoOtherFields();
  }
  if (tel.Has("mask_file")) {
    const std::filesystem::path f(tel.String("mask_file"));
    p.mask_file = (f.is_absolute() ? f : std::filesystem::path(source).parent_path() / f).string();
    std::error_code ec;  // the non-throwing form: a name too long for the OS is "not an existing file" too
    if (!std::filesystem::exists(p.mask_file, ec)) tel.Fail("mask_file", "\"" + p.mask_file + "\"", "an existing image file");
  }
  tel.CheckNoOtherFields();
  std::string why;
  if (!p.aperture.IsValid(&why)) tel.Fail("", "(inconsistent)", why);

  const ConfigNode sci = root.Child("science");
  p.science_wavelength_m = sci.Positive("wavelength_m");
  const int given = int(sci.Has("camera_pixel_lambda_over_d")) + int(sci.Has("camera_pixel_mas")) +
                    int(sci.Has("camera_pixel_m"));
  if (given != 1)
    sci.Fail("camera_pixel_*", std::to_string(given) + " given",
             "exactly one of camera_pixel_lambda_over_d, camera_pixel_mas, camera_pixel_m");
  if (sci.Has("camera_pixel_lambda_over_d")) {
    p.camera_pixel_rad = sci.Positive("camera_pixel_lambda_over_d") * p.LambdaOverD();
  } else if (sci.Has("camera_pixel_mas")) {
    p.camera_pixel_rad = sci.Positive("camera_pixel_mas") * kMas;
  } else {
    const double pixel_m = sci.Positive("camera_pixel_m");
    if (focal_length <= 0) tel.Fail("focal_length_m", "(missing)", "a focal length > 0 when camera_pixel_m is used");
    p.camera_pixel_rad = pixel_m / focal_length;
  }
  sci.CheckNoOtherFields();
  if (root.Has("atmosphere")) p.atmosphere = ParseAtmosphere(root.Child("atmosphere"));
  if (root.Has("ao")) p.ao = ParseAo(root.Child("ao"), p.aperture.pupil.diameter_m);
  root.CheckNoOtherFields();
  return p;
}

TelescopePreset LoadTelescopePreset(const std::string& name_or_path) {
  namespace fs = std::filesystem;
  std::string path = name_or_path;
  const bool looks_like_path = name_or_path.find('/') != std::string::npos ||
                               fs::path(name_or_path).extension() == ".json";
  if (!looks_like_path) {
    path = (fs::path(DataDirectory()) / "telescopes" / (name_or_path + ".json")).string();
    std::error_code ec;  // the non-throwing form: a name too long for the OS is "no such preset" too
    if (!fs::exists(path, ec)) {
      std::string names;
      for (const auto& e : fs::directory_iterator(fs::path(DataDirectory()) / "telescopes", ec))
        if (e.path().extension() == ".json") names += (names.empty() ? "" : ", ") + e.path().stem().string();
      throw InvalidArgument("LoadTelescopePreset", "preset", name_or_path,
                            names.empty() ? "a .json path (no presets found in " + DataDirectory() + ")" : names);
    }
  }
  return ParseTelescopePreset(ReadJsonFile(path), path);
}

}  // namespace aosr
