// Bad options and inputs of FitFramePowerSpectrum: each names the field or argument.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <limits>

#include "aosr/solvers/frame_power_spectrum.hpp"
#include "solvers/tikhonov_fixture.hpp"
#include "support/testing.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

using test::ErrorOf;
using ::testing::HasSubstr;

TEST(FramePowerSpectrumErrorsTest, OptionsAndFramesNameTheBadField) {
  const MultiFrameModel model = test::RasterModel({32, 32}, 2, {{0, 0}, {1, 1}}, 1.0);
  const ImageStack frames = {test::RandomImage({16, 16}, 1), test::RandomImage({16, 16}, 2)};
  auto fit = [&](const ImageStack& f, FramePowerSpectrumOptions o) {
    return ErrorOf([&] { FitFramePowerSpectrum(model, f, o); });
  };
  FramePowerSpectrumOptions o;
  o.min_radius = -1;
  EXPECT_THAT(fit(frames, o), HasSubstr("FitFramePowerSpectrum: options.min_radius"));
  o = {};
  o.noise_variance = std::numeric_limits<double>::infinity();
  EXPECT_THAT(fit(frames, o), HasSubstr("options.noise_variance"));
  o = {};
  o.tolerance = 0;
  EXPECT_THAT(fit(frames, o), HasSubstr("options.tolerance"));
  o = {};
  o.max_iterations = 5000;
  EXPECT_THAT(fit(frames, o), HasSubstr("options.max_iterations"));
  EXPECT_THAT(fit({frames[0]}, {}), HasSubstr("invalid frames"));
  EXPECT_THAT(fit({frames[0], test::RandomImage({8, 16}, 3)}, {}), HasSubstr("frames[1] shape"));
  ImageStack bad = frames;
  bad[1](3, 3) = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THAT(fit(bad, {}), HasSubstr("frames[1]"));
  EXPECT_THAT(fit({frames[0], Image::Constant(16, 16, 2.0)}, {}), HasSubstr("a constant frame"));
  // A grid too small for 4 annuli.
  const MultiFrameModel tiny = test::RasterModel({12, 12}, 2, {{0, 0}, {1, 1}}, 1.0);
  EXPECT_THAT(ErrorOf([&] {
                FitFramePowerSpectrum(tiny, {test::RandomImage({6, 6}, 1), test::RandomImage({6, 6}, 2)}, {});
              }),
              HasSubstr("at least 4"));
}

}  // namespace
}  // namespace aosr
