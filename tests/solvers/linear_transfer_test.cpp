#include "aosr/solvers/linear_transfer.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>

#include "aosr/core/fft.hpp"
#include "aosr/solvers/tikhonov.hpp"
#include "solvers/tikhonov_fixture.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

using test::RasterModel;

// The object cos(2π f·p) at HR bin (by, bx) of grid hr.
Image CosineAt(Shape hr, Index by, Index bx) {
  Image x(hr.rows, hr.cols);
  for (Index y = 0; y < hr.rows; ++y)
    for (Index c = 0; c < hr.cols; ++c)
      x(y, c) = std::cos(kTwoPi * (double(by * y) / double(hr.rows) + double(bx * c) / double(hr.cols)));
  return x;
}

ComplexImage Spectrum(const Image& x) { return FftForward(x.cast<Complex>()); }

// The oracle: Tikhonov's own estimate of a noise-free sinusoid. Its output at the input's frequency divided by
// the input's is T(f); its outputs at the other frequencies of the bin (f + j∘m) are the alias column. The
// frequencies are chosen so that −f is not in f's alias set (2f off the lattice), and the design is asymmetric
// (shifts not mirror-symmetric), so T is complex.
TEST(LinearTransferTest, TikhonovTransferIsTheEstimatorsResponseToASinusoid) {
  struct Case {
    int r;
    std::vector<std::pair<double, double>> shifts;
    double lambda;
    TikhonovPrior prior;
  };
  const std::vector<Case> cases = {
      {2, {{0, 0}, {0, 1}, {1, 0}, {1, 1}}, 1e-2, TikhonovPrior::kGradient},
      {2, {{0, 0}, {0.3, 1.1}, {1.4, 0.2}}, 3e-3, TikhonovPrior::kIdentity},
      {3, {{0, 0}, {0.5, 1.2}, {2.1, 0.7}, {1.2, 2.4}}, 1e-2, TikhonovPrior::kLaplacian},
      // N < r² at λ = 0: the minimum-norm path (SVD) on both sides.
      {2, {{0, 0}, {0.6, 1.3}}, 0.0, TikhonovPrior::kGradient},
  };
  for (const Case& c : cases) {
    const Shape hr{8 * c.r, 10 * c.r};
    const MultiFrameModel model = RasterModel(hr, c.r, c.shifts, 1.1);
    TikhonovOptions o;
    o.prior = c.prior;
    o.lambda = c.lambda;
    const TransferGrid g = TikhonovTransferGrid(model, {}, o, c.lambda);
    const Index m_rows = hr.rows / c.r, m_cols = hr.cols / c.r;
    for (auto [by, bx] : std::vector<std::pair<Index, Index>>{{1, 2}, {3, 7}, {hr.rows - 5, 3}, {6, hr.cols - 4}}) {
      const Image x = CosineAt(hr, by, bx);
      const Image xhat = TikhonovFourier(model, model.Render(x), o);
      const ComplexImage in = Spectrum(x), out = Spectrum(xhat);
      const Complex t = out(by, bx) / in(by, bx);
      EXPECT_LT(std::abs(t - g.transfer(by, bx)), 1e-10)
          << "r=" << c.r << " lambda=" << c.lambda << " bin (" << by << ", " << bx << "): " << t << " vs "
          << g.transfer(by, bx);
      double alias2 = 0;
      for (int jy = 0; jy < c.r; ++jy)
        for (int jx = 0; jx < c.r; ++jx)
          if (jy || jx) alias2 += std::norm(out((by + jy * m_rows) % hr.rows, (bx + jx * m_cols) % hr.cols) / in(by, bx));
      EXPECT_NEAR(std::sqrt(alias2), g.alias(by, bx), 1e-10) << "r=" << c.r << " bin (" << by << ", " << bx << ")";
    }
  }
}

// Where the frames see every frequency (N = r² raster, λ → 0) the estimator is the identity: T = 1, no alias,
// except on the pixel box's zeros (the alias lattice), which no design can see: T = 0 there.
TEST(LinearTransferTest, FullRasterAtZeroLambdaIsTheIdentityOffTheLattice) {
  const Shape hr{16, 16};
  const MultiFrameModel model = RasterModel(hr, 2, {{0, 0}, {0, 1}, {1, 0}, {1, 1}}, 0.8);
  const TransferGrid g = TikhonovTransferGrid(model, {}, TikhonovOptions{}, 0.0);
  for (Index y = 0; y < hr.rows; ++y)
    for (Index x = 0; x < hr.cols; ++x) {
      const bool lattice = y == 8 || x == 8;  // B vanishes where either axis is on the lattice
      EXPECT_NEAR(std::abs(g.transfer(y, x)), lattice ? 0.0 : 1.0, 1e-8) << y << "," << x;
      EXPECT_NEAR(g.alias(y, x), 0.0, 1e-8) << y << "," << x;
    }
}

// Frame weights enter as AᴴWA: doubling every weight is λ halved; weighting one frame changes T.
TEST(LinearTransferTest, FrameWeightsScaleLikeLambda) {
  const Shape hr{16, 20};
  const MultiFrameModel model = RasterModel(hr, 2, {{0, 0}, {0.5, 1}, {1.2, 0.3}}, 1.0);
  const TikhonovOptions o;
  const TransferGrid a = TikhonovTransferGrid(model, {2, 2, 2}, o, 0.02);
  const TransferGrid b = TikhonovTransferGrid(model, {}, o, 0.01);
  EXPECT_LT((a.transfer - b.transfer).abs().maxCoeff(), 1e-12);
  const TransferGrid c = TikhonovTransferGrid(model, {5, 1, 1}, o, 0.01);
  EXPECT_GT((c.transfer - b.transfer).abs().maxCoeff(), 1e-3);
}

