// Objective A on a continuous sky (design_continuous_sky.hpp): it is objective A on the HR grid's own sky, it
// predicts Monte-Carlo reconstructions of skies 4x finer than the HR grid (where objective A does not), and it
// converges as the sky's sampling grows. Small grids: a 32-pixel pupil of an 8 m telescope in K band, HR pixel
// λ/D (camera pixel 2 λ/D, r = 2): the optics pass frequencies up to twice the HR grid's Nyquist.
#include "aosr/design/design_continuous_sky.hpp"

#include <gtest/gtest.h>

#include <cstdio>
#include <random>

#include "aosr/solvers/tikhonov.hpp"
#include "design/design_fixture.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

using design_test::DrawObject;
using design_test::SmallOptics;
using design_test::SmallPupil;

// HR pixel λ/D: the coarsest the design allows, the PSF's period Q = n = 32 a multiple of every grid here.
DesignOptics CoarseOptics(bool ao) {
  DesignOptics o = SmallOptics(ao, /*grid=*/16, /*r=*/2, /*pupil_n=*/32);
  o.hr_pixel_rad = o.wavelength_m / o.diameter_m;
  return o;
}

// Defocus and astigmatism on two of three exposures: not the raster, so the test sees a design.
std::vector<Image> SomeDesign(const DesignOptics& optics, int frames) {
  DesignParameterisationOptions po;
  po.kind = DesignParameterisationKind::kZernike;
  po.zernike_modes = 6;
  const DesignParameterisation p(SmallPupil(optics), frames, optics.r, po);
  Vector theta = p.RasterParameters();
  theta[2] += 80e-9;
  theta[9] -= 60e-9;
  return p.Opds(theta);
}

// The sum of each s x s block: the sky integrated over HR pixels (edge-aligned, as the simulator's).
Image BlockSum(const Image& fine, int s) {
  Image out = Image::Zero(fine.rows() / s, fine.cols() / s);
  for (Index y = 0; y < fine.rows(); ++y)
    for (Index x = 0; x < fine.cols(); ++x) out(y / s, x / s) += fine(y, x);
  return out;
}

TEST(ContinuousSkyPhysicsTest, OnTheHrGridsOwnSkyItIsObjectiveA) {
  const DesignOptics optics = SmallOptics(/*ao=*/true);
  DesignObjectiveOptions o;
  o.reconstructor.prior = TikhonovPrior::kGradient;
  o.reconstructor.lambda = 0.03;
  o.noise_sigma = 0.2;
  o.realisations = 2;
  o.screens = 2;
  const DesignObjective f(optics, 3, o);
  const std::vector<Image> w = SomeDesign(optics, 3);
  const MultiFrameModel nominal = f.NominalModel(w);
  const std::vector<MultiFrameModel> truths = f.RealisedModels(w);
  const Image& s = f.object_spectrum();
  const Index m = s.rows();
  // The HR spectrum as a function of frequency: s = t = 1 must give (A) exactly.
  const SkySpectrum sky = [&](double vy, double vx) {
    auto idx = [m](double v) { return ((Index(std::llround(v * double(m))) % m) + m) % m; };
    return s(idx(vy), idx(vx));
  };
  const double a = ExpectedTikhonovMse(nominal, truths, o.reconstructor, o.noise_sigma);
  const double a_inf = ExpectedTikhonovMseOnContinuousSky(nominal, truths, 1, 1, o.reconstructor, o.noise_sigma, sky);
  EXPECT_NEAR(a_inf, a, 1e-10 * a);
  EXPECT_NEAR(a, f.Evaluate(w), 1e-10 * a);
}

