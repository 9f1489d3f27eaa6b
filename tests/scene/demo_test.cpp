#include "aosr/scene/demo.hpp"

#include <gtest/gtest.h>

#include "aosr/core/operators.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

DemoOptions Small() {
  DemoOptions o;
  o.lr_size = 32;
  o.psf_px = 32;
  o.pupil_px = 64;
  return o;
}

// Without noise the frames are exactly the shared forward model applied to the truth, and flux is kept.
TEST(DemoSceneTest, NoiselessFramesAreTheForwardModelOfTheTruth) {
  DemoOptions o = Small();
  o.noise_fraction = 0;
  const DemoScene s = MakeDemoScene(o);
  ASSERT_EQ(s.frames.size(), 4u);
  const ImageStack again = s.model->Render(s.truth);
  for (std::size_t i = 0; i < s.frames.size(); ++i) {
    EXPECT_EQ((s.frames[i] - again[i]).abs().maxCoeff(), 0.0);
    EXPECT_NEAR(s.frames[i].sum(), s.truth.sum(), 1e-10 * s.truth.sum());
  }
}

// The DM tip/tilt realises the raster: each PSF's centroid sits at its frame's offset.
TEST(DemoSceneTest, TiltedPsfsAreCentredOnTheRasterOffsets) {
  const DemoScene s = MakeDemoScene(Small());
  for (std::size_t i = 0; i < s.psfs.size(); ++i) {
    const Image& p = s.psfs[i];
    double cy = 0, cx = 0;
    for (Index y = 0; y < p.rows(); ++y)
      for (Index x = 0; x < p.cols(); ++x) cy += p(y, x) * (y - p.rows() / 2), cx += p(y, x) * (x - p.cols() / 2);
    // The window truncates faint wings asymmetrically, hence 0.02 px rather than rounding.
    EXPECT_NEAR(cy, s.offsets[i].dy, 0.02) << "frame " << i;
    EXPECT_NEAR(cx, s.offsets[i].dx, 0.02) << "frame " << i;
    EXPECT_NEAR(p.sum(), 1.0, 1e-12);
  }
}

TEST(DemoSceneTest, NoiseSigmaIsTheStatedFractionOfThePeak) {
  const DemoScene s = MakeDemoScene(Small());
  const DemoScene clean = [] {
    DemoOptions o = Small();
    o.noise_fraction = 0;
    return MakeDemoScene(o);
  }();
  double peak = 0;
  for (const Image& f : clean.frames) peak = std::max(peak, f.maxCoeff());
  EXPECT_DOUBLE_EQ(s.noise_sigma, 0.01 * peak);
  double var = 0;
  Index n = 0;
  for (std::size_t i = 0; i < s.frames.size(); ++i) {
    var += (s.frames[i] - clean.frames[i]).square().sum();
    n += s.frames[i].size();
  }
  EXPECT_NEAR(std::sqrt(var / n) / s.noise_sigma, 1.0, 0.05);
}

}  // namespace
}  // namespace aosr
