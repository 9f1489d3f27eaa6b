// RegisterFrames (solvers/registration.hpp): offsets applied by the "DM" that differ from the commanded ones
// (a gain error, a jitter per frame) are recovered from the frames at the paper's noise (Gaussian, σ = 1 % of
// the brightest noiseless pixel), and the reconstruction with them is as good as with the exact offsets.
#include "aosr/solvers/registration.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "aosr/core/metrics.hpp"
#include "aosr/scene/objects.hpp"
#include "solvers/tikhonov_fixture.hpp"
#include "support/testing.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

using Shifts = std::vector<std::pair<double, double>>;

// The classic N = 4 raster, ±1/4 camera px, in HR px.
Shifts Raster4(int r) {
  const double q = 0.25 * r;
  return {{-q, -q}, {-q, q}, {q, -q}, {q, q}};
}

struct Case {
  ReconstructionProblem commanded;  // model and offsets as commanded
  ReconstructionProblem exact;      // model and offsets as applied
  Image truth;
  Shifts applied;
};

// Frames made with `applied` shifts, modelled with `commanded` ones; the PSF a Gaussian of σ = 0.45 camera px
// (about the paper's K-band core at λ/D per camera pixel).
Case MakeCase(int r, const Shifts& commanded, const Shifts& applied, std::uint64_t seed) {
  const Shape hr{64 * r, 64 * r};
  Case c;
  c.truth = DemoObject(hr);
  const MultiFrameModel truth_model = test::RasterModel(hr, r, applied, 0.45 * r);
  ImageStack clean = truth_model.Render(c.truth);
  double peak = 0;
  for (const Image& f : clean) peak = std::max(peak, f.maxCoeff());
  c.commanded.model = std::make_shared<const MultiFrameModel>(test::RasterModel(hr, r, commanded, 0.45 * r));
  c.commanded.frames = test::AddNoise(clean, 0.01 * peak, seed);
  for (auto [dy, dx] : commanded) c.commanded.offsets.push_back({dy, dx});
  c.exact = c.commanded;
  c.exact.model = std::make_shared<const MultiFrameModel>(truth_model);
  c.exact.offsets.clear();
  for (auto [dy, dx] : applied) c.exact.offsets.push_back({dy, dx});
  c.applied = applied;
  return c;
}

// RMS over frames and axes of estimated − applied [camera px], after removing the mean difference (the
// absolute position is not in the data; the anchor fixes it to the commanded mean).
double RmsError(const RegistrationResult& res, const Shifts& applied, int r) {
  const std::size_t n = applied.size();
  double my = 0, mx = 0;
  for (std::size_t i = 0; i < n; ++i) {
    my += (res.estimated[i].dy - applied[i].first) / n;
    mx += (res.estimated[i].dx - applied[i].second) / n;
  }
  double s = 0;
  for (std::size_t i = 0; i < n; ++i) {
    s += std::pow(res.estimated[i].dy - applied[i].first - my, 2);
    s += std::pow(res.estimated[i].dx - applied[i].second - mx, 2);
  }
  return std::sqrt(s / (2.0 * n)) / r;
}

double TikhonovPsnr(const ReconstructionProblem& p, const Image& truth) {
  TikhonovOptions o;
  o.lambda_rule = TikhonovLambdaRule::kGcv;
  return Psnr(truth, ReconstructTikhonov(p, o).image);
}

Shifts Jittered(const Shifts& s, double rms_hr, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> n01;
  Shifts out;
  for (auto [dy, dx] : s) out.push_back({dy + rms_hr * n01(rng), dx + rms_hr * n01(rng)});
  return out;
}

Shifts Scaled(const Shifts& s, double gain) {
  Shifts out;
  for (auto [dy, dx] : s) out.push_back({gain * dy, gain * dx});
  return out;
}

