// Bad field directions and anisoplanatism arguments throw aosr::InvalidArgument naming the function, the
// argument, the value and the limit: the atmosphere (a footprint outside the screens, NaN), the closed loop,
// the analytic model (a direction the PSD grid cannot resolve, NaN) and the anisoplanatism functions.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <limits>
#include <string>

#include "aosr/ao/analytic_ao.hpp"
#include "aosr/ao/anisoplanatism.hpp"
#include "aosr/ao/atmosphere.hpp"
#include "aosr/ao/closed_loop.hpp"
#include "aosr/core/error.hpp"
#include "aosr/optics/pupil.hpp"
#include "loop_fixture.hpp"
#include "support/testing.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

using aosr::test::ErrorOf;
using ::testing::HasSubstr;

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kArcsec = kPi / (180.0 * 3600.0);

TEST(AnisoplanatismErrorsTest, AtmosphereRefusesDirectionsOutsideItsScreens) {
  AtmosphereOptions o = test::PaperAtmosphere(1);
  o.max_field_angle_rad = 20.0 * kArcsec;
  Atmosphere atm(o, 32, 8.0);
  EXPECT_NO_THROW(atm.Opd(0.0, FieldDirection{20.0 * kArcsec, 0.0}));
  const std::string e = ErrorOf([&] { atm.Opd(0.0, FieldDirection{0.0, 30.0 * kArcsec}); });
  EXPECT_THAT(e, HasSubstr("Atmosphere::Opd"));
  EXPECT_THAT(e, HasSubstr("direction"));
  EXPECT_THAT(e, HasSubstr("30 arcsec"));
  EXPECT_THAT(e, HasSubstr("max_field_angle_rad"));
  EXPECT_THAT(e, HasSubstr("layer 1 (4000 m)"));
  EXPECT_THAT(ErrorOf([&] { atm.Opd(0.0, FieldDirection{kNaN, 0.0}); }), HasSubstr("finite"));
  // On-axis-only screens refuse any direction with a layer above the ground...
  Atmosphere on_axis(test::PaperAtmosphere(1), 32, 8.0);
  EXPECT_THAT(ErrorOf([&] { on_axis.Opd(0.0, FieldDirection{1e-7, 0.0}); }), HasSubstr("max_field_angle_rad = 0"));
  std::vector<Image> opds;
  EXPECT_THAT(ErrorOf([&] { on_axis.Opd(0.0, {FieldDirection{}, FieldDirection{1e-7, 0.0}}, &opds); }),
              HasSubstr("directions[1]"));
  // ... but ground layers are the same in every direction.
  AtmosphereOptions ground = test::PaperAtmosphere(1);
  for (Layer& l : ground.layers) l.altitude_m = 0.0;
  Atmosphere g(ground, 32, 8.0);
  EXPECT_NO_THROW(g.Opd(0.0, FieldDirection{1e-3, 0.0}));
  // The option itself.
  for (double bad : {-1e-6, kNaN, 0.02}) {
    AtmosphereOptions b = test::PaperAtmosphere(1);
    b.max_field_angle_rad = bad;
    std::string why;
    EXPECT_FALSE(b.IsValid(&why));
    EXPECT_THAT(why, HasSubstr("max_field_angle_rad"));
    EXPECT_THAT(ErrorOf([&] { Atmosphere(b, 32, 8.0); }), HasSubstr("max_field_angle_rad"));
  }
}

