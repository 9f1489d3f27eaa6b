// RegisterFrames refuses what it cannot estimate, naming the frame and what is missing: never a silent
// fallback to the commanded offsets.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "aosr/scene/objects.hpp"
#include "aosr/solvers/registration.hpp"
#include "solvers/tikhonov_fixture.hpp"
#include "support/testing.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

using testing::HasSubstr;

ReconstructionProblem Problem(const std::vector<std::pair<double, double>>& applied,
                              const std::vector<std::pair<double, double>>& commanded, bool flat) {
  const Shape hr{128, 128};
  const Image x = flat ? Image::Constant(128, 128, 5.0) : DemoObject(hr);
  ReconstructionProblem p;
  p.frames = test::AddNoise(test::RasterModel(hr, 2, applied, 0.9).Render(x), flat ? 0.0 : 0.005, 3);
  p.model = std::make_shared<const MultiFrameModel>(test::RasterModel(hr, 2, commanded, 0.9));
  return p;
}

TEST(RegisterFramesErrors, FramesWithoutStructure) {
  const auto s = std::vector<std::pair<double, double>>{{0, 0}, {0, 1}, {1, 0}, {1, 1}};
  EXPECT_THAT(test::ErrorOf([&] { RegisterFrames(Problem(s, s, true)); }),
              AllOf(HasSubstr("RegisterFrames"), HasSubstr("frame 0"), HasSubstr("structure")));
}

TEST(RegisterFramesErrors, AShiftBeyondTheSearchRange) {
  // Frame 2 lands 2 camera px (4 HR px) from where it was commanded; the search range is ±0.5 camera px.
  const auto cmd = std::vector<std::pair<double, double>>{{0, 0}, {0, 1}, {1, 0}, {1, 1}};
  auto applied = cmd;
  applied[2] = {5, 0};
  EXPECT_THAT(test::ErrorOf([&] { RegisterFrames(Problem(applied, cmd, false)); }),
              AllOf(HasSubstr("frame 2"), HasSubstr("search range")));
}

TEST(RegisterFramesErrors, InvalidOptionsAndProblems) {
  const auto s = std::vector<std::pair<double, double>>{{0, 0}, {0, 1}};
  RegistrationOptions o;
  o.newton_iterations = 0;
  EXPECT_THAT(test::ErrorOf([&] { RegisterFrames(Problem(s, s, false), o); }), HasSubstr("newton_iterations"));
  ReconstructionProblem p = Problem(s, s, false);
  p.frames.pop_back();
  EXPECT_THAT(test::ErrorOf([&] { RegisterFrames(p); }), HasSubstr("RegisterFrames"));
  EXPECT_THAT(test::ErrorOf([&] { ShiftProblemFrames(Problem(s, s, false), {{0, 0}}); }),
              HasSubstr("correction count"));
}

}  // namespace
}  // namespace aosr
