#include "aosr/scene/photometry.hpp"

#include <cmath>

#include "aosr/core/error.hpp"

namespace aosr {
namespace {

constexpr double kPlanck = 6.62607015e-34;   // J s (exact, SI 2019)
constexpr double kLightSpeed = 299792458.0;  // m s⁻¹ (exact)
constexpr double kArcsecRad = M_PI / (180.0 * 3600.0);

// f_λ published in W m⁻² µm⁻¹; stored in W m⁻² m⁻¹ (× 1e6).
PhotometricBand MakeBand(const char* name, double lambda_um, double width_um, double f_lambda_w_m2_um,
                         const char* reference) {
  PhotometricBand b;
  b.name = name;
  b.effective_wavelength_m = lambda_um * 1e-6;
  b.bandwidth_m = width_um * 1e-6;
  b.flux_density_w_m3 = f_lambda_w_m2_um * 1e6;
  b.zero_point_photons =
      b.flux_density_w_m3 * b.bandwidth_m * b.effective_wavelength_m / (kPlanck * kLightSpeed);
  b.reference = reference;
  return b;
}

const std::vector<PhotometricBand>& Table() {
  static const std::vector<PhotometricBand> table = [] {
    const char* b98 = "Bessell, Castelli & Plez 1998, A&A 333, 231, Table A2";
    const char* c03 = "Cohen, Wheaton & Megeath 2003, AJ 126, 1090, Table 2 (2MASS)";
    // f_λ(B98) in 1e-11 erg cm⁻² s⁻¹ Å⁻¹ = 1e-10 W m⁻² µm⁻¹.
    return std::vector<PhotometricBand>{
        MakeBand("U", 0.360, 0.060, 417.5e-10, b98), MakeBand("B", 0.438, 0.090, 632.0e-10, b98),
        MakeBand("V", 0.545, 0.085, 363.1e-10, b98), MakeBand("R", 0.641, 0.150, 217.7e-10, b98),
        MakeBand("I", 0.798, 0.150, 112.6e-10, b98), MakeBand("J", 1.220, 0.260, 31.47e-10, b98),
        MakeBand("H", 1.630, 0.290, 11.38e-10, b98), MakeBand("K", 2.190, 0.410, 3.961e-10, b98),
        // C03: 4.283e-14 W cm⁻² µm⁻¹ = 4.283e-10 W m⁻² µm⁻¹.
        MakeBand("Ks", 2.159, 0.262, 4.283e-10, c03)};
  }();
  return table;
}


void CheckCollector(const char* function, const LightCollectorOptions& collector) {
  std::string why;
  if (!collector.IsValid(&why)) throw InvalidArgument(std::string(function) + ": collector." + why);
}

}  // namespace

const PhotometricBand& VegaBand(const std::string& name) {
  for (const PhotometricBand& b : Table())
    if (b.name == name) return b;
  std::string known;
  for (const PhotometricBand& b : Table()) known += (known.empty() ? "" : ", ") + b.name;
  throw InvalidArgument("VegaBand", "band", "\"" + name + "\"", "one of " + known);
}

std::vector<std::string> VegaBandNames() {
  std::vector<std::string> names;
  for (const PhotometricBand& b : Table()) names.push_back(b.name);
  return names;
}

double PhotonIrradiance(double magnitude, const PhotometricBand& band) {
  CheckArgument(std::isfinite(magnitude), "PhotonIrradiance", "magnitude", magnitude, "finite");
  CheckArgument(band.zero_point_photons > 0 && std::isfinite(band.zero_point_photons), "PhotonIrradiance",
                "band.zero_point_photons", band.zero_point_photons, "finite and > 0");
  return band.zero_point_photons * std::pow(10.0, -0.4 * magnitude);
}

double MagnitudeFromIrradiance(double photons_per_s_m2, const PhotometricBand& band) {
  CheckArgument(photons_per_s_m2 > 0 && std::isfinite(photons_per_s_m2), "MagnitudeFromIrradiance",
                "photons_per_s_m2", photons_per_s_m2, "finite and > 0");
  CheckArgument(band.zero_point_photons > 0 && std::isfinite(band.zero_point_photons),
                "MagnitudeFromIrradiance", "band.zero_point_photons", band.zero_point_photons,
                "finite and > 0");
  return -2.5 * std::log10(photons_per_s_m2 / band.zero_point_photons);
}

bool LightCollectorOptions::IsValid(std::string* why) const {
  if (!(collecting_area_m2 >= 0 && std::isfinite(collecting_area_m2)))
    return Fail(why, "collecting_area_m2 must be finite and >= 0 (0: from diameter_m), got " +
                         ToString(collecting_area_m2));
  if (collecting_area_m2 == 0) {
    if (!(diameter_m > 0 && std::isfinite(diameter_m)))
      return Fail(why, "diameter_m must be finite and > 0, got " + ToString(diameter_m));
    if (!(obstruction >= 0 && obstruction < 1))
      return Fail(why, "obstruction must be in [0, 1), got " + ToString(obstruction));
  }
  if (!(throughput > 0 && throughput <= 1))
    return Fail(why, "throughput must be in (0, 1], got " + ToString(throughput));
  return true;
}

double LightCollectorOptions::Area() const {
  if (collecting_area_m2 > 0) return collecting_area_m2;
  return 0.25 * M_PI * diameter_m * diameter_m * (1.0 - obstruction * obstruction);
}

bool ExposurePlan::IsValid(std::string* why) const {
  if (!(total_time_s > 0 && std::isfinite(total_time_s)))
    return Fail(why, "total_time_s must be finite and > 0, got " + ToString(total_time_s));
  if (frames < 1) return Fail(why, "frames must be >= 1, got " + std::to_string(frames));
  return true;
}

SourceFlux SourceFlux::Magnitude(double magnitude, std::string band) {
  SourceFlux s;
  s.kind = Kind::kMagnitude;
  s.magnitude = magnitude;
  s.band = std::move(band);
  return s;
}

SourceFlux SourceFlux::Irradiance(double photons_per_s_m2) {
  SourceFlux s;
  s.kind = Kind::kIrradiance;
  s.value = photons_per_s_m2;
  return s;
}

SourceFlux SourceFlux::DetectedRate(double electrons_per_s) {
  SourceFlux s;
  s.kind = Kind::kDetectedRate;
  s.value = electrons_per_s;
  return s;
}

double DetectedElectronRate(const SourceFlux& source, const LightCollectorOptions& collector) {
  if (source.kind == SourceFlux::Kind::kDetectedRate) {
    CheckArgument(source.value >= 0 && std::isfinite(source.value), "DetectedElectronRate", "source.value",
                  source.value, "finite and >= 0 electrons/s");
    return source.value;
  }
  CheckCollector("DetectedElectronRate", collector);
  double irradiance = 0;
  if (source.kind == SourceFlux::Kind::kMagnitude) {
    irradiance = PhotonIrradiance(source.magnitude, VegaBand(source.band));
  } else {
    CheckArgument(source.value >= 0 && std::isfinite(source.value), "DetectedElectronRate", "source.value",
                  source.value, "finite and >= 0 photons/s/m^2");
    irradiance = source.value;
  }
  return irradiance * collector.Area() * collector.throughput;
}

double ElectronsPerFrame(const SourceFlux& source, const LightCollectorOptions& collector,
                         const ExposurePlan& plan) {
  std::string why;
  if (!plan.IsValid(&why)) throw InvalidArgument("ElectronsPerFrame: plan." + why);
  return DetectedElectronRate(source, collector) * plan.FrameTime();
}

double SkyBackgroundRate(double magnitude_per_arcsec2, const PhotometricBand& band,
                         const LightCollectorOptions& collector, double pixel_scale_rad, double fill_factor) {
  CheckCollector("SkyBackgroundRate", collector);
  CheckArgument(pixel_scale_rad > 0 && std::isfinite(pixel_scale_rad), "SkyBackgroundRate", "pixel_scale_rad",
                pixel_scale_rad, "finite and > 0");
  CheckArgument(fill_factor > 0 && fill_factor <= 1, "SkyBackgroundRate", "fill_factor", fill_factor,
                "(0, 1]");
  const double pixel_arcsec = pixel_scale_rad / kArcsecRad;
  return PhotonIrradiance(magnitude_per_arcsec2, band) * collector.Area() * collector.throughput *
         pixel_arcsec * pixel_arcsec * fill_factor * fill_factor;
}

}  // namespace aosr
