#include "aosr/core/forward_model.hpp"

#include <gtest/gtest.h>

#include <random>
#include <utility>
#include <vector>

#include "aosr/core/adjoint_test.hpp"
#include "aosr/core/error.hpp"
#include "aosr/core/fft.hpp"
#include "aosr/core/operators.hpp"
#include "support/testing.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

Image Random(Shape s, std::uint64_t seed) { return aosr::test::RandomImage(s, seed); }

Image Gaussian(Index n, double sy, double sx, double cy, double cx) {
  Image k(n, n);
  for (Index y = 0; y < n; ++y)
    for (Index x = 0; x < n; ++x) {
      const double dy = y - n / 2 - cy, dx = x - n / 2 - cx;
      k(y, x) = std::exp(-0.5 * (dy * dy / (sy * sy) + dx * dx / (sx * sx)));
    }
  return k / k.sum();
}

MultiFrameModel TestModel(Shape hr, int r) {
  return MultiFrameModel::FromKernels(hr, r, {Gaussian(9, 1.0, 1.3, 0, 0), Gaussian(9, 1.2, 0.9, 0.3, -0.4),
                                              Gaussian(9, 0.8, 1.0, -1, 0.5)});
}

TEST(ForwardModelTest, OperatorPassesAdjointTest) {
  const MultiFrameModel m = TestModel({24, 18}, 3);
  EXPECT_LT(AdjointTest(*m.Operator()).worst(), 1e-10);
  EXPECT_EQ(m.Operator()->rows(), 3 * 8 * 6);
}

// The stacked Operator() runs through the aliasing structure (one HR and N LR FFTs each way); it must be
// the same operator as the per-frame compositions D_r ∘ H_i (FrameOperator), stacked, on even and odd grids,
// and its adjoint the same as theirs summed.
TEST(ForwardModelTest, StackedOperatorEqualsTheFrameOperators) {
  for (auto [hr, r] : std::vector<std::pair<Shape, int>>{{{24, 18}, 3}, {{21, 15}, 3}, {{32, 32}, 4},
                                                         {{20, 30}, 2}, {{14, 18}, 1}}) {
    const MultiFrameModel m = TestModel(hr, r);
    const Index lr = m.lr_shape().size();
    const Vector x = AsVector(Random(hr, 5));
    const Vector y = m.Operator()->Apply(x);
    const Vector v = Vector::Random(y.size());
    Vector adjoint = Vector::Zero(hr.size());
    for (int i = 0; i < m.frames(); ++i) {
      const Vector yi = m.FrameOperator(i)->Apply(x);
      EXPECT_LT((y.segment(i * lr, lr) - yi).norm(), 1e-12 * yi.norm()) << ToString(hr) << " r=" << r;
      adjoint += m.FrameOperator(i)->ApplyAdjoint(v.segment(i * lr, lr));
    }
    EXPECT_LT((m.Operator()->ApplyAdjoint(v) - adjoint).norm(), 1e-12 * adjoint.norm()) << ToString(hr);
    EXPECT_LT(AdjointTest(*m.Operator()).worst(), 1e-10) << ToString(hr);
  }
}

// The aliasing formula in forward_model.hpp, checked against the spatial operator: for every LR bin u,
// FFT(y_i)(u) == Σ_k A(u)_{ik} X(u + k∘m).
TEST(ForwardModelTest, AliasedSystemMatchesSpatialRendering) {
  for (int r : {2, 3}) {
    const Shape hr{12 * r / 2 * 2, 10 * r / 2 * 2};
    const MultiFrameModel m = TestModel(hr, r);
    const Image x = Random(hr, 3);
    const ImageStack frames = m.Render(x);
    const ComplexImage X = FftForward(x.cast<Complex>());
    std::vector<ComplexImage> Y;
    for (const Image& f : frames) Y.push_back(FftForward(f.cast<Complex>()));
    const Shape lr = m.lr_shape();
    double worst = 0, scale = 0;
    for (Index uy = 0; uy < lr.rows; ++uy)
      for (Index ux = 0; ux < lr.cols; ++ux) {
        const Eigen::MatrixXcd a = m.AliasedSystem(uy, ux);
        Eigen::VectorXcd xk(r * r);
        for (int ky = 0; ky < r; ++ky)
          for (int kx = 0; kx < r; ++kx) xk[ky * r + kx] = X(uy + ky * lr.rows, ux + kx * lr.cols);
        const Eigen::VectorXcd pred = a * xk;
        for (int i = 0; i < m.frames(); ++i) {
          worst = std::max(worst, std::abs(pred[i] - Y[i](uy, ux)));
          scale = std::max(scale, std::abs(Y[i](uy, ux)));
        }
      }
    EXPECT_LT(worst, 1e-12 * scale) << "r = " << r;
  }
}

