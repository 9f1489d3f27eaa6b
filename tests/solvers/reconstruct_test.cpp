// The dataset adapter (dataset_problem.hpp) and the single entry point of every reconstructor
// (reconstruct.hpp): units, folding, offsets, and the scaling laws of the automatic TV weight.
#include "aosr/solvers/reconstruct.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

#include "aosr/core/fft.hpp"
#include "aosr/core/operators.hpp"
#include "aosr/solvers/dataset_problem.hpp"
#include "support/testing.hpp"
#include "solvers/tikhonov_fixture.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

using ::testing::HasSubstr;

// Blocks on a dark sky: the piecewise-constant object TV is made for.
Image Blocks(Shape s) {
  Image x = Image::Constant(s.rows, s.cols, 0.1);
  x.block(s.rows / 4, s.cols / 4, s.rows / 3, s.cols / 3) += 1.0;
  x.block(s.rows / 2, s.cols / 2, s.rows / 4, s.cols / 5) += 0.6;
  return x;
}

// A dataset of N raster frames through Gaussian PSFs, in ADU with gain and bias.
Dataset MakeDataset(Shape hr, int r, int n_side, double gain, double bias, double sigma_e, int psf_side = 15) {
  Dataset d;
  d.r = r;
  d.hr_frame = hr;
  d.frame = {hr.rows / r, hr.cols / r};
  const Image k = test::GaussianKernel(psf_side, 1.2);
  for (int a = 0; a < n_side; ++a)
    for (int b = 0; b < n_side; ++b) {
      DmOffset o;
      o.shift_y_px = double(a) / n_side;
      o.shift_x_px = double(b) / n_side;
      d.offsets.push_back(o);
      // The PSF carries the shift (r·shift HR pixels), by Fourier shift of the centred kernel.
      const ComplexImage t = TransferFunction({psf_side, psf_side}, k) *
                             ShiftTransfer({psf_side, psf_side}, o.shift_y_px * r, o.shift_x_px * r);
      d.psfs.push_back(OriginToCentred(FftC2R(t, psf_side), {psf_side, psf_side}));
    }
  d.truth = Blocks(hr) * 1000.0;
  const MultiFrameModel m = MultiFrameModel::FromKernels(hr, r, d.psfs);
  const ImageStack clean = m.Render(*d.truth);
  const ImageStack noisy = test::AddNoise(clean, sigma_e, 7);
  for (const Image& f : noisy) {
    d.frames.push_back(f / gain + bias);
    d.valid.push_back(Image::Ones(d.frame.rows, d.frame.cols));
  }
  d.gain_e_per_adu = gain;
  d.bias_adu = bias;
  d.weights = ImageStack(d.frames.size(), Image::Constant(d.frame.rows, d.frame.cols, gain * gain / (sigma_e * sigma_e)));
  return d;
}

TEST(DatasetProblemTest, ElectronsWeightsAndDmOffsets) {
  const Dataset d = MakeDataset({32, 32}, 2, 2, 2.5, 100.0, 5.0);
  const DatasetProblem p = ProblemFromDataset(d);
  ASSERT_EQ(p.problem.frame_count(), 4);
  EXPECT_NEAR(p.problem.frames[1](3, 4), (d.frames[1](3, 4) - 100.0) * 2.5, 1e-9);
  // Inverse variance in e⁻⁻²: 1/σ_e².
  EXPECT_NEAR(p.problem.weights[2](5, 6), 1.0 / 25.0, 1e-15);
  EXPECT_EQ(p.weights_source, "dataset inverse variances (e-^-2)");
  EXPECT_EQ(p.offsets_source, "dm shifts");
  EXPECT_DOUBLE_EQ(p.problem.offsets[3].dy, 1.0);  // ½ camera pixel × r = 2
  EXPECT_DOUBLE_EQ(p.problem.offsets[3].dx, 1.0);
  // The PSFs carry the same shifts: the centroid path agrees with the commanded one.
  DatasetProblemOptions o;
  o.offsets = DatasetOffsets::kPsfCentroids;
  const DatasetProblem c = ProblemFromDataset(d, o);
  for (int i = 0; i < 4; ++i) {
    EXPECT_NEAR(c.problem.offsets[i].dy, p.problem.offsets[i].dy, 1e-6) << i;
    EXPECT_NEAR(c.problem.offsets[i].dx, p.problem.offsets[i].dx, 1e-6) << i;
  }
  o.weights = DatasetWeights::kMask;
  EXPECT_TRUE(ProblemFromDataset(d, o).problem.weights.empty());  // no bad pixel: uniform, Fourier-exact
}

