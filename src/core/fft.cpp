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
#include "fftw_wisdom.inc"  // kShippedFftwWisdom (generated from data/fftw_wisdom.txt)

namespace aosr {
namespace {

// How a transform is computed (fft.hpp, "Execution"):
//  * below kBlockedMinPixels: one FFTW 2-D plan, executed directly on the caller's arrays;
//  * from kBlockedMinPixels on: FFTW's own row-column algorithm, split into a fixed number of blocks: a row
//    pass (each block one batched 1-D plan over whole contiguous rows) and a column pass (each block one
//    batched, strided 1-D plan over a band of columns, run in place on the output). FFTW executes these
//    strided plans with its own buffered vector loops, as its 2-D plans do internally, so the arithmetic
//    per pixel is the same and nothing is copied by us.
// The partition into blocks is a function of the shape only, and each block is always computed by the
// plan made for its (shape, offset class), whichever thread takes it: the output bytes do not depend on
// the thread count. FFTW requires that an array passed to fftw_execute_* have the alignment of the
// arrays the plan was made on (fftw_alignment_of, SIMD alignment modulo 16 bytes here); Eigen's heap
// arrays are 16-byte aligned, and block starts are chosen so that offsets keep that alignment.
constexpr Index kBlockedMinPixels = 192 * 192;
// At most this many blocks per pass (enough for 8 threads), and at least kMinLinesPerBlock lines each.
constexpr Index kMaxBlocks = 8;
constexpr Index kMinLinesPerBlock = 32;
// The blocks of a pass run on DefaultThreads() threads from this many real values per pass on (a 320 x 320
// image), on one thread below it: at 192^2 and 256^2 handing blocks to a second thread cost more than it saved
// (0.69x and 0.98x, bench/results/fft.md). Which thread runs a block never changes its bytes.
constexpr Index kThreadedMinValues = 320 * 320;
int PassThreads(Index values) { return values >= kThreadedMinValues ? DefaultThreads() : 1; }

enum class Kind { kR2C, kC2R, kForward, kInverse };

// One FFTW plan: rank 2 (n0 x n1, one transform) or rank 1 (length n0, `howmany` transforms with the
// given strides and distances, in elements of the plan's input and output types).
struct PlanKey {
  Kind kind;
  int rank;
  Index n0, n1, howmany, istride, idist, ostride, odist;
  bool in_place;
  FftSettings::Planner planner;
  bool shipped_wisdom;
  auto Tie() const {
    return std::tie(kind, rank, n0, n1, howmany, istride, idist, ostride, odist, in_place, planner,
                    shipped_wisdom);
  }
  bool operator<(const PlanKey& o) const { return Tie() < o.Tie(); }
};

unsigned PlannerFlags(FftSettings::Planner p) {
  switch (p) {
    case FftSettings::Planner::kEstimate:
      return FFTW_ESTIMATE;
    case FftSettings::Planner::kMeasure:
      return FFTW_MEASURE;
    case FftSettings::Planner::kPatient:
      return FFTW_PATIENT;
  }
  return FFTW_ESTIMATE;
}

// Number of elements a rank-1 batched transform touches: the last line's last element plus one.
std::size_t Extent(Index n, Index howmany, Index stride, Index dist) {
  return std::size_t((howmany - 1) * dist + (n - 1) * stride + 1);
}

// Owns every plan for the life of the process; plans are never destroyed while in use. Plans are made on
// fftw_malloc'd buffers (FFTW's SIMD alignment) and executed on arrays of the same alignment.
class PlanCache {
 public:
  static PlanCache& Get() {
    // Never destroyed (as parallel.cpp's Pool): a pool worker may still execute a plan during static
    // destruction, and the plans stay reachable from this pointer, so LeakSanitizer does not report them.
    static PlanCache* cache = new PlanCache;
    return *cache;
  }

