// The design file's per-exposure reports (design_file.hpp): the Shack-Hartmann reference slopes of an offset,
// including a sensor whose lenslets do not divide the telescope's pupil grid (the paper bench: 25 lenslets on
// 128 pixels, sampled on 150).
#include "aosr/design/design_file.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "aosr/design/design_parameterisation.hpp"
#include "aosr/scene/scene_spec.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

// A pure image shift s (camera px) is a wavefront tilt of angle s · pixel [rad]: every lenslet of a
// geometric Shack-Hartmann sees that slope, whatever grid samples the pupil. Oracle: the geometry alone.
void ExpectShiftSlopes(const std::string& scene_file) {
  const SceneSpec scene = LoadScene(std::string(AOSR_SOURCE_DIR) + "/data/scenes/" + scene_file);
  DesignParameterisationOptions po;
  po.kind = DesignParameterisationKind::kRaster;
  const DesignParameterisation p(DesignPupilFromScene(scene), scene.frames, scene.r, po);
  const Vector theta = p.RasterParameters();
  const std::vector<DesignFrameReport> reports = DescribeDesign(scene, p, p.Opds(theta), p.Offsets(theta));
  const std::vector<DmOffset> offsets = p.Offsets(theta);
  ASSERT_EQ(reports.size(), offsets.size());
  for (std::size_t i = 0; i < reports.size(); ++i) {
    const Vector& s = reports[i].reference_slopes_rad;
    ASSERT_GT(s.size(), 0) << scene_file;
    ASSERT_EQ(s.size() % 2, 0);
    const Index v = s.size() / 2;  // x slopes of the valid lenslets, then y slopes
    const double ax = offsets[i].shift_x_px * scene.CameraPixelRad();
    const double ay = offsets[i].shift_y_px * scene.CameraPixelRad();
    ASSERT_GT(std::abs(ax), 0);
    for (Index k = 0; k < v; ++k) {
      EXPECT_NEAR(std::abs(s[k]), std::abs(ax), 2e-3 * std::abs(ax)) << scene_file << " frame " << i << " lenslet " << k;
      EXPECT_NEAR(std::abs(s[v + k]), std::abs(ay), 2e-3 * std::abs(ay)) << scene_file << " frame " << i << " lenslet " << k;
    }
  }
}

TEST(DescribeDesignTest, ShiftSlopesOnTheTelescopesOwnGrid) { ExpectShiftSlopes("paper-sim-r2.json"); }

TEST(DescribeDesignTest, ShiftSlopesWhenTheLensletsDoNotDivideThePupilGrid) {
  ExpectShiftSlopes("paper-bench.json");
}

}  // namespace
}  // namespace aosr
