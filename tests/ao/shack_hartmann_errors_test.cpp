// Bad input at every public entry point of shack_hartmann.hpp and wavefront_sensor.hpp throws
// aosr::InvalidArgument naming the function and the field or argument.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <functional>
#include <limits>
#include <string>

#include "aosr/ao/shack_hartmann.hpp"
#include "aosr/ao/wavefront_sensor.hpp"
#include "aosr/core/error.hpp"
#include "aosr/optics/pupil.hpp"
#include "support/testing.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

using ::aosr::test::ErrorOf;
using ::testing::HasSubstr;

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kInf = std::numeric_limits<double>::infinity();

Image Pupil() { return CircularPupil(64, PupilGeometry{8.0, 0.0}); }

ShackHartmannOptions Small() {
  ShackHartmannOptions o;
  o.subapertures_across = 8;
  return o;
}

void ExpectInvalid(const std::function<void(ShackHartmannOptions&)>& mutate, const std::string& field) {
  ShackHartmannOptions o = Small();
  mutate(o);
  std::string why;
  EXPECT_FALSE(o.IsValid(&why)) << field;
  EXPECT_THAT(why, HasSubstr(field));
  EXPECT_THAT(ErrorOf([&] { ShackHartmann(Pupil(), 8.0, o); }),
              HasSubstr("ShackHartmann: invalid options." + field));
  EXPECT_THAT(ErrorOf([&] { GeometricSlopeOperator(Pupil(), 8.0, o); }), HasSubstr(field));
}

TEST(ShackHartmannErrorsTest, EveryOptionsFieldIsNamed) {
  EXPECT_TRUE(Small().IsValid(nullptr));
  ExpectInvalid([](ShackHartmannOptions& o) { o.subapertures_across = 0; }, "subapertures_across = 0");
  ExpectInvalid([](ShackHartmannOptions& o) { o.valid_threshold = 0.0; }, "valid_threshold = 0");
  ExpectInvalid([](ShackHartmannOptions& o) { o.valid_threshold = 1.5; }, "valid_threshold = 1.5");
  ExpectInvalid([](ShackHartmannOptions& o) { o.mode = static_cast<ShackHartmannMode>(9); }, "mode = 9");
  ExpectInvalid([](ShackHartmannOptions& o) { o.wavelength_m = -1.0; }, "wavelength_m = -1");
  ExpectInvalid([](ShackHartmannOptions& o) { o.wavelength_m = kInf; }, "wavelength_m = inf");
  ExpectInvalid([](ShackHartmannOptions& o) { o.pixel_scale_lod = 0.0; }, "pixel_scale_lod = 0");
  ExpectInvalid([](ShackHartmannOptions& o) { o.pixel_scale_lod = 1.5; }, "pixel_scale_lod = 1.5");
  ExpectInvalid([](ShackHartmannOptions& o) { o.field_of_view_px = 1; }, "field_of_view_px = 1");
  ExpectInvalid([](ShackHartmannOptions& o) { o.field_of_view_px = -3; }, "field_of_view_px = -3");
  ExpectInvalid([](ShackHartmannOptions& o) { o.spot_transform = static_cast<SpotTransform>(5); },
                "spot_transform = 5");
  ExpectInvalid([](ShackHartmannOptions& o) { o.threshold_fraction = 1.0; }, "threshold_fraction = 1");
  ExpectInvalid([](ShackHartmannOptions& o) { o.threshold_fraction = kNaN; }, "threshold_fraction = nan");
  ExpectInvalid([](ShackHartmannOptions& o) { o.noise.guide_star_magnitude = kNaN; },
                "noise.guide_star_magnitude = nan");
  ExpectInvalid([](ShackHartmannOptions& o) { o.noise.zero_point_photons_per_s_m2 = 0.0; },
                "noise.zero_point_photons_per_s_m2 = 0");
  ExpectInvalid([](ShackHartmannOptions& o) { o.noise.throughput = 1.2; }, "noise.throughput = 1.2");
  ExpectInvalid([](ShackHartmannOptions& o) { o.noise.frame_time_s = -1e-3; }, "noise.frame_time_s = -0.001");
  ExpectInvalid([](ShackHartmannOptions& o) { o.noise.read_noise_e = -1.0; }, "noise.read_noise_e = -1");
  ExpectInvalid([](ShackHartmannOptions& o) { o.noise.geometric_noise_rad = kInf; },
                "noise.geometric_noise_rad = inf");
  // Noise that the mode cannot simulate.
  ExpectInvalid([](ShackHartmannOptions& o) { o.noise.photon_noise = true; }, "noise.photon_noise = true");
  ExpectInvalid([](ShackHartmannOptions& o) { o.noise.read_noise_e = 2.0; }, "noise.read_noise_e = 2");
  ExpectInvalid(
      [](ShackHartmannOptions& o) {
        o.mode = ShackHartmannMode::kDiffractive;
        o.noise.geometric_noise_rad = 1e-6;
      },
      "noise.geometric_noise_rad = 1e-06");
}

