#include "aosr/core/fft.hpp"

#include <fftw3.h>

#include <atomic>
#include <map>
#include <mutex>
#include <tuple>
#include <vector>

#include "aosr/core/error.hpp"

namespace aosr {
namespace {

enum class Kind { kR2C, kC2R, kForward, kInverse };

struct PlanKey {
  Kind kind;
  Index rows, cols;  // logical (real-space) shape
  bool aligned;
  int threads;
  FftSettings::Planner planner;
  bool operator<(const PlanKey& o) const {
    return std::tie(kind, rows, cols, aligned, threads, planner) <
           std::tie(o.kind, o.rows, o.cols, o.aligned, o.threads, o.planner);
  }
};

// Owns every plan for the life of the process; plans are never destroyed while in use.
class PlanCache {
 public:
  static PlanCache& Get() {
    static PlanCache cache;
    return cache;
  }

  fftw_plan Plan(Kind kind, Index rows, Index cols, bool aligned) {
    std::lock_guard<std::mutex> lock(mutex_);
    // Small transforms lose time to thread start-up; keep them single-threaded.
    const int threads = rows * cols >= 128 * 128 ? settings_.threads : 1;
    const PlanKey key{kind, rows, cols, aligned, threads, settings_.planner};
    auto it = plans_.find(key);
    if (it != plans_.end()) return it->second;
    fftw_plan_with_nthreads(threads);
    unsigned flags = settings_.planner == FftSettings::Planner::kEstimate  ? FFTW_ESTIMATE
                     : settings_.planner == FftSettings::Planner::kMeasure ? FFTW_MEASURE
                                                                           : FFTW_PATIENT;
    if (!aligned) flags |= FFTW_UNALIGNED;
    // Plan on scratch buffers: FFTW_MEASURE overwrites its arrays.
    const int r = static_cast<int>(rows), c = static_cast<int>(cols);
    const std::size_t nreal = static_cast<std::size_t>(rows) * cols;
    const std::size_t nhalf = static_cast<std::size_t>(rows) * (cols / 2 + 1);
    fftw_plan plan = nullptr;
    switch (kind) {
      case Kind::kR2C: {
        double* in = fftw_alloc_real(nreal);
        fftw_complex* out = fftw_alloc_complex(nhalf);
        plan = fftw_plan_dft_r2c_2d(r, c, in, out, flags);
        fftw_free(in);
        fftw_free(out);
        break;
      }
      case Kind::kC2R: {
        fftw_complex* in = fftw_alloc_complex(nhalf);
        double* out = fftw_alloc_real(nreal);
        plan = fftw_plan_dft_c2r_2d(r, c, in, out, flags);
        fftw_free(in);
        fftw_free(out);
        break;
      }
      case Kind::kForward:
      case Kind::kInverse: {
        fftw_complex* in = fftw_alloc_complex(nreal);
        fftw_complex* out = fftw_alloc_complex(nreal);
        plan = fftw_plan_dft_2d(r, c, in, out, kind == Kind::kForward ? FFTW_FORWARD : FFTW_BACKWARD,
                                flags);
        fftw_free(in);
        fftw_free(out);
        break;
      }
    }
    if (plan == nullptr) throw Error("FFTW failed to make a plan for shape " + std::to_string(rows) + "x" +
                                     std::to_string(cols));
    plans_.emplace(key, plan);
    return plan;
  }

  void Set(const FftSettings& s) {
    std::lock_guard<std::mutex> lock(mutex_);
    settings_ = s;
  }
  FftSettings Settings() {
    std::lock_guard<std::mutex> lock(mutex_);
    return settings_;
  }
  std::size_t Count() {
    std::lock_guard<std::mutex> lock(mutex_);
    return plans_.size();
  }

