// Target-PSF linear reconstruction (target_psf.hpp): the effective PSF, the leakage and the flux checked
// against the estimator's full response matrix, measured by reconstructing every HR delta; the CG path
// against the exact Fourier path; errors; determinism.
#include "aosr/solvers/target_psf.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <vector>

#include "aosr/core/error.hpp"
#include "aosr/core/fft.hpp"
#include "aosr/core/parallel.hpp"
#include "aosr/solvers/reconstruct.hpp"
#include "solvers/tikhonov_fixture.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

using test::RasterModel;

// A 2x2 sub-pixel raster plus one diagonal half-step: N = 5 > r² = 4, every bin of full rank but the
// pixel-box zeros.
std::shared_ptr<const MultiFrameModel> Model(Shape hr, double sigma = 0.9) {
  return std::make_shared<MultiFrameModel>(
      RasterModel(hr, 2, {{0, 0}, {0, 1}, {1, 0}, {1, 1}, {0.5, 0.5}}, sigma));
}

ReconstructionProblem Problem(std::shared_ptr<const MultiFrameModel> m, const Image& x) {
  ReconstructionProblem p;
  p.model = m;
  p.frames = m->Render(x);
  return p;
}

TargetPsfOptions Gaussian(double fwhm) {
  TargetPsfOptions o;
  o.kind = TargetPsfKind::kGaussian;
  o.fwhm_hr_px = fwhm;
  return o;
}

// The estimator's response to every HR delta (columns), for noiseless frames: the matrix QA in pixel space.
Eigen::MatrixXd ResponseMatrix(std::shared_ptr<const MultiFrameModel> m, const TargetPsfOptions& o,
                               TargetPsfSummary* summary) {
  const Shape hr = m->hr_shape();
  Eigen::MatrixXd resp(hr.size(), hr.size());
  TargetPsfOptions q = o;
  q.compute_noise = false;
  for (Index c = 0; c < hr.size(); ++c) {
    Image delta = Image::Zero(hr.rows, hr.cols);
    delta.data()[c] = 1.0;
    const TargetPsfResult r = ReconstructTargetPsf(Problem(m, delta), q);
    resp.col(c) = AsVector(r.image);
    if (c == 0 && summary) *summary = r.summary;
  }
  return resp;
}

// The circulant matrix of a periodic kernel given on the grid with its origin at (0, 0).
Eigen::MatrixXd Circulant(const Image& origin_kernel) {
  const Index rows = origin_kernel.rows(), cols = origin_kernel.cols(), n = rows * cols;
  Eigen::MatrixXd c(n, n);
  for (Index p = 0; p < n; ++p)
    for (Index s = 0; s < n; ++s) {
      const Index dy = ((p / cols - s / cols) % rows + rows) % rows, dx = ((p % cols - s % cols) % cols + cols) % cols;
      c(p, s) = origin_kernel(dy, dx);
    }
  return c;
}

TEST(TargetPsfTest, EffectivePsfAndLeakageAreThoseOfTheResponseMatrix) {
  const Shape hr{16, 16};
  const auto m = Model(hr);
  TargetPsfOptions o = Gaussian(3.0);
  o.psf_size = 16;  // the whole grid: the effective PSF is then the full periodic kernel
  TargetPsfSummary s;
  const Eigen::MatrixXd resp = ResponseMatrix(m, o, &s);
  o.compute_noise = false;
  const TargetPsfResult r = ReconstructTargetPsf(Problem(m, Image::Zero(16, 16)), o);
  // Shift-invariant part: the response averaged along each diagonal = the effective PSF.
  Image avg = Image::Zero(16, 16);
  for (Index p = 0; p < hr.size(); ++p)
    for (Index c = 0; c < hr.size(); ++c) {
      const Index dy = ((p / 16 - c / 16) % 16 + 16) % 16, dx = ((p % 16 - c % 16) % 16 + 16) % 16;
      avg(dy, dx) += resp(p, c) / double(hr.size());
    }
  const Image eff = CentredToOrigin(r.effective_psf, hr);
  EXPECT_LT((avg - eff).abs().maxCoeff(), 1e-12);
  EXPECT_NEAR(r.effective_psf.sum(), 1.0, 1e-12);  // flux
  // U = ||QA − C_T||²_F / ||C_T||²_F.
  const Eigen::MatrixXd ct = Circulant(CentredToOrigin(r.target_psf, hr));
  const double u = (resp - ct).squaredNorm() / ct.squaredNorm();
  EXPECT_NEAR(u, r.summary.leakage, 1e-9 + 1e-6 * r.summary.leakage);
  EXPECT_TRUE(r.summary.leakage_met);
  EXPECT_LE(r.summary.leakage, r.summary.leakage_unreachable + 1e-3 + 1e-12);
  EXPECT_GT(r.summary.kappa, 0.0);
  // The per-frequency leakage sums to the same total: Σ ℓ = U Σ|T|².
  const ComplexImage t = FftForward(CentredToOrigin(r.target_psf, hr).cast<Complex>());
  EXPECT_NEAR(r.leakage_spectrum.sum(), u * t.abs2().sum(), 1e-9);
}

