#include "aosr/scene/point_sources.hpp"

#include <gtest/gtest.h>

#include <chrono>
#include <cmath>

#include "aosr/core/fft.hpp"
#include "aosr/core/forward_model.hpp"
#include "aosr/core/operators.hpp"
#include "aosr/optics/psf.hpp"
#include "aosr/optics/pupil.hpp"
#include "aosr/scene/star_field.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

// Unit-sum diffraction-limited PSF of a 8 m, 14%-obstructed pupil, `pitch_lambda_over_d` per HR pixel,
// on an odd window so that the kernel is exactly symmetric about its centre pixel.
Image AiryKernel(double pitch_lambda_over_d, Index side = 65) {
  const double diameter = 8.0, wavelength = 2.2e-6;
  const Index n = 128;
  PupilGeometry geometry{diameter, 0.14};
  const Image pupil = CircularPupil(n, geometry);
  PsfSampling sampling{wavelength, pitch_lambda_over_d * wavelength / diameter, side, side};
  return NormaliseToUnitSum(PsfFromPupil(pupil, Image::Zero(n, n), diameter, sampling));
}

// Real, symmetric Gaussian transfer function exp(-2π²σ²|f|²) (f in cycles per pixel); at σ = 2.5 px it is
// 4e-14 at Nyquist, so the PSF is band-limited and compact to double precision.
ComplexImage GaussianOtf(Shape hr, double sigma) {
  ComplexImage h(hr.rows, hr.cols / 2 + 1);
  for (Index u = 0; u < hr.rows; ++u)
    for (Index v = 0; v < h.cols(); ++v) {
      const double fy = double(SignedFrequency(u, hr.rows)) / hr.rows, fx = double(v) / hr.cols;
      h(u, v) = std::exp(-2.0 * M_PI * M_PI * sigma * sigma * (fy * fy + fx * fx));
    }
  return h;
}

TEST(PointSourcesTest, IntegerStarsEqualTheFftPathOfTheForwardModel) {
  // The acceptance test: stars at integer HR positions, gridded as deltas, convolved by the periodic
  // FFT convolution and decimated by the forward model, against the point-source path.
  const Shape hr{128, 128};
  const int r = 2;
  const Image psf = AiryKernel(0.5);
  const ComplexImage h0 = TransferFunction(hr, psf);
  // Two frames: the second with a sub-pixel tip/tilt offset carried by its transfer function.
  const std::vector<ComplexImage> otfs = {h0, h0 * ShiftTransfer(hr, 0.5, -0.25)};
  const MultiFrameModel model(hr, r, otfs);

  StarFieldOptions options;
  options.count = 60;
  std::vector<PointSource> stars = StarField(hr, options, /*seed=*/7);
  Image deltas = Image::Zero(hr.rows, hr.cols);
  for (PointSource& s : stars) {
    s.y = std::min<double>(hr.rows - 1, std::max(0.0, std::round(s.y)));
    s.x = std::min<double>(hr.cols - 1, std::max(0.0, std::round(s.x)));
    deltas(Index(s.y), Index(s.x)) += s.flux;
  }
  const ImageStack fft_path = model.Render(deltas);
  const ImageStack star_path = RenderPointSourceFrames(model, stars);
  ASSERT_EQ(star_path.size(), 2u);
  for (int i = 0; i < 2; ++i) {
    const double peak = fft_path[i].abs().maxCoeff();
    const double err = (star_path[i] - fft_path[i]).abs().maxCoeff() / peak;
    std::printf("frame %d: max |star path - FFT path| / peak = %.3g\n", i, err);
    EXPECT_LT(err, 1e-6);
    EXPECT_LT(err, 1e-12);  // in fact equal to rounding
  }
  // And the HR image itself against the periodic convolution of the delta image.
  const Image z = RenderPointSources(hr, stars, h0);
  const Image conv = ToImage(PeriodicConvolution(hr, h0)->Apply(AsVector(deltas)), hr);
  EXPECT_LT((z - conv).abs().maxCoeff(), 1e-12 * conv.abs().maxCoeff());
  // PointSourceImage of integer positions is the delta image.
  EXPECT_LT((PointSourceImage(hr, stars) - deltas).abs().maxCoeff(), 1e-12 * deltas.maxCoeff());
}

TEST(PointSourcesTest, SubPixelStarsAreTheConvolutionOfTheBandLimitedPoints) {
  const Shape hr{96, 80};
  const ComplexImage h = TransferFunction(hr, AiryKernel(0.5));
  const std::vector<PointSource> stars = {{10.3, 20.7, 3.0}, {50.55, 40.125, 1.5}, {80.9, 5.01, 0.25}};
  const Image z = RenderPointSources(hr, stars, h);
  const Image x = PointSourceImage(hr, stars);
  const Image conv = ToImage(PeriodicConvolution(hr, h)->Apply(AsVector(x)), hr);
  EXPECT_LT((z - conv).abs().maxCoeff(), 1e-13 * z.abs().maxCoeff());
}

TEST(PointSourcesTest, SubPixelStarEqualsTheShiftedPsfOfShiftTransfer) {
  // For a PSF with (numerically) no power at Nyquist, our symmetric Nyquist convention and ShiftTransfer
  // agree: a star at p is the PSF translated by p.
  const Shape hr{64, 64};
  const ComplexImage h = GaussianOtf(hr, 2.5);
  const double y = 20.37, x = 41.81, flux = 2.5;
  const Image z = RenderPointSources(hr, {{y, x, flux}}, h);
  Image delta = Image::Zero(hr.rows, hr.cols);
  delta(0, 0) = flux;
  const Image shifted =
      ToImage(PeriodicConvolution(hr, h * ShiftTransfer(hr, y, x))->Apply(AsVector(delta)), hr);
  EXPECT_LT((z - shifted).abs().maxCoeff(), 1e-12 * z.maxCoeff());
}

