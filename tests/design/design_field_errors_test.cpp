// FieldDesignObjective and DesignOpticsOverField refuse what cannot be averaged over a field (design_field.hpp):
// no points, directions that do not match the points, points that do not share the DM's pupil and design grid,
// and a field point the analytic AO model cannot reach.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <string>

#include "aosr/design/design_field.hpp"
#include "aosr/io/config.hpp"
#include "design/design_fixture.hpp"
#include "support/testing.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

using aosr::test::ErrorOf;
using design_test::SmallOptics;
using ::testing::AllOf;
using ::testing::HasSubstr;

TEST(DesignFieldErrorsTest, PointsDirectionsAndSharedGrids) {
  DesignObjectiveOptions o;
  o.realisations = 0;
  FieldDesignOptics empty;
  EXPECT_THAT(ErrorOf([&] { FieldDesignObjective(empty, 2, o); }),
              AllOf(HasSubstr("FieldDesignObjective"), HasSubstr("field"), HasSubstr("at least one")));
  FieldDesignOptics mismatched;
  mismatched.optics = {SmallOptics(true), SmallOptics(true)};
  mismatched.directions = {{0.0, 0.0}};
  EXPECT_THAT(ErrorOf([&] { FieldDesignObjective(mismatched, 2, o); }),
              AllOf(HasSubstr("field.directions"), HasSubstr("1 directions"), HasSubstr("one per optics (2)")));
  FieldDesignOptics grids;
  grids.optics = {SmallOptics(true), SmallOptics(true, 32)};
  grids.directions = {{0.0, 0.0}, {1e-6, 0.0}};
  EXPECT_THAT(ErrorOf([&] { FieldDesignObjective(grids, 2, o); }),
              AllOf(HasSubstr("field.optics[1]"), HasSubstr("grid 32"), HasSubstr("the first node's")));
}

TEST(DesignFieldErrorsTest, SceneFieldPoints) {
  const std::string path = std::string(AOSR_SOURCE_DIR) + "/data/scenes/paper-sim-j-r2.json";
  nlohmann::json j = ReadJsonFile(path);
  EXPECT_TRUE(DesignOpticsOverField(ParseScene(j, path)).optics.empty()) << "no psf_field: no field points";
  // A field point the analytic model cannot reach: the scene is refused at its boundary, before any design.
  j["psf_field"] = {{"guide_star_arcsec", {2000.0, 0.0}}, {"grid", 3}};
  EXPECT_THAT(ErrorOf([&] { ParseScene(j, path); }), AllOf(HasSubstr("psf_field.guide_star_arcsec"), HasSubstr("at most")));
  // A reachable field: one design optics per point, each with its own AO direction.
  j["psf_field"] = {{"guide_star_arcsec", {-10.0, 0.0}}, {"grid", 3}};
  const FieldDesignOptics f = DesignOpticsOverField(ParseScene(j, path));
  ASSERT_EQ(f.optics.size(), 9u);
  EXPECT_NE(f.optics[0].ao->field_direction.x_rad, f.optics[2].ao->field_direction.x_rad);
}

}  // namespace AOSR_TEST_NS
}  // namespace aosr
