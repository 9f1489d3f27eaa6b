// atmosphere.hpp: layer r0 scaling, seeds, determinism, per-layer sums.
#include "aosr/ao/atmosphere.hpp"

#include <gtest/gtest.h>

#include <cmath>

#include "aosr/ao/von_karman.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

AtmosphereOptions ThreeLayers() {
  AtmosphereOptions o;
  o.r0_m = 0.12;
  o.r0_wavelength_m = 500e-9;
  o.L0_m = 20.0;
  o.seed = 99;
  o.layers = {{0.0, 0.6, 5.0, 0.0}, {4000.0, 0.3, 12.0, 1.0}, {10000.0, 0.1, 20.0, -2.5}};
  return o;
}

TEST(AtmosphereTest, LayerR0AndWavelengthScaling) {
  const Atmosphere atm(ThreeLayers(), 16, 2.0);
  EXPECT_NEAR(atm.LayerR0(0), 0.12 * std::pow(0.6, -0.6), 1e-15);
  EXPECT_NEAR(atm.LayerR0(2), 0.12 * std::pow(0.1, -0.6), 1e-15);
  // sum r0_i^(-5/3) = r0^(-5/3): the layers' structure functions add up to the total.
  double sum = 0.0;
  for (int i = 0; i < 3; ++i) sum += std::pow(atm.LayerR0(i), -5.0 / 3.0);
  EXPECT_NEAR(sum, std::pow(0.12, -5.0 / 3.0), 1e-12 * sum);
  EXPECT_NEAR(atm.R0At(2.2e-6), 0.12 * std::pow(2.2e-6 / 500e-9, 1.2), 1e-15);
  EXPECT_NEAR(atm.R0At(500e-9), 0.12, 1e-16);
}

TEST(AtmosphereTest, TotalIsTheSumOfLayersAndSeedsAreReproducible) {
  Atmosphere a(ThreeLayers(), 32, 4.0);
  Atmosphere b(ThreeLayers(), 32, 4.0);
  for (double t : {0.0, 0.013, 0.2, 0.21}) {
    const Image total = a.Opd(t);
    Image sum = Image::Zero(32, 32);
    for (int i = 0; i < 3; ++i) sum += a.LayerOpd(i, t);
    EXPECT_LT((total - sum).abs().maxCoeff(), 1e-15 * total.abs().maxCoeff() * 10) << "t = " << t;
    EXPECT_TRUE((b.Opd(t) == total).all()) << "t = " << t;
  }
  // Changing one layer's wind leaves the others' screens untouched (per-layer seeds).
  AtmosphereOptions o = ThreeLayers();
  o.layers[1].wind_speed_mps = 3.0;
  Atmosphere c(o, 32, 4.0);
  Atmosphere fresh(ThreeLayers(), 32,
                   4.0);  // `a` has moved on to t = 0.21: its screens no longer hold t = 0.1
  EXPECT_TRUE((c.LayerOpd(0, 0.1) == fresh.LayerOpd(0, 0.1)).all());
  EXPECT_TRUE((c.LayerOpd(2, 0.1) == fresh.LayerOpd(2, 0.1)).all());
  EXPECT_FALSE((c.LayerOpd(1, 0.1) == fresh.LayerOpd(1, 0.1)).all());
  // A different master seed changes everything.
  o = ThreeLayers();
  o.seed = 100;
  Atmosphere d(o, 32, 4.0);
  EXPECT_GT((d.Opd(0.0) - Atmosphere(ThreeLayers(), 32, 4.0).Opd(0.0)).abs().maxCoeff(), 1e-8);
}

TEST(AtmosphereTest, AntitheticAtmosphereIsTheNegation) {
  AtmosphereOptions o = ThreeLayers();
  Atmosphere a(o, 32, 4.0);
  o.antithetic = true;
  Atmosphere b(o, 32, 4.0);
  for (double t : {0.0, 0.05, 0.2}) {
    EXPECT_TRUE((b.Opd(t) == -a.Opd(t)).all()) << "t = " << t;
    EXPECT_TRUE((b.LayerOpd(1, t) == -a.LayerOpd(1, t)).all()) << "t = " << t;
  }
}

TEST(AtmosphereTest, ZeroFractionLayerContributesNothing) {
  AtmosphereOptions o = ThreeLayers();
  o.layers.push_back({20000.0, 0.0, 30.0, 0.5});
  Atmosphere atm(o, 16, 2.0);
  EXPECT_TRUE(std::isinf(atm.LayerR0(3)));
  EXPECT_TRUE((atm.LayerOpd(3, 0.5) == 0.0).all());
  Image opd;
  atm.Opd(0.05, &opd);
  EXPECT_EQ(opd.rows(), 16);
  EXPECT_TRUE(opd.isFinite().all());
  // OPD magnitude: metres, of order lambda/(2 pi) sqrt(D(D)) ~ 1e-7 .. 1e-5.
  const double rms = std::sqrt((opd - opd.mean()).square().mean());
  EXPECT_GT(rms, 1e-8);
  EXPECT_LT(rms, 1e-5);
}

}  // namespace
}  // namespace aosr