TEST(TargetPsfTest, FluxIsConservedForASourceAtAnySubPixelPosition) {
  const Shape hr{32, 32};
  const auto m = Model(hr);
  for (auto [y, x] : {std::pair{10.0, 10.0}, {10.5, 11.25}, {17.3, 5.8}}) {
    // A band-limited point source at (y, x): its spectrum is the shift phase.
    const Image src = FftC2R(ShiftTransfer(hr, y, x), hr.cols) * 7.0;
    const TargetPsfResult r = ReconstructTargetPsf(Problem(m, src), Gaussian(2.5));
    EXPECT_NEAR(r.image.sum(), src.sum(), 1e-9 * std::abs(src.sum())) << y << ", " << x;
  }
}

// The flux normalisation divides every frequency by the DC transfer, not the zero frequency alone: a jump at one
// frequency is a constant in space, a pedestal under the whole field that couples every pixel to every other
// (bench/results/kernel_reach.md). Far from a point source the output must keep falling with the distance, on
// the Fourier and the CG paths. The scene of bench/kernel_reach.py (r = 2, 2 x 2 raster, Gaussian PSFs of σ 1.5
// HR px; this file's Model, with its pixel-box zeros at full rank, decays too slowly to show it on a test's
// grid). Measured (printed): max |x| / peak at 16, 32, 64, 96, 128 HR px 6.5e-5, 1.7e-7, 2.7e-12, 2.3e-16, 2e-16.
// With the zero frequency alone divided, kernel_reach.py saw a floor of 1e-8 of the peak on its 384² grid.
TEST(TargetPsfTest, FluxNormalisationLeavesNoPedestalUnderTheField) {
  const Shape hr{256, 256};
  const auto m = std::make_shared<MultiFrameModel>(RasterModel(hr, 2, {{0, 0}, {0, 1}, {1, 0}, {1, 1}}, 1.5));
  Image x = Image::Zero(hr.rows, hr.cols);
  x(0, 0) = 1.0;
  ReconstructionProblem p = Problem(m, x);
  TargetPsfOptions o;  // the automatic target
  o.compute_noise = false;
  o.cg = {500, 1e-14};
  for (const bool weighted : {false, true}) {
    if (weighted) {
      for (int i = 0; i < m->frames(); ++i) p.weights.push_back(Image::Constant(128, 128, 1.0));
      p.weights[1](64, 64) = 1.0 + 1e-9;  // not uniform: the CG path
    }
    const TargetPsfResult r = ReconstructTargetPsf(p, o);
    EXPECT_EQ(r.summary.method, weighted ? "target-psf-cg" : "target-psf-fourier");
    EXPECT_NEAR(r.image.sum(), 1.0, 1e-9);  // the flux kept
    const double peak = r.image.abs().maxCoeff();
    std::vector<double> ring(129, 0.0);  // max |x| at Chebyshev distance d from the source (periodic)
    for (Index y = 0; y < hr.rows; ++y)
      for (Index xx = 0; xx < hr.cols; ++xx) {
        const Index d = std::max(std::min(y, hr.rows - y), std::min(xx, hr.cols - xx));
        ring[std::size_t(d)] = std::max(ring[std::size_t(d)], std::abs(r.image(y, xx)) / peak);
      }
    std::printf("%s: max |x| / peak at 16, 32, 64, 96, 128 HR px: %.2g %.2g %.2g %.2g %.2g\n",
                r.summary.method.c_str(), ring[16], ring[32], ring[64], ring[96], ring[128]);
    // Geometric decay, not a floor: far enough away the response is at rounding (a pedestal would stay put).
    EXPECT_LT(ring[96], 1e-6 * ring[32]) << r.summary.method;
    EXPECT_LT(ring[128], 1e-12) << r.summary.method;
  }
}

