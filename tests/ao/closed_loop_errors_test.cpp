// Bad input at every public entry point of closed_loop.hpp throws aosr::InvalidArgument naming the function
// and the field or argument.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <functional>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "aosr/ao/closed_loop.hpp"
#include "aosr/core/error.hpp"
#include "loop_fixture.hpp"
#include "support/testing.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

using ::aosr::test::ErrorOf;
using ::testing::HasSubstr;

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr double kD = test::kPaperDiameter;

test::LoopSystem Small() {
  return test::MakePaperSystem(test::SensorKind::kGeometric, false, 1, ControllerOptions(), 32);
}

void ExpectInvalid(const std::function<void(ClosedLoopOptions&)>& mutate, const std::string& field) {
  ClosedLoopOptions o;
  mutate(o);
  std::string why;
  EXPECT_FALSE(o.IsValid(&why)) << field;
  EXPECT_THAT(why, HasSubstr(field));
  test::LoopSystem s = Small();
  EXPECT_THAT(
      ErrorOf([&] { ClosedLoop(s.amplitude, kD, nullptr, s.dm, s.wfs.get(), s.controller.get(), o); }),
      HasSubstr("ClosedLoop: invalid options." + field));
}

TEST(ClosedLoopErrorsTest, EveryOptionsFieldIsNamed) {
  EXPECT_TRUE(ClosedLoopOptions().IsValid(nullptr));
  ExpectInvalid([](ClosedLoopOptions& o) { o.science.wavelength_m = 0.0; }, "science.wavelength_m = 0");
  ExpectInvalid([](ClosedLoopOptions& o) { o.science.pixel_scale_rad = kNaN; },
                "science.pixel_scale_rad = nan");
  ExpectInvalid([](ClosedLoopOptions& o) { o.science.rows = 0; }, "science.rows = 0");
  ExpectInvalid([](ClosedLoopOptions& o) { o.science.cols = -1; }, "science.cols = -1");
  ExpectInvalid([](ClosedLoopOptions& o) { o.psf_every_steps = 0; }, "psf_every_steps = 0");
  ExpectInvalid([](ClosedLoopOptions& o) { o.start_time_s = -1.0; }, "start_time_s = -1");
  ExpectInvalid([](ClosedLoopOptions& o) { o.start_time_s = kInf; }, "start_time_s = inf");
  ExpectInvalid([](ClosedLoopOptions& o) { o.dm_gain = 0.4; }, "dm_gain = 0.4");
  ExpectInvalid([](ClosedLoopOptions& o) { o.dm_gain = kNaN; }, "dm_gain = nan");
  ExpectInvalid([](ClosedLoopOptions& o) { o.dm_gain = 2.5; }, "dm_gain = 2.5");
}

