#include "aosr/scene/scene_spec.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>

#include "aosr/ao/anisoplanatism.hpp"
#include "aosr/ao/random.hpp"
#include "aosr/core/error.hpp"
#include "aosr/io/config.hpp"
#include "aosr/io/image_io.hpp"
#include "aosr/scene/preset_psf.hpp"
#include "aosr/scene/raster.hpp"

namespace aosr {
namespace {

namespace fs = std::filesystem;

// fs::is_regular_file without the exception: a path the OS refuses to look up (a name longer than NAME_MAX,
// found by fuzz/scene_fuzz.cpp) is "not an existing file", reported by the caller with the field's name.
bool IsRegularFile(const std::string& path) {
  std::error_code ec;
  return fs::is_regular_file(path, ec);
}

constexpr long long kMaxSeed = (1LL << 62);
constexpr double kNm = 1e-9;
constexpr double kSceneArcsecPerRad = 180.0 * 3600.0 / M_PI;
// Default PSF window: 32 λ/D across (16 λ/D radius) holds the diffraction core, the AO-corrected region
// (control radius D/(2d) = 8 λ/D for the paper's 17×17 DM) and the start of the fitting halo.
constexpr double kDefaultPsfWindowLod = 32.0;

// Seed streams derived from the scene's seed (ao/random.hpp): each effect has its own, so enabling one
// never changes another's random numbers.
enum SeedStream : std::uint64_t { kNoiseStream = 1, kAtmosphereStream = 2, kBadPixelStream = 3, kObjectStream = 100 };

std::string ResolvePath(const std::string& source, const std::string& file) {
  const fs::path f(file);
  if (f.is_absolute()) return f.string();
  return (fs::path(source).parent_path() / f).string();
}

std::uint64_t SeedOr(const ConfigNode& n, std::uint64_t fallback) {
  return static_cast<std::uint64_t>(n.IntegerOr("seed", static_cast<long long>(fallback & (kMaxSeed - 1)), 0, kMaxSeed));
}

// A [lo, hi] pair with 0 < lo <= hi (or lo < hi when strict).
std::pair<double, double> Range(const ConfigNode& n, const std::string& key, double lo, double hi, bool strict) {
  const std::vector<double> v = n.Numbers(key, lo, hi, 2, 2);
  if (strict ? !(v[0] < v[1]) : !(v[0] <= v[1]))
    n.Fail(key, "[" + ToString(v[0]) + ", " + ToString(v[1]) + "]",
           strict ? "[low, high] with low < high" : "[low, high] with low <= high");
  return {v[0], v[1]};
}

FluxSpec ParseFlux(const ConfigNode& object) {
  FluxSpec f;
  if (!object.Has("flux")) {
    object.NumberOr("flux", 0, 0, 0);  // marks the key read when it is explicitly null
    return f;
  }
  const ConfigNode n = object.Child("flux");
  const int given = int(n.Has("total_e")) + int(n.Has("peak_e")) + int(n.Has("magnitude"));
  if (given != 1) n.Fail("", std::to_string(given) + " of total_e, peak_e, magnitude", "exactly one of them");
  if (n.Has("total_e")) {
    f.kind = FluxSpec::Kind::kTotalElectrons;
    f.value = n.Positive("total_e");
  } else if (n.Has("peak_e")) {
    f.kind = FluxSpec::Kind::kPeakElectrons;
    f.value = n.Positive("peak_e");
  } else {
    f.kind = FluxSpec::Kind::kMagnitude;
    f.value = n.Number("magnitude", -30.0, 50.0);
  }
  n.CheckNoOtherFields();
  return f;
}

template <typename Options>
void CheckOptions(const ConfigNode& n, const Options& o) {
  std::string why;
  if (!o.IsValid(&why)) n.Fail("", "(inconsistent)", why);
}

ObjectVariation ParseVariation(const ConfigNode& n) {
  ObjectVariation v;
  if (n.Has("velocity_px_per_s")) {  // camera pixels per second, [v_y, v_x]
    const std::vector<double> a = n.Numbers("velocity_px_per_s", -1e6, 1e6, 2, 2);
    v.velocity_y_px_per_s = a[0];
    v.velocity_x_px_per_s = a[1];
  }
  if (n.Has("light_curve")) {
    const ConfigNode c = n.Child("light_curve");
    const std::string kind = c.Choice("kind", {"sine", "table"});
    if (kind == "sine") {
      v.curve = ObjectVariation::Curve::kSine;
      v.period_s = c.Number("period_s", 1e-9, 1e12);
      v.amplitude = c.Number("amplitude", 0.0, 1.0);  // a flux never negative: |a| <= 1
      v.phase_deg = c.NumberOr("phase_deg", 0.0, -360.0, 360.0);
    } else {
      v.curve = ObjectVariation::Curve::kTable;
      v.times_s = c.Numbers("times_s", -1e12, 1e12, 1, 100000);
      v.factors = c.Numbers("factors", 0.0, 1e12, 1, 100000);
      if (v.factors.size() != v.times_s.size())
        c.Fail("factors", std::to_string(v.factors.size()) + " entries", "one per time (" + std::to_string(v.times_s.size()) + ")");
      for (std::size_t i = 1; i < v.times_s.size(); ++i)
        if (!(v.times_s[i] > v.times_s[i - 1]))
          c.Fail("times_s", "[" + std::to_string(i) + "] = " + ToString(v.times_s[i]) + " after " + ToString(v.times_s[i - 1]),
                 "increasing times");
    }
    c.CheckNoOtherFields();
  }
  n.CheckNoOtherFields();
  return v;
}

ObjectSpec ParseObject(const ConfigNode& n, const SceneSpec& scene, std::size_t index, bool* needs_magnitudes) {
  ObjectSpec o;
  o.type = n.Choice("type", {"usaf", "demo", "stars", "galaxies", "dead-leaves", "image", "slanted-edge", "planet"});
  o.flux = ParseFlux(n);
  o.seed = SeedOr(n, DeriveSeed(scene.seed, kObjectStream + index));
  if (o.flux.kind == FluxSpec::Kind::kMagnitude) *needs_magnitudes = true;
  if (n.Has("variation")) {
    if (!scene.sequence.enabled())
      n.Fail("variation", "(given)", "a variation only in a scene with a \"sequence\" section (objects change in time only there)");
    o.variation = ParseVariation(n.Child("variation"));
  }
  if (o.type == "planet") {
    o.kind = ObjectSpec::Kind::kPlanet;
    PlanetOptions& p = o.planet;
    // Camera pixels here; the pipeline converts them to HR pixels.
    p.radius_px = n.Number("radius_px", 1e-3, 1e5);
    if (n.Has("centre_px")) {
      const std::vector<double> c = n.Numbers("centre_px", -1e6, 1e6, 2, 2);
      p.centre_y = c[0];
      p.centre_x = c[1];
    }
    p.rotation_period_s = n.NumberOr("rotation_period_s", 0.0, -1e12, 1e12);
    if (p.rotation_period_s != 0.0 && std::abs(p.rotation_period_s) < 1e-9)
      n.Fail("rotation_period_s", ToString(p.rotation_period_s), "0 (no rotation) or |period| >= 1e-9 s");
    p.pole_angle_deg = n.NumberOr("pole_angle_deg", 0.0, -360.0, 360.0);
    p.sub_observer_latitude_deg = n.NumberOr("sub_observer_latitude_deg", 0.0, -90.0, 90.0);
    p.longitude0_deg = n.NumberOr("longitude0_deg", 0.0, -360.0, 360.0);
    p.limb_darkening = n.NumberOr("limb_darkening", 0.0, 0.0, 1.0);
    p.supersample = int(n.IntegerOr("supersample", p.supersample, 1, 16));
    if (n.Has("texture") && n.Has("texture_path")) n.Fail("texture", "(both given)", "one of texture and texture_path");
    if (n.Has("texture_path")) {
      o.texture_path = ResolvePath(scene.source, n.String("texture_path"));
      if (!IsRegularFile(o.texture_path)) n.Fail("texture_path", "\"" + o.texture_path + "\"", "an existing FITS/PNG/TIFF file");
    }
    if (n.Has("texture")) {
      const ConfigNode t = n.Child("texture");
      PlanetTextureOptions& x = o.planet_texture;
      x.bands = int(t.IntegerOr("bands", x.bands, 0, 64));
      x.band_contrast = t.NumberOr("band_contrast", x.band_contrast, 0.0, 0.99);
      x.spots = int(t.IntegerOr("spots", x.spots, 0, 1000));
      x.spot_radius_deg = t.NumberOr("spot_radius_deg", x.spot_radius_deg, 0.1, 90.0);
      x.spot_contrast = t.NumberOr("spot_contrast", x.spot_contrast, 0.0, 100.0);
      t.CheckNoOtherFields();
    }
  } else if (o.type == "usaf") {
    o.kind = ObjectSpec::Kind::kUsaf;
    o.usaf_fill = n.NumberOr("fill", o.usaf_fill, 1e-3, 1.0);
    o.usaf.first_group = int(n.IntegerOr("first_group", o.usaf.first_group, -10, 12));
    o.usaf.last_group = int(n.IntegerOr("last_group", o.usaf.last_group, -10, 12));
    o.usaf.background = n.NumberOr("background", o.usaf.background, -1e30, 1e30);
    o.usaf.bar_value = n.NumberOr("bar", o.usaf.bar_value, -1e30, 1e30);
    o.usaf.supersample = int(n.IntegerOr("supersample", o.usaf.supersample, 0, 64));
    o.usaf.rotation_deg = n.NumberOr("rotation_deg", o.usaf.rotation_deg, -45.0, 45.0);
    CheckOptions(n, o.usaf);
  } else if (o.type == "slanted-edge") {
    o.kind = ObjectSpec::Kind::kSlantedEdge;
    SlantedEdgeTargetOptions& e = o.slanted_edge;
    e.angle_deg = n.NumberOr("angle_deg", e.angle_deg, -180.0, 180.0);
    e.low = n.NumberOr("low", e.low, -1e30, 1e30);
    e.high = n.NumberOr("high", e.high, -1e30, 1e30);
    if (n.Has("centre_px")) {  // camera pixels of the frame: [y, x]
      const std::vector<double> c = n.Numbers("centre_px", -1e6, 1e6, 2, 2);
      e.centre_y = c[0];
      e.centre_x = c[1];
    }
    CheckOptions(n, e);
  } else if (o.type == "demo") {
    o.kind = ObjectSpec::Kind::kDemo;
    // DemoObject draws its bars and stars on at least 64 x 64 HR pixels (objects.hpp).
    if (scene.HrFrame().rows < 64 || scene.HrFrame().cols < 64)
      n.Fail("type", "demo", "an HR frame (r * frame_px) of at least 64 x 64 pixels for the demo object; here " +
                                 ToString(scene.HrFrame()));
  } else if (o.type == "stars") {
    o.kind = ObjectSpec::Kind::kStars;
    if (n.Has("catalogue")) {
      for (const ConfigNode& s : n.Array("catalogue")) {
        PointSource p;
        p.y = s.Number("y_px", -0.5, double(scene.frame.rows) - 0.5);
        p.x = s.Number("x_px", -0.5, double(scene.frame.cols) - 0.5);
        const int given = int(s.Has("flux_e")) + int(s.Has("magnitude"));
        if (given != 1) s.Fail("", std::to_string(given) + " of flux_e, magnitude", "exactly one of them");
        if (s.Has("flux_e")) {
          p.flux = s.Number("flux_e", 0.0, 1e30);
        } else {
          p.flux = scene.ElectronsPerFrameForMagnitude(s.Number("magnitude", -30.0, 50.0));
          o.star_magnitudes = true;
        }
        s.CheckNoOtherFields();
        o.catalogue.push_back(p);
      }
      if (o.catalogue.empty()) n.Fail("catalogue", "[]", "at least one source");
    } else {
      o.stars.count = int(n.Integer("count", 1, 10000000));
      o.stars.luminosity.alpha = n.NumberOr("alpha", o.stars.luminosity.alpha, 0.0, 5.0);
      const int given = int(n.Has("flux_range_e")) + int(n.Has("magnitude_range"));
      if (given > 1) n.Fail("flux_range_e", "(both given)", "one of flux_range_e and magnitude_range");
      if (n.Has("magnitude_range")) {
        const auto [bright, faint] = Range(n, "magnitude_range", -30.0, 50.0, true);
        o.stars.luminosity.flux_min = scene.ElectronsPerFrameForMagnitude(faint);
        o.stars.luminosity.flux_max = scene.ElectronsPerFrameForMagnitude(bright);
        o.star_magnitudes = true;
      } else if (n.Has("flux_range_e")) {
        const auto [lo, hi] = Range(n, "flux_range_e", 1e-30, 1e30, true);
        o.stars.luminosity.flux_min = lo;
        o.stars.luminosity.flux_max = hi;
      }
      // Camera pixels here; the pipeline multiplies by r.
      o.stars.min_separation_px = n.NumberOr("min_separation_px", 0.0, 0.0, 1e4);
      o.stars.margin_px = n.NumberOr("margin_px", 0.0, 0.0, 1e4);
      if (2 * o.stars.margin_px >= double(std::min(scene.frame.rows, scene.frame.cols)))
        n.Fail("margin_px", ToString(o.stars.margin_px), "less than half the smaller frame side");
      // The hard-core field's packing limit (star_field.hpp), checked here so that it fails before any
      // computation. Camera pixels: the fraction is the same on the HR grid.
      if (o.stars.min_separation_px > 0) {
        const double m = o.stars.margin_px, sep = o.stars.min_separation_px;
        const double area = (double(scene.frame.rows) - 2 * m) * (double(scene.frame.cols) - 2 * m);
        const double packing = o.stars.count * M_PI * sep * sep / 4.0 / area;
        if (packing > 0.4)
          n.Fail("min_separation_px", ToString(sep),
                 "a packing fraction count*pi*s^2/4/area <= 0.4 (here " + ToString(packing) + " for count = " +
                     std::to_string(o.stars.count) + " on " + ToString(area) + " camera px^2)");
      }
      CheckOptions(n, o.stars);
    }
    if (o.star_magnitudes) {
      *needs_magnitudes = true;
      if (o.flux.kind != FluxSpec::Kind::kNative)
        n.Fail("flux", "(given)", "no flux normalisation when the stars' brightness is given in magnitudes");
    }
  } else if (o.type == "galaxies") {
    o.kind = ObjectSpec::Kind::kGalaxies;
    GalaxyFieldOptions& g = o.galaxies;
    g.count = int(n.Integer("count", 1, 100000));
    if (n.Has("sersic_n_range")) std::tie(g.n_min, g.n_max) = Range(n, "sersic_n_range", 0.2 + 1e-9, 20.0, false);
    if (n.Has("half_light_radius_px")) std::tie(g.re_min_px, g.re_max_px) = Range(n, "half_light_radius_px", 1e-3, 1e4, false);
    else g.re_min_px = 0.5, g.re_max_px = 4.0;  // camera pixels: barely resolved to clearly extended
    if (n.Has("axis_ratio_range")) std::tie(g.q_min, g.q_max) = Range(n, "axis_ratio_range", 1e-3, 1.0, false);
    g.flux.alpha = n.NumberOr("alpha", g.flux.alpha, 0.0, 5.0);
    if (n.Has("flux_range_e")) std::tie(g.flux.flux_min, g.flux.flux_max) = Range(n, "flux_range_e", 1e-30, 1e30, true);
    g.margin_px = n.NumberOr("margin_px", 0.0, 0.0, 1e4);
    if (2 * g.margin_px >= double(std::min(scene.frame.rows, scene.frame.cols)))
      n.Fail("margin_px", ToString(g.margin_px), "less than half the smaller frame side");
    CheckOptions(n, g);
  } else if (o.type == "dead-leaves") {
    o.kind = ObjectSpec::Kind::kDeadLeaves;
    DeadLeavesOptions& d = o.dead_leaves;
    if (n.Has("radius_range_px")) std::tie(d.r_min_px, d.r_max_px) = Range(n, "radius_range_px", 1e-3, 1e4, true);
    else d.r_min_px = 0.5, d.r_max_px = 32.0;  // camera pixels: edges finer than a camera pixel
    d.radius_exponent = n.NumberOr("radius_exponent", d.radius_exponent, 1.0, 6.0);
    if (n.Has("grey_range")) std::tie(d.grey_min, d.grey_max) = Range(n, "grey_range", -1e30, 1e30, true);
    d.supersample = int(n.IntegerOr("supersample", d.supersample, 1, 16));
    CheckOptions(n, d);
  } else {
    o.kind = ObjectSpec::Kind::kImage;
    o.image_path = ResolvePath(scene.source, n.String("path"));
    if (!IsRegularFile(o.image_path)) n.Fail("path", "\"" + o.image_path + "\"", "an existing FITS/PNG/TIFF file");
    o.image.fit = n.ChoiceOr("fit", "crop", {"crop", "stretch"}) == "crop" ? ImageFit::kCrop : ImageFit::kStretch;
    o.image.values = n.ChoiceOr("values", "surface-brightness", {"surface-brightness", "flux-per-pixel"}) ==
                             "surface-brightness"
                         ? PixelValues::kSurfaceBrightness
                         : PixelValues::kFluxPerPixel;
    const std::string bg = n.ChoiceOr("background", "none", {"none", "median", "border-median", "minimum"});
    o.image.background = bg == "none"     ? ImageBackground::kNone
                         : bg == "median" ? ImageBackground::kMedian
                         : bg == "border-median" ? ImageBackground::kBorderMedian
                                                 : ImageBackground::kMinimum;
    o.image.clip_negative = n.BoolOr("clip_negative", true);
  }
  n.CheckNoOtherFields();
  return o;
}

std::vector<DmOffset::Term> ParseTerms(const ConfigNode& n, const std::string& key) {
  std::vector<DmOffset::Term> terms;
  for (const ConfigNode& t : n.Array(key)) {
    DmOffset::Term term;
    term.noll = int(t.Integer("noll", 1, 1000));
    term.rms_m = t.Number("rms_nm", -1e7, 1e7) * kNm;
    t.CheckNoOtherFields();
    terms.push_back(term);
  }
  return terms;
}

DmOffset ParseDesignFrame(const ConfigNode& n) {
  DmOffset o;
  if (n.Has("shift_px")) {
    const std::vector<double> s = n.Numbers("shift_px", -1e3, 1e3, 2, 2);
    o.shift_y_px = s[0];
    o.shift_x_px = s[1];
  }
  if (n.Has("zernike")) o.zernike = ParseTerms(n, "zernike");
  if (n.Has("actuators_nm")) {
    o.actuators_m = n.Numbers("actuators_nm", -1e7, 1e7, 1, 100000);
    for (double& a : o.actuators_m) a *= kNm;
  }
  n.CheckNoOtherFields();
  return o;
}

std::vector<DmOffset> ParseDesignFrames(const ConfigNode& n) {
  std::vector<DmOffset> frames;
  for (const ConfigNode& f : n.Array("frames")) frames.push_back(ParseDesignFrame(f));
  if (frames.empty()) n.Fail("frames", "[]", "one entry per exposure");
  return frames;
}

OffsetsSpec ParseOffsets(const ConfigNode& n, const SceneSpec& scene) {
  OffsetsSpec o;
  const std::string type = n.Choice("type", {"none", "raster", "design"});
  if (type == "none") {
    o.kind = OffsetsSpec::Kind::kNone;
    o.frames.assign(scene.frames, DmOffset{});
  } else if (type == "raster") {
    o.kind = OffsetsSpec::Kind::kRaster;
    o.source = "ClassicRaster(N, r)";
    for (const FrameOffset& f : ClassicRaster(scene.frames, scene.r)) {
      DmOffset d;
      d.shift_y_px = f.dy / scene.r;  // HR pixels -> camera pixels
      d.shift_x_px = f.dx / scene.r;
      o.frames.push_back(d);
    }
  } else {
    o.kind = OffsetsSpec::Kind::kDesign;
    const int given = int(n.Has("frames")) + int(n.Has("file"));
    if (given != 1) n.Fail("", std::to_string(given) + " of frames, file", "exactly one of them");
    if (n.Has("file")) {
      o.source = ResolvePath(scene.source, n.String("file"));
      if (!IsRegularFile(o.source)) n.Fail("file", "\"" + o.source + "\"", "an existing design .json file");
      o.frames = LoadDesignFile(o.source);
    } else {
      o.source = "inline";
      o.frames = ParseDesignFrames(n);
    }
    if (int(o.frames.size()) != scene.frames)
      n.Fail(n.Has("file") ? "file" : "frames", std::to_string(o.frames.size()) + " frames",
             "exactly the scene's frames = " + std::to_string(scene.frames));
  }
  n.CheckNoOtherFields();
  return o;
}

AoSpec ParseAo(const ConfigNode& n, const SceneSpec& scene) {
  AoSpec a;
  const std::string mode = n.Choice("mode", {"none", "analytic", "closed-loop"});
  a.mode = mode == "none" ? AoSpec::Mode::kNone : mode == "analytic" ? AoSpec::Mode::kAnalytic : AoSpec::Mode::kClosedLoop;
  a.seed = SeedOr(n, DeriveSeed(scene.seed, kAtmosphereStream));
  if (a.mode == AoSpec::Mode::kAnalytic && !(scene.telescope.atmosphere && scene.telescope.ao))
    n.Fail("mode", "\"analytic\"", "\"none\" or \"closed-loop\": telescope " + scene.telescope.name +
                                       " lacks an \"atmosphere\" or \"ao\" section");
  if (a.mode == AoSpec::Mode::kClosedLoop) {
    if (!scene.telescope.ao)
      n.Fail("mode", "\"closed-loop\"", "\"none\": telescope " + scene.telescope.name + " has no \"ao\" section");
    const std::string sensor = n.ChoiceOr("sensor", "diffractive", {"ideal", "geometric", "diffractive"});
    a.sensor = sensor == "ideal" ? SensorKind::kIdeal : sensor == "geometric" ? SensorKind::kGeometric : SensorKind::kDiffractive;
    a.time_per_frame_s = n.NumberOr("time_per_frame_s", a.time_per_frame_s, 1e-4, 3600.0);
    a.settling_s = n.NumberOr("settling_s", a.settling_s, 0.0, 3600.0);
    a.psf_every_steps = int(n.IntegerOr("psf_every_steps", a.psf_every_steps, 1, 100000));
    a.dm_gain = n.NumberOr("dm_gain", a.dm_gain, 0.5, 2.0);
    a.offset_calibration =
        n.ChoiceOr("offset_calibration", "on-sky", {"on-sky", "flat"}) == "flat" ? OffsetCalibration::kFlat : OffsetCalibration::kOnSky;
    a.antithetic = n.BoolOr("antithetic", a.antithetic);
    const double steps = a.time_per_frame_s * scene.telescope.ao->loop.rate_hz;
    if (steps < a.psf_every_steps)
      n.Fail("time_per_frame_s", ToString(a.time_per_frame_s),
             "at least psf_every_steps loop frames (" + ToString(a.psf_every_steps / scene.telescope.ao->loop.rate_hz) + " s)");
  }
  n.CheckNoOtherFields();
  return a;
}

void ParseDetector(const ConfigNode& n, SceneSpec* s) {
  const nlohmann::json& size = n.json().contains("frame_px") ? n.json().at("frame_px") : nlohmann::json();
  if (size.is_array()) {
    const std::vector<double> v = n.Numbers("frame_px", 8, 4096, 2, 2);
    if (v[0] != std::floor(v[0]) || v[1] != std::floor(v[1])) n.Fail("frame_px", size.dump(), "whole numbers of pixels");
    s->frame = {Index(v[0]), Index(v[1])};
  } else {
    const Index side = n.Integer("frame_px", 8, 4096);
    s->frame = {side, side};
  }
  DetectorOptions& d = s->detector;
  s->total_exposure_s = n.PositiveOr("total_exposure_s", s->total_exposure_s);
  d.exposure_time_s = s->total_exposure_s / s->frames;
  d.gain_e_per_adu = n.PositiveOr("gain_e_per_adu", d.gain_e_per_adu);
  d.bias_adu = n.NumberOr("bias_adu", d.bias_adu, -1e9, 1e9);
  const std::string noise = n.ChoiceOr("noise", "physical", {"physical", "peak-fraction", "none"});
  d.noise_model = noise == "peak-fraction" ? NoiseModel::kPeakFraction : NoiseModel::kPhysical;
  d.enable_photon_noise = noise == "physical" && n.BoolOr("photon_noise", true);
  d.read_noise_e = n.NumberOr("read_noise_e", d.read_noise_e, 0.0, 1e6);
  d.enable_read_noise = noise == "physical" && d.read_noise_e > 0;
  d.peak_noise_fraction = n.NumberOr("peak_noise_fraction", d.peak_noise_fraction, 0.0, 10.0);
  if (noise == "none") d.peak_noise_fraction = 0.0;
  if (noise != "physical" && (n.Has("photon_noise") || n.Has("read_noise_e")))
    n.Fail(n.Has("photon_noise") ? "photon_noise" : "read_noise_e", "(given)",
           "photon_noise and read_noise_e only with noise = \"physical\"");
  if (noise != "peak-fraction" && n.Has("peak_noise_fraction"))
    n.Fail("peak_noise_fraction", "(given)", "only with noise = \"peak-fraction\"");
  if (n.Has("background_e_per_s") && n.Has("sky_mag_per_arcsec2"))
    n.Fail("background_e_per_s", "(both given)", "one of background_e_per_s and sky_mag_per_arcsec2");
  d.background_e_per_s = n.NumberOr("background_e_per_s", 0.0, 0.0, 1e12);
  if (n.Has("sky_mag_per_arcsec2")) {
    const double mu = n.Number("sky_mag_per_arcsec2", -10.0, 40.0);
    d.fill_factor = n.NumberOr("fill_factor", d.fill_factor, 1e-3, 1.0);
    const double arcsec = M_PI / 180.0 / 3600.0;
    const double pixel_arcsec2 = std::pow(s->CameraPixelRad() / arcsec, 2) * d.fill_factor * d.fill_factor;
    if (s->photometry.zero_point_mag) {
      d.background_e_per_s = std::pow(10.0, -0.4 * (mu - *s->photometry.zero_point_mag)) * pixel_arcsec2;
    } else {
      if (s->photometry.band.empty())
        n.Fail("sky_mag_per_arcsec2", ToString(mu), "a sky magnitude only with photometry.band or photometry.zero_point_mag");
      d.background_e_per_s = SkyBackgroundRate(mu, VegaBand(s->photometry.band), s->Collector(),
                                               s->CameraPixelRad(), d.fill_factor);
    }
  }
  d.enable_background = d.background_e_per_s > 0;
  d.dark_current_e_per_s = n.NumberOr("dark_current_e_per_s", 0.0, 0.0, 1e12);
  d.enable_dark_current = d.dark_current_e_per_s > 0;
  d.enable_saturation = n.BoolOr("saturation", true);
  d.saturation_adu = n.NumberOr("saturation_adu", d.saturation_adu, -1e15, 1e15);
  d.enable_quantization = n.BoolOr("quantize", false);
  d.fill_factor = n.NumberOr("fill_factor", d.fill_factor, 1e-3, 1.0);
  s->noise_seed = static_cast<std::uint64_t>(n.IntegerOr("noise_seed", static_cast<long long>(DeriveSeed(s->seed, kNoiseStream) & (kMaxSeed - 1)), 0, kMaxSeed));
  if (n.Has("bad_pixels")) {
    const ConfigNode b = n.Child("bad_pixels");
    const int given = int(b.Has("fraction")) + int(b.Has("file"));
    if (given != 1) b.Fail("", std::to_string(given) + " of fraction, file", "exactly one of them");
    d.enable_bad_pixels = true;
    if (b.Has("fraction")) {
      s->bad_pixel_fraction = b.Number("fraction", 0.0, 1.0);
      s->bad_pixel_seed = SeedOr(b, DeriveSeed(s->seed, kBadPixelStream));
      d.bad_pixel_mask = RandomBadPixelMask(s->frame, s->bad_pixel_fraction, s->bad_pixel_seed);
    } else {
      s->bad_pixel_file = ResolvePath(s->source, b.String("file"));
      if (!IsRegularFile(s->bad_pixel_file))
        b.Fail("file", "\"" + s->bad_pixel_file + "\"", "an existing FITS/PNG/TIFF mask (1 good, 0 bad)");
      d.bad_pixel_mask = ReadImage(s->bad_pixel_file);
      if (ShapeOf(d.bad_pixel_mask) != s->frame)
        b.Fail("file", ToString(ShapeOf(d.bad_pixel_mask)), "a mask of the frame's shape " + ToString(s->frame));
      if (!((d.bad_pixel_mask.array() == 0) || (d.bad_pixel_mask.array() == 1)).all())
        b.Fail("file", "\"" + s->bad_pixel_file + "\"", "a mask holding only 0 (bad) and 1 (good)");
    }
    b.CheckNoOtherFields();
  }
  n.CheckNoOtherFields();
  std::string why;
  if (!d.IsValid(&why)) n.Fail("", "(inconsistent)", why);
}

}  // namespace

bool DmOffset::IsZero() const {
  if (shift_y_px != 0.0 || shift_x_px != 0.0) return false;
  for (const Term& t : zernike)
    if (t.rms_m != 0.0) return false;
  for (double a : actuators_m)
    if (a != 0.0) return false;
  return true;
}

bool DmOffset::operator==(const DmOffset& o) const {
  if (shift_y_px != o.shift_y_px || shift_x_px != o.shift_x_px || actuators_m != o.actuators_m ||
      zernike.size() != o.zernike.size())
    return false;
  for (std::size_t i = 0; i < zernike.size(); ++i)
    if (zernike[i].noll != o.zernike[i].noll || zernike[i].rms_m != o.zernike[i].rms_m) return false;
  return true;
}

LightCollectorOptions SceneSpec::Collector() const {
  LightCollectorOptions c;
  c.diameter_m = telescope.aperture.pupil.diameter_m;
  c.obstruction = telescope.aperture.pupil.obstruction;
  c.throughput = photometry.throughput;
  return c;
}

double SceneSpec::ElectronsPerFrameForMagnitude(double magnitude) const {
  const double frame_s = total_exposure_s / frames;
  if (photometry.zero_point_mag) return std::pow(10.0, -0.4 * (magnitude - *photometry.zero_point_mag)) * frame_s;
  if (photometry.band.empty())
    throw InvalidArgument(source + ": magnitudes need photometry.band (a Vega band) or photometry.zero_point_mag");
  ExposurePlan plan;
  plan.total_time_s = total_exposure_s;
  plan.frames = frames;
  return ElectronsPerFrame(SourceFlux::Magnitude(magnitude, photometry.band), Collector(), plan);
}

namespace {

// psf_field (scene_spec.hpp, PsfFieldSpec): the guide star, the grid, and the checks that need the telescope,
// the AO mode and the frame: a mode that varies over the field, every node's direction within what the mode
// can compute (FieldDirectionLimit), and a spacing of at most θ0.
void ParsePsfField(const ConfigNode& n, SceneSpec* s) {
  PsfFieldSpec& f = s->psf_field;
  f.enabled = true;
  if (n.Has("guide_star_arcsec")) {
    const std::vector<double> g = n.Numbers("guide_star_arcsec", -2062.6, 2062.6, 2, 2);
    f.guide_star_x_arcsec = g[0];
    f.guide_star_y_arcsec = g[1];
  }
  if (n.Has("grid")) {
    if (n.json().at("grid").is_number()) {
      f.grid_y = f.grid_x = int(n.Integer("grid", 1, 33));
    } else {
      const std::vector<double> g = n.Numbers("grid", 1, 33, 2, 2);
      if (g[0] != std::floor(g[0]) || g[1] != std::floor(g[1]))
        n.Fail("grid", ToString(g[0]) + ", " + ToString(g[1]), "whole numbers of nodes [ny, nx]");
      f.grid_y = int(g[0]);
      f.grid_x = int(g[1]);
    }
  }
  n.CheckNoOtherFields();
  const PsfFieldGrid grid = s->FieldGrid();
  const std::string grid_text = std::to_string(f.grid_y) + " x " + std::to_string(f.grid_x);
  const std::string mode = s->ao.mode == AoSpec::Mode::kAnalytic ? "analytic" : "closed-loop";
  for (int k = 0; k < grid.nodes(); ++k) {
    const FieldDirection d = s->FieldNodeDirection(k);
    const std::string limit = FieldDirectionLimit(s->telescope, mode, d);
    if (!limit.empty())
      n.Fail("guide_star_arcsec", ToString(f.guide_star_x_arcsec) + ", " + ToString(f.guide_star_y_arcsec),
             "field points " + limit + "; node " + std::to_string(k) + " of the " + grid_text + " grid is at (" +
                 ToString(d.x_rad * kSceneArcsecPerRad) + ", " + ToString(d.y_rad * kSceneArcsecPerRad) +
                 ") arcsec from it");
  }
  if (s->telescope.atmosphere) {
    const auto& a = *s->telescope.atmosphere;
    const double theta0 =
        IsoplanaticAngleRad(a.r0_m, a.r0_wavelength_m, s->telescope.science_wavelength_m, a.layers);
    const std::array<double, 2> spacing = grid.Spacing();
    const double hr = s->HrPixelRad();
    auto needed = [&](Index side) { return 1 + int(std::ceil(double(side - 1) * hr / theta0 - 1e-9)); };
    if (std::isfinite(theta0) && (spacing[0] * hr > theta0 * (1 + 1e-9) || spacing[1] * hr > theta0 * (1 + 1e-9) ||
                                  (f.grid_y == 1 && double(s->HrFrame().rows - 1) * hr > theta0) ||
                                  (f.grid_x == 1 && double(s->HrFrame().cols - 1) * hr > theta0)))
      n.Fail("grid", grid_text,
             "at least " + std::to_string(needed(s->HrFrame().rows)) + " x " + std::to_string(needed(s->HrFrame().cols)) +
                 " nodes: the spacing must be at most the isoplanatic angle theta0 = " +
                 ToString(theta0 * kSceneArcsecPerRad) + " arcsec at the science wavelength (the frame spans " +
                 ToString(double(s->HrFrame().cols) * hr * kSceneArcsecPerRad) + " x " +
                 ToString(double(s->HrFrame().rows) * hr * kSceneArcsecPerRad) + " arcsec)");
  }
}

}  // namespace

SceneSpec ParseScene(const nlohmann::json& json, const std::string& source) {
  const ConfigNode root(json, source);
  SceneSpec s;
  s.source = source;
  s.name = root.String("name");
  s.seed = static_cast<std::uint64_t>(root.IntegerOr("seed", 1, 0, kMaxSeed));
  s.frames = int(root.Integer("frames", 1, 1024));
  s.r = int(root.Integer("r", 1, 16));

  // Telescope: a preset name, a path to a preset file, or the preset inline.
  const nlohmann::json& tel = json.contains("telescope") ? json.at("telescope") : nlohmann::json();
  if (tel.is_string()) {
    const std::string name = root.String("telescope");
    const bool is_path = name.find('/') != std::string::npos || fs::path(name).extension() == ".json";
    const std::string path = is_path ? ResolvePath(source, name) : name;
    if (is_path && !IsRegularFile(path)) root.Fail("telescope", "\"" + path + "\"", "a preset name or an existing .json file");
    s.telescope = LoadTelescopePreset(path);
  } else {
    s.telescope = ParseTelescopePreset(root.Child("telescope").json(), source + " (telescope)");
  }

  // Photometry comes before the objects and the detector, which convert magnitudes with it.
  if (root.Has("photometry")) {
    const ConfigNode p = root.Child("photometry");
    if (p.Has("band")) {
      const std::vector<std::string> names = VegaBandNames();
      s.photometry.band = p.Choice("band", names);
    }
    s.photometry.throughput = p.NumberOr("throughput", s.photometry.throughput, 1e-6, 1.0);
    if (p.Has("zero_point_mag")) s.photometry.zero_point_mag = p.Number("zero_point_mag", -10.0, 50.0);
    p.CheckNoOtherFields();
  }

  ParseDetector(root.Child("detector"), &s);

  // Geometry checks that need the telescope, r and the frame.
  const double hr_lod = s.HrPixelLambdaOverD();
  if (hr_lod > 1.0 + 1e-12)
    root.Fail("r", std::to_string(s.r),
              "r >= " + std::to_string(int(std::ceil(s.CameraPixelRad() / s.telescope.LambdaOverD() - 1e-12))) +
                  ": the HR pixel (camera pixel / r = " + ToString(hr_lod) +
                  " lambda/D) must be at most lambda/D for the PSF to be sampled without losing light");
  if (s.HrFrame().rows > 16384 || s.HrFrame().cols > 16384)
    root.Fail("r", std::to_string(s.r), "r * frame_px <= 16384 (HR grid " + ToString(s.HrFrame()) + ")");
  s.sky_oversampling = int(root.IntegerOr("sky_oversampling", 1, 1, 16));
  if (s.HrFrame().rows * s.sky_oversampling > 16384 || s.HrFrame().cols * s.sky_oversampling > 16384)
    root.Fail("sky_oversampling", std::to_string(s.sky_oversampling),
              "sky_oversampling * r * frame_px <= 16384 (HR grid " + ToString(s.HrFrame()) + ")");

  double window_lod = kDefaultPsfWindowLod;
  if (root.Has("psf")) {
    const ConfigNode p = root.Child("psf");
    if (p.Has("size_px") && p.Has("window_lambda_over_d"))
      p.Fail("size_px", "(both given)", "one of size_px and window_lambda_over_d");
    if (p.Has("size_px")) {
      s.psf_size_px = p.Integer("size_px", 4, 8192);
      if (s.psf_size_px % 2) p.Fail("size_px", std::to_string(s.psf_size_px), "an even number of HR pixels");
      window_lod = s.psf_size_px * hr_lod;
    } else {
      window_lod = p.NumberOr("window_lambda_over_d", window_lod, 1.0, 4096.0);
    }
    p.CheckNoOtherFields();
  }
  if (s.psf_size_px == 0) s.psf_size_px = 2 * Index(std::ceil(window_lod / hr_lod / 2.0 - 1e-9));
  // The PSF of a pupil sampled with n pixels repeats every n λ/D: a wider window would hold aliased copies.
  const double period_lod = double(s.telescope.pupil_px);
  if (s.psf_size_px * hr_lod > period_lod + 1e-9)
    root.Fail("psf", ToString(s.psf_size_px * hr_lod) + " lambda/D (" + std::to_string(s.psf_size_px) + " HR px)",
              "a window of at most the pupil grid's period, " + ToString(period_lod) + " lambda/D (telescope pupil_px)");

  if (root.Has("ao")) s.ao = ParseAo(root.Child("ao"), s);
  if (root.Has("static_aberrations")) {
    s.static_aberrations = ParseTerms(root, "static_aberrations");
    for (std::size_t i = 0; i < s.static_aberrations.size(); ++i)
      if (s.static_aberrations[i].noll < 2)
        root.Fail("static_aberrations[" + std::to_string(i) + "].noll", "1", "a Noll index >= 2 (piston changes nothing)");
  }
  if (root.Has("offsets")) s.offsets = ParseOffsets(root.Child("offsets"), s);
  else s.offsets.frames.assign(s.frames, DmOffset{});
  for (std::size_t i = 0; i < s.offsets.frames.size(); ++i)
    for (const DmOffset::Term& t : s.offsets.frames[i].zernike)
      if (t.noll < 2) root.Fail("offsets.frames[" + std::to_string(i) + "].zernike", "noll 1", "Noll indices >= 2");

  if (root.Has("sky")) {
    const ConfigNode k = root.Child("sky");
    s.sky.ra_deg = k.Number("ra_deg", 0.0, 360.0);
    if (s.sky.ra_deg == 360.0) s.sky.ra_deg = 0.0;
    s.sky.dec_deg = k.Number("dec_deg", -90.0, 90.0);
    s.sky.position_angle_deg = k.NumberOr("position_angle_deg", 0.0, -360.0, 360.0);
    s.sky.given = true;
    k.CheckNoOtherFields();
  }

  if (root.Has("psf_field")) {
    if (s.ao.mode != AoSpec::Mode::kAnalytic && s.ao.mode != AoSpec::Mode::kClosedLoop)
      root.Fail("psf_field", "(with ao.mode none)",
                "a psf_field only with ao.mode analytic or closed-loop: without AO correction the PSF does not "
                "depend on the guide star's direction (and a diffraction-limited PSF is the same everywhere)");
    ParsePsfField(root.Child("psf_field"), &s);
  }

  if (root.Has("sequence")) {
    const ConfigNode q = root.Child("sequence");
    s.sequence.frames = int(q.Integer("frames", 1, 100000));
    if (s.sequence.frames < s.frames)
      q.Fail("frames", std::to_string(s.sequence.frames), "at least the N = " + std::to_string(s.frames) + " phases (frames)");
    const double frame_s = s.detector.exposure_time_s;
    s.sequence.frame_interval_s = q.NumberOr("frame_interval_s", frame_s, 0.0, 1e9);
    if (s.sequence.frame_interval_s < frame_s * (1 - 1e-12))
      q.Fail("frame_interval_s", ToString(s.sequence.frame_interval_s),
             "at least the frame time total_exposure_s / frames = " + ToString(frame_s) + " s (exposures do not overlap)");
    s.sequence.start_s = q.NumberOr("start_s", 0.0, -1e12, 1e12);
    q.CheckNoOtherFields();
  }

  bool needs_magnitudes = false;
  const std::vector<ConfigNode> objects = root.Array("objects");
  if (objects.empty()) root.Fail("objects", "[]", "at least one object");
  for (std::size_t i = 0; i < objects.size(); ++i) s.objects.push_back(ParseObject(objects[i], s, i, &needs_magnitudes));
  if (needs_magnitudes && s.photometry.band.empty() && !s.photometry.zero_point_mag)
    root.Fail("photometry", "(no band or zero point)", "photometry.band or photometry.zero_point_mag when magnitudes are used");
  root.CheckNoOtherFields();
  return s;
}

UsafOptions ObjectUsafOptions(const ObjectSpec& o, Shape hr) {
  if (o.kind == ObjectSpec::Kind::kDemo) return DemoUsafOptions(hr);
  if (o.kind != ObjectSpec::Kind::kUsaf)
    throw InvalidArgument("ObjectUsafOptions", "object", o.type, "a usaf or demo object");
  UsafOptions u = o.usaf;
  u.pixels_per_mm = 1.0;
  const UsafSize size = UsafTargetSize(u);
  u.pixels_per_mm = o.usaf_fill * double(std::min(hr.rows, hr.cols)) / std::max(size.height_mm, size.width_mm);
  return u;
}

SceneSpec LoadScene(const std::string& path) { return ParseScene(ReadJsonFile(path), path); }

std::vector<DmOffset> LoadDesignFile(const std::string& path) {
  const nlohmann::json json = ReadJsonFile(path);
  const ConfigNode root(json, path);
  root.StringOr("name", "");
  if (root.Has("design")) root.Child("design");  // free-form provenance written by the designer
  std::vector<DmOffset> frames = ParseDesignFrames(root);
  root.CheckNoOtherFields();
  return frames;
}

double ObjectVariation::FluxFactor(double t) const {
  switch (curve) {
    case Curve::kNone:
      return 1.0;
    case Curve::kSine:
      return 1.0 + amplitude * std::sin(2 * M_PI * t / period_s + phase_deg * M_PI / 180.0);
    case Curve::kTable: {
      if (t <= times_s.front()) return factors.front();
      if (t >= times_s.back()) return factors.back();
      const std::size_t i = std::size_t(std::upper_bound(times_s.begin(), times_s.end(), t) - times_s.begin());
      const double w = (t - times_s[i - 1]) / (times_s[i] - times_s[i - 1]);
      return (1 - w) * factors[i - 1] + w * factors[i];
    }
  }
  return 1.0;
}

const DmOffset& SceneSpec::ExposureOffset(int j) const {
  // Checked without building the message first: Compile calls this M x N times.
  if (j < 0 || j >= Exposures() || frames <= 0 || offsets.frames.size() != std::size_t(frames))
    throw InvalidArgument("SceneSpec::ExposureOffset", "j", std::to_string(j),
                          "0.." + std::to_string(Exposures() - 1) + " (the exposures; one offset per phase)");
  return offsets.frames[std::size_t(j % frames)];
}

double SceneSpec::ExposureTime(int j) const {
  if (j < 0 || j >= Exposures())
    throw InvalidArgument("SceneSpec::ExposureTime", "j", std::to_string(j),
                          "0.." + std::to_string(Exposures() - 1) + " (the exposures)");
  const double frame_s = detector.exposure_time_s;
  const double interval = sequence.enabled() ? sequence.frame_interval_s : frame_s;
  return sequence.start_s + j * interval + 0.5 * frame_s;
}

bool SceneSpec::TimeVarying() const {
  if (!sequence.enabled()) return false;
  for (const ObjectSpec& o : objects)
    if (o.IsTimeVarying()) return true;
  return false;
}

PsfFieldGrid SceneSpec::FieldGrid() const {
  if (!psf_field.enabled) return PsfFieldGrid();
  return PsfFieldGrid(HrFrame(), psf_field.grid_y, psf_field.grid_x, "SceneSpec::FieldGrid");
}

FieldDirection SceneSpec::FieldNodeDirection(int k) const {
  const std::array<double, 2> p = FieldGrid().Node(k);
  const Shape hr = HrFrame();
  const double pitch = HrPixelRad();
  FieldDirection d;
  d.x_rad = (p[1] - 0.5 * double(hr.cols - 1)) * pitch - psf_field.guide_star_x_arcsec / kSceneArcsecPerRad;
  d.y_rad = (p[0] - 0.5 * double(hr.rows - 1)) * pitch - psf_field.guide_star_y_arcsec / kSceneArcsecPerRad;
  return d;
}

nlohmann::json DmOffsetToJson(const DmOffset& offset) {
  nlohmann::json j = nlohmann::json::object();
  j["shift_px"] = {offset.shift_y_px, offset.shift_x_px};
  nlohmann::json terms = nlohmann::json::array();
  for (const DmOffset::Term& t : offset.zernike) terms.push_back({{"noll", t.noll}, {"rms_nm", t.rms_m / kNm}});
  j["zernike"] = terms;
  if (!offset.actuators_m.empty()) {
    nlohmann::json a = nlohmann::json::array();
    for (double v : offset.actuators_m) a.push_back(v / kNm);
    j["actuators_nm"] = a;
  }
  return j;
}

}  // namespace aosr
