// BandPsfCalculator / UniformBand (psf.hpp): bookkeeping of band-integrated PSFs.
#include <gtest/gtest.h>

#include <cmath>

#include "aosr/optics/psf.hpp"
#include "aosr/optics/pupil.hpp"
#include "aosr/optics/zernike.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

constexpr double kDiameter = 8.0;
constexpr double kLambda = 1.65e-6;

TEST(BandPsfTest, SingleWavelengthReproducesTheMonochromaticPsf) {
  const Index n = 64;
  const Image pupil = CircularPupil(n, PupilGeometry{kDiameter, 0.14}, 4);
  const Image opd = 80e-9 * ZernikeUnmasked(7, n) + 50e-9 * ZernikeUnmasked(5, n);
  const double pixel = 0.4 * kLambda / kDiameter;
  const PsfCalculator mono(n, kDiameter, PsfSampling{kLambda, pixel, 48, 40});
  const BandPsfCalculator band(n, kDiameter, SpectralBand{{kLambda}, {3.7}}, pixel, 48, 40);
  const BandPsf result = band.Compute(pupil, opd);
  EXPECT_TRUE((result.psf == mono.Compute(pupil, opd)).all());
  ASSERT_EQ(result.strehl.size(), 1u);
  EXPECT_EQ(result.strehl[0], StrehlFromPupil(pupil, opd, kLambda));
  EXPECT_DOUBLE_EQ(result.band_strehl, result.strehl[0]);
  EXPECT_EQ(band.normalised_weights()[0], 1.0);
}

TEST(BandPsfTest, WeightsAreNormalisedAndTheBandIsTheWeightedSum) {
  const Index n = 64;
  const Image pupil = CircularPupil(n, PupilGeometry{kDiameter, 0.0});
  const Image opd = 100e-9 * ZernikeUnmasked(4, n);
  const double pixel = 0.3 * 1.2e-6 / kDiameter;
  const std::vector<double> lambdas = {1.2e-6, 1.65e-6, 2.2e-6};
  const BandPsfCalculator band(n, kDiameter, SpectralBand{lambdas, {1.0, 2.0, 1.0}}, pixel, 32, 32);
  const BandPsfCalculator scaled(n, kDiameter, SpectralBand{lambdas, {5.0, 10.0, 5.0}}, pixel, 32, 32);
  const BandPsf a = band.Compute(pupil, opd);
  const BandPsf b = scaled.Compute(pupil, opd);
  EXPECT_LT((a.psf - b.psf).abs().maxCoeff(), 1e-15 * a.psf.maxCoeff());
  Image expected = Image::Zero(32, 32);
  const double w[] = {0.25, 0.5, 0.25};
  double num = 0.0, den = 0.0;
  for (int k = 0; k < 3; ++k) {
    expected +=
        w[k] * PsfCalculator(n, kDiameter, PsfSampling{lambdas[k], pixel, 32, 32}).Compute(pupil, opd);
    const double s = StrehlFromPupil(pupil, opd, lambdas[k]);
    EXPECT_DOUBLE_EQ(a.strehl[k], s);
    num += w[k] / (lambdas[k] * lambdas[k]) * s;
    den += w[k] / (lambdas[k] * lambdas[k]);
  }
  EXPECT_LT((a.psf - expected).abs().maxCoeff(), 1e-14 * expected.maxCoeff());
  EXPECT_NEAR(a.band_strehl, num / den, 1e-15);
  // Strehl falls toward short wavelengths for an achromatic OPD.
  EXPECT_LT(a.strehl[0], a.strehl[1]);
  EXPECT_LT(a.strehl[1], a.strehl[2]);
}

// The band Strehl is the on-axis ratio of the band PSF to the unaberrated band PSF (exact for a sampled
// pupil, since the unaberrated on-axis value of each PSF_k is proportional to (D / lambda_k)^2).
TEST(BandPsfTest, BandStrehlIsTheOnAxisRatio) {
  const Index n = 64, rows = 33;  // odd: the optical axis is the pixel (16, 16)
  const Image pupil = CircularPupil(n, PupilGeometry{kDiameter, 0.2});
  const Image opd = 120e-9 * Zernike(11, n, 0.2) + 60e-9 * Zernike(8, n, 0.2);
  const BandPsfCalculator band(n, kDiameter, UniformBand(kLambda, 0.3e-6, 5), 0.25 * 1.5e-6 / kDiameter, rows,
                               rows);
  const BandPsf aberrated = band.Compute(pupil, opd);
  const BandPsf perfect = band.Compute(pupil, Image::Zero(n, n));
  EXPECT_NEAR(aberrated.psf(rows / 2, rows / 2) / perfect.psf(rows / 2, rows / 2), aberrated.band_strehl,
              1e-12);
  EXPECT_DOUBLE_EQ(perfect.band_strehl, 1.0);
}

TEST(BandPsfTest, UniformBandSamplesEqualSubIntervals) {
  const SpectralBand band = UniformBand(1.65e-6, 0.3e-6, 3);
  ASSERT_EQ(band.wavelengths_m.size(), 3u);
  EXPECT_NEAR(band.wavelengths_m[0], 1.55e-6, 1e-20);
  EXPECT_NEAR(band.wavelengths_m[1], 1.65e-6, 1e-20);
  EXPECT_NEAR(band.wavelengths_m[2], 1.75e-6, 1e-20);
  EXPECT_EQ(band.weights, std::vector<double>(3, 1.0));
  EXPECT_EQ(UniformBand(2e-6, 0.0, 1).wavelengths_m, std::vector<double>{2e-6});
  std::string why;
  EXPECT_TRUE(band.IsValid(&why)) << why;
}

}  // namespace
}  // namespace aosr