  fftw_plan Plan(const PlanKey& key) {
    // A per-thread memo of the last few plans looked up: loops of small transforms (a Shack-Hartmann
    // sensor's 200 lenslet spots per frame) then skip the lock and the map. Entries carry the cache's
    // generation, so Reset() invalidates every thread's memo.
    struct Memo {
      PlanKey key;
      fftw_plan plan = nullptr;
      std::uint64_t generation = 0;
    };
    constexpr int kMemo = 4;
    thread_local Memo memo[kMemo];
    thread_local int next = 0;
    const std::uint64_t generation = generation_.load(std::memory_order_acquire);
    for (const Memo& m : memo)
      if (m.plan != nullptr && m.generation == generation && !(m.key < key) && !(key < m.key)) return m.plan;
    fftw_plan plan = nullptr;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      auto it = plans_.find(key);
      if (it != plans_.end()) {
        plan = it->second;
      } else {
        PrepareWisdom(key);
        plan = Make(key);
        if (plan == nullptr)
          throw Error("FFTW failed to make a plan for shape " + std::to_string(key.n0) + "x" +
                      std::to_string(key.n1) + ", howmany " + std::to_string(key.howmany));
        plans_.emplace(key, plan);
      }
    }
    memo[next] = {key, plan, generation};
    next = (next + 1) % kMemo;
    return plan;
  }

  // Forgets every plan (and FFTW's accumulated wisdom), so that the next transforms plan afresh as a new
  // process would. For the run-to-run reproducibility test only: no transform may be running.
  void Reset() {
    std::lock_guard<std::mutex> lock(mutex_);
    generation_.fetch_add(1, std::memory_order_acq_rel);
    for (auto& [key, plan] : plans_) fftw_destroy_plan(plan);
    plans_.clear();
    fftw_forget_wisdom();
    shipped_loaded_ = false;
  }

  bool WisdomLoaded() {
    std::lock_guard<std::mutex> lock(mutex_);
    return shipped_loaded_;
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
  static fftw_plan Make(const PlanKey& k) {
    const unsigned flags = PlannerFlags(k.planner);
    const bool real_in = k.kind == Kind::kR2C, real_out = k.kind == Kind::kC2R;
    int n[2] = {int(k.n0), int(k.n1)};
    std::size_t in_count, out_count;
    if (k.rank == 2) {
      const std::size_t real = std::size_t(k.n0) * k.n1, half = std::size_t(k.n0) * (k.n1 / 2 + 1);
      in_count = real_in ? real : (real_out ? half : real);
      out_count = real_out ? real : (real_in ? half : real);
    } else {
      in_count = Extent(real_out ? k.n0 / 2 + 1 : k.n0, k.howmany, k.istride, k.idist);
      out_count = Extent(real_in ? k.n0 / 2 + 1 : k.n0, k.howmany, k.ostride, k.odist);
    }
    // In-place plans get one buffer large enough for both views (complex-to-complex, and the c2r row pass).
    const std::size_t bytes_in = in_count * (real_in ? sizeof(double) : sizeof(fftw_complex));
    const std::size_t bytes_out = out_count * (real_out ? sizeof(double) : sizeof(fftw_complex));
    void* in = fftw_malloc(k.in_place ? std::max(bytes_in, bytes_out) : bytes_in);
    void* out = k.in_place ? in : fftw_malloc(bytes_out);
    if (in == nullptr || out == nullptr) throw std::bad_alloc();
    const int howmany = int(k.howmany), is = int(k.istride), id = int(k.idist), os = int(k.ostride),
              od = int(k.odist);
    auto* ci = static_cast<fftw_complex*>(in);
    auto* co = static_cast<fftw_complex*>(out);
    fftw_plan plan = nullptr;
    switch (k.kind) {
      case Kind::kR2C:
        plan = fftw_plan_many_dft_r2c(k.rank, n, howmany, static_cast<double*>(in), nullptr, is, id, co,
                                      nullptr, os, od, flags);
        break;
      case Kind::kC2R:
        plan = fftw_plan_many_dft_c2r(k.rank, n, howmany, ci, nullptr, is, id, static_cast<double*>(out),
                                      nullptr, os, od, flags);
        break;
      case Kind::kForward:
      case Kind::kInverse:
        plan = fftw_plan_many_dft(k.rank, n, howmany, ci, nullptr, is, id, co, nullptr, os, od,
                                  k.kind == Kind::kForward ? FFTW_FORWARD : FFTW_BACKWARD, flags);
        break;
    }
    fftw_free(in);
    if (!k.in_place) fftw_free(out);
    return plan;
  }

  // FFTW keeps one wisdom store per process and consults it for every plan: an entry recorded while
  // planning with FFTW_MEASURE (by aosr's opt-in planners, or by anything else in the process that uses
  // FFTW directly: a benchmark's reference plans, another library) would answer a later FFTW_ESTIMATE
  // request for the same problem, and the "deterministic" plan would depend on what the process did
  // before. So every kEstimate plan is made from a store that holds exactly the shipped wisdom (or
  // nothing): it is forgotten and re-imported before each new plan (about 1 ms for the 170 kB of shipped
  // wisdom, once per shape and block class). kMeasure and kPatient plans, not reproducible anyway, plan on
  // top of what the store holds, so that their timings accumulate (build/bench/fft_wisdom exports them).
  void PrepareWisdom(const PlanKey& key) {
    if (key.planner == FftSettings::Planner::kEstimate) fftw_forget_wisdom();
    if (key.shipped_wisdom)
      shipped_loaded_ =
          kShippedFftwWisdom[0] != '\0' && fftw_import_wisdom_from_string(kShippedFftwWisdom) == 1;
  }

  std::mutex mutex_;
  FftSettings settings_;
  bool shipped_loaded_ = false;
  std::map<PlanKey, fftw_plan> plans_;
  std::atomic<std::uint64_t> generation_{1};
};

// Per-thread aligned work buffers (fftw_malloc), grown on demand and kept for the thread's life. Two
// slots, because a c2r holds its whole-spectrum copy in kSpectrum while the column pass, run partly on the
// same thread, uses kColumns for its chunks.
enum Slot { kSpectrum = 0, kColumns = 1 };
class Scratch {
 public:
  ~Scratch() {
    for (void* p : p_) fftw_free(p);
  }
  void* Reserve(Slot slot, std::size_t bytes) {
    if (bytes > size_[slot]) {
      fftw_free(p_[slot]);
      p_[slot] = nullptr;
      size_[slot] = 0;
      p_[slot] = fftw_malloc(bytes);
      if (p_[slot] == nullptr) throw std::bad_alloc();
      size_[slot] = bytes;
    }
    return p_[slot];
  }
  static Scratch& ForThread() {
    thread_local Scratch s;
    return s;
  }

