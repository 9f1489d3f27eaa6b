// Tikhonov's posterior std map by perturbation-optimisation draws (weighted, masked and zero-padded problems)
// against the closed form where both exist, with the draws' own standard errors as the yardstick.
#include <gtest/gtest.h>

#include "aosr/core/operators.hpp"
#include "aosr/solvers/tikhonov.hpp"
#include "solvers/tikhonov_fixture.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

TEST(TikhonovStdPhysicsTest, PosteriorDrawsMatchTheClosedFormWithinTheirErrorBars) {
  const Shape hr{32, 32};
  auto m = std::make_shared<MultiFrameModel>(test::RasterModel(hr, 2, {{0, 0}, {0, 1}, {1, 0}}, 0.9));
  ReconstructionProblem p;
  p.model = m;
  p.frames = m->Render(Image::Zero(32, 32));
  for (int i = 0; i < 3; ++i) p.weights.push_back(Image::Constant(16, 16, 2.0));
  TikhonovOptions o;
  o.lambda = 0.05;
  o.noise_sigma = 1.5;
  o.compute_std = true;
  const TikhonovResult exact = ReconstructTikhonov(p, o);
  ASSERT_EQ(exact.summary.std_samples, 0);
  ASSERT_TRUE(exact.summary.std_computed);
  // The same problem on the CG path (one weight off by 1e-12): the map is drawn.
  p.weights[1](5, 5) = 2.0 * (1 + 1e-12);
  o.std_samples = 64;
  o.std_seed = 9;
  const TikhonovResult drawn = ReconstructTikhonov(p, o);
  ASSERT_EQ(drawn.summary.std_samples, 64);
  ASSERT_TRUE(drawn.summary.std_computed);
  double z2 = 0;
  for (Index k = 0; k < exact.posterior_std.size(); ++k) {
    const double z = (drawn.posterior_std.data()[k] - exact.posterior_std.data()[k]) / drawn.posterior_std_error.data()[k];
    z2 += z * z;
  }
  z2 /= double(exact.posterior_std.size());
  EXPECT_GT(z2, 0.5);  // honest error bars: z-scores of unit variance
  EXPECT_LT(z2, 1.6);
  EXPECT_NEAR(drawn.summary.mean_posterior_variance, exact.summary.mean_posterior_variance,
              0.05 * exact.summary.mean_posterior_variance);
}

// Masked pixels: no closed form, so the oracle is the dense inverse of Q = AᵀWA + λΓᵀΓ built column by column.
TEST(TikhonovStdPhysicsTest, DrawsOnMaskedDataMatchTheDenseInverse) {
  const Shape hr{16, 16};
  auto m = std::make_shared<MultiFrameModel>(test::RasterModel(hr, 2, {{0, 0}, {0, 1}, {1, 0}, {1, 1}}, 0.9));
  ReconstructionProblem p;
  p.model = m;
  p.frames = m->Render(Image::Zero(16, 16));
  Image w_stack(4 * 8, 8);
  for (int i = 0; i < 4; ++i) {
    Image w = Image::Constant(8, 8, 1.0 + 0.25 * i);
    w.block(3, 3, 2, 2) = 0;  // the same patch lost in every frame
    p.weights.push_back(w);
    w_stack.middleRows(8 * i, 8) = w;
  }
  TikhonovOptions o;
  o.lambda = 0.05;
  o.noise_sigma = 1.0;
  o.compute_std = true;
  o.std_samples = 64;
  const TikhonovResult r = ReconstructTikhonov(p, o);
  ASSERT_TRUE(r.summary.std_computed) << r.summary.message;
  ASSERT_EQ(r.summary.std_samples, 64);
  const OperatorPtr a = m->Operator();
  const OperatorPtr q = Sum({Compose(Adjoint(a), Compose(Mask(w_stack), a)),
                             Scale(o.lambda, Normal(TikhonovPriorOperator(hr, o)))});
  Eigen::MatrixXd dense(hr.size(), hr.size());
  for (Index k = 0; k < hr.size(); ++k) dense.col(k) = q->Apply(Vector::Unit(hr.size(), k));
  const Eigen::VectorXd var = dense.inverse().diagonal();
  double z2 = 0;
  for (Index k = 0; k < hr.size(); ++k) {
    const double z = (r.posterior_std.data()[k] - std::sqrt(var[k])) / r.posterior_std_error.data()[k];
    z2 += z * z;
  }
  z2 /= double(hr.size());
  EXPECT_GT(z2, 0.5);
  EXPECT_LT(z2, 1.6);
}

}  // namespace
}  // namespace aosr