TEST(DatasetProblemTest, InvalidPixelsGetWeightZero) {
  Dataset d = MakeDataset({16, 16}, 2, 2, 1.0, 0.0, 1.0);
  d.valid[1](2, 3) = 0;
  (*d.weights)[1](2, 3) = 0;
  DatasetProblemOptions o;
  o.weights = DatasetWeights::kMask;
  const DatasetProblem p = ProblemFromDataset(d, o);
  ASSERT_EQ(p.problem.weights.size(), 4u);
  EXPECT_EQ(p.problem.weights[1](2, 3), 0.0);
  EXPECT_EQ(p.masked_pixels, 1);
  EXPECT_FALSE(p.problem.HasUniformWeights());
}

// A kernel larger than the HR grid is folded modulo the grid: the rendered frames are those of the periodic
// convolution with the full kernel (computed here directly on a grid that holds it, then folded by D_r
// periodicity: a 2× larger grid tiled by the object).
TEST(DatasetProblemTest, KernelsLargerThanTheGridAreFolded) {
  const Shape hr{12, 12};
  Dataset d = MakeDataset(hr, 2, 1, 1.0, 0.0, 1.0, 11);
  d.psfs = {test::GaussianKernel(31, 4.0)};  // a 31 x 31 kernel on a 12 x 12 grid
  const DatasetProblem p = ProblemFromDataset(d);
  EXPECT_EQ(p.psf_folded, 1);
  const Image x = test::RandomImage(hr, 3).abs();
  // The object tiled 4 × 4 (48 x 48 holds the kernel): periodic convolution on the big grid restricted to
  // one tile equals the periodic convolution on the small grid with the folded kernel.
  Image big(48, 48);
  for (int ty = 0; ty < 4; ++ty)
    for (int tx = 0; tx < 4; ++tx) big.block(12 * ty, 12 * tx, 12, 12) = x;
  const ImageStack ref = MultiFrameModel::FromKernels({48, 48}, 2, d.psfs).Render(big);
  const ImageStack got = p.problem.model->Render(x);
  EXPECT_LT((ref[0].block(0, 0, 6, 6) - got[0]).abs().maxCoeff(), 1e-12 * ref[0].abs().maxCoeff());
}

TEST(DatasetProblemTest, BadRequestsNameTheOption) {
  Dataset d = MakeDataset({16, 16}, 2, 2, 1.0, 0.0, 1.0);
  d.weights.reset();
  DatasetProblemOptions o;
  o.weights = DatasetWeights::kDataset;
  EXPECT_THAT(test::ErrorOf([&] { ProblemFromDataset(d, o); }), HasSubstr("weights"));
  o = {};
  o.model_psfs = {Image::Zero(5, 5)};
  EXPECT_THAT(test::ErrorOf([&] { ProblemFromDataset(d, o); }), HasSubstr("model_psfs[0]"));
  o.model_psfs = ImageStack(3, test::GaussianKernel(5, 1));
  EXPECT_THAT(test::ErrorOf([&] { ProblemFromDataset(d, o); }), HasSubstr("model_psfs count"));
  o = {};
  o.nominal_psfs = true;  // the dataset has none
  EXPECT_THAT(test::ErrorOf([&] { ProblemFromDataset(d, o); }), HasSubstr("nominal_psfs"));
  EXPECT_THAT(test::ErrorOf([] { ParseReconstructionMethod("wiener"); }), HasSubstr("shift-add | "));
  EXPECT_THAT(test::ErrorOf([] { ParseDatasetOffsets("x"); }), HasSubstr("auto | dm | centroids | estimate"));
  EXPECT_THAT(test::ErrorOf([] { ParseDatasetWeights("x"); }), HasSubstr("auto | background | dataset | poisson | mask"));
  EXPECT_THAT(test::ErrorOf([] { KernelCentroid(Image::Zero(4, 4)); }), HasSubstr("kernel sum"));
  // Options are validated by Reconstruct, naming the method's options.
  d.weights = ImageStack(d.frames.size(), Image::Ones(8, 8));
  const ReconstructionProblem p = ProblemFromDataset(d).problem;
  ReconstructOptions bad;
  bad.method = ReconstructionMethod::kTotalVariation;
  bad.auto_regularisation = false;
  bad.tv.mu = -1;
  EXPECT_THAT(test::ErrorOf([&] { Reconstruct(p, bad); }), HasSubstr("options.tv"));
  bad.method = ReconstructionMethod::kDrizzle;
  bad.drizzle.pixfrac = 2;
  EXPECT_THAT(test::ErrorOf([&] { Reconstruct(p, bad); }), HasSubstr("options.drizzle"));
}

