// Every public entry point of the object generators (star fields, point-source rendering, Sérsic galaxies,
// dead leaves, image-file objects) rejects bad input with a message naming the function and the argument or
// field.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <limits>

#include "aosr/core/error.hpp"
#include "aosr/core/forward_model.hpp"
#include "aosr/scene/dead_leaves.hpp"
#include "aosr/scene/galaxy.hpp"
#include "aosr/scene/image_object.hpp"
#include "aosr/scene/point_sources.hpp"
#include "aosr/scene/star_field.hpp"
#include "support/testing.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

using aosr::test::ErrorOf;

using ::testing::AllOf;
using ::testing::HasSubstr;


constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kInf = std::numeric_limits<double>::infinity();

// ---- luminosity function and star fields ----

TEST(ObjectGeneratorsErrorsTest, LuminosityFunction) {
  LuminosityFunction lf;
  lf.flux_min = 10.0;
  lf.flux_max = 10.0;
  std::string why;
  EXPECT_FALSE(lf.IsValid(&why));
  EXPECT_THAT(why, AllOf(HasSubstr("flux_max = 10"), HasSubstr("> flux_min")));
  EXPECT_THAT(ErrorOf([&] { lf.Quantile(0.5); }),
              AllOf(HasSubstr("LuminosityFunction::Quantile"), HasSubstr("flux_max")));
  EXPECT_THAT(ErrorOf([&] { lf.Cdf(1.0); }), HasSubstr("LuminosityFunction::Cdf"));
  EXPECT_THAT(ErrorOf([&] { lf.MeanFlux(); }), HasSubstr("LuminosityFunction::MeanFlux"));
  lf = {};
  lf.flux_min = -1.0;
  EXPECT_THAT(ErrorOf([&] { lf.MeanFlux(); }), HasSubstr("flux_min = -1"));
  lf = {};
  lf.alpha = kNaN;
  EXPECT_THAT(ErrorOf([&] { lf.Quantile(0.1); }), HasSubstr("alpha"));
  lf = {};
  lf.alpha = 7.0;
  EXPECT_THAT(ErrorOf([&] { lf.Quantile(0.1); }), AllOf(HasSubstr("alpha = 7"), HasSubstr("[0, 5]")));
  lf = {};
  EXPECT_THAT(ErrorOf([&] { lf.Quantile(1.5); }), AllOf(HasSubstr("Quantile"), HasSubstr("u = 1.5")));
  EXPECT_THAT(ErrorOf([&] { lf.Cdf(kNaN); }), HasSubstr("f = nan"));
}

TEST(ObjectGeneratorsErrorsTest, StarField) {
  StarFieldOptions o;
  EXPECT_THAT(ErrorOf([&] {
                StarField({0, 10}, o, 1);
              }),
              AllOf(HasSubstr("StarField"), HasSubstr("hr = 0x10")));
  o.count = -1;
  EXPECT_THAT(ErrorOf([&] {
                StarField({10, 10}, o, 1);
              }),
              AllOf(HasSubstr("StarField"), HasSubstr("count = -1")));
  o = {};
  o.luminosity.flux_min = 5.0;
  o.luminosity.flux_max = 1.0;
  EXPECT_THAT(ErrorOf([&] { StarField({10, 10}, o, 1); }), HasSubstr("luminosity.flux_max = 1"));
  o = {};
  o.min_separation_px = -2.0;
  EXPECT_THAT(ErrorOf([&] { StarField({10, 10}, o, 1); }), HasSubstr("min_separation_px = -2"));
  o = {};
  o.margin_px = kInf;
  EXPECT_THAT(ErrorOf([&] { StarField({10, 10}, o, 1); }), HasSubstr("margin_px = inf"));
  o = {};
  o.margin_px = 5.0;
  EXPECT_THAT(ErrorOf([&] {
                StarField({10, 40}, o, 1);
              }),
              AllOf(HasSubstr("options.margin_px = 5"), HasSubstr("half the smaller side")));
  o = {};
  o.count = 1000;
  o.min_separation_px = 3.0;  // packing 1000 π 9/4 / 1024 = 6.9
  EXPECT_THAT(ErrorOf([&] {
                StarField({32, 32}, o, 1);
              }),
              AllOf(HasSubstr("min_separation_px = 3"), HasSubstr("packing fraction")));
  std::string why;
  o = {};
  o.count = 20000000;
  EXPECT_FALSE(o.IsValid(&why));
  EXPECT_THAT(why, HasSubstr("count = 20000000"));
  EXPECT_THAT(ErrorOf([] {
                AssignFluxes({{kNaN, 1.0, 0.0}}, {}, 1);
              }),
              AllOf(HasSubstr("AssignFluxes"), HasSubstr("positions[0]")));
  LuminosityFunction bad;
  bad.flux_max = 0.5;
  EXPECT_THAT(ErrorOf([&] { AssignFluxes({}, bad, 1); }),
              AllOf(HasSubstr("AssignFluxes"), HasSubstr("flux_max")));
}

