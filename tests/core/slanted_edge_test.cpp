// The slanted-edge MTF's bookkeeping (core/slanted_edge.hpp): invariances (polarity, orientation, level and
// gain), the region of interest, and the reported figures. The physics is in slanted_edge_physics_test.cpp.
#include "aosr/core/slanted_edge.hpp"

#include <gtest/gtest.h>

#include "core/slanted_edge_fixture.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

using namespace aosr::test;

double MaxDifference(const SlantedEdgeMtf& a, const SlantedEdgeMtf& b) {
  EXPECT_EQ(a.mtf.size(), b.mtf.size());
  double worst = 0.0;
  for (std::size_t i = 0; i < std::min(a.mtf.size(), b.mtf.size()); ++i) worst = std::max(worst, std::abs(a.mtf[i] - b.mtf[i]));
  return worst;
}

TEST(SlantedEdgeTest, PolarityOrientationGainAndLevelDoNotChangeTheCurve) {
  const Image img = GaussianEdge(EdgeShape(80, 40, 6.0), 6.0, 1.2);
  const SlantedEdgeMtf m = MeasureSlantedEdgeMtf(img);
  EXPECT_TRUE(m.vertical);
  EXPECT_NEAR(m.angle_deg, 6.0, 0.01);  // one row down moves this edge tan 6° toward +x (the fixture's convention)
  EXPECT_DOUBLE_EQ(m.mtf[0], 1.0);
  // Bright on the left.
  const Image flipped = img.rowwise().reverse();
  const SlantedEdgeMtf f = MeasureSlantedEdgeMtf(flipped);
  EXPECT_NEAR(f.angle_deg, -6.0, 0.01);
  EXPECT_LT(MaxDifference(m, f), 1e-9);
  // A near-horizontal edge (the transpose) is read along the columns.
  const SlantedEdgeMtf t = MeasureSlantedEdgeMtf(Image(img.transpose()));
  EXPECT_FALSE(t.vertical);
  EXPECT_LT(MaxDifference(m, t), 1e-12);
  EXPECT_NEAR(t.centre_y, m.centre_x, 1e-9);
  EXPECT_NEAR(t.centre_x, m.centre_y, 1e-9);
  // Gain and offset: the levels follow, the curve does not move.
  const SlantedEdgeMtf g = MeasureSlantedEdgeMtf(3.0 * img + 5.0);
  EXPECT_LT(MaxDifference(m, g), 1e-9);
  EXPECT_NEAR(g.low, 3.0 * m.low + 5.0, 1e-9);
  EXPECT_NEAR(g.high, 3.0 * m.high + 5.0, 1e-9);
  EXPECT_FALSE(std::isfinite(m.contrast_to_noise));  // noise-free
}

TEST(SlantedEdgeTest, TheRegionSelectsOneEdgeOfMany) {
  // Two edges side by side (a bar 60 px wide); the region around the left one measures it alone.
  const Image edge = GaussianEdge({80, 60}, 5.0, 1.0);
  Image two(80, 120);
  two.leftCols(60) = edge;
  two.rightCols(60) = edge.rowwise().reverse();
  SlantedEdgeOptions o;
  o.roi = {10, 5, 40, 70};
  const SlantedEdgeMtf m = MeasureSlantedEdgeMtf(two, o);
  SlantedEdgeOptions whole;
  whole.roi = {0, 5, 60, 70};
  const SlantedEdgeMtf ref = MeasureSlantedEdgeMtf(edge, whole);
  EXPECT_NEAR(m.mtf50.frequency, ref.mtf50.frequency, 0.003);
  EXPECT_NEAR(m.centre_x, 29.5, 0.05);  // image coordinates: the edge's column at the region's middle row
  EXPECT_NEAR(m.centre_y, 39.5, 1e-12);
  EXPECT_EQ(m.edge_length_px, 70);
}

TEST(SlantedEdgeTest, FiguresAreReadOffTheSameCurve) {
  const double sigma = 1.0;
  const Image img = GaussianEdge(EdgeShape(100, 64, 5.0), 5.0, sigma);
  SlantedEdgeOptions o;
  o.r = 4;
  o.pixel_lambda_over_d = 0.25;
  o.frequencies = {0.1, 0.3};
  o.curve_max = 0.6;
  o.curve_step = 0.05;
  const SlantedEdgeMtf m = MeasureSlantedEdgeMtf(img, o);
  ASSERT_EQ(m.frequency.size(), 13u);
  EXPECT_NEAR(m.frequency.back(), 0.6, 1e-12);
  ASSERT_TRUE(m.has_nyquist);
  EXPECT_DOUBLE_EQ(m.nyquist.frequency, 0.125);
  EXPECT_NEAR(m.nyquist.mtf, GaussianMtf(sigma, 0.125), 0.01);
  ASSERT_TRUE(m.has_cutoff);
  EXPECT_DOUBLE_EQ(m.cutoff.frequency, 0.25);
  EXPECT_NEAR(m.cutoff.mtf, m.mtf[5], 1e-12);  // 0.25 = 5 steps of 0.05
  ASSERT_EQ(m.at.size(), 2u);
  EXPECT_NEAR(m.at[1].mtf, m.mtf[6], 1e-12);
  EXPECT_NEAR(m.at[0].mtf, GaussianMtf(sigma, 0.1), 0.01);
  ASSERT_TRUE(m.mtf50.reached && m.mtf10.reached);
  EXPECT_LT(m.mtf50.frequency, m.mtf10.frequency);
  EXPECT_NEAR(m.mtf10.frequency, std::sqrt(std::log(10.0) / (2 * M_PI * M_PI)) / sigma, 0.005);
  EXPECT_EQ(m.esf.size(), m.lsf.size());
  EXPECT_EQ(m.esf.size(), m.esf_distance.size());
  EXPECT_DOUBLE_EQ(m.esf_distance[1] - m.esf_distance[0], 0.25);
  EXPECT_NE(m.BriefReport().find("MTF50 0.18"), std::string::npos) << m.BriefReport();
  // A sharp-enough curve that never falls to 0.1 below 1.5 cycles/px says so.
  SlantedEdgeOptions wide;
  const SlantedEdgeMtf s = MeasureSlantedEdgeMtf(GaussianEdge(EdgeShape(100, 64, 5.0), 5.0, 0.15), wide);
  EXPECT_FALSE(s.mtf10.reached);
  EXPECT_TRUE(std::isnan(s.mtf10.frequency));
}

}  // namespace
}  // namespace aosr
