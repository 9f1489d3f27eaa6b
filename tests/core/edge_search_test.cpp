// Finding straight edges for the slanted-edge MTF (core/edge_search.hpp): edges found where they are, at their
// angles, in regions that hold them alone; the MTF measured in the region found is the analytic one; and an
// image with nothing to read says why.
#include "aosr/core/edge_search.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "core/slanted_edge_fixture.hpp"
#include "support/testing.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

using ::testing::HasSubstr;

// Two Gaussian edges (σ = 1 px) in one 160 x 200 image: a near-vertical one at 6° on a dark-to-bright step in
// the left half, and a near-horizontal one (its transpose, at −8°) in the right half.
Image TwoEdges() {
  const Image v = test::GaussianEdge({160, 100}, 6.0, 1.0);
  const Image h = test::GaussianEdge({100, 160}, -8.0, 1.0).transpose();
  Image a(160, 200);
  a.leftCols(100) = v;
  a.rightCols(100) = h;
  return a;
}

TEST(EdgeSearch, FindsEachEdgeAtItsAngleInARegionOfItsOwn) {
  const Image a = TwoEdges();
  const std::vector<EdgeCandidate> c = FindStraightEdges(a);
  ASSERT_GE(c.size(), 2u);
  // The seam between the halves is an edge too, along the column direction (0°): found, not measurable.
  int vertical = 0, horizontal = 0, seam = 0;
  for (const EdgeCandidate& e : c) {
    std::printf("%s at %+.3f deg, %lld px, clear %lld px, roi x %lld + %lld, y %lld + %lld\n",
                e.vertical ? "vertical" : "horizontal", e.angle_deg, (long long)e.length_px, (long long)e.clear_px,
                (long long)e.roi.x0, (long long)e.roi.width, (long long)e.roi.y0, (long long)e.roi.height);
    if (std::abs(e.angle_deg) < 1.0) {
      ++seam;
      continue;
    }
    EXPECT_GE(e.clear_px, 20);
    if (e.vertical) {
      ++vertical;
      EXPECT_NEAR(std::abs(e.angle_deg), 6.0, 0.3);
      EXPECT_LE(e.roi.x0 + e.roi.width, 100);  // the left half only
    } else {
      ++horizontal;
      EXPECT_NEAR(std::abs(e.angle_deg), 8.0, 0.3);
      EXPECT_GE(e.roi.x0, 100);
    }
    // The measurement in the region found agrees on the angle, to the fit's precision.
    SlantedEdgeOptions o;
    o.roi = e.roi;
    const SlantedEdgeMtf m = MeasureSlantedEdgeMtf(a, o);
    EXPECT_EQ(m.vertical, e.vertical);
    EXPECT_NEAR(m.angle_deg, e.angle_deg, 0.3);
  }
  EXPECT_EQ(seam, 1);
  EXPECT_EQ(vertical, 1);
  EXPECT_EQ(horizontal, 1);
}

// With no region, the whole image is refused (two edges) and the first candidate measures: its MTF is the
// point-sampled Gaussian's, exp(−2π²σ²f²), within 0.01 up to 0.5 cycles/px.
TEST(EdgeSearch, TheAutomaticRegionReadsTheAnalyticMtf) {
  const Image a = TwoEdges();
  SlantedEdgeOptions o;
  o.curve_max = 0.5;
  const AutoEdgeMtf r = MeasureSlantedEdgeMtfAuto(a, o);
  EXPECT_FALSE(r.whole_image);
  ASSERT_GE(r.candidate, 0);
  EXPECT_TRUE(r.refused.empty()) << r.refused.front();
  double worst = 0;
  for (std::size_t k = 0; k < r.mtf.frequency.size(); ++k)
    worst = std::max(worst, std::abs(r.mtf.mtf[k] - test::GaussianMtf(1.0, r.mtf.frequency[k])));
  EXPECT_LT(worst, 0.01);
  // One edge filling the image: the whole image is used, as with no search at all.
  const Image one = test::GaussianEdge({120, 80}, 5.0, 1.0);
  const AutoEdgeMtf w = MeasureSlantedEdgeMtfAuto(one, o);
  EXPECT_TRUE(w.whole_image);
  EXPECT_EQ(w.roi.width, 80);
  EXPECT_NEAR(w.mtf.mtf50.frequency, MeasureSlantedEdgeMtf(one, o).mtf50.frequency, 1e-12);
}

TEST(EdgeSearch, NothingToReadSaysWhy) {
  EXPECT_THAT(test::ErrorOf<InvalidArgument>([] { MeasureSlantedEdgeMtfAuto(Image::Constant(64, 64, 3.0), {}); }),
              HasSubstr("No straight edge"));
  // Edges along the axes (an untilted chart): found, and refused with the reason.
  Image bars = Image::Zero(100, 100);
  bars.block(20, 30, 60, 20).setConstant(1.0);
  const std::string why = test::ErrorOf<InvalidArgument>([&] { MeasureSlantedEdgeMtfAuto(bars, {}); });
  EXPECT_THAT(why, HasSubstr("within 1 deg of an axis"));
  EXPECT_THAT(why, HasSubstr("rotation_deg"));
}

TEST(EdgeSearch, BadArgumentsAreNamed) {
  EdgeSearchOptions o;
  o.threshold = 1.0;
  EXPECT_THAT(test::ErrorOf<InvalidArgument>([&] { FindStraightEdges(Image::Zero(10, 10), o); }), HasSubstr("threshold"));
  o = {};
  o.min_length_px = 4;
  EXPECT_THAT(test::ErrorOf<InvalidArgument>([&] { FindStraightEdges(Image::Zero(10, 10), o); }), HasSubstr("min_length_px"));
  o = {};
  o.max_half_width_px = 3;
  EXPECT_THAT(test::ErrorOf<InvalidArgument>([&] { FindStraightEdges(Image::Zero(10, 10), o); }),
              HasSubstr("max_half_width_px"));
  o = {};
  o.max_candidates = 0;
  EXPECT_THAT(test::ErrorOf<InvalidArgument>([&] { MeasureSlantedEdgeMtfAuto(Image::Zero(10, 10), {}, o); }),
              HasSubstr("max_candidates"));
  Image nan = Image::Zero(10, 10);
  nan(3, 3) = std::nan("");
  EXPECT_THAT(test::ErrorOf<InvalidArgument>([&] { FindStraightEdges(nan); }), HasSubstr("non-finite"));
  EXPECT_THAT(test::ErrorOf<InvalidArgument>([&] { FindStraightEdges(Image::Zero(2, 9)); }), HasSubstr("3 x 3"));
}

}  // namespace AOSR_TEST_NS
}  // namespace aosr
