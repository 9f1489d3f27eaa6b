// Scores across the field (scene/evaluation.hpp, EvaluationOptions::rings): the rings' scores are those of
// CompareImagesInRings, and each ring's photometric bias is the median flux error of the stars in it.
#include "aosr/scene/evaluation.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

namespace aosr {
namespace AOSR_TEST_NS {

// Stars as Gaussians of σ = 1.2 HR px on a faint smooth background, on a 128² HR grid.
Image RenderStars(const std::vector<PointSource>& stars, Shape s) {
  Image img(s.rows, s.cols);
  for (Index y = 0; y < s.rows; ++y)
    for (Index x = 0; x < s.cols; ++x) img(y, x) = 5.0 + 2.0 * std::sin(0.05 * double(y)) * std::cos(0.04 * double(x));
  const double var = 1.2 * 1.2;
  for (const PointSource& p : stars)
    for (Index y = 0; y < s.rows; ++y)
      for (Index x = 0; x < s.cols; ++x)
        img(y, x) += p.flux / (6.283185307179586 * var) * std::exp(-((y - p.y) * (y - p.y) + (x - p.x) * (x - p.x)) / (2 * var));
  return img;
}

// Stars beyond 45 HR px from the centre come back 5 % too bright, the others exactly: only the outer rings show the
// bias (+5 % to the aperture's rounding), and the ring scores are CompareImagesInRings'.
TEST(EvaluationTest, RingPhotometryShowsABiasOnlyWhereItIs) {
  const Shape s{128, 128};
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> u(8.0, 120.0), f(2e3, 2e4);
  std::vector<PointSource> stars;
  for (int tries = 0; stars.size() < 40 && tries < 100000; ++tries) {
    const PointSource p{u(rng), u(rng), f(rng)};
    bool isolated = true;  // no star's light (σ = 1.2 px) in another's aperture or annulus (8 px)
    for (const PointSource& q : stars) isolated = isolated && std::hypot(p.y - q.y, p.x - q.x) > 14;
    if (isolated) stars.push_back(p);
  }
  ASSERT_EQ(stars.size(), 40u);
  std::vector<PointSource> seen = stars;
  for (PointSource& p : seen)
    if (std::hypot(p.y - 63.5, p.x - 63.5) > 45) p.flux *= 1.05;
  const Image truth = RenderStars(stars, s), estimate = RenderStars(seen, s);
  EvaluationOptions o;
  o.rings = 3;  // 0-28, 28-56, 56-84 px: inside, across and beyond the 45-px boundary
  o.stars = 1000;
  o.crop_px = 4;
  const Evaluation e = EvaluateReconstruction(truth, estimate, stars, o);
  ASSERT_TRUE(e.measured_rings);
  ASSERT_EQ(e.rings.rings.size(), 3u);
  ASSERT_EQ(e.ring_stars.size(), 3u);
  MetricOptions mo;
  mo.crop_px = 4;
  const RingMetrics direct = CompareImagesInRings(truth, estimate, RingOptions{3}, mo);
  int measured = 0;
  for (std::size_t k = 0; k < 3; ++k) {
    const RingScore& r = e.rings.rings[k];
    EXPECT_EQ(r.scores.raw.psnr, direct.rings[k].scores.raw.psnr);
    EXPECT_EQ(r.scores.aligned.psnr, direct.rings[k].scores.aligned.psnr);
    const RingPhotometry& p = e.ring_stars[k];
    measured += p.stars;
    std::printf("ring %zu (%.1f-%.1f px): %d stars, flux bias %+.3f %%, PSNR %.2f dB\n", k, r.inner_px, r.outer_px,
                p.stars, 100 * p.flux_bias, r.scores.aligned.psnr);
    ASSERT_GT(p.stars, 2) << "ring " << k;
    if (r.outer_px <= 45) {
      EXPECT_NEAR(p.flux_bias, 0.0, 1e-9) << "ring " << k;
      EXPECT_NEAR(p.median_abs_flux_error, 0.0, 1e-9) << "ring " << k;
    } else if (r.inner_px >= 45) {
      EXPECT_NEAR(p.flux_bias, 0.05, 0.005) << "ring " << k;  // the aperture holds ~96 % of a star; the rest is the same
    }
  }
  // Every star (all lie in the crop, their annuli in the image) is in exactly one ring.
  EXPECT_EQ(measured, 40);
  // Without a catalogue: rings but no photometry.
  const Evaluation plain = EvaluateReconstruction(truth, estimate, {}, o);
  EXPECT_TRUE(plain.measured_rings);
  EXPECT_TRUE(plain.ring_stars.empty());
  // rings = 0: none.
  o.rings = 0;
  EXPECT_FALSE(EvaluateReconstruction(truth, estimate, stars, o).measured_rings);
}

}  // namespace
}  // namespace aosr