TEST(ForwardModelTest, PixelTransferVanishesOnTheAliasLattice) {
  const MultiFrameModel m = TestModel({16, 16}, 2);
  EXPECT_NEAR(std::abs(m.PixelTransfer(0, 0)), 4.0, 1e-12);
  EXPECT_NEAR(std::abs(m.PixelTransfer(8, 0)), 0.0, 1e-12);
  EXPECT_NEAR(std::abs(m.PixelTransfer(3, 8)), 0.0, 1e-12);
  EXPECT_GT(std::abs(m.PixelTransfer(7, 7)), 0.1);
}

TEST(ForwardModelTest, RenderConservesFlux) {
  const MultiFrameModel m = TestModel({32, 32}, 4);
  Image x = Random({32, 32}, 9).abs();
  for (const Image& f : m.Render(x)) EXPECT_NEAR(f.sum(), x.sum(), 1e-12 * x.sum());
}

// The space-variant extension (WithPsfField): an exact adjoint; the stacked and per-frame operators agree; with
// the same PSFs at every node it is the isoplanatic model (the weights sum to 1); a point at a node is imaged
// through that node's PSFs alone; the Fourier structure stays the model's own.
TEST(ForwardModelTest, SpaceVariantModelExtendsTheIsoplanaticOne) {
  const Shape hr{24, 18};
  const MultiFrameModel m = TestModel(hr, 3);
  const PsfFieldGrid grid(hr, 2, 3);
  std::vector<ImageStack> nodes;
  for (int k = 0; k < grid.nodes(); ++k)
    nodes.push_back({Gaussian(9, 0.6 + 0.2 * k, 1.0, 0, 0), Gaussian(9, 1.0, 0.5 + 0.15 * k, 0.2, 0),
                     Gaussian(9, 1.0, 1.0, 0, -0.3 * k)});
  const MultiFrameModel v = m.WithPsfField(grid, nodes);
  EXPECT_TRUE(v.space_variant());
  EXPECT_FALSE(m.space_variant());
  EXPECT_LT(AdjointTest(*v.Operator()).worst(), 1e-10);
  EXPECT_LT(AdjointTest(*v.FrameOperator(1)).worst(), 1e-10);
  const Image x = Random(hr, 5);
  const Vector stacked = v.Operator()->Apply(AsVector(x));
  const Index lr = v.lr_shape().size();
  for (int i = 0; i < 3; ++i)
    EXPECT_LT((stacked.segment(i * lr, lr) - v.FrameOperator(i)->Apply(AsVector(x))).cwiseAbs().maxCoeff(),
              1e-12 * stacked.cwiseAbs().maxCoeff());
  // The same PSFs everywhere: the isoplanatic model.
  std::vector<ImageStack> same(grid.nodes(), {Gaussian(9, 1.0, 1.3, 0, 0), Gaussian(9, 1.2, 0.9, 0.3, -0.4),
                                              Gaussian(9, 0.8, 1.0, -1, 0.5)});
  const Vector a = m.WithPsfField(grid, same).Operator()->Apply(AsVector(x)), b = m.Operator()->Apply(AsVector(x));
  EXPECT_LT((a - b).cwiseAbs().maxCoeff(), 1e-12 * b.cwiseAbs().maxCoeff());
  // A point at node 5 (HR (23, 17), the last pixel) is seen through node 5's PSFs only.
  Image point = Image::Zero(hr.rows, hr.cols);
  point(23, 17) = 1.0;
  const ImageStack seen = v.Render(point);
  const ImageStack expected = MultiFrameModel::FromKernels(hr, 3, nodes[5]).Render(point);
  for (int i = 0; i < 3; ++i) EXPECT_LT((seen[i] - expected[i]).abs().maxCoeff(), 1e-14) << i;
  // The Fourier structure is the isoplanatic model's, and Isoplanatic() drops the field.
  EXPECT_EQ(v.Otf(1, 2, 3), m.Otf(1, 2, 3));
  EXPECT_FALSE(v.Isoplanatic().space_variant());
  EXPECT_THROW(m.WithPsfField(PsfFieldGrid({12, 18}, 2, 2), nodes), InvalidArgument);
  EXPECT_THROW(m.WithPsfField(grid, {nodes[0]}), InvalidArgument);
  EXPECT_THROW(m.WithPsfField(grid, std::vector<ImageStack>(6, ImageStack{Gaussian(9, 1, 1, 0, 0)})), InvalidArgument);
}

}  // namespace
}  // namespace aosr
