#include "aosr/scene/objects.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <utility>

#include "aosr/core/slanted_edge.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

TEST(UsafTest, FrequenciesFollowTheChartFormula) {
  EXPECT_DOUBLE_EQ(UsafFrequency(0, 1), 1.0);
  EXPECT_DOUBLE_EQ(UsafFrequency(1, 1), 2.0);
  EXPECT_DOUBLE_EQ(UsafFrequency(-2, 1), 0.25);
  EXPECT_DOUBLE_EQ(UsafFrequency(2, 3), std::pow(2.0, 2.0 + 1.0 / 3.0));
  // Element 6 of group g is one sixth-octave below element 1 of group g + 1.
  EXPECT_NEAR(UsafFrequency(0, 6) * std::pow(2.0, 1.0 / 6.0), UsafFrequency(1, 1), 1e-15);
  EXPECT_DOUBLE_EQ(UsafBarWidthMm(0, 1), 0.5);
}

TEST(UsafTest, DefaultTargetSizeIsAsDocumented) {
  const UsafSize size = UsafTargetSize(UsafOptions{});
  EXPECT_NEAR(size.height_mm, 61.9, 0.05);
  EXPECT_NEAR(size.width_mm, 55.5, 1e-12);  // 24 + 6 + 12 + 3 + 6 + 1.5 + 3
}

TEST(UsafTest, BarGeometryMatchesTheFrequency) {
  UsafOptions opts;
  opts.pixels_per_mm = 7.3;
  const Shape shape{480, 440};
  const std::vector<UsafBar> bars = UsafBars(shape, opts);
  ASSERT_EQ(bars.size(), 4u * 6u * 6u);
  // Collect each element's bars by orientation.
  std::map<std::pair<int, int>, std::vector<UsafBar>> by_element;
  for (const UsafBar& b : bars) by_element[{b.group, b.element}].push_back(b);
  ASSERT_EQ(by_element.size(), 24u);
  for (const auto& [key, element_bars] : by_element) {
    const auto [g, e] = key;
    const double w = 1.0 / (2.0 * UsafFrequency(g, e)) * opts.pixels_per_mm;
    ASSERT_EQ(element_bars.size(), 6u);
    std::vector<PixelRect> vertical, horizontal;
    for (const UsafBar& b : element_bars) (b.horizontal ? horizontal : vertical).push_back(b.rect);
    ASSERT_EQ(vertical.size(), 3u);
    ASSERT_EQ(horizontal.size(), 3u);
    for (int k = 0; k < 3; ++k) {
      // Width w, length 5w.
      EXPECT_NEAR(vertical[k].width, w, 1e-12 * w) << g << "," << e;
      EXPECT_NEAR(vertical[k].height, 5 * w, 1e-12 * w);
      EXPECT_NEAR(horizontal[k].height, w, 1e-12 * w);
      EXPECT_NEAR(horizontal[k].width, 5 * w, 1e-12 * w);
      // Bar-to-bar gap equals the bar width: pitch 2w = one line pair = 1/f.
      if (k > 0) {
        EXPECT_NEAR(vertical[k].left - vertical[k - 1].right(), w, 1e-9 * w);
        EXPECT_NEAR(horizontal[k].top - horizontal[k - 1].bottom(), w, 1e-9 * w);
      }
      // Triplets are aligned: vertical bars share top and bottom, horizontal ones share left and right.
      EXPECT_NEAR(vertical[k].top, vertical[0].top, 1e-9);
      EXPECT_NEAR(horizontal[k].left, horizontal[0].left, 1e-9);
    }
    // Each triplet is a 5w square; the two sit side by side, 2w apart, tops aligned.
    EXPECT_NEAR(vertical[2].right() - vertical[0].left, 5 * w, 1e-9 * w);
    EXPECT_NEAR(horizontal[2].bottom() - horizontal[0].top, 5 * w, 1e-9 * w);
    EXPECT_NEAR(horizontal[0].left - vertical[2].right(), 2 * w, 1e-9 * w);
    EXPECT_NEAR(horizontal[0].top, vertical[0].top, 1e-9);
  }
}

