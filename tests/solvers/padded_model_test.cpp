#include "aosr/solvers/padded_model.hpp"

#include <gtest/gtest.h>

#include "aosr/core/adjoint_test.hpp"
#include "aosr/core/fft.hpp"
#include "solvers/tikhonov_fixture.hpp"
#include "support/testing.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

using test::GaussianKernel;

ImageStack Kernels() {
  // Two compact kernels: a Gaussian and an off-centre (asymmetric) one, so a wrong flip shows.
  Image k2 = Image::Zero(5, 5);
  k2(2, 2) = 0.5;
  k2(1, 3) = 0.3;
  k2(4, 0) = 0.2;
  return {GaussianKernel(7, 1.0), k2};
}

// C ∘ D_r ∘ H_i and its adjoint, for both constructions, r = 2 and 3, with and without padding.
TEST(PaddedModelTest, OperatorPassesTheAdjointTest) {
  for (int r : {2, 3})
    for (int pad : {0, 1, 3}) {
      const Shape hr{10 * r, 7 * r};
      const PaddedModel a = PaddedModel::FromKernels(hr, r, Kernels(), pad);
      const PaddedModel b =
          PaddedModel::FromPeriodicModel(MultiFrameModel::FromKernels(hr, r, Kernels()), pad);
      for (const PaddedModel* m : {&a, &b}) {
        EXPECT_EQ(m->Operator()->cols(), m->padded_hr_shape().size());
        EXPECT_EQ(m->Operator()->rows(), 2 * hr.size() / (r * r));
        const AdjointTestResult t = AdjointTest(*m->Operator(), 7);
        EXPECT_LT(t.worst(), 1e-10) << "r=" << r << " pad=" << pad << " " << m->Operator()->name();
      }
    }
}

// An object that stays a PSF radius away from the window's edges never meets the boundary: the padded and
// the periodic models render the same frames; and both constructions are the same model.
TEST(PaddedModelTest, InteriorObjectsDoNotSeeTheBoundary) {
  const int r = 2;
  const Shape hr{24, 28};
  const MultiFrameModel periodic = MultiFrameModel::FromKernels(hr, r, Kernels());
  const PaddedModel padded = PaddedModel::FromPeriodicModel(periodic, 3);
  const PaddedModel direct = PaddedModel::FromKernels(hr, r, Kernels(), 3);
  EXPECT_EQ(padded.padded_hr_shape(), (Shape{NextFastFftSize(12 + 6) * r, NextFastFftSize(14 + 6) * r}));
  Image x = Image::Zero(hr.rows, hr.cols);
  x.block(4, 4, hr.rows - 8, hr.cols - 8) = test::RandomImage({hr.rows - 8, hr.cols - 8}, 3, false);
  const ImageStack a = periodic.Render(x), b = padded.Render(padded.EmbedObject(x)),
                   c = direct.Render(direct.EmbedObject(x));
  for (int i = 0; i < 2; ++i) {
    EXPECT_LT((a[i] - b[i]).abs().maxCoeff(), 1e-12);
    EXPECT_LT((c[i] - b[i]).abs().maxCoeff(), 1e-12);
  }
  EXPECT_EQ(padded.CropObject(padded.EmbedObject(x)).matrix(), x.matrix());
}

// A point source on the window's left edge: the periodic model wraps part of its light to the right edge;
// the padded model keeps it on the left and loses what falls outside (flux in = flux seen + flux outside).
TEST(PaddedModelTest, EdgeLightDoesNotWrap) {
  const int r = 2;
  const Shape hr{20, 20};
  const ImageStack psf = {GaussianKernel(9, 1.5)};
  const MultiFrameModel periodic = MultiFrameModel::FromKernels(hr, r, psf);
  const PaddedModel padded = PaddedModel::FromKernels(hr, r, psf, 3);
  Image x = Image::Zero(hr.rows, hr.cols);
  x(10, 0) = 1.0;
  const Image wrapped = periodic.Render(x)[0], seen = padded.Render(padded.EmbedObject(x))[0];
  EXPECT_GT(wrapped.col(9).sum(), 0.05);          // light wrapped to the far edge
  EXPECT_LT(std::abs(seen.col(9).sum()), 1e-15);  // none here
  EXPECT_NEAR(wrapped.sum(), 1.0, 1e-12);         // periodic: all flux stays in the window
  // Padded: the flux left of the window is the kernel's mass at offsets < 0 (|dx| of the 9x9 kernel).
  const Image k = psf[0];
  EXPECT_NEAR(seen.sum(), k.rightCols(5).sum(), 1e-12);
}

// The suggested padding covers the PSF: a wider Gaussian needs more, a delta needs the minimum (1).
TEST(PaddedModelTest, SuggestedPaddingFollowsThePsfExtent) {
  const Shape hr{64, 64};
  Image delta = Image::Zero(3, 3);
  delta(1, 1) = 1;
  EXPECT_EQ(PaddedModel::SuggestPadding(MultiFrameModel::FromKernels(hr, 2, {delta})), 1);
  const int narrow =
      PaddedModel::SuggestPadding(MultiFrameModel::FromKernels(hr, 2, {GaussianKernel(31, 1.0)}));
  const int wide =
      PaddedModel::SuggestPadding(MultiFrameModel::FromKernels(hr, 2, {GaussianKernel(31, 3.0)}));
  EXPECT_LT(narrow, wide);
  // A Gaussian's energy beyond 3σ·√2 per axis is ~1e-5 of the total: the padding reaches about there.
  EXPECT_GE(2 * wide, 3 * 3.0);
  EXPECT_LE(2 * wide, 6 * 3.0);
}

}  // namespace
}  // namespace aosr
