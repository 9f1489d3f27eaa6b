#include "aosr/scene/preset_psf.hpp"

#include <algorithm>
#include <cmath>
#include <memory>

#include "aosr/ao/analytic_ao.hpp"
#include "aosr/ao/anisoplanatism.hpp"
#include "aosr/ao/closed_loop.hpp"
#include "aosr/core/error.hpp"
#include "aosr/optics/psf_metrics.hpp"
#include "aosr/optics/zernike.hpp"

namespace aosr {
namespace {
constexpr double kPresetPsfArcsecPerRad = 180.0 * 3600.0 / M_PI;
}  // namespace

bool PresetPsfOptions::IsValid(std::string* why) const {
  auto fail = [why](const std::string& m) {
    if (why) *why = m;
    return false;
  };
  if (!mode.empty() && mode != "analytic" && mode != "diffraction" && mode != "closed-loop")
    return fail("mode = " + mode + "; allowed: analytic | diffraction | closed-loop (or empty: automatic)");
  for (const Offset& o : offsets)
    if (o.noll < 2 || o.noll > 1000 || !std::isfinite(o.rms_nm))
      return fail("offset " + std::to_string(o.noll) + "=" + ToString(o.rms_nm) +
                  "; allowed: Noll index 2..1000 and a finite coefficient in nm RMS");
  if (r < 1 || r > 16) return fail("r = " + std::to_string(r) + "; allowed: 1..16");
  if (!(pixel_lod >= 0) || !std::isfinite(pixel_lod)) return fail("pixel_lod = " + ToString(pixel_lod) + "; allowed: >= 0 (0: camera pixel / r)");
  if (size < 8 || size > 4096) return fail("size = " + std::to_string(size) + "; allowed: 8..4096");
  if (!(exposure_s >= 1e-4 && exposure_s <= 3600)) return fail("exposure_s = " + ToString(exposure_s) + "; allowed: 1e-4..3600");
  if (!(settling_s >= 0) || !std::isfinite(settling_s)) return fail("settling_s = " + ToString(settling_s) + "; allowed: >= 0");
  if (!(std::isfinite(field_direction.x_rad) && std::isfinite(field_direction.y_rad) &&
        field_direction.Norm() <= 0.01))
    return fail("field_direction = (" + ToString(field_direction.x_rad * kPresetPsfArcsecPerRad) + ", " +
                ToString(field_direction.y_rad * kPresetPsfArcsecPerRad) +
                ") arcsec; allowed: finite, at most 0.01 rad = 2062.6 arcsec from the guide star");
  return true;
}

namespace {

PsfSampling Sampling(const TelescopePreset& preset, const PresetPsfOptions& o) {
  PsfSampling s;
  s.wavelength_m = preset.science_wavelength_m;
  s.pixel_scale_rad = o.pixel_lod > 0 ? o.pixel_lod * preset.LambdaOverD() : preset.camera_pixel_rad / o.r;
  s.rows = s.cols = o.size;
  return s;
}

}  // namespace

int MaxPresetPsfSize(const TelescopePreset& preset, const PresetPsfOptions& options) {
  const double pitch_lod = Sampling(preset, options).PixelScaleLambdaOverD(preset.aperture.pupil.diameter_m);
  return int(double(preset.pupil_px) / pitch_lod);
}

std::string FieldDirectionLimit(const TelescopePreset& preset, const std::string& mode, FieldDirection direction) {
  const double theta = direction.Norm();
  if (!std::isfinite(theta)) return "a finite direction";
  if (theta > 0.01) return "at most 0.01 rad = 2062.6 arcsec from the guide star";
  if (theta == 0.0 || !preset.atmosphere) return "";
  double reach = 0.0;  // the largest displacement h |θ| of a turbulent layer [m]
  for (const Layer& l : preset.atmosphere->layers)
    if (l.cn2_fraction > 0) reach = std::max(reach, l.altitude_m * theta);
  if (reach == 0.0) return "";
  const double diameter = preset.aperture.pupil.diameter_m;
  const double per_unit = reach / theta;  // displacement per radian
  if (mode == "analytic") {
    // The PSD grid (frequency_padding K, at most 4096 / n) must resolve the anisoplanatism filter:
    // h |θ| <= K D / 4 (analytic_ao.hpp).
    const int largest = int(4096 / preset.pupil_px);
    if (reach > largest * diameter / 4.0 + 1e-12)
      return "at most " + ToString(largest * diameter / 4.0 / per_unit * kPresetPsfArcsecPerRad) +
             " arcsec from the guide star in analytic mode (the PSD grid of a " + std::to_string(preset.pupil_px) +
             "-pixel pupil cannot resolve the anisoplanatism of the highest layer beyond it)";
  } else if (mode == "closed-loop") {
    // The phase screens carry a margin of h |θ| / (D / n) + 1 pixels, at most 1024 (atmosphere.cpp).
    const double pitch = diameter / double(preset.pupil_px);
    if (reach / pitch + 1.0 > 1024.0)
      return "at most " + ToString(1023.0 * pitch / per_unit * kPresetPsfArcsecPerRad) +
             " arcsec from the guide star in closed-loop mode (the phase screens' margin for the highest layer)";
  }
  return "";
}

AnalyticAoOptions AnalyticAoAt(const TelescopePreset& preset, FieldDirection direction, const char* function,
                               const std::string& field) {
  AnalyticAoOptions analytic = preset.ToAnalyticAo();
  if (direction.IsZero()) return analytic;
  const std::string limit = FieldDirectionLimit(preset, "analytic", direction);
  if (!limit.empty())
    throw InvalidArgument(function, field,
                          "(" + ToString(direction.x_rad * kPresetPsfArcsecPerRad) + ", " +
                              ToString(direction.y_rad * kPresetPsfArcsecPerRad) + ") arcsec",
                          limit);
  analytic.field_direction = direction;
  // The PSD grid must resolve the anisoplanatism filter: h |theta| <= K D / 4 (analytic_ao.hpp).
  double reach = 0.0;
  for (const Layer& l : analytic.layers)
    if (l.cn2_fraction > 0) reach = std::max(reach, l.altitude_m * direction.Norm());
  const int needed = int(std::ceil(4.0 * reach / analytic.diameter_m - 1e-9));
  analytic.frequency_padding = std::max(analytic.frequency_padding, needed);
  return analytic;
}

SensorKind ParseSensorKind(const std::string& name) {
  if (name == "ideal") return SensorKind::kIdeal;
  if (name == "geometric") return SensorKind::kGeometric;
  if (name == "diffractive") return SensorKind::kDiffractive;
  throw InvalidArgument("ParseSensorKind", "sensor", name, "ideal | geometric | diffractive");
}

PresetPsf ComputePresetPsf(const TelescopePreset& preset, const PresetPsfOptions& o,
                           const std::function<void(const std::string&)>& progress) {
  std::string why;
  if (!o.IsValid(&why)) throw InvalidArgument("ComputePresetPsf: invalid " + why);
  auto step = [&progress](const std::string& m) {
    if (progress) progress(m);
  };
  PresetPsf out;
  out.mode = o.mode.empty() ? (preset.atmosphere && preset.ao ? "analytic" : "diffraction") : o.mode;
  if (out.mode == "analytic" && !(preset.atmosphere && preset.ao))
    throw InvalidArgument("ComputePresetPsf", "mode", out.mode, "diffraction (preset " + preset.name + " has no atmosphere or AO)");
  if (out.mode == "closed-loop" && !preset.ao)
    throw InvalidArgument("ComputePresetPsf", "mode", out.mode, "analytic or diffraction (preset " + preset.name + " has no AO)");

  const Index n = preset.pupil_px;
  const double diameter = preset.aperture.pupil.diameter_m;
  const Image amplitude = preset.PupilAmplitude();
  Image opd = Image::Zero(n, n);
  for (const PresetPsfOptions::Offset& z : o.offsets)
    opd += z.rms_nm * 1e-9 * Zernike(z.noll, n, preset.aperture.pupil.obstruction);
  out.sampling = Sampling(preset, o);
  const PsfSampling& sampling = out.sampling;
  // The PSF of a pupil sampled by n pixels repeats every n λ/D: a wider field would show aliased copies.
  const double field_lod = o.size * sampling.PixelScaleLambdaOverD(diameter);
  if (field_lod > double(n))
    throw InvalidArgument("ComputePresetPsf", "size", std::to_string(o.size),
                          "at most " + std::to_string(int(n / sampling.PixelScaleLambdaOverD(diameter))) +
                              " pixels: the field (" + ToString(field_lod) + " lambda/D) must fit in the " +
                              std::to_string(n) + " lambda/D period of the " + std::to_string(n) + "-pixel pupil");

  step("computing the " + out.mode + " PSF of " + preset.name);
  const PsfCalculator diffraction(n, diameter, sampling);
  const Image perfect = diffraction.Compute(amplitude, Image::Zero(n, n));
  if (out.mode == "closed-loop") {
    AoSystemSpec spec = preset.ToAoSystemSpec(o.sensor, o.seed);
    // Off axis: screens wide enough for the direction (on axis: exactly the on-axis screens).
    if (spec.atmosphere) spec.atmosphere->max_field_angle_rad = o.field_direction.Norm();
    // Antithetic: the atmosphere, then its negation; the PSFs averaged, the residual variances too.
    const int runs = o.antithetic && spec.atmosphere ? 2 : 1;
    double residual_variance = 0.0;
    for (int run = 0; run < runs; ++run) {
      if (run == 1) spec.atmosphere->antithetic = true;
      const std::string which = runs == 2 ? (run == 0 ? " (the atmosphere)" : " (its negation)") : "";
      step("calibrating the AO system (interaction and control matrices)" + which);
      AoSystem system = BuildAoSystem(spec);
      ClosedLoopOptions loop_options;
      loop_options.science = sampling;
      loop_options.science_direction = o.field_direction;
      std::unique_ptr<ClosedLoop> loop = system.MakeLoop(loop_options);
      step("running the loop for " + ToString(o.settling_s) + " s settling + " + ToString(o.exposure_s) + " s" + which);
      // The DM offset is applied as the real-time computer would: through the WFS reference slopes.
      const ClosedLoopResult r = loop->RunSubExposures({opd}, o.exposure_s, o.settling_s).front();
      const double w = 1.0 / runs;
      out.psf = run == 0 ? Image(w * r.psf) : Image(out.psf + w * r.psf);
      residual_variance += w * r.RmsResidualM() * r.RmsResidualM();
      out.loop_report += (run == 0 ? "" : "; negated atmosphere: ") + r.BriefReport();
    }
    out.residual_rms_nm = std::sqrt(residual_variance) * 1e9;
  } else if (out.mode == "analytic") {
    const AnalyticAoOptions analytic = AnalyticAoAt(preset, o.field_direction, "ComputePresetPsf", "field_direction");
    const AnalyticAoPsfCalculator ao(analytic, n, sampling);
    const AnalyticAoPsf p = ao.Compute(amplitude, opd);
    out.psf = p.psf;
    out.residual_rms_nm = p.residual_rms_nm;
  } else {
    out.psf = diffraction.Compute(amplitude, opd);
  }
  if (out.psf.size() == 0 || !AllFinite(out.psf))
    throw NumericalError("ComputePresetPsf: the " + out.mode + " PSF is empty or not finite");
  const PsfStats stats = MeasurePsf(out.psf);
  out.strehl = out.psf.maxCoeff() / perfect.maxCoeff();
  out.lambda_over_d_px = preset.LambdaOverD() / sampling.pixel_scale_rad;
  out.fwhm_px = stats.fwhm_px;
  out.fwhm_major_px = stats.fwhm_major_px;
  out.fwhm_minor_px = stats.fwhm_minor_px;
  out.elongation = stats.Elongation();
  out.major_axis_angle_deg = stats.major_axis_angle_rad * 180.0 / M_PI;
  out.field_direction = o.field_direction;
  if (preset.atmosphere)
    out.isoplanatic_angle_rad = IsoplanaticAngleRad(preset.atmosphere->r0_m, preset.atmosphere->r0_wavelength_m,
                                                    preset.science_wavelength_m, preset.atmosphere->layers);
  out.window_sum = stats.window_sum;
  out.encircled_energy = EncircledEnergy(out.psf, {1.0 * out.lambda_over_d_px, 2.0 * out.lambda_over_d_px, 5.0 * out.lambda_over_d_px});
  const auto core = CoreCentroid(out.psf, 2.0 * out.lambda_over_d_px);
  out.core_centroid_lod[0] = (core.first - static_cast<double>(out.psf.rows() / 2)) / out.lambda_over_d_px;
  out.core_centroid_lod[1] = (core.second - static_cast<double>(out.psf.cols() / 2)) / out.lambda_over_d_px;
  return out;
}

}  // namespace aosr
