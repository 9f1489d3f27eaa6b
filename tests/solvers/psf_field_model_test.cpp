// The field-varying model in the reconstructors (solvers/psf_field_model.hpp): the tile hook interpolates the
// field's PSFs at each tile's centre; a dataset with a psf_field is reconstructed by tiles with local PSFs
// (automatically, and when asked), which beats the guide star's single PSF far from the guide star; what cannot
// use a field model says so.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <nlohmann/json.hpp>

#include "aosr/core/error.hpp"
#include "aosr/core/metrics.hpp"
#include "aosr/core/parallel.hpp"
#include "aosr/scene/dataset_memory.hpp"
#include "aosr/scene/pipeline.hpp"
#include "aosr/solvers/psf_field_model.hpp"
#include "support/testing.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

using ::testing::HasSubstr;

TEST(PsfFieldModelTest, TilePsfsAreTheFieldInterpolatedAtTheCoreCentre) {
  // Nodes on a 64 x 64 HR frame (32 camera px at r = 2): rows and columns 0 and 63.
  const PsfFieldGrid grid({64, 64}, 2, 2);
  std::vector<ImageStack> psfs;
  for (int k = 0; k < 4; ++k) psfs.push_back({Image::Constant(6, 6, k + 1.0), Image::Constant(6, 6, 10.0 * (k + 1))});
  const auto hook = FieldTilePsfs(grid, psfs, 2);
  TileWindow t;
  t.core_y0 = 0, t.core_rows = 16, t.core_x0 = 16, t.core_cols = 16;  // centre HR (15.5, 47.5)
  const ImageStack local = hook(t);
  ASSERT_EQ(local.size(), 2u);
  for (int i = 0; i < 2; ++i) {
    ImageStack node;
    for (const ImageStack& p : psfs) node.push_back(p[i]);
    EXPECT_LT((local[i] - grid.Interpolate(node, 15.5, 47.5)).abs().maxCoeff(), 1e-15);
  }
  // Half the spacing (63 HR px = 31.5 camera px): 16 camera px; one node along an axis: the whole axis.
  EXPECT_EQ(SuggestFieldTile(grid, 2, {32, 32}), 16);
  EXPECT_EQ(SuggestFieldTile(PsfFieldGrid({256, 256}, 2, 2), 2, {128, 128}), 64);
  EXPECT_EQ(SuggestFieldTile(PsfFieldGrid({256, 256}, 1, 2), 2, {128, 128}), 64);
  EXPECT_EQ(SuggestFieldTile(PsfFieldGrid({256, 256}, 1, 1), 2, {128, 128}), 128);
}

// paper-8m at K, analytic AO, a star cluster on a 64-px frame (3.6 arcsec) whose centre is 45 arcsec from the
// guide star: everywhere the PSF is the anisoplanatic one, broader than the guide star's. Tikhonov with the
// field model (auto: tiles) recovers the stars better than with the guide star's PSF (none), and as well as the
// space-variant operator over the whole field. Measured: tiles 36.03 dB, operator 36.09, guide star's PSF 33.76.
nlohmann::json WideScene() {
  return {{"name", "field-model"},
          {"telescope", "paper-8m"},
          {"frames", 4},
          {"r", 2},
          {"seed", 3},
          {"ao", {{"mode", "analytic"}}},
          {"offsets", {{"type", "raster"}}},
          {"psf_field", {{"guide_star_arcsec", {-45.0, 0.0}}, {"grid", 2}}},
          {"detector", {{"frame_px", 64}, {"noise", "peak-fraction"}, {"peak_noise_fraction", 0.0005}, {"saturation", false}}},
          {"objects", {{{"type", "stars"}, {"count", 40}, {"flux_range_e", {2e4, 2e5}}, {"margin_px", 6.0}}}}};
}

