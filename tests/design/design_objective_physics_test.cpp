// Objective A against Monte-Carlo reconstructions, and where phase diversity pays (design_objective.hpp,
// design_optimizer.hpp). Small grids: a 32-pixel pupil of an 8 m telescope in K band, camera pixel λ/D.
#include <gtest/gtest.h>

#include <cstdio>
#include <random>

#include "aosr/core/fft.hpp"
#include "aosr/design/design_objective.hpp"
#include "aosr/design/design_optimizer.hpp"
#include "aosr/solvers/tikhonov.hpp"
#include "design/design_fixture.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

using design_test::DrawObject;
using design_test::SmallOptics;
using design_test::SmallPupil;

// Predicted (objective A) vs measured MSE of Tikhonov reconstructions with the nominal model, frames made by
// the realised PSFs (mismatch included), objects drawn from the prior, Gaussian noise: 240 realisations
// (120 per PSF realisation), seed 11, tolerance 5%.
TEST(DesignObjectivePhysicsTest, PredictedMseMatchesMonteCarloWithin5Percent) {
  const DesignOptics optics = SmallOptics(/*ao=*/true, /*grid=*/32);
  for (int realisations : {0, 2}) {
    DesignObjectiveOptions o;
    o.reconstructor.prior = TikhonovPrior::kPowerSpectrum;
    o.reconstructor.lambda = 0.05;
    o.noise_sigma = 0.1;
    o.realisations = realisations;
    o.screens = 2;
    const int frames = 3;
    const DesignObjective f(optics, frames, o);
    DesignParameterisationOptions po;
    po.kind = DesignParameterisationKind::kZernike;
    po.zernike_modes = 6;
    const DesignParameterisation p(SmallPupil(optics), frames, 2, po);
    Vector theta = p.RasterParameters();
    theta[2] += 80e-9;  // defocus on exposure 0, astigmatism on exposure 1
    theta[9] -= 60e-9;
    const std::vector<Image> opds = p.Opds(theta);
    const double predicted = f.Evaluate(opds);
    const MultiFrameModel nominal = f.NominalModel(opds);
    std::vector<MultiFrameModel> truths = f.RealisedModels(opds);
    if (truths.empty()) truths.push_back(nominal);
    std::mt19937_64 rng(11);
    std::normal_distribution<double> n01;
    const int trials = 240;
    double measured = 0;
    for (int t = 0; t < trials; ++t) {
      const Image x = DrawObject(f.object_spectrum(), rng);
      ImageStack y = truths[t % truths.size()].Render(x);
      for (Image& fr : y)
        for (Index k = 0; k < fr.size(); ++k) fr.data()[k] += o.noise_sigma * n01(rng);
      const Image xhat = TikhonovFourier(nominal, y, o.reconstructor);
      measured += (xhat - x).square().mean() / trials;
    }
    std::printf("R = %d: predicted MSE %.6g, measured %.6g over %d trials (ratio %.4f)\n", realisations, predicted,
                measured, trials, measured / predicted);
    EXPECT_NEAR(measured / predicted, 1.0, 0.05) << "R = " << realisations << ", seed 11";
  }
}

struct Outcome {
  double raster, final;
};

Outcome Optimise(const DesignOptics& optics, int frames, DesignParameterisationKind kind, int realisations) {
  DesignObjectiveOptions o;
  o.reconstructor.prior = TikhonovPrior::kPowerSpectrum;
  o.reconstructor.lambda = 0.01;
  o.realisations = realisations;
  o.screens = 2;
  const DesignObjective f(optics, frames, o);
  DesignParameterisationOptions po;
  po.kind = kind;
  po.zernike_modes = 6;
  const DesignParameterisation p(SmallPupil(optics), frames, optics.r, po);
  DesignOptimizerOptions oo;
  oo.starts = 2;
  oo.max_iterations = 60;
  const DesignResult r = OptimizeDesign(f, p, oo);
  std::printf("N = %d, r = %d, %s, R = %d: %s\n", frames, optics.r, ToString(kind), realisations,
              r.summary.FullReport().c_str());
  EXPECT_LE(r.summary.final_objective, r.summary.initial_objective);
  return {r.summary.raster_objective, r.summary.final_objective};
}

// Idealised model (no AO, no mismatch), N = r² = 4: the half-pixel raster is already (near-)optimal; what
// the optimiser finds is within 1% of it (typically a translated copy: a common shift changes nothing).
TEST(DesignObjectivePhysicsTest, RasterIsNearOptimalInTheIdealisedCase) {
  const DesignOptics optics = SmallOptics(/*ao=*/false);
  for (DesignParameterisationKind kind : {DesignParameterisationKind::kTipTilt, DesignParameterisationKind::kZernike}) {
    const Outcome o = Optimise(optics, 4, kind, 0);
    EXPECT_GT(o.final, 0.99 * o.raster) << ToString(kind);
  }
}

// N < r²: the classic raster of N = 3 is a 1 x 3 line (no half-pixel step in y); designed offsets sample both
// axes, and pay clearly.
TEST(DesignObjectivePhysicsTest, DiversityPaysWhenFramesAreFewerThanRSquared) {
  const DesignOptics optics = SmallOptics(/*ao=*/false);
  const Outcome tt = Optimise(optics, 3, DesignParameterisationKind::kTipTilt, 0);
  EXPECT_LT(tt.final, 0.97 * tt.raster);
  const Outcome z = Optimise(optics, 3, DesignParameterisationKind::kZernike, 0);
  EXPECT_LE(z.final, tt.final * 1.001);  // Zernike includes tip/tilt
}

// With the AO residual and PSF mismatch (realised screens vs the nominal long exposure): designs never lose
// to the raster on the objective; the gain is reported.
TEST(DesignObjectivePhysicsTest, WithAoMismatchDesignsAreNeverWorseThanTheRaster) {
  const DesignOptics optics = SmallOptics(/*ao=*/true);
  const Outcome z = Optimise(optics, 4, DesignParameterisationKind::kZernike, 2);
  EXPECT_LE(z.final, z.raster * (1 + 1e-12));
}

}  // namespace
}  // namespace aosr