// ---- point sources ----

TEST(ObjectGeneratorsErrorsTest, PointSources) {
  const Shape hr{16, 16};
  const ComplexImage h = ComplexImage::Ones(16, 9);
  EXPECT_THAT(ErrorOf([&] {
                RenderPointSources({0, 16}, {}, h);
              }),
              AllOf(HasSubstr("RenderPointSources"), HasSubstr("hr = 0x16")));
  EXPECT_THAT(ErrorOf([&] {
                RenderPointSources(hr, {{1.0, 1.0, -2.0}}, h);
              }),
              AllOf(HasSubstr("RenderPointSources"), HasSubstr("sources[0].flux = -2"), HasSubstr(">= 0")));
  EXPECT_THAT(ErrorOf([&] {
                RenderPointSources(hr, {{1.0, 1.0, 1.0}, {1.0, 1.0, kNaN}}, h);
              }),
              HasSubstr("sources[1].flux = nan"));
  EXPECT_THAT(ErrorOf([&] {
                RenderPointSources(hr, {{16.0, 1.0, 1.0}}, h);
              }),
              AllOf(HasSubstr("sources[0].y = 16"), HasSubstr("[-0.5, 15.5]")));
  EXPECT_THAT(ErrorOf([&] {
                RenderPointSources(hr, {{1.0, -0.6, 1.0}}, h);
              }),
              HasSubstr("sources[0].x = -0.6"));
  EXPECT_THAT(ErrorOf([&] { RenderPointSources(hr, {}, ComplexImage::Ones(16, 16)); }),
              AllOf(HasSubstr("otf_half shape = 16x16"), HasSubstr("16x9")));
  ComplexImage nan_otf = h;
  nan_otf(2, 3) = Complex(kNaN, 0.0);
  EXPECT_THAT(ErrorOf([&] { RenderPointSources(hr, {}, nan_otf); }), HasSubstr("otf_half"));
  EXPECT_THAT(ErrorOf([&] {
                PointSourceSpectrum({5, 0}, {});
              }),
              AllOf(HasSubstr("PointSourceSpectrum"), HasSubstr("hr = 5x0")));
  EXPECT_THAT(ErrorOf([&] {
                PointSourceImage(hr, {{1.0, 99.0, 1.0}});
              }),
              AllOf(HasSubstr("PointSourceImage"), HasSubstr("sources[0].x = 99")));
  const MultiFrameModel model(hr, 2, {h});
  EXPECT_THAT(ErrorOf([&] {
                RenderPointSourceFrames(model, {{1.0, 1.0, -1.0}});
              }),
              AllOf(HasSubstr("RenderPointSourceFrames"), HasSubstr("sources[0].flux")));
}

// ---- Sérsic galaxies ----

