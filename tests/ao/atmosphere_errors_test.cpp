// Bad input at the public entry points of the turbulence modules (von_karman, phase_screen,
// infinite_phase_screen, atmosphere) throws aosr::InvalidArgument naming the function and the field.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <functional>
#include <limits>
#include <string>

#include "aosr/ao/atmosphere.hpp"
#include "aosr/ao/infinite_phase_screen.hpp"
#include "aosr/ao/phase_screen.hpp"
#include "aosr/ao/von_karman.hpp"
#include "aosr/core/error.hpp"
#include "support/testing.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

using aosr::test::ErrorOf;

using ::testing::HasSubstr;

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kInf = std::numeric_limits<double>::infinity();


AtmosphereOptions Valid() {
  AtmosphereOptions o;
  o.r0_m = 0.15;
  o.L0_m = 25.0;
  o.layers = {{0.0, 0.7, 10.0, 0.0}, {8000.0, 0.3, 20.0, 1.0}};
  return o;
}

TEST(AtmosphereErrorsTest, BadAtmosphereOptionsNameTheField) {
  auto make = [](const AtmosphereOptions& o) { return [o] { Atmosphere(o, 16, 2.0); }; };
  AtmosphereOptions o = Valid();
  o.r0_m = -0.1;
  EXPECT_THAT(ErrorOf(make(o)), HasSubstr("Atmosphere: invalid options.r0_m = -0.1"));
  o = Valid();
  o.r0_wavelength_m = 0.0;
  EXPECT_THAT(ErrorOf(make(o)), HasSubstr("invalid options.r0_wavelength_m = 0"));
  o = Valid();
  o.L0_m = 0.0;
  EXPECT_THAT(ErrorOf(make(o)), HasSubstr("invalid options.L0_m = 0"));
  o.L0_m = -3.0;
  EXPECT_THAT(ErrorOf(make(o)), HasSubstr("invalid options.L0_m = -3"));
  o.L0_m = kInf;
  EXPECT_THAT(ErrorOf(make(o)), HasSubstr("invalid options.L0_m = inf"));
  o = Valid();
  o.layers.clear();
  EXPECT_THAT(ErrorOf(make(o)), HasSubstr("invalid options.layers = (empty)"));
  o = Valid();
  o.layers[1].cn2_fraction = 0.2;  // sums to 0.9
  EXPECT_THAT(ErrorOf(make(o)), HasSubstr("invalid options.layers[*].cn2_fraction (sum) = 0.9"));
  o.layers[1].cn2_fraction = 0.3 + 2e-6;  // off by more than 1e-6
  EXPECT_THAT(ErrorOf(make(o)), HasSubstr("cn2_fraction (sum)"));
  o.layers[1].cn2_fraction = 0.3 + 5e-7;  // within 1e-6: accepted
  EXPECT_EQ(ErrorOf(make(o)), "no exception");
  o = Valid();
  o.layers[0].cn2_fraction = 1.5;
  EXPECT_THAT(ErrorOf(make(o)), HasSubstr("invalid options.layers[0].cn2_fraction = 1.5"));
  o = Valid();
  o.layers[1].wind_speed_mps = kNaN;
  EXPECT_THAT(ErrorOf(make(o)), HasSubstr("invalid options.layers[1].wind_speed_mps = nan"));
  o.layers[1].wind_speed_mps = kInf;
  EXPECT_THAT(ErrorOf(make(o)), HasSubstr("invalid options.layers[1].wind_speed_mps = inf"));
  o.layers[1].wind_speed_mps = -1.0;
  EXPECT_THAT(ErrorOf(make(o)), HasSubstr("invalid options.layers[1].wind_speed_mps = -1"));
  o = Valid();
  o.layers[0].wind_direction_rad = kInf;
  EXPECT_THAT(ErrorOf(make(o)), HasSubstr("invalid options.layers[0].wind_direction_rad = inf"));
  o = Valid();
  o.layers[1].altitude_m = -10.0;
  EXPECT_THAT(ErrorOf(make(o)), HasSubstr("invalid options.layers[1].altitude_m = -10"));
  std::string why;
  o = Valid();
  EXPECT_TRUE(o.IsValid(&why));
  o.r0_m = kNaN;
  EXPECT_FALSE(o.IsValid(&why));
  EXPECT_THAT(why, HasSubstr("r0_m = nan"));
}

TEST(AtmosphereErrorsTest, BadAtmosphereArgumentsAndTimes) {
  EXPECT_THAT(ErrorOf([] { Atmosphere(Valid(), 1, 2.0); }), HasSubstr("Atmosphere: invalid pupil_n = 1"));
  EXPECT_THAT(ErrorOf([] { Atmosphere(Valid(), 16, -2.0); }),
              HasSubstr("Atmosphere: invalid diameter_m = -2"));
  Atmosphere atm(Valid(), 16, 2.0);
  EXPECT_THAT(ErrorOf([&] { atm.Opd(-1.0); }), HasSubstr("Atmosphere::Opd: invalid t_s = -1"));
  EXPECT_THAT(ErrorOf([&] { atm.Opd(kNaN); }), HasSubstr("Atmosphere::Opd: invalid t_s = nan"));
  EXPECT_THAT(ErrorOf([&] { atm.Opd(0.0, nullptr); }), HasSubstr("Atmosphere::Opd: invalid opd"));
  EXPECT_THAT(ErrorOf([&] { atm.LayerOpd(2, 0.0); }), HasSubstr("Atmosphere::LayerOpd: invalid layer = 2"));
  EXPECT_THAT(ErrorOf([&] { atm.LayerR0(-1); }), HasSubstr("Atmosphere::LayerR0: invalid layer = -1"));
  EXPECT_THAT(ErrorOf([&] { atm.R0At(0.0); }), HasSubstr("Atmosphere::R0At: invalid wavelength_m = 0"));
  // Far back in time after the screens moved on: the rows are gone.
  atm.Opd(10.0);
  EXPECT_THAT(ErrorOf([&] { atm.Opd(1.0); }), HasSubstr("Atmosphere::Opd: invalid t_s = 1"));
  EXPECT_EQ(ErrorOf([&] { atm.Opd(10.0); }), "no exception");
}

