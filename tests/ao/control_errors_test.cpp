// Bad input at every public entry point of control.hpp throws aosr::InvalidArgument naming the function and
// the field or argument.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <functional>
#include <limits>
#include <memory>
#include <string>

#include "aosr/ao/control.hpp"
#include "aosr/ao/shack_hartmann.hpp"
#include "aosr/core/error.hpp"
#include "aosr/optics/pupil.hpp"
#include "support/testing.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

using ::aosr::test::ErrorOf;
using ::testing::HasSubstr;

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kInf = std::numeric_limits<double>::infinity();

DeformableMirrorPtr SmallDm(Index n = 32) {
  DeformableMirrorOptions o;
  o.actuators_across = 5;
  o.pitch_m = 2.0;
  return std::make_shared<const DeformableMirror>(n, PupilGeometry{8.0, 0.0}, o);
}

TEST(ControlErrorsTest, InteractionMatrixArguments) {
  const auto dm = SmallDm();
  ShackHartmannOptions so;
  so.subapertures_across = 4;
  ShackHartmann sh(CircularPupil(32, PupilGeometry{8.0, 0.0}), 8.0, so);
  InteractionMatrixOptions o;
  EXPECT_TRUE(o.IsValid(nullptr));
  o.poke_amplitude_m = 0.0;
  std::string why;
  EXPECT_FALSE(o.IsValid(&why));
  EXPECT_THAT(why, HasSubstr("poke_amplitude_m = 0"));
  EXPECT_THAT(ErrorOf([&] { MeasureInteractionMatrix(*dm, &sh, o); }),
              HasSubstr("MeasureInteractionMatrix: invalid options.poke_amplitude_m = 0"));
  o.poke_amplitude_m = kNaN;
  EXPECT_THAT(ErrorOf([&] { MeasureInteractionMatrix(*dm, &sh, o); }), HasSubstr("poke_amplitude_m = nan"));
  EXPECT_THAT(ErrorOf([&] { MeasureInteractionMatrix(*dm, nullptr); }),
              HasSubstr("MeasureInteractionMatrix: invalid wfs = null"));
  ShackHartmann other(CircularPupil(64, PupilGeometry{8.0, 0.0}), 8.0, so);
  EXPECT_THAT(ErrorOf([&] { MeasureInteractionMatrix(*dm, &other); }),
              HasSubstr("invalid wfs pupil grid = 64"));
}

void ExpectInvalidCm(const std::function<void(ControlMatrixOptions&)>& mutate, const std::string& field) {
  ControlMatrixOptions o;
  mutate(o);
  std::string why;
  EXPECT_FALSE(o.IsValid(&why)) << field;
  EXPECT_THAT(why, HasSubstr(field));
  EXPECT_THAT(ErrorOf([&] { ComputeControlMatrix(Eigen::MatrixXd::Identity(3, 3), o); }),
              HasSubstr("ComputeControlMatrix: invalid options." + field));
}

TEST(ControlErrorsTest, ControlMatrixArguments) {
  ExpectInvalidCm([](ControlMatrixOptions& o) { o.method = static_cast<ControlMatrixOptions::Method>(4); },
                  "method = 4");
  ExpectInvalidCm([](ControlMatrixOptions& o) { o.relative_threshold = 1.0; }, "relative_threshold = 1");
  ExpectInvalidCm([](ControlMatrixOptions& o) { o.relative_threshold = -0.1; }, "relative_threshold = -0.1");
  ExpectInvalidCm([](ControlMatrixOptions& o) { o.modes_to_cut = -2; }, "modes_to_cut = -2");
  ExpectInvalidCm([](ControlMatrixOptions& o) { o.tikhonov_alpha = kInf; }, "tikhonov_alpha = inf");
  EXPECT_THAT(ErrorOf([&] { ComputeControlMatrix(Eigen::MatrixXd()); }),
              HasSubstr("ComputeControlMatrix: invalid interaction_matrix = empty"));
  Eigen::MatrixXd bad = Eigen::MatrixXd::Identity(3, 3);
  bad(1, 2) = kNaN;
  EXPECT_THAT(ErrorOf([&] { ComputeControlMatrix(bad); }),
              HasSubstr("invalid interaction_matrix = non-finite"));
  EXPECT_THAT(ErrorOf([&] { ComputeControlMatrix(Eigen::MatrixXd::Zero(3, 2)); }),
              HasSubstr("invalid interaction_matrix = all zero"));
  ControlMatrixOptions o;
  o.modes_to_cut = 3;
  EXPECT_THAT(ErrorOf([&] { ComputeControlMatrix(Eigen::MatrixXd::Identity(4, 3), o); }),
              HasSubstr("invalid options.modes_to_cut = 3"));
}

