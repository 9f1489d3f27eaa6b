#include "aosr/design/design_optimizer.hpp"

#include <ceres/first_order_function.h>
#include <ceres/gradient_problem.h>
#include <ceres/gradient_problem_solver.h>
#include <ceres/iteration_callback.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <random>

#include "aosr/core/error.hpp"
#include "aosr/core/progress.hpp"
#include "aosr/solvers/ceres_termination.hpp"

namespace aosr {

bool DesignOptimizerOptions::IsValid(std::string* why) const {
  auto fail = [why](const std::string& m) {
    if (why) *why = m;
    return false;
  };
  if (starts < 1 || starts > 64) return fail("starts = " + std::to_string(starts) + "; allowed: 1 .. 64");
  if (!(std::isfinite(start_spread) && start_spread >= 0))
    return fail("start_spread = " + ToString(start_spread) + "; allowed: >= 0 and finite");
  if (max_iterations < 1 || max_iterations > 100000)
    return fail("max_iterations = " + std::to_string(max_iterations) + "; allowed: 1 .. 100000");
  for (auto [name, v] : {std::pair<const char*, double>{"function_tolerance", function_tolerance},
                         {"gradient_tolerance", gradient_tolerance},
                         {"parameter_tolerance", parameter_tolerance}})
    if (!(v > 0 && v < 1)) return fail(std::string(name) + " = " + ToString(v) + "; allowed: (0, 1)");
  if (lbfgs_memory < 1 || lbfgs_memory > 100)
    return fail("lbfgs_memory = " + std::to_string(lbfgs_memory) + "; allowed: 1 .. 100");
  return true;
}

std::string DesignSummary::FullReport(bool include_time) const {
  char buf[640];
  char time[32] = "";
  if (include_time) std::snprintf(time, sizeof time, ", %.2f s", seconds);
  const double rel = raster_objective > 0 ? 100.0 * (final_objective / raster_objective - 1.0) : 0.0;
  if (!std::isfinite(invisible_floor)) {  // objective B: no floor to measure the excess against
    std::snprintf(buf, sizeof buf,
                  "%s (%d parameters): J %.6g -> %.6g (%+.4f %% vs raster %.6g) in %zu starts, %d iterations, %d "
                  "evaluations%s; best start %d (%s)%s",
                  parameterisation.c_str(), parameters, initial_objective, final_objective, rel, raster_objective,
                  start_objectives.size(), iterations, evaluations, time, best_start, ToString(termination),
                  improved ? "" : "; no start improved on the raster: the raster is returned");
    return buf;
  }
  const double excess = raster_objective - invisible_floor;
  const double rel_excess = excess > 0 ? 100.0 * (final_objective - raster_objective) / excess : 0.0;
  std::snprintf(buf, sizeof buf,
                "%s (%d parameters): J %.6g -> %.6g (%+.4f %% vs raster %.6g; %+.3f %% of its excess over the "
                "invisible floor %.6g) in %zu starts, %d iterations, %d evaluations%s; best start %d (%s)%s",
                parameterisation.c_str(), parameters, initial_objective, final_objective, rel, raster_objective,
                rel_excess, invisible_floor,
                start_objectives.size(), iterations, evaluations, time, best_start, ToString(termination),
                improved ? "" : "; no start improved on the raster: the raster is returned");
  return buf;
}

namespace {

// J(θ = scale z) for Ceres, counting evaluations and keeping the best point seen.
class CeresDesignFunction : public ceres::FirstOrderFunction {
 public:
  CeresDesignFunction(const DesignCriterion& f, const DesignParameterisation& p, double scale, int* evaluations,
                      double* best, Vector* best_theta)
      : f_(f), p_(p), scale_(scale), evaluations_(evaluations), best_(best), best_theta_(best_theta) {}
  bool Evaluate(const double* z, double* cost, double* gradient) const override {
    const Vector theta = Eigen::Map<const Vector>(z, p_.parameters()) * scale_;
    std::vector<Image> grad;
    double j;
    try {
      j = f_.Evaluate(p_.Opds(theta), gradient ? &grad : nullptr);
    } catch (const NumericalError&) {
      return false;  // Ceres contracts the step
    }
    ++*evaluations_;
    if (!std::isfinite(j)) return false;
    *cost = j;
    if (gradient) {
      const Vector g = p_.PullBack(theta, grad) * scale_;
      if (!g.allFinite()) return false;
      Eigen::Map<Vector>(gradient, g.size()) = g;
    }
    if (j < *best_) {
      *best_ = j;
      *best_theta_ = theta;
    }
    return true;
  }
  int NumParameters() const override { return p_.parameters(); }

