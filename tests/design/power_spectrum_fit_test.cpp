// Unit tests of power_spectrum_fit.hpp: the model grid, the random-field generator, the periodogram's
// bookkeeping (patches, window normalisation, scaling, Parseval) and the mapping to the Tikhonov/Wiener prior.
#include "aosr/design/power_spectrum_fit.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>

#include "aosr/core/fft.hpp"
#include "aosr/design/design_objective.hpp"
#include "aosr/io/fits.hpp"
#include "design/design_fixture.hpp"
#include "support/testing.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

TEST(PowerSpectrumFitTest, GridIsTheModelSymmetricWithZeroFrequencyAtTheOrigin) {
  const PowerSpectrumModel m{2.0, 0.07, 2.5, 0.01};
  const Image s = PowerSpectrumGrid(m, {32, 48});
  EXPECT_NEAR(s(0, 0), 2.0 * std::pow(0.07, -2.5) + 0.01, 1e-12 * s(0, 0));
  EXPECT_NEAR(s(3, 0), m(3.0 / 32), 1e-12 * s(3, 0));
  EXPECT_NEAR(s(0, 47), m(1.0 / 48), 1e-12 * s(0, 47));
  for (Index y = 0; y < 32; ++y)
    for (Index x = 0; x < 48; ++x) EXPECT_EQ(s(y, x), s((32 - y) % 32, (48 - x) % 48)) << y << "," << x;
}

TEST(PowerSpectrumFitTest, RandomFieldIsDeterministicRealAndHasTheModelsVariance) {
  const PowerSpectrumModel m{1e-3, 0.05, 3.0, 0.0};
  const Image a = GaussianRandomField({256, 256}, m, 11), b = GaussianRandomField({256, 256}, m, 11);
  EXPECT_TRUE((a == b).all());
  EXPECT_FALSE((a == GaussianRandomField({256, 256}, m, 12)).all());
  // Variance per pixel = mean of s over the grid (Parseval), within the statistical spread of one draw
  // (dominated by the few low-frequency modes: ~10%).
  const double var = (a - a.mean()).square().mean();
  const double expected = PowerSpectrumGrid(m, {256, 256}).mean();
  EXPECT_NEAR(var / expected, 1.0, 0.15) << "seed 11";
}

TEST(PowerSpectrumFitTest, ParsevalIsExactForOnePatchWithTheRectangularWindow) {
  const Image img = test::RandomImage({32, 32}, 5) * 3.0 + 7.0;
  PowerSpectrumFitOptions o;
  o.grid = 32;
  o.window = SpectralWindow::kRectangular;
  const PowerSpectrumFit fit = FitPowerSpectrum({img}, o);
  EXPECT_EQ(fit.patches, 1);
  const double var = (img - img.mean()).square().mean();
  EXPECT_NEAR(fit.periodogram.mean(), var, 1e-12 * var);
  EXPECT_NEAR(fit.mean_power, var, 1e-12 * var);
  EXPECT_NEAR(fit.periodogram(0, 0), 0.0, 1e-12 * var);  // the mean is removed
}

TEST(PowerSpectrumFitTest, HannWindowPowerLossIsCorrected) {
  // One patch, Hann: mean_f P = Σ w² x² / Σ w², the window-weighted variance; for white noise ≈ σ².
  PowerSpectrumFitOptions o;
  o.grid = 64;
  const Image img = test::RandomImage({64, 64}, 9) * 2.0;
  const PowerSpectrumFit fit = FitPowerSpectrum({img}, o);
  Image w(64, 64);
  for (Index y = 0; y < 64; ++y)
    for (Index x = 0; x < 64; ++x)
      w(y, x) = std::pow(std::sin(M_PI * (y + 0.5) / 64), 2) * std::pow(std::sin(M_PI * (x + 0.5) / 64), 2);
  const Image c = img - img.mean();
  const double cw = (w * c).sum() / w.sum();
  const double expected = (w.square() * (c - cw).square()).sum() / w.square().sum();
  EXPECT_NEAR(fit.mean_power, expected, 1e-12 * expected);
  EXPECT_NEAR(fit.mean_power, 4.0, 0.4);
}

TEST(PowerSpectrumFitTest, PatchesTileTheImageWithTheLastFlushWithTheEdge) {
  PowerSpectrumFitOptions o;
  o.grid = 32;
  const Image img = test::RandomImage({80, 64}, 2);
  // Hann, step 16: rows 0,16,32,48 (flush: 48 = 80-32), cols 0,16,32 -> 12 patches.
  EXPECT_EQ(FitPowerSpectrum({img}, o).patches, 12);
  o.window = SpectralWindow::kRectangular;  // step 32: rows 0,32,48; cols 0,32 -> 6
  EXPECT_EQ(FitPowerSpectrum({img}, o).patches, 6);
  o.patch_step = 100;  // larger than the image: the first and the flush patch
  EXPECT_EQ(FitPowerSpectrum({img, img}, o).patches, 8);
}