TEST(AnisoplanatismErrorsTest, ClosedLoopRefusesADirectionItsAtmosphereCannotServe) {
  ControllerOptions control;
  test::LoopSystem s = test::MakePaperSystem(SensorKind::kIdeal, true, 1, control, 64, 10.0 * kArcsec);
  ClosedLoopOptions o = test::KBandScience();
  o.science = {2.2e-6, 2.2e-6 / 16.0, 32, 32};
  o.science_direction = {0.0, 25.0 * kArcsec};
  const std::string e = ErrorOf([&] { s.MakeLoop(o); });
  EXPECT_THAT(e, HasSubstr("science_direction"));
  EXPECT_THAT(e, HasSubstr("25 arcsec"));
  EXPECT_THAT(e, HasSubstr("10 arcsec"));
  o.science_direction = {kNaN, 0.0};
  EXPECT_THAT(ErrorOf([&] { s.MakeLoop(o); }), HasSubstr("science_direction = (nan"));
  // The further directions of one loop, each named.
  o.science_direction = {};
  o.extra_science_directions = {{0.0, 5.0 * kArcsec}, {25.0 * kArcsec, 0.0}};
  const std::string e2 = ErrorOf([&] { s.MakeLoop(o); });
  EXPECT_THAT(e2, HasSubstr("extra_science_directions"));
  EXPECT_THAT(e2, HasSubstr("25 arcsec"));
  o.extra_science_directions = {{0.0, 5.0 * kArcsec}, {0.0, kNaN}};
  EXPECT_THAT(ErrorOf([&] { s.MakeLoop(o); }), HasSubstr("extra_science_directions[1] = (0, nan"));
}

TEST(AnisoplanatismErrorsTest, AnalyticModelRefusesDirectionsItsGridCannotResolve) {
  AnalyticAoOptions o = test::PaperAnalytic(ControllerOptions(), true);
  o.field_direction = {kNaN, 0.0};
  std::string why;
  EXPECT_FALSE(o.IsValid(&why));
  EXPECT_THAT(why, HasSubstr("field_direction = (nan"));
  // K D / 4 = 8 m: the 10 km layer allows 8e-4 rad (165"); 200" is refused, naming the layer and the limit.
  o.field_direction = {200.0 * kArcsec, 0.0};
  const std::string e = ErrorOf([&] { ComputeAnalyticAoErrorBudget(o); });
  EXPECT_THAT(e, HasSubstr("layers[2]"));
  EXPECT_THAT(e, HasSubstr("frequency_padding * diameter_m / 4 = 8"));
  o.frequency_padding = 8;
  EXPECT_NO_THROW(ComputeAnalyticAoErrorBudget(o));
}

TEST(AnisoplanatismErrorsTest, AnisoplanatismFunctionsNameTheArgument) {
  const std::vector<Layer> layers = test::PaperAtmosphere(1).layers;
  EXPECT_THAT(ErrorOf([&] { EffectiveTurbulenceAltitudeM({}); }), HasSubstr("layers"));
  std::vector<Layer> bad = layers;
  bad[1].altitude_m = -5.0;
  EXPECT_THAT(ErrorOf([&] { EffectiveTurbulenceAltitudeM(bad); }), HasSubstr("layers[1].altitude_m"));
  bad = layers;
  bad[0].cn2_fraction = 0.5;
  EXPECT_THAT(ErrorOf([&] { EffectiveTurbulenceAltitudeM(bad); }), HasSubstr("cn2_fraction"));
  EXPECT_THAT(ErrorOf([&] { IsoplanaticAngleRad(kNaN, 5e-7, 2.2e-6, layers); }), HasSubstr("r0_m"));
  EXPECT_THAT(ErrorOf([&] { IsoplanaticAngleRad(0.15, 5e-7, -1.0, layers); }), HasSubstr("wavelength_m"));
  EXPECT_THAT(ErrorOf([&] { IsoplanaticAngleRad(0.15, 5e-7, 2.2e-6, layers, 2.0); }), HasSubstr("zenith_rad"));
  EXPECT_THAT(ErrorOf([&] { FriedAnisoplanaticVarianceRad2(kNaN, 1e-4); }), HasSubstr("theta_rad"));
  EXPECT_THAT(ErrorOf([&] { FriedAnisoplanaticVarianceRad2(1e-4, 0.0); }), HasSubstr("theta0_rad"));
  EXPECT_THAT(ErrorOf([&] { ZernikeTiltVariance(Image::Zero(3, 3), 0.1, 8.0, 0.0); }), HasSubstr("psd shape"));
  EXPECT_THAT(ErrorOf([&] { ZernikeTiltVariance(Image::Zero(4, 4), 0.0, 8.0, 0.0); }), HasSubstr("df_per_m"));
  EXPECT_THAT(ErrorOf([&] { TiltCoefficientToAngleRad(1.0, 2.2e-6, 0.0); }), HasSubstr("diameter_m"));
}

}  // namespace
}  // namespace aosr
