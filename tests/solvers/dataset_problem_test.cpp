// The weights a dataset becomes (dataset_problem.hpp): the source-independent background weights behind
// `--weights auto` for the linear methods, by name and by method, and the diffraction-limited target PSF.
#include "aosr/solvers/dataset_problem.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <map>
#include <optional>
#include <random>
#include <nlohmann/json.hpp>
#include <string>

#include "aosr/optics/psf_metrics.hpp"
#include "aosr/scene/dataset_memory.hpp"
#include "aosr/scene/pipeline.hpp"
#include "aosr/scene/scene_spec.hpp"
#include "aosr/scene/telescope.hpp"
#include "../io/temp_dir.hpp"
#include "scene/dataset_fixture.hpp"
#include "solvers/tikhonov_fixture.hpp"
#include "support/testing.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

using ::testing::HasSubstr;

// A star on a K-band sky behind the paper's telescope (no turbulence: diffraction-limited PSFs), 4 raster
// frames of 32² camera pixels, r = 2: physical noise (sky 550 e-/s, read 5 e-, 1 s frames).
nlohmann::json StarScene(double flux_e, std::uint64_t seed, int frame_px = 32) {
  return {{"name", "one-star"},
          {"seed", seed},
          {"telescope", "paper-8m"},
          {"frames", 4},
          {"r", 2},
          {"ao", {{"mode", "none"}}},
          {"offsets", {{"type", "raster"}}},
          {"objects", {{{"type", "stars"}, {"catalogue", {{{"y_px", 15.25}, {"x_px", 16.25}, {"flux_e", flux_e}}}}}}},
          {"detector",
           {{"frame_px", frame_px},
            {"total_exposure_s", 4.0},
            {"background_e_per_s", 550.0},
            {"noise", "physical"},
            {"read_noise_e", 5.0},
            {"gain_e_per_adu", 2.0},
            {"saturation_adu", 1e6}}}};
}

Dataset Simulated(const nlohmann::json& j) {
  const SceneSpec scene = ParseScene(j, "dataset_problem_test");
  const ScenePipeline pipeline(scene);
  return DatasetFromSimulation(scene, pipeline.Run());
}

TEST(DatasetWeightsTest, NamesParseAndAutoResolvesPerMethod) {
  EXPECT_EQ(ParseDatasetWeights("auto"), DatasetWeights::kAuto);
  EXPECT_EQ(ParseDatasetWeights("background"), DatasetWeights::kBackground);
  EXPECT_EQ(ParseDatasetWeights("dataset"), DatasetWeights::kDataset);
  EXPECT_EQ(ParseDatasetWeights("poisson"), DatasetWeights::kDataset);
  EXPECT_EQ(ParseDatasetWeights("mask"), DatasetWeights::kMask);
  EXPECT_THAT(test::ErrorOf([] { ParseDatasetWeights("ivar"); }), HasSubstr("auto | background | dataset | poisson | mask"));
  for (ReconstructionMethod m : {ReconstructionMethod::kDrizzle, ReconstructionMethod::kLinear,
                                 ReconstructionMethod::kShiftAddMean, ReconstructionMethod::kShiftAddMedian,
                                 ReconstructionMethod::kTikhonov})
    EXPECT_EQ(AutoWeights(m), DatasetWeights::kBackground) << ToString(m);
  for (ReconstructionMethod m : {ReconstructionMethod::kTotalVariation, ReconstructionMethod::kMap})
    EXPECT_EQ(AutoWeights(m), DatasetWeights::kAuto) << ToString(m);
}