TEST(PowerSpectrumFitTest, ScalingIsExplicitAndReported) {
  const Image img = test::RandomImage({64, 64}, 3, false);  // U(0, 1)
  PowerSpectrumFitOptions o;
  o.grid = 32;
  const PowerSpectrumFit base = FitPowerSpectrum({img}, o);
  // kNone: units kept, so s scales with the square of the pixel values.
  const PowerSpectrumFit doubled = FitPowerSpectrum({2.0 * img}, o);
  EXPECT_NEAR(doubled.mean_power, 4.0 * base.mean_power, 1e-12 * base.mean_power);
  EXPECT_NEAR(doubled.model.amplitude, 4.0 * base.model.amplitude, 1e-6 * base.model.amplitude);
  EXPECT_NEAR(doubled.model.slope, base.model.slope, 1e-6);
  // kPeak: any input scale gives the same spectrum (that of the image with peak scale_value).
  o.scaling = TrainingScaling::kPeak;
  o.scale_value = 1000.0;
  const PowerSpectrumFit p1 = FitPowerSpectrum({img}, o), p7 = FitPowerSpectrum({7.0 * img}, o);
  EXPECT_NEAR(p1.scales[0], 1000.0 / img.maxCoeff(), 1e-12);
  EXPECT_NEAR(p7.mean_power, p1.mean_power, 1e-10 * p1.mean_power);
  o.scaling = TrainingScaling::kMean;
  const PowerSpectrumFit m1 = FitPowerSpectrum({img}, o);
  EXPECT_NEAR(m1.scales[0], 1000.0 / img.mean(), 1e-12);
  EXPECT_NEAR(m1.mean_power, base.mean_power * m1.scales[0] * m1.scales[0], 1e-10 * m1.mean_power);
}

TEST(PowerSpectrumFitTest, WienerPriorIsTheFittedSpectrumParametricallyOrSampled) {
  const double sigma = 0.3;
  const Shape hr{32, 32};
  for (const PowerSpectrumModel& m : {PowerSpectrumModel{5.0, 0.04, 2.7, 0.0}, PowerSpectrumModel{5.0, 0.04, 2.7, 0.5},
                                      PowerSpectrumModel{5.0, 0.9, 2.0, 0.0}}) {
    const TikhonovOptions t = WienerPriorOptions(m, sigma, hr);
    EXPECT_EQ(t.prior, TikhonovPrior::kPowerSpectrum);
    EXPECT_EQ(t.object_power_spectrum.size() == 0, m.floor == 0 && m.corner <= 0.5);
    std::string why;
    EXPECT_TRUE(t.IsValid(&why)) << why;
    // tikhonov.hpp: E|X(f)|²/M² = (σ²/λ) S(f) = (σ²/λ) / |Γ̂(f)|².
    const Image s = PowerSpectrumGrid(m, hr);
    for (Index y = 0; y < hr.rows; ++y)
      for (Index x = 0; x < hr.cols; ++x)
        EXPECT_NEAR(sigma * sigma / t.lambda / TikhonovPriorSymbol(t, hr, y, x), s(y, x), 1e-10 * s(y, x));
  }
}

TEST(PowerSpectrumFitTest, DesignObjectivesWienerSpectrumIsTheFittedModel) {
  // The objective's Wiener-consistent s = (σ²/λ)/P with the fitted prior equals the fitted spectrum, so the
  // design can use either WienerPriorOptions alone or object_power_spectrum = fit.spectrum.
  const DesignOptics optics = design_test::SmallOptics(false);
  const PowerSpectrumModel m{0.02, 0.06, 2.4, 0.0};
  DesignObjectiveOptions o;
  o.noise_sigma = 0.1;
  o.reconstructor = WienerPriorOptions(m, o.noise_sigma, {optics.grid, optics.grid});
  const DesignObjective f(optics, 2, o);
  const Image s = PowerSpectrumGrid(m, {optics.grid, optics.grid});
  EXPECT_LT(((f.object_spectrum() - s).abs() / s).maxCoeff(), 1e-10);
}

TEST(PowerSpectrumFitTest, LoadTrainingImagesReadsFitsAsStored) {
  const std::filesystem::path dir = std::filesystem::temp_directory_path() / "aosr_psd_load_test";
  std::filesystem::create_directories(dir);
  const Image img = test::RandomImage({40, 50}, 4) * 100.0;
  const std::string path = (dir / "a.fits").string();
  WriteFits(path, img, {}, FitsType::kFloat64);
  const std::vector<Image> loaded = LoadTrainingImages({path, path});
  ASSERT_EQ(loaded.size(), 2u);
  EXPECT_TRUE((loaded[1] == img).all());
  std::filesystem::remove_all(dir);
}

TEST(PowerSpectrumFitTest, BriefReportNamesTheParameters) {
  PowerSpectrumFitOptions o;
  o.grid = 32;
  const PowerSpectrumFit fit = FitPowerSpectrum({test::RandomImage({64, 64}, 1)}, o);
  const std::string r = fit.BriefReport();
  EXPECT_NE(r.find("beta"), std::string::npos) << r;
  EXPECT_NE(r.find("9 patches of 32x32 from 1 images"), std::string::npos) << r;
}

}  // namespace
}  // namespace aosr
