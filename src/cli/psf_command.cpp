// `aosr psf PRESET`: the science PSF of a telescope preset, with optional DM offsets (the computation is the
// library's ComputePresetPsf, scene/preset_psf.hpp, which the Python aosr.psf() calls too).
#include <cmath>
#include <cstdio>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "aosr/core/error.hpp"
#include "aosr/io/fits.hpp"
#include "aosr/scene/preset_psf.hpp"
#include "aosr/scene/telescope.hpp"
#include "cli_util.hpp"
#include "commands.hpp"

namespace aosr::cli {
namespace {

struct PsfArgs {
  std::string preset;
  std::string mode;  // empty: analytic when the preset has atmosphere and AO, else diffraction
  std::vector<std::string> offsets;
  int r = 2;
  double pixel_lod = 0;  // > 0 overrides camera_pixel / r
  int size = 128;
  std::string output;
  bool json = false;
  // Closed loop only.
  std::string sensor = "diffractive";
  double exposure_s = 0.5;
  double settling_s = 0.1;
  std::uint64_t seed = 1;
  bool antithetic = true;
  // Science direction from the guide star [arcsec]: --field-angle A is (A, 0); --field-direction X,Y.
  double field_angle_arcsec = 0.0;
  std::string field_direction;
  ExecutionArgs exec;
};

constexpr double kPsfCommandArcsecPerRad = 180.0 * 3600.0 / M_PI;

// "X,Y" [arcsec] -> direction [rad]; finite numbers only.
FieldDirection ParseFieldDirection(const std::string& text) {
  const std::string allowed = "X,Y: two finite angles in arcsec from the guide star (x along columns), e.g. 20,-5";
  const auto comma = text.find(',');
  if (comma == std::string::npos) throw InvalidArgument("aosr psf", "--field-direction", text, allowed);
  try {
    std::size_t used_x = 0, used_y = 0;
    const double x = std::stod(text.substr(0, comma), &used_x);
    const double y = std::stod(text.substr(comma + 1), &used_y);
    if (used_x != comma || used_y != text.size() - comma - 1 || !std::isfinite(x) || !std::isfinite(y))
      throw InvalidArgument("aosr psf", "--field-direction", text, allowed);
    return {x / kPsfCommandArcsecPerRad, y / kPsfCommandArcsecPerRad};
  } catch (const std::logic_error&) {
    throw InvalidArgument("aosr psf", "--field-direction", text, allowed);
  }
}

struct ZernikeOffset {
  int j;
  double nm;
};

// "J=NM" -> (j, nm). Noll index j >= 2 (piston does nothing), coefficient in nm of wavefront OPD RMS.
ZernikeOffset ParseOffset(const std::string& text) {
  const auto eq = text.find('=');
  const std::string allowed = "J=NM with Noll index J >= 2 and a finite coefficient in nm RMS, e.g. 4=50";
  if (eq == std::string::npos) throw InvalidArgument("aosr psf", "--offset", text, allowed);
  try {
    std::size_t used_j = 0, used_c = 0;
    const int j = std::stoi(text.substr(0, eq), &used_j);
    const double nm = std::stod(text.substr(eq + 1), &used_c);
    if (used_j != eq || used_c != text.size() - eq - 1 || j < 2 || j > 1000 || !std::isfinite(nm))
      throw InvalidArgument("aosr psf", "--offset", text, allowed);
    return {j, nm};
  } catch (const std::logic_error&) {
    throw InvalidArgument("aosr psf", "--offset", text, allowed);
  }
}

void RunPsf(const PsfArgs& args) {
  ApplyExecution(args.exec);
  const Progress progress(!args.json);
  Stopwatch clock;
  PresetPsfOptions o;
  for (const auto& t : args.offsets) {
    const ZernikeOffset z = ParseOffset(t);
    o.offsets.push_back({z.j, z.nm});
  }
  o.mode = args.mode;
  o.r = args.r;
  o.pixel_lod = args.pixel_lod;
  o.size = args.size;
  o.sensor = ParseSensorKind(args.sensor);
  o.exposure_s = args.exposure_s;
  o.settling_s = args.settling_s;
  o.seed = args.seed;
  o.antithetic = args.antithetic;
  if (!std::isfinite(args.field_angle_arcsec) || std::abs(args.field_angle_arcsec) > 0.01 * kPsfCommandArcsecPerRad)
    throw InvalidArgument("aosr psf", "--field-angle", ToString(args.field_angle_arcsec),
                          "a finite angle in arcsec, at most 2062.6 (0.01 rad) from the guide star");
  if (!args.field_direction.empty() && args.field_angle_arcsec != 0.0)
    throw InvalidArgument("aosr psf", "--field-direction", args.field_direction,
                          "not together with --field-angle (one direction: --field-angle A is --field-direction A,0)");
  o.field_direction = args.field_direction.empty() ? FieldDirection{args.field_angle_arcsec / kPsfCommandArcsecPerRad, 0.0}
                                                   : ParseFieldDirection(args.field_direction);
  {
    std::string why;
    if (!o.IsValid(&why))
      throw InvalidArgument("aosr psf", args.field_direction.empty() ? "--field-angle" : "--field-direction",
                            args.field_direction.empty() ? ToString(args.field_angle_arcsec) : args.field_direction,
                            why);
  }
  const TelescopePreset preset = LoadTelescopePreset(args.preset);
  // Checked here too so that the message names the flag (the library checks it again).
  const int max_size = MaxPresetPsfSize(preset, o);
  if (args.size > max_size)
    throw InvalidArgument("aosr psf", "--size", std::to_string(args.size),
                          "at most " + std::to_string(max_size) + " pixels: the field must fit in the " +
                              std::to_string(preset.pupil_px) + " lambda/D period of the " +
                              std::to_string(preset.pupil_px) + "-pixel pupil");
  if (!args.output.empty()) CheckWritableFile(args.output);

  const PresetPsf result = ComputePresetPsf(preset, o, [&progress](const std::string& m) { progress.Step(m); });
  const std::string& mode = result.mode;
  const Image& psf = result.psf;
  const PsfSampling& sampling = result.sampling;
  const double strehl = result.strehl, residual_nm = result.residual_rms_nm, lod_px = result.lambda_over_d_px;
  const std::vector<double>& ee = result.encircled_energy;
  const std::string& loop_report = result.loop_report;
  const double seconds = clock.Seconds();

  if (!args.output.empty()) {
    FitsHeader h;
    h.Set("ORIGIN", std::string("aosr ") + AOSR_VERSION, "software that wrote this file");
    h.Set("PRESET", preset.name, "telescope preset");
    h.Set("PSFMODE", mode, "analytic: long-exposure AO residual model");
    h.Set("WAVELEN", sampling.wavelength_m, "[m] science wavelength");
    h.Set("PIXSCALE", sampling.pixel_scale_rad, "[rad] pixel angular pitch");
    h.Set("STREHL", strehl, "peak / diffraction-limited peak");
    h.Set("NORMALIS", "whole focal plane sums to 1", "window sum = light in the window");
    if (!o.field_direction.IsZero()) {
      h.Set("FIELDX", o.field_direction.x_rad * kPsfCommandArcsecPerRad, "[arcsec] science direction from the guide star, x");
      h.Set("FIELDY", o.field_direction.y_rad * kPsfCommandArcsecPerRad, "[arcsec] science direction from the guide star, y");
    }
    for (std::size_t i = 0; i < o.offsets.size(); ++i)
      h.Set("ZOFF" + std::to_string(i), std::to_string(o.offsets[i].noll) + "=" + ToString(o.offsets[i].rms_nm) + " nm",
            "Noll index = wavefront OPD RMS offset");
    WriteFits(args.output, psf, h, FitsType::kFloat64);
  }
  if (args.json) {
    nlohmann::json j = {{"preset", preset.name},
                        {"mode", mode},
                        {"wavelength_m", sampling.wavelength_m},
                        {"pixel_scale_rad", sampling.pixel_scale_rad},
                        {"pixel_scale_lambda_over_d", 1.0 / lod_px},
                        {"strehl", strehl},
                        {"fwhm_px", result.fwhm_px},
                        {"fwhm_lambda_over_d", result.fwhm_px / lod_px},
                        {"fwhm_major_lambda_over_d", result.fwhm_major_px / lod_px},
                        {"fwhm_minor_lambda_over_d", result.fwhm_minor_px / lod_px},
                        {"elongation", result.elongation},
                        {"major_axis_angle_deg", result.major_axis_angle_deg},
                        {"field_direction_arcsec",
                         {{"x", o.field_direction.x_rad * kPsfCommandArcsecPerRad}, {"y", o.field_direction.y_rad * kPsfCommandArcsecPerRad}}},
                        {"field_angle_arcsec", o.field_direction.Norm() * kPsfCommandArcsecPerRad},
                        {"encircled_energy", {{"radius_lambda_over_d", {1, 2, 5}}, {"fraction_of_window", ee}}},
                        {"window_sum", result.window_sum},
                        {"core_centroid_lambda_over_d", {{"y", result.core_centroid_lod[0]}, {"x", result.core_centroid_lod[1]}}},
                        {"residual_rms_nm", residual_nm},
                        {"seconds", seconds}};
    // JSON has no infinity: null when no atmosphere or all the turbulence is at the ground.
    j["isoplanatic_angle_arcsec"] = result.isoplanatic_angle_rad > 0 && std::isfinite(result.isoplanatic_angle_rad)
                                        ? nlohmann::json(result.isoplanatic_angle_rad * kPsfCommandArcsecPerRad)
                                        : nlohmann::json(nullptr);
    if (!args.output.empty()) j["output"] = args.output;
    if (!loop_report.empty())
      j["closed_loop"] = {{"sensor", args.sensor}, {"antithetic", args.antithetic}, {"report", loop_report}};
    std::printf("%s\n", j.dump(2).c_str());
    return;
  }
  std::printf("aosr psf %s (%s) at %.3g um, pixel %.3g lambda/D, %dx%d\n", preset.name.c_str(), mode.c_str(),
              sampling.wavelength_m * 1e6, 1.0 / lod_px, args.size, args.size);
  std::printf("  Strehl %.4f   FWHM %.3f lambda/D   residual %.1f nm RMS\n", strehl, result.fwhm_px / lod_px, residual_nm);
  std::printf("  elongation %.3f (FWHM %.3f x %.3f lambda/D), major axis at %+.1f deg from +x\n", result.elongation,
              result.fwhm_major_px / lod_px, result.fwhm_minor_px / lod_px, result.major_axis_angle_deg);
  if (!o.field_direction.IsZero() || result.isoplanatic_angle_rad > 0) {
    std::printf("  field direction (x, y) = (%+.2f, %+.2f) arcsec from the guide star", o.field_direction.x_rad * kPsfCommandArcsecPerRad,
                o.field_direction.y_rad * kPsfCommandArcsecPerRad);
    if (result.isoplanatic_angle_rad > 0 && std::isfinite(result.isoplanatic_angle_rad))
      std::printf("; isoplanatic angle theta0 = %.2f arcsec", result.isoplanatic_angle_rad * kPsfCommandArcsecPerRad);
    std::printf("\n");
  }
  std::printf("  EE(1, 2, 5 lambda/D) = %.4f, %.4f, %.4f of the window (window holds %.4f of all light)\n", ee[0],
              ee[1], ee[2], result.window_sum);
  std::printf("  core centroid (y, x) = (%+.4f, %+.4f) lambda/D from the optical axis\n", result.core_centroid_lod[0],
              result.core_centroid_lod[1]);
  if (!loop_report.empty())
    std::printf("  loop (%s sensor%s): %s\n", args.sensor.c_str(), args.antithetic ? ", antithetic pair" : "",
                loop_report.c_str());
  std::printf("  %.3f s\n", seconds);
}

}  // namespace

void RegisterPsf(CLI::App& app) {
  auto args = std::make_shared<PsfArgs>();
  CLI::App* cmd = app.add_subcommand(
      "psf",
      "Compute the science PSF of a telescope preset (a name from data/telescopes/ or a .json path): "
      "diffraction-limited, long-exposure through the analytic AO residual model, or from a closed-loop "
      "Monte-Carlo run (atmosphere, Shack-Hartmann, controller, DM), with optional DM offsets given as Zernike "
      "coefficients (held by the loop through the WFS reference slopes), on the guide star's axis or at a field direction "
      "from it (anisoplanatism). Prints Strehl, FWHM, elongation, encircled energy, residual and time.");
  cmd->add_option("preset", args->preset, "telescope preset name or .json path")->required();
  cmd->add_option("--mode", args->mode,
                  "analytic | closed-loop | diffraction (default: analytic when the preset has atmosphere and AO)")
      ->check(CLI::IsMember({"analytic", "diffraction", "closed-loop"}));
  cmd->add_option("--offset", args->offsets, "DM offset J=NM: Noll index J, wavefront OPD RMS in nm (repeatable)");
  cmd->add_option("-r,--factor", args->r, "HR factor: pixel = camera pixel / r")->capture_default_str()->check(CLI::Range(1, 16));
  cmd->add_option("--pixel-lod", args->pixel_lod, "pixel scale in lambda/D (overrides -r)")->check(NonNegativeFinite());
  cmd->add_option("--size", args->size, "PSF side in pixels")->capture_default_str()->check(CLI::Range(8, 4096));
  cmd->add_option("-o,--output", args->output, "write the PSF as FITS (float64)");
  cmd->add_flag("--json", args->json, "print the results as JSON");
  cmd->add_option("--sensor", args->sensor, "closed loop: ideal | geometric | diffractive Shack-Hartmann")
      ->capture_default_str()->check(CLI::IsMember({"ideal", "geometric", "diffractive"}));
  cmd->add_option("--exposure", args->exposure_s, "closed loop: recorded time [s]")->capture_default_str()
      ->check(CLI::Range(1e-4, 3600.0));
  cmd->add_option("--settling", args->settling_s, "closed loop: unrecorded time first [s]")->capture_default_str()
      ->check(NonNegativeFinite());
  cmd->add_option("--seed", args->seed, "closed loop: atmosphere and noise seed")->capture_default_str();
  cmd->add_flag("--antithetic,!--no-antithetic", args->antithetic,
                "closed loop: average the PSFs of the atmosphere and of its negation (default; the stretch's random "
                "tip/tilt cancels, as in a scene), or --no-antithetic for one realisation in half the time");
  cmd->add_option("--field-angle", args->field_angle_arcsec,
                  "science direction: A arcsec from the guide star along +x (anisoplanatism; default 0, on axis)");
  cmd->add_option("--field-direction", args->field_direction,
                  "science direction X,Y in arcsec from the guide star (x along columns, y along rows)");
  AddExecutionOptions(cmd, &args->exec);
  cmd->callback([args] { RunPsf(*args); });
}

}  // namespace aosr::cli