TEST(UsafTest, ElementsDoNotOverlapAndAreCentredInTheField) {
  const Shape shape{500, 460};
  const UsafOptions opts;  // 8 px/mm: box 495 x 444 px
  const std::vector<UsafElement> elements = UsafElements(shape, opts);
  ASSERT_EQ(elements.size(), 24u);
  double top = 1e9, left = 1e9, bottom = -1e9, right = -1e9;
  for (size_t i = 0; i < elements.size(); ++i) {
    const PixelRect& a = elements[i].box;
    EXPECT_NEAR(elements[i].bar_width_px, 4.0 / elements[i].frequency_lp_per_mm, 1e-12);
    top = std::min(top, a.top);
    left = std::min(left, a.left);
    bottom = std::max(bottom, a.bottom());
    right = std::max(right, a.right());
    for (size_t j = i + 1; j < elements.size(); ++j) {
      const PixelRect& b = elements[j].box;
      const bool disjoint = a.right() <= b.left || b.right() <= a.left || a.bottom() <= b.top || b.bottom() <= a.top;
      EXPECT_TRUE(disjoint) << "elements " << i << " and " << j;
    }
  }
  const UsafSize size = UsafTargetSize(opts);
  EXPECT_NEAR(bottom - top, size.height_mm * 8.0, 1e-9);
  EXPECT_NEAR(right - left, size.width_mm * 8.0, 1e-9);
  EXPECT_NEAR(0.5 * (top + bottom), 0.5 * (shape.rows - 1), 1e-9);
  EXPECT_NEAR(0.5 * (left + right), 0.5 * (shape.cols - 1), 1e-9);
}

TEST(UsafTest, RenderedFluxEqualsTheBarArea) {
  UsafOptions opts;
  opts.pixels_per_mm = 3.7;  // an awkward scale: every bar edge cuts pixels
  opts.background = 0.2;
  opts.bar_value = 1.7;
  const Shape shape{240, 230};
  const Image img = UsafTarget(shape, opts);
  double area = 0.0;
  for (const UsafBar& b : UsafBars(shape, opts)) {
    // The whole target must be on the grid for this test to mean anything.
    ASSERT_GE(b.rect.top, -0.5);
    ASSERT_GE(b.rect.left, -0.5);
    ASSERT_LE(b.rect.bottom(), shape.rows - 0.5);
    ASSERT_LE(b.rect.right(), shape.cols - 0.5);
    area += b.rect.area();
  }
  const double rendered = (img - opts.background).sum() / (opts.bar_value - opts.background);
  EXPECT_NEAR(rendered, area, 1e-9 * area);
  // Anti-aliased, not binary: some pixels are partly covered; none is outside [background, bar_value].
  EXPECT_GE(img.minCoeff(), opts.background - 1e-12);
  EXPECT_LE(img.maxCoeff(), opts.bar_value + 1e-12);
  const Image fraction = (img - opts.background) / (opts.bar_value - opts.background);
  EXPECT_GT(((fraction > 0.01) && (fraction < 0.99)).count(), 100);
}

TEST(UsafTest, PixelAlignedBarsRenderBinary) {
  // At 2 px/mm group -2 element 1 has 4 px bars. A single group's column is 12 w = 24 mm = 48 px wide, so
  // on a 48-px-wide grid its left edge sits exactly on the pixel edge x = -0.5.
  UsafOptions opts;
  opts.first_group = -2;
  opts.last_group = -2;
  opts.pixels_per_mm = 2.0;
  const UsafSize size = UsafTargetSize(opts);  // one column: 24 mm wide
  const Shape shape{static_cast<Index>(std::ceil(size.height_mm * 2)) + 10, 48};
  const Image img = UsafTarget(shape, opts);
  const std::vector<UsafBar> bars = UsafBars(shape, opts);
  // Element 1's vertical bars then cover whole pixel columns: 4 px bar, 4 px gap, 4 px bar, ...
  ASSERT_NEAR(bars[0].rect.left, -0.5, 1e-12);
  const double top = bars[0].rect.top;
  const Index row = static_cast<Index>(std::ceil(top + 0.5)) + 1;  // a row fully inside element 1's bars
  for (Index x = 0; x < 20; ++x) {
    const double expected = (x / 4) % 2 == 0 ? 1.0 : 0.0;
    EXPECT_NEAR(img(row, x), expected, 1e-12) << "x = " << x;
  }
}

TEST(UsafTest, SupersamplingConvergesToExactCoverage) {
  UsafOptions opts;
  opts.pixels_per_mm = 2.9;
  const Shape shape{190, 170};
  const Image exact = UsafTarget(shape, opts);
  for (const int s : {4, 16}) {
    opts.supersample = s;
    const Image sampled = UsafTarget(shape, opts);
    EXPECT_LE((sampled - exact).abs().maxCoeff(), 2.0 / s) << "supersample " << s;
    EXPECT_GT((sampled - exact).abs().maxCoeff(), 0.0);  // the two methods really differ
  }
}

