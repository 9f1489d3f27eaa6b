// phase_screen.hpp and random.hpp: determinism, the Re/Im pair, options, and the exact expectation helper.
#include "aosr/ao/phase_screen.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <set>

#include "aosr/ao/random.hpp"
#include "aosr/ao/von_karman.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

PhaseScreenOptions SmallOptions() {
  PhaseScreenOptions o;
  o.size = 64;
  o.pixel_scale_m = 0.02;
  o.r0_m = 0.1;
  o.L0_m = 10.0;
  return o;
}

TEST(RandomTest, NormalGeneratorIsDeterministicWithUnitMoments) {
  NormalGenerator a(42), b(42), c(43);
  std::vector<double> va(100000), vb(100000);
  a.Fill(va.data(), 100000);
  for (double& v : vb) v = b.Next();
  EXPECT_EQ(va, vb);
  EXPECT_NE(va[0], c.Next());
  double m = 0.0, m2 = 0.0, m4 = 0.0;
  for (double v : va) {
    m += v;
    m2 += v * v;
    m4 += v * v * v * v;
  }
  m /= va.size();
  m2 /= va.size();
  m4 /= va.size();
  // Standard errors: mean 1/sqrt(N) = 0.0032, variance sqrt(2/N) = 0.0045, 4th moment sqrt(96/N) = 0.031.
  EXPECT_NEAR(m, 0.0, 0.013) << "seed 42";
  EXPECT_NEAR(m2, 1.0, 0.018) << "seed 42";
  EXPECT_NEAR(m4, 3.0, 0.12) << "seed 42";
}

TEST(RandomTest, DerivedSeedsAreDistinct) {
  std::set<std::uint64_t> seeds;
  for (std::uint64_t master = 0; master < 20; ++master) {
    for (std::uint64_t stream = 0; stream < 20; ++stream) seeds.insert(DeriveSeed(master, stream));
  }
  EXPECT_EQ(seeds.size(), 400u);
  EXPECT_NE(DeriveSeed(1, 2), DeriveSeed(2, 1));
}

TEST(PhaseScreenTest, SeedDeterminesScreenAndPairSharesIt) {
  const PhaseScreenGenerator gen(SmallOptions());
  const Image a = gen.Generate(7);
  const Image b = gen.Generate(7);
  const Image c = gen.Generate(8);
  ASSERT_EQ(a.rows(), 64);
  ASSERT_EQ(a.cols(), 64);
  EXPECT_TRUE((a == b).all());
  EXPECT_GT((a - c).abs().maxCoeff(), 0.1);
  const auto pair = gen.GeneratePair(7);
  EXPECT_TRUE((pair.first == a).all());
  EXPECT_GT((pair.second - a).abs().maxCoeff(), 0.1);
  EXPECT_NEAR(a.mean(), 0.0, 1e-12);
  EXPECT_NEAR(pair.second.mean(), 0.0, 1e-12);
  EXPECT_TRUE(a.isFinite().all());
}

TEST(PhaseScreenTest, LevelsAndExpectedStructureFunction) {
  PhaseScreenOptions o;
  o.size = 128;
  o.pixel_scale_m = 0.02;
  o.r0_m = 0.1;
  o.L0_m = 10.0;  // L0 / (n dx) = 3.9 -> 3 + ceil(log3 3.9) = 5 levels
  const PhaseScreenGenerator gen(o);
  EXPECT_EQ(gen.subharmonic_levels(), 5);
  o.L0_m = 2.0;  // below the screen size: 3 levels
  EXPECT_EQ(PhaseScreenGenerator(o).subharmonic_levels(), 3);
  o.subharmonic_levels = 0;
  EXPECT_EQ(PhaseScreenGenerator(o).subharmonic_levels(), 0);

  EXPECT_NEAR(gen.ExpectedStructureFunction(0.0, 0.0), 0.0, 1e-12);
  // Symmetric under s -> -s and x <-> y (the frequency set has the square's symmetry).
  const double d = gen.ExpectedStructureFunction(3.0, 5.0);
  EXPECT_NEAR(gen.ExpectedStructureFunction(-3.0, -5.0), d, 1e-12 * d);
  EXPECT_NEAR(gen.ExpectedStructureFunction(5.0, 3.0), d, 1e-12 * d);
  EXPECT_NEAR(gen.ExpectedStructureFunction(0.0, 7.0), gen.ExpectedStructureFunction(7.0, 0.0), 1e-12 * d);
}

TEST(PhaseScreenTest, OptionsNameTheBadField) {
  std::string why;
  PhaseScreenOptions o = SmallOptions();
  EXPECT_TRUE(o.IsValid(&why));
  o.size = 8;
  EXPECT_FALSE(o.IsValid(&why));
  EXPECT_NE(why.find("size = 8"), std::string::npos) << why;
  o = SmallOptions();
  o.subharmonic_levels = 21;
  EXPECT_FALSE(o.IsValid(&why));
  EXPECT_NE(why.find("subharmonic_levels = 21"), std::string::npos) << why;
  o = SmallOptions();
  o.L0_m = std::numeric_limits<double>::infinity();
  EXPECT_FALSE(o.IsValid(nullptr));
}

}  // namespace
}  // namespace aosr
