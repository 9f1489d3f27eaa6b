// EstimateStarsPsf (and ProblemFromDataset's stars_psfs) refuse frames that cannot support an estimate, naming
// what is missing: never a silent fallback to another PSF.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "aosr/scene/dataset_memory.hpp"
#include "aosr/solvers/dataset_problem.hpp"
#include "aosr/solvers/stars_psf.hpp"
#include "solvers/stars_psf_fixture.hpp"
#include "support/testing.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

using testing::AllOf;
using testing::HasSubstr;

StarsPsfOptions Small() {
  StarsPsfOptions o;
  o.psf_size_hr_px = 16;
  o.rounds = 2;
  return o;
}

TEST(StarsPsfErrors, AnEmptyFieldHasNoDetection) {
  const test::StarFrames f = test::MakeStarFrames({}, 0);
  EXPECT_THAT(test::ErrorOf([&] { EstimateStarsPsf(f.y, f.valid, {}, f.offsets, 2, Small()); }),
              AllOf(HasSubstr("EstimateStarsPsf"), HasSubstr("no point source above 5 sigma"),
                    HasSubstr("unsaturated point sources")));
}

TEST(StarsPsfErrors, TooFewStarsNameTheMinimumAndWhy) {
  const test::StarFrames f = test::MakeStarFrames({{20.3, 20.6}, {44.2, 40.7}}, 5000);
  EXPECT_THAT(test::ErrorOf([&] { EstimateStarsPsf(f.y, f.valid, {}, f.offsets, 2, Small()); }),
              AllOf(HasSubstr("usable stars = 2 detected"), HasSubstr(">= 4 = max(min_stars 4"),
                    HasSubstr("ceil(r^2/N) = 1")));
  // One frame at r = 2 needs r²/N = 4 stars at distinct sub-pixel phases, whatever min_stars says.
  StarsPsfOptions o = Small();
  o.min_stars = 1;
  EXPECT_THAT(test::ErrorOf([&] {
                EstimateStarsPsf({f.y[0]}, {f.valid[0]}, {}, {FrameOffset{}}, 2, o);  // r = 2, N = 1: 4
              }),
              HasSubstr(">= 4 = max(min_stars 1, ceil(r^2/N) = 4"));
}

TEST(StarsPsfErrors, OnlySaturatedStars) {
  const std::vector<std::pair<double, double>> stars = {{12.2, 12.7}, {12.4, 48.1}, {48.6, 12.3}, {48.5, 48.9}, {30.1, 30.4}};
  const test::StarFrames f = test::MakeStarFrames(stars, 20000, 1500);  // peaks ~2000 e-: every core saturates
  EXPECT_THAT(test::ErrorOf([&] { EstimateStarsPsf(f.y, f.valid, {}, f.offsets, 2, Small()); }),
              AllOf(HasSubstr("only saturated stars (5 detections"), HasSubstr("saturated core cannot constrain")));
}

TEST(StarsPsfErrors, BadArguments) {
  const test::StarFrames f = test::MakeStarFrames({{20.3, 20.6}}, 5000);
  StarsPsfOptions o = Small();
  o.psf_size_hr_px = 15;
  EXPECT_THAT(test::ErrorOf([&] { EstimateStarsPsf(f.y, f.valid, {}, f.offsets, 2, o); }),
              AllOf(HasSubstr("options"), HasSubstr("psf_size_hr_px = 15")));
  o = Small();
  o.detection_sigma = 0;
  EXPECT_THAT(test::ErrorOf([&] { EstimateStarsPsf(f.y, f.valid, {}, f.offsets, 2, o); }),
              HasSubstr("detection_sigma = 0"));
  o = Small();
  o.psf_size_hr_px = 128;
  EXPECT_THAT(test::ErrorOf([&] { EstimateStarsPsf(f.y, f.valid, {}, f.offsets, 2, o); }),
              AllOf(HasSubstr("psf_size_hr_px = 128"), HasSubstr("<= the HR frame 64x64")));
  EXPECT_THAT(test::ErrorOf([&] { EstimateStarsPsf(f.y, {f.valid[0]}, {}, f.offsets, 2, Small()); }),
              HasSubstr("valid count = 1"));
  EXPECT_THAT(test::ErrorOf([&] { EstimateStarsPsf(f.y, f.valid, {}, {FrameOffset{}}, 2, Small()); }),
              HasSubstr("offsets count = 1"));
  EXPECT_THAT(test::ErrorOf([&] { EstimateStarsPsf({}, {}, {}, {}, 2, Small()); }), HasSubstr("at least one frame"));
  o = Small();
  o.known_stars = {{10, 10, -1}};
  EXPECT_THAT(test::ErrorOf([&] { EstimateStarsPsf(f.y, f.valid, {}, f.offsets, 2, o); }),
              AllOf(HasSubstr("known_stars"), HasSubstr("positive fluxes")));
}

Dataset DatasetOf(const test::StarFrames& f, bool zernike) {
  DatasetArrays a;
  a.frames = f.y;
  a.valid = f.valid;
  a.r = 2;
  Image psf = Image::Zero(16, 16);
  psf(8, 8) = 1;
  a.psfs = {psf};
  a.nominal_psfs = {psf, psf, psf, psf};
  for (const FrameOffset& o : f.offsets) {
    DmOffset d;
    d.shift_y_px = o.dy / 2;
    d.shift_x_px = o.dx / 2;
    if (zernike) d.zernike.push_back({4, 50e-9});
    a.offsets.push_back(d);
  }
  return DatasetFromArrays(a);
}

TEST(StarsPsfErrors, DatasetOffsetsThatChangeThePsfShape) {
  const test::StarFrames f = test::MakeStarFrames({{20.3, 20.6}}, 5000);
  EXPECT_THAT(test::ErrorOf([&] { EstimateStarsPsf(DatasetOf(f, true), Small()); }),
              AllOf(HasSubstr("dataset offsets[0]"), HasSubstr("Zernike or actuator terms"), HasSubstr("tip/tilt")));
}

TEST(StarsPsfErrors, ProblemFromDatasetTakesOneSourceOfModelPsfs) {
  const test::StarFrames f = test::MakeStarFrames({{20.3, 20.6}}, 5000);
  DatasetProblemOptions o;
  o.stars_psfs = true;
  o.nominal_psfs = true;
  EXPECT_THAT(test::ErrorOf([&] { ProblemFromDataset(DatasetOf(f, false), o); }),
              AllOf(HasSubstr("stars_psfs"), HasSubstr("one source of model PSFs")));
  // And what the frames lack reaches the caller unchanged.
  o.nominal_psfs = false;
  o.stars = Small();
  EXPECT_THAT(test::ErrorOf([&] { ProblemFromDataset(DatasetOf(f, false), o); }), HasSubstr("usable stars = 1 detected"));
}

}  // namespace
}  // namespace aosr