TEST(PointSourcesTest, FluxIsConservedAndCentroidIsExact) {
  const Shape shape{20, 25};
  const std::vector<PointSource> cases = {
      {3.25, 7.6, 1.0}, {10.0, 12.0, 2.5}, {0.0, 0.0, 0.3}, {19.0, 24.0, 1.1}, {18.9, 0.01, 4.0}, {5.5, 5.5, -0.7}};
  for (const PointSource& s : cases) {
    Image img = Image::Zero(shape.rows, shape.cols);
    AddPointSources(&img, {s});
    EXPECT_NEAR(img.sum(), s.flux, 1e-12 * std::abs(s.flux));
    double cy = 0.0, cx = 0.0;
    for (Index y = 0; y < shape.rows; ++y)
      for (Index x = 0; x < shape.cols; ++x) {
        cy += y * img(y, x);
        cx += x * img(y, x);
      }
    EXPECT_NEAR(cy / img.sum(), s.y, 1e-12) << s.y << "," << s.x;
    EXPECT_NEAR(cx / img.sum(), s.x, 1e-12) << s.y << "," << s.x;
    EXPECT_LE((img != 0.0).count(), 4);
  }
}

TEST(PointSourcesTest, AtAPixelCentreASourceIsOnePixel) {
  Image img = Image::Constant(8, 8, 0.5);
  AddPointSources(&img, {{3.0, 4.0, 2.0}, {6.0, 1.0, 1.0}});
  EXPECT_DOUBLE_EQ(img(3, 4), 2.5);
  EXPECT_DOUBLE_EQ(img(6, 1), 1.5);
  EXPECT_NEAR(img.sum(), 0.5 * 64 + 3.0, 1e-12);
  EXPECT_EQ((img != 0.5).count(), 2);
}

TEST(PointSourcesTest, SingleRowOrColumnGrids) {
  Image img = Image::Zero(1, 6);
  AddPointSources(&img, {{0.0, 2.25, 1.0}});
  EXPECT_NEAR(img(0, 2), 0.75, 1e-15);
  EXPECT_NEAR(img(0, 3), 0.25, 1e-15);
}

TEST(DemoObjectTest, DeterministicAndInRange) {
  for (const Shape shape : {Shape{64, 64}, Shape{128, 128}, Shape{256, 256}, Shape{200, 90}, Shape{64, 300},
                            Shape{512, 512}}) {
    const Image a = DemoObject(shape);
    const Image b = DemoObject(shape);
    ASSERT_EQ(ShapeOf(a), shape);
    EXPECT_TRUE((a == b).all()) << ToString(shape);
    EXPECT_GE(a.minCoeff(), 0.05 - 1e-12) << ToString(shape);
    EXPECT_LE(a.maxCoeff(), 1.0 + 1e-12) << ToString(shape);
    // Mostly background, with a good share of bar flux.
    const double bright = (a > 0.5).count() / static_cast<double>(a.size());
    EXPECT_GT(bright, 0.01) << ToString(shape);
    EXPECT_LT(bright, 0.5) << ToString(shape);
  }
}

TEST(DemoObjectTest, ContainsTheFivePointSources) {
  // The demo minus the bare target leaves exactly the sources' total flux 0.9 + 0.6 + 0.8 + 0.5 + 0.7.
  const Shape shape{256, 256};
  UsafOptions opts;
  opts.background = 0.05;
  const UsafSize size = UsafTargetSize(opts);
  opts.pixels_per_mm = 0.9 * std::min(shape.rows / size.height_mm, shape.cols / size.width_mm);
  const Image diff = DemoObject(shape) - UsafTarget(shape, opts);
  EXPECT_NEAR(diff.sum(), 3.5, 1e-12);
  EXPECT_GE(diff.minCoeff(), 0.0);
  EXPECT_LE((diff > 0.0).count(), 20);
  // They sit on the background: every pixel with source flux has target value 0.05.
  const Image target = UsafTarget(shape, opts);
  for (Index i = 0; i < diff.size(); ++i) {
    if (diff.data()[i] > 0.0) {
      EXPECT_EQ(target.data()[i], 0.05) << "pixel " << i;
    }
  }
}

TEST(DemoObjectTest, FinestBarsBoxHoldsGroupsZeroAndOneInsideTheField) {
  const Shape shape{256, 256};
  const UsafOptions opts = DemoUsafOptions(shape);
  EXPECT_NEAR(UsafTarget(shape, opts).sum() + 3.5, DemoObject(shape).sum(), 1e-8);  // the options DemoObject uses
  const PixelRect box = DemoFinestBars(shape);
  EXPECT_GT(box.top, 0.0);
  EXPECT_GT(box.left, 0.0);
  EXPECT_LT(box.bottom(), 256.0);
  EXPECT_LT(box.right(), 256.0);
  int inside = 0;
  for (const UsafElement& e : UsafElements(shape, opts)) {
    const bool in = e.box.top >= box.top && e.box.left >= box.left && e.box.bottom() <= box.bottom() + 1e-9 &&
                    e.box.right() <= box.right() + 1e-9;
    EXPECT_EQ(in, e.group >= 0) << "group " << e.group << " element " << e.element;
    inside += in;
  }
  EXPECT_EQ(inside, 12);
}

