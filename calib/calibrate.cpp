#include "aosr/calib/calibrate.hpp"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <exception>
#include <map>
#include <mutex>
#include <sstream>
#include <thread>

#include "aosr/core/error.hpp"
#include "aosr/optics/zernike.hpp"

namespace aosr {

bool CalibrateOptions::IsValid(std::string* why) const {
  std::string w;
  if (!fit.IsValid(&w)) {
    if (why) *why = "fit." + w;
    return false;
  }
  if (!linearity.IsValid(&w)) {
    if (why) *why = "linearity." + w;
    return false;
  }
  if (threads < 1 || threads > 256) {
    if (why) *why = "threads = " + ToString(threads) + "; allowed: 1..256";
    return false;
  }
  return true;
}

namespace {

ModalFitResult FitFrames(const CalibrationSet& set, const Image& shape, const std::vector<int>& frames,
                         const ModalFitOptions& options, const ModalFitStart& start) {
  std::vector<ModalFitImage> images;
  for (int i : frames) images.push_back({&set.frames[i].adu, &set.frames[i].valid, set.frames[i].amplitude_m});
  return FitModalImages(set.optics, shape, images, set.noise, options, start);
}

ModeCalibration CalibrateMode(const CalibrationSet& set, int m, const CalibrateOptions& o) {
  ModeCalibration mc;
  mc.mode = m;
  mc.name = set.modes[m].name;
  mc.noll = set.modes[m].noll;
  mc.frames = set.FramesOfMode(m);
  const Image shape = set.ModeShape(m);
  mc.joint = FitFrames(set, shape, mc.frames, o.fit, ModalFitStart());
  mc.final_frames = mc.frames;
  mc.final_fit = mc.joint;
  if (!o.per_amplitude) return mc;

  // Per-level fits: everything but g and the photometry held at the joint fit.
  std::map<double, std::vector<int>> levels;
  for (int i : mc.frames)
    if (!set.frames[i].reference && set.frames[i].amplitude_m != 0.0)
      levels[std::abs(set.frames[i].amplitude_m)].push_back(i);
  ModalFitStart held;
  held.gain = mc.joint.gain > 0 ? mc.joint.gain : 1.0;
  held.position_given = true;
  held.dy_px = mc.joint.dy_px, held.dx_px = mc.joint.dx_px;
  held.static_m = mc.joint.static_m;
  held.source_sigma_px = mc.joint.source_sigma_px;
  held.fix_position = held.fix_static = held.fix_source_size = true;
  std::vector<AmplitudeGain> gains;
  for (const auto& [amp, frames] : levels) {
    const ModalFitResult r = FitFrames(set, shape, frames, o.fit, held);
    AmplitudeGain ag;
    ag.amplitude_m = amp;
    ag.gain = r.gain;
    ag.sigma = r.gain_sigma;
    ag.frames = int(frames.size());
    ag.converged = r.termination == Termination::kConverged;
    if (std::isfinite(ag.gain)) gains.push_back(ag);
  }
  if (gains.empty()) return mc;
  mc.linearity = AnalyseLinearity(gains, o.linearity);
  if (mc.linearity.onset_m > 0 && mc.linearity.linear_max_m > 0) {
    std::vector<int> inside;
    for (int i : mc.frames)
      if (std::abs(set.frames[i].amplitude_m) <= mc.linearity.linear_max_m * (1 + 1e-9)) inside.push_back(i);
    ModalFitStart s;
    s.gain = held.gain;
    s.position_given = true;
    s.dy_px = mc.joint.dy_px, s.dx_px = mc.joint.dx_px;
    s.static_m = mc.joint.static_m;
    s.source_sigma_px = mc.joint.source_sigma_px;
    mc.final_frames = inside;
    mc.final_fit = FitFrames(set, shape, inside, o.fit, s);
    mc.refit = true;
  }
  return mc;
}

}  // namespace

CalibrationResult Calibrate(const CalibrationSet& set_in, const CalibrateOptions& options) {
  const auto t0 = std::chrono::steady_clock::now();
  std::string why;
  if (!options.IsValid(&why)) throw InvalidArgument("Calibrate: invalid options: " + why);
  CalibrationSet set = set_in;
  ValidateCalibrationSet(&set);
  // Every mode's shape is built once here so that a bad actuator pattern fails before any thread starts.
  for (int m = 0; m < int(set.modes.size()); ++m) (void)set.ModeShape(m);

  CalibrationResult result;
  const int n = int(set.modes.size());
  result.modes.resize(n);
  result.threads = std::min(options.threads, n);
  std::atomic<int> next{0}, done{0};
  std::atomic<bool> stop{false};
  std::vector<char> fitted(n, 0);
  std::exception_ptr error;
  std::mutex error_mutex;
  // Only the calling thread reports (core/progress.hpp: never concurrently, never from a pool thread).
  ProgressReporter reporter(options.progress, "calibrate", n, "gain");
  reporter.Start();
  auto worker = [&](bool reports) {
    while (!stop) {
      const int m = next++;
      if (m >= n) return;
      try {
        result.modes[m] = CalibrateMode(set, m, options);
        fitted[m] = 1;
      } catch (...) {
        std::lock_guard<std::mutex> lock(error_mutex);
        if (!error) error = std::current_exception();
      }
      const int d = ++done;
      if (reports && !reporter.Report(d, result.modes[m].final_fit.gain, d == n)) stop = true;
    }
  };
  std::vector<std::thread> pool;
  for (int t = 1; t < result.threads; ++t) pool.emplace_back(worker, false);
  worker(true);
  for (std::thread& t : pool) t.join();
  if (!stop) reporter.Finish(done, n > 0 ? result.modes[n - 1].final_fit.gain : 0.0);
  reporter.RethrowIfThrown();
  if (error) std::rethrow_exception(error);
  if (stop) {
    result.cancelled = true;
    for (int m = 0; m < n; ++m)
      if (!fitted[m]) {
        ModeCalibration& mc = result.modes[m];
        mc.mode = m;
        mc.name = set.modes[m].name;
        mc.noll = set.modes[m].noll;
        mc.joint.termination = mc.final_fit.termination = Termination::kUserCancelled;
        mc.joint.message = mc.final_fit.message = "not fitted: cancelled by the caller";
      }
    result.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    return result;
  }

  // Twin image (modal_fit.hpp): |F{A e^{iφ}}|² is unchanged by φ(u) -> −φ(−u), which flips the even-m static
  // terms and leaves the odd-m ones. Only a poked mode of even m (and g > 0) pins the branch; a mode of odd m
  // (tip/tilt, coma, trefoil) fits either branch with the same gain and likelihood. Align those modes' static
  // terms with the branch of the even-m modes (nearest in the metric of their σ) before combining.
  if (!result.modes.empty()) {
    const std::vector<int>& ks = result.modes[0].final_fit.static_modes;
    auto even = [](int j) { return NollToNM(j).m % 2 == 0; };
    std::vector<double> sw(ks.size(), 0.0), swc(ks.size(), 0.0);
    for (const ModeCalibration& mc : result.modes)
      if (mc.noll > 0 && even(mc.noll) && mc.final_fit.termination != Termination::kFailed)
        for (std::size_t k = 0; k < ks.size(); ++k)
          if (mc.final_fit.static_sigma_m[k] > 0) {
            const double w = 1.0 / (mc.final_fit.static_sigma_m[k] * mc.final_fit.static_sigma_m[k]);
            sw[k] += w, swc[k] += w * mc.final_fit.static_m[k];
          }
    for (ModeCalibration& mc : result.modes) {
      if ((mc.noll > 0 && even(mc.noll)) || mc.final_fit.static_m.size() != ks.size()) continue;
      double keep = 0, flip = 0;
      for (std::size_t k = 0; k < ks.size(); ++k) {
        if (!even(ks[k]) || sw[k] == 0) continue;
        const double ref = swc[k] / sw[k], c = mc.final_fit.static_m[k];
        const double v = mc.final_fit.static_sigma_m[k] * mc.final_fit.static_sigma_m[k] + 1.0 / sw[k];
        keep += (c - ref) * (c - ref) / v;
        flip += (c + ref) * (c + ref) / v;
      }
      if (flip < keep)
        for (ModalFitResult* f : {&mc.final_fit, &mc.joint})
          for (std::size_t k = 0; k < f->static_m.size(); ++k)
            if (even(f->static_modes[k])) f->static_m[k] = -f->static_m[k];
    }
  }
  // Combined static aberration: inverse-variance weighted mean over the modes whose final fit is usable.
  if (!result.modes.empty()) {
    result.static_modes = result.modes[0].final_fit.static_modes;
    const std::size_t k_n = result.static_modes.size();
    std::vector<double> sw(k_n, 0.0), swc(k_n, 0.0);
    for (const ModeCalibration& mc : result.modes) {
      if (mc.final_fit.termination == Termination::kFailed) continue;
      for (std::size_t k = 0; k < k_n; ++k) {
        const double s = mc.final_fit.static_sigma_m[k];
        if (!(s > 0)) continue;
        sw[k] += 1.0 / (s * s);
        swc[k] += mc.final_fit.static_m[k] / (s * s);
      }
    }
    for (std::size_t k = 0; k < k_n; ++k) {
      result.static_m.push_back(sw[k] > 0 ? swc[k] / sw[k] : 0.0);
      result.static_sigma_m.push_back(sw[k] > 0 ? std::sqrt(1.0 / sw[k]) : 0.0);
    }
  }
  result.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return result;
}

std::string CalibrationResult::BriefReport() const {
  std::ostringstream os;
  char line[256];
  std::snprintf(line, sizeof line, "%-8s %18s %14s %12s %9s %11s\n", "mode", "gain +- sigma", "linear to nm",
                "verdict", "chi2/dof", "termination");
  os << line;
  for (const ModeCalibration& m : modes) {
    std::snprintf(line, sizeof line, "%-8s %9.4f +- %6.4f %14.1f %12s %9.3f %11s\n", m.name.c_str(), m.final_fit.gain,
                  m.final_fit.gain_sigma, m.linearity.linear_max_m * 1e9, m.linearity.levels.empty() ? "-" : m.linearity.verdict.c_str(),
                  m.final_fit.reduced_chi2, ToString(m.final_fit.termination));
    os << line;
  }
  if (!static_modes.empty()) {
    os << "static aberration [nm RMS]:";
    for (std::size_t k = 0; k < static_modes.size(); ++k) {
      std::snprintf(line, sizeof line, " Z%d %.2f+-%.2f", static_modes[k], static_m[k] * 1e9, static_sigma_m[k] * 1e9);
      os << line;
    }
    os << "\n";
  }
  std::snprintf(line, sizeof line, "%.2f s on %d thread(s)\n", seconds, threads);
  os << line;
  return os.str();
}

}  // namespace aosr
