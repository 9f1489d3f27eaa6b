// Objective A (design_objective.hpp): Taylor tests of its gradient through every parameterisation, the
// special case A = A0 against the Tikhonov posterior variance, and the objective's structure.
#include "aosr/design/design_objective.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <random>

#include "aosr/core/fft.hpp"
#include "aosr/solvers/tikhonov.hpp"
#include "design/design_fixture.hpp"
#include "support/testing.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

using design_test::SmallOptics;
using design_test::SmallPupil;
using design_test::TaylorAwayFromRaster;

// Objective A as a function of θ, through the parameterisation.
void ExpectQuadraticRemainders(const std::vector<double>& ratios, const std::vector<double>& rem, const std::string& what) {
  ASSERT_FALSE(ratios.empty());
  std::string all;
  for (double r : ratios) all += " " + ToString(r);
  std::printf("%s: Taylor remainder ratios%s\n", what.c_str(), all.c_str());
  // The first halvings may still see third-order terms; the last three must be quadratic.
  for (std::size_t k = ratios.size() - 3; k < ratios.size(); ++k) {
    EXPECT_GT(rem[k + 1], 1e-14) << what << ": remainder at rounding level, the test is blind";
    EXPECT_NEAR(ratios[k], 4.0, 0.4) << what << " halving " << k;
  }
}

struct Case {
  DesignParameterisationKind kind;
  bool ao;
  int realisations;
  double rms_max_m;
  double strehl_min;
  TikhonovPrior prior;
};

TEST(DesignObjectiveTest, TaylorTestThroughEveryParameterisation) {
  const Case cases[] = {
      {DesignParameterisationKind::kTipTilt, false, 0, 0.0, 0.0, TikhonovPrior::kGradient},
      {DesignParameterisationKind::kTipTilt, true, 2, 400e-9, 0.0, TikhonovPrior::kIdentity},
      {DesignParameterisationKind::kZernike, false, 0, 0.0, 0.0, TikhonovPrior::kPowerSpectrum},
      {DesignParameterisationKind::kZernike, true, 2, 500e-9, 0.7, TikhonovPrior::kGradient},
      {DesignParameterisationKind::kActuators, false, 0, 0.0, 0.0, TikhonovPrior::kLaplacian},
      {DesignParameterisationKind::kActuators, true, 1, 500e-9, 0.6, TikhonovPrior::kIdentity},
  };
  int seed = 7;
  for (const Case& c : cases) {
    const DesignOptics optics = SmallOptics(c.ao);
    DesignObjectiveOptions o;
    o.reconstructor.prior = c.prior;
    o.reconstructor.lambda = 0.05;
    o.realisations = c.realisations;
    o.screens = 2;
    const DesignObjective f(optics, 3, o);
    DesignParameterisationOptions po;
    po.kind = c.kind;
    po.zernike_modes = 6;
    po.rms_max_m = c.rms_max_m;
    po.strehl_min = c.strehl_min;
    const DesignParameterisation p(SmallPupil(optics), 3, 2, po);
    std::vector<double> rem;
    const std::vector<double> ratios = TaylorAwayFromRaster(f, p, seed++, &rem);
    ExpectQuadraticRemainders(ratios, rem, std::string(ToString(c.kind)) + (c.ao ? " ao" : ""));
  }
}

// With A = A0 and the Wiener-consistent prior, objective A is the mean posterior variance of tikhonov.hpp (6).
TEST(DesignObjectiveTest, EqualsTheTikhonovPosteriorVarianceWhenModelsMatch) {
  for (int frames : {2, 4}) {
    const DesignOptics optics = SmallOptics(/*ao=*/true);
    DesignObjectiveOptions o;
    o.reconstructor.prior = TikhonovPrior::kPowerSpectrum;
    o.reconstructor.lambda = 0.02;
    o.noise_sigma = 0.3;
    o.realisations = 0;
    const DesignObjective f(optics, frames, o);
    DesignParameterisationOptions po;
    po.kind = DesignParameterisationKind::kZernike;
    po.zernike_modes = 5;
    const DesignParameterisation p(SmallPupil(optics), frames, 2, po);
    Vector theta = p.RasterParameters();
    theta[2] += 1e-7;  // some defocus on exposure 0
    const std::vector<Image> opds = p.Opds(theta);
    const double j = f.Evaluate(opds);
    ReconstructionProblem problem;
    problem.model = std::make_shared<MultiFrameModel>(f.NominalModel(opds));
    problem.frames.assign(frames, Image::Zero(8, 8));
    TikhonovOptions t = o.reconstructor;
    t.noise_sigma = o.noise_sigma;
    t.compute_std = true;
    const TikhonovResult res = ReconstructTikhonov(problem, t);
    ASSERT_TRUE(res.summary.std_computed);
    EXPECT_NEAR(j, res.summary.mean_posterior_variance, 1e-9 * j) << "N = " << frames;
    // The engine on the models agrees with Evaluate.
    EXPECT_NEAR(ExpectedTikhonovMse(*problem.model, {}, o.reconstructor, o.noise_sigma), j, 1e-12 * j);
  }
}

// The nominal model's kernels are unit-sum PSFs: H(0) = 1; the AO factor is 1 at f = 0 and < 1 elsewhere.
TEST(DesignObjectiveTest, NominalModelIsUnitSumAndAoAttenuates) {
  const DesignOptics optics = SmallOptics(true);
  DesignObjectiveOptions o;
  o.realisations = 1;
  o.screens = 2;
  const DesignObjective f(optics, 2, o);
  const std::vector<Image> zero(2, Image::Zero(32, 32));
  const MultiFrameModel m = f.NominalModel(zero);
  EXPECT_NEAR(std::abs(m.Otf(0, 0, 0) - 1.0), 0.0, 1e-12);
  EXPECT_DOUBLE_EQ(f.ao_factor()(0, 0), 1.0);
  EXPECT_LT(f.ao_factor()(4, 3), 1.0);
  const std::vector<MultiFrameModel> real = f.RealisedModels(zero);
  ASSERT_EQ(real.size(), 1u);
  EXPECT_NEAR(std::abs(real[0].Otf(1, 0, 0) - 1.0), 0.0, 1e-12);
  // Mismatch costs: the realised systems differ from the nominal one.
  DesignObjectiveOptions o0 = o;
  o0.realisations = 0;
  EXPECT_NE(f.Evaluate(zero), DesignObjective(optics, 2, o0).Evaluate(zero));
}

}  // namespace
}  // namespace aosr
