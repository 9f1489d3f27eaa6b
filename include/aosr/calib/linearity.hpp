// Linearity of a DM mode from its gain measured at each commanded amplitude separately.
//
// Input: levels k = 1..K of commanded amplitude |a_k| (increasing), each with its own gain estimate g_k ± σ_k
// (a fit of that level's frames alone, shared nuisances held at the joint fit's values). The applied amplitude
// is p_k = g_k |a_k|.
//
// Linear range. Walking up from the smallest level, g_ref is the inverse-variance weighted mean of the levels
// accepted so far; level k is accepted while
//     |g_k − g_ref| <= max(tolerance · |g_ref|,  z · sqrt(σ_k² + σ_ref²)),
// so a deviation counts only when it is both larger than the stated tolerance and significant. The linear range
// is [0, |a_last accepted|]; the first rejected level is the onset of the non-linearity, classified as
//     "saturates"    g_k < g_ref and p_k >= p_{k−1}   (the applied amplitude still grows, sub-linearly)
//     "wraps"        p_k < p_{k−1}                     (the applied amplitude folds back)
//     "superlinear"  g_k > g_ref
// and "linear" when every level is accepted.
//
// Residual of a linear fit: the weighted least-squares line through the origin p = ĝ a over all levels
// (weights 1/(σ_k a_k)²), its RMS residual in metres and its χ²/dof; a linear mode has χ²/dof ~ 1.
#pragma once

#include <string>
#include <vector>

namespace aosr {

struct AmplitudeGain {
  double amplitude_m = 0.0;  // commanded |a| [m RMS OPD], > 0
  double gain = 0.0;
  double sigma = 0.0;        // 1σ of gain, >= 0
  int frames = 0;            // frames in the level
  bool converged = true;     // the level's fit converged
};

struct LinearityOptions {
  // Relative gain change tolerated in the linear range, in (0, 1). Default 0.05 (5 %).
  double tolerance = 0.05;
  // Significance (in σ) a deviation must also reach, >= 0. Default 3.
  double z = 3.0;

  bool IsValid(std::string* why) const;
};

struct LinearityReport {
  std::vector<AmplitudeGain> levels;  // sorted by amplitude
  double reference_gain = 0.0;        // g_ref over the accepted levels
  double reference_sigma = 0.0;
  double linear_max_m = 0.0;          // largest accepted |a| (0 if even the first level is rejected)
  double onset_m = 0.0;               // first rejected |a| (0 if none)
  std::string verdict = "linear";     // linear | saturates | wraps | superlinear
  double fit_gain = 0.0;              // ĝ of the line through the origin over all levels
  double fit_rms_m = 0.0;             // RMS of p_k − ĝ a_k [m]
  double fit_reduced_chi2 = 0.0;
};

// Throws InvalidArgument for no levels, a non-positive or non-finite amplitude, a non-finite gain or σ < 0, or
// invalid options.
LinearityReport AnalyseLinearity(std::vector<AmplitudeGain> levels, const LinearityOptions& options = {});

}  // namespace aosr