TEST(ClosedLoopErrorsTest, ConstructorArguments) {
  test::LoopSystem s = Small();
  const ClosedLoopOptions o;
  auto make = [&](const Image& a, double d, Atmosphere* atm, DeformableMirrorPtr dm, WavefrontSensor* wfs,
                  Controller* c, const ClosedLoopOptions& opt) { ClosedLoop(a, d, atm, dm, wfs, c, opt); };
  const std::string fn = "ClosedLoop: invalid ";
  EXPECT_THAT(
      ErrorOf([&] { make(Image::Ones(32, 16), kD, nullptr, s.dm, s.wfs.get(), s.controller.get(), o); }),
      HasSubstr(fn + "amplitude shape = 32x16"));
  EXPECT_THAT(ErrorOf([&] { make(-s.amplitude, kD, nullptr, s.dm, s.wfs.get(), s.controller.get(), o); }),
              HasSubstr(fn + "amplitude"));
  EXPECT_THAT(
      ErrorOf([&] { make(Image::Zero(32, 32), kD, nullptr, s.dm, s.wfs.get(), s.controller.get(), o); }),
      HasSubstr(fn + "amplitude = all zero"));
  EXPECT_THAT(ErrorOf([&] { make(s.amplitude, 0.0, nullptr, s.dm, s.wfs.get(), s.controller.get(), o); }),
              HasSubstr(fn + "diameter_m = 0"));
  EXPECT_THAT(ErrorOf([&] { make(s.amplitude, kD, nullptr, nullptr, s.wfs.get(), s.controller.get(), o); }),
              HasSubstr(fn + "dm = null"));
  EXPECT_THAT(ErrorOf([&] { make(s.amplitude, kD, nullptr, s.dm, nullptr, s.controller.get(), o); }),
              HasSubstr(fn + "wfs = null"));
  EXPECT_THAT(ErrorOf([&] { make(s.amplitude, kD, nullptr, s.dm, s.wfs.get(), nullptr, o); }),
              HasSubstr(fn + "controller = null"));
  // Mismatched grids, diameters and matrix sizes.
  test::LoopSystem big =
      test::MakePaperSystem(test::SensorKind::kGeometric, false, 1, ControllerOptions(), 64);
  EXPECT_THAT(ErrorOf([&] { make(s.amplitude, kD, nullptr, big.dm, s.wfs.get(), s.controller.get(), o); }),
              HasSubstr(fn + "dm pupil grid = 64"));
  EXPECT_THAT(ErrorOf([&] { make(s.amplitude, 7.0, nullptr, s.dm, s.wfs.get(), s.controller.get(), o); }),
              HasSubstr(fn + "dm diameter = 8"));
  EXPECT_THAT(ErrorOf([&] { make(s.amplitude, kD, nullptr, s.dm, big.wfs.get(), s.controller.get(), o); }),
              HasSubstr(fn + "wfs pupil grid = 64"));
  Atmosphere atmosphere(test::PaperAtmosphere(1), 64, kD);
  EXPECT_THAT(ErrorOf([&] { make(s.amplitude, kD, &atmosphere, s.dm, s.wfs.get(), s.controller.get(), o); }),
              HasSubstr(fn + "atmosphere pupil grid = 64"));
  Controller wrong(Eigen::MatrixXd::Identity(3, s.wfs->n_measurements()), Eigen::MatrixXd(),
                   ControllerOptions());
  EXPECT_THAT(ErrorOf([&] { make(s.amplitude, kD, nullptr, s.dm, s.wfs.get(), &wrong, o); }),
              HasSubstr(fn + "controller actuators = 3"));
  Controller wrong_meas(Eigen::MatrixXd::Identity(s.dm->n_active(), 5), Eigen::MatrixXd(),
                        ControllerOptions());
  EXPECT_THAT(ErrorOf([&] { make(s.amplitude, kD, nullptr, s.dm, s.wfs.get(), &wrong_meas, o); }),
              HasSubstr(fn + "controller measurements = 5"));
  // Static OPDs.
  ClosedLoopOptions bad = o;
  bad.common_static_opd_m = Image::Zero(16, 16);
  EXPECT_THAT(ErrorOf([&] { make(s.amplitude, kD, nullptr, s.dm, s.wfs.get(), s.controller.get(), bad); }),
              HasSubstr(fn + "options.common_static_opd_m shape = 16x16"));
  bad = o;
  bad.science_static_opd_m = Image::Zero(32, 32);
  bad.science_static_opd_m(16, 16) = kNaN;
  EXPECT_THAT(ErrorOf([&] { make(s.amplitude, kD, nullptr, s.dm, s.wfs.get(), s.controller.get(), bad); }),
              HasSubstr(fn + "options.science_static_opd_m = nan"));
  // A noisy sensor read at another rate than the loop's.
  ShackHartmannOptions so = test::PaperSensor(ShackHartmannMode::kDiffractive);
  so.noise.photon_noise = true;
  so.noise.frame_time_s = 1e-3;
  so.field_of_view_px = 0;  // p = 2 on this 32-pixel grid
  ShackHartmann noisy(s.amplitude, kD, so);
  EXPECT_THAT(ErrorOf([&] { make(s.amplitude, kD, nullptr, s.dm, &noisy, s.controller.get(), o); }),
              HasSubstr(fn + "wfs noise.frame_time_s = 0.001"));
}

TEST(ClosedLoopErrorsTest, RunArguments) {
  test::LoopSystem s = Small();
  ClosedLoopOptions o;
  o.compute_psf = false;
  ClosedLoop loop(s.amplitude, kD, nullptr, s.dm, s.wfs.get(), s.controller.get(), o);
  EXPECT_THAT(ErrorOf([&] { loop.Run(0.0); }), HasSubstr("ClosedLoop::Run: invalid duration_s = 0"));
  EXPECT_THAT(ErrorOf([&] { loop.Run(1e-5); }), HasSubstr("ClosedLoop::Run: invalid duration_s = 1e-05"));
  EXPECT_THAT(ErrorOf([&] { loop.Run(kNaN); }), HasSubstr("invalid duration_s = nan"));
  EXPECT_THAT(ErrorOf([&] { loop.Run(0.01, -1.0); }), HasSubstr("ClosedLoop::Run: invalid settling_s = -1"));
  const std::string fn = "ClosedLoop::RunSubExposures: invalid ";
  EXPECT_THAT(ErrorOf([&] { loop.RunSubExposures({}, 0.01, 0.0); }), HasSubstr(fn + "dm_offsets_m = empty"));
  const std::vector<Image> one = {Image::Zero(32, 32)};
  EXPECT_THAT(ErrorOf([&] { loop.RunSubExposures(one, 0.0, 0.0); }), HasSubstr(fn + "exposure_s = 0"));
  EXPECT_THAT(ErrorOf([&] { loop.RunSubExposures(one, 0.01, kInf); }), HasSubstr(fn + "settling_s = inf"));
  EXPECT_THAT(ErrorOf([&] {
                loop.RunSubExposures({Image::Zero(32, 32), Image::Zero(8, 8)}, 0.01, 0.0);
              }),
              HasSubstr(fn + "dm_offsets_m[1] shape = 8x8"));
  Image nan = Image::Zero(32, 32);
  nan(16, 16) = kNaN;
  EXPECT_THAT(ErrorOf([&] { loop.RunSubExposures({nan}, 0.01, 0.0); }), HasSubstr(fn + "dm_offsets_m[0]"));
  EXPECT_EQ(loop.frame(), 0);  // nothing ran
}

}  // namespace
}  // namespace aosr
