#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>

#include "aosr/ao/ao_system.hpp"
#include "aosr/optics/pupil.hpp"
#include "support/testing.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

using aosr::test::ErrorOf;
using ::testing::HasSubstr;

AoSystemSpec SmallSpec() {
  AoSystemSpec s;
  s.amplitude = CircularPupil(32, PupilGeometry{8.0, 0.0});
  s.diameter_m = 8.0;
  s.dm.actuators_across = 9;
  s.dm.pitch_m = 1.0;
  s.sensor = SensorKind::kGeometric;
  s.wfs.subapertures_across = 8;
  return s;
}

TEST(AoSystemErrorsTest, BadPartsAreNamed) {
  EXPECT_EQ(BuildAoSystem(SmallSpec()).dm->options().actuators_across, 9);
  AoSystemSpec s = SmallSpec();
  s.amplitude = Image::Ones(32, 16);
  EXPECT_THAT(ErrorOf([&] { BuildAoSystem(s); }), HasSubstr("spec.amplitude shape"));
  s = SmallSpec();
  s.dm.pitch_m = -1.0;
  EXPECT_THAT(ErrorOf([&] { BuildAoSystem(s); }), HasSubstr("pitch_m"));
  s = SmallSpec();
  s.control.gain = -0.5;
  EXPECT_THAT(ErrorOf([&] { BuildAoSystem(s); }), HasSubstr("gain"));
  s = SmallSpec();
  s.wfs.subapertures_across = 0;
  EXPECT_THAT(ErrorOf([&] { BuildAoSystem(s); }), HasSubstr("subapertures_across"));
}

TEST(AoSystemErrorsTest, WfsNoiseMeasurementArgumentsAreNamed) {
  AoSystem system = BuildAoSystem(SmallSpec());
  EXPECT_EQ(MeasureWfsNoiseRad2(system, 550e-9, 2), 0.0);  // a noiseless sensor
  EXPECT_THAT(ErrorOf([&] { MeasureWfsNoiseRad2(system, 0.0, 2); }), HasSubstr("wavelength_m"));
  EXPECT_THAT(ErrorOf([&] { MeasureWfsNoiseRad2(system, std::nan(""), 2); }), HasSubstr("wavelength_m"));
  EXPECT_THAT(ErrorOf([&] { MeasureWfsNoiseRad2(system, 550e-9, 0); }), HasSubstr("samples"));
  AoSystem empty;
  EXPECT_THAT(ErrorOf([&] { MeasureWfsNoiseRad2(empty, 550e-9, 2); }), HasSubstr("system"));
}

}  // namespace
}  // namespace aosr
