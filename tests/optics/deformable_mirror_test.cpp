#include "aosr/core/image.hpp"  // kPi
#include "aosr/optics/deformable_mirror.hpp"

#include <gtest/gtest.h>

#include <Eigen/QR>
#include <chrono>
#include <cmath>
#include <iostream>
#include <memory>
#include <random>

#include "aosr/core/adjoint_test.hpp"
#include "aosr/optics/pupil.hpp"
#include "aosr/optics/zernike.hpp"

namespace aosr {
namespace {


// The 8 m telescope with 16 x 16 subapertures in Fried geometry: 17 x 17 actuators of pitch D/16 = 0.5 m,
// on a 128-pixel pupil (8 pixels per pitch).
DeformableMirrorOptions FriedOptions(double coupling = 0.15) {
  DeformableMirrorOptions o;
  o.actuators_across = 17;
  o.pitch_m = 0.5;
  o.coupling = coupling;
  return o;
}

std::shared_ptr<DeformableMirror> FriedMirror(double coupling = 0.15, double obstruction = 0.0) {
  return std::make_shared<DeformableMirror>(128, PupilGeometry{8.0, obstruction}, FriedOptions(coupling));
}

// RMS over the pupil (weights > 0) of an image, after removing its weighted mean when `remove_mean`.
double PupilRms(const Image& x, const Image& pupil, bool remove_mean) {
  const double w = pupil.sum();
  const double mean = remove_mean ? (pupil * x).sum() / w : 0.0;
  return std::sqrt((pupil * (x - mean).square()).sum() / w);
}

TEST(DeformableMirrorTest, InfluenceAtTheNeighbouringActuatorIsTheCoupling) {
  // Pixel centres on the actuator positions: odd n = 129, pixel 1/16 m, pitch 0.5 m = 8 pixels, so the
  // middle pixel (64, 64) is the middle actuator (8, 8).
  const double pixel = 1.0 / 16.0;
  for (double coupling : {0.1, 0.15, 0.3}) {
    DeformableMirrorOptions o = FriedOptions(coupling);
    const DeformableMirror dm(129, PupilGeometry{129 * pixel, 0.0}, o);
    EXPECT_NEAR(dm.Influence(0.5, 0.0), coupling, 1e-15);
    EXPECT_NEAR(dm.Influence(0.0, -0.5), coupling, 1e-15);
    Image grid = Image::Zero(17, 17);
    grid(8, 8) = 1.0;
    const Image opd = dm.Opd(dm.GridToCommands(grid));
    EXPECT_NEAR(opd(64, 64), 1.0, 1e-15);
    EXPECT_NEAR(opd(64, 72), coupling, 1e-15) << "next actuator along +x";
    EXPECT_NEAR(opd(56, 64), coupling, 1e-15) << "next actuator along -y";
    EXPECT_NEAR(opd(72, 72), coupling * coupling, 1e-15) << "diagonal neighbour: c^2";
    EXPECT_NEAR(opd(64, 80), std::pow(coupling, 4), 1e-15) << "two pitches: c^4";
  }
}

TEST(DeformableMirrorTest, SeparableProductEqualsTheSumOfGaussianInfluenceFunctions) {
  const auto dm = FriedMirror(0.2, 0.14);
  std::mt19937_64 rng(7);
  std::normal_distribution<double> normal;
  Vector c(dm->n_active());
  for (Index q = 0; q < c.size(); ++q) c[q] = 1e-7 * normal(rng);
  const Image opd = dm->Opd(c);
  const Eigen::Matrix2Xd pos = dm->ActuatorPositions();
  double worst = 0.0;
  for (Index i = 0; i < 128; i += 5) {
    for (Index k = 0; k < 128; k += 3) {
      const double y = (i - 63.5) / 16.0, x = (k - 63.5) / 16.0;
      double direct = 0.0;
      for (Index q = 0; q < c.size(); ++q) direct += c[q] * dm->Influence(x - pos(0, q), y - pos(1, q));
      worst = std::max(worst, std::abs(direct - opd(i, k)));
    }
  }
  EXPECT_LT(worst, 1e-20);  // commands ~1e-7 m: agreement to ~1e-13 relative
}

TEST(DeformableMirrorTest, ActiveActuatorsFollowThePupil) {
  const auto dm = FriedMirror();
  // Active: within 1/sqrt(2) pitch of the 4 m rim, i.e. r <= 8.7071 pitches.
  int expected = 0;
  for (int a = 0; a < 17; ++a) {
    for (int b = 0; b < 17; ++b) expected += std::hypot(a - 8.0, b - 8.0) <= 8.0 + std::sqrt(0.5) ? 1 : 0;
  }
  EXPECT_EQ(dm->n_active(), expected);
  EXPECT_EQ(dm->n_active(), 241);
  std::cout << "17x17 Fried DM on an 8 m pupil: " << dm->n_active() << " active actuators\n";
  const Image& m = dm->ActiveMask();
  EXPECT_TRUE((m == m.colwise().reverse()).all());
  EXPECT_TRUE((m == m.rowwise().reverse()).all());
  EXPECT_TRUE((m == m.transpose()).all());
  EXPECT_EQ(m(0, 0), 0.0);  // grid corner at r = 11.3 pitches: no light
  EXPECT_EQ(m(8, 0), 1.0);  // on the rim
  // A central obstruction of 0.3 (R_obs = 1.2 m = 2.4 pitches) drops the actuators deeper than 1/sqrt(2)
  // pitch behind it: r < 1.69 pitches, i.e. the centre, its 4 neighbours and 4 diagonals.
  const auto obstructed = FriedMirror(0.15, 0.3);
  EXPECT_EQ(obstructed->n_active(), expected - 9);
  EXPECT_EQ(obstructed->ActiveMask()(8, 8), 0.0);
  // Round trip of the command <-> grid maps.
  Vector c = Vector::LinSpaced(dm->n_active(), 1.0, 2.0);
  EXPECT_EQ((dm->GridToCommands(dm->CommandsToGrid(c)) - c).norm(), 0.0);
}

TEST(DeformableMirrorTest, AdjointIsExact) {
  for (double obstruction : {0.0, 0.3}) {
    const auto dm = FriedMirror(0.15, obstruction);
    const AdjointTestResult r = AdjointTest(*dm, 3);
    EXPECT_LT(r.adjoint_error, 1e-10) << "obstruction " << obstruction;
    EXPECT_LT(r.normal_error, 1e-10);
  }
  // A non-Fried geometry: 10 x 10 actuators of 0.9 m on a 96-pixel 8 m pupil.
  DeformableMirrorOptions o;
  o.actuators_across = 10;
  o.pitch_m = 0.9;
  const DeformableMirror dm(96, PupilGeometry{8.0, 0.1}, o);
  EXPECT_LT(AdjointTest(dm, 5).worst(), 1e-10);
}

TEST(DeformableMirrorTest, ClipReportsCountAndRmsOfTheRemovedPart) {
  const auto dm = FriedMirror();
  const double s = dm->options().stroke_m;
  Vector c = Vector::Zero(dm->n_active());
  c[0] = 1.5 * s;   // removes 0.5 s
  c[1] = -3.0 * s;  // removes 2 s
  c[2] = 0.99 * s;  // kept
  c[3] = -s;        // exactly at the stroke: kept
  const ClipSummary summary = dm->Clip(&c);
  EXPECT_EQ(summary.clipped, 2);
  EXPECT_NEAR(summary.clipped_rms_m, s * std::sqrt((0.25 + 4.0) / dm->n_active()), 1e-20);
  EXPECT_NEAR(summary.max_excess_m, 2.0 * s, 1e-20);
  EXPECT_EQ(c[0], s);
  EXPECT_EQ(c[1], -s);
  EXPECT_EQ(c[2], 0.99 * s);
  EXPECT_EQ(c[3], -s);
  const ClipSummary none = dm->Clip(&c);
  EXPECT_EQ(none.clipped, 0);
  EXPECT_EQ(none.clipped_rms_m, 0.0);
}

// Fitting smooth modes. A lattice of Gaussians cannot reproduce even a constant exactly: by Poisson
// summation, sum_k g(x - k d) = const * (1 + 2 sum_m G(m/d) cos(2 pi m x / d)) with G(1/d)/G(0) = exp(-pi^2 /
// ln(1/c)), so a constant (and locally any smooth mode) carries a ripple of RMS ~ 2 exp(-pi^2 / ln(1/c)) (two
// axes) that no choice of commands removes: 2.8% for c = 0.1, 1.1% for c = 0.15, 0.16% for c = 0.25, 0.055%
// for c = 0.3. Measured residual RMS / mode RMS over the whole pupil (n = 128, D = 8 m, d = 0.5 m, default
// regularisation):
//   * one ring of actuators beyond the rim (19 x 19, active_margin_pitch 1.5, 293 actuators): the fit sits on
//   the
//     floor: Z2/Z3 1.00 - 1.12 x floor, Z4 1.09 - 1.63 x floor; e.g. c = 0.3: 0.062% (tilt), 0.090%
//     (defocus);
//   * the bare Fried grid (17 x 17, default margin, 241 actuators) ends at the rim along the axes, and the
//   rim
//     dominates: 1.0 - 1.9% for every coupling >= 0.15 (1.27% tilt, 1.73% defocus at c = 0.15).
// So "<< 1%" needs both a stiff-enough coupling (>= 0.25) and actuators beyond the rim; the test checks both
// regimes against these figures.
TEST(DeformableMirrorTest, FitsTipTiltAndDefocusToTheLatticeRippleFloor) {
  const Image pupil = CircularPupil(128, PupilGeometry{8.0, 0.0});
  for (double coupling : {0.1, 0.15, 0.2, 0.25, 0.3}) {
    const double floor = 2.0 * std::exp(-kPi * kPi / std::log(1.0 / coupling));
    DeformableMirrorOptions extended = FriedOptions(coupling);
    extended.actuators_across = 19;
    extended.active_margin_pitch = 1.5;
    const auto dm = std::make_shared<DeformableMirror>(128, PupilGeometry{8.0, 0.0}, extended);
    const DmFitter fitter(dm, pupil);
    const DmFitter fried(FriedMirror(coupling), pupil);
    for (int j : {2, 3, 4}) {
      const Image target = 1e-6 * Zernike(j, 128);  // 1 um RMS of wavefront OPD
      const double rms = PupilRms(target, pupil, true);
      const double rel = PupilRms(fitter.Residual(target), pupil, true) / rms;
      const double rel_fried = PupilRms(fried.Residual(target), pupil, true) / rms;
      std::cout << "coupling " << coupling << " Z" << j << ": residual " << 100 * rel
                << "% RMS (ripple floor " << 100 * floor << "%); bare Fried 17x17: " << 100 * rel_fried
                << "%\n";
      EXPECT_LT(rel, 2.0 * floor) << "coupling " << coupling << ", Z" << j;
      EXPECT_GT(rel, 0.9 * floor) << "coupling " << coupling << ", Z" << j;
      if (coupling >= 0.25) {
        EXPECT_LT(rel, 2.5e-3) << "coupling " << coupling << ", Z" << j;
      }
      if (coupling >= 0.15) {
        EXPECT_LT(rel_fried, 0.025) << "coupling " << coupling << ", Z" << j;
      }
    }
  }
}

// The separable assembly of the normal matrix against a dense solve: H built column by column from Apply,
// minimise |sqrt(A) (H c - w)|^2 + mu |c|^2 with Eigen's QR on the stacked system [sqrt(A) H; sqrt(mu) I].
TEST(DeformableMirrorTest, FitterMatchesADenseRegularisedLeastSquaresSolve) {
  DeformableMirrorOptions o;
  o.actuators_across = 9;
  o.pitch_m = 1.0;
  o.coupling = 0.2;
  const auto dm = std::make_shared<DeformableMirror>(40, PupilGeometry{8.0, 0.25}, o);
  const Image pupil = CircularPupil(40, PupilGeometry{8.0, 0.25}, 4);  // grey weights
  std::mt19937_64 rng(5);
  std::normal_distribution<double> normal;
  Image target(40, 40);
  for (Index p = 0; p < target.size(); ++p) target.data()[p] = normal(rng);
  for (double reg : {0.0, 1e-3, 0.1}) {
    DmFitOptions options;
    options.regularisation = reg;
    const DmFitter fitter(dm, pupil, options);
    const Index na = dm->n_active(), np = 40 * 40;
    Eigen::MatrixXd h(np, na);
    for (Index q = 0; q < na; ++q) h.col(q) = dm->Apply(Vector::Unit(na, q));
    const Vector sqrt_a = AsVector(pupil).cwiseSqrt();
    Eigen::MatrixXd stacked(np + na, na);
    stacked.topRows(np) = sqrt_a.asDiagonal() * h;
    stacked.bottomRows(na) = std::sqrt(fitter.mu()) * Eigen::MatrixXd::Identity(na, na);
    Vector rhs = Vector::Zero(np + na);
    rhs.head(np) = sqrt_a.cwiseProduct(AsVector(target));
    const Vector dense = stacked.colPivHouseholderQr().solve(rhs);
    const Vector fast = fitter.Fit(target);
    EXPECT_LT((fast - dense).norm(), 1e-8 * dense.norm()) << "regularisation " << reg;
    // mu is regularisation x the mean diagonal of H^T A H.
    const double mean_diag =
        (h.transpose() * pupil.matrix().reshaped<Eigen::RowMajor>().asDiagonal() * h).diagonal().mean();
    EXPECT_NEAR(fitter.mu(), reg * mean_diag, 1e-12 * mean_diag) << "regularisation " << reg;
  }
}

TEST(DeformableMirrorTest, RegularisationDampsUnlitActuatorsOnly) {
  const Image pupil = CircularPupil(128, PupilGeometry{8.0, 0.0});
  const auto dm = FriedMirror();
  const Image target = 1e-6 * Zernike(4, 128);
  DmFitOptions plain;
  plain.regularisation = 0.0;
  const Vector c0 = DmFitter(dm, pupil, plain).Fit(target);
  const Vector c1 = DmFitter(dm, pupil).Fit(target);
  DmFitOptions heavy;
  heavy.regularisation = 1.0;
  const Vector c2 = DmFitter(dm, pupil, heavy).Fit(target);
  EXPECT_LT(c1.norm(), c0.norm() * (1.0 + 1e-12));
  EXPECT_LT(c2.norm(), 0.7 * c0.norm());
  // The default weight changes the fit itself very little.
  const double r0 = PupilRms(target - dm->Opd(c0), pupil, true);
  const double r1 = PupilRms(target - dm->Opd(c1), pupil, true);
  std::cout << "defocus residual: plain LS " << r0 << " m, default Tikhonov " << r1 << " m\n";
  EXPECT_LT(r1, 1.2 * r0 + 1e-10);
}

// Apply is called every closed-loop iteration: 17 x 17 actuators onto a 128-pixel pupil. Measured ~0.03 ms
// for Apply and ~0.03 ms for ApplyAdjoint on one core (Release), printed here for the record and measured by
// bench/closed_loop_bench; tests never assert wall time. What is asserted: repeated calls stay finite and
// the fitter returns one command per active actuator.
TEST(DeformableMirrorTest, RepeatedApplyStaysFiniteAndTheFitterRuns) {
  const auto dm = FriedMirror();
  Vector c = Vector::Random(dm->n_active());
  Vector y(dm->rows()), x(dm->cols());
  const int reps = 2000;
  auto t0 = std::chrono::steady_clock::now();
  for (int r = 0; r < reps; ++r) {
    c[r % c.size()] += 1e-9;
    dm->Apply(c, y);
  }
  auto t1 = std::chrono::steady_clock::now();
  for (int r = 0; r < reps; ++r) {
    y[r % y.size()] += 1e-9;
    dm->ApplyAdjoint(y, x);
  }
  auto t2 = std::chrono::steady_clock::now();
  const double apply_ms = std::chrono::duration<double, std::milli>(t1 - t0).count() / reps;
  const double adjoint_ms = std::chrono::duration<double, std::milli>(t2 - t1).count() / reps;
  std::cout << "DM 17x17 -> 128x128: Apply " << apply_ms << " ms, ApplyAdjoint " << adjoint_ms << " ms\n";
  EXPECT_TRUE(y.allFinite());
  EXPECT_TRUE(x.allFinite());
  // Fitter set-up and one fit, for the record.
  const Image pupil = CircularPupil(128, PupilGeometry{8.0, 0.0});
  const Image target = Zernike(5, 128);
  auto t3 = std::chrono::steady_clock::now();
  const DmFitter fitter(dm, pupil);
  auto t4 = std::chrono::steady_clock::now();
  const Vector fit = fitter.Fit(target);
  auto t5 = std::chrono::steady_clock::now();
  std::cout << "DmFitter set-up " << std::chrono::duration<double, std::milli>(t4 - t3).count() << " ms, Fit "
            << std::chrono::duration<double, std::milli>(t5 - t4).count() << " ms\n";
  EXPECT_EQ(fit.size(), dm->n_active());
}

}  // namespace
}  // namespace aosr