// The requirement: the default weights of a linear method are the same for two scenes that differ only
// in the sources' flux (same seeds, so the same sky and read-noise draws up to the Poisson draws of the star).
TEST(DatasetWeightsTest, DefaultWeightsOfLinearMethodsDoNotDependOnTheSources) {
  const Dataset faint = Simulated(StarScene(1e3, 5)), bright = Simulated(StarScene(1e6, 5));  // K 21.6 and 14
  for (ReconstructionMethod m : {ReconstructionMethod::kLinear, ReconstructionMethod::kDrizzle}) {
    DatasetProblemOptions o;
    o.method = m;
    const DatasetProblem a = ProblemFromDataset(faint, o), b = ProblemFromDataset(bright, o);
    EXPECT_EQ(a.weights_source, "background variances from the detector model (e-^-2)");
    ASSERT_EQ(a.problem.weights.size(), 4u);
    for (int i = 0; i < 4; ++i) EXPECT_TRUE((a.problem.weights[i] == b.problem.weights[i]).all()) << i;
    // σ² = read² + (sky + dark) t = 25 + 550 e-²; uniform, so the Fourier-exact path runs.
    EXPECT_NEAR(a.problem.weights[0](3, 3), 1.0 / 575.0, 1e-15);
    EXPECT_TRUE(a.problem.HasUniformWeights());
    EXPECT_NEAR(a.background_sigma_e[2], std::sqrt(575.0), 1e-12);
    EXPECT_TRUE(a.warning.empty());
  }
  // The dataset's (Poisson) weights do depend on them, and say so next to a linear method.
  DatasetProblemOptions o;
  o.weights = DatasetWeights::kDataset;
  o.method = ReconstructionMethod::kLinear;
  const DatasetProblem a = ProblemFromDataset(faint, o), b = ProblemFromDataset(bright, o);
  EXPECT_LT(b.problem.weights[0].minCoeff(), 0.1 * a.problem.weights[0].minCoeff());
  EXPECT_THAT(a.warning, HasSubstr("bias bright sources low"));
  // TV keeps the dataset's inverse variances by default; no method: the same (the library's old rule).
  o.weights = DatasetWeights::kAuto;
  o.method = ReconstructionMethod::kTotalVariation;
  EXPECT_EQ(ProblemFromDataset(faint, o).weights_source, "dataset inverse variances (e-^-2)");
  EXPECT_TRUE(ProblemFromDataset(faint, o).warning.empty());
  EXPECT_EQ(ProblemFromDataset(faint).weights_source, "dataset inverse variances (e-^-2)");
}

// Without a detector model (measured data), the background σ is estimated from each frame: for a sparse field
// within 5 % of the model's √575 e-, pooled to one value (uniform weights), and nearly the same for a star 100x
// brighter (K 16.6 against 21.6, 64² frames). The estimate is the noise of the typical pixel: a star bright
// enough for its halo to cover much of the frame raises it (1e5 e- on 32² frames: +5 %); the detector model,
// when the manifest has one, is exactly source-independent.
TEST(DatasetWeightsTest, EstimatedBackgroundWeightsMatchTheModelOnASparseField) {
  Dataset faint = Simulated(StarScene(1e3, 5, 64)), bright = Simulated(StarScene(1e5, 5, 64));
  faint.manifest = nlohmann::json();
  bright.manifest = nlohmann::json();
  DatasetProblemOptions o;
  o.weights = DatasetWeights::kBackground;
  const DatasetProblem a = ProblemFromDataset(faint, o), b = ProblemFromDataset(bright, o);
  EXPECT_EQ(a.weights_source, "background variances estimated from the frames (e-^-2)");
  ASSERT_EQ(a.background_sigma_e.size(), 4u);
  // 63 x 64 pairs per frame: SE(σ̂)/σ ≈ 1.17/√4032 = 1.8 %; pooled over 4 frames 0.9 %. 5 %: > 5 SE.
  EXPECT_NEAR(a.background_sigma_e[0] / std::sqrt(575.0), 1.0, 0.05);
  EXPECT_TRUE(a.problem.HasUniformWeights()) << "the frames' estimates agree, so they are pooled";
  EXPECT_NEAR(b.background_sigma_e[0] / a.background_sigma_e[0], 1.0, 0.05) << "a bright star does not move it";
}

TEST(DatasetWeightsTest, EstimateBackgroundSigmaOfWhiteNoiseOnASlope) {
  const Image noise = test::AddNoise({Image::Zero(64, 64)}, 3.0, 11)[0];
  Image y(64, 64);
  for (Index r = 0; r < 64; ++r)
    for (Index c = 0; c < 64; ++c) y(r, c) = noise(r, c) + 100.0 + 0.5 * double(c) + 0.2 * double(r);  // smooth sky
  double se = 0;
  const double sigma = EstimateBackgroundSigma(y, Image::Ones(64, 64), &se);
  EXPECT_NEAR(sigma, 3.0, 3.0 * 3 * 1.17 / std::sqrt(64.0 * 63.0));  // 3 standard errors
  EXPECT_NEAR(se, 2.33 / std::sqrt(64.0 * 63.0), 1e-12);
  EXPECT_EQ(EstimateBackgroundSigma(y, Image::Zero(64, 64)), 0.0);  // no valid pair
  EXPECT_THAT(test::ErrorOf([&] { EstimateBackgroundSigma(y, Image::Zero(3, 3)); }), HasSubstr("valid"));
}