TEST(ObjectGeneratorsErrorsTest, SersicFunctions) {
  for (double n : {0.2, 0.1, 20.5, kNaN}) {
    EXPECT_THAT(ErrorOf([&] { SersicBn(n); }),
                AllOf(HasSubstr("SersicBn"), HasSubstr("n = "), HasSubstr("(0.2, 20]")));
    EXPECT_THAT(ErrorOf([&] { SersicBnCiottiBertin(n); }), HasSubstr("SersicBnCiottiBertin"));
    EXPECT_THAT(ErrorOf([&] { SersicEnclosedFraction(n, 1.0); }), HasSubstr("SersicEnclosedFraction"));
  }
  EXPECT_THAT(ErrorOf([] { SersicEnclosedFraction(1.0, -1.0); }), HasSubstr("radius_over_re = -1"));
  EXPECT_THAT(ErrorOf([] { RegularisedGammaP(0.0, 1.0); }),
              AllOf(HasSubstr("RegularisedGammaP"), HasSubstr("a = 0")));
  EXPECT_THAT(ErrorOf([] { RegularisedGammaP(1.0, -1.0); }), HasSubstr("x = -1"));
}

TEST(ObjectGeneratorsErrorsTest, SersicGalaxy) {
  const Shape hr{32, 32};
  SersicGalaxy g;
  g.flux = -1.0;
  EXPECT_THAT(ErrorOf([&] { RenderSersic(hr, g); }),
              AllOf(HasSubstr("RenderSersic"), HasSubstr("flux = -1")));
  g = {};
  g.n = 0.2;
  EXPECT_THAT(ErrorOf([&] { RenderSersic(hr, g); }), AllOf(HasSubstr("n = 0.2"), HasSubstr("(0.2, 20]")));
  g.n = 21.0;
  EXPECT_THAT(ErrorOf([&] { RenderSersic(hr, g); }), HasSubstr("n = 21"));
  g = {};
  g.axis_ratio = 0.0;
  EXPECT_THAT(ErrorOf([&] { RenderSersic(hr, g); }), AllOf(HasSubstr("axis_ratio = 0"), HasSubstr("(0, 1]")));
  g.axis_ratio = 1.5;
  EXPECT_THAT(ErrorOf([&] { RenderSersic(hr, g); }), HasSubstr("axis_ratio = 1.5"));
  g = {};
  g.half_light_radius_px = 0.0;
  EXPECT_THAT(ErrorOf([&] { RenderSersic(hr, g); }), HasSubstr("half_light_radius_px = 0"));
  g = {};
  g.position_angle_rad = kInf;
  EXPECT_THAT(ErrorOf([&] { RenderSersic(hr, g); }), HasSubstr("position_angle_rad = inf"));
  g = {};
  g.x = kNaN;
  EXPECT_THAT(ErrorOf([&] { RenderSersic(hr, g); }), HasSubstr("centre"));
  EXPECT_THAT(ErrorOf([&] { g.EffectiveIntensity(); }), HasSubstr("SersicGalaxy::EffectiveIntensity"));
  EXPECT_THAT(ErrorOf([&] { g.Intensity(0.0, 0.0); }), HasSubstr("SersicGalaxy::Intensity"));
  g = {};
  EXPECT_THAT(ErrorOf([&] { g.Intensity(kNaN, 0.0); }), HasSubstr("(y, x)"));
  EXPECT_THAT(ErrorOf([&] {
                RenderSersic({0, 0}, g);
              }),
              AllOf(HasSubstr("RenderSersic"), HasSubstr("hr = 0x0")));
  SersicRenderOptions ro;
  ro.relative_tolerance = 0.5;
  EXPECT_THAT(ErrorOf([&] { RenderSersic(hr, g, ro); }), HasSubstr("relative_tolerance = 0.5"));
  ro = {};
  ro.max_depth = 41;
  EXPECT_THAT(ErrorOf([&] { RenderSersic(hr, g, ro); }), HasSubstr("max_depth = 41"));
  SersicGalaxy bad;
  bad.n = 0.0;
  EXPECT_THAT(ErrorOf([&] {
                RenderGalaxies(hr, {g, bad});
              }),
              AllOf(HasSubstr("RenderGalaxies"), HasSubstr("galaxies[1]"), HasSubstr("n = 0")));
}

