// The design file's per-exposure reports (design_file.hpp): the Shack-Hartmann reference slopes of an offset,
// including a sensor whose lenslets do not divide the telescope's pupil grid (the paper bench: 25 lenslets on
// 128 pixels, sampled on 150), and the modal content.
#include "aosr/design/design_file.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <nlohmann/json.hpp>
#include <string>

#include "aosr/design/design_parameterisation.hpp"
#include "aosr/optics/zernike.hpp"
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

// Modal content (design_file.hpp): the least-squares Zernike fit of each offset. Oracles: a raster is tip and
// tilt only, of the coefficient a shift's tilt has (optics/zernike.hpp TiltCoefficientForShift); a Zernike
// design's own coefficients come back exactly (the fit is exact on combinations of the modes) with nothing beyond.
TEST(DescribeDesignTest, ModalContentOfARasterIsItsTipAndTilt) {
  const SceneSpec scene = LoadScene(std::string(AOSR_SOURCE_DIR) + "/data/scenes/paper-sim-r2.json");
  DesignParameterisationOptions po;
  po.kind = DesignParameterisationKind::kRaster;
  const DesignParameterisation p(DesignPupilFromScene(scene), scene.frames, scene.r, po);
  const Vector theta = p.RasterParameters();
  const std::vector<DmOffset> offsets = p.Offsets(theta);
  const std::vector<DesignFrameReport> reports = DescribeDesign(scene, p, p.Opds(theta), offsets);
  const double d = scene.telescope.aperture.pupil.diameter_m;
  double largest = 0;
  for (std::size_t i = 0; i < reports.size(); ++i) {
    const Vector& c = reports[i].zernike_m;
    ASSERT_EQ(c.size(), kModalContentNoll);
    // Noll: Z2 tilts along x, Z3 along y; the sign follows the shift convention, the size is the oracle's.
    const double tx = std::abs(TiltCoefficientForShift(offsets[i].shift_x_px * scene.CameraPixelRad(), d));
    const double ty = std::abs(TiltCoefficientForShift(offsets[i].shift_y_px * scene.CameraPixelRad(), d));
    EXPECT_NEAR(std::abs(c[1]), tx, 1e-6 * std::max(tx, ty) + 1e-15) << "frame " << i;
    EXPECT_NEAR(std::abs(c[2]), ty, 1e-6 * std::max(tx, ty) + 1e-15) << "frame " << i;
    largest = std::max({largest, tx, ty});
    for (int j = 4; j <= kModalContentNoll; ++j) EXPECT_LT(std::abs(c[j - 1]), 1e-9 * largest + 1e-15) << "Z" << j;
    EXPECT_LT(reports[i].beyond_m, 1e-9 * largest + 1e-15);
  }
  ASSERT_GT(largest, 0);
  // The file's record: Noll 2..36, the per-mode sums over the offsets.
  const nlohmann::json mc = ModalContentJson(reports);
  ASSERT_EQ(mc["noll"].size(), std::size_t(kModalContentNoll - 1));
  EXPECT_EQ(mc["noll"][0].get<int>(), 2);
  double sum_abs_z2 = 0, power_z3 = 0;
  for (const DesignFrameReport& r : reports) sum_abs_z2 += std::abs(r.zernike_m[1]) * 1e9, power_z3 += std::pow(r.zernike_m[2] * 1e9, 2);
  EXPECT_NEAR(mc["sum_abs_nm"][0].get<double>(), sum_abs_z2, 1e-9 * sum_abs_z2);
  EXPECT_NEAR(mc["power_nm2"][1].get<double>(), power_z3, 1e-9 * power_z3);
  EXPECT_NEAR(mc["rms_over_frames_nm"][1].get<double>(), std::sqrt(power_z3 / reports.size()), 1e-9 * std::sqrt(power_z3));
}

TEST(DescribeDesignTest, ModalContentRecoversAZernikeDesignsCoefficients) {
  const SceneSpec scene = LoadScene(std::string(AOSR_SOURCE_DIR) + "/data/scenes/paper-sim-r2.json");
  DesignParameterisationOptions po;
  po.kind = DesignParameterisationKind::kZernike;
  po.zernike_modes = 20;  // Noll 2..21
  const DesignParameterisation p(DesignPupilFromScene(scene), scene.frames, scene.r, po);
  Vector theta = p.RasterParameters();
  for (Index k = 0; k < theta.size(); ++k) theta[k] += 0.3 * p.ParameterScale() * std::sin(1.7 * double(k) + 0.4);
  const std::vector<Vector> coefficients = p.Coefficients(theta);
  const std::vector<DesignFrameReport> reports = DescribeDesign(scene, p, p.Opds(theta), p.Offsets(theta));
  for (std::size_t i = 0; i < reports.size(); ++i) {
    const Vector& c = reports[i].zernike_m;
    const double scale = coefficients[i].cwiseAbs().maxCoeff();
    ASSERT_GT(scale, 0);
    for (int j = 2; j <= 21; ++j)
      EXPECT_NEAR(c[j - 1], coefficients[i][j - 2], 1e-8 * scale) << "frame " << i << " Z" << j;
    for (int j = 22; j <= kModalContentNoll; ++j) EXPECT_LT(std::abs(c[j - 1]), 1e-8 * scale) << "Z" << j;
    EXPECT_LT(reports[i].beyond_m, 1e-8 * scale);
  }
}

}  // namespace
}  // namespace aosr