// --target-psf diffraction: the telescope's Airy pattern (paper-8m: 14 % central obstruction) on the HR grid.
// Sampled at λ/(8D) its FWHM is 1.03 λ/D within 3 % (the obstruction narrows the core by ~1 %; the
// equivalent-area FWHM of psf_metrics.hpp, a bilinear interpolant, is good to ~1 % at 8 px per λ/D), at λ/(4D)
// within 4 % (measured 1.024 and 1.005). At the demo's r = 2 (λ/(2D) per HR px) the bilinear measure itself is
// biased (0.90): there the PSF must be the same pattern point-sampled, i.e. every 4th pixel of the r = 8 one.
// The weights' rule applied to a section gives what the whole field's weights hold there, and refuses a rule it
// cannot apply; a dataset opened by sections is refused where its whole frames would be needed.
TEST(DatasetWeightsTest, RuleAppliedToASectionAndItsRefusals) {
  const ImageStack valid{Image::Ones(4, 5), Image::Ones(4, 5)};
  WeightsRule rule;
  EXPECT_TRUE(ApplyWeightsRule(rule, valid, std::nullopt).empty());
  EXPECT_TRUE(rule.Uniform());
  rule.kind = WeightsRule::Kind::kBackground;
  rule.variance_e2 = {4.0, 4.0};
  const ImageStack w = ApplyWeightsRule(rule, valid, std::nullopt);
  ASSERT_EQ(w.size(), 2u);
  EXPECT_EQ(w[1](2, 3), 0.25);
  EXPECT_TRUE(rule.Uniform());
  rule.any_invalid = true;
  EXPECT_FALSE(rule.Uniform());
  rule.variance_e2 = {4.0};  // one per frame
  EXPECT_THROW(ApplyWeightsRule(rule, valid, std::nullopt), InvalidArgument);
  rule.kind = WeightsRule::Kind::kDataset;
  EXPECT_THROW(ApplyWeightsRule(rule, valid, std::nullopt), InvalidArgument);  // no dataset weights
  rule.gain2 = 4.0;
  const ImageStack wd = ApplyWeightsRule(rule, valid, ImageStack{Image::Constant(4, 5, 8.0), Image::Constant(4, 5, 8.0)});
  EXPECT_EQ(wd[0](1, 1), 2.0);

  Dataset lazy;
  lazy.r = 2;
  lazy.frame = {8, 8};
  lazy.hr_frame = {16, 16};
  lazy.psfs.assign(2, Image::Constant(4, 4, 1.0 / 16));
  lazy.offsets.assign(2, DmOffset{});
  lazy.pixel_files = Dataset::PixelFiles{"/nonexistent/frames.fits", "", "", 2};
  DatasetProblemOptions o;
  EXPECT_THROW(ProblemFromDataset(lazy, o), InvalidArgument);  // a whole-grid model needs the whole frames
  o.whole_grid_model = false;
  EXPECT_THROW(ProblemFromDataset(lazy, o), IoError);  // no rule from a plan: decided from the frames, here missing
  o.weights_rule = WeightsRule{};
  o.stars_psfs = true;
  EXPECT_THROW(ProblemFromDataset(lazy, o), InvalidArgument);  // stars need the whole frames
  o.stars_psfs = false;
  const DatasetProblem dp = ProblemFromDataset(lazy, o);  // reads nothing until a window is asked for
  ASSERT_TRUE(dp.field && dp.field->sections);
  EXPECT_TRUE(dp.field->frames.empty());
  ImageStack f, ww;
  EXPECT_THROW(dp.field->sections->read(0, 0, 4, 4, &f, &ww), IoError);  // the missing file, by name
}