TEST(ObjectGeneratorsErrorsTest, GalaxyField) {
  const Shape hr{32, 32};
  GalaxyFieldOptions o;
  EXPECT_THAT(ErrorOf([&] {
                GalaxyField({32, 0}, o, 1);
              }),
              AllOf(HasSubstr("GalaxyField"), HasSubstr("hr = 32x0")));
  o.n_min = 0.1;
  EXPECT_THAT(ErrorOf([&] { GalaxyField(hr, o, 1); }), HasSubstr("n_min = 0.1"));
  o = {};
  o.n_max = 0.3;
  EXPECT_THAT(ErrorOf([&] { GalaxyField(hr, o, 1); }), HasSubstr("n_max = 0.3"));
  o = {};
  o.re_min_px = 0.0;
  EXPECT_THAT(ErrorOf([&] { GalaxyField(hr, o, 1); }), HasSubstr("re_min_px = 0"));
  o = {};
  o.re_max_px = 0.5;
  EXPECT_THAT(ErrorOf([&] { GalaxyField(hr, o, 1); }), HasSubstr("re_max_px = 0.5"));
  o = {};
  o.q_min = 0.0;
  EXPECT_THAT(ErrorOf([&] { GalaxyField(hr, o, 1); }), HasSubstr("q_min = 0"));
  o = {};
  o.q_max = 1.2;
  EXPECT_THAT(ErrorOf([&] { GalaxyField(hr, o, 1); }), HasSubstr("q_max = 1.2"));
  o = {};
  o.count = -3;
  EXPECT_THAT(ErrorOf([&] { GalaxyField(hr, o, 1); }), HasSubstr("count = -3"));
  o = {};
  o.flux.flux_min = 1e5;
  EXPECT_THAT(ErrorOf([&] { GalaxyField(hr, o, 1); }), HasSubstr("flux.flux_max"));
  o = {};
  o.margin_px = 16.0;
  EXPECT_THAT(ErrorOf([&] { GalaxyField(hr, o, 1); }), HasSubstr("options.margin_px = 16"));
  o.margin_px = -1.0;
  EXPECT_THAT(ErrorOf([&] { GalaxyField(hr, o, 1); }), HasSubstr("margin_px = -1"));
}

// ---- dead leaves ----

TEST(ObjectGeneratorsErrorsTest, DeadLeaves) {
  DeadLeavesOptions o;
  EXPECT_THAT(ErrorOf([&] {
                DeadLeaves({0, 8}, o, 1);
              }),
              AllOf(HasSubstr("DeadLeaves"), HasSubstr("hr = 0x8")));
  o.r_min_px = 0.0;
  EXPECT_THAT(ErrorOf([&] { DeadLeaves({8, 8}, o, 1); }), HasSubstr("r_min_px = 0"));
  o = {};
  o.r_min_px = 5.0;
  o.r_max_px = 5.0;
  EXPECT_THAT(ErrorOf([&] {
                DeadLeaves({8, 8}, o, 1);
              }),
              AllOf(HasSubstr("r_max_px = 5"), HasSubstr("> r_min_px")));
  o = {};
  o.r_max_px = 1e5;
  EXPECT_THAT(ErrorOf([&] { DeadLeaves({8, 8}, o, 1); }), HasSubstr("r_max_px = 100000"));
  o = {};
  o.radius_exponent = 0.5;
  EXPECT_THAT(ErrorOf([&] { DeadLeaves({8, 8}, o, 1); }), HasSubstr("radius_exponent = 0.5"));
  o = {};
  o.grey_max = 0.0;
  EXPECT_THAT(ErrorOf([&] { DeadLeaves({8, 8}, o, 1); }), HasSubstr("grey_max = 0"));
  o = {};
  o.grey_min = kNaN;
  EXPECT_THAT(ErrorOf([&] { DeadLeaves({8, 8}, o, 1); }), HasSubstr("grey_min = nan"));
  o = {};
  o.supersample = 0;
  EXPECT_THAT(ErrorOf([&] { DeadLeaves({8, 8}, o, 1); }), HasSubstr("supersample = 0"));
  o = {};
  o.max_leaves = 0;
  EXPECT_THAT(ErrorOf([&] { DeadLeaves({8, 8}, o, 1); }), HasSubstr("max_leaves = 0"));
}

