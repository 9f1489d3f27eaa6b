// Field directions change nothing on axis: the zero direction reads the atmosphere, builds the analytic model
// and runs the closed loop exactly as before (the same bytes), and an atmosphere whose screens serve a field
// still reads each layer displaced by exactly h theta (a whole-pixel displacement is the on-axis OPD shifted).
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "aosr/ao/analytic_ao.hpp"
#include "aosr/ao/anisoplanatism.hpp"
#include "aosr/ao/atmosphere.hpp"
#include "aosr/ao/closed_loop.hpp"
#include "aosr/core/parallel.hpp"
#include "aosr/optics/pupil.hpp"
#include "loop_fixture.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

constexpr double kArcsec = kPi / (180.0 * 3600.0);

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

// What a direction reads does not depend on which directions were read before it: the screens hold the rows
// of the time asked, whatever the direction (Atmosphere::Prepare), so the interpolation's rounding is the same.
TEST(AnisoplanatismTest, ADirectionReadsTheSameBytesWhicheverDirectionsWereReadBeforeIt) {
  AtmosphereOptions o = test::PaperAtmosphere(5);
  o.max_field_angle_rad = 40.0 * kArcsec;
  Atmosphere alone(o, 64, 8.0), beside(o, 64, 8.0);
  const FieldDirection d{-12.0 * kArcsec, 5.0 * kArcsec};
  const std::vector<FieldDirection> others = {{36.0 * kArcsec, 0.0}, {0.0, -36.0 * kArcsec}, {-25.0 * kArcsec, 25.0 * kArcsec}};
  Atmosphere together(o, 64, 8.0);
  std::vector<FieldDirection> all = others;
  all.push_back(d);
  all.push_back(FieldDirection{});
  const int saved = DefaultThreads();
  SetDefaultThreads(2);  // the many-directions call reads them in parallel
  int differ = 0, differ_together = 0;
  std::vector<Image> opds;
  for (int step = 0; step < 16; ++step) {
    const double t = (step + 0.5) / 200.0;
    for (const FieldDirection& other : others) beside.Opd(t, other);
    const Image mine = alone.Opd(t, d);
    differ += !(mine == beside.Opd(t, d)).all();
    together.Opd(t, all, &opds);
    differ_together += !(mine == opds[3]).all() || !(opds[4] == alone.Opd(t)).all() ||
                       !(opds[0] == beside.Opd(t, others[0])).all();
  }
  SetDefaultThreads(saved);
  EXPECT_EQ(differ, 0) << "of 16 steps";
  EXPECT_EQ(differ_together, 0) << "of 16 steps";
}

// A field of directions in one loop (extra_science_directions) gives each direction the bytes of a loop run
// for it alone: the loop does not depend on the science direction, and the screens hold the same rows at a
// given time whichever directions read them (Atmosphere::Prepare).
TEST(AnisoplanatismTest, ManyDirectionsInOneLoopAreEachTheBytesOfTheirOwnLoop) {
  ControllerOptions control;
  const Index n = 32;
  const std::vector<FieldDirection> field = {{30.0 * kArcsec, 0.0}, {0.0, 0.0}, {-20.0 * kArcsec, 25.0 * kArcsec}};
  auto loop = [&](FieldDirection primary, std::vector<FieldDirection> extra) {
    test::LoopSystem s = test::MakePaperSystem(SensorKind::kIdeal, true, 7, control, n, 40.0 * kArcsec);
    ClosedLoopOptions o = test::KBandScience(2);
    o.science = {2.2e-6, 2.2e-6 / 16.0, 32, 32};
    o.science_direction = primary;
    o.extra_science_directions = std::move(extra);
    // Two sub-exposures: each result carries every direction.
    const Image flat = Image::Zero(n, n);
    return s.MakeLoop(o)->RunSubExposures({flat, flat}, 0.01, 0.005);
  };
  const std::vector<ClosedLoopResult> joint = loop(field[0], {field[1], field[2]});
  ASSERT_EQ(joint.size(), 2u);
  // The directions' science stages in parallel (two groups of directions): the same bytes.
  const int saved = DefaultThreads();
  SetDefaultThreads(2);
  const std::vector<ClosedLoopResult> parallel = loop(field[0], {field[1], field[2]});
  SetDefaultThreads(saved);
  for (std::size_t i = 0; i < 2; ++i) {
    EXPECT_TRUE((parallel[i].psf == joint[i].psf).all());
    for (std::size_t k = 0; k < 2; ++k) {
      EXPECT_TRUE((parallel[i].extra_directions[k].psf == joint[i].extra_directions[k].psf).all()) << k;
      EXPECT_EQ(parallel[i].extra_directions[k].strehl, joint[i].extra_directions[k].strehl) << k;
    }
  }
  for (std::size_t k = 0; k < field.size(); ++k) {
    const std::vector<ClosedLoopResult> alone = loop(field[k], {});
    for (std::size_t i = 0; i < 2; ++i) {
      ASSERT_EQ(joint[i].extra_directions.size(), 2u);
      EXPECT_TRUE(alone[i].extra_directions.empty());
      const ClosedLoopResult& j = k == 0 ? joint[i] : joint[i].extra_directions[k - 1];
      EXPECT_TRUE((j.psf == alone[i].psf).all()) << "direction " << k << ", exposure " << i;
      EXPECT_EQ(j.strehl, alone[i].strehl) << k;
      EXPECT_EQ(j.residual_rms_m, alone[i].residual_rms_m) << k;
      EXPECT_EQ(j.psf_strehl, alone[i].psf_strehl) << k;
      EXPECT_EQ(j.steps, alone[i].steps);
      EXPECT_EQ(j.tilt_gain[0], alone[i].tilt_gain[0]);
    }
  }
  // The directions differ (the test is not comparing one PSF with itself).
  EXPECT_GT((joint[0].psf - joint[0].extra_directions[0].psf).abs().maxCoeff(), 1e-3 * joint[0].psf.maxCoeff());
}

}  // namespace
}  // namespace aosr
