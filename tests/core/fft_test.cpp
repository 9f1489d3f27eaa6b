#include "aosr/core/fft.hpp"

#include <fftw3.h>
#include <gtest/gtest.h>

#include <cstring>
#include <vector>

#include "aosr/core/parallel.hpp"
#include "support/testing.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

Image RandomImage(Shape s, std::uint64_t seed) { return aosr::test::RandomImage(s, seed, /*normal=*/false); }

// The naive DFT, the oracle for both execution paths (2-D plan and blocked row-column): direct sums along
// rows, then along columns (the 2-D DFT is separable), with exact integer phase reduction.
ComplexImage NaiveDft(const ComplexImage& x, int sign) {
  const Index R = x.rows(), C = x.cols();
  ComplexImage rows = ComplexImage::Zero(R, C), X = ComplexImage::Zero(R, C);
  for (Index y = 0; y < R; ++y)
    for (Index v = 0; v < C; ++v)
      for (Index c = 0; c < C; ++c) rows(y, v) += x(y, c) * std::polar(1.0, sign * 2 * M_PI * double(v * c % C) / C);
  for (Index u = 0; u < R; ++u)
    for (Index v = 0; v < C; ++v)
      for (Index y = 0; y < R; ++y) X(u, v) += rows(y, v) * std::polar(1.0, sign * 2 * M_PI * double(u * y % R) / R);
  return X;
}

template <typename A, typename B>
bool SameBytes(const A& a, const B& b) {
  return a.rows() == b.rows() && a.cols() == b.cols() &&
         std::memcmp(a.data(), b.data(), sizeof(typename A::Scalar) * a.size()) == 0;
}

TEST(FftTest, RoundTrips) {
  // Small (one 2-D plan) and blocked (row-column) shapes, odd and prime sizes included.
  for (Shape s : {Shape{8, 8}, Shape{7, 13}, Shape{64, 50}, Shape{1, 5}, Shape{128, 128}, Shape{131, 257},
                  Shape{256, 192}, Shape{600, 1}, Shape{1, 40000}, Shape{211, 1009}}) {
    const Image x = RandomImage(s, 5);
    const Image back = FftC2R(FftR2C(x), s.cols);
    EXPECT_LT((back - x).abs().maxCoeff(), 1e-13) << ToString(s);
    const ComplexImage xc = x.cast<Complex>();
    EXPECT_LT((FftInverse(FftForward(xc)) - xc).abs().maxCoeff(), 1e-13) << ToString(s);
    EXPECT_LT((ExpandHalfSpectrum(FftR2C(x), s.cols) - FftForward(xc)).abs().maxCoeff(), 1e-10) << ToString(s);
  }
}

TEST(FftTest, MatchesTheNaiveDftOnBothPaths) {
  // 2-D plan; blocked row-column (>= 192 x 192: prime and odd sizes)
  for (Shape s : {Shape{6, 10}, Shape{193, 197}}) {
    const Image x = RandomImage(s, 9);
    const ComplexImage ref = NaiveDft(x.cast<Complex>(), -1);
    const double scale = ref.abs().maxCoeff();
    EXPECT_LT((FftForward(x.cast<Complex>()) - ref).abs().maxCoeff(), 1e-12 * scale) << ToString(s);
    EXPECT_LT((ExpandHalfSpectrum(FftR2C(x), s.cols) - ref).abs().maxCoeff(), 1e-12 * scale) << ToString(s);
    const ComplexImage inv = NaiveDft(ref, +1) / double(s.size());
    EXPECT_LT((FftInverse(ref) - inv).abs().maxCoeff(), 1e-12 * inv.abs().maxCoeff()) << ToString(s);
  }
}

TEST(FftTest, PlansAreCachedByShape) {
  for (Shape s : {Shape{20, 22}, Shape{200, 220}}) {
    const Image x = RandomImage(s, 1);
    FftR2C(x);
    const std::size_t n = FftPlanCount();
    for (int i = 0; i < 5; ++i) FftR2C(x);
    EXPECT_EQ(FftPlanCount(), n) << ToString(s);
  }
}

// Reproducibility (fft.hpp): the output bytes depend on the input bytes only, not on the thread count.
// Every size class the library meets: powers of two, even non-powers (2^a 3^b 5^c 7^d), odd sizes, primes
// above 7, tall and wide, one-row and one-column images, on every execution path (one 2-D plan below
// 192 x 192; blocked row-column above, its column pass strided or buffered: 200 x 382 has a half spectrum
// of 192 columns, 1024 x 2048 one of 16 MiB).
const std::vector<Shape>& SizeClasses() {
  static const std::vector<Shape> shapes = {
      {30, 40},   {1, 5},      {5, 1},      {7, 13},    {128, 128}, {192, 192}, {256, 192}, {257, 131},
      {193, 195}, {211, 223},  {200, 384},  {500, 500}, {512, 512}, {1, 40000}, {40000, 1}, {2, 30011},
      {1000, 96}, {1024, 1024}, {1009, 1013}, {200, 382}, {1024, 2048}};
  return shapes;
}

