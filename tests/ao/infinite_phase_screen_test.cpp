// infinite_phase_screen.hpp: extrusion mechanics (the window slides by whole rows, old rows are kept as they
// were, a seed fixes everything).
#include "aosr/ao/infinite_phase_screen.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <thread>

namespace aosr {
namespace AOSR_TEST_NS {

InfinitePhaseScreenOptions Small() {
  InfinitePhaseScreenOptions o;
  o.width = 24;
  o.length = 20;
  o.pixel_scale_m = 0.05;
  o.r0_m = 0.1;
  o.L0_m = 10.0;
  return o;
}

TEST(InfinitePhaseScreenTest, WindowSlidesAndKeepsOldRows) {
  InfinitePhaseScreen s(Small(), 5);
  EXPECT_EQ(s.rows_extruded(), 0);
  const Image before = s.Window();
  ASSERT_EQ(before.rows(), 20);
  ASSERT_EQ(before.cols(), 24);
  s.Extrude(0);
  EXPECT_TRUE((Image(s.Window()) == before).all());
  // Extrude across several buffer compactions (capacity is 2 x length).
  for (int step = 0; step < 7; ++step) {
    const Image old = s.Window();
    s.Extrude(3 + step);
    const Index k = 3 + step;
    const Image now = s.Window();
    EXPECT_TRUE((now.topRows(20 - k) == old.bottomRows(20 - k)).all()) << "step " << step;
    EXPECT_TRUE(now.isFinite().all());
    EXPECT_GT((now.bottomRows(k) - now.row(19 - k).replicate(k, 1)).abs().maxCoeff(), 0.0);
    for (Index r = 0; r < 20; ++r) {
      EXPECT_EQ(s.Row(r)[5], now(r, 5));
    }
  }
  EXPECT_EQ(s.rows_extruded(), 3 + 4 + 5 + 6 + 7 + 8 + 9);
  EXPECT_GT(s.stencil_size(), 2 * 24);
}

TEST(InfinitePhaseScreenTest, SeedDeterminesTheWholeRun) {
  InfinitePhaseScreen a(Small(), 11), b(Small(), 11), c(Small(), 12);
  a.Extrude(57);
  b.Extrude(30);
  b.Extrude(27);
  c.Extrude(57);
  EXPECT_TRUE((Image(a.Window()) == Image(b.Window())).all());
  EXPECT_GT((Image(a.Window()) - Image(c.Window())).abs().maxCoeff(), 0.01);
}

// Screens with the same options share one stencil (A, B) per process; each keeps its own window and noise.
TEST(InfinitePhaseScreenTest, SharedStencilLeavesEachScreenItsOwnState) {
  InfinitePhaseScreen a(Small(), 11), b(Small(), 11);
  const Image b_before = b.Window();
  a.Extrude(41);
  EXPECT_TRUE((Image(b.Window()) == b_before).all());  // extruding a does not move b
  b.Extrude(41);
  EXPECT_TRUE((Image(a.Window()) == Image(b.Window())).all());
  EXPECT_EQ(a.stencil_size(), b.stencil_size());
}

// The stencil is looked up by every option: a screen with twice r0 and the same seed is the first one times
// 2^(-5/6) (the phase's r0^(-5/6) scaling; A does not depend on r0, B scales so), which a stencil of the other
// r0 would break on every extruded row. Another L0 changes the screen.
TEST(InfinitePhaseScreenTest, StencilOfAnotherR0OrL0IsNeverReused) {
  InfinitePhaseScreenOptions twice = Small();
  twice.r0_m = 2.0 * Small().r0_m;
  InfinitePhaseScreenOptions outer = Small();
  outer.L0_m = 2.0 * Small().L0_m;
  InfinitePhaseScreen a(Small(), 3), b(twice, 3), c(outer, 3);
  a.Extrude(30);
  b.Extrude(30);
  c.Extrude(30);
  const Image expected = std::pow(2.0, -5.0 / 6.0) * Image(a.Window());
  EXPECT_LT((Image(b.Window()) - expected).abs().maxCoeff(), 1e-9 * expected.abs().maxCoeff());
  EXPECT_GT((Image(c.Window()) - Image(a.Window())).abs().maxCoeff(), 1e-3 * expected.abs().maxCoeff());
}

// Two threads building a screen of new options at once (both may compute the stencil) give the serial bytes.
TEST(InfinitePhaseScreenTest, ScreensBuiltOnTwoThreadsAtOnceGiveTheSerialBytes) {
  InfinitePhaseScreenOptions o = Small();
  o.width = 27;  // options no other test builds, so the stencil is not cached yet
  o.r0_m = 0.137;
  Image parallel[2];
  std::thread t0([&] {
    InfinitePhaseScreen s(o, 21);
    s.Extrude(25);
    parallel[0] = s.Window();
  });
  std::thread t1([&] {
    InfinitePhaseScreen s(o, 21);
    s.Extrude(25);
    parallel[1] = s.Window();
  });
  t0.join();
  t1.join();
  InfinitePhaseScreen serial(o, 21);
  serial.Extrude(25);
  EXPECT_TRUE((parallel[0] == Image(serial.Window())).all());
  EXPECT_TRUE((parallel[1] == Image(serial.Window())).all());
}

}  // namespace
}  // namespace aosr
