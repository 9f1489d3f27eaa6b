// Every public entry point of the planet renderer (scene/planet.hpp) rejects bad input with a message naming
// the function and the argument or field.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <limits>

#include "aosr/core/error.hpp"
#include "aosr/scene/planet.hpp"
#include "support/testing.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

using aosr::test::ErrorOf;

using ::testing::AllOf;
using ::testing::HasSubstr;

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kInf = std::numeric_limits<double>::infinity();

PlanetOptions Good() {
  PlanetOptions o;
  o.radius_px = 5.0;
  o.rotation_period_s = 10.0;
  return o;
}

const Shape kField{16, 16};

// Renders with `o` and returns the error message.
std::string RenderError(const PlanetOptions& o) {
  return ErrorOf([&] { RenderPlanet(kField, o, Image::Ones(4, 8), 0.0); });
}

TEST(PlanetErrorsTest, GoodInputRenders) {
  EXPECT_EQ(RenderError(Good()), "no exception");
  std::string why;
  EXPECT_TRUE(Good().IsValid(&why));
  EXPECT_TRUE(PlanetTextureOptions{}.IsValid(&why));
  // A NaN centre is the field centre; a finite one off the field is allowed (the disc is clipped away).
  PlanetOptions o = Good();
  o.centre_y = -100.0;
  o.centre_x = 1e6;
  EXPECT_EQ(RenderError(o), "no exception");
  EXPECT_EQ(RenderPlanet(kField, o, Image::Ones(4, 8), 0.0).sum(), 0.0);
}

TEST(PlanetErrorsTest, Radius) {
  for (double r : {0.0, -1.0, kNaN, kInf, 1e6}) {
    PlanetOptions o = Good();
    o.radius_px = r;
    EXPECT_THAT(RenderError(o), AllOf(HasSubstr("RenderPlanet"), HasSubstr("radius_px"))) << r;
    std::string why;
    EXPECT_FALSE(o.IsValid(&why));
    EXPECT_THAT(why, AllOf(HasSubstr("radius_px = "), HasSubstr("(0, 100000]")));
  }
  PlanetOptions o = Good();
  o.radius_px = 0.0;
  EXPECT_THAT(RenderError(o), HasSubstr("radius_px = 0"));
}

TEST(PlanetErrorsTest, Supersample) {
  for (int s : {0, -1, 17}) {
    PlanetOptions o = Good();
    o.supersample = s;
    EXPECT_THAT(RenderError(o), AllOf(HasSubstr("RenderPlanet"),
                                      HasSubstr("supersample = " + std::to_string(s)), HasSubstr("[1, 16]")));
  }
}

TEST(PlanetErrorsTest, LimbDarkening) {
  for (double u : {-0.1, 1.01, kNaN}) {
    PlanetOptions o = Good();
    o.limb_darkening = u;
    EXPECT_THAT(RenderError(o),
                AllOf(HasSubstr("RenderPlanet"), HasSubstr("limb_darkening"), HasSubstr("[0, 1]")));
  }
}

TEST(PlanetErrorsTest, SubObserverLatitude) {
  for (double b : {-90.5, 91.0, kNaN, kInf}) {
    PlanetOptions o = Good();
    o.sub_observer_latitude_deg = b;
    EXPECT_THAT(RenderError(o), AllOf(HasSubstr("RenderPlanet"), HasSubstr("sub_observer_latitude_deg"),
                                      HasSubstr("[-90, 90]")));
  }
}