// ---- image-file objects ----

TEST(ObjectGeneratorsErrorsTest, ImageObject) {
  const Image src = Image::Ones(8, 8);
  EXPECT_THAT(ErrorOf([&] {
                ResampleArea(Image(), {4, 4});
              }),
              AllOf(HasSubstr("ResampleArea"), HasSubstr("source")));
  EXPECT_THAT(ErrorOf([&] {
                ResampleArea(src, {0, 4});
              }),
              AllOf(HasSubstr("ResampleArea"), HasSubstr("out = 0x4")));
  Image with_nan = src;
  with_nan(1, 1) = kNaN;
  EXPECT_THAT(ErrorOf([&] { ResampleArea(with_nan, {4, 4}); }), HasSubstr("1 non-finite pixels"));
  EXPECT_THAT(ErrorOf([&] { ResampleArea(src, {4, 4}, static_cast<ImageFit>(7)); }), HasSubstr("fit = 7"));
  EXPECT_THAT(ErrorOf([&] {
                ResampleArea(src, {4, 4}, ImageFit::kCrop, static_cast<PixelValues>(9));
              }),
              HasSubstr("values = 9"));

  ImageObjectOptions o;
  EXPECT_THAT(ErrorOf([&] {
                MakeImageObject(src, {4, -1}, o);
              }),
              AllOf(HasSubstr("MakeImageObject"), HasSubstr("hr = 4x-1")));
  EXPECT_THAT(ErrorOf([&] {
                MakeImageObject(with_nan, {4, 4}, o);
              }),
              AllOf(HasSubstr("MakeImageObject"), HasSubstr("non-finite")));
  o.total_flux = 0.0;
  EXPECT_THAT(ErrorOf([&] { MakeImageObject(src, {4, 4}, o); }), HasSubstr("total_flux = 0"));
  o = {};
  o.peak_value = -1.0;
  EXPECT_THAT(ErrorOf([&] { MakeImageObject(src, {4, 4}, o); }), HasSubstr("peak_value = -1"));
  o = {};
  o.normalisation = static_cast<FluxNormalisation>(5);
  EXPECT_THAT(ErrorOf([&] { MakeImageObject(src, {4, 4}, o); }), HasSubstr("normalisation = 5"));
  o = {};
  o.background = static_cast<ImageBackground>(-1);
  EXPECT_THAT(ErrorOf([&] { MakeImageObject(src, {4, 4}, o); }), HasSubstr("background = -1"));
  o = {};
  o.normalisation = FluxNormalisation::kPeak;
  o.background = ImageBackground::kMedian;  // a constant image has nothing left
  EXPECT_THAT(ErrorOf([&] {
                MakeImageObject(src, {4, 4}, o);
              }),
              AllOf(HasSubstr("image maximum = 0"), HasSubstr("peak_value")));
  o = {};
  EXPECT_THAT(ErrorOf([&] {
                LoadImageObject("/nonexistent/x.png", {0, 4}, o);
              }),
              AllOf(HasSubstr("LoadImageObject"), HasSubstr("hr = 0x4")));
  o.total_flux = kNaN;
  EXPECT_THAT(ErrorOf([&] {
                LoadImageObject("/nonexistent/x.png", {4, 4}, o);
              }),
              AllOf(HasSubstr("/nonexistent/x.png"), HasSubstr("total_flux = nan")));
  // A missing file is an IoError naming the path (image_object_test checks the type).
  EXPECT_THAT(ErrorOf<IoError>([] {
                LoadImageObject("/nonexistent/x.png", {4, 4});
              }),
              HasSubstr("/nonexistent/x.png"));
}

}  // namespace
}  // namespace aosr
