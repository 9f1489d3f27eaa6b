#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "aosr/core/error.hpp"
#include "aosr/scene/detector.hpp"
#include "aosr/scene/photometry.hpp"
#include "support/testing.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

using aosr::test::ErrorOf;

using ::testing::HasSubstr;


std::string DetectorError(const DetectorOptions& o) {
  std::string why;
  EXPECT_FALSE(o.IsValid(&why));
  const std::string thrown = ErrorOf<Error>([&] { Detector d(o); });
  EXPECT_THAT(thrown, HasSubstr(why));
  return thrown;
}

TEST(DetectorErrorsTest, OptionsNameTheBadField) {
  DetectorOptions o;
  o.gain_e_per_adu = -1;
  EXPECT_THAT(DetectorError(o), HasSubstr("gain_e_per_adu"));
  o = {};
  o.read_noise_e = -0.5;
  EXPECT_THAT(DetectorError(o), HasSubstr("read_noise_e"));
  for (double f : {0.0, -0.2, 1.5}) {
    o = {};
    o.fill_factor = f;
    EXPECT_THAT(DetectorError(o), HasSubstr("fill_factor must be in (0, 1]"));
  }
  o = {};
  o.saturation_adu = 0;
  EXPECT_THAT(DetectorError(o), HasSubstr("saturation_adu"));
  o = {};
  o.saturation_adu = -10;
  EXPECT_THAT(DetectorError(o), HasSubstr("saturation_adu"));
  o = {};
  o.bias_adu = 1000;
  o.saturation_adu = 900;
  EXPECT_THAT(DetectorError(o), HasSubstr("exceed bias_adu"));
  o = {};
  o.exposure_time_s = 0;
  EXPECT_THAT(DetectorError(o), HasSubstr("exposure_time_s"));
  o = {};
  o.background_e_per_s = -1;
  EXPECT_THAT(DetectorError(o), HasSubstr("background_e_per_s"));
  o = {};
  o.dark_current_e_per_s = NAN;
  EXPECT_THAT(DetectorError(o), HasSubstr("dark_current_e_per_s"));
  o = {};
  o.peak_noise_fraction = -0.01;
  EXPECT_THAT(DetectorError(o), HasSubstr("peak_noise_fraction"));
  o = {};
  o.enable_bad_pixels = true;
  EXPECT_THAT(DetectorError(o), HasSubstr("bad_pixel_mask must be non-empty"));
  o.bad_pixel_mask = Image::Constant(2, 2, 0.5);
  EXPECT_THAT(DetectorError(o), HasSubstr("bad_pixel_mask must hold only 0"));
}

TEST(DetectorErrorsTest, RecordRejectsBadFrames) {
  DetectorOptions o;
  o.enable_bad_pixels = true;
  o.bad_pixel_mask = Image::Ones(4, 4);
  const Detector d(o);
  EXPECT_THAT(ErrorOf<Error>([&] { d.Record(Image::Ones(4, 5), 1); }),
              HasSubstr("Detector::Record: invalid bad_pixel_mask = 4x4; allowed: the frame's shape 4x5"));
  EXPECT_THAT(ErrorOf<Error>([&] { d.Record(Image::Constant(4, 4, -3.0), 1); }), HasSubstr("expected_e"));
  Image nan = Image::Ones(4, 4);
  nan(1, 1) = NAN;
  EXPECT_THAT(ErrorOf<Error>([&] { d.Record(nan, 1); }), HasSubstr("non-finite"));
  EXPECT_THAT(ErrorOf<Error>([&] { d.Record(Image(), 1); }), HasSubstr("expected_e"));
  EXPECT_THAT(ErrorOf<Error>([&] { d.RecordSequence({}, 1); }), HasSubstr("at least one frame"));
  EXPECT_THAT(ErrorOf<Error>([&] {
                d.RecordSequence({Image::Ones(4, 4), Image::Ones(3, 3)}, 1);
              }),
              HasSubstr("every frame of shape 4x4"));
  EXPECT_THAT(ErrorOf<Error>([&] { d.InverseVarianceFromData(Image::Ones(4, 4), Image::Ones(2, 2)); }),
              HasSubstr("valid"));
}