// ---- Slanted edge -------------------------------------------------------------------------------------------

// Exact area coverage: an axis-aligned edge at a pixel boundary renders 0/1, a quarter into a pixel 0.25.
TEST(SlantedEdgeTargetTest, AxisAlignedEdgesCoverExactly) {
  SlantedEdgeTargetOptions o;
  o.angle_deg = 0.0;
  o.centre_y = 4.0;
  o.centre_x = 10.25;  // pixel 10 covers [9.5, 10.5): a quarter of it lies right of the edge
  const Image img = SlantedEdgeTarget({8, 20}, o);
  for (Index y = 0; y < 8; ++y) {
    EXPECT_EQ(img(y, 9), 0.0);
    EXPECT_DOUBLE_EQ(img(y, 10), 0.25);
    EXPECT_EQ(img(y, 11), 1.0);
  }
  o.angle_deg = 90.0;  // horizontal: the high side is the top rows (normal (cos 90, -sin 90) = -y)
  o.centre_y = 3.5;
  const Image h = SlantedEdgeTarget({8, 20}, o);
  EXPECT_NEAR(h(3, 5), 1.0, 1e-12);
  EXPECT_NEAR(h(4, 5), 0.0, 1e-12);
}

// Against brute force: 400 x 400 point samples per pixel agree to their own error (< 1/400 per side).
TEST(SlantedEdgeTargetTest, CoverageMatchesDenseSupersampling) {
  SlantedEdgeTargetOptions o;
  o.angle_deg = 7.0;
  o.low = 0.2;
  o.high = 1.5;
  const Shape shape{12, 12};
  const Image img = SlantedEdgeTarget(shape, o);
  const double t = o.angle_deg * M_PI / 180.0, cy = 5.5, cx = 5.5;
  const int s = 400;
  double worst = 0.0;
  for (Index y = 3; y < 9; ++y)
    for (Index x = 3; x < 9; ++x) {
      int in = 0;
      for (int i = 0; i < s; ++i)
        for (int j = 0; j < s; ++j) {
          const double py = y - 0.5 + (i + 0.5) / s, px = x - 0.5 + (j + 0.5) / s;
          in += (px - cx) * std::cos(t) - (py - cy) * std::sin(t) > 0;
        }
      const double brute = o.low + (o.high - o.low) * double(in) / (double(s) * s);
      worst = std::max(worst, std::abs(img(y, x) - brute));
    }
  EXPECT_LT(worst, 1.3 * 2.0 / s);
}

// The rendered target is the pixel box's edge: its slanted-edge MTF is sinc(f cos θ) sinc(f sin θ) up to
// 1 cycle/px, twice the sampling's Nyquist (core/slanted_edge.hpp divides out the method's own transfer).
TEST(SlantedEdgeTargetTest, SlantedEdgeMtfIsThePixelBoxSinc) {
  for (double angle : {3.0, 5.0, -8.0}) {
    SlantedEdgeTargetOptions o;
    o.angle_deg = angle;
    const Image img = SlantedEdgeTarget({160, 64}, o);
    const SlantedEdgeMtf m = MeasureSlantedEdgeMtf(img);
    EXPECT_NEAR(m.angle_deg, angle, 0.02);
    const double t = angle * M_PI / 180.0;
    auto sinc = [](double x) { return x == 0 ? 1.0 : std::sin(M_PI * x) / (M_PI * x); };
    double worst = 0.0;
    for (std::size_t i = 0; i < m.frequency.size(); ++i) {
      const double f = m.frequency[i];
      worst = std::max(worst, std::abs(m.mtf[i] - sinc(f * std::cos(t)) * sinc(f * std::sin(t))));
    }
    EXPECT_LT(worst, 0.02) << angle << " deg";
  }
}

TEST(SlantedEdgeTargetTest, InvalidOptionsAreNamed) {
  SlantedEdgeTargetOptions o;
  o.angle_deg = 200;
  try {
    SlantedEdgeTarget({8, 8}, o);
    ADD_FAILURE() << "no exception";
  } catch (const std::exception& e) {
    EXPECT_NE(std::string(e.what()).find("angle_deg = 200"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace aosr