TEST(PointSourcesTest, SubPixelStarsConserveFluxAndSitAtTheirPositions) {
  const Shape hr{128, 128};
  const ComplexImage airy = TransferFunction(hr, AiryKernel(0.5));
  const ComplexImage gauss = GaussianOtf(hr, 2.5);
  const std::vector<PointSource> positions = {{40.3, 70.77, 1.0}, {63.5, 63.5, 1.0}, {90.123, 30.987, 1.0}};
  for (const PointSource& p : positions) {
    SCOPED_TRACE("star at (" + std::to_string(p.y) + ", " + std::to_string(p.x) + ")");
    const std::vector<PointSource> stars = {{p.y, p.x, 7.25}};
    // Flux: Σ z = H(0) F with H(0) = 1 for a unit-sum PSF.
    for (const ComplexImage* h : {&airy, &gauss}) {
      const Image z = RenderPointSources(hr, stars, *h);
      EXPECT_NEAR(z.sum(), 7.25, 1e-12 * 7.25);
    }
    // Centroid, plain first moment, for the compact band-limited (Gaussian) PSF.
    const Image z = RenderPointSources(hr, stars, gauss);
    double my = 0.0, mx = 0.0;
    for (Index i = 0; i < hr.rows; ++i)
      for (Index j = 0; j < hr.cols; ++j) {
        my += i * z(i, j);
        mx += j * z(i, j);
      }
    EXPECT_NEAR(my / z.sum(), p.y, 1e-6);
    EXPECT_NEAR(mx / z.sum(), p.x, 1e-6);
    // Circular centroid (phase of the fundamental) for the symmetric Airy PSF, whose r^-3 wings make the
    // plain moment depend on the periodic wrap.
    const ComplexImage za = FftR2C(RenderPointSources(hr, stars, airy));
    const double cy = -std::arg(za(1, 0)) * hr.rows / (2.0 * M_PI);
    const double cx = -std::arg(za(0, 1)) * hr.cols / (2.0 * M_PI);
    EXPECT_NEAR(std::remainder(cy - p.y, double(hr.rows)), 0.0, 1e-6);
    EXPECT_NEAR(std::remainder(cx - p.x, double(hr.cols)), 0.0, 1e-6);
  }
}

TEST(PointSourcesTest, HalfPixelStarIsMirrorSymmetricEvenWhenUndersampled) {
  // An undersampled PSF (1 λ/D per pixel: strong power at Nyquist) exercises the Nyquist convention: the
  // image of a star at a half-integer position is mirror-symmetric about it.
  const Shape hr{64, 64};
  const ComplexImage h = TransferFunction(hr, AiryKernel(1.0, 63));
  const Image z = RenderPointSources(hr, {{30.5, 20.5, 1.0}}, h);
  double worst = 0.0;
  for (Index k = 0; k < 30; ++k)
    for (Index j = 0; j < hr.cols; ++j) worst = std::max(worst, std::abs(z(30 - k, j) - z(31 + k, j)));
  for (Index i = 0; i < hr.rows; ++i)
    for (Index k = 0; k < 20; ++k) worst = std::max(worst, std::abs(z(i, 20 - k) - z(i, 21 + k)));
  EXPECT_LT(worst, 1e-14 * z.maxCoeff() * 10);
}

TEST(PointSourcesTest, LinearInTheSourcesAndEmptyIsZero) {
  const Shape hr{32, 48};
  const ComplexImage h = GaussianOtf(hr, 1.5);
  const PointSource a{5.5, 7.25, 2.0}, b{20.1, 30.9, 3.0};
  const Image za = RenderPointSources(hr, {a}, h), zb = RenderPointSources(hr, {b}, h);
  const Image zab = RenderPointSources(hr, {a, b}, h);
  EXPECT_LT((zab - za - zb).abs().maxCoeff(), 1e-14 * zab.maxCoeff());
  EXPECT_EQ(RenderPointSources(hr, {}, h).abs().maxCoeff(), 0.0);
}

TEST(PointSourcesTest, ManyStarsAreCheaperThanTheyLook) {
  // Blocks of 256 stars (exercises the block boundary) and a rough timing for the record.
  const Shape hr{256, 256};
  const ComplexImage h = GaussianOtf(hr, 2.0);
  StarFieldOptions options;
  options.count = 1000;
  const std::vector<PointSource> stars = StarField(hr, options, 3);
  const auto t0 = std::chrono::steady_clock::now();
  const Image z = RenderPointSources(hr, stars, h);
  const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  std::printf("RenderPointSources: %d stars on %s in %.1f ms\n", options.count, ToString(hr).c_str(), ms);
  double total = 0.0;
  for (const PointSource& s : stars) total += s.flux;
  EXPECT_NEAR(z.sum(), total, 1e-12 * total);
  // Compare with the sum of single-star renderings of a few blocks' worth.
  Image sum = Image::Zero(hr.rows, hr.cols);
  for (const PointSource& s : stars) sum += RenderPointSources(hr, {s}, h);
  EXPECT_LT((z - sum).abs().maxCoeff(), 1e-12 * z.maxCoeff());
}

}  // namespace
}  // namespace aosr