TEST(ShackHartmannErrorsTest, ConstructorArguments) {
  const ShackHartmannOptions o = Small();
  EXPECT_THAT(ErrorOf([&] { ShackHartmann(Image::Ones(64, 32), 8.0, o); }),
              HasSubstr("ShackHartmann: invalid amplitude shape = 64x32"));
  EXPECT_THAT(ErrorOf([&] { ShackHartmann(-Pupil(), 8.0, o); }), HasSubstr("invalid amplitude"));
  EXPECT_THAT(ErrorOf([&] { ShackHartmann(Image::Zero(64, 64), 8.0, o); }),
              HasSubstr("amplitude = all zero"));
  EXPECT_THAT(ErrorOf([&] { ShackHartmann(Pupil(), 0.0, o); }), HasSubstr("invalid diameter_m = 0"));
  EXPECT_THAT(ErrorOf([&] { ShackHartmann(Pupil(), kNaN, o); }), HasSubstr("invalid diameter_m = nan"));
  ShackHartmannOptions bad = o;
  bad.subapertures_across = 12;  // does not divide 64
  EXPECT_THAT(ErrorOf([&] { ShackHartmann(Pupil(), 8.0, bad); }),
              HasSubstr("invalid options.subapertures_across = 12"));
  bad.subapertures_across = 64;  // 1 pixel per lenslet
  EXPECT_THAT(ErrorOf([&] { ShackHartmann(Pupil(), 8.0, bad); }),
              HasSubstr("invalid options.subapertures_across = 64"));
  // A pupil that lights no lenslet to the threshold.
  Image speck = Image::Zero(64, 64);
  speck(3, 3) = 1.0;
  EXPECT_THAT(ErrorOf([&] { ShackHartmann(speck, 8.0, o); }), HasSubstr("no valid lenslet"));
  // Diffractive geometry: a window wider than one period, and kFft with a non-integer period.
  ShackHartmannOptions d = o;
  d.mode = ShackHartmannMode::kDiffractive;
  d.field_of_view_px = 20;  // p = 8, s = 0.5: at most 16
  EXPECT_THAT(ErrorOf([&] { ShackHartmann(Pupil(), 8.0, d); }),
              HasSubstr("ShackHartmann: invalid options.field_of_view_px = 20"));
  d.field_of_view_px = 0;
  d.pixel_scale_lod = 0.3;
  d.spot_transform = SpotTransform::kFft;
  EXPECT_THAT(ErrorOf([&] { ShackHartmann(Pupil(), 8.0, d); }),
              HasSubstr("invalid options.pixel_scale_lod = 0.3"));
  // The operator on its own.
  EXPECT_THAT(ErrorOf([&] { GeometricSlopeOperator(Image::Ones(10, 10), 8.0, bad); }),
              HasSubstr("GeometricSlopeOperator: invalid options.subapertures_across"));
}