// Replacing the model PSFs (PSF mismatch) is reported and changes the model.
TEST(DatasetProblemTest, ModelPsfsCanBeReplaced) {
  const Dataset d = MakeDataset({16, 16}, 2, 2, 1.0, 0.0, 1.0);
  DatasetProblemOptions o;
  o.model_psfs = {test::GaussianKernel(9, 2.0) * 3.0};  // renormalised, shared by all frames
  const DatasetProblem p = ProblemFromDataset(d, o);
  EXPECT_TRUE(p.model_psfs_replaced);
  const Image x = Image::Ones(16, 16);
  for (const Image& f : p.problem.model->Render(x)) EXPECT_NEAR(f.mean(), 4.0, 1e-12);  // unit sum × r²
}

// Every method runs through Reconstruct and returns a finite estimate of the right shape; the model-based
// ones beat the baselines on a well-posed problem.
TEST(ReconstructTest, EveryMethodRunsAndModelBasedOnesWin) {
  const Dataset d = MakeDataset({48, 48}, 2, 2, 1.0, 0.0, 10.0);
  const DatasetProblem p = ProblemFromDataset(d);
  double err[6];
  int k = 0;
  for (ReconstructionMethod m : {ReconstructionMethod::kShiftAddMean, ReconstructionMethod::kShiftAddMedian,
                                 ReconstructionMethod::kDrizzle, ReconstructionMethod::kTikhonov,
                                 ReconstructionMethod::kTotalVariation, ReconstructionMethod::kMap}) {
    ReconstructOptions o;
    o.method = m;
    const Reconstruction r = Reconstruct(p.problem, o);
    ASSERT_EQ(ShapeOf(r.image), d.hr_frame) << ToString(m);
    ASSERT_TRUE(AllFinite(r.image)) << ToString(m);
    EXPECT_NE(r.summary.termination, Termination::kFailed) << ToString(m) << ": " << r.summary.message;
    EXPECT_EQ(r.summary.frame_residual_rms.size(), 4u) << ToString(m);
    err[k++] = (r.image - *d.truth).matrix().norm() / d.truth->matrix().norm();
    if (m == ReconstructionMethod::kDrizzle) {
      EXPECT_EQ(r.aux_name, "weight");
    }
  }
  EXPECT_LT(err[3], err[2]);  // Tikhonov beats Drizzle
  EXPECT_LT(err[4], err[3]);  // TV beats Tikhonov on blocks
  EXPECT_LT(err[5], err[3]);  // so does MAP with its Charbonnier-TV prior
}

