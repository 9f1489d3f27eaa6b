// Seeded Monte-Carlo trials of the calibration on synthetic sets (shared by the physics and slow tests).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <string>
#include <vector>

#include "aosr/calib/calibrate.hpp"
#include "aosr/calib/calibration_set.hpp"

namespace aosr::test {

struct TrialStatistics {
  std::map<int, std::vector<double>> gain, sigma;  // per Noll index, one entry per trial
  std::map<int, double> truth;
  int failed = 0;
  double seconds = 0;

  double FractionWithinTwoSigma() const {
    int in = 0, all = 0;
    for (const auto& [j, g] : gain)
      for (std::size_t t = 0; t < g.size(); ++t) {
        ++all;
        in += std::abs(g[t] - truth.at(j)) <= 2 * sigma.at(j)[t];
      }
    return all ? double(in) / all : 0.0;
  }
  // Mean reported σ over the empirical standard deviation of the gains about their mean, for mode j.
  double SigmaOverScatter(int j) const {
    const std::vector<double>& g = gain.at(j);
    double mean = 0, ms = 0;
    for (double v : g) mean += v / double(g.size());
    double ss = 0;
    for (double v : g) ss += (v - mean) * (v - mean);
    for (double s : sigma.at(j)) ms += s / double(g.size());
    return ms / std::sqrt(ss / double(g.size() - 1));
  }
  // Standard deviation of all pulls (g − g_true)/σ.
  double PooledPullStd() const {
    double ss = 0;
    int n = 0;
    for (const auto& [j, g] : gain)
      for (std::size_t t = 0; t < g.size(); ++t) {
        const double p = (g[t] - truth.at(j)) / sigma.at(j)[t];
        ss += p * p;
        ++n;
      }
    return std::sqrt(ss / n);
  }
  std::string Report() const {
    std::string out;
    char line[200];
    for (const auto& [j, g] : gain) {
      double mean = 0;
      for (double v : g) mean += v / double(g.size());
      double ms = 0;
      for (double s : sigma.at(j)) ms += s / double(g.size());
      std::snprintf(line, sizeof line, "Z%-3d truth %.4f mean %.5f  mean sigma %.5f  sigma/scatter %.3f\n", j,
                    truth.at(j), mean, ms, SigmaOverScatter(j));
      out += line;
    }
    std::snprintf(line, sizeof line, "within 2 sigma: %.1f %%; pooled pull std %.3f; failed fits %d; %.1f s\n",
                  100 * FractionWithinTwoSigma(), PooledPullStd(), failed, seconds);
    return out + line;
  }
};

// Runs `trials` synthetic sets with seeds first_seed, first_seed + 1, ... (linear response) and collects gains.
inline TrialStatistics RunTrials(SyntheticCalibrationOptions o, int trials, std::uint64_t first_seed,
                                 CalibrateOptions co = CalibrateOptions()) {
  TrialStatistics s;
  co.per_amplitude = false;  // the gain statistics only need the joint fit
  for (int t = 0; t < trials; ++t) {
    o.seed = first_seed + std::uint64_t(t);
    const CalibrationResult r = Calibrate(SynthesizeCalibrationSet(o), co);
    s.seconds += r.seconds;
    for (std::size_t m = 0; m < r.modes.size(); ++m) {
      const ModeCalibration& mc = r.modes[m];
      if (mc.final_fit.termination == Termination::kFailed) {
        ++s.failed;
        std::printf("seed %llu mode %s failed: %s\n", (unsigned long long)o.seed, mc.name.c_str(), mc.final_fit.message.c_str());
        continue;
      }
      s.gain[mc.noll].push_back(mc.final_fit.gain);
      s.sigma[mc.noll].push_back(mc.final_fit.gain_sigma);
      s.truth[mc.noll] = o.gains.empty() ? 1.0 : o.gains[m];
    }
  }
  return s;
}

}  // namespace aosr::test
