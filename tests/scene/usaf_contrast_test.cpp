// Resolving power read from the USAF target (scene/usaf_contrast.hpp): the truth resolves every representable
// element with transfer 1, a flat image none, and a Gaussian blur stops within one element of where the
// square-wave contrast of the blur falls to the threshold.
#include "aosr/scene/usaf_contrast.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include "aosr/core/error.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

// Separable Gaussian blur (standard deviation sigma px, kernel to 5 sigma, zero outside the image).
Image GaussianBlur(const Image& img, double sigma) {
  const int rad = int(std::ceil(5 * sigma));
  std::vector<double> k(2 * rad + 1);
  double sum = 0;
  for (int i = -rad; i <= rad; ++i) sum += k[i + rad] = std::exp(-0.5 * i * i / (sigma * sigma));
  for (double& v : k) v /= sum;
  Image tmp = Image::Zero(img.rows(), img.cols()), out = Image::Zero(img.rows(), img.cols());
  for (Index y = 0; y < img.rows(); ++y)
    for (Index x = 0; x < img.cols(); ++x)
      for (int i = -rad; i <= rad; ++i)
        if (x + i >= 0 && x + i < img.cols()) tmp(y, x) += k[i + rad] * img(y, x + i);
  for (Index y = 0; y < img.rows(); ++y)
    for (Index x = 0; x < img.cols(); ++x)
      for (int i = -rad; i <= rad; ++i)
        if (y + i >= 0 && y + i < img.rows()) out(y, x) += k[i + rad] * tmp(y + i, x);
  return out;
}

TEST(UsafContrastTest, TheTruthResolvesEveryRepresentableElement) {
  const UsafOptions o;  // groups -2..1, 8 px/mm: the finest bars are 1.12 px wide
  const Shape shape{520, 480};
  const UsafResolvingPower p = MeasureUsafResolvingPower(UsafTarget(shape, o), o);
  ASSERT_EQ(p.elements.size(), 24u);
  for (const UsafElementContrast& e : p.elements) {
    ASSERT_TRUE(e.measured) << e.group << "/" << e.element;
    EXPECT_NEAR(e.transfer, 1.0, 1e-12);
    if (e.bar_width_px >= 5.0) {
      EXPECT_NEAR(e.contrast, 1.0, 1e-12) << e.group << "/" << e.element;
    }
    EXPECT_NEAR(e.cycles_per_px, 0.5 / e.bar_width_px, 1e-15);
  }
  EXPECT_EQ(p.finest, 23);
}

TEST(UsafContrastTest, AFlatImageResolvesNothing) {
  const UsafOptions o;
  const UsafResolvingPower p = MeasureUsafResolvingPower(Image::Constant(520, 480, 2.0), o);
  EXPECT_EQ(p.finest, -1);
  for (const UsafElementContrast& e : p.elements) EXPECT_FALSE(e.resolved);
}

// The three-bar contrast of a Gaussian blur, analytically: bars 0/1 of width w at 0, 2w, 4w, rendered by area
// coverage (the pixel box) and blurred by a Gaussian of standard deviation σ have the profile
//   P(x) = Σ_k B(x − 2kw),   B(x) = S(x) − S(x − w),   S(x) = G(x + 1/2) − G(x − 1/2),   G(x) = σ (u Φ(u) + φ(u)), u = x/σ
// (G is the integral of the blurred step Φ(x/σ)); its Michelson contrast between bar and gap centres, as the
// measurement reads it, falls to the threshold at f_limit = 1/(2w). The measured finest element (frequency steps
// of 2^(1/6)) lies within one element of it; the residual is the measurement's linear interpolation between
// pixel samples.
double ThreeBarContrast(double w, double sigma) {
  auto G = [sigma](double x) {
    const double u = x / sigma;
    return sigma * (u * 0.5 * std::erfc(-u / std::sqrt(2.0)) + std::exp(-0.5 * u * u) / std::sqrt(2 * M_PI));
  };
  auto S = [&](double x) { return G(x + 0.5) - G(x - 0.5); };
  auto P = [&](double x) {
    double v = 0;
    for (int k = 0; k < 3; ++k) v += S(x - 2 * k * w) - S(x - 2 * k * w - w);
    return v;
  };
  double peaks = 0, gaps = 0;
  for (int k = 0; k < 3; ++k) peaks += P(2 * k * w + 0.5 * w) / 3;
  for (int k = 0; k < 2; ++k) gaps += P((2 * k + 1) * w + 0.5 * w) / 2;
  return (peaks - gaps) / (peaks + gaps);
}

TEST(UsafContrastTest, GaussianBlurStopsWhereTheThreeBarContrastFalls) {
  UsafOptions o;
  o.first_group = -1;
  o.last_group = 2;
  o.pixels_per_mm = 8.0;
  const Shape shape{280, 260};
  for (double sigma : {0.8, 1.2, 2.0}) {
    const Image img = GaussianBlur(UsafTarget(shape, o), sigma);
    UsafContrastOptions co;
    co.r = 2;
    const UsafResolvingPower p = MeasureUsafResolvingPower(img, o, co);
    ASSERT_GE(p.finest, 0) << sigma;
    double lo = 0.01, hi = 0.5;  // f = 1/(2w) where the analytic three-bar contrast falls to the threshold
    for (int i = 0; i < 60; ++i) {
      const double mid = 0.5 * (lo + hi);
      (ThreeBarContrast(0.5 / mid, sigma) > co.threshold ? lo : hi) = mid;
    }
    const double measured = p.elements[p.finest].cycles_per_px;
    std::printf("[usaf] Gaussian sigma %.1f px: finest resolved %.4f cycles/px (group %d element %d), analytic limit %.4f\n",
                sigma, measured, p.elements[p.finest].group, p.elements[p.finest].element, lo);
    EXPECT_NEAR(std::log2(measured / lo) * 6.0, 0.0, 1.0) << "sigma " << sigma;
    EXPECT_DOUBLE_EQ(p.elements[p.finest].cycles_per_camera_px, 2 * measured);
  }
}

TEST(UsafContrastTest, ErrorsNameTheArgument) {
  UsafContrastOptions co;
  co.threshold = 1.5;
  EXPECT_THROW(MeasureUsafResolvingPower(Image::Zero(64, 64), UsafOptions{}, co), InvalidArgument);
  try {
    MeasureUsafResolvingPower(Image::Zero(64, 64), UsafOptions{}, co);
  } catch (const InvalidArgument& e) {
    EXPECT_THAT(e.what(), ::testing::HasSubstr("threshold = 1.5"));
  }
  EXPECT_THROW(MeasureUsafResolvingPower(Image(), UsafOptions{}), InvalidArgument);
}

}  // namespace
}  // namespace aosr