TEST(PlanetErrorsTest, OtherOptions) {
  PlanetOptions o = Good();
  o.rotation_period_s = kInf;
  EXPECT_THAT(RenderError(o), HasSubstr("rotation_period_s"));
  o = Good();
  o.rotation_period_s = kNaN;
  EXPECT_THAT(RenderError(o), HasSubstr("rotation_period_s"));
  o = Good();
  o.pole_angle_deg = 400.0;
  EXPECT_THAT(RenderError(o), AllOf(HasSubstr("pole_angle_deg = 400"), HasSubstr("[-360, 360]")));
  o = Good();
  o.pole_angle_deg = kNaN;
  EXPECT_THAT(RenderError(o), HasSubstr("pole_angle_deg"));
  o = Good();
  o.longitude0_deg = kInf;
  EXPECT_THAT(RenderError(o), HasSubstr("longitude0_deg"));
  o = Good();
  o.centre_x = kInf;
  EXPECT_THAT(RenderError(o), AllOf(HasSubstr("centre"), HasSubstr("NaN for the field centre")));
  o = Good();
  o.centre_y = -kInf;
  EXPECT_THAT(RenderError(o), HasSubstr("centre"));
}

TEST(PlanetErrorsTest, Texture) {
  const PlanetOptions o = Good();
  EXPECT_THAT(ErrorOf([&] { RenderPlanet(kField, o, Image(), 0.0); }),
              AllOf(HasSubstr("RenderPlanet"), HasSubstr("texture = 0x0"), HasSubstr("non-empty")));
  Image bad = Image::Ones(4, 8);
  bad(1, 2) = kNaN;
  EXPECT_THAT(ErrorOf([&] { RenderPlanet(kField, o, bad, 0.0); }),
              AllOf(HasSubstr("RenderPlanet"), HasSubstr("texture"), HasSubstr("non-finite")));
  bad(1, 2) = kInf;
  EXPECT_THAT(ErrorOf([&] { RenderPlanet(kField, o, bad, 0.0); }), HasSubstr("non-finite"));
  bad(1, 2) = -0.5;
  EXPECT_THAT(
      ErrorOf([&] { RenderPlanet(kField, o, bad, 0.0); }),
      AllOf(HasSubstr("RenderPlanet"), HasSubstr("texture"), HasSubstr("minimum -0.5"), HasSubstr(">= 0")));
  // 1 x 1 and all-zero maps are fine.
  EXPECT_EQ(ErrorOf([&] { RenderPlanet(kField, o, Image::Constant(1, 1, 2.0), 0.0); }), "no exception");
  EXPECT_EQ(ErrorOf([&] { RenderPlanet(kField, o, Image::Zero(3, 3), 0.0); }), "no exception");
}

TEST(PlanetErrorsTest, TimeAndField) {
  const PlanetOptions o = Good();
  const Image t = Image::Ones(4, 8);
  for (double time : {kNaN, kInf, -kInf})
    EXPECT_THAT(ErrorOf([&] { RenderPlanet(kField, o, t, time); }),
                AllOf(HasSubstr("RenderPlanet"), HasSubstr("time_s"), HasSubstr("finite")));
  const auto field_error = [&](Shape hr) { return ErrorOf([&] { RenderPlanet(hr, o, t, 0.0); }); };
  EXPECT_THAT(field_error({0, 16}),
              AllOf(HasSubstr("RenderPlanet"), HasSubstr("hr = 0x16"), HasSubstr(">= 1")));
  EXPECT_THAT(field_error({16, 0}), HasSubstr("hr = 16x0"));
  EXPECT_THAT(field_error({-3, 4}), HasSubstr("hr = -3x4"));
}

