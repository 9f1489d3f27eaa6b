// The acceptance run for the modal-gain fit: 50 seeded synthetic sets of the paper bench
// (data/calibration/paper-bench.json: modes 2-11 with gains 0.72-1.27, five amplitude levels poked at + and -,
// photon and read noise, a five-term static aberration, a resolved source, flux jitter). Label `slow`
// (about 25 CPU-minutes); CI runs the 10-trial version in calibrate_physics_test.cpp.
#include <gtest/gtest.h>

#include <cstdio>

#include "aosr/calib/calibration_set.hpp"
#include "calib_trials.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

TEST(CalibrateSlow, FiftyTrialsOfThePaperBenchSet) {
  const SyntheticCalibrationOptions o =
      LoadSyntheticCalibrationSpec(std::string(AOSR_SOURCE_DIR) + "/data/calibration/paper-bench.json");
  const test::TrialStatistics s = test::RunTrials(o, 50, /*first_seed=*/1000);
  std::printf("%s", s.Report().c_str());
  EXPECT_EQ(s.failed, 0);
  EXPECT_GE(s.FractionWithinTwoSigma(), 0.9);
  // Each mode's reported σ within 30 % of its empirical scatter over the 50 trials (the scatter of a 50-sample
  // standard deviation is itself ~10 %).
  for (const auto& [j, g] : s.gain) EXPECT_NEAR(s.SigmaOverScatter(j), 1.0, 0.3) << "Z" << j;
}

}  // namespace
}  // namespace aosr
