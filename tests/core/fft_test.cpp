#include "aosr/core/fft.hpp"

#include <gtest/gtest.h>

#include <cstring>

#include "aosr/core/parallel.hpp"
#include "support/testing.hpp"

namespace aosr {
namespace {

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
                  Shape{256, 192}, Shape{600, 1}}) {
    const Image x = RandomImage(s, 5);
    const Image back = FftC2R(FftR2C(x), s.cols);
    EXPECT_LT((back - x).abs().maxCoeff(), 1e-13) << ToString(s);
    const ComplexImage xc = x.cast<Complex>();
    EXPECT_LT((FftInverse(FftForward(xc)) - xc).abs().maxCoeff(), 1e-13) << ToString(s);
    EXPECT_LT((ExpandHalfSpectrum(FftR2C(x), s.cols) - FftForward(xc)).abs().maxCoeff(), 1e-10) << ToString(s);
  }
}

TEST(FftTest, MatchesTheNaiveDftOnBothPaths) {
  for (Shape s : {Shape{6, 10}, Shape{128, 129}}) {  // 2-D plan; blocked row-column (>= 128 x 128)
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
TEST(FftTest, ResultsAreBitIdenticalForOneAndTwoThreads) {
  const int saved = DefaultThreads();
  for (Shape s : {Shape{30, 40}, Shape{128, 128}, Shape{256, 192}, Shape{257, 131}, Shape{512, 512}}) {
    SCOPED_TRACE(ToString(s));
    const Image x = RandomImage(s, 21);
    const ComplexImage xc = RandomImage(s, 22).cast<Complex>() + Complex(0, 1) * RandomImage(s, 23).cast<Complex>();
    SetDefaultThreads(1);
    const ComplexImage a1 = FftR2C(x), f1 = FftForward(xc), i1 = FftInverse(xc);
    const Image c1 = FftC2R(a1, s.cols);
    SetDefaultThreads(2);
    const ComplexImage a2 = FftR2C(x), f2 = FftForward(xc), i2 = FftInverse(xc);
    const Image c2 = FftC2R(a2, s.cols);
    EXPECT_TRUE(SameBytes(a1, a2));
    EXPECT_TRUE(SameBytes(c1, c2));
    EXPECT_TRUE(SameBytes(f1, f2));
    EXPECT_TRUE(SameBytes(i1, i2));
  }
  SetDefaultThreads(saved);
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

}  // namespace
}  // namespace aosr
