// Objective A on a continuous sky (design_continuous_sky.hpp): every bad argument is refused by name.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "aosr/design/design_continuous_sky.hpp"
#include "design/design_fixture.hpp"
#include "support/testing.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

using ::testing::HasSubstr;
using design_test::SmallOptics;

TEST(ContinuousSkyErrors, EachBadArgumentIsNamed) {
  const DesignOptics optics = SmallOptics(false);
  DesignObjectiveOptions o;
  o.realisations = 0;
  const DesignObjective hr(optics, 2, o), fine(OversampledOptics(optics, 2), 2, o);
  const std::vector<Image> w(2, Image::Zero(32, 32));
  const MultiFrameModel nominal = hr.NominalModel(w), truth2 = fine.NominalModel(w);
  const SkySpectrum sky = SkySpectrumOfPrior(o.reconstructor, 1.0);
  auto err = [&](const std::vector<MultiFrameModel>& truths, int t, int s, const SkySpectrum& f,
                 double lambda = 1e-2) {
    TikhonovOptions rec = o.reconstructor;
    rec.lambda = lambda;
    return test::ErrorOf<InvalidArgument>(
        [&] { ExpectedTikhonovMseOnContinuousSky(nominal, truths, t, s, rec, 1.0, f); });
  };
  EXPECT_THAT(err({}, 2, 4, sky), HasSubstr("truths"));
  EXPECT_THAT(err({truth2}, 1, 4, sky), HasSubstr("truths[0]"));  // a t = 2 model given as t = 1
  EXPECT_THAT(err({truth2}, 2, 1, sky), HasSubstr("sky_oversampling"));
  EXPECT_THAT(err({truth2}, 2, 65, sky), HasSubstr("sky_oversampling"));
  EXPECT_THAT(err({truth2}, 0, 4, sky), HasSubstr("truth_oversampling"));
  EXPECT_THAT(err({truth2}, 2, 4, SkySpectrum()), HasSubstr("sky"));
  EXPECT_THAT(err({truth2}, 2, 4, [](double, double) { return -1.0; }), HasSubstr("finite values >= 0"));
  EXPECT_THAT(err({truth2}, 2, 4, [](double, double) { return std::nan(""); }), HasSubstr("sky"));
  EXPECT_THAT(err({truth2}, 2, 4, sky, 0.0), HasSubstr("lambda"));
  EXPECT_NO_THROW(ExpectedTikhonovMseOnContinuousSky(nominal, {truth2}, 2, 4, o.reconstructor, 1.0, sky));

  TikhonovOptions sampled;
  sampled.prior = TikhonovPrior::kPowerSpectrum;
  sampled.object_power_spectrum = Image::Ones(16, 16);
  EXPECT_THAT(test::ErrorOf<InvalidArgument>([&] { SkySpectrumOfPrior(sampled, 1.0); }),
              HasSubstr("object_power_spectrum"));
  EXPECT_THAT(test::ErrorOf<InvalidArgument>([&] { SkySpectrumOfPrior(o.reconstructor, 0.0); }),
              HasSubstr("noise_sigma"));
  PowerSpectrumModel bad;
  bad.amplitude = -1;
  EXPECT_THAT(test::ErrorOf<InvalidArgument>([&] { SkySpectrumOfModel(bad); }), HasSubstr("model."));
  EXPECT_THAT(test::ErrorOf<InvalidArgument>([&] { OversampledOptics(optics, 0); }), HasSubstr("t"));
  DesignOptics zero = optics;
  zero.hr_pixel_rad = 0;
  EXPECT_THAT(test::ErrorOf<InvalidArgument>([&] { TruthOversamplingFor(zero); }), HasSubstr("optics"));
}

}  // namespace AOSR_TEST_NS
}  // namespace aosr
