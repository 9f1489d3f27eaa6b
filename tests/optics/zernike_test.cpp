#include "aosr/core/image.hpp"  // kPi
#include "aosr/optics/zernike.hpp"

#include <gtest/gtest.h>

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <iostream>
#include <random>
#include <vector>

#include "aosr/optics/pupil.hpp"

namespace aosr {
namespace {


// Noll (1976), Table 1: (n, m) of Z_1 .. Z_22, with m < 0 for the sin modes.
TEST(ZernikeTest, NollTableMatchesNoll1976) {
  const std::vector<ZernikeNM> table = {
      {0, 0}, {1, 1},  {1, -1}, {2, 0},  {2, -2}, {2, 2},  {3, -1}, {3, 1},  {3, -3}, {3, 3},  {4, 0},
      {4, 2}, {4, -2}, {4, 4},  {4, -4}, {5, 1},  {5, -1}, {5, 3},  {5, -3}, {5, 5},  {5, -5}, {6, 0},
  };
  for (int j = 1; j <= 22; ++j) {
    const ZernikeNM nm = NollToNM(j);
    EXPECT_EQ(nm.n, table[j - 1].n) << "j = " << j;
    EXPECT_EQ(nm.m, table[j - 1].m) << "j = " << j;
  }
}

TEST(ZernikeTest, NollIndexingIsABijection) {
  int expected_j = 1;
  for (int n = 0; n <= 60; ++n) {
    std::vector<bool> seen(n + 1, false);
    for (int k = 0; k <= n; ++k, ++expected_j) {
      const ZernikeNM nm = NollToNM(expected_j);
      ASSERT_EQ(nm.n, n) << "j = " << expected_j;
      ASSERT_EQ(NMToNoll(nm.n, nm.m), expected_j);
      // Even j carries cos (m > 0), odd j sin (m < 0); |m| is non-decreasing within an order.
      if (nm.m != 0) {
        EXPECT_EQ(nm.m > 0, expected_j % 2 == 0) << "j = " << expected_j;
      }
    }
  }
}

// Closed forms from Noll (1976) Table 1.
TEST(ZernikeTest, LowOrdersMatchClosedForms) {
  std::mt19937_64 rng(2024);
  std::uniform_real_distribution<double> ur(0.0, 1.0), ut(-kPi, kPi);
  for (int trial = 0; trial < 200; ++trial) {
    const double r = ur(rng), t = ut(rng);
    const double r2 = r * r, r3 = r2 * r, r4 = r2 * r2, r6 = r4 * r2;
    const std::vector<std::pair<int, double>> forms = {
        {1, 1.0},
        {2, 2.0 * r * std::cos(t)},
        {3, 2.0 * r * std::sin(t)},
        {4, std::sqrt(3.0) * (2.0 * r2 - 1.0)},
        {5, std::sqrt(6.0) * r2 * std::sin(2 * t)},
        {6, std::sqrt(6.0) * r2 * std::cos(2 * t)},
        {7, std::sqrt(8.0) * (3.0 * r3 - 2.0 * r) * std::sin(t)},
        {8, std::sqrt(8.0) * (3.0 * r3 - 2.0 * r) * std::cos(t)},
        {9, std::sqrt(8.0) * r3 * std::sin(3 * t)},
        {10, std::sqrt(8.0) * r3 * std::cos(3 * t)},
        {11, std::sqrt(5.0) * (6.0 * r4 - 6.0 * r2 + 1.0)},
        {12, std::sqrt(10.0) * (4.0 * r4 - 3.0 * r2) * std::cos(2 * t)},
        {13, std::sqrt(10.0) * (4.0 * r4 - 3.0 * r2) * std::sin(2 * t)},
        {14, std::sqrt(10.0) * r4 * std::cos(4 * t)},
        {15, std::sqrt(10.0) * r4 * std::sin(4 * t)},
        {16, std::sqrt(12.0) * (10.0 * r4 * r - 12.0 * r3 + 3.0 * r) * std::cos(t)},
        {22, std::sqrt(7.0) * (20.0 * r6 - 30.0 * r4 + 12.0 * r2 - 1.0)},
    };
    for (const auto& [j, value] : forms) {
      EXPECT_NEAR(ZernikeValue(j, r, t), value, 1e-13) << "j = " << j << " rho = " << r << " theta = " << t;
    }
  }
}

// The explicit factorial sum in long double (64-bit mantissa) is trustworthy to ~1e-12 for n <= 24; the
// recurrence must agree with it there.
long double FactorialRadial(int n, int m, long double rho) {
  auto fact = [](int k) {
    long double f = 1;
    for (int i = 2; i <= k; ++i) f *= i;
    return f;
  };
  long double sum = 0;
  for (int k = 0; k <= (n - m) / 2; ++k) {
    const long double c = fact(n - k) / (fact(k) * fact((n + m) / 2 - k) * fact((n - m) / 2 - k));
    sum += ((k % 2) ? -c : c) * std::pow(rho, static_cast<long double>(n - 2 * k));
  }
  return sum;
}

TEST(ZernikeTest, RecurrenceMatchesFactorialSumUpToOrder24) {
  for (int n = 0; n <= 24; ++n) {
    for (int m = n % 2; m <= n; m += 2) {
      for (int i = 0; i <= 50; ++i) {
        const double rho = i / 50.0;
        EXPECT_NEAR(ZernikeRadial(n, m, rho), static_cast<double>(FactorialRadial(n, m, rho)), 1e-11)
            << "n = " << n << " m = " << m << " rho = " << rho;
      }
    }
  }
}

// Where factorial sums have lost every digit (n ~ 50 and beyond) the recurrence keeps R_n^m(1) = 1 and
// |R_n^m| <= 1 on the disk.
TEST(ZernikeTest, HighOrderRadialPolynomialsStayBounded) {
  for (int n : {40, 80, 150, 200}) {
    for (int m = n % 2; m <= n; m += 2) {
      EXPECT_NEAR(ZernikeRadial(n, m, 1.0), 1.0, 1e-11) << "n = " << n << " m = " << m;
      for (int i = 0; i < 1000; ++i) {
        const double r = ZernikeRadial(n, m, i / 1000.0);
        ASSERT_LE(std::abs(r), 1.0 + 1e-11) << "n = " << n << " m = " << m << " rho = " << i / 1000.0;
      }
    }
  }
  // R_n^0(0) = (-1)^(n/2).
  EXPECT_NEAR(ZernikeRadial(200, 0, 0.0), 1.0, 1e-12);
  EXPECT_NEAR(ZernikeRadial(198, 0, 0.0), -1.0, 1e-12);
}

// Gauss-Legendre nodes and weights on [0, 1] (Newton on P_N, textbook initial guesses).
void GaussLegendre01(int N, std::vector<double>* x, std::vector<double>* w) {
  x->resize(N);
  w->resize(N);
  for (int i = 0; i < N; ++i) {
    double z = std::cos(kPi * (i + 0.75) / (N + 0.5)), dp = 0.0;
    for (int it = 0; it < 100; ++it) {
      double p0 = 1.0, p1 = z;
      for (int k = 2; k <= N; ++k) {
        const double p2 = ((2 * k - 1) * z * p1 - (k - 1) * p0) / k;
        p0 = p1;
        p1 = p2;
      }
      dp = N * (z * p1 - p0) / (z * z - 1.0);
      const double dz = p1 / dp;
      z -= dz;
      if (std::abs(dz) < 1e-16) break;
    }
    (*x)[i] = 0.5 * (1.0 - z);
    (*w)[i] = 1.0 / ((1.0 - z * z) * dp * dp);  // = (2 / ((1-z^2) P'^2)) / 2 for [0, 1]
  }
}

// Orthonormality of Z_1..Z_200 (n <= 19) by a quadrature that is exact for these integrands: Gauss-Legendre
// with 24 nodes in rho (integrand rho * R R is a polynomial of degree <= 39 < 48) and the trapezoid rule with
// 64 points in theta (exact for harmonics below 64; here |m1| + |m2| <= 38). Any deviation is an error in the
// polynomials themselves, not discretisation: tolerance 1e-12.
TEST(ZernikeTest, Modes1To200AreOrthonormalByExactQuadrature) {
  const int J = 200, n_rho = 24, n_theta = 64;
  std::vector<double> xr, wr;
  GaussLegendre01(n_rho, &xr, &wr);
  Eigen::MatrixXd values(n_rho * n_theta, J);
  Eigen::VectorXd weights(n_rho * n_theta);
  for (int a = 0; a < n_rho; ++a) {
    for (int b = 0; b < n_theta; ++b) {
      const int row = a * n_theta + b;
      const double theta = 2.0 * kPi * b / n_theta;
      // (1/pi) integral f rho drho dtheta  ->  sum f * rho * w_rho * (2 pi / n_theta) / pi.
      weights(row) = xr[a] * wr[a] * 2.0 / n_theta;
      for (int j = 1; j <= J; ++j) values(row, j - 1) = ZernikeValue(j, xr[a], theta);
    }
  }
  const Eigen::MatrixXd gram = values.transpose() * weights.asDiagonal() * values;
  const double err = (gram - Eigen::MatrixXd::Identity(J, J)).cwiseAbs().maxCoeff();
  EXPECT_LT(err, 1e-12);
}

// Radial orthogonality (1/pi) integral Z Z' = delta  <=>  2(n+1) integral_0^1 R_n^m R_n'^m rho drho =
// delta_nn', far beyond the orders that factorial sums can reach: the integrand has degree <= 2 n_max + 1 =
// 241 and Gauss-Legendre with 122 nodes is exact up to degree 243. Measured worst error 6e-14.
TEST(ZernikeTest, RadialPolynomialsAreOrthogonalUpToOrder120) {
  const int n_max = 120, nodes = 122;
  std::vector<double> x, w;
  GaussLegendre01(nodes, &x, &w);
  double worst = 0.0;
  for (int m = 0; m <= n_max; m += 7) {
    for (int n1 = m; n1 <= n_max; n1 += 2) {
      for (int n2 = n1; n2 <= n_max; n2 += 2) {
        double s = 0.0;
        for (int a = 0; a < nodes; ++a)
          s += w[a] * x[a] * ZernikeRadial(n1, m, x[a]) * ZernikeRadial(n2, m, x[a]);
        worst = std::max(worst, std::abs(2.0 * (n1 + 1) * s - (n1 == n2 ? 1.0 : 0.0)));
      }
    }
  }
  EXPECT_LT(worst, 1e-12);
}

// Max |G - I| of the Gram matrix of Z_1..Z_J sampled on the n x n pupil grid, with the disk measure
// replaced by the pixel count inside the pupil.
double GridGramError(int J, Index n) {
  const ImageStack basis = ZernikeBasis(J, n);
  const Image pupil = CircularPupil(n, PupilGeometry{1.0, 0.0});
  std::vector<Index> inside;
  for (Index p = 0; p < pupil.size(); ++p)
    if (pupil.data()[p] > 0) inside.push_back(p);
  Eigen::MatrixXd m(inside.size(), J);
  for (int j = 0; j < J; ++j)
    for (std::size_t r = 0; r < inside.size(); ++r) m(r, j) = basis[j].data()[inside[r]];
  Eigen::MatrixXd gram = Eigen::MatrixXd::Zero(J, J);
  gram.selfadjointView<Eigen::Lower>().rankUpdate(m.transpose(), 1.0 / inside.size());
  gram = gram.selfadjointView<Eigen::Lower>();
  return (gram - Eigen::MatrixXd::Identity(J, J)).cwiseAbs().maxCoeff();
}

// The same orthonormality on the pixel grid, where only discretisation separates the Gram matrix from the
// identity: the jagged pixel boundary of the disk (whose count error relative to pi R^2 fluctuates like
// R^(-4/3)) weighted by the large rim values of high orders (Z^2 ~ 2(n+1) = 40 at n = 19), plus the midpoint
// rule on modes with ~n/2 radial oscillations. The measured error must be small and must fall with
// refinement.
TEST(ZernikeTest, Modes1To200AreOrthonormalOnTheFinePixelGrid) {
  const double err256 = GridGramError(200, 256);
  const double err512 = GridGramError(200, 512);
  std::cout << "max |G - I| for Z1..Z200: 256 px " << err256 << ", 512 px " << err512 << "\n";
  // Measured: 8.8e-3 at 256 px, 4.4e-3 at 512 px: first order in the pixel size, the signature of the
  // pixelated edge (a discretisation error, not a polynomial error; see the exact-quadrature test above).
  EXPECT_LT(err512, 6e-3);
  EXPECT_LT(err512, 0.6 * err256);
  // Low orders are far more accurate (smooth, small rim values).
  EXPECT_LT(GridGramError(21, 512), 1e-3);
}

TEST(ZernikeTest, BasisMatchesSingleModesAndMasks) {
  const Index n = 64;
  const double eps = 0.3;
  const ImageStack basis = ZernikeBasis(40, n, eps);
  const Image pupil = CircularPupil(n, PupilGeometry{8.0, eps});
  ASSERT_EQ(basis.size(), 40u);
  for (int j = 1; j <= 40; ++j) {
    const Image z = Zernike(j, n, eps);
    EXPECT_LT((basis[j - 1] - z).abs().maxCoeff(), 1e-12) << "j = " << j;
    EXPECT_TRUE(((pupil == 0.0) <= (z == 0.0)).all()) << "mode nonzero outside the binary pupil, j = " << j;
  }
  // Pixel (i, k) of the grid carries Z_j(rho, theta) at its centre.
  const PolarCoordinates c = PupilCoordinates(n);
  for (Index i : {5, 20, 33, 50})
    for (Index k : {7, 31, 32, 60})
      if (c.rho(i, k) <= 1.0 && c.rho(i, k) >= eps) {
        EXPECT_NEAR(basis[13](i, k), ZernikeValue(14, c.rho(i, k), c.theta(i, k)), 1e-12);
      }
}

TEST(ZernikeTest, ProjectionRecoversTheCoefficientsExactly) {
  std::mt19937_64 rng(7);
  std::normal_distribution<double> g(0.0, 1.0);
  const int J = 45;
  for (double eps : {0.0, 0.35}) {
    for (int supersample : {1, 4}) {
      const Index n = 96;
      const Image pupil = CircularPupil(n, PupilGeometry{4.0, eps}, supersample);
      Vector c(J);
      for (int j = 0; j < J; ++j) c(j) = g(rng);
      // A phase made of Z_1..Z_J evaluated at every pixel centre (also the grey edge pixels beyond rho = 1).
      const PolarCoordinates pc = PupilCoordinates(n);
      Image phase = Image::Zero(n, n);
      for (Index p = 0; p < phase.size(); ++p)
        if (pupil.data()[p] > 0)
          for (int j = 1; j <= J; ++j)
            phase.data()[p] += c(j - 1) * ZernikeValue(j, pc.rho.data()[p], pc.theta.data()[p]);
      const Vector est = ProjectOntoZernike(phase, pupil, J);
      EXPECT_LT((est - c).cwiseAbs().maxCoeff(), 1e-10) << "eps = " << eps << " supersample " << supersample;
    }
  }
}

TEST(ZernikeTest, TiltCoefficientRoundTripAndSlope) {
  const double d = 8.2;
  for (double shift : {-3e-7, 0.0, 1e-8, 4.85e-6}) {
    const double a = TiltCoefficientForShift(shift, d);
    EXPECT_DOUBLE_EQ(a, shift * d / 4.0);
    EXPECT_NEAR(ShiftForTiltCoefficient(a, d), shift, 1e-22 + 1e-15 * std::abs(shift));
  }
  // The OPD a Z2 on the grid has slope 4a/D along x (pitch D/n) and none along y; a Z3 the converse.
  const Index n = 32;
  const double a = 1e-7;
  const Image z2 = Zernike(2, n) * a, z3 = Zernike(3, n) * a;
  const double pitch = d / n;
  EXPECT_NEAR((z2(16, 17) - z2(16, 16)) / pitch, 4 * a / d, 1e-12 * a / d);
  EXPECT_NEAR((z2(17, 16) - z2(16, 16)) / pitch, 0.0, 1e-12 * a / d);
  EXPECT_NEAR((z3(17, 16) - z3(16, 16)) / pitch, 4 * a / d, 1e-12 * a / d);
  EXPECT_NEAR((z3(16, 17) - z3(16, 16)) / pitch, 0.0, 1e-12 * a / d);
}

}  // namespace
}  // namespace aosr
