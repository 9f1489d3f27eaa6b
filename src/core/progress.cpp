#include "aosr/core/progress.hpp"

#include <cmath>
#include <utility>

#include "aosr/core/error.hpp"

namespace aosr {

ProgressReporter::ProgressReporter(ProgressCallback callback, std::string stage, int total,
                                   std::string value_name, double min_interval_seconds)
    : callback_(std::move(callback)),
      stage_(std::move(stage)),
      value_name_(std::move(value_name)),
      total_(total > 0 ? total : 0),
      min_interval_(min_interval_seconds) {
  CheckArgument(std::isfinite(min_interval_seconds) && min_interval_seconds >= 0, "ProgressReporter",
                "min_interval_seconds", min_interval_seconds, "finite and >= 0");
  if (callback_) start_ = last_delivery_ = std::chrono::steady_clock::now();
}

bool ProgressReporter::Deliver(int iteration, double value, std::chrono::steady_clock::time_point now) {
  last_delivery_ = now;
  last_delivered_ = iteration;
  Progress p;
  p.stage = stage_;
  p.iteration = iteration;
  p.total = total_;
  p.value = value;
  p.value_name = value_name_;
  p.elapsed_seconds = std::chrono::duration<double>(now - start_).count();
  try {
    if (!callback_(p)) cancelled_ = true;
  } catch (...) {
    // Never let it cross the solver (Ceres, thread pools): stop as if cancelled, rethrow after cleanup.
    if (!thrown_) thrown_ = std::current_exception();
    cancelled_ = true;
  }
  return !cancelled_;
}

bool ProgressReporter::Start() {
  if (!callback_) return true;
  return Deliver(0, std::numeric_limits<double>::quiet_NaN(), std::chrono::steady_clock::now());
}

bool ProgressReporter::Report(int iteration, double value, bool last) {
  if (!callback_) return true;
  if (cancelled_) return false;
  const auto now = std::chrono::steady_clock::now();
  const bool first = last_delivered_ <= 0;
  if (first || last || std::chrono::duration<double>(now - last_delivery_).count() >= min_interval_)
    return Deliver(iteration, value, now);
  return true;
}

void ProgressReporter::Finish(int iteration, double value) {
  if (!callback_ || iteration == last_delivered_) return;
  Deliver(iteration, value, std::chrono::steady_clock::now());
}

void ProgressReporter::RethrowIfThrown() const {
  if (thrown_) std::rethrow_exception(thrown_);
}

}  // namespace aosr
