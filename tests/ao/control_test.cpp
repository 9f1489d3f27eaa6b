// Unit tests of control.hpp: the push-pull interaction matrix of the geometric SH equals the analytic product
// WFS o DM, the SVD control matrix (truncation, Tikhonov, report), the delay line and the control laws.
#include "aosr/ao/control.hpp"

#include <gtest/gtest.h>

#include <Eigen/LU>
#include <cmath>
#include <cstdio>
#include <memory>
#include <vector>

#include "aosr/ao/shack_hartmann.hpp"
#include "aosr/optics/deformable_mirror.hpp"
#include "aosr/optics/pupil.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

constexpr double kD = 8.0;

// The paper's geometry: 128-pixel 8 m pupil, 16 x 16 SH, 17 x 17 Fried DM of pitch 0.5 m.
struct PaperSystem {
  Image amplitude = CircularPupil(128, PupilGeometry{kD, 0.0});
  DeformableMirrorPtr dm;
  PaperSystem() {
    DeformableMirrorOptions o;
    o.actuators_across = 17;
    o.pitch_m = 0.5;
    dm = std::make_shared<const DeformableMirror>(128, PupilGeometry{kD, 0.0}, o);
  }
};

TEST(ControlTest, GeometricInteractionMatrixIsTheProductOfWfsAndDm) {
  PaperSystem sys;
  ShackHartmann sh(sys.amplitude, kD, ShackHartmannOptions());
  const Eigen::MatrixXd im = MeasureInteractionMatrix(*sys.dm, &sh);
  ASSERT_EQ(im.rows(), sh.n_measurements());
  ASSERT_EQ(im.cols(), sys.dm->n_active());
  // Analytic product: G applied to each actuator's influence function, evaluated from its closed form
  // exp(ln(c) r^2 / d^2) at every pixel centre (not through the mirror's separable Apply).
  const Eigen::Matrix2Xd pos = sys.dm->ActuatorPositions();
  const Index n = 128;
  const double dx = kD / n;
  Image influence(n, n);
  double worst = 0.0;
  for (Index j = 0; j < im.cols(); ++j) {
    for (Index i = 0; i < n; ++i) {
      for (Index k = 0; k < n; ++k) {
        influence(i, k) =
            sys.dm->Influence((k - 0.5 * (n - 1)) * dx - pos(0, j), (i - 0.5 * (n - 1)) * dx - pos(1, j));
      }
    }
    const Vector col = sh.geometric_operator()->Apply(AsVector(influence));
    worst = std::max(worst, (im.col(j) - col).cwiseAbs().maxCoeff() / col.cwiseAbs().maxCoeff());
  }
  std::printf("push-pull IM vs analytic G H: worst column relative error %.3g\n", worst);
  EXPECT_LT(worst, 1e-9);
}

TEST(ControlTest, ControlMatrixTruncationAndReport) {
  PaperSystem sys;
  ShackHartmann sh(sys.amplitude, kD, ShackHartmannOptions());
  const Eigen::MatrixXd im = MeasureInteractionMatrix(*sys.dm, &sh);
  ControlMatrixOptions o;  // default threshold
  const ControlMatrix cm = ComputeControlMatrix(im, o);
  std::printf("%s\n", cm.BriefReport().c_str());
  const Vector& s = cm.singular_values;
  std::printf("smallest singular values / s_1:");
  for (Index i = s.size() - 8; i < s.size(); ++i) std::printf(" %.2e", s[i] / s[0]);
  std::printf("\n");
  EXPECT_EQ(cm.matrix.rows(), sys.dm->n_active());
  EXPECT_EQ(cm.matrix.cols(), sh.n_measurements());
  EXPECT_EQ(cm.modes_kept + cm.modes_cut, std::min(im.rows(), im.cols()));
  // Piston and waffle are invisible to a Fried-geometry SH: at least two modes cut by the default threshold.
  EXPECT_GE(cm.modes_cut, 2);
  EXPECT_LT(cm.modes_cut, 20);
  EXPECT_NEAR(cm.condition_number, s[0] / s[cm.modes_kept - 1], 1e-9 * cm.condition_number);
  // M D is the projector onto the kept modes: idempotent, of trace modes_kept.
  const Eigen::MatrixXd p = cm.matrix * im;
  EXPECT_NEAR(p.trace(), cm.modes_kept, 1e-8);
  EXPECT_LT((p * p - p).norm(), 1e-8 * p.norm());
  // Cutting an exact number of modes.
  o.modes_to_cut = 10;
  const ControlMatrix cut10 = ComputeControlMatrix(im, o);
  EXPECT_EQ(cut10.modes_cut, 10);
  EXPECT_NEAR((cut10.matrix * im).trace(), static_cast<double>(cut10.modes_kept), 1e-8);
  // Tikhonov: filter s / (s^2 + alpha^2 s_1^2) on every mode.
  o.method = ControlMatrixOptions::Method::kTikhonov;
  o.tikhonov_alpha = 0.1;
  const ControlMatrix tik = ComputeControlMatrix(im, o);
  double expected_trace = 0.0;
  for (Index i = 0; i < s.size(); ++i) expected_trace += s[i] * s[i] / (s[i] * s[i] + 0.01 * s[0] * s[0]);
  EXPECT_NEAR((tik.matrix * im).trace(), expected_trace, 1e-8 * expected_trace);
}

