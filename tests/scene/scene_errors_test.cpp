#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "aosr/core/error.hpp"
#include "aosr/scene/demo.hpp"
#include "aosr/scene/noise.hpp"
#include "aosr/scene/raster.hpp"
#include "support/testing.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

using aosr::test::ErrorOf;

using ::testing::HasSubstr;


TEST(SceneErrorsTest, DemoOptionsNameTheBadField) {
  DemoOptions o;
  o.r = 9;
  EXPECT_THAT(ErrorOf([&] { MakeDemoScene(o); }), HasSubstr("r must be in 1..8"));
  o = {};
  o.noise_fraction = -0.1;
  EXPECT_THAT(ErrorOf([&] { MakeDemoScene(o); }), HasSubstr("noise_fraction"));
  o = {};
  o.psf_px = 10000;
  EXPECT_THAT(ErrorOf([&] { MakeDemoScene(o); }), HasSubstr("psf_px"));
}

TEST(SceneErrorsTest, NoiseAndRasterRejectBadArguments) {
  ImageStack f(1, Image::Zero(2, 2));
  EXPECT_THAT(ErrorOf([&] { AddGaussianNoise(&f, -1.0, 1); }), HasSubstr("sigma"));
  EXPECT_THAT(ErrorOf([&] { ClassicRaster(0, 2); }), HasSubstr("n"));
  EXPECT_THAT(ErrorOf([&] { ClassicRaster(4, 0); }), HasSubstr("r"));
}

}  // namespace
}  // namespace aosr