void ExpectInvalidController(const std::function<void(ControllerOptions&)>& mutate,
                             const std::string& field) {
  ControllerOptions o;
  mutate(o);
  std::string why;
  EXPECT_FALSE(o.IsValid(&why)) << field;
  EXPECT_THAT(why, HasSubstr(field));
  EXPECT_THAT(
      ErrorOf([&] { Controller(Eigen::MatrixXd::Identity(2, 3), Eigen::MatrixXd::Identity(3, 2), o); }),
      HasSubstr("Controller: invalid options." + field));
}

TEST(ControlErrorsTest, ControllerArguments) {
  ExpectInvalidController([](ControllerOptions& o) { o.loop_rate_hz = 0.0; }, "loop_rate_hz = 0");
  ExpectInvalidController([](ControllerOptions& o) { o.loop_rate_hz = kInf; }, "loop_rate_hz = inf");
  ExpectInvalidController([](ControllerOptions& o) { o.delay_frames = -1; }, "delay_frames = -1");
  ExpectInvalidController([](ControllerOptions& o) { o.delay_frames = 101; }, "delay_frames = 101");
  ExpectInvalidController([](ControllerOptions& o) { o.law = static_cast<ControlLaw>(3); }, "law = 3");
  ExpectInvalidController([](ControllerOptions& o) { o.leak = 1.0; }, "leak = 1");
  ExpectInvalidController([](ControllerOptions& o) { o.gain = -0.1; }, "gain = -0.1");
  ExpectInvalidController([](ControllerOptions& o) { o.gain = kNaN; }, "gain = nan");
  ExpectInvalidController([](ControllerOptions& o) { o.gain = 1.2; }, "gain = 1.2");  // unstable for k = 1
  ExpectInvalidController(
      [](ControllerOptions& o) {
        o.law = ControlLaw::kPseudoOpenLoop;
        o.gain = 2.0;
      },
      "gain = 2");
  const ControllerOptions ok;
  EXPECT_THAT(ErrorOf([&] { Controller(Eigen::MatrixXd(), Eigen::MatrixXd(), ok); }),
              HasSubstr("Controller: invalid control_matrix = empty"));
  Eigen::MatrixXd nan = Eigen::MatrixXd::Identity(2, 3);
  nan(0, 0) = kNaN;
  EXPECT_THAT(ErrorOf([&] { Controller(nan, Eigen::MatrixXd(), ok); }),
              HasSubstr("Controller: invalid control_matrix = non-finite"));
  ControllerOptions pol;
  pol.law = ControlLaw::kPseudoOpenLoop;
  EXPECT_THAT(
      ErrorOf([&] { Controller(Eigen::MatrixXd::Identity(2, 3), Eigen::MatrixXd::Identity(2, 2), pol); }),
      HasSubstr("Controller: invalid interaction_matrix shape = 2x2"));
  Eigen::MatrixXd im_nan = Eigen::MatrixXd::Identity(3, 2);
  im_nan(2, 1) = kInf;
  EXPECT_THAT(ErrorOf([&] { Controller(Eigen::MatrixXd::Identity(2, 3), im_nan, pol); }),
              HasSubstr("invalid interaction_matrix = non-finite"));

  Controller c(Eigen::MatrixXd::Identity(2, 3), Eigen::MatrixXd(), ok);
  EXPECT_THAT(ErrorOf([&] { c.Update(Vector::Zero(2)); }),
              HasSubstr("Controller::Update: invalid measurement size = 2"));
  Vector m = Vector::Zero(3);
  m[0] = kNaN;
  EXPECT_THAT(ErrorOf([&] { c.Update(m); }),
              HasSubstr("Controller::Update: invalid measurement = non-finite"));
  EXPECT_THAT(ErrorOf([&] { c.Reset(Vector::Zero(5)); }),
              HasSubstr("Controller::Reset: invalid commands size = 5"));
  Vector r = Vector::Zero(2);
  r[1] = kInf;
  EXPECT_THAT(ErrorOf([&] { c.Reset(r); }), HasSubstr("Controller::Reset: invalid commands = non-finite"));
  EXPECT_THAT(ErrorOf([&] { c.OverrideApplied(Vector::Zero(1)); }),
              HasSubstr("Controller::OverrideApplied: invalid commands size = 1"));
}

TEST(ControlErrorsTest, DelayLineArguments) {
  EXPECT_THAT(ErrorOf([] { DelayLine(-1, 1); }), HasSubstr("DelayLine: invalid size = -1"));
  EXPECT_THAT(ErrorOf([] { DelayLine(3, -2); }), HasSubstr("DelayLine: invalid delay = -2"));
  DelayLine line(3, 1);
  EXPECT_THAT(ErrorOf([&] { line.Push(Vector::Zero(2)); }), HasSubstr("DelayLine::Push: invalid u size = 2"));
  EXPECT_THAT(ErrorOf([&] { line.Reset(Vector::Zero(4)); }),
              HasSubstr("DelayLine::Reset: invalid value size = 4"));
}

}  // namespace
}  // namespace aosr
