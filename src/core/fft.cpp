#include "aosr/core/fft.hpp"

#include <fftw3.h>

#include <algorithm>
#include <atomic>
#include <cstring>
#include <map>
#include <mutex>
#include <tuple>
#include <vector>

#include "aosr/core/error.hpp"
#include "aosr/core/parallel.hpp"

namespace aosr {
namespace {

// How a transform is computed (fft.hpp, "Execution"):
//  * below kBlockedMinPixels: one 2-D FFTW plan, executed on aligned scratch copies;
//  * from kBlockedMinPixels on: row-column, in blocks of whole rows and then whole columns, each block a
//    batched 1-D plan executed on an aligned scratch copy. Blocks are tasks of ParallelFor.
// Every block of a given shape is computed by the same plan on a buffer of the same alignment, whichever
// thread takes it, so the result does not depend on the thread count or on where Eigen put the arrays.
constexpr Index kBlockedMinPixels = 128 * 128;
// A block holds about this many bytes of data, so that its 1-D transforms stay in cache.
constexpr std::size_t kBlockBytes = 256 * 1024;

enum class Kind { kR2C, kC2R, kForward, kInverse };

// A batched 1-D transform: `howmany` contiguous lines of length n (real lines of n, half spectra of
// n/2+1, or complex lines of n), in-place for complex, out-of-place (separate buffers) for real.
// howmany == 0 marks a 2-D plan of shape rows x n.
struct PlanKey {
  Kind kind;
  Index n, howmany, rows;
  FftSettings::Planner planner;
  bool operator<(const PlanKey& o) const {
    return std::tie(kind, n, howmany, rows, planner) < std::tie(o.kind, o.n, o.howmany, o.rows, o.planner);
  }
};

unsigned PlannerFlags(FftSettings::Planner p) {
  switch (p) {
    case FftSettings::Planner::kEstimate: return FFTW_ESTIMATE;
    case FftSettings::Planner::kMeasure: return FFTW_MEASURE;
    case FftSettings::Planner::kPatient: return FFTW_PATIENT;
  }
  return FFTW_ESTIMATE;
}

// Owns every plan for the life of the process; plans are never destroyed while in use. Plans are made on
// fftw_malloc'd buffers (FFTW's SIMD alignment) and executed only on such buffers (Scratch below).
class PlanCache {
 public:
  static PlanCache& Get() {
    // Never destroyed (as parallel.cpp's Pool): a pool worker may still execute a plan during static
    // destruction, and the plans stay reachable from this pointer, so LeakSanitizer does not report them.
    // A static object's destructor would free the map but not the plans (no fftw_destroy_plan).
    static PlanCache* cache = new PlanCache;
    return *cache;
  }

  fftw_plan Plan(const PlanKey& key) {
    std::lock_guard<std::mutex> lock(mutex_);
    auto it = plans_.find(key);
    if (it != plans_.end()) return it->second;
    const unsigned flags = PlannerFlags(key.planner);
    const int n = static_cast<int>(key.n);
    const int half = n / 2 + 1;
    fftw_plan plan = nullptr;
    if (key.howmany == 0) {  // 2-D
      const int r = static_cast<int>(key.rows);
      const std::size_t nreal = std::size_t(key.rows) * key.n, nhalf = std::size_t(key.rows) * half;
      double* re = fftw_alloc_real(nreal);
      fftw_complex* c1 = fftw_alloc_complex(key.kind == Kind::kR2C || key.kind == Kind::kC2R ? nhalf : nreal);
      fftw_complex* c2 = fftw_alloc_complex(nreal);
      switch (key.kind) {
        case Kind::kR2C: plan = fftw_plan_dft_r2c_2d(r, n, re, c1, flags); break;
        case Kind::kC2R: plan = fftw_plan_dft_c2r_2d(r, n, c1, re, flags); break;
        case Kind::kForward: plan = fftw_plan_dft_2d(r, n, c1, c2, FFTW_FORWARD, flags); break;
        case Kind::kInverse: plan = fftw_plan_dft_2d(r, n, c1, c2, FFTW_BACKWARD, flags); break;
      }
      fftw_free(re);
      fftw_free(c1);
      fftw_free(c2);
    } else {
      const int m = static_cast<int>(key.howmany);
      const std::size_t lines = std::size_t(key.howmany);
      double* re = fftw_alloc_real(lines * n);
      fftw_complex* c = fftw_alloc_complex(lines * std::max(n, half));
      fftw_complex* c2 = fftw_alloc_complex(lines * n);  // complex plans are out-of-place, as executed
      switch (key.kind) {
        case Kind::kR2C:
          plan = fftw_plan_many_dft_r2c(1, &n, m, re, nullptr, 1, n, c, nullptr, 1, half, flags);
          break;
        case Kind::kC2R:
          plan = fftw_plan_many_dft_c2r(1, &n, m, c, nullptr, 1, half, re, nullptr, 1, n, flags);
          break;
        case Kind::kForward:
        case Kind::kInverse:
          plan = fftw_plan_many_dft(1, &n, m, c, nullptr, 1, n, c2, nullptr, 1, n,
                                    key.kind == Kind::kForward ? FFTW_FORWARD : FFTW_BACKWARD, flags);
          break;
      }
      fftw_free(re);
      fftw_free(c);
      fftw_free(c2);
    }
    if (plan == nullptr)
      throw Error("FFTW failed to make a plan for n = " + std::to_string(key.n) + ", howmany " +
                  std::to_string(key.howmany) + ", rows " + std::to_string(key.rows));
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
  std::mutex mutex_;
  FftSettings settings_;
  std::map<PlanKey, fftw_plan> plans_;
};

// Per-thread aligned work buffers, grown on demand and kept for the thread's life.
class Scratch {
 public:
  ~Scratch() {
    fftw_free(a_);
    fftw_free(b_);
  }
  // Two buffers of at least `bytes_a` and `bytes_b` bytes, aligned as fftw_malloc aligns.
  void Reserve(std::size_t bytes_a, std::size_t bytes_b) {
    Grow(&a_, &size_a_, bytes_a);
    Grow(&b_, &size_b_, bytes_b);
  }
  void* a() const { return a_; }
  void* b() const { return b_; }

