#include "aosr/core/image.hpp"  // kPi
#include "aosr/optics/pupil.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <string>

namespace aosr {
namespace {


TEST(PupilTest, GridCoordinatesSpanTheDiameterSymmetrically) {
  // Even n: centres at +-1/n, ..., +-(n-1)/n; odd n: the middle pixel is the centre.
  EXPECT_DOUBLE_EQ(NormalisedPupilPosition(0, 4), -0.75);
  EXPECT_DOUBLE_EQ(NormalisedPupilPosition(1, 4), -0.25);
  EXPECT_DOUBLE_EQ(NormalisedPupilPosition(3, 4), 0.75);
  EXPECT_DOUBLE_EQ(NormalisedPupilPosition(2, 5), 0.0);
  EXPECT_DOUBLE_EQ(NormalisedPupilPosition(4, 5), 0.8);
  const PolarCoordinates c = PupilCoordinates(6);
  EXPECT_NEAR(c.rho(0, 0), std::sqrt(2.0) * 5.0 / 6.0, 1e-15);
  EXPECT_NEAR(c.theta(5, 5), kPi / 4, 1e-15);   // +x, +y (larger row) quadrant
  EXPECT_NEAR(c.theta(0, 5), -kPi / 4, 1e-15);  // +x, -y
  EXPECT_NEAR(c.theta(3, 0), kPi - std::atan(0.2), 1e-15);
}

TEST(PupilTest, BinaryPupilHasTheDiskAreaAndIsSymmetric) {
  for (Index n : {64, 65, 256}) {
    const Image a = CircularPupil(n, PupilGeometry{8.0, 0.0});
    EXPECT_TRUE(((a == 0.0) || (a == 1.0)).all());
    // Area in D^2 units: pi/4, up to the staircase (relative error ~ n^-1.5 here).
    EXPECT_NEAR(a.sum() / (n * n), kPi / 4, 2.0 / (n * n) * std::sqrt(n)) << "n = " << n;
    EXPECT_TRUE((a == a.colwise().reverse()).all());
    EXPECT_TRUE((a == a.rowwise().reverse()).all());
    EXPECT_TRUE((a == a.transpose()).all());
    // Exactly the pixels whose centre has rho <= 1.
    const PolarCoordinates c = PupilCoordinates(n);
    EXPECT_TRUE(((a > 0.0) == (c.rho <= 1.0)).all());
  }
}

TEST(PupilTest, GreyEdgesEstimateTheCoveredFraction) {
  const Index n = 128;
  const Image binary = CircularPupil(n, PupilGeometry{8.0, 0.0});
  const Image grey = CircularPupil(n, PupilGeometry{8.0, 0.0}, 16);
  EXPECT_TRUE((grey >= 0.0).all() && (grey <= 1.0).all());
  EXPECT_TRUE((grey == grey.colwise().reverse()).all());
  const double area = kPi / 4 * n * n;
  EXPECT_LT(std::abs(grey.sum() - area), std::abs(binary.sum() - area) + 1e-9);
  EXPECT_NEAR(grey.sum() / area, 1.0, 5e-5);  // measured 2.7e-5 (16 x 16 sub-grid)
  // Interior pixels are exactly 1; far outside exactly 0; edge pixels grey.
  EXPECT_EQ(grey(n / 2, n / 2), 1.0);
  EXPECT_EQ(grey(0, 0), 0.0);
  EXPECT_GT(((grey > 0.0) && (grey < 1.0)).count(), 2 * n);
  // The covered fraction of the pixel straddling the rim on the x axis: the rim at x = 1 crosses pixel
  // n-1 (centre 1 - 1/n, width 2/n) at its right edge, so it is almost fully covered (the arc bulges out).
  EXPECT_GT(grey(n / 2, n - 1), 0.9);
}

TEST(PupilTest, CentralObstructionIsAnAnnulus) {
  const Index n = 200;
  const double eps = 0.3;
  const Image a = CircularPupil(n, PupilGeometry{8.0, eps}, 8);
  EXPECT_EQ(a(n / 2, n / 2), 0.0);
  EXPECT_NEAR(a.sum() / (n * n), kPi / 4 * (1 - eps * eps), 1e-4);
  const Image b = CircularPupil(n, PupilGeometry{8.0, eps});
  const PolarCoordinates c = PupilCoordinates(n);
  EXPECT_TRUE(((b > 0.0) == ((c.rho <= 1.0) && (c.rho >= eps))).all());
}

TEST(PupilTest, GeometryValidationNamesTheField) {
  std::string why;
  EXPECT_TRUE((PupilGeometry{8.0, 0.14}.IsValid(&why)));
  EXPECT_FALSE((PupilGeometry{0.0, 0.0}.IsValid(&why)));
  EXPECT_NE(why.find("diameter_m"), std::string::npos) << why;
  EXPECT_FALSE((PupilGeometry{8.0, 1.0}.IsValid(&why)));
  EXPECT_NE(why.find("obstruction"), std::string::npos) << why;
  EXPECT_FALSE((PupilGeometry{8.0, -0.1}.IsValid(nullptr)));
}

}  // namespace
}  // namespace aosr
