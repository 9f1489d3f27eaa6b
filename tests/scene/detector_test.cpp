#include "aosr/scene/detector.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>

#include "aosr/core/adjoint_test.hpp"
#include "aosr/core/operators.hpp"
#include "aosr/scene/noise.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

// Every effect off: the detector is the read-out conversion only.
DetectorOptions Noiseless() {
  DetectorOptions o;
  o.enable_photon_noise = false;
  o.enable_read_noise = false;
  o.enable_saturation = false;
  return o;
}

Image Ramp(Index rows, Index cols, double scale) {
  Image img(rows, cols);
  for (Index y = 0; y < rows; ++y)
    for (Index x = 0; x < cols; ++x) img(y, x) = scale * (1 + y * cols + x);
  return img;
}

TEST(FillFactorTest, WeightsAreTheSensitiveOverlap) {
  EXPECT_THAT(FillFactorWeights(4, 0.5), ::testing::ElementsAre(0.0, 1.0, 1.0, 0.0));
  EXPECT_THAT(FillFactorWeights(3, 0.5), ::testing::ElementsAre(0.25, 1.0, 0.25));
  EXPECT_THAT(FillFactorWeights(2, 1.0), ::testing::ElementsAre(1.0, 1.0));
  EXPECT_THAT(FillFactorWeights(1, 0.7), ::testing::ElementsAre(::testing::DoubleNear(0.7, 1e-15)));
  for (int r : {1, 2, 3, 5, 8})
    for (double f : {0.1, 0.33, 0.5, 0.9, 1.0}) {
      double sum = 0;
      for (double w : FillFactorWeights(r, f)) sum += w;
      EXPECT_NEAR(sum, f * r, 1e-14) << "r " << r << " f " << f;
    }
}

TEST(FillFactorTest, AdjointAndFlatFieldResponse) {
  for (int r : {1, 2, 3, 4})
    for (double f : {0.3, 0.5, 0.8}) {
      const Shape hr{6 * r, 4 * r};
      const OperatorPtr op = PixelResponse(hr, r, f);
      EXPECT_LT(AdjointTest(*op, 17).worst(), 1e-10) << op->name();
      // A uniform field of 1 per HR pixel: each camera pixel collects (F r)² (light on dead area is lost).
      const Vector y = op->Apply(Vector::Ones(hr.size()));
      EXPECT_NEAR(y.minCoeff(), f * f * r * r, 1e-12);
      EXPECT_NEAR(y.maxCoeff(), f * f * r * r, 1e-12);
    }
}

TEST(FillFactorTest, FullFillIsTheForwardModelsDecimate) {
  const Shape hr{12, 8};
  const Image x = Ramp(12, 8, 0.37);
  const Vector a = PixelResponse(hr, 4, 1.0)->Apply(AsVector(x));
  const Vector b = Decimate(hr, 4)->Apply(AsVector(x));
  EXPECT_TRUE(a == b);
  DetectorOptions o;
  o.fill_factor = 0.5;
  EXPECT_EQ(Detector(o).PixelResponse(hr, 4)->name(), "PixelResponse(r=4, fill=0.5)");
}

TEST(DetectorTest, NoiselessOutputIsExpectedOverGainPlusBias) {
  DetectorOptions o = Noiseless();
  o.gain_e_per_adu = 2.5;
  o.bias_adu = 100;
  o.background_e_per_s = 3.0;
  o.dark_current_e_per_s = 0.5;
  o.exposure_time_s = 2.0;
  const Detector d(o);
  const Image s = Ramp(7, 9, 1.3);
  const DetectorFrame f = d.Record(s, 1);
  const Image expected = (s + 7.0) / 2.5 + 100.0;
  EXPECT_TRUE((f.adu == expected).all());
  EXPECT_TRUE((f.adu == d.MeanAdu(s)).all());
  EXPECT_EQ(f.uniform_draws, 0);
  EXPECT_EQ(f.normal_draws, 0);
  EXPECT_TRUE((f.valid == 1).all());
  EXPECT_TRUE((f.inverse_variance == 1).all());  // no noise: uniform weights
  // Switching background and dark off removes them.
  o.enable_background = o.enable_dark_current = false;
  EXPECT_TRUE((Detector(o).Record(s, 1).adu == s / 2.5 + 100.0).all());
}

