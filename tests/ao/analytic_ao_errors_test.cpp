// Bad input at every public analytic-AO entry point throws aosr::InvalidArgument naming the field or
// argument (include/aosr/ao/analytic_ao.hpp).
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <limits>
#include <string>

#include "aosr/ao/analytic_ao.hpp"
#include "aosr/core/error.hpp"
#include "aosr/optics/pupil.hpp"
#include "support/testing.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

using aosr::test::ErrorOf;

using ::testing::HasSubstr;

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kInf = std::numeric_limits<double>::infinity();


// Each mutation of valid options must fail IsValid with a message naming `field`, and every entry point
// taking options must throw with that message.
void ExpectInvalid(const std::function<void(AnalyticAoOptions&)>& mutate, const std::string& field) {
  AnalyticAoOptions o;
  mutate(o);
  std::string why;
  EXPECT_FALSE(o.IsValid(&why)) << field;
  EXPECT_THAT(why, HasSubstr(field));
  EXPECT_THAT(ErrorOf([&] { ComputeAnalyticAoErrorBudget(o); }),
              HasSubstr("ComputeAnalyticAoErrorBudget: invalid options. " + field));
  EXPECT_THAT(ErrorOf([&] { ComputeResidualPsd(o, 64, 0.03); }), HasSubstr(field));
  EXPECT_THAT(ErrorOf([&] { AnalyticAoResidual(o, 64); }), HasSubstr(field));
  EXPECT_THAT(ErrorOf([&] { AnalyticAoLoopTransfer(o, 1.0); }), HasSubstr(field));
  EXPECT_THAT(ErrorOf([&] { AnalyticAoNoiseGain(o); }), HasSubstr(field));
  EXPECT_THAT(ErrorOf([&] {
                AnalyticAoPsfCalculator(o, 64, PsfSampling{2.2e-6, 5e-8, 32, 32});
              }),
              HasSubstr(field));
}

TEST(AnalyticAoErrorsTest, EveryOptionsFieldIsNamed) {
  ExpectInvalid([](AnalyticAoOptions& o) { o.diameter_m = 0.0; }, "diameter_m = 0");
  ExpectInvalid([](AnalyticAoOptions& o) { o.diameter_m = kInf; }, "diameter_m");
  ExpectInvalid([](AnalyticAoOptions& o) { o.actuator_pitch_m = -0.5; }, "actuator_pitch_m = -0.5");
  ExpectInvalid([](AnalyticAoOptions& o) { o.actuator_pitch_m = 5.0; }, "actuator_pitch_m = 5");
  ExpectInvalid([](AnalyticAoOptions& o) { o.control_domain = static_cast<ControlDomain>(7); },
                "control_domain");
  ExpectInvalid([](AnalyticAoOptions& o) { o.r0_m = 0.0; }, "r0_m = 0");
  ExpectInvalid([](AnalyticAoOptions& o) { o.r0_m = kNaN; }, "r0_m");
  ExpectInvalid([](AnalyticAoOptions& o) { o.reference_wavelength_m = -1e-6; }, "reference_wavelength_m");
  ExpectInvalid([](AnalyticAoOptions& o) { o.outer_scale_m = 0.0; }, "outer_scale_m = 0");
  ExpectInvalid([](AnalyticAoOptions& o) { o.layers.clear(); }, "layers");
  ExpectInvalid([](AnalyticAoOptions& o) { o.layers[0].altitude_m = -10.0; }, "layers[0].altitude_m");
  ExpectInvalid([](AnalyticAoOptions& o) { o.layers[0].cn2_fraction = 1.5; }, "layers[0].cn2_fraction");
  ExpectInvalid([](AnalyticAoOptions& o) { o.layers[0].wind_speed_mps = kNaN; }, "layers[0].wind_speed_mps");
  ExpectInvalid([](AnalyticAoOptions& o) { o.layers[0].wind_direction_rad = kInf; },
                "layers[0].wind_direction_rad");
  ExpectInvalid(
      [](AnalyticAoOptions& o) {
        o.layers = {{0.0, 0.5, 5.0, 0.0}, {1e4, 0.4, 5.0, 0.0}};
      },
      "layers[].cn2_fraction sum = 0.9");
  ExpectInvalid(
      [](AnalyticAoOptions& o) {
        o.layers = {{0.0, 0.5, 5.0, 0.0}, {1e4, 0.5, -1.0, 0.0}};
      },
      "layers[1].wind_speed_mps = -1");
  ExpectInvalid([](AnalyticAoOptions& o) { o.loop_rate_hz = 0.0; }, "loop_rate_hz = 0");
  ExpectInvalid([](AnalyticAoOptions& o) { o.loop_gain = -0.1; }, "loop_gain = -0.1");
  ExpectInvalid([](AnalyticAoOptions& o) { o.loop_gain = 1.2; }, "loop_gain = 1.2 is unstable");
  ExpectInvalid([](AnalyticAoOptions& o) { o.loop_delay_frames = -1.0; }, "loop_delay_frames = -1");
  ExpectInvalid([](AnalyticAoOptions& o) { o.loop_delay_frames = 25.0; }, "loop_delay_frames = 25");
  ExpectInvalid([](AnalyticAoOptions& o) { o.wfs_noise_rad2 = -1.0; }, "wfs_noise_rad2 = -1");
  ExpectInvalid([](AnalyticAoOptions& o) { o.science_wavelength_m = 0.0; }, "science_wavelength_m = 0");
  ExpectInvalid([](AnalyticAoOptions& o) { o.frequency_padding = 1; }, "frequency_padding = 1");
  ExpectInvalid([](AnalyticAoOptions& o) { o.aliasing_orders = 0; }, "aliasing_orders = 0");
}

