// Field directions change nothing on axis: the zero direction reads the atmosphere, builds the analytic model
// and runs the closed loop exactly as before (the same bytes), and an atmosphere whose screens serve a field
// still reads each layer displaced by exactly h theta (a whole-pixel displacement is the on-axis OPD shifted).
#include <gtest/gtest.h>

#include <cmath>

#include "aosr/ao/analytic_ao.hpp"
#include "aosr/ao/anisoplanatism.hpp"
#include "aosr/ao/atmosphere.hpp"
#include "aosr/ao/closed_loop.hpp"
#include "aosr/optics/pupil.hpp"
#include "loop_fixture.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

TEST(AnisoplanatismTest, ZeroDirectionIsTheOnAxisPathToTheByte) {
  Atmosphere a(test::PaperAtmosphere(3), 64, 8.0);
  Atmosphere b(test::PaperAtmosphere(3), 64, 8.0);
  for (double t : {0.0, 0.01, 0.0125}) {
    const Image on = a.Opd(t);
    const Image zero = b.Opd(t, FieldDirection{});
    EXPECT_TRUE((on == zero).all()) << t;
  }
  AnalyticAoOptions o = test::PaperAnalytic(ControllerOptions(), true);
  const ResidualPsd p0 = ComputeResidualPsd(o, 96, 1.0 / 32.0);
  o.field_direction = {0.0, 0.0};
  o.anisoplanatism_servo_cross_term = false;  // irrelevant on axis
  const ResidualPsd p1 = ComputeResidualPsd(o, 96, 1.0 / 32.0);
  EXPECT_EQ(p1.anisoplanatism.size(), 0);
  EXPECT_TRUE((p0.Total() == p1.Total()).all());
  EXPECT_EQ(p0.Budget().TotalRad2(), p1.Budget().TotalRad2());
  EXPECT_EQ(p0.Budget().BriefReport(), p1.Budget().BriefReport());
}

// A layer at altitude h seen from theta with h theta_x = k pupil pixels (wind along x, so the strip's columns
// are the pupil's) is the on-axis layer shifted by k columns: OPD_theta(y, x) = OPD_0(y, x + k).
TEST(AnisoplanatismTest, AnOffAxisDirectionReadsTheLayerDisplacedByAltitudeTimesAngle) {
  AtmosphereOptions o;
  o.r0_m = 0.15;
  o.layers = {Layer{5000.0, 1.0, 10.0, 0.0}};
  o.max_field_angle_rad = 1e-4;
  const Index n = 32;
  const double dx = 8.0 / n;  // 0.25 m
  Atmosphere atm(o, n, 8.0);
  const int k = 2;
  const double theta = k * dx / 5000.0;  // 1e-4 rad: 0.5 m = 2 pixels
  for (double t : {0.0, 0.0125}) {
    const Image on = atm.Opd(t);
    const Image off = atm.Opd(t, FieldDirection{theta, 0.0});
    const Image up = atm.Opd(t, FieldDirection{0.0, -theta});
    EXPECT_LT((off.block(0, 0, n, n - k) - on.block(0, k, n, n - k)).abs().maxCoeff(), 1e-12 * on.abs().maxCoeff());
    EXPECT_LT((up.block(k, 0, n - k, n) - on.block(0, 0, n - k, n)).abs().maxCoeff(), 1e-12 * on.abs().maxCoeff());
  }
}

TEST(AnisoplanatismTest, OnAxisClosedLoopIsUnchangedByAFieldReadyLoopOption) {
  ControllerOptions control;
  const Index n = 64;
  auto run = [&](bool explicit_zero) {
    test::LoopSystem s = test::MakePaperSystem(SensorKind::kIdeal, true, 7, control, n);
    ClosedLoopOptions o = test::KBandScience(2);
    o.science = {2.2e-6, 2.2e-6 / 16.0, 32, 32};
    if (explicit_zero) o.science_direction = {0.0, 0.0};
    return s.MakeLoop(o)->Run(0.02, 0.01);
  };
  const ClosedLoopResult a = run(false), b = run(true);
  EXPECT_TRUE((a.psf == b.psf).all());
  EXPECT_EQ(a.strehl, b.strehl);
}

}  // namespace
}  // namespace aosr
