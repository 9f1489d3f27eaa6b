// Unit tests of closed_loop.hpp: the long-exposure PSF is exactly the average of PsfCalculator PSFs of the
// frames' residuals (every frame and every k-th), frame timing, and the loop delay in frames.
#include "aosr/ao/closed_loop.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "aosr/optics/psf.hpp"
#include "aosr/optics/zernike.hpp"
#include "loop_fixture.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

using test::KBandScience;
using test::kPaperDiameter;
using test::MakePaperSystem;
using test::SensorKind;

TEST(ClosedLoopTest, LongExposurePsfIsTheAverageOfPsfCalculatorPsfs) {
  ControllerOptions control;
  const Index n = 64;
  ClosedLoopOptions options = KBandScience();
  options.science = {2.2e-6, 0.7 * 2.2e-6 / kPaperDiameter, 40, 36};  // any pitch, any window
  options.science_static_opd_m = 50e-9 * Zernike(7, n);
  for (int every : {1, 3}) {
    options.psf_every_steps = every;
    // Two identical systems: one runs the loop, the other replays the same frames for the reference.
    test::LoopSystem a = MakePaperSystem(SensorKind::kGeometric, true, 5, control, n);
    test::LoopSystem b = MakePaperSystem(SensorKind::kGeometric, true, 5, control, n);
    ClosedLoop loop_a(a.amplitude, kPaperDiameter, a.atmosphere.get(), a.dm, a.wfs.get(), a.controller.get(),
                      options);
    ClosedLoop loop_b(b.amplitude, kPaperDiameter, b.atmosphere.get(), b.dm, b.wfs.get(), b.controller.get(),
                      options);
    const int frames = 10;
    const ClosedLoopResult r = loop_a.Run(frames / 800.0, 4 / 800.0);
    ASSERT_EQ(r.steps, frames);
    EXPECT_EQ(r.settling_steps, 4);
    EXPECT_EQ(r.psf_frames, (frames + every - 1) / every);
    PsfCalculator calc(n, kPaperDiameter, options.science);
    Image expected = Image::Zero(40, 36);
    double strehl_sum = 0.0;
    for (int i = 0; i < 4; ++i) loop_b.Step(false);
    for (int i = 0; i < frames; ++i) {
      loop_b.Step(false);
      const Image science = loop_b.residual_opd_m() + options.science_static_opd_m;
      const double s = StrehlFromPupil(b.amplitude, science, 2.2e-6);
      EXPECT_NEAR(r.strehl[i], s, 1e-12) << "frame " << i;
      if (i % every != 0) continue;
      expected += calc.Compute(b.amplitude, science);
      strehl_sum += s;
    }
    expected /= r.psf_frames;
    EXPECT_LT((r.psf - expected).abs().maxCoeff(), 1e-10 * expected.maxCoeff()) << "every " << every;
    EXPECT_NEAR(r.psf_strehl, strehl_sum / r.psf_frames, 1e-12);
    EXPECT_GT(r.long_exposure_strehl, 0.0);
    EXPECT_EQ(r.residual_rms_m.size(), static_cast<std::size_t>(frames));
  }
}

TEST(ClosedLoopTest, FramesAndTime) {
  ControllerOptions control;
  test::LoopSystem s = MakePaperSystem(SensorKind::kGeometric, false, 1, control, 32);
  ClosedLoopOptions options = KBandScience();
  options.compute_psf = false;
  options.start_time_s = 0.5;
  ClosedLoop loop(s.amplitude, kPaperDiameter, nullptr, s.dm, s.wfs.get(), s.controller.get(), options);
  EXPECT_DOUBLE_EQ(loop.time_s(), 0.5 + 0.5 / 800.0);
  const ClosedLoopResult r = loop.Run(0.01, 0.005);  // 8 recorded frames after 4
  EXPECT_EQ(r.steps, 8);
  EXPECT_EQ(r.settling_steps, 4);
  EXPECT_EQ(loop.frame(), 12);
  EXPECT_DOUBLE_EQ(r.start_time_s, 0.5 + 4.5 / 800.0);
  EXPECT_EQ(r.psf.size(), 0);
  EXPECT_EQ(r.psf_frames, 0);
  // No turbulence, no aberration: a perfect loop.
  EXPECT_NEAR(r.long_exposure_strehl, 1.0, 1e-12);
  EXPECT_EQ(loop.stage_times().frames, 12);
  EXPECT_GE(loop.stage_times().Total(), 0.0);
  EXPECT_NE(r.BriefReport().find("8 frames (+4 settling) at 800 Hz"), std::string::npos) << r.BriefReport();
}

TEST(ClosedLoopTest, TheLoopDelayIsExactlyKFrames) {
  // A static aberration, no turbulence: the residual of frames 0 .. k is the aberration itself (the mirror is
  // flat until the first command arrives) and frame k + 1 is the first one corrected.
  const Index n = 64;
  for (int k : {0, 1, 3}) {
    ControllerOptions control;
    control.gain = 0.3;
    control.delay_frames = k;
    test::LoopSystem s = MakePaperSystem(SensorKind::kGeometric, false, 1, control, n);
    ClosedLoopOptions options = KBandScience();
    options.compute_psf = false;
    options.common_static_opd_m = 100e-9 * ZernikeUnmasked(5, n) + 60e-9 * ZernikeUnmasked(8, n);
    ClosedLoop loop(s.amplitude, kPaperDiameter, nullptr, s.dm, s.wfs.get(), s.controller.get(), options);
    const ClosedLoopResult r = loop.Run((k + 3) / 800.0);
    for (int f = 1; f <= k; ++f)
      EXPECT_EQ(r.residual_rms_m[f], r.residual_rms_m[0]) << "k = " << k << ", frame " << f;
    EXPECT_LT(r.residual_rms_m[k + 1], 0.9 * r.residual_rms_m[0]) << "k = " << k;
  }
}

}  // namespace
}  // namespace aosr