// WideScene with `frames` frames of `frame_px` camera px, simulated into a dataset (the smaller fields the error,
// memory and reproducibility tests need).
Dataset WideDataset(int frames, int frame_px) {
  nlohmann::json j = WideScene();
  j["frames"] = frames;
  j["detector"]["frame_px"] = frame_px;
  const SceneSpec scene = ParseScene(j, "<test>");
  return DatasetFromSimulation(scene, ScenePipeline(scene).Run());
}

TEST(PsfFieldModelTest, TilesWithLocalPsfsBeatTheGuideStarsPsfOffAxis) {
  const SceneSpec scene = ParseScene(WideScene(), "<test>");
  const Simulation sim = ScenePipeline(scene).Run();
  const Dataset d = DatasetFromSimulation(scene, sim);
  ASSERT_TRUE(d.psf_field.has_value());
  ReconstructOptions o;
  o.method = ReconstructionMethod::kTikhonov;
  DatasetProblemOptions dpo;
  dpo.method = o.method;
  const DatasetProblem field = ProblemFromDataset(d, dpo);  // auto: the field model
  ASSERT_TRUE(field.psf_field.has_value());
  TilingSummary ts;
  const Reconstruction with_field = ReconstructDataset(field, o, {}, &ts);
  EXPECT_EQ(ts.tile, 32);  // half of 127 HR px = 31.75 camera px
  EXPECT_EQ(ts.tiles_y * ts.tiles_x, 4);
  // λ on the central kFieldRegularisationWindow² camera px: here the whole (smaller) field, with the PSFs of
  // its centre; a smaller window when asked.
  EXPECT_EQ(ts.regularisation_source, "whole field");
  TilingOptions small;
  small.regularisation_window = 32;
  TilingSummary ts_small;
  const Reconstruction with_small = ReconstructDataset(field, o, small, &ts_small);
  EXPECT_EQ(ts_small.regularisation_source, "central 32 x 32 camera px");
  EXPECT_NE(with_small.regularisation, with_field.regularisation);
  dpo.psf_field = DatasetPsfField::kNone;
  const DatasetProblem single = ProblemFromDataset(d, dpo);
  EXPECT_FALSE(single.psf_field.has_value());
  const Reconstruction on_axis = ReconstructDataset(single, o);
  MetricOptions mo;
  mo.crop_px = 8;
  const double psnr_field = CompareImagesAligned(*d.truth, with_field.image, mo).aligned.psnr;
  const double psnr_axis = CompareImagesAligned(*d.truth, on_axis.image, mo).aligned.psnr;
  // The reference: the space-variant operator over the whole field, at the tiles' λ.
  dpo.psf_field = DatasetPsfField::kOperator;
  const DatasetProblem exact = ProblemFromDataset(d, dpo);
  ASSERT_TRUE(exact.problem.model->space_variant());
  const Reconstruction with_operator = ReconstructDataset(exact, o);
  EXPECT_EQ(with_operator.summary.termination, Termination::kConverged) << with_operator.summary.message;
  EXPECT_EQ(with_operator.regularisation, with_field.regularisation);  // the tiles' plan's λ
  // The operator takes the tiles' plan, window included (only the plan: its λ, not a solve, is compared).
  ReconstructOptions given = o;
  given.tikhonov.cg.max_iterations = 1;
  EXPECT_EQ(ReconstructDataset(exact, given, small).regularisation, with_small.regularisation);
  const double psnr_operator = CompareImagesAligned(*d.truth, with_operator.image, mo).aligned.psnr;
  std::printf("aligned PSNR: tiles %.2f dB, operator %.2f dB, guide star's PSF %.2f dB\n", psnr_field,
              psnr_operator, psnr_axis);
  EXPECT_GT(psnr_field, psnr_axis + 1.0);
  EXPECT_GT(psnr_operator, psnr_axis + 1.0);
  EXPECT_NEAR(psnr_field, psnr_operator, 0.5);
  EXPECT_TRUE(AllFinite(with_field.image));
  EXPECT_TRUE(AllFinite(with_operator.image));
}