// All four transforms of one shape: r2c, c2r of that spectrum, complex forward and inverse.
struct Outputs {
  ComplexImage r2c, fwd, inv;
  Image c2r;
};
Outputs Transform(Shape s) {
  const Image x = RandomImage(s, 21);
  const ComplexImage xc = RandomImage(s, 22).cast<Complex>() + Complex(0, 1) * RandomImage(s, 23).cast<Complex>();
  Outputs o;
  o.r2c = FftR2C(x);
  o.c2r = FftC2R(o.r2c, s.cols);
  o.fwd = FftForward(xc);
  o.inv = FftInverse(xc);
  return o;
}
void ExpectSameBytes(const Outputs& a, const Outputs& b) {
  EXPECT_TRUE(SameBytes(a.r2c, b.r2c));
  EXPECT_TRUE(SameBytes(a.c2r, b.c2r));
  EXPECT_TRUE(SameBytes(a.fwd, b.fwd));
  EXPECT_TRUE(SameBytes(a.inv, b.inv));
}

TEST(FftTest, ResultsAreBitIdenticalForOneAndTwoThreads) {
  const int saved = DefaultThreads();
  for (Shape s : SizeClasses()) {
    SCOPED_TRACE(ToString(s));
    SetDefaultThreads(1);
    const Outputs one = Transform(s);
    SetDefaultThreads(2);
    const Outputs two = Transform(s);
    SetDefaultThreads(3);  // more threads than blocks on small shapes, an odd count on large ones
    const Outputs three = Transform(s);
    ExpectSameBytes(one, two);
    ExpectSameBytes(one, three);
  }
  SetDefaultThreads(saved);
}

// Run to run: plans made afresh (as in a new process, FFTW's wisdom forgotten) give the same bytes.
TEST(FftTest, ResultsAreBitIdenticalAfterPlanningAfresh) {
  const int saved = DefaultThreads();
  SetDefaultThreads(2);
  std::vector<Outputs> first;
  for (Shape s : SizeClasses()) first.push_back(Transform(s));
  FftResetPlansForTesting();
  EXPECT_EQ(FftPlanCount(), 0u);
  SetDefaultThreads(1);
  for (std::size_t k = 0; k < SizeClasses().size(); ++k) {
    SCOPED_TRACE(ToString(SizeClasses()[k]));
    ExpectSameBytes(first[k], Transform(SizeClasses()[k]));
  }
  SetDefaultThreads(saved);
}

TEST(FftTest, IntoVariantsEqualTheReturningOnesAndReuseTheBuffer) {
  for (Shape s : {Shape{20, 21}, Shape{300, 257}}) {
    const Image x = RandomImage(s, 3);
    ComplexImage X(s.rows, s.cols / 2 + 1);
    const Complex* before = X.data();
    FftR2CInto(x, &X);
    EXPECT_EQ(X.data(), before);
    EXPECT_TRUE(SameBytes(X, FftR2C(x)));
    Image back(s.rows, s.cols);
    const double* back_before = back.data();
    FftC2RInto(X, s.cols, &back);
    EXPECT_EQ(back.data(), back_before);
    EXPECT_TRUE(SameBytes(back, FftC2R(X, s.cols)));
    EXPECT_LT((back - x).abs().maxCoeff(), 1e-13);
  }
}

TEST(FftTest, ResultsDoNotDependOnWhereTheArraysLive) {
  // The same input bytes at a different address (and after other shapes have used the scratch buffers).
  const Image x = RandomImage({200, 170}, 4);
  const ComplexImage first = FftR2C(x);
  FftR2C(RandomImage({300, 300}, 5));
  std::vector<Image> elsewhere(3, x);
  for (const Image& e : elsewhere) EXPECT_TRUE(SameBytes(FftR2C(e), first));
}

TEST(FftTest, PlannerIsASettingNotMaths) {
  const FftSettings saved = GetFftSettings();
  EXPECT_EQ(saved.planner, FftSettings::Planner::kEstimate);  // the reproducible default
  const Image x = RandomImage({256, 192}, 21);
  const ComplexImage reference = FftR2C(x);
  FftSettings s;
  s.planner = FftSettings::Planner::kMeasure;
  SetFftSettings(s);
  const ComplexImage measured = FftR2C(x);
  SetFftSettings(saved);
  EXPECT_LT((measured - reference).abs().maxCoeff(), 1e-12 * reference.abs().maxCoeff());
}