void ExpectRecovered(const Case& c, int r, double rms_tol, double db_tol) {
  const RegistrationResult res = RegisterFrames(c.commanded);
  const double rms = RmsError(res, c.applied, r);
  const double before = [&] {
    RegistrationResult none;
    none.estimated = c.commanded.offsets;
    return RmsError(none, c.applied, r);
  }();
  const double p_exact = TikhonovPsnr(c.exact, c.truth), p_est = TikhonovPsnr(res.problem, c.truth),
               p_cmd = TikhonovPsnr(c.commanded, c.truth);
  std::printf("r = %d: commanded error %.4f camera px RMS, estimated %.4f (%d rounds%s); PSNR exact %.2f, "
              "estimated %.2f, commanded %.2f dB\n",
              r, before, rms, res.rounds, res.converged ? ", converged" : "", p_exact, p_est, p_cmd);
  for (std::size_t i = 0; i < c.applied.size(); ++i)
    std::printf("  frame %zu: applied (%.4f, %.4f) estimated (%.4f, %.4f) ± %.4f camera px\n", i,
                c.applied[i].first / r, c.applied[i].second / r, res.estimated[i].dy / r, res.estimated[i].dx / r,
                res.sigma_hr_px[i] / r);
  EXPECT_LE(rms, rms_tol);
  EXPECT_NEAR(p_est, p_exact, db_tol);
}

TEST(RegisterFrames, RecoversADmGainErrorAtR2) {
  const Shifts cmd = Raster4(2);
  ExpectRecovered(MakeCase(2, cmd, Scaled(cmd, 1.1), 11), 2, 0.02, 0.1);
}

TEST(RegisterFrames, RecoversADmGainErrorAtR4) {
  const Shifts cmd = Raster4(4);
  ExpectRecovered(MakeCase(4, cmd, Scaled(cmd, 1.1), 12), 4, 0.02, 0.1);
}

TEST(RegisterFrames, RecoversAJitterPerFrameAtR2) {
  const Shifts cmd = Raster4(2);
  ExpectRecovered(MakeCase(2, cmd, Jittered(cmd, 0.05 * 2, 7), 13), 2, 0.02, 0.1);
}

TEST(RegisterFrames, RecoversAJitterPerFrameAtR4) {
  const Shifts cmd = Raster4(4);
  ExpectRecovered(MakeCase(4, cmd, Jittered(cmd, 0.05 * 4, 8), 14), 4, 0.02, 0.1);
}

TEST(RegisterFrames, LeavesExactCommandsAlone) {
  const Shifts cmd = Raster4(2);
  const Case c = MakeCase(2, cmd, cmd, 15);
  const RegistrationResult res = RegisterFrames(c.commanded);
  EXPECT_LE(RmsError(res, cmd, 2), 0.005);
  EXPECT_EQ(res.commanded.size(), 4u);
}

TEST(RegisterFrames, AnchorsAtFrameZero) {
  const Shifts cmd = Raster4(2);
  RegistrationOptions o;
  o.anchor = RegistrationAnchor::kFrameZero;
  const RegistrationResult res = RegisterFrames(MakeCase(2, cmd, Scaled(cmd, 1.1), 16).commanded, o);
  EXPECT_EQ(res.correction[0].dy, 0.0);
  EXPECT_EQ(res.correction[0].dx, 0.0);
}

TEST(RegisterFrames, ShiftProblemFramesMovesModelAndOffsets) {
  const Shape hr{32, 32};
  ReconstructionProblem p;
  p.model = std::make_shared<const MultiFrameModel>(test::RasterModel(hr, 2, {{0, 0}}, 1.0));
  p.frames = {Image::Zero(16, 16)};
  const ReconstructionProblem q = ShiftProblemFrames(p, {{0.5, -1.0}});
  const ComplexImage want = p.model->otf(0) * ShiftTransfer(hr, 0.5, -1.0);
  EXPECT_LT((q.model->otf(0) - want).abs().maxCoeff(), 1e-14);
  EXPECT_DOUBLE_EQ(q.offsets[0].dy, 0.5);
  EXPECT_DOUBLE_EQ(q.offsets[0].dx, -1.0);
}

TEST(RegisterFrames, OptionsAreChecked) {
  std::string why;
  RegistrationOptions o;
  EXPECT_TRUE(o.IsValid(&why));
  o.search_range_camera_px = 0;
  EXPECT_FALSE(o.IsValid(&why));
  EXPECT_THAT(why, testing::HasSubstr("search_range_camera_px"));
  o = {};
  o.outer_iterations = 0;
  EXPECT_FALSE(o.IsValid(&why));
  EXPECT_THAT(why, testing::HasSubstr("outer_iterations"));
  EXPECT_EQ(ParseRegistrationAnchor("frame0"), RegistrationAnchor::kFrameZero);
  EXPECT_THAT(test::ErrorOf([] { ParseRegistrationAnchor("x"); }), testing::HasSubstr("mean | frame0"));
}

}  // namespace
}  // namespace aosr