TEST(PlanetErrorsTest, HelpersValidateToo) {
  PlanetOptions o = Good();
  EXPECT_THAT(ErrorOf([&] { PlanetCentralMeridianDeg(o, kNaN); }),
              AllOf(HasSubstr("PlanetCentralMeridianDeg"), HasSubstr("time_s")));
  EXPECT_THAT(ErrorOf([&] { PlanetSurfaceAt(kField, o, kNaN, 1.0, 0.0); }),
              AllOf(HasSubstr("PlanetSurfaceAt"), HasSubstr("invalid y")));
  EXPECT_THAT(ErrorOf([&] { PlanetSurfaceAt(kField, o, 1.0, kInf, 0.0); }),
              AllOf(HasSubstr("PlanetSurfaceAt"), HasSubstr("invalid x")));
  EXPECT_THAT(ErrorOf([&] { PlanetSurfaceAt(kField, o, 1.0, 1.0, kInf); }), HasSubstr("time_s"));
  EXPECT_THAT(ErrorOf([&] { PlanetSurfaceAt(Shape{0, 0}, o, 1.0, 1.0, 0.0); }), HasSubstr("hr"));
  o.radius_px = -2.0;
  EXPECT_THAT(ErrorOf([&] { PlanetCentralMeridianDeg(o, 0.0); }),
              AllOf(HasSubstr("PlanetCentralMeridianDeg"), HasSubstr("radius_px = -2")));
  EXPECT_THAT(ErrorOf([&] { PlanetSurfaceAt(kField, o, 1.0, 1.0, 0.0); }),
              AllOf(HasSubstr("PlanetSurfaceAt"), HasSubstr("radius_px")));
}

TEST(PlanetErrorsTest, TextureOptions) {
  struct Case {
    const char* field;
    void (*set)(PlanetTextureOptions*);
    const char* allowed;
  };
  const Case cases[] = {
      {"rows = 1", [](PlanetTextureOptions* t) { t->rows = 1; }, "[2, 65536]"},
      {"rows = 0", [](PlanetTextureOptions* t) { t->rows = 0; }, "[2, 65536]"},
      {"cols = 1", [](PlanetTextureOptions* t) { t->cols = 1; }, "[2, 65536]"},
      {"cols = 70000", [](PlanetTextureOptions* t) { t->cols = 70000; }, "[2, 65536]"},
      {"bands = -1", [](PlanetTextureOptions* t) { t->bands = -1; }, "[0, 1000]"},
      {"band_contrast = -0.1", [](PlanetTextureOptions* t) { t->band_contrast = -0.1; }, "[0, 1)"},
      {"band_contrast = 1", [](PlanetTextureOptions* t) { t->band_contrast = 1.0; }, "[0, 1)"},
      {"band_contrast = nan", [](PlanetTextureOptions* t) { t->band_contrast = kNaN; }, "[0, 1)"},
      {"band_wobble_deg = -1", [](PlanetTextureOptions* t) { t->band_wobble_deg = -1.0; }, "[0, 45]"},
      {"spots = -2", [](PlanetTextureOptions* t) { t->spots = -2; }, "[0, 100000]"},
      {"spot_radius_deg = 0", [](PlanetTextureOptions* t) { t->spot_radius_deg = 0.0; }, "(0, 90]"},
      {"spot_radius_deg = 91", [](PlanetTextureOptions* t) { t->spot_radius_deg = 91.0; }, "(0, 90]"},
      {"spot_contrast = -1", [](PlanetTextureOptions* t) { t->spot_contrast = -1.0; }, "[0, 1e6]"},
      {"spot_contrast = inf", [](PlanetTextureOptions* t) { t->spot_contrast = kInf; }, "[0, 1e6]"},
  };
  for (const Case& c : cases) {
    PlanetTextureOptions t;
    c.set(&t);
    EXPECT_THAT(ErrorOf([&] { PlanetTexture(t, 1); }),
                AllOf(HasSubstr("PlanetTexture"), HasSubstr(c.field), HasSubstr(c.allowed)))
        << c.field;
    std::string why;
    EXPECT_FALSE(t.IsValid(&why));
    EXPECT_THAT(why, HasSubstr(c.field));
    EXPECT_FALSE(t.IsValid(nullptr));
  }
  // Zero counts and contrasts are allowed.
  PlanetTextureOptions t;
  t.bands = 0;
  t.band_contrast = 0.0;
  t.spots = 0;
  t.spot_contrast = 0.0;
  EXPECT_EQ(ErrorOf([&] { PlanetTexture(t, 1); }), "no exception");
}

}  // namespace AOSR_TEST_NS
}  // namespace aosr