TEST(TargetPsfTest, WideTargetIsReachedToTheLeakageBoundAndTighterBoundsCostNoise) {
  const Shape hr{32, 32};
  const auto m = Model(hr);
  double previous_noise = 0, previous_u = 1;
  for (double eps : {1e-2, 1e-3, 1e-4}) {
    TargetPsfOptions o = Gaussian(4.0);
    o.leakage = eps;
    const TargetPsfResult r = ReconstructTargetPsf(Problem(m, Image::Zero(32, 32)), o);
    EXPECT_TRUE(r.summary.leakage_met) << eps;
    // The search's U; the flux normalisation 1/dc (not in the search) moves it slightly.
    EXPECT_NEAR(r.summary.leakage, r.summary.leakage_unreachable + eps, 0.05 * eps) << eps;
    EXPECT_LT(r.summary.leakage, previous_u);
    EXPECT_GT(r.summary.noise_rms, previous_noise);  // less leakage, more noise
    previous_noise = r.summary.noise_rms;
    previous_u = r.summary.leakage;
  }
}

// Nearly uniform weights force the CG path; it must agree with the exact Fourier path.
TEST(TargetPsfTest, ConjugateGradientPathAgreesWithTheFourierPath) {
  const Shape hr{32, 32};
  const auto m = Model(hr);
  Image x(32, 32);
  for (Index i = 0; i < x.size(); ++i) x.data()[i] = 1.0 + std::sin(0.37 * double(i)) + 0.5 * std::cos(0.11 * double(i * i % 97));
  ReconstructionProblem p = Problem(m, x);
  TargetPsfOptions o = Gaussian(3.0);
  o.compute_noise = false;
  o.cg = {500, 1e-12};
  const TargetPsfResult exact = ReconstructTargetPsf(p, o);
  ASSERT_EQ(exact.summary.method, "target-psf-fourier");
  for (int i = 0; i < m->frames(); ++i) p.weights.push_back(Image::Constant(16, 16, 1.0));
  p.weights[2](3, 4) = 1.0 + 1e-12;  // not uniform: the weighted path
  const TargetPsfResult cg = ReconstructTargetPsf(p, o);
  ASSERT_EQ(cg.summary.method, "target-psf-cg");
  EXPECT_LT((cg.image - exact.image).abs().maxCoeff(), 1e-8 * exact.image.abs().maxCoeff());
  EXPECT_DOUBLE_EQ(cg.summary.kappa, exact.summary.kappa);
}

TEST(TargetPsfTest, AutoTargetIsAtLeastOneCameraPixel) {
  const Shape hr{32, 32};
  const auto m = Model(hr, 0.6);  // a PSF narrower than a camera pixel
  TargetPsfOptions o;
  o.compute_noise = false;
  const TargetPsfResult r = ReconstructTargetPsf(Problem(m, Image::Zero(32, 32)), o);
  EXPECT_DOUBLE_EQ(r.summary.target_fwhm_hr_px, 2.0);  // r HR pixels
  EXPECT_THAT(r.summary.target, ::testing::HasSubstr("auto"));
  const auto wide = Model(hr, 3.0);
  const TargetPsfResult w = ReconstructTargetPsf(Problem(wide, Image::Zero(32, 32)), o);
  EXPECT_NEAR(w.summary.target_fwhm_hr_px, 2.3548 * 3.0, 0.2);  // the PSF's own FWHM
}

TEST(TargetPsfTest, ImageTargetEqualsTheSameGaussian) {
  const Shape hr{32, 32};
  const auto m = Model(hr);
  Image x = Image::Zero(32, 32);
  x(9, 12) = 5;
  x(20, 21) = 3;
  const TargetPsfResult g = ReconstructTargetPsf(Problem(m, x), Gaussian(3.0));
  TargetPsfOptions o;
  o.kind = TargetPsfKind::kImage;
  o.image = GaussianTargetKernel(3.0, 32) * 4.0;  // renormalised
  const TargetPsfResult i = ReconstructTargetPsf(Problem(m, x), o);
  EXPECT_LT((g.image - i.image).abs().maxCoeff(), 1e-10);
  EXPECT_NEAR(i.summary.target_fwhm_hr_px, 3.0, 0.15);
}

