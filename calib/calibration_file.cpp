#include "aosr/calib/calibration_file.hpp"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <map>

#include "aosr/core/error.hpp"
#include "aosr/io/atomic_file.hpp"
#include "aosr/io/config.hpp"

namespace aosr {
namespace {

nlohmann::json StaticJson(const std::vector<int>& modes, const std::vector<double>& values_m,
                          const std::vector<double>& sigmas_m) {
  nlohmann::json j = nlohmann::json::object();
  for (std::size_t k = 0; k < modes.size(); ++k)
    j[std::to_string(modes[k])] = {{"value", values_m[k] * 1e9}, {"sigma", sigmas_m[k] * 1e9}};
  return j;
}

nlohmann::json FitJson(const ModalFitResult& r, std::size_t frames) {
  return {{"gain", r.gain},
          {"gain_sigma", r.gain_sigma},
          {"reduced_chi2", r.reduced_chi2},
          {"chi2", r.chi2},
          {"dof", r.dof},
          {"covariance_scale", r.covariance_scale},
          {"iterations", r.iterations},
          {"termination", ToString(r.termination)},
          {"message", r.message},
          {"frames", frames}};
}

}  // namespace

nlohmann::json CalibrationToJson(const CalibrationSet& set, const CalibrationResult& result) {
  nlohmann::json j;
  j["format"] = kCalibrationFormat;
  j["set"] = set.source;
  j["telescope"] = set.telescope;
  j["wavelength_m"] = set.optics.wavelength_m;
  j["pixel_lambda_over_d"] = set.optics.pixel_lambda_over_d;
  j["frame_px"] = {set.shape().rows, set.shape().cols};
  j["masked_pixels"] = set.masked_pixels;
  // The set's "truth" is free-form provenance (a manifest may hold anything there, and a synthetic set names its
  // actuator-pattern modes by string): only {"mode": Noll integer, "gain": number} entries give a true gain.
  std::map<int, double> truth_gain;
  if (set.truth.is_object() && set.truth.contains("modes") && set.truth.at("modes").is_array())
    for (const auto& m : set.truth.at("modes"))
      if (m.is_object() && m.contains("mode") && m.at("mode").is_number_integer() && m.contains("gain") &&
          m.at("gain").is_number())
        truth_gain[int(std::clamp<long long>(m.at("mode").get<long long>(), -1, 1 << 20))] = m.at("gain").get<double>();
  double worst_chi2 = 0;
  bool all_converged = true;
  j["modes"] = nlohmann::json::array();
  for (const ModeCalibration& mc : result.modes) {
    const ModalFitResult& f = mc.final_fit;
    nlohmann::json m;
    m["mode"] = mc.noll > 0 ? nlohmann::json(mc.noll) : nlohmann::json(mc.name);
    m["name"] = mc.name;
    m["gain"] = f.gain;
    m["gain_sigma"] = f.gain_sigma;
    const LinearityReport& lin = mc.linearity;
    if (!lin.levels.empty()) {
      m["linear_range_nm"] = {0.0, lin.linear_max_m * 1e9};
      m["onset_nm"] = lin.onset_m > 0 ? nlohmann::json(lin.onset_m * 1e9) : nlohmann::json();
      m["verdict"] = lin.verdict;
      m["linear_fit"] = {{"gain", lin.fit_gain}, {"rms_nm", lin.fit_rms_m * 1e9}, {"reduced_chi2", lin.fit_reduced_chi2}};
      m["per_amplitude"] = nlohmann::json::array();
      for (const AmplitudeGain& l : lin.levels)
        m["per_amplitude"].push_back({{"amplitude_nm", l.amplitude_m * 1e9},
                                      {"gain", l.gain},
                                      {"gain_sigma", l.sigma},
                                      {"frames", l.frames},
                                      {"converged", l.converged}});
    }
    m["fit"] = FitJson(f, mc.final_frames.size());
    m["joint_fit"] = FitJson(mc.joint, mc.frames.size());
    m["refit_on_linear_range"] = mc.refit;
    m["position_px"] = {f.dy_px, f.dx_px};
    m["position_sigma_px"] = {f.dy_sigma_px, f.dx_sigma_px};
    m["source_sigma_px"] = f.source_sigma_px;
    m["source_sigma_sigma_px"] = f.source_sigma_sigma_px;
    m["static_nm"] = StaticJson(f.static_modes, f.static_m, f.static_sigma_m);
    if (mc.noll > 0 && truth_gain.count(mc.noll)) {
      const double t = truth_gain[mc.noll];
      m["truth_gain"] = t;
      m["pull"] = f.gain_sigma > 0 ? (f.gain - t) / f.gain_sigma : 0.0;
    }
    worst_chi2 = std::max(worst_chi2, f.reduced_chi2);
    all_converged = all_converged && f.termination == Termination::kConverged;
    j["modes"].push_back(m);
  }
  j["static_aberration_nm"] = StaticJson(result.static_modes, result.static_m, result.static_sigma_m);
  j["fit_quality"] = {{"worst_reduced_chi2", worst_chi2},
                      {"all_converged", all_converged}};
  if (!set.truth.is_null()) j["truth"] = set.truth;
  return j;
}

void WriteCalibrationJson(const std::string& path, const nlohmann::json& json) {
  const std::string text = json.dump(2) + "\n";
  AtomicWrite(path, [&](const std::string& tmp) {
    std::ofstream out(tmp);
    out << text;
    if (!out) throw IoError(tmp, "write failed");
  });
}

const ModeGain* Calibration::FindNoll(int j) const {
  for (const ModeGain& m : modes)
    if (m.noll == j) return &m;
  return nullptr;
}

Calibration LoadCalibration(const std::string& path) {
  const nlohmann::json json = ReadJsonFile(path);
  const ConfigNode root(json, path);
  const std::string format = root.String("format");
  if (format != kCalibrationFormat) root.Fail("format", format, kCalibrationFormat);
  Calibration c;
  c.source = path;
  const nlohmann::json& modes = json.contains("modes") ? json["modes"] : nlohmann::json();
  if (!modes.is_array() || modes.empty()) root.Fail("modes", modes.dump(), "a non-empty array of calibrated modes");
  for (std::size_t i = 0; i < modes.size(); ++i) {
    const ConfigNode m(modes[i], path, "modes[" + std::to_string(i) + "]");
    ModeGain g;
    if (modes[i].contains("mode") && modes[i]["mode"].is_number_integer()) g.noll = int(m.Integer("mode", 2, 100000));
    g.name = m.StringOr("name", g.noll > 0 ? "Z" + std::to_string(g.noll) : "");
    g.gain = m.Number("gain", -1e300, 1e300);
    if (!(std::isfinite(g.gain) && g.gain > 0)) m.Fail("gain", ToString(g.gain), "finite and > 0 (a DM mode that applies power)");
    g.gain_sigma = m.NumberOr("gain_sigma", 0.0, 0.0, 1e300);
    if (modes[i].contains("linear_range_nm")) g.linear_max_m = m.Numbers("linear_range_nm", 0, 1e12, 2, 2)[1] * 1e-9;
    g.verdict = m.StringOr("verdict", "");
    c.modes.push_back(g);  // other fields are informative; not checked
  }
  return c;
}

namespace {

// Scales each calibrated Zernike term (and the tip/tilt shift, made with Z2/Z3) by 1/g (command from design)
// or by g (what the DM applies for a command). Notes list what is left unscaled or beyond the linear range.
DmOffset ScaleByGains(const DmOffset& offset, const Calibration& cal, bool divide, std::vector<std::string>* notes) {
  DmOffset out = offset;
  auto note = [notes](const std::string& s) {
    if (notes) notes->push_back(s);
  };
  auto scale = [&](int j, double* value, const std::string& what) {
    if (*value == 0.0) return;
    const ModeGain* g = cal.FindNoll(j);
    if (!g) {
      note(what + ": Z" + std::to_string(j) + " is not in the calibration; left unscaled");
      return;
    }
    *value = divide ? *value / g->gain : *value * g->gain;
  };
  scale(2, &out.shift_x_px, "shift_x_px");
  scale(3, &out.shift_y_px, "shift_y_px");
  for (DmOffset::Term& t : out.zernike) {
    const double commanded = divide ? t.rms_m / (cal.FindNoll(t.noll) ? cal.FindNoll(t.noll)->gain : 1.0) : t.rms_m;
    scale(t.noll, &t.rms_m, "zernike term");
    const ModeGain* g = cal.FindNoll(t.noll);
    if (g && g->linear_max_m > 0 && std::abs(commanded) > g->linear_max_m)
      note("Z" + std::to_string(t.noll) + ": commanded " + ToString(std::abs(commanded) * 1e9) +
           " nm exceeds the measured linear range " + ToString(g->linear_max_m * 1e9) + " nm");
  }
  if (!out.actuators_m.empty()) note("actuator commands are left unscaled (the calibration is modal)");
  return out;
}

}  // namespace

DmOffset ApplyCalibration(const DmOffset& design, const Calibration& cal, std::vector<std::string>* notes) {
  return ScaleByGains(design, cal, true, notes);
}

DmOffset DmResponse(const DmOffset& command, const Calibration& cal, std::vector<std::string>* notes) {
  return ScaleByGains(command, cal, false, notes);
}

void ApplyCalibrationToDesignFile(const std::string& calibration_path, const std::vector<DmOffset>& designed,
                                  nlohmann::json* file, std::vector<std::string>* notes) {
  CheckArgument(file != nullptr && file->contains("frames") && (*file)["frames"].size() == designed.size(),
                "ApplyCalibrationToDesignFile", "design_file", file ? std::to_string((*file)["frames"].size()) + " frames" : "null",
                "a design file with one frame per designed offset (" + std::to_string(designed.size()) + ")");
  const Calibration cal = LoadCalibration(calibration_path);
  std::vector<std::string> local;
  std::vector<std::string>& n = notes ? *notes : local;
  const nlohmann::json designed_frames = (*file)["frames"];
  for (std::size_t i = 0; i < designed.size(); ++i) (*file)["frames"][i] = DmOffsetToJson(ApplyCalibration(designed[i], cal, &n));
  (*file)["design"]["calibration"] = {{"file", calibration_path}, {"applied_frames", designed_frames}, {"notes", n}};
}

}  // namespace aosr