// Frames of skies drawn 4x finer than the HR grid (spectrum: the gradient prior's continuum form), through the
// realised PSFs on that grid; Tikhonov on the HR grid with the nominal model; scored against the sky integrated
// over HR pixels. The prediction uses the PSFs at half the HR pitch only (t = 2). 300 trials, seed 5, 5 %.
TEST(ContinuousSkyPhysicsTest, PredictsMonteCarloReconstructionsOfAFinerSky) {
  const DesignOptics optics = CoarseOptics(/*ao=*/true);
  const int frames = 3, s = 4;
  const int t = TruthOversamplingFor(optics);
  EXPECT_EQ(t, 2);
  EXPECT_EQ(TruthOversamplingFor(SmallOptics(false)), 1);  // HR pixel λ/2D: the HR grid holds the cutoff
  DesignObjectiveOptions o;
  o.reconstructor.prior = TikhonovPrior::kGradient;
  o.reconstructor.lambda = 0.02;
  o.noise_sigma = 0.05;
  o.realisations = 1;
  o.screens = 2;
  const std::vector<Image> w = SomeDesign(optics, frames);
  const DesignObjective hr(optics, frames, o);
  const DesignObjective at_t(OversampledOptics(optics, t), frames, o);
  const DesignObjective at_s(OversampledOptics(optics, s), frames, o);
  const MultiFrameModel nominal = hr.NominalModel(w);
  const std::vector<MultiFrameModel> truths_t = at_t.RealisedModels(w), truths_s = at_s.RealisedModels(w);
  const SkySpectrum sky = SkySpectrumOfPrior(o.reconstructor, o.noise_sigma);
  const double predicted =
      ExpectedTikhonovMseOnContinuousSky(nominal, truths_t, t, s, o.reconstructor, o.noise_sigma, sky);
  // The same prediction from the PSFs on the sky's own grid: nothing beyond the t grid's band was left out.
  const double from_s =
      ExpectedTikhonovMseOnContinuousSky(nominal, truths_s, s, s, o.reconstructor, o.noise_sigma, sky);
  EXPECT_NEAR(from_s, predicted, 1e-3 * predicted);

  const Index fine = optics.grid * s;
  Image spectrum(fine, fine);  // E|X_f|² = (sM)² · σ / s² = M² σ
  for (Index gy = 0; gy < fine; ++gy)
    for (Index gx = 0; gx < fine; ++gx)
      spectrum(gy, gx) = sky(double(SignedFrequency(gy, fine)) / double(optics.grid),
                             double(SignedFrequency(gx, fine)) / double(optics.grid)) / double(s * s);
  std::mt19937_64 rng(5);
  std::normal_distribution<double> n01;
  const int trials = 300;
  double measured = 0;
  for (int k = 0; k < trials; ++k) {
    const Image x = DrawObject(spectrum, rng);
    ImageStack y = truths_s[0].Render(x);
    for (Image& fr : y)
      for (Index p = 0; p < fr.size(); ++p) fr.data()[p] += o.noise_sigma * n01(rng);
    const Image xhat = TikhonovFourier(nominal, y, o.reconstructor);
    measured += (xhat - BlockSum(x, s)).square().mean() / trials;
  }
  // Objective A on the HR grid's sky of the same prior does not predict it: the test is not blind.
  const double discrete = ExpectedTikhonovMse(nominal, hr.RealisedModels(w), o.reconstructor, o.noise_sigma);
  std::printf("continuous sky (s = %d): predicted %.6g, measured %.6g over %d trials (ratio %.4f); objective A on "
              "the HR grid's sky %.6g\n", s, predicted, measured, trials, measured / predicted, discrete);
  EXPECT_NEAR(measured / predicted, 1.0, 0.05);
  EXPECT_GT(std::abs(discrete / measured - 1.0), 0.15);
}

// (A∞) converges as the sky's grid refines, as 1/s² (the HR pixel's box falls as 1/|ν| per axis and the sky as
// 1/|ν|²), with and without AO; the gain of a design over no offsets at all converges much faster (both
// carry the same unseen part of the sky).
TEST(ContinuousSkyPhysicsTest, ConvergesAsTheSkyGridRefines) {
  for (bool ao : {false, true}) {
    const DesignOptics optics = CoarseOptics(ao);
    DesignObjectiveOptions o;
    o.reconstructor.lambda = 0.01;
    o.noise_sigma = 0.05;
    o.realisations = ao ? 1 : 0;
    o.screens = 2;
    const int t = TruthOversamplingFor(optics);
    const DesignObjective hr(optics, 3, o), at_t(OversampledOptics(optics, t), 3, o);
    const SkySpectrum sky = SkySpectrumOfPrior(o.reconstructor, o.noise_sigma);
    const int ss[] = {2, 4, 8, 16};
    std::vector<std::vector<double>> j;  // [design, no offsets][s]
    for (const std::vector<Image>& w : {SomeDesign(optics, 3), std::vector<Image>(3, Image::Zero(32, 32))}) {
      std::vector<MultiFrameModel> truths = at_t.RealisedModels(w);
      if (truths.empty()) truths.push_back(at_t.NominalModel(w));
      j.emplace_back();
      for (int s : ss)
        j.back().push_back(ExpectedTikhonovMseOnContinuousSky(hr.NominalModel(w), truths, t, s, o.reconstructor,
                                                              o.noise_sigma, sky));
      const std::vector<double>& v = j.back();
      std::printf("ao %d: J at s = 2, 4, 8, 16: %.6g %.6g %.6g %.6g\n", int(ao), v[0], v[1], v[2], v[3]);
      EXPECT_LT(std::abs(v[3] - v[2]), 0.4 * std::abs(v[2] - v[1]));
      EXPECT_LT(std::abs(v[2] - v[1]), 0.4 * std::abs(v[1] - v[0]));
      EXPECT_NEAR(v[1], v[3], 0.06 * v[3]);
    }
    for (int k = 0; k < 4; ++k) {
      const double gain = 10 * std::log10(j[1][k] / j[0][k]), gain16 = 10 * std::log10(j[1][3] / j[0][3]);
      std::printf("ao %d: gain at s = %d: %+.4f dB\n", int(ao), ss[k], gain);
      if (ss[k] >= 4) { EXPECT_NEAR(gain, gain16, 0.02) << "s = " << ss[k]; }
    }
  }
}

}  // namespace AOSR_TEST_NS
}  // namespace aosr