TEST(TargetPsfTest, SameBitsWithOneAndTwoThreads) {
  const Shape hr{32, 32};
  const auto m = Model(hr);
  Image x(32, 32);
  for (Index i = 0; i < x.size(); ++i) x.data()[i] = double((i * 7919) % 101);
  ReconstructionProblem p = Problem(m, x);
  for (int i = 0; i < m->frames(); ++i) p.weights.push_back(Image::Constant(16, 16, 1.0 + 0.1 * i));
  p.weights[1](2, 2) = 0;
  TargetPsfOptions o = Gaussian(3.0);
  o.noise_probes = 4;
  const int saved = DefaultThreads();
  SetDefaultThreads(1);
  const TargetPsfResult a = ReconstructTargetPsf(p, o);
  SetDefaultThreads(2);
  const TargetPsfResult b = ReconstructTargetPsf(p, o);
  SetDefaultThreads(saved);
  EXPECT_EQ(0, std::memcmp(a.image.data(), b.image.data(), sizeof(double) * a.image.size()));
  EXPECT_EQ(0, std::memcmp(a.noise_std.data(), b.noise_std.data(), sizeof(double) * a.noise_std.size()));
}

// κ and e_max given (what tiling gives each tile): the bins are analysed once, and the run is the searched one's:
// the estimate, its noise and the maps to the bit, U_min and the bound's verdict to rounding. Another e_max moves
// only the reach floor (U_min, the unreachable count), never the estimate.
TEST(TargetPsfTest, GivenKappaAndEmaxReproduceTheSearchedRun) {
  const Shape hr{32, 32};
  const auto m = Model(hr);
  Image x(32, 32);
  for (Index i = 0; i < x.size(); ++i) x.data()[i] = double((i * 7919) % 101);
  for (const bool weighted : {false, true}) {
    SCOPED_TRACE(weighted ? "weighted (CG path)" : "uniform (Fourier path)");
    ReconstructionProblem p = Problem(m, x);
    if (weighted) {
      for (int i = 0; i < m->frames(); ++i) p.weights.push_back(Image::Constant(16, 16, 1.0 + 0.1 * i));
      p.weights[1](2, 2) = 0;
    }
    TargetPsfOptions o = Gaussian(3.0);
    o.noise_probes = 4;
    const TargetPsfResult a = ReconstructTargetPsf(p, o);
    ASSERT_GT(a.summary.e_max, 0.0);
    // The choice alone (what tiling fixes for its tiles) is the run's.
    const TargetPsfChoice choice = ChooseTargetPsf(p, o);
    EXPECT_EQ(choice.kappa, a.summary.kappa);
    EXPECT_EQ(choice.e_max, a.summary.e_max);
    EXPECT_EQ(choice.target_fwhm_hr_px, a.summary.target_fwhm_hr_px);
    TargetPsfOptions g = o;
    g.kappa = a.summary.kappa;
    g.e_max = a.summary.e_max;
    const TargetPsfResult b = ReconstructTargetPsf(p, g);
    auto same = [](const Image& u, const Image& v) {
      return u.size() == v.size() && std::memcmp(u.data(), v.data(), sizeof(double) * u.size()) == 0;
    };
    EXPECT_TRUE(same(a.image, b.image));
    EXPECT_TRUE(same(a.noise_std, b.noise_std));
    EXPECT_TRUE(same(a.leakage_spectrum, b.leakage_spectrum));
    EXPECT_TRUE(same(a.effective_psf, b.effective_psf));
    EXPECT_EQ(a.summary.kappa, b.summary.kappa);
    EXPECT_EQ(a.summary.e_max, b.summary.e_max);
    EXPECT_EQ(a.summary.dc_transfer, b.summary.dc_transfer);
    EXPECT_EQ(a.summary.leakage, b.summary.leakage);
    EXPECT_EQ(a.summary.unreachable_frequencies, b.summary.unreachable_frequencies);
    EXPECT_NEAR(a.summary.leakage_unreachable, b.summary.leakage_unreachable, 1e-13);
    EXPECT_TRUE(b.summary.leakage_met);
    // A floor 100x higher: more frequencies unreachable, the same estimate.
    g.e_max = 100 * a.summary.e_max;
    const TargetPsfResult c = ReconstructTargetPsf(p, g);
    EXPECT_TRUE(same(a.image, c.image));
    EXPECT_GT(c.summary.leakage_unreachable, a.summary.leakage_unreachable);
    EXPECT_GE(c.summary.unreachable_frequencies, a.summary.unreachable_frequencies);
  }
}