// The wisdom aosr ships (data/fftw_wisdom.txt, compiled in) is read by this machine's FFTW: if a new FFTW
// build refuses it, this test says so (regenerate it with build/bench/fft_wisdom), instead of every transform
// silently falling back to FFTW_ESTIMATE's plans, 1.5-2x slower at 512^2 and up.
TEST(FftTest, ShippedWisdomIsReadByThisFftw) {
  ASSERT_NE(FftShippedWisdom()[0], '\0') << "data/fftw_wisdom.txt is empty";
#if defined(__x86_64__)
  // FFTW registers its AVX codelets only on a CPU that has AVX, and wisdom names the set it was made with.
  if (!__builtin_cpu_supports("avx")) GTEST_SKIP() << "no AVX: this FFTW's solver set differs from the wisdom's";
#endif
  FftResetPlansForTesting();
  EXPECT_FALSE(FftWisdomLoaded());
  FftR2C(RandomImage({256, 256}, 30));
  EXPECT_TRUE(FftWisdomLoaded());
}

// The shipped plans and FFTW_ESTIMATE's heuristic ones compute the same transforms to rounding, on both
// execution paths and for shapes in the wisdom (64, 256, 512) and not in it (odd, prime, rectangular).
TEST(FftTest, ShippedWisdomAndHeuristicPlansAgreeToRounding) {
  const FftSettings saved = GetFftSettings();
  EXPECT_TRUE(saved.shipped_wisdom);  // the default
  for (Shape s : {Shape{64, 64}, Shape{256, 256}, Shape{512, 512}, Shape{375, 375}, Shape{211, 300}}) {
    SCOPED_TRACE(ToString(s));
    SetFftSettings(saved);
    const Outputs shipped = Transform(s);
    FftSettings heuristic = saved;
    heuristic.shipped_wisdom = false;
    SetFftSettings(heuristic);
    const Outputs plain = Transform(s);
    const double scale = shipped.r2c.abs().maxCoeff();
    EXPECT_LT((shipped.r2c - plain.r2c).abs().maxCoeff(), 1e-13 * scale);
    EXPECT_LT((shipped.fwd - plain.fwd).abs().maxCoeff(), 1e-13 * shipped.fwd.abs().maxCoeff());
    EXPECT_LT((shipped.c2r - plain.c2r).abs().maxCoeff(), 1e-13 * shipped.c2r.abs().maxCoeff());
    EXPECT_LT((shipped.inv - plain.inv).abs().maxCoeff(), 1e-13 * shipped.inv.abs().maxCoeff());
  }
  SetFftSettings(saved);
}

// A plan is a function of its shape, whatever else the process planned: FFTW's wisdom store is shared by
// every FFTW user in the process, and an entry made by a timed FFTW_MEASURE plan of the very same problem
// (aosr's 2-D r2c, out of place) must not leak into aosr's reproducible plans: neither for a shape the
// shipped wisdom lacks (120^2) nor with the shipped wisdom off.
TEST(FftTest, PlansDoNotDependOnWhatElseThisProcessPlanned) {
  const FftSettings saved = GetFftSettings();
  FftSettings heuristic = saved;
  heuristic.shipped_wisdom = false;
  for (const auto& [settings, s] : {std::pair{saved, Shape{120, 120}}, std::pair{heuristic, Shape{128, 128}}}) {
    SCOPED_TRACE(ToString(s));
    SetFftSettings(settings);
    const Image x = RandomImage(s, 31);
    FftResetPlansForTesting();
    const ComplexImage clean = FftR2C(x);
    for (unsigned flags : {unsigned(FFTW_MEASURE), unsigned(FFTW_PATIENT)}) {
      FftResetPlansForTesting();
      double* in = fftw_alloc_real(std::size_t(s.rows * s.cols));
      fftw_complex* out = fftw_alloc_complex(std::size_t(s.rows * (s.cols / 2 + 1)));
      fftw_plan foreign = fftw_plan_dft_r2c_2d(int(s.rows), int(s.cols), in, out, flags);
      ASSERT_NE(foreign, nullptr);
      EXPECT_TRUE(SameBytes(FftR2C(x), clean)) << "after a foreign plan with flags " << flags;
      fftw_destroy_plan(foreign);
      fftw_free(in);
      fftw_free(out);
    }
  }
  SetFftSettings(saved);
}

}  // namespace
}  // namespace aosr
