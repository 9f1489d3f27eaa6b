// Physics of band-integrated PSFs: a broad band fills in the Airy pattern's dark rings.
#include <gtest/gtest.h>

#include <cmath>
#include <iostream>
#include <vector>

#include "aosr/optics/psf.hpp"
#include "aosr/optics/pupil.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

constexpr double kDiameter = 8.0;
constexpr double kLambda = 1.65e-6;  // band centre [m]

// Azimuthal mean of a centred PSF (pitch s lambda_c/D) in annuli of width s/2, as (radius, value) pairs.
std::vector<std::pair<double, double>> RadialProfile(const Image& psf, double s) {
  const Index rows = psf.rows();
  const double c = rows / 2;
  std::vector<double> sum_r, sum_v;
  std::vector<int> count;
  for (Index y = 0; y < rows; ++y) {
    for (Index x = 0; x < rows; ++x) {
      const double r = std::hypot(y - c, x - c);
      const std::size_t b = static_cast<std::size_t>(r / 0.5);
      if (b >= sum_r.size()) sum_r.resize(b + 1, 0.0), sum_v.resize(b + 1, 0.0), count.resize(b + 1, 0);
      sum_r[b] += r;
      sum_v[b] += psf(y, x);
      ++count[b];
    }
  }
  std::vector<std::pair<double, double>> profile;
  for (std::size_t b = 0; b < sum_r.size(); ++b) {
    if (count[b] > 0) profile.emplace_back(sum_r[b] / count[b] * s, sum_v[b] / count[b]);
  }
  return profile;
}

// Depth of the first dark ring: the minimum of the radial profile for r in [1.0, 1.5] lambda_c/D, relative to
// the peak.
double FirstRingDepth(const Image& psf, double s) {
  double depth = 1e300;
  for (const auto& [r, v] : RadialProfile(psf, s)) {
    if (r >= 1.0 && r <= 1.5) depth = std::min(depth, v);
  }
  return depth / psf.maxCoeff();
}

// The Airy zero at 1.22 lambda/D moves with wavelength; a band of fractional width b spreads it over
// +-b/2 x 1.22 lambda_c/D. Near the zero x0 = 3.8317 (x = pi r D / lambda) the Airy intensity is
// I/I0 ~ (J0(x0) (x - x0) / (x0 / 2))^2 = (0.2104 (x - x0))^2, whose mean over a flat band of half-width
// dx = x0 b / 2 is 0.2104^2 dx^2 / 3: 2.2e-3 for b = 20%, 8.7e-3 for b = 40% (first order in dx; it ignores
// the 1/lambda^2 weighting of each PSF's peak and the curvature of the Airy minimum). Set-up: binary
// 256-pixel pupil, 0.05 lambda_c/D sampling, flat bands of 21 samples. Measured depths: monochromatic 7.4e-5
// (not 0: each annulus of the profile is 0.025 lambda/D wide), 20% band 2.15e-3, 40% band 7.3e-3. Tolerances:
// mono < 1e-4; a band within a factor 2 of the estimate and > 20 x the monochromatic depth; wider band,
// shallower ring.
TEST(BandPsfPhysicsTest, BroadBandFillsTheFirstAiryMinimum) {
  const Index n = 256, rows = 96;
  const double s = 0.05;
  const double pixel = s * kLambda / kDiameter;
  const Image pupil = CircularPupil(n, PupilGeometry{kDiameter, 0.0});
  const Image flat = Image::Zero(n, n);
  const Image mono =
      PsfCalculator(n, kDiameter, PsfSampling{kLambda, pixel, rows, rows}).Compute(pupil, flat);
  const double mono_depth = FirstRingDepth(mono, s);
  std::cout << "monochromatic first-ring depth " << mono_depth << "\n";
  EXPECT_LT(mono_depth, 1e-4);
  double previous = mono_depth;
  for (double b : {0.2, 0.4}) {
    const BandPsfCalculator calc(n, kDiameter, UniformBand(kLambda, b * kLambda, 21), pixel, rows, rows);
    const BandPsf band = calc.Compute(pupil, flat);
    const double depth = FirstRingDepth(band.psf, s);
    const double dx = 3.8317059702075123 * b / 2.0;
    const double estimate = 0.2104 * 0.2104 * dx * dx / 3.0;
    std::cout << "band " << 100 * b << "%: first-ring depth " << depth << " (first-order estimate "
              << estimate << "), band Strehl " << band.band_strehl << ", flux in window " << band.psf.sum()
              << " (mono " << mono.sum() << ")\n";
    EXPECT_GT(depth, 20.0 * mono_depth);
    EXPECT_GT(depth, 0.5 * estimate);
    EXPECT_LT(depth, 2.0 * estimate);
    EXPECT_GT(depth, previous);
    previous = depth;
    EXPECT_NEAR(band.band_strehl, 1.0, 1e-12);
  }
}

}  // namespace
}  // namespace aosr
