#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include "aosr/core/forward_model.hpp"
#include "aosr/scene/detector.hpp"
#include "aosr/scene/photometry.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

struct Moments {
  double mean = 0, variance = 0;
};

Moments MomentsOf(const Image& img) {
  Moments m;
  m.mean = img.mean();
  m.variance = (img - m.mean).square().sum() / double(img.size() - 1);
  return m;
}

// Acceptance: a flat field's frame variance equals mean/gain + read² (mean above bias, both in ADU) within 2%
// over 10⁶ pixels, and the mean is exact to its standard error, for means 0.5, 5, 50 and 5000 e⁻, several
// gains, with and without read noise. The standard error of the variance is <= 0.2% here, so 2% is a loose
// bound that a normal approximation to Poisson at small means (variance off by up to ~8% at 0.5 e⁻) would
// fail.
TEST(DetectorPhysicsTest, FlatFieldVarianceIsMeanOverGainPlusReadSquared) {
  const Index side = 1000;
  std::uint64_t seed = 20240;
  for (double mean_e : {0.5, 5.0, 50.0, 5000.0})
    for (double gain : {0.5, 1.0, 3.7})
      for (double read_e : {0.0, 3.0}) {
        DetectorOptions o;
        o.gain_e_per_adu = gain;
        o.read_noise_e = read_e;
        o.bias_adu = 100.0;
        o.enable_saturation = false;
        ++seed;
        const DetectorFrame f = Detector(o).Record(Image::Constant(side, side, mean_e), seed);
        const Moments m = MomentsOf(f.adu);
        const double mean_adu = mean_e / gain, read_adu = read_e / gain;
        const double expected_var = mean_adu / gain + read_adu * read_adu;
        const double se_mean = std::sqrt(expected_var / double(side * side));
        const double z = (m.mean - o.bias_adu - mean_adu) / se_mean;
        std::printf("mean %7.1f e-  gain %.1f  read %.0f e-:  var/expected = %.5f   mean z = %+.2f\n", mean_e,
                    gain, read_e, m.variance / expected_var, z);
        EXPECT_NEAR(m.variance / expected_var, 1.0, 0.02) << "seed " << seed;
        EXPECT_LT(std::fabs(z), 4.0) << "seed " << seed;
        // Var = (mean − bias)/g + read² also holds with the *measured* mean.
        EXPECT_NEAR(m.variance / ((m.mean - o.bias_adu) / gain + read_adu * read_adu), 1.0, 0.02);
      }
}

// The oracle weights are the inverse variances: over a frame with a range of means the weighted squared
// residuals average 1.
TEST(DetectorPhysicsTest, InverseVarianceNormalisesTheResiduals) {
  DetectorOptions o;
  o.gain_e_per_adu = 1.8;
  o.read_noise_e = 6.0;
  o.bias_adu = 300;
  o.background_e_per_s = 2.0;
  o.exposure_time_s = 3.0;
  o.enable_saturation = false;
  const Detector d(o);
  Image s(1000, 1000);
  for (Index y = 0; y < s.rows(); ++y)
    for (Index x = 0; x < s.cols(); ++x) s(y, x) = 0.01 * double(x * x);  // 0 .. ~10⁴ e⁻
  const std::uint64_t seed = 77;
  const DetectorFrame f = d.Record(s, seed);
  const double chi2 = ((f.adu - d.MeanAdu(s)).square() * f.inverse_variance).mean();
  std::printf("mean weighted squared residual = %.5f\n", chi2);
  EXPECT_NEAR(chi2, 1.0, 0.01) << "seed " << seed;
  EXPECT_TRUE((f.inverse_variance == 1.0 / d.VarianceAdu(s)).all());
}

// Total flux through every noiseless stage: photometry -> object -> PSF convolution and D_r (the shared
// forward model) -> background -> gain and bias. Each conserves electrons to 1e-10.
TEST(DetectorPhysicsTest, NoiselessChainConservesElectrons) {
  LightCollectorOptions collector;
  const ExposurePlan plan{10.0, 4};
  const double electrons = ElectronsPerFrame(SourceFlux::Magnitude(14, "H"), collector, plan);

  const Shape hr{64, 64};
  const int r = 4;
  Image x = Image::Zero(hr.rows, hr.cols);
  for (Index y = 20; y < 44; ++y)
    for (Index c = 10; c < 50; ++c) x(y, c) = 1.0 + 0.1 * ((y * 7 + c * 3) % 11);
  x *= electrons / x.sum();
  Image psf(9, 9);
  for (Index y = 0; y < 9; ++y)
    for (Index c = 0; c < 9; ++c) psf(y, c) = std::exp(-((y - 4) * (y - 4) + (c - 4) * (c - 4)) / 4.0);
  psf /= psf.sum();
  const MultiFrameModel model = MultiFrameModel::FromKernels(hr, r, {psf, psf});
  const ImageStack frames = model.Render(x);
  EXPECT_NEAR(frames[1].sum() / electrons, 1.0, 1e-10);

  DetectorOptions o;
  o.enable_photon_noise = o.enable_read_noise = o.enable_saturation = false;
  o.gain_e_per_adu = 2.2;
  o.bias_adu = 1000;
  o.background_e_per_s = 0.7;
  o.exposure_time_s = plan.FrameTime();
  const auto recorded = Detector(o).RecordSequence(frames, 1);
  const double n = double(frames[0].size());
  for (std::size_t i = 0; i < frames.size(); ++i) {
    const double back = ((recorded[i].adu - o.bias_adu) * o.gain_e_per_adu).sum();
    EXPECT_NEAR(back / (electrons + n * 0.7 * o.exposure_time_s), 1.0, 1e-10);
    // Exactly λ/g + bias, λ = s + background (FFT rounding's ~1e-17 negatives count as 0).
    EXPECT_TRUE((recorded[i].adu == (frames[i].max(0.0) + 0.7 * o.exposure_time_s) / 2.2 + 1000.0).all());
  }
}

}  // namespace
}  // namespace aosr