// Under a memory limit (a dataset without a whole-grid model, as a whole detector is run), a field model's own
// tiles (half the node spacing) are kept where they fit, and the tiles that fit are used where they are smaller:
// the tiles' estimated peak stays under the limit. Not even the smallest tile: ResourceError.
TEST(PsfFieldModelTest, AFieldModelsTilesFitTheMemoryLimit) {
  const Dataset d = WideDataset(2, 192);
  ReconstructOptions o;
  o.method = ReconstructionMethod::kTikhonov;
  DatasetProblemOptions dpo;
  dpo.method = o.method;
  dpo.whole_grid_model = false;
  const DatasetProblem dp = ProblemFromDataset(d, dpo);
  ASSERT_TRUE(dp.psf_field.has_value() && dp.field);
  const int own = SuggestFieldTile(dp.psf_field->grid, d.r, d.frame);
  ASSERT_EQ(own, 96);
  // A generous limit: the field's own tiles (tile 0: ReconstructDataset's SuggestFieldTile).
  TilingOptions roomy;
  FitDatasetTilingToMemory(dp, o, 1e12, &roomy);
  EXPECT_EQ(roomy.tile, 0);
  EXPECT_EQ(roomy.regularisation_window, kFieldRegularisationWindow);
  // The smallest limit whose memory plan chooses tiles smaller than the field's own.
  double limit = 0;
  TilingOptions fit;
  for (double bytes = 1e6; bytes < 1e9 && limit == 0; bytes *= 1.25) {
    TilingOptions t;
    try {
      FitTilingToMemory(*dp.field, o, bytes, &t);
    } catch (const ResourceError&) {
      continue;
    }
    if (t.tile < own) limit = bytes, fit = t;
  }
  ASSERT_GT(limit, 0);
  TilingOptions tight;
  FitDatasetTilingToMemory(dp, o, limit, &tight);
  EXPECT_EQ(tight.tile, fit.tile);
  EXPECT_LT(tight.tile, own);
  TilingSummary ts;
  const Reconstruction rec = ReconstructDataset(dp, o, tight, &ts);
  EXPECT_EQ(ts.tile, fit.tile);
  EXPECT_TRUE(AllFinite(rec.image));
  const int concurrent = tight.parallel_tiles ? DefaultThreads() : 1;
  EXPECT_LE(EstimateTiledBytes(*dp.field, o.method, ts.tile, ts.overlap, concurrent, o.tikhonov.compute_std), limit)
      << "tile " << ts.tile << ", overlap " << ts.overlap;
  // The field's own tiles would not have fitted (what the CLI ran before: tiles of 96 under this limit).
  EXPECT_GT(EstimateTiledBytes(*dp.field, o.method, own, ts.overlap, 1, o.tikhonov.compute_std), limit);
  TilingOptions none;
  EXPECT_THROW(FitDatasetTilingToMemory(dp, o, 1e4, &none), ResourceError);
  // A problem without FieldData (a whole-grid model only) has nothing to plan: named, not a crash.
  const DatasetProblem whole_grid_only;
  EXPECT_THAT([&] { FitDatasetTilingToMemory(whole_grid_only, o, 1e12, &none); },
              ::testing::ThrowsMessage<InvalidArgument>(HasSubstr("problem.field")));
}