 private:
  void* p_[2] = {nullptr, nullptr};
  std::size_t size_[2] = {0, 0};
};

fftw_complex* C(const Complex* p) { return reinterpret_cast<fftw_complex*>(const_cast<Complex*>(p)); }
double* R(const double* p) { return const_cast<double*>(p); }

std::atomic<std::uint64_t> g_executions{0};
void CountExecution() { g_executions.fetch_add(1, std::memory_order_relaxed); }

void CheckNonEmpty(const char* fn, Index rows, Index cols) {
  CheckArgument(rows > 0 && cols > 0, fn, "shape", ToString(Shape{rows, cols}), "positive rows and cols");
  CheckArgument(rows <= (Index(1) << 30) && cols <= (Index(1) << 30), fn, "shape",
                ToString(Shape{rows, cols}), "at most 2^30 per axis (FFTW takes int sizes)");
}

// FFTW executes a plan only on arrays aligned as the ones it was made on. Eigen's heap arrays always are
// (16 bytes); an array that is not (a foreign buffer) would be a programming error here, not bad input.
template <typename T>
void CheckAligned(const T* p) {
  if (fftw_alignment_of(reinterpret_cast<double*>(const_cast<T*>(p))) != 0)
    throw Error("fft.cpp: array not aligned for FFTW (programming error)");
}

bool Blocked(Index rows, Index cols) { return rows * cols >= kBlockedMinPixels; }

// The fixed partition of `lines` lines into blocks: block starts are even, so that an offset of a whole
// number of blocks keeps 16-byte alignment for real lines of any length. A function of `lines` only.
struct Partition {
  Index per, count;
  explicit Partition(Index lines) {
    const Index blocks = std::clamp<Index>(lines / kMinLinesPerBlock, 1, kMaxBlocks);
    per = (lines + blocks - 1) / blocks;
    per += per % 2;
    count = (lines + per - 1) / per;
  }
  Index Begin(Index b) const { return b * per; }
  Index Size(Index b, Index lines) const { return std::min(per, lines - b * per); }
};

// Row pass: a rank-1 transform of length n along each of `rows` contiguous rows, in (row length in_len) ->
// out (row length out_len), out of place. For kC2R the rows of `out` are also multiplied by `scale`.
template <typename In, typename Out>
void RowPass(Kind kind, Index n, Index rows, const In* in, Index in_len, Out* out, Index out_len,
             const FftSettings& fs, double scale) {
  const Partition part(rows);
  ParallelFor(part.count, PassThreads(n * rows), [&](Index b) {
    const Index r0 = part.Begin(b), nb = part.Size(b, rows);
    const fftw_plan p = PlanCache::Get().Plan(
        {kind, 1, n, 0, nb, 1, in_len, 1, out_len, false, fs.planner, fs.shipped_wisdom});
    const In* src = in + r0 * in_len;
    Out* dst = out + r0 * out_len;
    if constexpr (std::is_same_v<In, double>) {
      fftw_execute_dft_r2c(p, R(src), C(dst));
    } else if constexpr (std::is_same_v<Out, double>) {
      fftw_execute_dft_c2r(p, C(src), dst);
      if (scale != 1.0)
        for (Index i = 0, count = nb * out_len; i < count; ++i) dst[i] *= scale;
    } else {
      fftw_execute_dft(p, C(src), C(dst));
    }
  });
}

// The c2r row pass run in place on the half spectrum (rows of `half` complex = 2*half doubles, the padded
// layout FFTW documents for in-place r2c/c2r), then copied to `out` with the scale. From this row length on,
// FFTW_ESTIMATE's in-place batched c2r plans were measured faster than its out-of-place ones (1.08-1.49x at
// 1000-2048; equal at 800; slower, 0.44-0.71x, at 200-768, where the out-of-place pass stays), and the copy
// is the pass the scale needs anyway. A function of the row length only, so of the shape.
constexpr Index kInPlaceC2RMinCols = 900;

void RowPassC2RInPlace(Index n, Index rows, Complex* work, Index half, double* out, const FftSettings& fs,
                       double scale) {
  const Partition part(rows);
  ParallelFor(part.count, PassThreads(n * rows), [&](Index b) {
    const Index r0 = part.Begin(b), nb = part.Size(b, rows);
    const fftw_plan p = PlanCache::Get().Plan(
        {Kind::kC2R, 1, n, 0, nb, 1, half, 1, 2 * half, true, fs.planner, fs.shipped_wisdom});
    Complex* block = work + r0 * half;
    double* real = reinterpret_cast<double*>(block);
    fftw_execute_dft_c2r(p, C(block), real);
    for (Index i = 0; i < nb; ++i) {
      const double* src = real + i * 2 * half;
      double* dst = out + (r0 + i) * n;
      for (Index j = 0; j < n; ++j) dst[j] = src[j] * scale;
    }
  });
}

// Column pass: a complex rank-1 transform of length `rows` down each of the `cols` columns of the
// row-major rows x cols arrays `in` -> `out` (the same array for in place).
//
// Two ways, chosen by the shape alone (so the choice cannot vary between runs or thread counts):
//  * strided: each block of columns is one batched 1-D plan reading the columns in place with stride
//    `cols`. Fine while the stride does not alias in the cache;
//  * buffered: chunks of kChunkColumns columns are gathered into contiguous lines of a per-thread buffer,
//    transformed there by a contiguous batched plan, and scattered back (FFTW's own "dft-buffered"
//    strategy, which FFTW_MEASURE finds and FFTW_ESTIMATE does not). A stride of a multiple of 256 bytes
//    (cols % 16 == 0 for complex rows) maps successive rows of a column onto few cache sets, and past
//    16 MiB every row of a column is a new page: there FFTW_ESTIMATE's strided plans were measured 3 to
//    10x slower than buffering (256^2 complex: 2.0 ms against 0.20 ms; bench/results/fft.md).
constexpr Index kChunkColumns = 8;

bool BufferedColumns(Index rows, Index cols) {
  return cols % 16 == 0 || std::size_t(rows) * std::size_t(cols) * sizeof(Complex) >= (std::size_t(16) << 20);
}

void ColumnPass(Kind kind, Index rows, Index cols, const Complex* in, Complex* out, const FftSettings& fs) {
  if (BufferedColumns(rows, cols)) {
    const Index chunks = (cols + kChunkColumns - 1) / kChunkColumns;
    ParallelFor(chunks, PassThreads(2 * rows * cols), [&](Index b) {
      const Index c0 = b * kChunkColumns, nb = std::min(kChunkColumns, cols - c0);
      const fftw_plan p = PlanCache::Get().Plan(
          {kind, 1, rows, 0, nb, 1, rows, 1, rows, true, fs.planner, fs.shipped_wisdom});
      Complex* buf =
          static_cast<Complex*>(Scratch::ForThread().Reserve(kColumns, sizeof(Complex) * rows * nb));
      for (Index i = 0; i < rows; ++i) {
        const Complex* src = in + i * cols + c0;
        for (Index c = 0; c < nb; ++c) buf[c * rows + i] = src[c];
      }
      fftw_execute_dft(p, C(buf), C(buf));
      for (Index i = 0; i < rows; ++i) {
        Complex* dst = out + i * cols + c0;
        for (Index c = 0; c < nb; ++c) dst[c] = buf[c * rows + i];
      }
    });
    return;
  }
  const Partition part(cols);
  const bool in_place = in == out;
  ParallelFor(part.count, PassThreads(2 * rows * cols), [&](Index b) {
    const Index c0 = part.Begin(b), nb = part.Size(b, cols);
    const fftw_plan p = PlanCache::Get().Plan(
        {kind, 1, rows, 0, nb, cols, 1, cols, 1, in_place, fs.planner, fs.shipped_wisdom});
    fftw_execute_dft(p, C(in + c0), C(out + c0));
  });
}

FftSettings CurrentSettings() { return PlanCache::Get().Settings(); }

}  // namespace

void SetFftSettings(const FftSettings& settings) { PlanCache::Get().Set(settings); }

FftSettings GetFftSettings() { return PlanCache::Get().Settings(); }

std::size_t FftPlanCount() { return PlanCache::Get().Count(); }

void FftResetPlansForTesting() { PlanCache::Get().Reset(); }

bool FftWisdomLoaded() { return PlanCache::Get().WisdomLoaded(); }

const char* FftShippedWisdom() { return kShippedFftwWisdom; }

std::uint64_t FftExecutionCount() { return g_executions.load(std::memory_order_relaxed); }

void FftR2CInto(const Image& x, ComplexImage* X) {
  CheckNonEmpty("FftR2C", x.rows(), x.cols());
  CheckArgument(X != nullptr, "FftR2C", "X", "null", "an output array");
  const Index rows = x.rows(), cols = x.cols(), half = cols / 2 + 1;
  const FftSettings fs = CurrentSettings();
  X->resize(rows, half);
  CheckAligned(x.data());
  CheckAligned(X->data());
  CountExecution();
  if (!Blocked(rows, cols)) {
    const fftw_plan p = PlanCache::Get().Plan(
        {Kind::kR2C, 2, rows, cols, 1, 1, 0, 1, 0, false, fs.planner, fs.shipped_wisdom});
    fftw_execute_dft_r2c(p, R(x.data()), C(X->data()));
  } else {
    RowPass(Kind::kR2C, cols, rows, x.data(), cols, X->data(), half, fs, 1.0);
    ColumnPass(Kind::kForward, rows, half, X->data(), X->data(), fs);
  }
}

ComplexImage FftR2C(const Image& x) {
  ComplexImage X;
  FftR2CInto(x, &X);
  return X;
}

void FftC2RInto(const ComplexImage& X, Index cols, Image* x) {
  CheckNonEmpty("FftC2R", X.rows(), cols);
  CheckArgument(cols / 2 + 1 == X.cols(), "FftC2R", "cols", cols,
                "2*(X.cols()-1) or 2*(X.cols()-1)+1 with X.cols() = " + std::to_string(X.cols()));
  CheckArgument(x != nullptr, "FftC2R", "x", "null", "an output array");
  const Index rows = X.rows(), half = X.cols();
  const FftSettings fs = CurrentSettings();
  x->resize(rows, cols);
  CheckAligned(X.data());
  CheckAligned(x->data());
  const double scale = 1.0 / static_cast<double>(rows * cols);
  CountExecution();
  // c2r destroys its input, so the half spectrum goes through a per-thread scratch buffer: copied whole for
  // the one 2-D plan, or written by the (out-of-place) column pass in the blocked path, which costs no pass.
  Complex* work = static_cast<Complex*>(Scratch::ForThread().Reserve(kSpectrum, sizeof(Complex) * X.size()));
  if (!Blocked(rows, cols)) {
    std::memcpy(work, X.data(), sizeof(Complex) * X.size());
    const fftw_plan p = PlanCache::Get().Plan(
        {Kind::kC2R, 2, rows, cols, 1, 1, 0, 1, 0, false, fs.planner, fs.shipped_wisdom});
    fftw_execute_dft_c2r(p, C(work), x->data());
    *x *= scale;
  } else {
    ColumnPass(Kind::kInverse, rows, half, X.data(), work, fs);
    if (cols >= kInPlaceC2RMinCols)
      RowPassC2RInPlace(cols, rows, work, half, x->data(), fs, scale);
    else
      RowPass(Kind::kC2R, cols, rows, static_cast<const Complex*>(work), half, x->data(), cols, fs, scale);
  }
}

Image FftC2R(const ComplexImage& X, Index cols) {
  Image x;
  FftC2RInto(X, cols, &x);
  return x;
}

namespace {
void FullComplex(const char* fn, Kind kind, const ComplexImage& in, ComplexImage* out) {
  CheckNonEmpty(fn, in.rows(), in.cols());
  CheckArgument(out != nullptr && out != &in, fn, "out", "null or the input", "a separate output array");
  const Index rows = in.rows(), cols = in.cols();
  const FftSettings fs = CurrentSettings();
  out->resize(rows, cols);
  CheckAligned(in.data());
  CheckAligned(out->data());
  CountExecution();
  if (!Blocked(rows, cols)) {
    const fftw_plan p =
        PlanCache::Get().Plan({kind, 2, rows, cols, 1, 1, 0, 1, 0, false, fs.planner, fs.shipped_wisdom});
    fftw_execute_dft(p, C(in.data()), C(out->data()));
  } else {
    RowPass(kind, cols, rows, in.data(), cols, out->data(), cols, fs, 1.0);
    ColumnPass(kind, rows, cols, out->data(), out->data(), fs);
  }
}
}  // namespace

ComplexImage FftForward(const ComplexImage& x) {
  ComplexImage X;
  FullComplex("FftForward", Kind::kForward, x, &X);
  return X;
}

void FftForwardInto(const ComplexImage& x, ComplexImage* X) {
  FullComplex("FftForward", Kind::kForward, x, X);
}

ComplexImage FftInverse(const ComplexImage& X) {
  ComplexImage x;
  FftInverseInto(X, &x);
  return x;
}

void FftInverseInto(const ComplexImage& X, ComplexImage* x) {
  FullComplex("FftInverse", Kind::kInverse, X, x);
  *x /= static_cast<double>(X.rows() * X.cols());
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

void HermitianProjectInPlace(ComplexImage* half, Index cols) {
  CheckArgument(cols / 2 + 1 == half->cols(), "HermitianProjection", "cols", cols,
                "consistent with half.cols() = " + std::to_string(half->cols()));
  ComplexImage& h = *half;
  const Index R = h.rows();
  std::vector<Index> self_conjugate_cols = {0};
  if (cols % 2 == 0 && cols > 1) self_conjugate_cols.push_back(cols / 2);
  // Each pair (u, w = −u mod R) from both originals, so that the result is the copying projection's bytes.
  for (Index v : self_conjugate_cols)
    for (Index u = 0; u < R; ++u) {
      const Index w = (R - u) % R;
      if (w < u) continue;
      const Complex a = h(u, v), b = h(w, v);
      h(u, v) = 0.5 * (a + std::conj(b));
      if (w != u) h(w, v) = 0.5 * (b + std::conj(a));
    }
}

ComplexImage HermitianProjection(const ComplexImage& half, Index cols) {
  ComplexImage out = half;
  HermitianProjectInPlace(&out, cols);
  return out;
}

}  // namespace aosr
