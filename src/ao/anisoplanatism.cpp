#include "aosr/ao/anisoplanatism.hpp"

#include <cmath>
#include <limits>
#include <string>

#include "aosr/core/error.hpp"

namespace aosr {
namespace {

// 6.8839^(-3/5): the structure function constant 2 [24/5 Gamma(6/5)]^(5/6) to the power -3/5.
double AnisoplanatismThetaZeroConstant() {
  const double c = 2.0 * std::pow(24.0 / 5.0 * std::tgamma(6.0 / 5.0), 5.0 / 6.0);
  return std::pow(c, -3.0 / 5.0);
}

}  // namespace

double EffectiveTurbulenceAltitudeM(const std::vector<Layer>& layers) {
  const char* fn = "EffectiveTurbulenceAltitudeM";
  CheckArgument(!layers.empty(), fn, "layers", "empty", "at least one layer");
  double sum = 0.0, fractions = 0.0;
  for (std::size_t l = 0; l < layers.size(); ++l) {
    const Layer& layer = layers[l];
    const std::string name = "layers[" + std::to_string(l) + "]";
    CheckArgument(std::isfinite(layer.altitude_m) && layer.altitude_m >= 0.0, fn, name + ".altitude_m",
                  layer.altitude_m, ">= 0 and finite [m]");
    CheckArgument(layer.cn2_fraction >= 0.0 && layer.cn2_fraction <= 1.0, fn, name + ".cn2_fraction",
                  layer.cn2_fraction, "[0, 1]");
    sum += layer.cn2_fraction * std::pow(layer.altitude_m, 5.0 / 3.0);
    fractions += layer.cn2_fraction;
  }
  CheckArgument(std::abs(fractions - 1.0) <= 1e-6, fn, "layers[].cn2_fraction (sum)", fractions,
                "1 (within 1e-6)");
  return std::pow(sum, 3.0 / 5.0);
}

double IsoplanaticAngleRad(double r0_m, double r0_wavelength_m, double wavelength_m,
                           const std::vector<Layer>& layers, double zenith_rad) {
  const char* fn = "IsoplanaticAngleRad";
  CheckArgument(std::isfinite(r0_m) && r0_m > 0.0, fn, "r0_m", r0_m, "> 0 and finite [m]");
  CheckArgument(std::isfinite(r0_wavelength_m) && r0_wavelength_m > 0.0, fn, "r0_wavelength_m",
                r0_wavelength_m, "> 0 and finite [m]");
  CheckArgument(std::isfinite(wavelength_m) && wavelength_m > 0.0, fn, "wavelength_m", wavelength_m,
                "> 0 and finite [m]");
  CheckArgument(zenith_rad >= 0.0 && zenith_rad < 0.5 * kPi, fn, "zenith_rad", zenith_rad,
                "[0, pi/2) [rad]");
  const double h_bar = EffectiveTurbulenceAltitudeM(layers);
  if (h_bar == 0.0) return std::numeric_limits<double>::infinity();
  const double cos_z = std::cos(zenith_rad);
  // r0 along the line of sight: r0 cos(zeta)^(3/5); layers at h sec(zeta) from the telescope.
  const double r0 = r0_m * std::pow(wavelength_m / r0_wavelength_m, 6.0 / 5.0) * std::pow(cos_z, 3.0 / 5.0);
  return AnisoplanatismThetaZeroConstant() * r0 / (h_bar / cos_z);
}

double FriedAnisoplanaticVarianceRad2(double theta_rad, double theta0_rad) {
  const char* fn = "FriedAnisoplanaticVarianceRad2";
  CheckArgument(std::isfinite(theta_rad) && theta_rad >= 0.0, fn, "theta_rad", theta_rad, ">= 0 and finite");
  CheckArgument(theta0_rad > 0.0, fn, "theta0_rad", theta0_rad, "> 0 (+inf: no anisoplanatism)");
  if (std::isinf(theta0_rad)) return 0.0;
  return std::pow(theta_rad / theta0_rad, 5.0 / 3.0);
}

TiltVariance ZernikeTiltVariance(const Image& psd, double df_per_m, double diameter_m, double axis_angle_rad) {
  const char* fn = "ZernikeTiltVariance";
  CheckArgument(psd.rows() >= 2 && psd.rows() == psd.cols() && psd.rows() % 2 == 0, fn, "psd shape",
                ToString(ShapeOf(psd)), "a square grid of even side");
  CheckArgument(AllFinite(psd), fn, "psd", "non-finite values", "finite values");
  CheckArgument(std::isfinite(df_per_m) && df_per_m > 0.0, fn, "df_per_m", df_per_m, "> 0 and finite");
  CheckArgument(std::isfinite(diameter_m) && diameter_m > 0.0, fn, "diameter_m", diameter_m, "> 0 and finite");
  CheckArgument(std::isfinite(axis_angle_rad), fn, "axis_angle_rad", axis_angle_rad, "finite [rad]");
  const Index p = psd.rows(), c = p / 2;
  const double ca = std::cos(axis_angle_rad), sa = std::sin(axis_angle_rad);
  TiltVariance out;
  for (Index i = 0; i < p; ++i) {
    const double fy = static_cast<double>(i - c) * df_per_m;
    for (Index j = 0; j < p; ++j) {
      const double v = psd(i, j);
      if (v == 0.0) continue;
      const double fx = static_cast<double>(j - c) * df_per_m;
      const double f = std::hypot(fx, fy);
      if (f == 0.0) continue;
      const double u = kPi * diameter_m * f;
      const double airy = 2.0 * std::cyl_bessel_j(2.0, u) / u;
      const double radial = 2.0 * airy * airy;  // (n + 1) [2 J_2(u)/u]^2, n = 1
      const double cos_par = (fx * ca + fy * sa) / f;
      out.parallel_rad2 += v * radial * 2.0 * cos_par * cos_par;
      out.perpendicular_rad2 += v * radial * 2.0 * (1.0 - cos_par * cos_par);
    }
  }
  out.parallel_rad2 *= df_per_m * df_per_m;
  out.perpendicular_rad2 *= df_per_m * df_per_m;
  return out;
}

double TiltCoefficientToAngleRad(double coefficient_rad, double wavelength_m, double diameter_m) {
  CheckArgument(std::isfinite(wavelength_m) && wavelength_m > 0.0, "TiltCoefficientToAngleRad", "wavelength_m",
                wavelength_m, "> 0 and finite [m]");
  CheckArgument(std::isfinite(diameter_m) && diameter_m > 0.0, "TiltCoefficientToAngleRad", "diameter_m",
                diameter_m, "> 0 and finite [m]");
  return 2.0 * coefficient_rad * wavelength_m / (kPi * diameter_m);
}

}  // namespace aosr