TEST(AtmosphereErrorsTest, BadScreenOptions) {
  PhaseScreenOptions p;
  p.size = 64;
  p.pixel_scale_m = 0.01;
  p.r0_m = -0.1;
  EXPECT_THAT(ErrorOf([&] { PhaseScreenGenerator g(p); }),
              HasSubstr("PhaseScreenGenerator: invalid options.r0_m = -0.1"));
  p.r0_m = 0.1;
  p.L0_m = 0.0;
  EXPECT_THAT(ErrorOf([&] { PhaseScreenGenerator g(p); }), HasSubstr("invalid options.L0_m = 0"));
  p.L0_m = 10.0;
  p.pixel_scale_m = kNaN;
  EXPECT_THAT(ErrorOf([&] { PhaseScreenGenerator g(p); }), HasSubstr("invalid options.pixel_scale_m = nan"));
  p.pixel_scale_m = 0.01;
  const PhaseScreenGenerator gen(p);
  EXPECT_THAT(ErrorOf([&] { gen.ExpectedStructureFunction(kNaN, 1.0); }),
              HasSubstr("ExpectedStructureFunction: invalid separation"));

  InfinitePhaseScreenOptions q;
  q.width = 32;
  q.length = 32;
  q.pixel_scale_m = 0.01;
  q.r0_m = 0.1;
  q.L0_m = -5.0;
  EXPECT_THAT(ErrorOf([&] { InfinitePhaseScreen s(q, 1); }),
              HasSubstr("InfinitePhaseScreen: invalid options.L0_m = -5"));
  q.L0_m = 10.0;
  q.width = 2;
  EXPECT_THAT(ErrorOf([&] { InfinitePhaseScreen s(q, 1); }), HasSubstr("invalid options.width = 2"));
  q.width = 32;
  InfinitePhaseScreen s(q, 1);
  EXPECT_THAT(ErrorOf([&] { s.Extrude(-1); }), HasSubstr("InfinitePhaseScreen::Extrude: invalid rows = -1"));
}

TEST(AtmosphereErrorsTest, BadStatisticsArguments) {
  EXPECT_THAT(ErrorOf([] { VonKarmanPsd(1.0, -0.1, 25.0); }), HasSubstr("VonKarmanPsd: invalid r0_m = -0.1"));
  EXPECT_THAT(ErrorOf([] { VonKarmanPsd(-1.0, 0.1, 25.0); }),
              HasSubstr("VonKarmanPsd: invalid f_cycles_per_m"));
  EXPECT_THAT(ErrorOf([] { VonKarmanStructureFunction(1.0, 0.1, 0.0); }),
              HasSubstr("VonKarmanStructureFunction: invalid L0_m = 0"));
  EXPECT_THAT(ErrorOf([] { VonKarmanStructureFunction(-1.0, 0.1, 10.0); }),
              HasSubstr("VonKarmanStructureFunction: invalid r_m = -1"));
  EXPECT_THAT(ErrorOf([] { VonKarmanCovariance(1.0, 0.1, kInf); }),
              HasSubstr("VonKarmanCovariance: invalid L0_m"));
  EXPECT_THAT(ErrorOf([] { VonKarmanPhaseVariance(0.0, 10.0); }),
              HasSubstr("VonKarmanPhaseVariance: invalid r0_m"));
  EXPECT_THAT(ErrorOf([] { KolmogorovStructureFunction(1.0, kNaN); }),
              HasSubstr("KolmogorovStructureFunction: invalid r0_m = nan"));
  EXPECT_THAT(ErrorOf([] { ScaleR0(0.1, 500e-9, -1.0); }), HasSubstr("ScaleR0: invalid wavelength_m = -1"));
  EXPECT_THAT(ErrorOf([] { ModifiedBesselK(0.5, 0.0); }), HasSubstr("ModifiedBesselK: invalid x = 0"));
  EXPECT_THAT(ErrorOf([] { KolmogorovZernikeVariance(0, 8.0, 0.1); }),
              HasSubstr("KolmogorovZernikeVariance: invalid j = 0"));
  EXPECT_THAT(ErrorOf([] { VonKarmanZernikeVariance(2, -8.0, 0.1, 25.0); }),
              HasSubstr("VonKarmanZernikeVariance: invalid diameter_m = -8"));
  EXPECT_THAT(ErrorOf([] { NollResidualCoefficient(0); }),
              HasSubstr("NollResidualCoefficient: invalid J = 0"));
  EXPECT_THAT(ErrorOf([] { NollResidualVariance(3, 8.0, -1.0); }),
              HasSubstr("NollResidualVariance: invalid r0_m = -1"));
}

}  // namespace
}  // namespace aosr