// The kernel curve is |DTFT| of the kernel: on the DFT grid of a kernel as large as the grid, the FFT's modulus.
TEST(LinearTransferTest, KernelCurveIsTheModulusOfTheKernelsTransfer) {
  const Index n = 32;
  Image k = test::GaussianKernel(n, 1.7);
  k(17, 15) += 0.05;  // not symmetric
  k /= k.sum();
  const ComplexImage t = Spectrum(CentredToOrigin(k, {n, n}));
  TransferCurveOptions o;
  o.hr_pixel_box = false;
  o.direction_y = 0.0;
  o.direction_x = 1.0;
  o.curve_step = 1.0 / n;
  const TransferCurve c = KernelTransferCurve(k, o);
  ASSERT_EQ(c.frequency.size(), std::size_t(n / 2 + 1));
  EXPECT_TRUE(c.alias.empty());
  for (std::size_t i = 0; i < c.frequency.size(); ++i) EXPECT_NEAR(c.mtf[i], std::abs(t(0, Index(i))), 1e-12) << i;
  // A diagonal direction (1, 1)/√2 at f = √2·3/n hits bin (3, 3).
  o.direction_y = o.direction_x = 1.0;
  o.frequencies = {std::sqrt(2.0) * 3.0 / n};
  EXPECT_NEAR(KernelTransferCurve(k, o).mtf[0], std::abs(t(3, 3)), 1e-12);
  // With the HR pixel box, the Gaussian's curve is exp(−2π²σ²f²)·sinc(f) (σ in px), up to the sampled kernel's
  // own deviation from it.
  Image g = test::GaussianKernel(n, 1.5);
  TransferCurveOptions ob;
  const TransferCurve cb = KernelTransferCurve(g, ob);
  for (std::size_t i = 0; i < cb.frequency.size(); ++i) {
    const double f = cb.frequency[i];
    const double sinc = f > 0 ? std::sin(kPi * f) / (kPi * f) : 1.0;
    EXPECT_NEAR(cb.mtf[i], std::exp(-2 * kPi * kPi * 1.5 * 1.5 * f * f) * sinc, 1e-4) << f;
  }
}

// The grid curve interpolates T between grid points and is exact on them; the radial average of an isotropic
// transfer is the transfer along any direction; normalise_dc divides by |T(0)|.
TEST(LinearTransferTest, GridCurveOnTheGridRadialAndDc) {
  const Shape hr{40, 40};
  TransferGrid g;
  g.transfer = ComplexImage(hr.rows, hr.cols);
  g.alias = Image::Zero(hr.rows, hr.cols);
  for (Index y = 0; y < hr.rows; ++y)
    for (Index x = 0; x < hr.cols; ++x) {
      const double fy = double(SignedFrequency(y, hr.rows)) / hr.rows, fx = double(SignedFrequency(x, hr.cols)) / hr.cols;
      g.transfer(y, x) = 0.8 * std::exp(-3.0 * (fy * fy + fx * fx)) * std::polar(1.0, 0.3 * std::sin(kTwoPi * fx));
      g.alias(y, x) = 0.1;
    }
  TransferCurveOptions o;
  o.hr_pixel_box = false;
  o.curve_step = 1.0 / hr.cols;
  const TransferCurve c = GridTransferCurve(g, o);
  EXPECT_DOUBLE_EQ(c.dc, 0.8);
  for (std::size_t i = 0; i < c.frequency.size(); ++i) {
    const double f = c.frequency[i];
    EXPECT_NEAR(c.mtf[i], std::exp(-3.0 * f * f), 1e-12) << f;
    EXPECT_NEAR(c.alias[i], 0.1 / 0.8, 1e-12);
  }
  o.radial = true;
  const TransferCurve rc = GridTransferCurve(g, o);
  for (std::size_t i = 0; i < rc.frequency.size(); ++i)
    EXPECT_NEAR(rc.mtf[i], std::exp(-3.0 * rc.frequency[i] * rc.frequency[i]), 2e-3) << rc.frequency[i];
  o.radial = false;
  o.normalise_dc = false;
  EXPECT_NEAR(GridTransferCurve(g, o).mtf[0], 0.8, 1e-15);
}

// SetDirectionFromEdge gives the normal of the edge the slanted-edge method read: n = (cos θ, −sin θ) in (x, y)
// for scene/objects.hpp's edge at θ from the columns, (f_y, f_x) = (−sin θ, cos θ); a near-horizontal edge swaps.
TEST(LinearTransferTest, DirectionFromEdge) {
  SlantedEdgeMtf e;
  e.vertical = true;
  e.angle_deg = 5.0;
  TransferCurveOptions o;
  o.radial = true;
  SetDirectionFromEdge(e, &o);
  EXPECT_FALSE(o.radial);
  EXPECT_NEAR(o.direction_y, -std::sin(5.0 * kPi / 180), 1e-15);
  EXPECT_NEAR(o.direction_x, std::cos(5.0 * kPi / 180), 1e-15);
  e.vertical = false;
  e.angle_deg = -8.0;
  SetDirectionFromEdge(e, &o);
  EXPECT_NEAR(o.direction_y, std::cos(8.0 * kPi / 180), 1e-15);
  EXPECT_NEAR(o.direction_x, std::sin(8.0 * kPi / 180), 1e-15);
}

}  // namespace AOSR_TEST_NS
}  // namespace aosr