TEST(PsfFieldModelErrorsTest, WhatCannotUseAFieldModelSaysSo) {
  const Dataset d = WideDataset(2, 32);
  DatasetProblemOptions dpo;
  dpo.psf_field = DatasetPsfField::kTiles;
  dpo.method = ReconstructionMethod::kDrizzle;
  EXPECT_THAT([&] { ProblemFromDataset(d, dpo); },
              ::testing::ThrowsMessage<InvalidArgument>(HasSubstr("a method that models the PSF")));
  dpo.method = ReconstructionMethod::kTikhonov;
  dpo.model_psfs = {d.psfs.front()};
  EXPECT_THAT([&] { ProblemFromDataset(d, dpo); },
              ::testing::ThrowsMessage<InvalidArgument>(HasSubstr("the field model's PSFs are the dataset's")));
  dpo.model_psfs.clear();
  dpo.psf_field = DatasetPsfField::kOperator;
  dpo.method = ReconstructionMethod::kLinear;
  EXPECT_THAT([&] { ProblemFromDataset(d, dpo); }, ::testing::ThrowsMessage<InvalidArgument>(HasSubstr("per-frequency design")));
  dpo.method = ReconstructionMethod::kTikhonov;
  TilingOptions tiled;
  tiled.tile = 16;
  EXPECT_THAT([&] { ReconstructDataset(ProblemFromDataset(d, dpo), ReconstructOptions(), tiled); },
              ::testing::ThrowsMessage<InvalidArgument>(HasSubstr("one space-variant solve")));
  dpo.psf_field = DatasetPsfField::kTiles;
  dpo.nominal_psfs = true;  // an analytic simulation has no nominal PSFs (closed loops do)
  EXPECT_THAT([&] { ProblemFromDataset(d, dpo); }, ::testing::ThrowsMessage<InvalidArgument>(HasSubstr("nominal_psfs")));
  Dataset plain = d;
  plain.psf_field.reset();
  dpo.nominal_psfs = false;
  EXPECT_THAT([&] { ProblemFromDataset(plain, dpo); },
              ::testing::ThrowsMessage<InvalidArgument>(HasSubstr("a dataset with a psf_field")));
  // Registration moves the model's PSFs, not the field's: refused with a field model, also under auto.
  dpo.psf_field = DatasetPsfField::kAuto;
  dpo.method = ReconstructionMethod::kTikhonov;
  dpo.offsets = DatasetOffsets::kEstimate;
  EXPECT_THAT([&] { ProblemFromDataset(d, dpo); },
              ::testing::ThrowsMessage<InvalidArgument>(HasSubstr("registration does not move the field's PSFs")));
  dpo.offsets = DatasetOffsets::kAuto;
  // Auto with drizzle: no field model, no error.
  dpo.psf_field = DatasetPsfField::kAuto;
  dpo.method = ReconstructionMethod::kDrizzle;
  EXPECT_FALSE(ProblemFromDataset(d, dpo).psf_field.has_value());
  EXPECT_THAT([] { ParseDatasetPsfField("grid"); }, ::testing::ThrowsMessage<InvalidArgument>(HasSubstr("auto | none | tiles | operator")));
  EXPECT_THAT([] { FieldTilePsfs(PsfFieldGrid({8, 8}, 2, 2), {}, 2); },
              ::testing::ThrowsMessage<InvalidArgument>(HasSubstr("one stack per node")));
}

}  // namespace AOSR_TEST_NS
}  // namespace aosr

namespace aosr {
namespace AOSR_TEST_NS {

// Reproducible: the field's simulation and both field models give the same bytes on 1 and 2 threads (tiles are
// solved in parallel and blended in tile order; the operator's sum runs in node order).
TEST(PsfFieldModelStabilityTest, SameBytesOnOneAndTwoThreads) {
  const int saved = DefaultThreads();
  std::vector<Image> images;
  for (int threads : {1, 2}) {
    SetDefaultThreads(threads);
    const Dataset d = WideDataset(2, 48);
    images.push_back(d.frames[1]);
    ReconstructOptions o;
    o.method = ReconstructionMethod::kTikhonov;
    DatasetProblemOptions dpo;
    dpo.method = o.method;
    for (DatasetPsfField f : {DatasetPsfField::kTiles, DatasetPsfField::kOperator}) {
      dpo.psf_field = f;
      images.push_back(ReconstructDataset(ProblemFromDataset(d, dpo), o).image);
    }
  }
  SetDefaultThreads(saved);
  const std::size_t half = images.size() / 2;
  for (std::size_t k = 0; k < half; ++k)
    EXPECT_TRUE((images[k].array() == images[k + half].array()).all()) << "output " << k;
}

}  // namespace AOSR_TEST_NS
}  // namespace aosr
