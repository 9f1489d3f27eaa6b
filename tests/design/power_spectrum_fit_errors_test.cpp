// Bad input to power_spectrum_fit.hpp's entry points gets a clear InvalidArgument (or IoError) naming it.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>

#include "aosr/design/power_spectrum_fit.hpp"
#include "support/testing.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

using ::testing::HasSubstr;
using test::ErrorOf;

PowerSpectrumFitOptions Grid32() {
  PowerSpectrumFitOptions o;
  o.grid = 32;
  return o;
}

TEST(PowerSpectrumFitErrorsTest, FitRejectsBadImages) {
  const Image good = test::RandomImage({40, 40}, 1);
  EXPECT_THAT(ErrorOf([&] { FitPowerSpectrum({}, Grid32()); }), HasSubstr("images"));
  EXPECT_THAT(ErrorOf([&] { FitPowerSpectrum({good, test::RandomImage({40, 31}, 2)}, Grid32()); }),
              HasSubstr("images[1] shape"));
  Image nan = good;
  nan(3, 4) = std::nan("");
  EXPECT_THAT(ErrorOf([&] { FitPowerSpectrum({nan}, Grid32()); }), HasSubstr("images[0]"));
  EXPECT_THAT(ErrorOf([&] { FitPowerSpectrum({nan}, Grid32()); }), HasSubstr("non-finite"));
  Image inf = good;
  inf(0, 0) = INFINITY;
  EXPECT_THAT(ErrorOf([&] { FitPowerSpectrum({good, inf}, Grid32()); }), HasSubstr("images[1]"));
  EXPECT_THAT(ErrorOf([&] { FitPowerSpectrum({good, Image::Constant(40, 40, 3.0)}, Grid32()); }),
              HasSubstr("constant"));
  PowerSpectrumFitOptions o = Grid32();
  o.scaling = TrainingScaling::kPeak;
  EXPECT_THAT(ErrorOf([&] { FitPowerSpectrum({Image(good.abs() * -1.0 - 1.0)}, o); }), HasSubstr("images[0] maximum"));
  o.scaling = TrainingScaling::kMean;
  EXPECT_THAT(ErrorOf([&] { FitPowerSpectrum({Image(good - 10.0)}, o); }), HasSubstr("images[0] mean"));
  // Power in too few annuli: a pure cosine along x has power in one annulus only.
  Image cosine(32, 32);
  for (Index y = 0; y < 32; ++y)
    for (Index x = 0; x < 32; ++x) cosine(y, x) = std::cos(2 * M_PI * 5 * x / 32.0);
  o = Grid32();
  o.window = SpectralWindow::kRectangular;
  EXPECT_THAT(ErrorOf([&] { FitPowerSpectrum({cosine}, o); }), HasSubstr("annuli with power"));
}

TEST(PowerSpectrumFitErrorsTest, FitRejectsBadOptions) {
  const Image good = test::RandomImage({40, 40}, 1);
  auto with = [&](auto edit) {
    PowerSpectrumFitOptions o = Grid32();
    edit(o);
    return ErrorOf([&] { FitPowerSpectrum({good}, o); });
  };
  EXPECT_THAT(with([](auto& o) { o.grid = 4; }), HasSubstr("options.grid"));
  EXPECT_THAT(with([](auto& o) { o.patch_step = -1; }), HasSubstr("options.patch_step"));
  EXPECT_THAT(with([](auto& o) { o.scale_value = 0; }), HasSubstr("options.scale_value"));
  EXPECT_THAT(with([](auto& o) { o.scale_value = NAN; }), HasSubstr("options.scale_value"));
  EXPECT_THAT(with([](auto& o) { o.min_frequency = 0.6; }), HasSubstr("options.min_frequency"));
  EXPECT_THAT(with([](auto& o) { o.max_frequency = 0.9; }), HasSubstr("options.max_frequency"));
  EXPECT_THAT(with([](auto& o) { o.min_frequency = 0.3, o.max_frequency = 0.2; }), HasSubstr("options.max_frequency"));
  EXPECT_THAT(with([](auto& o) { o.max_iterations = 0; }), HasSubstr("options.max_iterations"));
  EXPECT_THAT(with([](auto& o) { o.tolerance = 0; }), HasSubstr("options.tolerance"));
  // A band with fewer than 5 annuli.
  EXPECT_THAT(with([](auto& o) { o.min_frequency = 0.4, o.max_frequency = 0.45; }), HasSubstr("at least 5"));
}

TEST(PowerSpectrumFitErrorsTest, ModelGridFieldAndPriorRejectBadInput) {
  PowerSpectrumModel bad;
  bad.amplitude = 0;
  EXPECT_THAT(ErrorOf([&] { PowerSpectrumGrid(bad, {8, 8}); }), HasSubstr("model.amplitude"));
  bad = PowerSpectrumModel();
  bad.corner = -1;
  EXPECT_THAT(ErrorOf([&] { PowerSpectrumGrid(bad, {8, 8}); }), HasSubstr("model.corner"));
  bad = PowerSpectrumModel();
  bad.slope = 20;
  EXPECT_THAT(ErrorOf([&] { GaussianRandomField({8, 8}, bad, 1); }), HasSubstr("model.slope"));
  bad = PowerSpectrumModel();
  bad.floor = -1;
  EXPECT_THAT(ErrorOf([&] { WienerPriorOptions(bad, 1.0, {8, 8}); }), HasSubstr("model.floor"));
  EXPECT_THAT(ErrorOf([&] { PowerSpectrumGrid(PowerSpectrumModel(), {0, 8}); }), HasSubstr("grid"));
  EXPECT_THAT(ErrorOf([&] { GaussianRandomField({1, 8}, PowerSpectrumModel(), 1); }), HasSubstr("shape"));
  EXPECT_THAT(ErrorOf([&] { WienerPriorOptions(PowerSpectrumModel(), 0.0, {8, 8}); }), HasSubstr("noise_sigma"));
  EXPECT_THAT(ErrorOf([&] { WienerPriorOptions(PowerSpectrumModel(), 1.0, {8, 0}); }), HasSubstr("hr"));
}

TEST(PowerSpectrumFitErrorsTest, LoadTrainingImagesNamesThePath) {
  EXPECT_THAT(ErrorOf([&] { LoadTrainingImages({}); }), HasSubstr("paths"));
  EXPECT_THAT(ErrorOf<IoError>([&] { LoadTrainingImages({"/nonexistent/training.fits"}); }),
              HasSubstr("/nonexistent/training.fits"));
  EXPECT_THAT(ErrorOf<IoError>([&] { LoadTrainingImages({"/nonexistent/training.png"}); }),
              HasSubstr("/nonexistent/training.png"));
}

}  // namespace
}  // namespace aosr
