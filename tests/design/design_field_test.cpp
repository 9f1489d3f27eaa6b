// Design over a wide field (design_field.hpp, issue 31 item 7): the field objective is the mean of objective A
// over the psf_field's points, its gradient passes a Taylor test, anisoplanatism makes the far points' MSE larger,
// and RunDesignStudy reports each point's gain and the on-axis advice beside the field's.
#include "aosr/design/design_field.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <string>

#include "aosr/design/design_parameterisation.hpp"
#include "aosr/design/design_study.hpp"
#include "aosr/io/config.hpp"
#include "design/design_fixture.hpp"
#include "support/testing.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

using design_test::SmallOptics;
using design_test::TaylorAwayFromRaster;

// The J-band scene of the design regimes (camera pixel 1.76 λ/D, r = 2, analytic AO) with a psf_field: the guide
// star 10" left of the centre of a 100 x 200 frame (5.7" x 11.3"), a 1 x 3 grid along x (the nodes 4.3", 10" and
// 15.7" from it; at J θ0 ≈ 10").
SceneSpec FieldScene() {
  nlohmann::json j = ReadJsonFile(std::string(AOSR_SOURCE_DIR) + "/data/scenes/paper-sim-j-r2.json");
  j["detector"]["frame_px"] = {100, 200};
  j["psf_field"] = {{"guide_star_arcsec", {-10.0, 0.0}}, {"grid", {1, 3}}};
  return ParseScene(j, std::string(AOSR_SOURCE_DIR) + "/data/scenes/paper-sim-j-r2.json");
}

// Identical optics at every point and no realisations: the field objective is objective A, value and gradient.
TEST(DesignFieldTest, EqualPointsGiveObjectiveA) {
  FieldDesignOptics field;
  for (int k = 0; k < 3; ++k) {
    field.optics.push_back(SmallOptics(true));
    field.directions.push_back({1e-6 * k, 0.0});
  }
  DesignObjectiveOptions o;
  o.reconstructor.lambda = 0.05;
  o.realisations = 0;
  const FieldDesignObjective f(field, 3, o);
  const DesignObjective a(SmallOptics(true), 3, o);
  const DesignParameterisation p(design_test::SmallPupil(SmallOptics(true)), 3, 2, {});
  const std::vector<Image> w = p.RasterOpds();
  std::vector<Image> gf, ga;
  const double jf = f.Evaluate(w, &gf), ja = a.Evaluate(w, &ga);
  EXPECT_NEAR(jf, ja, 1e-12 * ja);
  ASSERT_EQ(gf.size(), ga.size());
  for (std::size_t i = 0; i < ga.size(); ++i) EXPECT_LT((gf[i] - ga[i]).abs().maxCoeff(), 1e-12 * ga[i].abs().maxCoeff());
  EXPECT_EQ(f.nodes(), 3);
  EXPECT_NEAR(f.invisible_floor(), a.invisible_floor(), 1e-15);
}

// A real field: each point's analytic AO model at its direction. J is the mean of the points' J, the far
// points' MSE is larger (the residual grows with the angle from the guide star), and the gradient of the mean
// passes the Taylor test (remainders fall 4x per halving).
TEST(DesignFieldTest, FieldMeanOfAnisoplanaticPointsWithItsGradient) {
  const SceneSpec scene = FieldScene();
  const FieldDesignOptics field = DesignOpticsOverField(scene);
  ASSERT_EQ(field.optics.size(), 3u);
  ASSERT_TRUE(field.optics[0].ao.has_value());
  DesignObjectiveOptions o;
  o.reconstructor.lambda = 0.05;
  const FieldDesignObjective f(field, scene.frames, o);
  DesignParameterisationOptions po;
  po.kind = DesignParameterisationKind::kTipTilt;
  const DesignParameterisation p(DesignPupilFromScene(scene), scene.frames, scene.r, po);
  const std::vector<Image> w = p.RasterOpds();
  const double j = f.Evaluate(w);
  double mean = 0;
  std::vector<double> per;
  for (int k = 0; k < 3; ++k) per.push_back(f.EvaluateNode(k, w)), mean += per.back() / 3;
  EXPECT_NEAR(j, mean, 1e-12 * j);
  EXPECT_LT(f.direction(0).Norm(), f.direction(2).Norm());
  EXPECT_LT(per[0], per[1]);
  EXPECT_LT(per[1], per[2]) << "anisoplanatism: the far point's expected MSE is larger";
  EXPECT_EQ(&f.optics(), &f.node(0).optics()) << "the point nearest the guide star describes the instrument";
  std::vector<double> rem;
  const std::vector<double> ratios = TaylorAwayFromRaster(f, p, 11, &rem);
  ASSERT_GE(ratios.size(), 3u);
  for (std::size_t k = ratios.size() - 3; k < ratios.size(); ++k) {
    EXPECT_GT(rem[k + 1], 1e-14) << "remainder at rounding level: the test is blind";
    EXPECT_NEAR(ratios[k], 4.0, 0.4) << "halving " << k;
  }
}

// RunDesignStudy with a psf_field: objective A over the field, each point's gain and advice, and the advice of
// the on-axis objective beside the field's; without realisations every J is exact and the field's gain is that
// of the points' mean.
TEST(DesignFieldTest, StudyReportsEachPointAndTheOnAxisAdvice) {
  const SceneSpec scene = FieldScene();
  DesignStudyOptions o;
  o.param = "tiptilt";
  o.starts = 1;
  o.iterations = 4;
  o.realisations = 0;
  o.threads = 1;
  const DesignStudy s = RunDesignStudy(scene, o);
  ASSERT_TRUE(s.summary.contains("field")) << s.summary.dump(2);
  const nlohmann::json& f = s.summary["field"];
  EXPECT_EQ(f["points"], 3);
  ASSERT_EQ(f["per_point"].size(), 3u);
  double raster = 0, design = 0;
  for (const nlohmann::json& q : f["per_point"]) {
    raster += q["objective_raster"].get<double>() / 3;
    design += q["objective_design"].get<double>() / 3;
    EXPECT_TRUE(q["advice"] == "design" || q["advice"] == "raster");
  }
  // Without realisations the check is the nominal model, exact: the gain's J are the points' means.
  EXPECT_NEAR(s.gain.objective_raster, raster, 1e-12 * raster);
  EXPECT_NEAR(s.gain.objective_design, design, 1e-12 * design);
  EXPECT_TRUE(f["on_axis"]["advice"] == "design" || f["on_axis"]["advice"] == "raster");
  EXPECT_EQ(f["advice"], s.gain.advice);
  EXPECT_EQ(f["advice_changes"].get<bool>(), f["on_axis"]["advice"] != s.gain.advice);
  EXPECT_TRUE(s.file["design"].contains("field"));
  // The on-axis objective sees less residual than the field's far point: its raster MSE is smaller.
  EXPECT_LT(f["on_axis"]["objective_raster"].get<double>(), f["per_point"][2]["objective_raster"].get<double>());
}

}  // namespace AOSR_TEST_NS
}  // namespace aosr