TEST(ControlTest, ControlMatrixOfASmallKnownMatrix) {
  // D = diag(4, 2, 1e-3) padded to 4 x 3: threshold 0.01 keeps two modes.
  Eigen::MatrixXd d = Eigen::MatrixXd::Zero(4, 3);
  d(0, 0) = 4.0;
  d(1, 1) = 2.0;
  d(2, 2) = 1e-3;
  ControlMatrixOptions o;
  o.relative_threshold = 0.01;
  const ControlMatrix cm = ComputeControlMatrix(d, o);
  EXPECT_EQ(cm.modes_kept, 2);
  EXPECT_EQ(cm.modes_cut, 1);
  EXPECT_DOUBLE_EQ(cm.condition_number, 2.0);
  EXPECT_NEAR(cm.matrix(0, 0), 0.25, 1e-15);
  EXPECT_NEAR(cm.matrix(1, 1), 0.5, 1e-15);
  EXPECT_NEAR(cm.matrix(2, 2), 0.0, 1e-15);
  o.relative_threshold = 0.0;
  EXPECT_NEAR(ComputeControlMatrix(d, o).matrix(2, 2), 1000.0, 1e-9);
}

TEST(ControlTest, DelayLineDelaysByExactlyKPushes) {
  for (int k : {0, 1, 3}) {
    DelayLine line(2, k);
    for (int n = 0; n < 10; ++n) {
      Vector u(2);
      u << n + 1.0, -(n + 1.0);
      const Vector out = line.Push(u);
      const double expected = n - k >= 0 ? n - k + 1.0 : 0.0;
      EXPECT_EQ(out[0], expected) << "k = " << k << ", push " << n;
      EXPECT_EQ(out[1], -expected);
    }
  }
  DelayLine line(1, 2);
  line.Reset(Vector::Constant(1, 7.0));
  EXPECT_EQ(line.Push(Vector::Constant(1, 1.0))[0], 7.0);
  EXPECT_EQ(line.Push(Vector::Constant(1, 2.0))[0], 7.0);
  EXPECT_EQ(line.Push(Vector::Constant(1, 3.0))[0], 1.0);
}

TEST(ControlTest, IntegratorAndPseudoOpenLoopLaws) {
  // A 2-actuator, 3-measurement toy with an exact reconstructor (M D = I).
  Eigen::MatrixXd d(3, 2);
  d << 1.0, 0.5, -0.2, 2.0, 0.3, 0.1;
  const Eigen::MatrixXd dtd = d.transpose() * d;
  const Eigen::MatrixXd m = dtd.inverse() * d.transpose();
  ControllerOptions o;
  o.gain = 0.4;
  o.delay_frames = 0;
  Controller integrator(m, Eigen::MatrixXd(), o);
  o.law = ControlLaw::kPseudoOpenLoop;
  Controller pol(m, d, o);
  Vector meas(3);
  meas << 0.3, -0.1, 0.2;
  for (int n = 0; n < 5; ++n) {
    const Vector before = integrator.state();
    const Vector ci = integrator.Update(meas);
    const Vector cp = pol.Update(meas);
    EXPECT_LT((ci - (before - 0.4 * m * meas)).norm(), 1e-15);    // u <- u - g M m
    EXPECT_LT((ci - cp).norm(), 1e-14);                           // POL = integrator for k = 0, M D = I
    EXPECT_EQ((ci - integrator.applied_commands()).norm(), 0.0);  // k = 0: applied next frame
  }
  // With a delay the applied command lags the state by k updates; the leak shrinks the state.
  o.law = ControlLaw::kIntegrator;
  o.delay_frames = 2;
  o.leak = 0.1;
  Controller delayed(m, Eigen::MatrixXd(), o);
  std::vector<Vector> states;
  for (int n = 0; n < 6; ++n) {
    const Vector before = delayed.state();
    delayed.Update(meas);
    EXPECT_LT((delayed.state() - (0.9 * before - 0.4 * m * meas)).norm(), 1e-15);
    states.push_back(delayed.state());
    if (n >= 2) {
      EXPECT_EQ((delayed.applied_commands() - states[n - 2]).norm(), 0.0);
    } else {
      EXPECT_EQ(delayed.applied_commands().norm(), 0.0);
    }
  }
  delayed.Reset();
  EXPECT_EQ(delayed.state().norm() + delayed.applied_commands().norm(), 0.0);
  EXPECT_DOUBLE_EQ(delayed.frame_time_s(), 1.0 / 800.0);
}

TEST(ControlTest, GainStabilityLimits) {
  ControllerOptions o;
  o.delay_frames = 1;
  o.gain = 0.95;
  EXPECT_TRUE(o.IsValid(nullptr));
  o.gain = 1.05;
  EXPECT_FALSE(o.IsValid(nullptr));
  o.delay_frames = 0;
  o.gain = 1.9;
  EXPECT_TRUE(o.IsValid(nullptr));
  o.law = ControlLaw::kPseudoOpenLoop;
  o.delay_frames = 5;
  EXPECT_TRUE(o.IsValid(nullptr));  // POL: any delay for g < 2
}

}  // namespace
}  // namespace aosr
