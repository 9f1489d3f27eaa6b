#include "aosr/solvers/fourier_normal_system.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include "aosr/core/error.hpp"
#include "aosr/core/operators.hpp"
#include "aosr/core/parallel.hpp"
#include "aosr/solvers/tikhonov.hpp"
#include "solvers/tikhonov_internal.hpp"  // the library's solvers/ folder (tests/CMakeLists.txt)
#include "support/testing.hpp"
#include "total_variation_fixture.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

using tv_test::RasterModel;

std::vector<std::pair<double, double>> Shifts(int n) {
  std::vector<std::pair<double, double>> s;
  for (int i = 0; i < n; ++i) s.push_back({0.37 * i, 0.61 * ((i * 3) % 5)});
  return s;
}

// The spatial operator w AᵀA + a ∇ᵀ∇ + b I, built independently from the core primitives.
OperatorPtr SpatialNormal(const MultiFrameModel& m, double w, double a, double b) {
  const Shape hr = m.hr_shape();
  return Sum({Scale(w, Normal(m.Operator())), Scale(a, Normal(Gradient(hr, Boundary::kPeriodic))),
              Scale(b, Identity(hr.size()))});
}

// Every per-bin form (Woodbury where N < r², the dense Cholesky where N >= r² or where the Woodbury
// subtraction would cancel, i.e. the lowest frequencies without the identity term) solves the system: the
// residual in the spatial operator is at rounding level, including r = 8 (64 x 64 bins).
TEST(FourierNormalSystemTest, EveryBinFormSolvesTheSystem) {
  struct Case {
    int r, frames;
    double a, b;
  };
  for (const Case& c : std::vector<Case>{{2, 2, 0.7, 0.0},
                                         {2, 6, 0.7, 0.3},
                                         {3, 4, 0.7, 0.3},
                                         {4, 3, 1.3, 0.0},
                                         {4, 20, 0.2, 0.1},
                                         {8, 4, 0.9, 0.0},
                                         {8, 4, 0.9, 0.05}}) {
    const Shape hr{c.r * (12 / c.r + 2), c.r * (12 / c.r + 3)};  // at least the 11 x 11 PSF
    const auto m = RasterModel(hr, c.r, Shifts(c.frames), 0.9);
    const double w = 3.0;
    FourierNormalSystem system(*m, w);
    system.Factorize(c.a, c.b);
    const Image rhs = test::RandomImage(hr, 17);
    const Image x = system.Solve(rhs);
    const Vector res = SpatialNormal(*m, w, c.a, c.b)->Apply(AsVector(x)) - AsVector(rhs);
    EXPECT_LT(res.norm() / AsVector(rhs).norm(), 1e-10) << "r=" << c.r << " N=" << c.frames;
    EXPECT_EQ(system.singular_bins(), 0);
    if (c.frames < c.r * c.r) {
      EXPECT_GT(system.woodbury_bins(), system.bins() / 2) << "r=" << c.r << " N=" << c.frames;
    } else {
      EXPECT_EQ(system.woodbury_bins(), 0);
    }
  }
}

