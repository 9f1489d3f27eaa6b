// Photometry: from a source's magnitude (or photon rate) to the electrons a frame collects.
//
// ## Magnitudes and zero points
//
// A source of (Vega) magnitude m in band b delivers, above the atmosphere, a photon irradiance
//
//     Φ(m) = Φ₀(b) · 10^(−0.4 m)          photons s⁻¹ m⁻² (integrated over the band)
//
// where Φ₀(b) is the band's zero point, the photon irradiance of a magnitude-0 (Vega-like) star. For a band
// of effective wavelength λ_eff and width Δλ whose magnitude-0 flux density is f_λ,
//
//     Φ₀ = f_λ · Δλ · λ_eff / (h c)                                   (a photon carries h c / λ of energy).
//
// The table (VegaBand) stores f_λ, λ_eff and Δλ as published and computes Φ₀ with the SI values of h and c:
//
//     band  λ_eff/µm  Δλ/µm   f_λ / (W m⁻² µm⁻¹)   Φ₀ / (photons s⁻¹ m⁻²)   source
//     U     0.360     0.060   4.175e-8             4.54e9                   [B98]
//     B     0.438     0.090   6.320e-8             1.25e10                  [B98]
//     V     0.545     0.085   3.631e-8             8.47e9                   [B98]
//     R     0.641     0.150   2.177e-8             1.05e10                  [B98]
//     I     0.798     0.150   1.126e-8             6.79e9                   [B98]
//     J     1.220     0.260   3.147e-9             5.03e9                   [B98]
//     H     1.630     0.290   1.138e-9             2.71e9                   [B98]
//     K     2.190     0.410   3.961e-10            1.79e9                   [B98]
//     Ks    2.159     0.262   4.283e-10            1.22e9                   [C03]
//
// [B98] Bessell, Castelli & Plez 1998, A&A 333, 231, Table A2: f_λ of a magnitude-0 star in the
//       Johnson-Cousins-Glass UBVRIJHK system and λ_eff. f_λ is published in 1e-11 erg cm⁻² s⁻¹ Å⁻¹;
//       1 erg cm⁻² s⁻¹ Å⁻¹ = 10 W m⁻² µm⁻¹, so V's 363.1 is 3.631e-8 W m⁻² µm⁻¹. The band widths Δλ are the
//       approximate widths conventionally tabulated with them (e.g. P. Martini, "Useful astronomical data",
//       paulmartini.github.io/useful-data, whose photon densities f_λ λ / (h c) = 756, 1393, 996, 702, 452,
//       193, 93.3, 43.6 photons cm⁻² s⁻¹ Å⁻¹ this table reproduces). Rectangular bands of width Δλ are
//       an approximation: expect ~10% errors in Φ₀, more for very red or very blue sources.
// [C03] Cohen, Wheaton & Megeath 2003, AJ 126, 1090, Table 2: 2MASS Ks isophotal wavelength, f_λ
//       (4.283e-14 W cm⁻² µm⁻¹) and bandwidth. Ks is the filter of most K-band AO imagers.
//
// Hand check (K, m = 12): Φ = 1.790e9 · 10^−4.8 = 2.84e4 photons s⁻¹ m⁻².
//
// ## From irradiance to electrons
//
// A telescope of diameter D with a central obstruction of linear fraction ε collects over
//
//     A = (π/4) D² (1 − ε²)                                           (spiders ignored; or give A directly)
//
// and a fraction τ (throughput: atmosphere, mirrors, instrument, filter in-band transmission and detector
// quantum efficiency together) of the photons becomes electrons:
//
//     rate = Φ(m) · A · τ   electrons s⁻¹,       per frame: rate · T / N   for T seconds split over N frames.
//
// The object on the HR grid is then scaled so its sum is the per-frame count; the forward model is
// flux-conserving (D_r sums HR pixels), so the camera frames carry exactly those electrons (less what falls
// outside the field or, with a fill factor < 1, on insensitive pixel area: see detector.hpp).
//
// ## Sky background
//
// A sky of surface brightness μ magnitudes per arcsec² puts on one camera pixel of angular side θ
//
//     B = Φ(μ) · A · τ · (θ / 1")² · F²    electrons s⁻¹ pixel⁻¹
//
// where F is the detector's linear fill factor (detector.hpp), F² the sensitive fraction of the pixel area.
//
// Errors: aosr::InvalidArgument naming the function and the argument (an unknown band lists the known ones).
#pragma once

#include <string>
#include <vector>

