// The field-varying PSF in the simulator (scene_spec.hpp, PsfFieldSpec; core/psf_field.hpp): a grid with one node
// at the guide star renders the isoplanatic frames byte for byte; a star is imaged through the bilinear
// interpolation of its neighbours' PSFs, exactly; flux is conserved; off-axis stars are blurred by
// anisoplanatism as the analytic model says; and the interpolation's error against the true PSF between nodes
// falls as the grid is refined.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <nlohmann/json.hpp>

#include "aosr/core/operators.hpp"
#include "aosr/scene/pipeline.hpp"
#include "aosr/scene/preset_psf.hpp"
#include "aosr/scene/telescope.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

constexpr double kFieldTestArcsecPerRad = 180.0 * 3600.0 / M_PI;

nlohmann::json FieldScene(nlohmann::json objects, int frame_px = 32) {
  return {{"name", "field"},
          {"telescope", "paper-8m"},
          {"frames", 2},
          {"r", 2},
          {"ao", {{"mode", "analytic"}}},
          {"offsets", {{"type", "raster"}}},
          {"detector", {{"frame_px", frame_px}, {"noise", "none"}, {"saturation", false}}},
          {"objects", std::move(objects)}};
}

Image Decimated(const Image& hr, int r) {
  const Shape lr{hr.rows() / r, hr.cols() / r};
  return ToImage(Decimate(ShapeOf(hr), r)->Apply(AsVector(hr)), lr);
}

// One node, at the frame's centre, with the guide star there: the same PSF as the isoplanatic scene, and the
// same frames to the last bit (the weight is exactly 1 everywhere).
TEST(PsfFieldPhysics, OneNodeAtTheGuideStarRendersTheIsoplanaticFramesExactly) {
  const nlohmann::json objects = {
      {{"type", "galaxies"}, {"count", 2}, {"margin_px", 8.0}, {"flux", {{"total_e", 1e5}}}},
      {{"type", "stars"}, {"catalogue", {{{"y_px", 12.3}, {"x_px", 17.8}, {"flux_e", 5e3}}}}}};
  nlohmann::json j = FieldScene(objects);
  const Simulation plain = ScenePipeline(ParseScene(j, "<test>")).Run();
  j["psf_field"] = {{"grid", 1}};
  const Simulation field = ScenePipeline(ParseScene(j, "<test>")).Run();
  ASSERT_EQ(field.field_psfs.size(), 1u);
  EXPECT_EQ(field.field_directions[0].Norm(), 0.0);
  for (int i = 0; i < 2; ++i) {
    EXPECT_TRUE((field.psfs[i].array() == plain.psfs[i].array()).all()) << i;
    EXPECT_TRUE((field.field_psfs[0][i].array() == plain.psfs[i].array()).all()) << i;
    EXPECT_TRUE((field.expected_e[i].array() == plain.expected_e[i].array()).all()) << i;
  }
}

// A star at an HR pixel centre is imaged through Σ_k w_k(p) h_k (psf_field.hpp): the frame is D_r of the
// linear convolution of a delta with that interpolated PSF, to rounding.
TEST(PsfFieldPhysics, AStarIsImagedThroughItsInterpolatedPsf) {
  // Camera (y, x) = (9.75, 21.25) is HR (20, 43) at r = 2: (c + 1/2) r − 1/2.
  nlohmann::json j = FieldScene({{{"type", "stars"}, {"catalogue", {{{"y_px", 9.75}, {"x_px", 21.25}, {"flux_e", 1e4}}}}}});
  j["psf_field"] = {{"guide_star_arcsec", {-15.0, 4.0}}, {"grid", {2, 3}}};
  const Simulation sim = ScenePipeline(ParseScene(j, "<test>")).Run();
  ASSERT_EQ(sim.field_psfs.size(), 6u);
  const Shape hr = sim.geometry.hr_frame;
  Image delta = Image::Zero(hr.rows, hr.cols);
  delta(20, 43) = 1e4;
  for (int i = 0; i < 2; ++i) {
    ImageStack node_psfs;
    for (const ImageStack& node : sim.field_psfs) node_psfs.push_back(node[i]);
    const Image h = sim.field_grid.Interpolate(node_psfs, 20.0, 43.0);
    const Image expected = Decimated(ToImage(LinearConvolution(hr, h)->Apply(AsVector(delta)), hr), 2);
    const double peak = expected.maxCoeff();
    EXPECT_LT((sim.expected_e[i] - expected).abs().maxCoeff(), 1e-9 * peak) << "frame " << i;
  }
  // The nodes' PSFs differ (anisoplanatism across 1.8 arcsec at 15 arcsec from the guide star), so the test
  // above could tell a wrong interpolation from a right one.
  const double peak = sim.field_psfs[0][0].maxCoeff();
  EXPECT_GT((sim.field_psfs[0][0] - sim.field_psfs[5][0]).abs().maxCoeff(), 1e-3 * peak);
}