TEST(AnalyticAoErrorsTest, UnstableGainMessageGivesTheLimit) {
  AnalyticAoOptions o;
  o.loop_delay_frames = 1.0;
  o.loop_gain = 1.5;
  std::string why;
  EXPECT_FALSE(o.IsValid(&why));
  EXPECT_THAT(why, HasSubstr("allowed: [0, 1)"));
}

TEST(AnalyticAoErrorsTest, LoopFunctionArguments) {
  const AnalyticAoOptions o;
  EXPECT_THAT(ErrorOf([&] { AnalyticAoLoopTransfer(o, kNaN); }),
              HasSubstr("AnalyticAoLoopTransfer: invalid nu_hz"));
  EXPECT_THAT(ErrorOf([] { AnalyticAoLoopSpectralRadius(-1.0, 1.0); }),
              HasSubstr("AnalyticAoLoopSpectralRadius: invalid gain = -1"));
  EXPECT_THAT(ErrorOf([] { AnalyticAoLoopSpectralRadius(0.5, 30.0); }),
              HasSubstr("AnalyticAoLoopSpectralRadius: invalid delay_frames = 30"));
}

TEST(AnalyticAoErrorsTest, PsdGridArguments) {
  const AnalyticAoOptions o;
  EXPECT_THAT(ErrorOf([&] { ComputeResidualPsd(o, 63, 0.03); }),
              HasSubstr("ComputeResidualPsd: invalid grid_n = 63"));
  EXPECT_THAT(ErrorOf([&] { ComputeResidualPsd(o, 64, 0.0); }),
              HasSubstr("ComputeResidualPsd: invalid frequency_step_per_m = 0"));
  // 64 cells of 0.01 cycles/m reach 0.31 cycles/m: far short of the control region (f_c = 1).
  EXPECT_THAT(ErrorOf([&] { ComputeResidualPsd(o, 64, 0.01); }),
              HasSubstr("the grid's disk must hold the control region"));
}

TEST(AnalyticAoErrorsTest, PupilGridAndSampling) {
  const AnalyticAoOptions o;  // 16 actuators across: needs n >= sqrt(2) 16 + 1 = 24
  EXPECT_THAT(ErrorOf([&] { AnalyticAoResidual(o, 16); }),
              HasSubstr("AnalyticAoResidual: invalid pupil_n = 16"));
  EXPECT_THAT(ErrorOf([&] { AnalyticAoResidual(o, 2000); }),
              HasSubstr("AnalyticAoResidual: invalid pupil_n = 2000; allowed: [24, 1024]"));
  EXPECT_THAT(ErrorOf([&] {
                AnalyticAoPsfCalculator(o, 20, PsfSampling{2.2e-6, 5e-8, 32, 32});
              }),
              HasSubstr("AnalyticAoPsfCalculator: invalid pupil_n = 20"));
  EXPECT_THAT(ErrorOf([&] {
                AnalyticAoPsfCalculator(o, 32, PsfSampling{1.6e-6, 5e-8, 32, 32});
              }),
              HasSubstr("invalid sampling.wavelength_m"));
  EXPECT_THAT(ErrorOf([&] {
                AnalyticAoPsfCalculator(o, 32, PsfSampling{2.2e-6, 5e-8, 0, 32});
              }),
              HasSubstr("AnalyticAoPsfCalculator: invalid sampling.rows"));

  const AnalyticAoPsfCalculator calc(o, 32, PsfSampling{2.2e-6, 5e-8, 32, 32});
  const Image pupil = CircularPupil(32, PupilGeometry{8.0, 0.0}, 1);
  EXPECT_THAT(ErrorOf([&] { calc.Compute(Image::Ones(30, 30), Image::Zero(30, 30)); }),
              HasSubstr("AnalyticAoPsfCalculator::Compute: invalid amplitude shape = 30x30"));
  EXPECT_THAT(ErrorOf([&] { calc.Compute(pupil, Image::Zero(32, 31)); }), HasSubstr("invalid opd_m shape"));
  EXPECT_THAT(ErrorOf([&] { calc.Compute(Image::Zero(32, 32), Image::Zero(32, 32)); }),
              HasSubstr("invalid amplitude = all zero"));
  EXPECT_THAT(ErrorOf([&] { calc.Compute(-pupil, Image::Zero(32, 32)); }), HasSubstr("invalid amplitude"));
  Image opd = Image::Zero(32, 32);
  opd(16, 16) = kNaN;
  EXPECT_THAT(ErrorOf([&] { calc.Compute(pupil, opd); }), HasSubstr("invalid opd_m = nan"));
  EXPECT_THAT(ErrorOf([&] {
                AnalyticAoPsfFromPupil(o, Image::Ones(32, 30), Image::Zero(32, 30),
                                       PsfSampling{2.2e-6, 5e-8, 32, 32});
              }),
              HasSubstr("AnalyticAoPsfFromPupil: invalid amplitude shape"));
}

}  // namespace
}  // namespace aosr