TEST(DetectorErrorsTest, FreeFunctionsRejectBadArguments) {
  EXPECT_THAT(ErrorOf<Error>([] { PixelResponse({8, 8}, 2, 0.0); }), HasSubstr("fill_factor"));
  EXPECT_THAT(ErrorOf<Error>([] { PixelResponse({8, 8}, 3, 0.5); }), HasSubstr("hr"));
  EXPECT_THAT(ErrorOf<Error>([] { PixelResponse({8, 8}, 3, 1.0); }), HasSubstr("Decimate"));
  EXPECT_THAT(ErrorOf<Error>([] { FillFactorWeights(0, 0.5); }), HasSubstr("r"));
  EXPECT_THAT(ErrorOf<Error>([] { PeakFractionSigma({}, 0.1); }), HasSubstr("frames"));
  EXPECT_THAT(ErrorOf<Error>([] { PeakFractionSigma({Image::Ones(2, 2)}, -1); }), HasSubstr("fraction"));
  Image img = Image::Ones(2, 2);
  NormalGenerator g(1);
  EXPECT_THAT(ErrorOf<Error>([&] { AddNormalNoise(&img, -1, &g); }), HasSubstr("sigma"));
  EXPECT_THAT(ErrorOf<Error>([] { RandomBadPixelMask({4, 4}, 1.5, 1); }), HasSubstr("fraction"));
}

TEST(DetectorErrorsTest, PhotometryNamesTheBadArgument) {
  EXPECT_THAT(ErrorOf<Error>([] { VegaBand("Q"); }),
              HasSubstr("VegaBand: invalid band = \"Q\"; allowed: one of U, B, V, R, I, J, H, K, Ks"));
  LightCollectorOptions c;
  EXPECT_THAT(ErrorOf<Error>([&] { ElectronsPerFrame(SourceFlux::Magnitude(10, "k"), c, {}); }), HasSubstr("band"));
  EXPECT_THAT(ErrorOf<Error>([&] { ElectronsPerFrame(SourceFlux::Magnitude(NAN, "K"), c, {}); }),
              HasSubstr("magnitude"));
  EXPECT_THAT(ErrorOf<Error>([&] {
                ElectronsPerFrame(SourceFlux::Magnitude(10, "K"), c, {10.0, 0});
              }),
              HasSubstr("plan.frames"));
  EXPECT_THAT(ErrorOf<Error>([&] {
                ElectronsPerFrame(SourceFlux::Magnitude(10, "K"), c, {-1.0, 2});
              }),
              HasSubstr("plan.total_time_s"));
  EXPECT_THAT(ErrorOf<Error>([&] { DetectedElectronRate(SourceFlux::Irradiance(-1), c); }),
              HasSubstr("source.value"));
  c.throughput = 1.5;
  EXPECT_THAT(ErrorOf<Error>([&] { DetectedElectronRate(SourceFlux::Irradiance(1), c); }),
              HasSubstr("collector.throughput"));
  c = {};
  c.obstruction = 1.0;
  EXPECT_THAT(ErrorOf<Error>([&] { DetectedElectronRate(SourceFlux::Irradiance(1), c); }),
              HasSubstr("collector.obstruction"));
  c = {};
  c.diameter_m = 0;
  EXPECT_THAT(ErrorOf<Error>([&] { DetectedElectronRate(SourceFlux::Irradiance(1), c); }),
              HasSubstr("collector.diameter_m"));
  c = {};
  EXPECT_THAT(ErrorOf<Error>([&] { SkyBackgroundRate(13, VegaBand("K"), c, 0.0); }), HasSubstr("pixel_scale_rad"));
  EXPECT_THAT(ErrorOf<Error>([&] { SkyBackgroundRate(13, VegaBand("K"), c, 1e-7, 2.0); }), HasSubstr("fill_factor"));
  EXPECT_THAT(ErrorOf<Error>([&] { MagnitudeFromIrradiance(0, VegaBand("K")); }), HasSubstr("photons_per_s_m2"));
}

}  // namespace
}  // namespace aosr
