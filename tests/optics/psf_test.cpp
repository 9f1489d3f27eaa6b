#include "aosr/optics/psf.hpp"

#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <iostream>
#include <string>

#include "aosr/optics/pupil.hpp"
#include "aosr/optics/zernike.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

constexpr double kDiameter = 8.0;
constexpr double kWavelength = 1.0e-6;
constexpr double kLambdaOverD = kWavelength / kDiameter;

TEST(PsfTest, SamplingValidationNamesTheField) {
  std::string why;
  EXPECT_TRUE((PsfSampling{1e-6, 1e-8, 32, 16}.IsValid(&why)));
  EXPECT_FALSE((PsfSampling{0.0, 1e-8, 32, 32}.IsValid(&why)));
  EXPECT_NE(why.find("wavelength_m"), std::string::npos) << why;
  EXPECT_FALSE((PsfSampling{1e-6, -1.0, 32, 32}.IsValid(&why)));
  EXPECT_NE(why.find("pixel_scale_rad"), std::string::npos) << why;
  EXPECT_FALSE((PsfSampling{1e-6, 1e-8, 0, 32}.IsValid(&why)));
  EXPECT_NE(why.find("rows"), std::string::npos) << why;
  EXPECT_DOUBLE_EQ((PsfSampling{1e-6, 0.5e-6 / 8.0, 1, 1}.PixelScaleLambdaOverD(8.0)), 0.5);
}

// The unaberrated on-axis value is (sum A)^2 / (n^2 sum A^2) s^2 (psf.hpp), the PSF is centro-symmetric about
// pixel (rows/2, cols/2), and the one-shot function agrees with the calculator.
TEST(PsfTest, UnaberratedPsfIsCentredWithTheExpectedPeak) {
  const Index n = 64;
  const double s = 0.3;
  const Image pupil = CircularPupil(n, PupilGeometry{kDiameter, 0.1}, 4);
  for (Shape out : {Shape{33, 33}, Shape{32, 40}}) {
    const PsfSampling sampling{kWavelength, s * kLambdaOverD, out.rows, out.cols};
    const Image psf = PsfFromPupil(pupil, Image::Zero(n, n), kDiameter, sampling);
    const Index cy = out.rows / 2, cx = out.cols / 2;
    Index py, px;
    psf.maxCoeff(&py, &px);
    EXPECT_EQ(py, cy);
    EXPECT_EQ(px, cx);
    const double peak = pupil.sum() * pupil.sum() / (n * n * pupil.square().sum()) * s * s;
    EXPECT_NEAR(psf(cy, cx), peak, 1e-13);
    for (Index dy = -(out.rows - 1 - cy); dy <= cy - (out.rows % 2 == 0 ? 1 : 0); ++dy)
      for (Index dx = -(out.cols - 1 - cx); dx <= cx - (out.cols % 2 == 0 ? 1 : 0); ++dx)
        ASSERT_NEAR(psf(cy + dy, cx + dx), psf(cy - dy, cx - dx), 1e-15) << dy << "," << dx;
    const PsfCalculator calc(n, kDiameter, sampling);
    EXPECT_LT((calc.Compute(pupil, Image::Zero(n, n)) - psf).abs().maxCoeff(), 1e-16);
  }
}

// OPDs are achromatic: doubling lambda with the OPD and the pixel scale leaves the phase and the sampling in
// lambda/D unchanged, so the PSF is identical.
TEST(PsfTest, PsfDependsOnPhaseAndLambdaOverDOnly) {
  const Index n = 48;
  const Image pupil = CircularPupil(n, PupilGeometry{kDiameter, 0.0}, 2);
  const Image opd = Zernike(8, n) * 0.1e-6 + Zernike(5, n) * 0.05e-6;
  const Image a = PsfFromPupil(pupil, opd, kDiameter, PsfSampling{1e-6, 0.4 * 1e-6 / kDiameter, 30, 30});
  const Image b =
      PsfFromPupil(pupil, 2.0 * opd, kDiameter, PsfSampling{2e-6, 0.4 * 2e-6 / kDiameter, 30, 30});
  EXPECT_LT((a - b).abs().maxCoeff(), 1e-14);
}

TEST(PsfTest, StrehlOfFlatAndPistonWavefrontsIsOne) {
  const Index n = 64;
  const Image pupil = CircularPupil(n, PupilGeometry{kDiameter, 0.0}, 3);
  EXPECT_NEAR(StrehlFromPupil(pupil, Image::Zero(n, n), kWavelength), 1.0, 1e-14);
  EXPECT_NEAR(StrehlFromPupil(pupil, Image::Constant(n, n, 0.37e-6), kWavelength), 1.0, 1e-12);
  // A phase of pi on half the pupil cancels the on-axis field of a symmetric pupil exactly.
  Image half = Image::Zero(n, n);
  half.leftCols(n / 2).setConstant(kWavelength / 2);
  EXPECT_NEAR(StrehlFromPupil(pupil, half, kWavelength), 0.0, 1e-14);
}

TEST(PsfTest, PeakStrehlAndUnitSumNormalisation) {
  Image ref = Image::Zero(5, 5), psf = Image::Zero(5, 5);
  ref(2, 2) = 0.4;
  psf(1, 3) = 0.1;
  EXPECT_DOUBLE_EQ(PeakStrehl(psf, ref), 0.25);
  const Image k = NormaliseToUnitSum(ref + psf);
  EXPECT_NEAR(k.sum(), 1.0, 1e-15);
  EXPECT_DOUBLE_EQ(k(2, 2), 0.8);
}

// Not a pass/fail benchmark: prints the cost of one PSF so regressions are visible in the logs.
TEST(PsfTest, ReportsTheCostOfOnePsf) {
  const Index n = 256;
  const Image pupil = CircularPupil(n, PupilGeometry{kDiameter, 0.14}, 2);
  const Image opd = Zernike(11, n, 0.14) * 50e-9;
  const PsfCalculator calc(n, kDiameter, PsfSampling{kWavelength, 0.25 * kLambdaOverD, 256, 256});
  calc.Compute(pupil, opd);
  const auto t0 = std::chrono::steady_clock::now();
  const int reps = 5;
  double sum = 0.0;
  for (int i = 0; i < reps; ++i) sum += calc.Compute(pupil, opd).sum();
  const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  std::cout << "PSF 256-px pupil -> 256x256: " << ms / reps << " ms each\n";
  EXPECT_GT(sum, 0.0);
}

}  // namespace
}  // namespace aosr