// A plan that opens the dataset by sections (aosr.distributed.reconstruct_tiles) decides the weights' rule by
// reading the frames in bands: the rule and the masked pixels of the frames held whole, bit for bit, for each way
// the weights can be made (the dataset's, the background estimated from the frames, the mask), with a NaN pixel, a
// masked one and a zero weight.
TEST(DatasetWeightsTest, RuleDecidedBySectionsEqualsTheHeldFramesRule) {
  testing_io::TempDir dir;
  std::mt19937 rng(7);
  std::normal_distribution<double> noise(0.0, 3.0);
  ImageStack frames(2, Image(40, 36)), valid(2, Image::Ones(40, 36)), weights(2, Image::Constant(40, 36, 0.1));
  for (Image& f : frames)
    for (Index p = 0; p < f.size(); ++p) f(p) = 100.0 + noise(rng);
  frames[1](3, 4) = std::nan("");
  valid[0](30, 9) = 0;
  weights[1](12, 20) = 0;
  WriteFitsCube(dir.File("frames.fits"), frames, {}, FitsType::kFloat64);
  WriteFitsCube(dir.File("valid.fits"), valid, {}, FitsType::kFloat64);
  WriteFitsCube(dir.File("w.fits"), weights, {}, FitsType::kFloat64);
  WriteFits(dir.File("psf.fits"), Image::Constant(4, 4, 1.0 / 16), {}, FitsType::kFloat64);
  test::WriteJson(dir.File("manifest.json"), {{"format", "aosr-manifest"}, {"version", 1}, {"frames", "frames.fits"},
                                              {"valid", "valid.fits"}, {"weights", "w.fits"}, {"psfs", "psf.fits"},
                                              {"r", 2}, {"gain_e_per_adu", 2.0}, {"bias_adu", 100.0}});
  const Dataset held = LoadDataset(dir.path().string());
  const Dataset lazy = LoadDataset(dir.path().string(), DatasetPixels::kSections);
  for (const DatasetWeights choice : {DatasetWeights::kDataset, DatasetWeights::kBackground, DatasetWeights::kMask}) {
    SCOPED_TRACE(int(choice));
    DatasetProblemOptions o;
    o.weights = choice;
    o.method = ReconstructionMethod::kTikhonov;
    o.whole_grid_model = false;
    const DatasetProblem a = ProblemFromDataset(held, o), b = ProblemFromDataset(lazy, o);
    EXPECT_EQ(a.weights_rule.kind, b.weights_rule.kind);
    EXPECT_EQ(a.weights_rule.variance_e2, b.weights_rule.variance_e2);  // exactly: the same estimate
    EXPECT_EQ(a.weights_rule.gain2, b.weights_rule.gain2);
    EXPECT_TRUE(a.weights_rule.any_invalid && b.weights_rule.any_invalid);
    EXPECT_EQ(a.weights_source, b.weights_source);
    EXPECT_EQ(a.masked_pixels, b.masked_pixels);
    EXPECT_EQ(a.masked_pixels, choice == DatasetWeights::kDataset ? 3 : 2);  // the NaN, the mask (and the zero weight)
    ASSERT_TRUE(b.field && b.field->sections);
    ImageStack f, w;
    b.field->sections->read(0, 0, 40, 36, &f, &w);
    ASSERT_EQ(w.size(), 2u);
    for (int i = 0; i < 2; ++i) EXPECT_TRUE((w[i] == a.field->weights[i]).all()) << i;
  }
}

TEST(DiffractionTargetTest, AiryFwhmAtTheDatasetsWavelengthAndSampling) {
  const TelescopePreset preset = LoadTelescopePreset("paper-8m");
  std::map<int, Image> psfs;
  for (int r : {8, 4, 2}) {
    Dataset d;
    d.r = r;
    d.frame = {32, 32};
    d.hr_frame = {32 * r, 32 * r};
    d.wavelength_m = preset.science_wavelength_m;
    d.camera_pixel_rad = preset.LambdaOverD();  // camera pixel = λ/D
    d.manifest = {{"simulation", {{"scene", {{"source", "test"}, {"json", {{"telescope", "paper-8m"}}}}}}}};
    const Image psf = DiffractionTargetPsf(d);
    EXPECT_EQ(psf.rows(), 64);
    EXPECT_NEAR(psf.sum(), 1.0, 1e-12);
    const double fwhm_lod = MeasurePsf(psf).fwhm_px / double(r);  // λ/D is r HR pixels
    std::printf("r = %d: FWHM %.4f lambda/D\n", r, fwhm_lod);
    if (r == 8) {
      EXPECT_NEAR(fwhm_lod, 1.03, 0.03);
    } else if (r == 4) {
      EXPECT_NEAR(fwhm_lod, 1.03, 0.04);
    }
    Index py = 0, px = 0;
    psf.maxCoeff(&py, &px);
    EXPECT_EQ(py, 32);  // centred at (K/2, K/2)
    EXPECT_EQ(px, 32);
    psfs[r] = psf / psf.maxCoeff();
  }
  for (Index y = -7; y <= 7; ++y)
    for (Index x = -7; x <= 7; ++x)
      EXPECT_NEAR(psfs[2](32 + y, 32 + x), psfs[8](32 + 4 * y, 32 + 4 * x), 1e-9) << y << ", " << x;
  Dataset bare;
  bare.r = 2;
  bare.hr_frame = {64, 64};
  bare.manifest_path = "measured/manifest.json";
  EXPECT_THAT(test::ErrorOf([&] { DiffractionTargetPsf(bare); }), HasSubstr("scene"));
}

}  // namespace
}  // namespace aosr
