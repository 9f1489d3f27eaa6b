// The stars PSF's pieces: the Fourier kernel shift, and the estimate on a small synthetic field of Gaussian
// stars whose PSF is known in closed form (one saturated star among them, masked out).
#include <gtest/gtest.h>

#include <cmath>

#include "aosr/core/error.hpp"
#include "aosr/solvers/dataset_problem.hpp"
#include "aosr/solvers/stars_psf.hpp"
#include "solvers/stars_psf_fixture.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

Image Gaussian(Index k, double cy, double cx, double sigma) {
  Image g(k, k);
  for (Index y = 0; y < k; ++y)
    for (Index x = 0; x < k; ++x)
      g(y, x) = std::exp(-((y - cy) * (y - cy) + (x - cx) * (x - cx)) / (2 * sigma * sigma));
  return g / g.sum();
}

TEST(FourierShiftKernel, IntegerShiftsAreCircularShiftsAndFractionalOnesMoveTheCentroid) {
  // Band-limited to rounding (σ = 2 px on 32 px): the shift is exact up to the Nyquist bins' real part.
  const Image g = Gaussian(32, 16, 16, 2.0);
  const Image s = FourierShiftKernel(g, 2, -3);
  for (Index y = 0; y < 32; ++y)
    for (Index x = 0; x < 32; ++x) EXPECT_NEAR(s((y + 2) % 32, (x + 29) % 32), g(y, x), 1e-14);
  const FrameOffset c = KernelCentroid(FourierShiftKernel(g, 0.3, -0.45));
  EXPECT_NEAR(c.dy, 0.3, 1e-9);
  EXPECT_NEAR(c.dx, -0.45, 1e-9);
  EXPECT_LT((FourierShiftKernel(FourierShiftKernel(g, 0.3, -0.45), -0.3, 0.45) - g).abs().maxCoeff(), 1e-10);
}

TEST(StarsPsf, GaussianFieldWithASaturatedStar) {
  // 12 stars of 3e4 e- (peak ~5000 e- per camera px) at scattered sub-pixel phases, and one of 1e6 e- whose
  // core saturates at 2e4 e-, more than 2 fit_radius_px + 2 = 8 camera px from the others (its masked zone).
  std::vector<std::pair<double, double>> pos;
  std::vector<double> flux;
  for (int j = 0; j < 12; ++j) {
    // Camera-pixel phases (position mod r = 2 HR px) spread over [0, 2) by golden-ratio steps: each star
    // samples other phases of h (real fields have random ones).
    const double gy = 0.382 * j + 0.2, gx = 0.618 * j;
    pos.push_back({6.0 + 14.0 * (j / 3) + 2 * (gy - std::floor(gy)), 6.0 + 13.0 * (j % 3) + 2 * (gx - std::floor(gx))});
    flux.push_back(3e4);
  }
  pos.push_back({30.2, 59.4});
  flux.push_back(1e6);
  const test::StarFrames f = test::MakeStarFrames(pos, 0, 2e4, flux);
  StarsPsfOptions o;
  o.psf_size_hr_px = 16;
  const StarsPsfResult s = EstimateStarsPsf(f.y, f.valid, {}, f.offsets, 2, o);
  std::printf("%s\n", s.BriefReport().c_str());
  EXPECT_EQ(s.saturated, 1);
  EXPECT_EQ(s.used, 12);
  ASSERT_EQ(s.psfs.size(), 4u);
  EXPECT_EQ(s.psf.rows(), 16);
  EXPECT_NEAR(s.psf.sum(), 1.0, 1e-12);
  const Image truth = Gaussian(16, 8, 8, 1.2);
  const double rms = std::sqrt((s.psf - truth).square().mean()) / truth.maxCoeff();
  std::printf("RMS difference / peak %.4f, chi2/dof %.3f\n", rms, s.chi2_per_dof);
  EXPECT_LT(rms, 0.01);
  // The weights are the noise's inverse variances (background σ from the residual's quiet pixels, plus the
  // model's photon noise): measured chi2/dof 1.06 (0.78 while σ came from every pixel, the stars' photon noise
  // inflating it).
  EXPECT_GT(s.chi2_per_dof, 0.85);
  EXPECT_LT(s.chi2_per_dof, 1.2);
  for (double b : s.background_e) EXPECT_NEAR(b, 100.0, 1.0);
  for (std::size_t i = 0; i < 4; ++i) {
    // The centring convention: the first moment within 3 camera px of the centre carries the frame's offset.
    Image core = s.psfs[i];
    for (Index y = 0; y < core.rows(); ++y)
      for (Index x = 0; x < core.cols(); ++x)
        if (std::hypot(double(y - core.rows() / 2), double(x - core.cols() / 2)) > 6) core(y, x) = 0;
    const FrameOffset c = KernelCentroid(core);
    EXPECT_NEAR(c.dy, f.offsets[i].dy, 0.02);
    EXPECT_NEAR(c.dx, f.offsets[i].dx, 0.02);
  }
  EXPECT_TRUE(s.cg_converged) << s.BriefReport();
  EXPECT_EQ(s.BriefReport().find("NOT converged"), std::string::npos);
  EXPECT_GE(s.cg_iterations_total, s.cg_iterations_last);
  // An h solve held to too few CG iterations is reported, not hidden behind the cap.
  StarsPsfOptions capped = o;
  capped.cg_iterations = 3;
  const StarsPsfResult c = EstimateStarsPsf(f.y, f.valid, {}, f.offsets, 2, capped);
  EXPECT_FALSE(c.cg_converged);
  EXPECT_EQ(c.cg_iterations_last, 3);
  EXPECT_NE(c.BriefReport().find("NOT converged (3 CG iterations"), std::string::npos) << c.BriefReport();
}