TEST(TargetPsfTest, ReconstructRunsItAsMethodLinear) {
  const Shape hr{32, 32};
  const auto m = Model(hr);
  ReconstructOptions o;
  o.method = ParseReconstructionMethod("linear");
  o.linear = Gaussian(3.0);
  const Reconstruction r = Reconstruct(Problem(m, Image::Constant(32, 32, 2.0)), o);
  EXPECT_EQ(r.aux_name, "noise-std");
  ASSERT_TRUE(r.linear.has_value());
  EXPECT_NEAR(r.effective_psf.sum(), 1.0, 1e-12);
  EXPECT_NEAR(r.image.mean(), 2.0, 1e-10);
  EXPECT_EQ(r.noise_correlation.rows(), 2 * 2 * 2 + 1);
}

TEST(TargetPsfTest, BadOptionsAreNamed) {
  const Shape hr{32, 32};
  const auto m = Model(hr);
  const ReconstructionProblem p = Problem(m, Image::Zero(32, 32));
  TargetPsfOptions o = Gaussian(0.1);
  EXPECT_THAT([&] { ReconstructTargetPsf(p, o); },
              ::testing::ThrowsMessage<InvalidArgument>(::testing::HasSubstr("fwhm_hr_px")));
  o = Gaussian(3.0);
  o.leakage = 0;
  EXPECT_THAT([&] { ReconstructTargetPsf(p, o); },
              ::testing::ThrowsMessage<InvalidArgument>(::testing::HasSubstr("leakage")));
  o = TargetPsfOptions();
  o.kind = TargetPsfKind::kImage;
  EXPECT_THAT([&] { ReconstructTargetPsf(p, o); },
              ::testing::ThrowsMessage<InvalidArgument>(::testing::HasSubstr("image is empty")));
  o.image = Image::Constant(40, 40, 1.0);
  EXPECT_THAT([&] { ReconstructTargetPsf(p, o); },
              ::testing::ThrowsMessage<InvalidArgument>(::testing::HasSubstr("larger than the HR grid")));
  o = Gaussian(3.0);
  o.e_max = 1.0;  // without κ
  EXPECT_THAT([&] { ReconstructTargetPsf(p, o); },
              ::testing::ThrowsMessage<InvalidArgument>(::testing::HasSubstr("e_max = 1.000000 without kappa")));
  o.kappa = 1e-3;
  o.e_max = std::nan("");
  EXPECT_THAT([&] { ReconstructTargetPsf(p, o); },
              ::testing::ThrowsMessage<InvalidArgument>(::testing::HasSubstr("e_max = nan")));
  // The choice alone validates as the run does.
  EXPECT_THAT([&] { ChooseTargetPsf(p, o); },
              ::testing::ThrowsMessage<InvalidArgument>(::testing::HasSubstr("e_max = nan")));
  o = Gaussian(0.1);
  EXPECT_THAT([&] { ChooseTargetPsf(p, o); },
              ::testing::ThrowsMessage<InvalidArgument>(::testing::HasSubstr("fwhm_hr_px")));
  ReconstructionProblem empty = p;
  empty.frames.clear();
  EXPECT_THAT([&] { ChooseTargetPsf(empty, Gaussian(3.0)); }, ::testing::Throws<InvalidArgument>());
  o = Gaussian(3.0);
  o.noise_probes = 1;
  EXPECT_THAT([&] { ReconstructTargetPsf(p, o); },
              ::testing::ThrowsMessage<InvalidArgument>(::testing::HasSubstr("noise_probes")));
}

}  // namespace
}  // namespace aosr
