#include "aosr/core/image.hpp"  // kPi
#include "aosr/optics/mft.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <complex>
#include <random>

#include "aosr/core/fft.hpp"

namespace aosr {
namespace {


ComplexImage RandomField(Shape s, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> g(0.0, 1.0);
  ComplexImage f(s.rows, s.cols);
  for (Index i = 0; i < f.size(); ++i) f.data()[i] = Complex(g(rng), g(rng));
  return f;
}

// The defining sum of mft.hpp, evaluated term by term.
ComplexImage BruteForce(const ComplexImage& e, double span, double s, Shape out) {
  ComplexImage r(out.rows, out.cols);
  for (Index p = 0; p < out.rows; ++p)
    for (Index q = 0; q < out.cols; ++q) {
      const double ay = (p - out.rows / 2) * s, ax = (q - out.cols / 2) * s;
      Complex sum = 0.0;
      for (Index k = 0; k < e.rows(); ++k)
        for (Index l = 0; l < e.cols(); ++l) {
          const double uy = (k - (e.rows() - 1) / 2.0) / span, ux = (l - (e.cols() - 1) / 2.0) / span;
          sum += e(k, l) * std::polar(1.0, -2 * kPi * (uy * ay + ux * ax));
        }
      r(p, q) = sum / (span * span);
    }
  return r;
}

TEST(MftTest, MatchesTheDefiningSumForAnyShapes) {
  // Rectangular input, span different from the input size, odd and even outputs, both product orders.
  struct Case {
    Shape in;
    double span;
    Shape out;
    double s;
  };
  for (const Case& c : {Case{{7, 10}, 6.5, {9, 12}, 0.37}, Case{{16, 16}, 16, {3, 40}, 1.3},
                        Case{{5, 5}, 5, {40, 2}, 0.05}, Case{{12, 9}, 12, {11, 11}, 2.0}}) {
    const ComplexImage e = RandomField(c.in, 3);
    const ComplexImage got = Mft(e, c.span, c.s, c.out);
    const ComplexImage want = BruteForce(e, c.span, c.s, c.out);
    ASSERT_EQ(ShapeOf(got), c.out);
    EXPECT_LT((got - want).abs().maxCoeff(), 1e-12 * want.abs().maxCoeff())
        << ToString(c.in) << " -> " << ToString(c.out);
  }
}

// With span = n and pitch 1 lambda/D on n x n outputs the MFT is the DFT up to a unit-modulus phase (the
// centring) and the 1/n^2 factor: |out(p, q)| n^2 = |FFT(E)((p - n/2) mod n, (q - n/2) mod n)|.
TEST(MftTest, ReducesToTheFftAtUnitPitch) {
  const Index n = 24;
  const ComplexImage e = RandomField({n, n}, 5);
  const ComplexImage out = Mft(e, n, 1.0, {n, n});
  const ComplexImage fft = FftForward(e);
  double worst = 0.0;
  for (Index p = 0; p < n; ++p)
    for (Index q = 0; q < n; ++q) {
      const Index u = ((p - n / 2) % n + n) % n, v = ((q - n / 2) % n + n) % n;
      worst = std::max(worst, std::abs(std::abs(out(p, q)) * n * n - std::abs(fft(u, v))));
    }
  EXPECT_LT(worst, 1e-10 * fft.abs().maxCoeff());
}

TEST(MftTest, AdjointIsExact) {
  MftGeometry g{{20, 17}, 15.0, {13, 31}, 0.45};
  const MatrixFourierTransform mft(g);
  const ComplexImage x = RandomField(g.input, 11), y = RandomField(g.output, 12);
  const Complex lhs = (mft.Apply(x) * y.conjugate()).sum();
  const Complex rhs = (x * mft.ApplyAdjoint(y).conjugate()).sum();
  EXPECT_LT(std::abs(lhs - rhs) / (std::abs(lhs) + std::abs(rhs)), 1e-12);
}

// Discrete Parseval: over exactly one period (rows s = cols s = span, s <= 1) the output energy
// sum |out|^2 s^2 equals the pupil energy sum |E|^2 / span^2.
TEST(MftTest, ConservesEnergyOverOnePeriod) {
  const Index n = 32;
  const ComplexImage e = RandomField({n, n}, 8);
  const double pupil_energy = e.abs2().sum() / (n * n);
  for (double s : {1.0, 0.5, 0.25}) {
    const Index m = static_cast<Index>(std::lround(n / s));
    const double out_energy = Mft(e, n, s, {m, m}).abs2().sum() * s * s;
    EXPECT_NEAR(out_energy, pupil_energy, 1e-12 * pupil_energy) << "s = " << s;
  }
}

// Sign convention: a field exp(+2 pi i t.u) focuses at alpha = +t (larger indices for t > 0).
TEST(MftTest, TiltedFieldFocusesAtPlusT) {
  const Index n = 32, rows = 40, cols = 40;
  const double ty = -2.0, tx = 3.0, s = 0.5;
  ComplexImage e(n, n);
  for (Index k = 0; k < n; ++k)
    for (Index l = 0; l < n; ++l) {
      const double uy = (k - (n - 1) / 2.0) / n, ux = (l - (n - 1) / 2.0) / n;
      e(k, l) = std::polar(1.0, 2 * kPi * (ty * uy + tx * ux));
    }
  const Image intensity = Mft(e, n, s, {rows, cols}).abs2();
  Index py, px;
  intensity.maxCoeff(&py, &px);
  EXPECT_EQ(py, rows / 2 + static_cast<Index>(ty / s));
  EXPECT_EQ(px, cols / 2 + static_cast<Index>(tx / s));
  // The peak of a unit-amplitude field is the pupil area in D^2 units: 1 for the full square grid.
  EXPECT_NEAR(std::sqrt(intensity(py, px)), 1.0, 1e-12);
}

}  // namespace
}  // namespace aosr
