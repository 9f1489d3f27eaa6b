// A USAF chart turned as a test bench mounts it (objects.hpp rotation_deg) and the slanted-edge MTF read from its
// bars with no region given (core/edge_search.hpp): the turned bars keep their area exactly, the edges found read
// the analytic transfer of a blurred chart, the untilted chart is refused with the reason, and the contrast
// reading (usaf_contrast.hpp) refuses a turned chart.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "aosr/core/edge_search.hpp"
#include "aosr/core/fft.hpp"
#include "aosr/scene/objects.hpp"
#include "aosr/scene/usaf_contrast.hpp"
#include "core/slanted_edge_fixture.hpp"
#include "support/testing.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

using ::testing::HasSubstr;

// Group -2 alone at 8 px/mm: bars 16 px wide (element 1) down to 9 px (element 6), in a 400 x 400 field.
UsafOptions BigChart(double rotation_deg) {
  UsafOptions o;
  o.first_group = -2;
  o.last_group = -2;
  o.pixels_per_mm = 8.0;
  o.rotation_deg = rotation_deg;
  return o;
}

// The image blurred by a Gaussian of σ px (periodic; the chart sits far from the field's sides).
Image GaussianBlur(const Image& a, double sigma) {
  ComplexImage f = FftForward(a.cast<Complex>());
  for (Index y = 0; y < f.rows(); ++y)
    for (Index x = 0; x < f.cols(); ++x) {
      const double fy = double(SignedFrequency(y, f.rows())) / double(f.rows());
      const double fx = double(SignedFrequency(x, f.cols())) / double(f.cols());
      f(y, x) *= test::GaussianMtf(sigma, std::hypot(fy, fx));
    }
  return FftInverse(f).real();
}

TEST(UsafEdgePhysics, ATurnedChartKeepsEveryBarsAreaExactly) {
  const Shape shape{560, 560};
  const Image flat = UsafTarget(shape, BigChart(0.0));
  double area = 0;  // the bars' total area: every bar lies inside the field, turned or not
  for (const UsafBar& b : UsafBars(shape, BigChart(0.0))) area += b.rect.area();
  const UsafSize size = UsafTargetSize(BigChart(0.0));
  ASSERT_LT(8.0 * std::hypot(size.height_mm, size.width_mm), 556.0);
  EXPECT_NEAR(flat.sum(), area, 1e-9 * area);
  for (double deg : {5.0, -7.0, 30.0}) {
    const Image turned = UsafTarget(shape, BigChart(deg));
    EXPECT_NEAR(turned.sum(), area, 1e-9 * area) << deg << " deg";
    EXPECT_GE(turned.minCoeff(), -1e-12);
    EXPECT_LE(turned.maxCoeff(), 1.0 + 1e-12);  // overlapping bars would exceed 1
  }
  // A turn by a right angle's worth of nothing: 0 renders the untilted chart itself.
  EXPECT_EQ((UsafTarget(shape, BigChart(0.0)) - flat).abs().maxCoeff(), 0.0);
}

// The chart turned by 5° and blurred by a Gaussian (σ = 1.2 px): the edge found reads
// exp(−2π²σ²f²) sinc(f cos θ) sinc(f sin θ) (the exact area coverage is the pixel box) within 0.02 up to the
// Nyquist, and its MTF50 within 2 %.
TEST(UsafEdgePhysics, EdgesFoundOnTheTurnedChartReadItsTransfer) {
  const double sigma = 1.2;
  const Image chart = GaussianBlur(UsafTarget({400, 400}, BigChart(5.0)), sigma);
  SlantedEdgeOptions o;
  o.curve_max = 0.5;
  const AutoEdgeMtf r = MeasureSlantedEdgeMtfAuto(chart, o);
  ASSERT_FALSE(r.whole_image);
  const EdgeCandidate& e = r.candidates[std::size_t(r.candidate)];
  std::printf("%s edge at %+.3f deg, %lld rows, clear %lld px; %s\n", e.vertical ? "vertical" : "horizontal",
              r.mtf.angle_deg, (long long)r.mtf.edge_length_px, (long long)e.clear_px, r.mtf.BriefReport().c_str());
  EXPECT_NEAR(std::abs(r.mtf.angle_deg), 5.0, 0.1);
  const double th = r.mtf.angle_deg * M_PI / 180.0;
  auto truth = [&](double f) {
    return test::GaussianMtf(sigma, f) * test::SincPi(f * std::cos(th)) * test::SincPi(f * std::sin(th));
  };
  double worst = 0;
  for (std::size_t k = 0; k < r.mtf.frequency.size(); ++k)
    worst = std::max(worst, std::abs(r.mtf.mtf[k] - truth(r.mtf.frequency[k])));
  EXPECT_LT(worst, 0.02);
  // MTF50 of the analytic curve, by bisection.
  double lo = 0.0, hi = 0.5;
  for (int i = 0; i < 60; ++i) ((truth(0.5 * (lo + hi)) > 0.5) ? lo : hi) = 0.5 * (lo + hi);
  ASSERT_TRUE(r.mtf.mtf50.reached);
  EXPECT_NEAR(r.mtf.mtf50.frequency, lo, 0.02 * lo);
}

TEST(UsafEdgePhysics, TheUntiltedChartAndATooSmallOneSayWhy) {
  const Image flat = GaussianBlur(UsafTarget({400, 400}, BigChart(0.0)), 1.2);
  EXPECT_THAT(test::ErrorOf<InvalidArgument>([&] { MeasureSlantedEdgeMtfAuto(flat, {}); }),
              HasSubstr("within 1 deg of an axis"));
  UsafOptions small = BigChart(5.0);
  small.pixels_per_mm = 3.0;  // bars of 6 px and less: no level on either side of an edge
  const Image crowded = UsafTarget({200, 200}, small);
  EXPECT_THAT(test::ErrorOf<InvalidArgument>([&] { MeasureSlantedEdgeMtfAuto(crowded, {}); }),
              HasSubstr("clear of the next edge"));
}

TEST(UsafEdgePhysics, TurnedChartsAreRefusedWhereTheyCannotBeRead) {
  const UsafOptions turned = BigChart(5.0);
  EXPECT_THAT(test::ErrorOf<InvalidArgument>(
                  [&] { MeasureUsafResolvingPower(UsafTarget({400, 400}, turned), turned, UsafContrastOptions{}); }),
              HasSubstr("rotation_deg"));
  UsafOptions bad = turned;
  bad.supersample = 4;
  EXPECT_THAT(test::ErrorOf<InvalidArgument>([&] { UsafTarget({400, 400}, bad); }), HasSubstr("supersample"));
  bad = turned;
  bad.rotation_deg = 50;
  EXPECT_THAT(test::ErrorOf<InvalidArgument>([&] { UsafTarget({400, 400}, bad); }), HasSubstr("rotation_deg"));
}

}  // namespace AOSR_TEST_NS
}  // namespace aosr