 private:
  PlanCache() { fftw_init_threads(); }
  std::mutex mutex_;
  FftSettings settings_;
  std::map<PlanKey, fftw_plan> plans_;
};

bool Aligned(const void* a, const void* b) {
  return fftw_alignment_of(const_cast<double*>(static_cast<const double*>(a))) == 0 &&
         fftw_alignment_of(const_cast<double*>(static_cast<const double*>(b))) == 0;
}

fftw_complex* C(Complex* p) { return reinterpret_cast<fftw_complex*>(p); }

void CheckNonEmpty(const char* fn, Index rows, Index cols) {
  CheckArgument(rows > 0 && cols > 0, fn, "shape", ToString(Shape{rows, cols}), "positive rows and cols");
}

}  // namespace

void SetFftSettings(const FftSettings& settings) {
  CheckArgument(settings.threads >= 1, "SetFftSettings", "threads", settings.threads, ">= 1");
  PlanCache::Get().Set(settings);
}

FftSettings GetFftSettings() { return PlanCache::Get().Settings(); }

std::size_t FftPlanCount() { return PlanCache::Get().Count(); }

namespace {
std::atomic<std::uint64_t> g_executions{0};
void CountExecution() { g_executions.fetch_add(1, std::memory_order_relaxed); }
}  // namespace

std::uint64_t FftExecutionCount() { return g_executions.load(std::memory_order_relaxed); }

ComplexImage FftR2C(const Image& x) {
  CheckNonEmpty("FftR2C", x.rows(), x.cols());
  ComplexImage X(x.rows(), x.cols() / 2 + 1);
  fftw_plan p = PlanCache::Get().Plan(Kind::kR2C, x.rows(), x.cols(), Aligned(x.data(), X.data()));
  CountExecution();
  fftw_execute_dft_r2c(p, const_cast<double*>(x.data()), C(X.data()));
  return X;
}

Image FftC2R(const ComplexImage& X, Index cols) {
  CheckNonEmpty("FftC2R", X.rows(), cols);
  CheckArgument(cols / 2 + 1 == X.cols(), "FftC2R", "cols", cols,
                "2*(X.cols()-1) or 2*(X.cols()-1)+1 with X.cols() = " + std::to_string(X.cols()));
  ComplexImage scratch = X;  // c2r destroys its input
  Image x(X.rows(), cols);
  fftw_plan p = PlanCache::Get().Plan(Kind::kC2R, X.rows(), cols, Aligned(scratch.data(), x.data()));
  CountExecution();
  fftw_execute_dft_c2r(p, C(scratch.data()), x.data());
  x /= static_cast<double>(X.rows() * cols);
  return x;
}

ComplexImage FftForward(const ComplexImage& x) {
  CheckNonEmpty("FftForward", x.rows(), x.cols());
  ComplexImage X(x.rows(), x.cols());
  fftw_plan p = PlanCache::Get().Plan(Kind::kForward, x.rows(), x.cols(), Aligned(x.data(), X.data()));
  CountExecution();
  fftw_execute_dft(p, C(const_cast<Complex*>(x.data())), C(X.data()));
  return X;
}

ComplexImage FftInverse(const ComplexImage& X) {
  CheckNonEmpty("FftInverse", X.rows(), X.cols());
  ComplexImage x(X.rows(), X.cols());
  fftw_plan p = PlanCache::Get().Plan(Kind::kInverse, X.rows(), X.cols(), Aligned(X.data(), x.data()));
  CountExecution();
  fftw_execute_dft(p, C(const_cast<Complex*>(X.data())), C(x.data()));
  x /= static_cast<double>(X.rows() * X.cols());
  return x;
}

Index NextFastFftSize(Index n) {
  CheckArgument(n >= 1, "NextFastFftSize", "n", n, ">= 1");
  for (Index m = n + (n % 2);; m += 2) {
    Index k = m;
    for (Index p : {2, 3, 5, 7})
      while (k % p == 0) k /= p;
    if (k == 1) return m;
  }
}

ComplexImage ExpandHalfSpectrum(const ComplexImage& half, Index cols) {
  CheckArgument(cols / 2 + 1 == half.cols(), "ExpandHalfSpectrum", "cols", cols,
                "consistent with half.cols() = " + std::to_string(half.cols()));
  const Index R = half.rows();
  ComplexImage full(R, cols);
  for (Index u = 0; u < R; ++u)
    for (Index v = 0; v < cols; ++v)
      full(u, v) = v < half.cols() ? half(u, v) : std::conj(half((R - u) % R, cols - v));
  return full;
}

ComplexImage HermitianProjection(const ComplexImage& half, Index cols) {
  CheckArgument(cols / 2 + 1 == half.cols(), "HermitianProjection", "cols", cols,
                "consistent with half.cols() = " + std::to_string(half.cols()));
  ComplexImage out = half;
  const Index R = half.rows();
  std::vector<Index> self_conjugate_cols = {0};
  if (cols % 2 == 0 && cols > 1) self_conjugate_cols.push_back(cols / 2);
  for (Index v : self_conjugate_cols)
    for (Index u = 0; u < R; ++u) {
      const Index w = (R - u) % R;
      out(u, v) = 0.5 * (half(u, v) + std::conj(half(w, v)));
    }
  return out;
}

}  // namespace aosr