 private:
  const DesignCriterion& f_;
  const DesignParameterisation& p_;
  double scale_;
  int* evaluations_;
  double* best_;
  Vector* best_theta_;
};

// Per L-BFGS iteration: the text line of options.progress, and the report of options.progress_callback
// (`reporter`, shared by all starts; `done` iterations of earlier starts). A cancellation ends the start at
// its current point (SOLVER_TERMINATE_SUCCESSFULLY keeps it; OptimizeDesign then runs no further start).
class IterationReport : public ceres::IterationCallback {
 public:
  IterationReport(const DesignOptimizerOptions& o, int start, ProgressReporter* reporter, int done)
      : o_(o), start_(start), reporter_(reporter), done_(done) {}
  ceres::CallbackReturnType operator()(const ceres::IterationSummary& s) override {
    if (o_.progress) {
      char buf[200];
      std::snprintf(buf, sizeof buf, "start %d/%d iteration %d: J = %.6g, |g|max = %.3g, %.1f s", start_ + 1,
                    o_.starts, s.iteration, s.cost, s.gradient_max_norm, s.cumulative_time_in_seconds);
      o_.progress(buf);
    }
    if (s.iteration > 0 && !reporter_->Report(done_ + s.iteration, s.cost)) return ceres::SOLVER_TERMINATE_SUCCESSFULLY;
    return ceres::SOLVER_CONTINUE;
  }