namespace aosr {

// One photometric band of the zero-point table (see the top of this file).
struct PhotometricBand {
  std::string name;                     // "U", "B", ..., "K", "Ks"
  double effective_wavelength_m = 0.0;  // λ_eff
  double bandwidth_m = 0.0;             // Δλ (width of the equivalent rectangular band)
  double flux_density_w_m3 = 0.0;       // f_λ of a magnitude-0 star, W m⁻² per metre of wavelength
  double zero_point_photons = 0.0;  // Φ₀ = f_λ Δλ λ_eff / (h c), photons s⁻¹ m⁻² for magnitude 0
  std::string reference;            // where f_λ, λ_eff and Δλ come from
};

// The Vega zero-point band called `name` (case-sensitive: "U", "B", "V", "R", "I", "J", "H", "K", "Ks").
// Throws InvalidArgument naming `name` and listing the known bands.
const PhotometricBand& VegaBand(const std::string& name);
// Names of the tabulated bands, blue to red.
std::vector<std::string> VegaBandNames();

// Photon irradiance Φ₀ 10^(−0.4 m) of a magnitude-m source in `band`, photons s⁻¹ m⁻². m finite.
double PhotonIrradiance(double magnitude, const PhotometricBand& band);
// Magnitude of a source of photon irradiance `photons_per_s_m2` (> 0) in `band`: the inverse of the above.
double MagnitudeFromIrradiance(double photons_per_s_m2, const PhotometricBand& band);

// The light collector: what turns photon irradiance into detected electrons.
struct LightCollectorOptions {
  // Entrance-pupil diameter in metres, > 0. Default 8 m: the paper's telescope class (VLT/Gemini/Subaru).
  double diameter_m = 8.0;
  // Central obstruction as a linear fraction of the diameter, in [0, 1). Default 0.14 (VLT-like secondary).
  double obstruction = 0.14;
  // Collecting area in m². 0 (default): computed as (π/4) D² (1 − obstruction²). > 0: used as given
  // (e.g. a segmented or spidered pupil's measured area), and diameter/obstruction are then ignored here.
  double collecting_area_m2 = 0.0;
  // Fraction of photons at the entrance pupil that become electrons in the detector, in (0, 1]:
  // atmosphere × telescope × instrument × filter transmission × detector QE. Default 0.3, a typical
  // end-to-end near-IR AO imager value; set 1 to count photons at the pupil.
  double throughput = 0.3;

  // True if every field is in range; otherwise false and, if why != nullptr, *why names the field.
  bool IsValid(std::string* why) const;
  // The collecting area A in m² (see collecting_area_m2).
  double Area() const;
};

// How a total integration is split: `total_time_s` seconds over `frames` equal frames.
struct ExposurePlan {
  // Total integration in seconds, > 0. Default 10 s.
  double total_time_s = 10.0;
  // Number of frames sharing it, >= 1. Default 1.
  int frames = 1;

  bool IsValid(std::string* why) const;
  double FrameTime() const { return total_time_s / frames; }
};

// A source's brightness, either as a magnitude in a band or as a photon rate.
struct SourceFlux {
  enum class Kind {
    kMagnitude,     // `magnitude` in `band` (Vega system)
    kIrradiance,    // `value` photons s⁻¹ m⁻² at the entrance pupil (goes through area and throughput)
    kDetectedRate,  // `value` electrons s⁻¹ already detected (bypasses the telescope: a lab source)
  };
  Kind kind = Kind::kMagnitude;
  double magnitude = 0.0;
  std::string band = "K";
  double value = 0.0;

  static SourceFlux Magnitude(double magnitude, std::string band);
  static SourceFlux Irradiance(double photons_per_s_m2);
  static SourceFlux DetectedRate(double electrons_per_s);
};

// Detected electrons per second from `source` through `collector` (validated). Magnitudes must be finite,
// rates finite and >= 0, the band known.
double DetectedElectronRate(const SourceFlux& source, const LightCollectorOptions& collector);

// Electrons one frame of `plan` collects: DetectedElectronRate · total_time_s / frames. E.g. "magnitude 12
// in K, 10 s over 16 frames" is ElectronsPerFrame(SourceFlux::Magnitude(12, "K"), collector, {10.0, 16}).
double ElectronsPerFrame(const SourceFlux& source, const LightCollectorOptions& collector,
                         const ExposurePlan& plan);

// Sky background in electrons s⁻¹ per camera pixel from a surface brightness of `magnitude_per_arcsec2` in
// `band`, for camera pixels of angular side `pixel_scale_rad` (> 0) with linear fill factor `fill_factor`
// in (0, 1] (only the sensitive area F² of the pixel collects sky).
double SkyBackgroundRate(double magnitude_per_arcsec2, const PhotometricBand& band,
                         const LightCollectorOptions& collector, double pixel_scale_rad,
                         double fill_factor = 1.0);

}  // namespace aosr