// The 12 stars of the test above (3e4 e-), on a structured background: a smooth nebula (a 2-D Gaussian of
// 400 e- peak per camera px, σ = 8 camera px), then also three compact knots (Gaussians of σ = 3 HR px, 2.5x the
// PSF's, 2e4 e-) between the stars. The mesh takes out most of the nebula (the PSF's error 3x smaller than
// without it); the knots, detected as stars, are rejected as not point-like and the PSF is the stars'; a fit held
// to an impossible χ² is refused with the count of stars kept.
TEST(StarsPsf, StructuredBackgroundIsRemovedOrRefused) {
  std::vector<std::pair<double, double>> pos;
  for (int j = 0; j < 12; ++j) {
    const double gy = 0.382 * j + 0.2, gx = 0.618 * j;
    pos.push_back({6.0 + 14.0 * (j / 3) + 2 * (gy - std::floor(gy)), 6.0 + 13.0 * (j % 3) + 2 * (gx - std::floor(gx))});
  }
  const test::StarFrames stars = test::MakeStarFrames(pos, 3e4);
  auto with = [&](bool knots) {
    test::StarFrames f = stars;
    const std::vector<std::pair<double, double>> at = {{20.0, 58.0}, {47.0, 55.0}, {33.0, 30.0}};  // HR px
    for (std::size_t i = 0; i < f.y.size(); ++i)
      for (Index a = 0; a < 32; ++a)
        for (Index b = 0; b < 32; ++b) {
          double add = 400.0 * std::exp(-((a - 18.0) * (a - 18.0) + (b - 12.0) * (b - 12.0)) / (2 * 64.0));
          for (auto [ky, kx] : at) {
            const double dy = 2.0 * a + 0.5 - ky, dx = 2.0 * b + 0.5 - kx;  // camera pixel centre in HR px
            if (knots) add += 2e4 / (2 * M_PI * 9.0) * 4.0 * std::exp(-(dy * dy + dx * dx) / (2 * 9.0));
          }
          f.y[i](a, b) += add;
        }
    return f;
  };
  const Image truth = Gaussian(16, 8, 8, 1.2);
  auto rms = [&](const StarsPsfResult& s) { return std::sqrt((s.psf - truth).square().mean()) / truth.maxCoeff(); };
  StarsPsfOptions o;
  o.psf_size_hr_px = 16;
  o.background_mesh_px = 8;
  o.reject_extended = true;
  const test::StarFrames nebula = with(false);
  const StarsPsfResult s = EstimateStarsPsf(nebula.y, nebula.valid, {}, nebula.offsets, 2, o);
  std::printf("nebula, mesh 8: %s; RMS / peak %.4f\n", s.BriefReport().c_str(), rms(s));
  EXPECT_EQ(s.background_mesh_px, 8);
  EXPECT_LT(rms(s), 0.015);
  StarsPsfOptions flat = o;
  flat.background_mesh_px = 0;
  flat.max_chi2_near_stars = 0;
  const StarsPsfResult c = EstimateStarsPsf(nebula.y, nebula.valid, {}, nebula.offsets, 2, flat);
  std::printf("nebula, no mesh: %s; RMS / peak %.4f\n", c.BriefReport().c_str(), rms(c));
  EXPECT_GT(c.chi2_near_stars, s.chi2_near_stars);
  EXPECT_GT(rms(c), 2 * rms(s));  // measured 0.029 against 0.009
  EXPECT_LT(s.used, c.used);      // fewer knots of residual nebula taken for stars (17 against 33; 12 are real)

  const test::StarFrames knots = with(true);
  const StarsPsfResult k = EstimateStarsPsf(knots.y, knots.valid, {}, knots.offsets, 2, o);
  std::printf("nebula and knots, mesh 8: %s; RMS / peak %.4f\n", k.BriefReport().c_str(), rms(k));
  EXPECT_GE(k.rejected, 3);
  EXPECT_LT(rms(k), 0.015);
  StarsPsfOptions strict = o;
  strict.max_chi2_near_stars = 0.5;
  try {
    EstimateStarsPsf(knots.y, knots.valid, {}, knots.offsets, 2, strict);
    ADD_FAILURE() << "a fit above max_chi2_near_stars was not refused";
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("stars kept"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("max_chi2_near_stars"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace aosr