// The cost proof: with photon noise off and read noise 0 (or off) the RNG is never called, and the output
// does not depend on the seed.
TEST(DetectorTest, DisabledNoiseDrawsNothing) {
  DetectorOptions o;
  o.enable_photon_noise = false;
  o.read_noise_e = 0.0;  // enabled, but zero
  const Image s = Ramp(16, 16, 4.0);
  const DetectorFrame a = Detector(o).Record(s, 1), b = Detector(o).Record(s, 999, 3);
  EXPECT_EQ(a.uniform_draws + a.normal_draws, 0);
  EXPECT_TRUE((a.adu == b.adu).all());
  EXPECT_TRUE((a.adu == s).all());
  // And each noise source draws exactly one deviate per pixel when on (Poisson: >= 1 uniform).
  o.read_noise_e = 2.0;
  EXPECT_EQ(Detector(o).Record(s, 1).normal_draws, s.size());
  o.enable_photon_noise = true;
  o.enable_read_noise = false;
  const DetectorFrame p = Detector(o).Record(s, 1);
  EXPECT_EQ(p.normal_draws, 0);
  EXPECT_GE(p.uniform_draws, s.size());
  // Peak fraction 0 draws nothing either.
  o.noise_model = NoiseModel::kPeakFraction;
  o.peak_noise_fraction = 0;
  EXPECT_EQ(Detector(o).Record(s, 1).normal_draws, 0);
}

TEST(DetectorTest, SeedsAndFramesSelectIndependentReproducibleStreams) {
  DetectorOptions o;
  const Detector d(o);
  const Image s = Image::Constant(32, 32, 40.0);
  const DetectorFrame a = d.Record(s, 5, 0), b = d.Record(s, 5, 0), c = d.Record(s, 5, 1),
                      e = d.Record(s, 6, 0);
  EXPECT_TRUE((a.adu == b.adu).all());
  EXPECT_FALSE((a.adu == c.adu).all());
  EXPECT_FALSE((a.adu == e.adu).all());
  // RecordSequence frame i is Record(.., i).
  const auto seq = d.RecordSequence({s, s}, 5);
  EXPECT_TRUE((seq[0].adu == a.adu).all());
  EXPECT_TRUE((seq[1].adu == c.adu).all());
}

TEST(DetectorTest, SaturationClipsFlagsAndZeroesTheWeight) {
  DetectorOptions o = Noiseless();
  o.enable_saturation = true;
  o.gain_e_per_adu = 2.0;
  o.bias_adu = 10;
  o.saturation_adu = 60;             // 100 e- above the bias
  const Image s = Ramp(1, 6, 40.0);  // 40 .. 240 e-: 30, 50, 70, 90, 110, 130 ADU
  const DetectorFrame f = Detector(o).Record(s, 1);
  EXPECT_THAT(std::vector<double>(f.adu.data(), f.adu.data() + 6),
              ::testing::ElementsAre(30, 50, 60, 60, 60, 60));
  EXPECT_THAT(std::vector<double>(f.saturated.data(), f.saturated.data() + 6),
              ::testing::ElementsAre(0, 0, 1, 1, 1, 1));
  EXPECT_TRUE((f.valid == 1 - f.saturated).all());
  EXPECT_TRUE(((f.inverse_variance == 0) == (f.saturated == 1)).all());
  // A value exactly at the level is flagged too (it cannot be told from a clipped one).
  EXPECT_EQ(Detector(o).Record(Image::Constant(1, 1, 100.0), 1).saturated(0, 0), 1);
  // Off: nothing clipped.
  o.enable_saturation = false;
  EXPECT_EQ(Detector(o).Record(s, 1).adu(0, 5), 130);
}

TEST(DetectorTest, BadPixelsReadTheBiasAndHaveZeroWeight) {
  DetectorOptions o;
  o.bias_adu = 500;
  o.read_noise_e = 3;
  o.enable_bad_pixels = true;
  o.bad_pixel_mask = RandomBadPixelMask({64, 64}, 0.05, 11);
  const Index bad = (o.bad_pixel_mask == 0).count();
  EXPECT_GT(bad, 100);  // ~205 expected
  EXPECT_LT(bad, 320);
  const Image s = Image::Constant(64, 64, 1000.0);
  const DetectorFrame f = Detector(o).Record(s, 2);
  for (Index i = 0; i < s.size(); ++i) {
    const bool is_bad = o.bad_pixel_mask.data()[i] == 0;
    EXPECT_EQ(f.valid.data()[i], is_bad ? 0 : 1);
    if (is_bad) {
      EXPECT_EQ(f.adu.data()[i], 500);
      EXPECT_EQ(f.inverse_variance.data()[i], 0);
    } else {
      EXPECT_NEAR(f.inverse_variance.data()[i], 1.0 / (1000 + 9), 1e-15);
    }
  }
  // Masks do not shift the random streams: good pixels read as without the mask.
  o.enable_bad_pixels = false;
  const DetectorFrame g = Detector(o).Record(s, 2);
  EXPECT_TRUE(((f.adu == g.adu) || (o.bad_pixel_mask == 0)).all());
  // The plan lists what is enabled, in order.
  o.enable_bad_pixels = true;
  EXPECT_THAT(Detector(o).Plan().back(), ::testing::HasSubstr("bad pixels: " + std::to_string(bad)));
}