// The automatic TV weight scales as the objective does, so the estimate is invariant to the units of the
// weights and equivariant to the units of the data (reconstruct.hpp): w → c·w leaves x̂ unchanged, y → c·y
// scales it by c.
TEST(ReconstructTest, AutomaticTvWeightFollowsTheUnits) {
  const Dataset d = MakeDataset({32, 32}, 2, 2, 1.0, 0.0, 20.0);
  const ReconstructionProblem p = ProblemFromDataset(d).problem;
  ReconstructOptions o;
  o.method = ReconstructionMethod::kTotalVariation;
  o.tv.relative_tolerance = 1e-8;
  o.tv.max_iterations = 20000;
  const Reconstruction base = Reconstruct(p, o);
  ReconstructionProblem w = p;
  for (Image& x : w.weights) x *= 37.0;
  ReconstructionProblem y = p;
  for (Image& x : y.frames) x *= 0.01;
  const Reconstruction rw = Reconstruct(w, o), ry = Reconstruct(y, o);
  EXPECT_NEAR(rw.regularisation, 37.0 * base.regularisation, 1e-6 * rw.regularisation);
  EXPECT_NEAR(ry.regularisation, 0.01 * base.regularisation, 1e-6 * ry.regularisation);
  const double scale = base.image.matrix().norm();
  EXPECT_LT((rw.image - base.image).matrix().norm(), 1e-5 * scale);
  EXPECT_LT((ry.image / 0.01 - base.image).matrix().norm(), 1e-5 * scale);
}

// A masked pixel holding NaN changes nothing but its own contribution; GCV's λ is then taken on the
// unweighted frames and scaled by the mean weight (and said so).
TEST(ReconstructTest, MaskedNanPixelIsIgnoredByEveryMethod) {
  const Dataset d = MakeDataset({32, 32}, 2, 2, 1.0, 0.0, 5.0);
  ReconstructionProblem p = ProblemFromDataset(d).problem;
  p.frames[2](4, 5) = std::numeric_limits<double>::quiet_NaN();
  p.weights[2](4, 5) = 0;
  for (ReconstructionMethod m : {ReconstructionMethod::kShiftAddMean, ReconstructionMethod::kShiftAddMedian,
                                 ReconstructionMethod::kDrizzle, ReconstructionMethod::kTikhonov,
                                 ReconstructionMethod::kTotalVariation}) {
    ReconstructOptions o;
    o.method = m;
    const Reconstruction r = Reconstruct(p, o);
    EXPECT_TRUE(AllFinite(r.image)) << ToString(m);
    EXPECT_LT((r.image - *d.truth).matrix().norm(), 0.5 * d.truth->matrix().norm()) << ToString(m);
    if (m == ReconstructionMethod::kTikhonov) {
      EXPECT_THAT(r.summary.message, HasSubstr("GCV on the unweighted"));
    }
  }
}

// One callback sees every stage of a run in order: the pilot (0 then 1 of 1, with its λ), then the solver's
// iterations, ending at the summary's count; a callback that continues leaves the bits unchanged.
TEST(ReconstructTest, ProgressShowsThePilotThenTheSolverStage) {
  const Dataset d = MakeDataset({32, 32}, 2, 2, 1.0, 0.0, 20.0);
  const ReconstructionProblem p = ProblemFromDataset(d).problem;
  for (ReconstructionMethod m : {ReconstructionMethod::kTotalVariation, ReconstructionMethod::kMap}) {
    ReconstructOptions o;
    o.method = m;
    const Reconstruction quiet = Reconstruct(p, o);
    std::vector<Progress> seen;
    o.progress = [&seen](const Progress& q) {
      seen.push_back(q);
      return true;
    };
    const Reconstruction r = Reconstruct(p, o);
    ASSERT_GE(seen.size(), 3u) << ToString(m);
    EXPECT_EQ(seen[0].stage, "pilot");
    EXPECT_EQ(seen[0].iteration, 0);
    EXPECT_EQ(seen[1].stage, "pilot");
    EXPECT_EQ(seen[1].iteration, 1);
    EXPECT_EQ(seen[1].total, 1);
    EXPECT_EQ(seen[1].value_name, "lambda");
    EXPECT_GT(seen[1].value, 0.0);
    for (std::size_t i = 2; i < seen.size(); ++i) {
      EXPECT_EQ(seen[i].stage, ToString(m));
      if (i > 2) {
        EXPECT_GT(seen[i].iteration, seen[i - 1].iteration);
      }
    }
    EXPECT_EQ(seen.back().iteration, r.summary.iterations);
    EXPECT_TRUE((quiet.image == r.image).all()) << ToString(m);
    EXPECT_EQ(quiet.summary.iterations, r.summary.iterations);
  }
}