// The weights are a partition of unity: light is conserved through the field-varying convolution.
TEST(PsfFieldPhysics, FluxIsConservedThroughTheFieldVaryingConvolution) {
  nlohmann::json j = FieldScene({{{"type", "galaxies"}, {"count", 3}, {"margin_px", 24.0}, {"flux", {{"total_e", 5e4}}}},
                                 {{"type", "stars"}, {"catalogue", {{{"y_px", 31.25}, {"x_px", 32.75}, {"flux_e", 2e3}}}}}},
                                64);
  j["psf_field"] = {{"guide_star_arcsec", {12.0, -30.0}}, {"grid", 3}};
  const Simulation sim = ScenePipeline(ParseScene(j, "<test>")).Run();
  const double total = sim.truth.sum();
  for (int i = 0; i < 2; ++i) EXPECT_NEAR(sim.expected_e[i].sum(), total, 2e-4 * total) << i;
}

// Off axis the Strehl falls as the analytic model's: the nodes' Strehl ratios are those of aosr psf at the
// same directions, and a star imaged 40 arcsec from the guide star has a fainter peak than on axis.
TEST(PsfFieldPhysics, StarsFarFromTheGuideStarAreBlurredByAnisoplanatism) {
  const nlohmann::json star = {{{"type", "stars"}, {"catalogue", {{{"y_px", 15.75}, {"x_px", 15.75}, {"flux_e", 1e4}}}}}};
  nlohmann::json j = FieldScene(star);
  j.erase("offsets");  // no designed tilt: the PSFs are centred, as aosr psf's
  j["psf_field"] = {{"guide_star_arcsec", {0.0, 0.0}}, {"grid", 2}};
  const Simulation near = ScenePipeline(ParseScene(j, "<test>")).Run();
  j["psf_field"] = {{"guide_star_arcsec", {-40.0, 0.0}}, {"grid", 2}};
  const SceneSpec far_scene = ParseScene(j, "<test>");
  const Simulation far = ScenePipeline(far_scene).Run();
  EXPECT_LT(far.expected_e[0].maxCoeff(), 0.8 * near.expected_e[0].maxCoeff());
  // Node 0's PSF against the preset PSF at its direction (same analytic model, same sampling).
  PresetPsfOptions o;
  o.mode = "analytic";
  o.r = 2;
  o.size = int(far.geometry.psf_size);
  o.field_direction = far.field_directions[0];
  const PresetPsf p = ComputePresetPsf(far_scene.telescope, o);
  EXPECT_NEAR(far.field_directions[0].x_rad * kFieldTestArcsecPerRad, 40.0 - 31.5 * 0.5 * 2.2e-6 / 8 * kFieldTestArcsecPerRad, 1e-9);
  const double preset_peak = p.psf.maxCoeff() / p.psf.sum();
  EXPECT_NEAR(far.field_psfs[0][0].maxCoeff(), preset_peak, 1e-6 * preset_peak);
}

// Bilinear interpolation between nodes against the analytic PSF computed at the point itself, along the line
// from the guide star (where the PSF changes fastest), for node spacings of 2 theta0 / 3 ... theta0 / 6. The
// error is second order in the spacing away from the guide star (the PSF's curvature in field position): halving
// the spacing divides it by about four. Measured (paper-8m, K, HR px lambda/2D, % of the true PSF's peak):
// printed by the test; bench/results/wide_field.md has the table.
TEST(PsfFieldPhysics, InterpolationErrorFallsWithTheNodeSpacing) {
  const TelescopePreset preset = LoadTelescopePreset("paper-8m");
  PresetPsfOptions o;
  o.mode = "analytic";
  o.r = 2;
  o.size = 64;
  auto psf_at = [&](double arcsec) {
    o.field_direction = {arcsec / kFieldTestArcsecPerRad, 0.0};
    const Image p = ComputePresetPsf(preset, o).psf;
    return Image(p / p.sum());
  };
  // Error at the midpoint of nodes (a, b), relative to the true PSF's peak there.
  auto mid_error = [&](double a, double b) {
    const Image truth = psf_at(0.5 * (a + b));
    return (0.5 * (psf_at(a) + psf_at(b)) - truth).abs().maxCoeff() / truth.maxCoeff();
  };
  const double coarse = mid_error(20.0, 34.0), fine = std::max(mid_error(20.0, 27.0), mid_error(27.0, 34.0));
  std::printf("interpolation error at the midpoint, %% of peak: spacing 14\" %.3f, 7\" %.3f (ratio %.2f)\n",
              100 * coarse, 100 * fine, coarse / fine);
  EXPECT_GT(coarse / fine, 2.5);
  EXPECT_LT(coarse, 0.05);
}

}  // namespace AOSR_TEST_NS
}  // namespace aosr
