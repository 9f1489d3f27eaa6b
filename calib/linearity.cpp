#include "aosr/calib/linearity.hpp"

#include <algorithm>
#include <cmath>

#include "aosr/core/error.hpp"

namespace aosr {

bool LinearityOptions::IsValid(std::string* why) const {
  if (!(std::isfinite(tolerance) && tolerance > 0 && tolerance < 1)) {
    if (why) *why = "tolerance = " + ToString(tolerance) + "; allowed: in (0, 1)";
    return false;
  }
  if (!(std::isfinite(z) && z >= 0)) {
    if (why) *why = "z = " + ToString(z) + "; allowed: >= 0";
    return false;
  }
  return true;
}

LinearityReport AnalyseLinearity(std::vector<AmplitudeGain> levels, const LinearityOptions& options) {
  const char* fn = "AnalyseLinearity";
  std::string why;
  if (!options.IsValid(&why)) throw InvalidArgument(std::string(fn) + ": invalid options: " + why);
  CheckArgument(!levels.empty(), fn, "levels", "none", "at least one amplitude level");
  for (const AmplitudeGain& l : levels) {
    CheckArgument(std::isfinite(l.amplitude_m) && l.amplitude_m > 0, fn, "amplitude_m", l.amplitude_m, "> 0");
    CheckArgument(std::isfinite(l.gain), fn, "gain", l.gain, "finite");
    CheckArgument(std::isfinite(l.sigma) && l.sigma >= 0, fn, "sigma", l.sigma, ">= 0");
  }
  std::sort(levels.begin(), levels.end(),
            [](const AmplitudeGain& a, const AmplitudeGain& b) { return a.amplitude_m < b.amplitude_m; });
  LinearityReport rep;
  rep.levels = levels;

  // A σ of 0 (noiseless data) must not give infinite weights: floor at 1e-12 of the gain.
  auto var = [](const AmplitudeGain& l) { return std::max(l.sigma * l.sigma, 1e-24 * (1 + l.gain * l.gain)); };
  double sw = 0, swg = 0;
  std::size_t accepted = 0;
  for (std::size_t k = 0; k < levels.size(); ++k) {
    const AmplitudeGain& l = levels[k];
    if (k > 0) {
      const double g_ref = swg / sw, s_ref2 = 1.0 / sw;
      const double limit = std::max(options.tolerance * std::abs(g_ref), options.z * std::sqrt(l.sigma * l.sigma + s_ref2));
      if (std::abs(l.gain - g_ref) > limit) {
        rep.onset_m = l.amplitude_m;
        const double p_prev = levels[k - 1].gain * levels[k - 1].amplitude_m, p = l.gain * l.amplitude_m;
        rep.verdict = p < p_prev ? "wraps" : l.gain < g_ref ? "saturates" : "superlinear";
        break;
      }
    }
    sw += 1.0 / var(l);
    swg += l.gain / var(l);
    ++accepted;
  }
  rep.reference_gain = swg / sw;
  rep.reference_sigma = std::sqrt(1.0 / sw);
  rep.linear_max_m = accepted ? levels[accepted - 1].amplitude_m : 0.0;

  // Weighted line through the origin, p = ĝ a, with σ_p = σ_g a.
  double saa = 0, sap = 0;
  for (const AmplitudeGain& l : levels) {
    const double w = 1.0 / (var(l) * l.amplitude_m * l.amplitude_m);
    saa += w * l.amplitude_m * l.amplitude_m;
    sap += w * l.amplitude_m * (l.gain * l.amplitude_m);
  }
  rep.fit_gain = sap / saa;
  double ss = 0, chi2 = 0;
  for (const AmplitudeGain& l : levels) {
    const double r = l.gain * l.amplitude_m - rep.fit_gain * l.amplitude_m;
    ss += r * r;
    chi2 += r * r / (var(l) * l.amplitude_m * l.amplitude_m);
  }
  rep.fit_rms_m = std::sqrt(ss / double(levels.size()));
  rep.fit_reduced_chi2 = levels.size() > 1 ? chi2 / double(levels.size() - 1) : 0.0;
  return rep;
}

}  // namespace aosr