 private:
  const DesignOptimizerOptions& o_;
  int start_;
  ProgressReporter* reporter_;
  int done_;
};

}  // namespace

DesignResult OptimizeDesign(const DesignCriterion& objective, const DesignParameterisation& p,
                            const DesignOptimizerOptions& options) {
  const char* fn = "OptimizeDesign";
  std::string why;
  if (!options.IsValid(&why)) throw InvalidArgument(std::string(fn) + ": options." + why);
  CheckArgument(p.frames() == objective.frames(), fn, "parameterisation frames", p.frames(),
                "the objective's " + std::to_string(objective.frames()));
  CheckArgument(p.pupil_n() == objective.optics().amplitude.rows(), fn, "parameterisation pupil grid", p.pupil_n(),
                "the objective's " + std::to_string(objective.optics().amplitude.rows()));
  const auto t0 = std::chrono::steady_clock::now();
  DesignResult result;
  DesignSummary& s = result.summary;
  s.parameterisation = ToString(p.options().kind);
  s.parameters = p.parameters();
  s.raster_objective = objective.Evaluate(p.RasterOpds());
  s.invisible_floor = objective.invisible_floor();
  s.objective = objective.method();
  s.evaluations = 1;
  Vector best_theta = p.RasterParameters();
  double best = objective.Evaluate(p.Opds(best_theta));
  ++s.evaluations;
  s.initial_objective = best;
  if (options.progress)
    options.progress(std::string(ToString(p.options().kind)) + ": J(raster) = " + ToString(s.raster_objective) +
                     ", J(start 0) = " + ToString(best) + ", " + std::to_string(p.parameters()) + " parameters");
  if (p.parameters() == 0) {
    s.method = "design-raster";
    s.message = "the raster has no free parameters: evaluated, not optimised";
  } else {
    s.method = "design-lbfgs";
    const double scale = p.ParameterScale();
    const Vector theta_raster = best_theta;
    std::mt19937_64 rng(options.seed);
    std::normal_distribution<double> n01;
    std::vector<std::string> messages;
    ProgressReporter reporter(options.progress_callback, "design", options.starts * options.max_iterations, "J");
    reporter.Start();
    for (int k = 0; k < options.starts && !reporter.cancelled(); ++k) {
      Vector theta = theta_raster;
      if (k > 0)
        for (Index q = 0; q < theta.size(); ++q) theta[q] += options.start_spread * scale * n01(rng);
      Vector z = theta / scale;
      double start_best = std::numeric_limits<double>::infinity();
      Vector start_theta = theta;
      ceres::GradientProblemSolver::Options co;
      co.line_search_direction_type = ceres::LBFGS;
      co.line_search_type = ceres::WOLFE;
      co.max_lbfgs_rank = options.lbfgs_memory;
      co.max_num_iterations = options.max_iterations;
      co.function_tolerance = options.function_tolerance;
      co.parameter_tolerance = options.parameter_tolerance;
      co.logging_type = ceres::SILENT;
      IterationReport callback(options, k, &reporter, s.iterations);
      co.callbacks.push_back(&callback);
      // Gradient tolerance relative to the start's gradient (Ceres' is absolute).
      {
        std::vector<Image> g;
        try {
          objective.Evaluate(p.Opds(theta), &g);
        } catch (const NumericalError& e) {  // objective B could not be trusted here: skip this start
          ++s.evaluations;
          s.start_objectives.push_back(std::numeric_limits<double>::infinity());
          messages.push_back("start " + std::to_string(k) + ": not run, " + e.what());
          if (options.progress) options.progress(messages.back());
          continue;
        }
        ++s.evaluations;
        const double g0 = (p.PullBack(theta, g) * scale).lpNorm<Eigen::Infinity>();
        co.gradient_tolerance = std::max(1e-300, options.gradient_tolerance * g0);
      }
      std::string ceres_why;
      if (!co.IsValid(&ceres_why)) throw InvalidArgument(std::string(fn) + ": options rejected by Ceres: " + ceres_why);
      int evaluations = 0;
      ceres::GradientProblem problem(
          new CeresDesignFunction(objective, p, scale, &evaluations, &start_best, &start_theta));
      ceres::GradientProblemSolver::Summary cs;
      ceres::Solve(co, problem, z.data(), &cs);
      reporter.RethrowIfThrown();
      s.evaluations += evaluations;
      s.iterations += std::max<int>(0, int(cs.iterations.size()) - 1);
      s.start_objectives.push_back(start_best);
      messages.push_back("start " + std::to_string(k) + ": " + cs.message);
      if (options.progress)
        options.progress("start " + std::to_string(k + 1) + "/" + std::to_string(options.starts) + " done: J = " +
                         ToString(start_best) + " (" + cs.message + ")");
      if (start_best < best) {
        best = start_best;
        best_theta = start_theta;
        s.best_start = k;
        s.termination = TerminationOf(cs.termination_type);
        s.improved = true;
      }
    }
    const bool cancelled = reporter.cancelled();
    reporter.Finish(s.iterations, best);
    s.message = s.improved ? messages[s.best_start] : "no start improved on start 0 (the raster)";
    if (cancelled) {
      s.termination = Termination::kUserCancelled;
      s.message = "cancelled by the caller after " + std::to_string(s.iterations) + " iterations in " +
                  std::to_string(s.start_objectives.size()) + " of " + std::to_string(options.starts) +
                  " starts; best so far: " + s.message;
    }
  }
  result.parameters = p.parameters() ? best_theta : Vector();
  result.coefficients = p.Coefficients(result.parameters);
  result.offsets = p.Offsets(result.parameters);
  result.opds = p.Opds(result.parameters);
  s.final_objective = best;
  s.final_cost = best;
  s.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return result;
}

}  // namespace aosr