// A general penalty symbol (Factorize(penalty)): D(u) = λ|Γ(f)|² of every Tikhonov prior, the preconditioner of
// the weighted Tikhonov path (tikhonov_cg.cpp). The oracle is the spatial operator w AᵀA + λΓᵀΓ built from the
// prior's own operator; NormalSystemInverse applies the same solve. The gradient symbol given as an image gives
// the bits of Factorize(λ, 0), whose symbol is the same arithmetic.
TEST(FourierNormalSystemTest, APenaltySymbolSolvesEveryTikhonovPrior) {
  for (const auto& [r, frames] : std::vector<std::pair<int, int>>{{2, 3}, {4, 3}, {4, 16}}) {
    const Shape hr{r * (12 / r + 2), r * (12 / r + 3)};
    const auto m = RasterModel(hr, r, Shifts(frames), 0.9);
    const double w = 2.5, lambda = 0.3;
    const Image rhs = test::RandomImage(hr, 23);
    for (TikhonovPrior prior : {TikhonovPrior::kIdentity, TikhonovPrior::kGradient, TikhonovPrior::kLaplacian,
                                TikhonovPrior::kPowerSpectrum}) {
      TikhonovOptions o;
      o.prior = prior;
      auto system = std::make_shared<FourierNormalSystem>(*m, w);
      system->Factorize(lambda * tikhonov_internal::PriorSymbolImage(o, hr));
      const Image x = system->Solve(rhs);
      const OperatorPtr normal =
          Sum({Scale(w, Normal(m->Operator())), Scale(lambda, Normal(TikhonovPriorOperator(hr, o)))});
      const std::string what = std::string(ToString(prior)) + ", r = " + std::to_string(r) + ", N = " +
                               std::to_string(frames);
      EXPECT_LT((normal->Apply(AsVector(x)) - AsVector(rhs)).norm() / AsVector(rhs).norm(), 1e-10) << what;
      EXPECT_EQ(system->singular_bins(), 0) << what;
      const OperatorPtr inverse = NormalSystemInverse(system);
      const Vector via_operator = inverse->Apply(AsVector(rhs));
      EXPECT_EQ((via_operator - AsVector(x)).cwiseAbs().maxCoeff(), 0.0) << what;
      // Adjointness (G⁻¹ is Hermitian): <G⁻¹u, v> = <u, G⁻¹v> for random u, v, and the adjoint is the same map.
      const Vector u = AsVector(test::RandomImage(hr, 31)), v = AsVector(test::RandomImage(hr, 32));
      const double lhs = inverse->Apply(u).dot(v), rhs_dot = u.dot(inverse->Apply(v));
      EXPECT_NEAR(lhs, rhs_dot, 1e-12 * std::abs(lhs)) << what;
      EXPECT_EQ((inverse->ApplyAdjoint(v) - inverse->Apply(v)).cwiseAbs().maxCoeff(), 0.0) << what;
      if (prior == TikhonovPrior::kGradient) {
        FourierNormalSystem same(*m, w);
        same.Factorize(lambda, 0.0);
        EXPECT_TRUE((same.Solve(rhs) == x).all()) << what;
      }
    }
  }
  FourierNormalSystem system(*RasterModel({16, 16}, 2, Shifts(2), 0.9), 1.0);
  EXPECT_THROW(system.Factorize(Image::Constant(16, 16, -1.0)), InvalidArgument);
  EXPECT_THROW(system.Factorize(Image::Constant(8, 16, 1.0)), InvalidArgument);
  EXPECT_THROW(NormalSystemInverse(nullptr), InvalidArgument);
}

// Ill-conditioned bins: a small gradient weight and no identity term make D(u) small beside the data at low
// frequencies; those bins fall back to the dense form (the Woodbury subtraction would cancel), and the
// solution stays accurate. The spatial residual's floor is rounding in the operators times the condition
// number (~1e10 in the second case, where Eigen's own LLT per bin gives the same 5e-6).
TEST(FourierNormalSystemTest, IllConditionedBinsStayAccurate) {
  const int r = 4;
  const Shape hr{16 * r, 16 * r};
  const auto m = RasterModel(hr, r, Shifts(3), 0.9);
  for (auto [w, a, tolerance] : std::vector<std::tuple<double, double, double>>{{1.0, 1e-4, 1e-8},
                                                                               {1e4, 1e-6, 1e-4}}) {
    FourierNormalSystem system(*m, w);
    system.Factorize(a, 0.0);
    EXPECT_LT(system.woodbury_bins(), system.bins());
    EXPECT_EQ(system.singular_bins(), 0);
    const Image rhs = test::RandomImage(hr, 3);
    const Image x = system.Solve(rhs);
    const Vector res = SpatialNormal(*m, w, a, 0.0)->Apply(AsVector(x)) - AsVector(rhs);
    EXPECT_LT(res.norm() / AsVector(rhs).norm(), tolerance) << "w=" << w << " a=" << a;
  }
}