TEST(DetectorTest, PlanListsOnlyEnabledStages) {
  DetectorOptions o = Noiseless();
  EXPECT_THAT(Detector(o).Plan(), ::testing::ElementsAre(::testing::HasSubstr("gain 1 e-/ADU")));
  o.enable_photon_noise = true;
  o.enable_read_noise = true;
  o.background_e_per_s = 2;
  o.enable_quantization = true;
  o.enable_saturation = true;
  EXPECT_THAT(
      Detector(o).Plan(),
      ::testing::ElementsAre(::testing::HasSubstr("background"), ::testing::HasSubstr("photon noise"),
                             ::testing::HasSubstr("read noise 5 e-"), ::testing::HasSubstr("gain"),
                             ::testing::HasSubstr("quantisation"), ::testing::HasSubstr("saturation")));
}

TEST(DetectorTest, QuantisationRoundsToWholeAdu) {
  DetectorOptions o = Noiseless();
  o.enable_quantization = true;
  o.gain_e_per_adu = 3.0;
  const DetectorFrame f = Detector(o).Record(Ramp(3, 3, 1.0), 1);
  EXPECT_TRUE((f.adu == (Ramp(3, 3, 1.0) / 3.0 + 0.5).floor()).all());
  EXPECT_NEAR(f.inverse_variance(0, 0), 12.0, 1e-12);  // only the 1/12 ADU² of the ADC
}

TEST(DetectorTest, PeakFractionModelIsTheDemosNoise) {
  // The paper's model through the detector: σ = p · max over the sequence; noise.hpp's functions agree.
  DetectorOptions o;
  o.noise_model = NoiseModel::kPeakFraction;
  o.peak_noise_fraction = 0.02;
  o.enable_saturation = false;
  const ImageStack frames = {Ramp(20, 20, 1.0), Ramp(20, 20, 2.0)};
  const auto rec = Detector(o).RecordSequence(frames, 3);
  EXPECT_DOUBLE_EQ(rec[0].noise_sigma_e, 0.02 * 800);
  EXPECT_DOUBLE_EQ(rec[1].noise_sigma_e, NoiseSigmaFromPeakFraction(frames, 0.02));
  EXPECT_NEAR(rec[0].inverse_variance(3, 3), 1.0 / (16.0 * 16.0), 1e-15);
  // A single-frame Record takes that frame's own peak.
  EXPECT_DOUBLE_EQ(Detector(o).Record(frames[0], 3).noise_sigma_e, 0.02 * 400);
  // AddGaussianNoise is AddNormalNoise over one NormalGenerator stream.
  ImageStack a = frames;
  AddGaussianNoise(&a, 0.5, 42);
  NormalGenerator g(42);
  Image b0 = frames[0], b1 = frames[1];
  AddNormalNoise(&b0, 0.5, &g);
  AddNormalNoise(&b1, 0.5, &g);
  EXPECT_TRUE((a[0] == b0).all());
  EXPECT_TRUE((a[1] == b1).all());
}

TEST(DetectorTest, WeightsFromDataMatchTheOracleOnAverage) {
  DetectorOptions o;
  o.gain_e_per_adu = 2.0;
  o.bias_adu = 200;
  o.read_noise_e = 4.0;
  const Detector d(o);
  const Image s = Image::Constant(100, 100, 300.0);
  const DetectorFrame f = d.Record(s, 9);
  const Image w = d.InverseVarianceFromData(f.adu, f.valid);
  EXPECT_NEAR(w.mean() / f.inverse_variance.mean(), 1.0, 0.01);
  EXPECT_NEAR(f.inverse_variance(0, 0), 4.0 / 316.0, 1e-15);
  // A Poisson-only pixel expecting nothing gets one electron of variance, not infinite weight.
  o.enable_read_noise = false;
  EXPECT_NEAR(Detector(o).Record(Image::Zero(2, 2), 1).inverse_variance(0, 0), 4.0, 1e-15);
}

TEST(DetectorTest, TinyNegativeExpectationsFromFftRoundingCountAsZero) {
  DetectorOptions o = Noiseless();
  Image s = Image::Constant(4, 4, 10.0);
  s(0, 0) = -1e-14;
  EXPECT_EQ(Detector(o).Record(s, 1).adu(0, 0), 0.0);
  o.enable_photon_noise = true;
  EXPECT_EQ(Detector(o).Record(s, 1).adu(0, 0), 0.0);
}

}  // namespace
}  // namespace aosr