TEST(ShackHartmannErrorsTest, MeasurementArguments) {
  ShackHartmannOptions o = Small();
  o.mode = ShackHartmannMode::kDiffractive;
  ShackHartmann sh(Pupil(), 8.0, o);
  EXPECT_THAT(ErrorOf([&] { sh.Measure(Image::Zero(32, 32)); }),
              HasSubstr("WavefrontSensor::Measure: invalid opd_m shape = 32x32"));
  EXPECT_THAT(ErrorOf([&] { sh.MeasureNoiseless(Image::Zero(64, 63)); }),
              HasSubstr("WavefrontSensor::MeasureNoiseless: invalid opd_m shape"));
  Vector wrong(5);
  EXPECT_THAT(ErrorOf([&] { sh.Measure(Image::Zero(64, 64), wrong); }),
              HasSubstr("invalid measurement size = 5"));
  Image nan = Image::Zero(64, 64);
  nan(32, 32) = kNaN;
  EXPECT_THAT(ErrorOf([&] { sh.Measure(nan); }), HasSubstr("invalid opd_m"));
  EXPECT_THAT(ErrorOf([&] { sh.ReferenceOffsetForOpd(nan); }),
              HasSubstr("WavefrontSensor::ReferenceOffsetForOpd: invalid opd_m"));
  EXPECT_THAT(ErrorOf([&] { sh.ReferenceOffsetForOpd(Image::Zero(8, 8)); }),
              HasSubstr("ReferenceOffsetForOpd: invalid opd_m shape = 8x8"));
  // NaN outside the pupil is ignored.
  Image corner = Image::Zero(64, 64);
  corner(0, 0) = kNaN;
  EXPECT_EQ(ErrorOf([&] { sh.Measure(corner); }), "no exception");
  EXPECT_THAT(ErrorOf([&] { sh.SetReferenceOffset(Vector::Zero(3)); }),
              HasSubstr("WavefrontSensor::SetReferenceOffset: invalid offset size = 3"));
  Vector bad_offset = Vector::Zero(sh.n_measurements());
  bad_offset[1] = kInf;
  EXPECT_THAT(ErrorOf([&] { sh.SetReferenceOffset(bad_offset); }), HasSubstr("invalid offset"));
  EXPECT_THAT(ErrorOf([&] { sh.LastSpot(-1); }), HasSubstr("ShackHartmann::LastSpot: invalid v = -1"));
  EXPECT_THAT(ErrorOf([&] { sh.LastSpot(sh.n_valid()); }), HasSubstr("invalid v"));
  ShackHartmann geometric(Pupil(), 8.0, Small());
  EXPECT_THAT(ErrorOf([&] { geometric.LastSpot(0); }), HasSubstr("ShackHartmann::LastSpot: invalid mode"));
  // The operator checks sizes like every LinearOperator.
  Vector x(10), y(geometric.geometric_operator()->rows());
  EXPECT_THAT(ErrorOf([&] { geometric.geometric_operator()->Apply(x, y); }),
              HasSubstr("GeometricShackHartmann"));
}

TEST(ShackHartmannErrorsTest, IdealSensorArguments) {
  DeformableMirrorOptions dmo;
  dmo.actuators_across = 9;
  dmo.pitch_m = 1.0;
  auto dm = std::make_shared<const DeformableMirror>(64, PupilGeometry{8.0, 0.0}, dmo);
  EXPECT_THAT(ErrorOf([&] { IdealWavefrontSensor(nullptr, Pupil()); }),
              HasSubstr("IdealWavefrontSensor: invalid dm = null"));
  EXPECT_THAT(ErrorOf([&] { IdealWavefrontSensor(dm, Image::Ones(32, 32)); }),
              HasSubstr("IdealWavefrontSensor: invalid amplitude shape = 32x32"));
  DmFitOptions fit;
  fit.regularisation = -1.0;
  EXPECT_THAT(ErrorOf([&] { IdealWavefrontSensor(dm, Pupil(), fit); }), HasSubstr("regularisation = -1"));
  IdealWavefrontSensor ideal(dm, Pupil());
  EXPECT_THAT(ErrorOf([&] { ideal.Measure(Image::Zero(16, 16)); }), HasSubstr("invalid opd_m shape = 16x16"));
}

}  // namespace
}  // namespace aosr