  static Scratch& ForThread() {
    thread_local Scratch s;
    return s;
  }

 private:
  static void Grow(void** p, std::size_t* size, std::size_t bytes) {
    if (bytes <= *size) return;
    fftw_free(*p);
    *p = fftw_malloc(bytes);
    if (*p == nullptr) throw std::bad_alloc();
    *size = bytes;
  }
  void* a_ = nullptr;
  void* b_ = nullptr;
  std::size_t size_a_ = 0, size_b_ = 0;
};

fftw_complex* C(void* p) { return static_cast<fftw_complex*>(p); }
double* R(void* p) { return static_cast<double*>(p); }

std::atomic<std::uint64_t> g_executions{0};
void CountExecution() { g_executions.fetch_add(1, std::memory_order_relaxed); }

void CheckNonEmpty(const char* fn, Index rows, Index cols) {
  CheckArgument(rows > 0 && cols > 0, fn, "shape", ToString(Shape{rows, cols}), "positive rows and cols");
  CheckArgument(rows <= (Index(1) << 30) && cols <= (Index(1) << 30), fn, "shape",
                ToString(Shape{rows, cols}), "at most 2^30 per axis (FFTW takes int sizes)");
}

// Lines per block for lines of `line_bytes` bytes (a function of the shape only).
Index LinesPerBlock(std::size_t line_bytes, Index lines) {
  return std::clamp<Index>(Index(kBlockBytes / std::max<std::size_t>(line_bytes, 1)), 1, std::min<Index>(lines, 64));
}

// Applies a batched 1-D transform to every row of a row-major (rows x in_len) array `in`, writing rows of
// out_len to `out` (which may equal `in` when both are complex of one length). Element types by Kind.
template <typename In, typename Out>
void RowPass(Kind kind, Index n, Index rows, const In* in, Index in_len, Out* out, Index out_len,
             FftSettings::Planner planner) {
  const Index per = LinesPerBlock(std::max(sizeof(In) * in_len, sizeof(Out) * out_len), rows);
  const Index blocks = (rows + per - 1) / per;
  ParallelFor(blocks, DefaultThreads(), [&](Index b) {
    const Index r0 = b * per, nb = std::min(per, rows - r0);
    const fftw_plan p = PlanCache::Get().Plan({kind, n, nb, 0, planner});
    Scratch& s = Scratch::ForThread();
    s.Reserve(sizeof(In) * in_len * nb, sizeof(Out) * out_len * nb);
    std::memcpy(s.a(), in + r0 * in_len, sizeof(In) * in_len * nb);
    if constexpr (std::is_same_v<In, double>)
      fftw_execute_dft_r2c(p, R(s.a()), C(s.b()));
    else if constexpr (std::is_same_v<Out, double>)
      fftw_execute_dft_c2r(p, C(s.a()), R(s.b()));
    else
      fftw_execute_dft(p, C(s.a()), C(s.b()));
    std::memcpy(out + r0 * out_len, s.b(), sizeof(Out) * out_len * nb);
  });
}

// Applies a complex 1-D transform of length `rows` to every column of the row-major rows x cols complex
// array `x`, in place: blocks of columns are gathered into contiguous lines, transformed and scattered back.
void ColumnPass(Kind kind, Index rows, Index cols, Complex* x, FftSettings::Planner planner) {
  const Index per = LinesPerBlock(sizeof(Complex) * rows, cols);
  const Index blocks = (cols + per - 1) / per;
  ParallelFor(blocks, DefaultThreads(), [&](Index b) {
    const Index c0 = b * per, nb = std::min(per, cols - c0);
    const fftw_plan p = PlanCache::Get().Plan({kind, rows, nb, 0, planner});
    Scratch& s = Scratch::ForThread();
    s.Reserve(sizeof(Complex) * rows * nb, sizeof(Complex) * rows * nb);
    Complex* line = static_cast<Complex*>(s.a());
    for (Index i = 0; i < rows; ++i)
      for (Index c = 0; c < nb; ++c) line[c * rows + i] = x[i * cols + c0 + c];
    fftw_execute_dft(p, C(s.a()), C(s.b()));
    const Complex* res = static_cast<const Complex*>(s.b());
    for (Index i = 0; i < rows; ++i)
      for (Index c = 0; c < nb; ++c) x[i * cols + c0 + c] = res[c * rows + i];
  });
}

// A small transform: one 2-D plan, input copied to aligned scratch (c2r destroys its input anyway).
template <typename In, typename Out>
void Small(Kind kind, Index rows, Index cols, const In* in, std::size_t in_count, Out* out,
           std::size_t out_count, FftSettings::Planner planner) {
  const fftw_plan p = PlanCache::Get().Plan({kind, cols, 0, rows, planner});
  Scratch& s = Scratch::ForThread();
  s.Reserve(sizeof(In) * in_count, sizeof(Out) * out_count);
  std::memcpy(s.a(), in, sizeof(In) * in_count);
  if constexpr (std::is_same_v<In, double>)
    fftw_execute_dft_r2c(p, R(s.a()), C(s.b()));
  else if constexpr (std::is_same_v<Out, double>)
    fftw_execute_dft_c2r(p, C(s.a()), R(s.b()));
  else
    fftw_execute_dft(p, C(s.a()), C(s.b()));
  std::memcpy(out, s.b(), sizeof(Out) * out_count);
}

bool Blocked(Index rows, Index cols) { return rows * cols >= kBlockedMinPixels; }

}  // namespace

void SetFftSettings(const FftSettings& settings) { PlanCache::Get().Set(settings); }

FftSettings GetFftSettings() { return PlanCache::Get().Settings(); }

std::size_t FftPlanCount() { return PlanCache::Get().Count(); }

std::uint64_t FftExecutionCount() { return g_executions.load(std::memory_order_relaxed); }

ComplexImage FftR2C(const Image& x) {
  CheckNonEmpty("FftR2C", x.rows(), x.cols());
  const Index rows = x.rows(), cols = x.cols(), half = cols / 2 + 1;
  const auto planner = GetFftSettings().planner;
  ComplexImage X(rows, half);
  CountExecution();
  if (!Blocked(rows, cols)) {
    Small(Kind::kR2C, rows, cols, x.data(), x.size(), X.data(), X.size(), planner);
  } else {
    RowPass(Kind::kR2C, cols, rows, x.data(), cols, X.data(), half, planner);
    ColumnPass(Kind::kForward, rows, half, X.data(), planner);
  }
  return X;
}

Image FftC2R(const ComplexImage& X, Index cols) {
  CheckNonEmpty("FftC2R", X.rows(), cols);
  CheckArgument(cols / 2 + 1 == X.cols(), "FftC2R", "cols", cols,
                "2*(X.cols()-1) or 2*(X.cols()-1)+1 with X.cols() = " + std::to_string(X.cols()));
  const Index rows = X.rows(), half = X.cols();
  const auto planner = GetFftSettings().planner;
  Image x(rows, cols);
  CountExecution();
  if (!Blocked(rows, cols)) {
    Small(Kind::kC2R, rows, cols, X.data(), X.size(), x.data(), x.size(), planner);
  } else {
    ComplexImage work = X;
    ColumnPass(Kind::kInverse, rows, half, work.data(), planner);
    RowPass(Kind::kC2R, cols, rows, work.data(), half, x.data(), cols, planner);
  }
  x /= static_cast<double>(rows * cols);
  return x;
}

namespace {
ComplexImage FullComplex(const char* fn, Kind kind, const ComplexImage& in) {
  CheckNonEmpty(fn, in.rows(), in.cols());
  const Index rows = in.rows(), cols = in.cols();
  const auto planner = GetFftSettings().planner;
  ComplexImage out(rows, cols);
  CountExecution();
  if (!Blocked(rows, cols)) {
    Small(kind, rows, cols, in.data(), in.size(), out.data(), out.size(), planner);
  } else {
    RowPass(kind, cols, rows, in.data(), cols, out.data(), cols, planner);
    ColumnPass(kind, rows, cols, out.data(), planner);
  }
  return out;
}
}  // namespace

ComplexImage FftForward(const ComplexImage& x) { return FullComplex("FftForward", Kind::kForward, x); }

ComplexImage FftInverse(const ComplexImage& X) {
  ComplexImage x = FullComplex("FftInverse", Kind::kInverse, X);
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
