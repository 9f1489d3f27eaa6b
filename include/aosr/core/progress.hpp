// Progress of long computations, and the caller's way to cancel them.
//
// Every iterative method (TV's ADMM, MAP's L-BFGS, the Reconstruct driver's stages) takes an optional
// ProgressCallback in its options (a field `progress`, empty by default: then nothing is measured or called
// and the method costs what it did before). With a callback the method hands it a Progress at most every
// ProgressReporter::kDefaultInterval (0.2 s) of wall time, and always on the first iteration of a stage and
// on its last (the one whose iteration equals the summary's `iterations`), so a fast solve pays one clock
// read per iteration and the caller always sees where a stage ended.
//
// Rules, written once for every method that takes a callback:
//  * The callback runs on the thread that called the method, never concurrently with itself, between two
//    iterations (never inside a parallel loop). It may take the time it needs; that time is wall time of the
//    solve.
//  * Returning false asks the method to stop at the end of the iteration just reported. It then returns its
//    current estimate, finite as always, with Termination::kUserCancelled (solvers/summary.hpp) and a summary
//    message that says "cancelled by the caller". If that iteration was the stage's last anyway (it met the
//    stopping rule or the iteration limit), nothing is cut short and the method reports that termination.
//  * The callback cannot change the maths: it sees copies of scalars, never the iterate, and returning true
//    leaves the result bit-identical to a run without a callback (tested).
//  * It should not throw. If it does, the reporter catches the exception, the method stops as if cancelled,
//    and the exception is rethrown to the method's caller once the method has released what it holds (the
//    exception never crosses Ceres or a thread pool).
//
// For language bindings (issue 17): Python delivers Ctrl-C as a flag that only the interpreter sees. A
// binding releases the GIL around the solve and passes a callback that re-acquires it, calls
// PyErr_CheckSignals() (and the user's own Python progress function, if any) and returns false when a
// KeyboardInterrupt (or any Python exception) is pending; after the method returns, the binding raises it.
// The solve then stops within one interval plus one iteration of the key press.
#pragma once

#include <chrono>
#include <exception>
#include <functional>
#include <limits>
#include <string>

namespace aosr {

// One report. Plain data: it may be copied and kept.
struct Progress {
  // What runs: "tv", "map", "pilot" (the Tikhonov estimate that sets TV/MAP's weight and warm start), ...
  std::string stage;
  // Iterations completed in this stage (1-based; 0: the stage has just started).
  int iteration = 0;
  // The stage's iteration limit, 0 if unknown. A solver may stop before it (converged).
  int total = 0;
  // A number that shows convergence, NaN if the stage has none; value_name says what it is (e.g. "cost" for
  // MAP's objective, "primal/tol" for TV's primal residual over its tolerance, which falls to 1 at
  // convergence).
  double value = std::numeric_limits<double>::quiet_NaN();
  std::string value_name;
  // Wall time since the stage started, seconds.
  double elapsed_seconds = 0.0;
};

// Returns true to continue, false to cancel (see the rules above).
using ProgressCallback = std::function<bool(const Progress&)>;

// The method side of the contract: rate-limits the calls, times the stage, remembers a cancellation and a
// callback's exception. One per stage; not thread-safe (one solver loop owns it).
//
//   ProgressReporter reporter(options.progress, "tv", options.max_iterations, "primal/tol");
//   for (k...) { ...; const bool last = done || k + 1 == max; if (!reporter.Report(k + 1, value, last)) ... }
//   reporter.Finish(summary.iterations, value);   // delivers the last iteration if it was not yet delivered
//   reporter.RethrowIfThrown();                   // after cleanup, before returning
class ProgressReporter {
 public:
  // Seconds between deliveries (the first and the last report are always delivered).
  static constexpr double kDefaultInterval = 0.2;

  // An empty callback makes every member a no-op (Report returns true without reading the clock).
  // min_interval_seconds >= 0 (0: every report is delivered).
  ProgressReporter(ProgressCallback callback, std::string stage, int total, std::string value_name,
                   double min_interval_seconds = kDefaultInterval);

  bool active() const { return static_cast<bool>(callback_); }

  // Iteration `iteration` (1-based) has completed with `value`. Delivers it when it is the first report, when
  // `last` is true, or when min_interval has passed since the previous delivery; returns false if the
  // callback asked to cancel (now or earlier) or threw. Iterations should increase.
  bool Report(int iteration, double value, bool last = false);

  // The stage has started (iteration 0): always delivered. Returns false to cancel.
  bool Start();

  // The stage ended at `iteration`: delivers it unless that iteration was already delivered (e.g. the solver
  // stopped on a path that could not know in advance it was the last). Its return value is ignored (nothing
  // is left to cancel); a cancellation it asks for is still recorded.
  void Finish(int iteration, double value);

  bool cancelled() const { return cancelled_; }
  // Rethrows an exception the callback threw (no-op otherwise).
  void RethrowIfThrown() const;

 private:
  bool Deliver(int iteration, double value, std::chrono::steady_clock::time_point now);

  ProgressCallback callback_;
  std::string stage_, value_name_;
  int total_ = 0;
  double min_interval_ = kDefaultInterval;
  std::chrono::steady_clock::time_point start_, last_delivery_;
  int last_delivered_ = -1;  // iteration of the last delivery, -1 before the first
  bool cancelled_ = false;
  std::exception_ptr thrown_;
};

}  // namespace aosr