// SolveWithData is Solve of rhs + w Aᵀv, and its model frames are A x.
TEST(FourierNormalSystemTest, SolveWithDataAddsTheDataTermAndReturnsTheModelFrames) {
  for (auto [r, frames] : std::vector<std::pair<int, int>>{{2, 3}, {2, 5}, {3, 4}, {4, 2}}) {
    const Shape hr{r * (12 / r + 3), r * (12 / r + 2)};
    const auto m = RasterModel(hr, r, Shifts(frames), 1.1);
    const double w = 0.6;
    FourierNormalSystem system(*m, w);
    system.Factorize(0.4, 0.2);
    const Image rhs = test::RandomImage(hr, 1);
    ImageStack v;
    for (int i = 0; i < frames; ++i) v.push_back(test::RandomImage(m->lr_shape(), 100 + i));
    Image x;
    ImageStack ax;
    system.SolveWithData(rhs, v, &x, &ax);
    const Vector full = AsVector(rhs) + w * m->Operator()->ApplyAdjoint(m->Flatten(v));
    const Image expected = system.Solve(ToImage(full, hr));
    EXPECT_LT((AsVector(x) - AsVector(expected)).norm() / AsVector(expected).norm(), 1e-12) << "r=" << r;
    const Vector ax_expected = m->Operator()->Apply(AsVector(x));
    EXPECT_LT((m->Flatten(ax) - ax_expected).norm() / ax_expected.norm(), 1e-12) << "r=" << r;
  }
}

// ||A||₂ is the largest gain of the model: no image exceeds it, and power iteration on AᵀA reaches it.
TEST(FourierNormalSystemTest, ModelNormIsTheOperatorNorm) {
  const Shape hr{24, 32};
  const auto m = RasterModel(hr, 2, Shifts(3), 1.0);
  const FourierNormalSystem system(*m, 1.0);
  const OperatorPtr normal = Normal(m->Operator());
  Vector x = AsVector(test::RandomImage(hr, 9));
  double gain = 0;
  for (int k = 0; k < 300; ++k) {
    x /= x.norm();
    gain = std::sqrt(x.dot(normal->Apply(x)));
    x = normal->Apply(x);
  }
  EXPECT_LE(gain, system.ModelNorm() * (1 + 1e-12));
  EXPECT_GT(gain, system.ModelNorm() * (1 - 1e-3));
}

// Bins are solved in parallel; each writes only its own values, so 1 and 2 threads agree bit for bit.
TEST(FourierNormalSystemTest, OneAndTwoThreadsGiveIdenticalBits) {
  const Shape hr{64, 48};
  const auto m = RasterModel(hr, 4, Shifts(3), 1.0);
  const Image rhs = test::RandomImage(hr, 4);
  ImageStack v;
  for (int i = 0; i < 3; ++i) v.push_back(test::RandomImage(m->lr_shape(), 40 + i));
  std::vector<Image> xs;
  std::vector<ImageStack> axs;
  const int saved = DefaultThreads();
  for (int threads : {1, 2}) {
    SetDefaultThreads(threads);
    FourierNormalSystem system(*m, 2.0);
    system.Factorize(0.5, 0.0);
    Image x;
    ImageStack ax;
    system.SolveWithData(rhs, v, &x, &ax);
    xs.push_back(x);
    axs.push_back(ax);
  }
  SetDefaultThreads(saved);
  EXPECT_TRUE((xs[0] == xs[1]).all());
  for (int i = 0; i < 3; ++i) EXPECT_TRUE((axs[0][i] == axs[1][i]).all());
}

}  // namespace
}  // namespace aosr
