// Tikhonov's λ searches: the discrepancy principle (bracket + Illinois), the log-grid minimiser, and GCV, the
// L-curve corner and UPRE on the engine's spectral sums (tikhonov.hpp, "λ rules").
#include "tikhonov_internal.hpp"

#include <cmath>
#include <limits>

#include "aosr/core/error.hpp"

namespace aosr::tikhonov_internal {

LambdaSearch DiscrepancySearch(const std::function<double(double)>& residual, double target, double lambda0,
                               double tolerance, int max_evaluations) {
  constexpr double kTMin = -16, kTMax = 8, kStep = 2;
  LambdaSearch out;
  // g(t) = log(residual / target): increasing in t = log10(λ/λ₀); a zero residual stays finite.
  auto g = [&](double t) {
    out.lambda = lambda0 * std::pow(10.0, t);
    out.residual = residual(out.lambda);
    ++out.evaluations;
    out.met = std::abs(out.residual / target - 1.0) <= tolerance;
    return std::log((out.residual + 1e-300 * target) / target);
  };
  double ta = -3, ga = g(ta);
  if (out.met) return out;
  // Bracket: walk in 2-decade steps towards the sign change.
  const double dir = ga < 0 ? kStep : -kStep;
  double tb = ta, gb = ga;
  while ((gb < 0) == (ga < 0)) {
    if (out.evaluations >= max_evaluations) {
      out.note = "no bracket within the evaluation limit";
      out.termination = Termination::kMaxIterations;
      return out;
    }
    if (tb == (dir > 0 ? kTMax : kTMin)) {
      out.note = dir > 0
                     ? "even the largest lambda leaves a residual below the target (sigma overestimated?)"
                     : "even the smallest lambda leaves a residual above the target (model misfit or sigma "
                       "underestimated?)";
      out.termination = Termination::kFailed;
      return out;
    }
    ta = tb;
    ga = gb;
    tb = std::clamp(tb + dir, kTMin, kTMax);
    gb = g(tb);
    if (out.met) return out;
  }
  // Illinois (modified regula falsi) on the bracket [ta, tb].
  int side = 0;
  while (out.evaluations < max_evaluations) {
    if (std::abs(tb - ta) < 1e-12) {
      out.note = "the bracket shrank to rounding level (1e-12 decades) with the residual " +
                 ToString(out.residual / target) + " x the target: it is flat or jumps there";
      out.termination = Termination::kStagnated;
      return out;
    }
    const double tc = (ta * gb - tb * ga) / (gb - ga);
    const double gc = g(tc);
    if (out.met) return out;
    if ((gc < 0) == (gb < 0)) {
      tb = tc;
      gb = gc;
      if (side == -1) ga *= 0.5;
      side = -1;
    } else {
      ta = tc;
      ga = gc;
      if (side == +1) gb *= 0.5;
      side = +1;
    }
  }
  out.note = "evaluation limit reached";
  out.termination = Termination::kMaxIterations;
  return out;
}

LogGridMinimum MinimiseOnLogGrid(const std::function<double(double)>& f, double decades, int steps_per_decade) {
  LogGridMinimum out;
  const int steps = int(std::lround(decades * steps_per_decade));
  const double dt = 1.0 / steps_per_decade;
  auto eval = [&](double t) {
    ++out.evaluations;
    return f(t);
  };
  auto grid_t = [&](int k) { return -decades + double(k) * dt; };
  double best = std::numeric_limits<double>::infinity();
  int best_k = steps;
  auto visit = [&](int k) {
    const double g = eval(grid_t(k));
    if (g < best) best = g, best_k = k;
  };
  for (int k = 0; k <= steps; ++k) visit(k);
  // A minimum at the top of the grid means the data want more smoothing than λ₀ (weak data: strong blur,
  // N < r², faint object): walk on upwards, up to `decades` more, until the score turns. (A minimum at the
  // bottom is, for GCV, its known undersmoothing failure; walking down would only deepen it, so it is reported.)
  int top = steps;
  while (best_k == top && top < 2 * steps) visit(++top);
  double t_best = grid_t(best_k);
  const bool at_edge = steps > 0 && (best_k == 0 || best_k == top);
  if (steps > 0 && !at_edge) {
    // Golden-section search on [t_{k−1}, t_{k+1}], which brackets a minimum (the middle point is lowest).
    const double phi = 0.5 * (std::sqrt(5.0) - 1.0);
    double a = grid_t(best_k - 1), b = grid_t(best_k + 1);
    double c = b - phi * (b - a), d = a + phi * (b - a);
    double gc = eval(c), gd = eval(d);
    while (b - a > 1e-4) {
      if (gc <= gd) {
        b = d, d = c, gd = gc;
        c = b - phi * (b - a), gc = eval(c);
      } else {
        a = c, c = d, gc = gd;
        d = a + phi * (b - a), gd = eval(d);
      }
    }
    const double t_mid = 0.5 * (a + b), g_mid = eval(t_mid);
    if (g_mid < best) best = g_mid, t_best = t_mid;  // never worse than the best grid point
  }
  out.t = t_best;
  out.value = best;
  out.edge = at_edge ? (best_k == 0 ? -1 : +1) : 0;
  return out;
}

namespace {

// "; GCV minimum at the smallest lambda searched (...): a bound, not a GCV minimiser (advice)".
std::string EdgeNote(const char* what, const char* optimiser, int edge, const char* bottom_advice) {
  if (edge == 0) return "";
  return std::string("; ") + what + " at the " + (edge < 0 ? "smallest" : "largest") +
         " lambda searched (lambda0 x 10^[-gcv_decades, " + (edge < 0 ? "0" : "gcv_decades") +
         "]): a bound, not a " + optimiser + (edge < 0 ? bottom_advice : "");
}

}  // namespace

double GcvSearch(const FourierSystem& sys, const TikhonovOptions& options, double* score, int* evaluations,
                 std::string* edge) {
  // GCV(λ) = n · ||y − A x_λ||² / (n − tr H_λ)² (Golub, Heath & Wahba 1979), exactly per bin. Each value is a
  // sum over the bins' singular values (FourierSystem::EvaluateSpectral), so the search costs one
  // decomposition per bin: a log grid finds the basin, golden-section search on log λ then finds the minimum
  // between the grid neighbours of the best point to 1e-4 decades (continuous, not a grid point).
  const double n_data = double(sys.model().frames()) * double(sys.bins());
  sys.PrepareSpectral();  // the decomposition and λ₀ in one pass
  const LogGridMinimum m = MinimiseOnLogGrid(
      [&](double t) {
        const FourierSystem::Fit f = sys.EvaluateSpectral(sys.lambda0() * std::pow(10.0, t));
        return f.dof > 0 ? n_data * f.residual2 / (f.dof * f.dof) : std::numeric_limits<double>::infinity();
      },
      options.gcv_decades, options.gcv_steps_per_decade);
  *score = m.value;
  *evaluations = m.evaluations;
  if (edge)
    *edge = EdgeNote("GCV minimum", "GCV minimiser", m.edge, " (GCV undersmooths here: prefer the discrepancy rule or a fixed lambda)");
  return sys.lambda0() * std::pow(10.0, m.t);
}

double LcurveCurvature(const FourierSystem& sys, double lambda) {
  // κ of the curve (ln ρ, ln η) in terms of ρ, η and η' (tikhonov.hpp, kLcurve): the second derivatives cancel
  // because dρ/dλ = −λ dη/dλ at the exact minimiser.
  const FourierSystem::Fit f = sys.EvaluateSpectral(lambda, true);
  const double rho = f.residual2, eta = f.prior2, d = f.dprior2, mu = lambda;
  if (!(rho > 0 && eta > 0 && d < 0 && mu > 0)) return -std::numeric_limits<double>::infinity();
  const double num = 1.0 / (rho * eta) + mu * d * (1.0 / (rho * eta * eta) + mu / (rho * rho * eta));
  const double den = -d * std::pow(mu * mu / (rho * rho) + 1.0 / (eta * eta), 1.5);
  const double k = num / den;
  return std::isfinite(k) ? k : -std::numeric_limits<double>::infinity();
}

double LcurveSearch(const FourierSystem& sys, const TikhonovOptions& options, double* curvature, int* evaluations,
                    std::string* edge) {
  // The corner is the positive local maximum of κ at the largest λ: the turn from the over-smoothed (flat)
  // branch into the steep one. Further maxima at smaller λ lie where the curve comes to rest at the
  // least-squares end (ρ and η both saturate; a short arc turning a little has a large κ): not an L corner
  // (Hansen 2001, "The L-curve and its use in the numerical treatment of inverse problems", restricts the
  // curve for the same reason). Grid t = log10(λ/λ₀) from +gcv_decades/2 down to −gcv_decades (walking on up
  // to +gcv_decades while κ still rises at the top), then golden-section on [t_{k−1}, t_{k+1}].
  const double dt = 1.0 / options.gcv_steps_per_decade;
  sys.PrepareSpectral();  // the decomposition and λ₀ in one pass
  int evaluated = 0;
  auto kappa = [&](double t) {
    ++evaluated;
    return LcurveCurvature(sys, sys.lambda0() * std::pow(10.0, t));
  };
  const int below = int(std::lround(options.gcv_decades * options.gcv_steps_per_decade));
  int above = std::max(1, below / 2);
  std::vector<double> k_of;  // κ at t_j = (j − below)·dt, j = 0 .. below + above
  for (int j = 0; j <= below + above; ++j) k_of.push_back(kappa(double(j - below) * dt));
  while (k_of.back() > k_of[k_of.size() - 2] && above < 2 * below) {
    ++above;
    k_of.push_back(kappa(double(int(k_of.size()) - below) * dt));
  }
  const int top = int(k_of.size()) - 1;
  int best = -1;
  for (int j = top - 1; j >= 1 && best < 0; --j)
    if (k_of[j] > 0 && k_of[j] >= k_of[j - 1] && k_of[j] >= k_of[j + 1]) best = j;
  int edge_side = 0;
  if (best < 0) {  // no interior corner: the largest κ on the grid, reported as a bound
    best = int(std::max_element(k_of.begin(), k_of.end()) - k_of.begin());
    edge_side = best == 0 ? -1 : best == top ? +1 : 0;
    if (edge_side == 0) edge_side = -1;
  }
  double t_best = double(best - below) * dt, k_best = k_of[best];
  if (best >= 1 && best <= top - 1) {
    const double phi = 0.5 * (std::sqrt(5.0) - 1.0);
    double a = t_best - dt, b = t_best + dt;
    double c = b - phi * (b - a), d = a + phi * (b - a);
    double kc = kappa(c), kd = kappa(d);
    while (b - a > 1e-4) {
      if (kc >= kd) {
        b = d, d = c, kd = kc;
        c = b - phi * (b - a), kc = kappa(c);
      } else {
        a = c, c = d, kc = kd;
        d = a + phi * (b - a), kd = kappa(d);
      }
    }
    const double t_mid = 0.5 * (a + b), k_mid = kappa(t_mid);
    if (k_mid > k_best) k_best = k_mid, t_best = t_mid;
  }
  *curvature = k_best;
  *evaluations = evaluated;
  if (edge) {
    edge->clear();
    if (edge_side != 0)
      *edge = std::string("; no L-curve corner (positive local maximum of the curvature) in lambda0 x 10^[-") +
              ToString(options.gcv_decades) + ", " + ToString(double(above) * dt) +
              "]: the largest curvature there, a bound, not a corner";
  }
  return sys.lambda0() * std::pow(10.0, t_best);
}

double Upre(const FourierSystem& sys, double lambda, double variance) {
  // U = ||y − Ax||² + 2v tr H − n v with tr H = n − dof (Mallows 1973; Vogel 2002, §7.1), per pixel.
  const double n = double(sys.model().frames()) * double(sys.bins());
  const FourierSystem::Fit f = sys.EvaluateSpectral(lambda);
  return (f.residual2 + 2.0 * variance * (n - f.dof) - n * variance) / n;
}

double UpreSearch(const FourierSystem& sys, const TikhonovOptions& options, double variance, double* score,
                  int* evaluations, std::string* edge) {
  sys.PrepareSpectral();  // the decomposition and λ₀ in one pass
  const LogGridMinimum m = MinimiseOnLogGrid(
      [&](double t) { return Upre(sys, sys.lambda0() * std::pow(10.0, t), variance); }, options.gcv_decades,
      options.gcv_steps_per_decade);
  *score = m.value;
  *evaluations = m.evaluations;
  if (edge) *edge = EdgeNote("UPRE minimum", "UPRE minimiser", m.edge, " (check noise_sigma: an underestimate undersmooths)");
  return sys.lambda0() * std::pow(10.0, m.t);
}

}  // namespace aosr::tikhonov_internal
