// Bad tilings are refused with an InvalidArgument that names the function, the field and the value.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <memory>

#include "aosr/solvers/tiling.hpp"
#include "solvers/tikhonov_fixture.hpp"
#include "support/testing.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

using ::testing::AllOf;
using ::testing::HasSubstr;

ReconstructionProblem SmallProblem() {
  ReconstructionProblem p;
  p.model = std::make_shared<const MultiFrameModel>(test::RasterModel({64, 64}, 2, {{0, 0}, {1, 1}}, 1.0));
  p.frames = p.model->Render(test::RandomImage({64, 64}, 3, false));
  return p;
}

TEST(TilingErrorsTest, BadTileAndOverlap) {
  const ReconstructionProblem p = SmallProblem();  // 32 x 32 camera px
  ReconstructOptions o;
  TilingOptions t;
  t.tile = 0;
  EXPECT_THAT(test::ErrorOf([&] { ReconstructTiled(p, o, t); }),
              AllOf(HasSubstr("ReconstructTiled"), HasSubstr("tile = 0"), HasSubstr(">= 1")));
  t.tile = 8;
  t.overlap = -2;
  EXPECT_THAT(test::ErrorOf([&] { ReconstructTiled(p, o, t); }),
              AllOf(HasSubstr("ReconstructTiled"), HasSubstr("overlap = -2")));
  t.overlap = 9;  // more than a core of 8
  EXPECT_THAT(test::ErrorOf([&] { ReconstructTiled(p, o, t); }),
              AllOf(HasSubstr("ReconstructTiled"), HasSubstr("overlap"), HasSubstr("9"),
                    HasSubstr("smallest tile core")));
  t.tile = 20;  // cores 16 + 2·9 = 34 > 32
  EXPECT_THAT(test::ErrorOf([&] { ReconstructTiled(p, o, t); }),
              AllOf(HasSubstr("ReconstructTiled"), HasSubstr("tile, overlap"), HasSubstr("20, 9")));
  t.overlap = 2;
  t.psf_tail = 1.5;
  EXPECT_THAT(test::ErrorOf([&] { ReconstructTiled(p, o, t); }), HasSubstr("psf_tail"));
  t.psf_tail = 1e-4;
  for (const double tolerance : {0.0, 1.0, -1e-6}) {
    t.tolerance = tolerance;
    EXPECT_THAT(test::ErrorOf([&] { ReconstructTiled(p, o, t); }),
                AllOf(HasSubstr("ReconstructTiled"), HasSubstr("tolerance"))) << tolerance;
  }
  t.tolerance = 1e-6;
  t.max_overlap = -2;
  EXPECT_THAT(test::ErrorOf([&] { ReconstructTiled(p, o, t); }),
              AllOf(HasSubstr("ReconstructTiled"), HasSubstr("max_overlap = -2")));
  EXPECT_THAT(test::ErrorOf([&] { MakeTiles({32, 32}, 4, -1); }), AllOf(HasSubstr("MakeTiles"), HasSubstr("overlap")));
}

TEST(TilingErrorsTest, BadLocalPsfs) {
  const ReconstructionProblem p = SmallProblem();
  ReconstructOptions o;
  o.tikhonov.lambda_rule = TikhonovLambdaRule::kFixed;
  TilingOptions t;
  t.tile = 16;
  t.overlap = 4;
  t.local_psfs = [](const TileWindow&) { return ImageStack{test::GaussianKernel(5, 1.0)}; };  // one, not two
  EXPECT_THAT(test::ErrorOf([&] { ReconstructTiled(p, o, t); }),
              AllOf(HasSubstr("ReconstructTiled"), HasSubstr("local_psfs"), HasSubstr("1 kernels")));
}

TEST(TilingErrorsTest, BadOptionsOfTheMethodAreNamed) {
  const ReconstructionProblem p = SmallProblem();
  ReconstructOptions o;
  o.method = ReconstructionMethod::kLinear;
  o.linear.kappa = -1;
  TilingOptions t;
  t.tile = 16;
  EXPECT_THAT(test::ErrorOf([&] { ReconstructTiled(p, o, t); }), HasSubstr("kappa = -1"));
}

}  // namespace
}  // namespace aosr
