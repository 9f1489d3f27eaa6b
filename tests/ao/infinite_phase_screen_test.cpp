// infinite_phase_screen.hpp: extrusion mechanics (the window slides by whole rows, old rows are kept as they
// were, a seed fixes everything).
#include "aosr/ao/infinite_phase_screen.hpp"

#include <gtest/gtest.h>

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

}  // namespace
}  // namespace aosr
