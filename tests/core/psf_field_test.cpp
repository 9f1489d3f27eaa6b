#include "aosr/core/psf_field.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <vector>


namespace aosr {
namespace AOSR_TEST_NS {

TEST(PsfFieldGridTest, NodesSitOnTheFrameEdgesAndCentre) {
  const PsfFieldGrid g({64, 48}, 3, 4);
  EXPECT_EQ(g.nodes(), 12);
  EXPECT_DOUBLE_EQ(g.Node(0)[0], 0.0);
  EXPECT_DOUBLE_EQ(g.Node(0)[1], 0.0);
  EXPECT_DOUBLE_EQ(g.Node(11)[0], 63.0);
  EXPECT_DOUBLE_EQ(g.Node(11)[1], 47.0);
  EXPECT_DOUBLE_EQ(g.Node(5)[0], 31.5);  // row 1 of 3: the centre
  EXPECT_DOUBLE_EQ(g.Node(5)[1], 47.0 / 3.0);
  EXPECT_DOUBLE_EQ(g.Spacing()[0], 31.5);
  EXPECT_DOUBLE_EQ(g.Spacing()[1], 47.0 / 3.0);
  const PsfFieldGrid one({64, 48}, 1, 1);
  EXPECT_DOUBLE_EQ(one.Node(0)[0], 31.5);
  EXPECT_DOUBLE_EQ(one.Node(0)[1], 23.5);
  EXPECT_DOUBLE_EQ(one.Spacing()[0], 0.0);
}

// The weights form a partition of unity at every pixel (flux is conserved whatever the PSFs), are 1 at their
// own node and 0 at the others, and are bilinear in between.
TEST(PsfFieldGridTest, WeightMapsArePartitionOfUnityAndExactAtNodes) {
  for (int s : {1, 3}) {
    const PsfFieldGrid g({40, 30}, 3, 2);
    Image sum = Image::Zero(40 * s, 30 * s);
    for (int k = 0; k < g.nodes(); ++k) {
      const Image w = g.WeightMap(k, s);
      EXPECT_GE(w.minCoeff(), 0.0);
      sum += w;
    }
    EXPECT_LT((sum.array() - 1.0).abs().maxCoeff(), 1e-14) << "s = " << s;
  }
  const PsfFieldGrid g({41, 31}, 3, 2);  // nodes at whole pixels: rows 0, 20, 40; cols 0, 30
  const Image w4 = g.WeightMap(4);       // node (2, 0)
  EXPECT_DOUBLE_EQ(w4(40, 0), 1.0);
  EXPECT_DOUBLE_EQ(w4(20, 0), 0.0);
  EXPECT_DOUBLE_EQ(w4(30, 0), 0.5);
  EXPECT_DOUBLE_EQ(w4(30, 15), 0.25);
  EXPECT_DOUBLE_EQ(w4(30, 30), 0.0);
  // The point weights agree with the maps.
  for (const PsfFieldGrid::Weight& w : g.Weights(33.0, 7.0))
    EXPECT_NEAR(w.weight, g.WeightMap(w.node)(33, 7), 1e-15) << w.node;
}

TEST(PsfFieldGridTest, FinerSkyMapsSampleTheSameWeightsAtTheSameAngles) {
  const PsfFieldGrid g({21, 21}, 2, 2);
  const Image coarse = g.WeightMap(0, 1), fine = g.WeightMap(0, 3);
  // Fine pixel 3 J + 1 is centred on HR pixel J.
  for (Index y = 0; y < 21; ++y)
    for (Index x = 0; x < 21; ++x) EXPECT_NEAR(fine(3 * y + 1, 3 * x + 1), coarse(y, x), 1e-15);
}

TEST(PsfFieldGridTest, InterpolationIsExactAtNodesAndLinearBetween) {
  const PsfFieldGrid g({11, 11}, 2, 2);
  ImageStack psfs;
  for (int k = 0; k < 4; ++k) psfs.push_back(Image::Constant(4, 4, double(k + 1)));
  EXPECT_DOUBLE_EQ(g.Interpolate(psfs, 0, 0)(0, 0), 1.0);
  EXPECT_DOUBLE_EQ(g.Interpolate(psfs, 10, 10)(2, 3), 4.0);
  // Midway along x at the top: (1 + 2) / 2; the centre: the mean of all four.
  EXPECT_DOUBLE_EQ(g.Interpolate(psfs, 0, 5)(1, 1), 1.5);
  EXPECT_DOUBLE_EQ(g.Interpolate(psfs, 5, 5)(1, 1), 2.5);
  // Beyond the outer nodes: clamped to them.
  EXPECT_DOUBLE_EQ(g.Interpolate(psfs, -3, 14)(0, 0), 2.0);
}

}  // namespace AOSR_TEST_NS
}  // namespace aosr