// Cancelling during the pilot returns the pilot's Tikhonov estimate; later, the solver's current iterate.
TEST(ReconstructTest, ProgressCancellationInEitherStage) {
  const Dataset d = MakeDataset({32, 32}, 2, 2, 1.0, 0.0, 20.0);
  const ReconstructionProblem p = ProblemFromDataset(d).problem;
  ReconstructOptions t;
  t.method = ReconstructionMethod::kTikhonov;
  const Reconstruction tikhonov = Reconstruct(p, t);
  for (ReconstructionMethod m : {ReconstructionMethod::kTotalVariation, ReconstructionMethod::kMap})
    for (const std::string stop_in : {"pilot", "solver"}) {
      ReconstructOptions o;
      o.method = m;
      o.progress = [&](const Progress& q) {
        return stop_in == "pilot" ? q.stage != "pilot" : q.stage == "pilot";
      };
      const Reconstruction r = Reconstruct(p, o);
      EXPECT_EQ(r.summary.termination, Termination::kUserCancelled) << ToString(m) << " " << stop_in;
      EXPECT_THAT(r.summary.message, HasSubstr("cancelled by the caller"));
      EXPECT_TRUE(AllFinite(r.image));
      if (stop_in == "pilot") {
        EXPECT_EQ(r.summary.iterations, 0);
        EXPECT_LT((r.image - tikhonov.image).matrix().norm(), 1e-12 * tikhonov.image.matrix().norm());
      } else {
        EXPECT_EQ(r.summary.iterations, 1);
      }
    }
}

TEST(ReconstructTest, MethodListIsWhatParseAccepts) {
  const std::vector<ReconstructionMethod>& all = ReconstructionMethods();
  ASSERT_EQ(all.size(), 7u);
  std::string listed;
  for (ReconstructionMethod m : all) {
    EXPECT_EQ(ParseReconstructionMethod(ToString(m)), m);
    listed += (listed.empty() ? "" : " | ") + std::string(ToString(m));
  }
  EXPECT_THAT(test::ErrorOf<InvalidArgument>([] { ParseReconstructionMethod("nope"); }), HasSubstr(listed));
}

// Tikhonov's CG path reports each PCG iteration ("tikhonov-cg") and stops when asked; the Fourier path is one step.
TEST(ReconstructTest, TikhonovProgressAndCancellation) {
  const Dataset d = MakeDataset({32, 32}, 2, 2, 1.0, 0.0, 20.0);
  const ReconstructionProblem p = ProblemFromDataset(d).problem;
  ReconstructOptions o;
  o.method = ReconstructionMethod::kTikhonov;
  o.tikhonov.method = TikhonovMethod::kConjugateGradient;
  o.tikhonov.precondition = false;
  const Reconstruction quiet = Reconstruct(p, o);
  ASSERT_GT(quiet.summary.iterations, 2);
  std::vector<Progress> seen;
  o.progress = [&seen](const Progress& q) {
    seen.push_back(q);
    return true;
  };
  const Reconstruction r = Reconstruct(p, o);
  ASSERT_FALSE(seen.empty());
  for (const Progress& q : seen) EXPECT_EQ(q.stage, "tikhonov-cg");
  EXPECT_TRUE((quiet.image == r.image).all());
  o.progress = [](const Progress&) { return false; };
  const Reconstruction cut = Reconstruct(p, o);
  EXPECT_EQ(cut.summary.termination, Termination::kUserCancelled);
  EXPECT_LT(cut.summary.iterations, quiet.summary.iterations);
  EXPECT_TRUE(AllFinite(cut.image));
  // The direct Fourier solve: steps 0 and 1 of 1, nothing to cut short.
  o.tikhonov.method = TikhonovMethod::kAuto;
  seen.clear();
  o.progress = [&seen](const Progress& q) {
    seen.push_back(q);
    return false;
  };
  const Reconstruction direct = Reconstruct(p, o);
  ASSERT_EQ(seen.size(), 2u);
  EXPECT_EQ(seen[0].stage, "tikhonov");
  EXPECT_EQ(seen[1].iteration, 1);
  EXPECT_NE(direct.summary.termination, Termination::kUserCancelled);
}

}  // namespace
}  // namespace aosr
