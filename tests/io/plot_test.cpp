#include "aosr/io/plot.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <string>

#include "aosr/core/error.hpp"
#include "temp_dir.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

using ::testing::HasSubstr;
using testing_io::TempDir;

std::string ErrorOf(const std::function<void()>& f) {
  try {
    f();
  } catch (const InvalidArgument& e) {
    return e.what();
  } catch (const std::exception& e) {
    return std::string("wrong exception type: ") + e.what();
  }
  return "no exception";
}

// Two series on a log-x axis: what `aosr tradeoff` draws.
LinePlot TwoCurves() {
  LinePlot p;
  p.title = "PSNR against wall time";
  p.x.label = "wall time [s]";
  p.x.log = true;
  p.y.label = "PSNR [dB]";
  p.series.push_back({"tikhonov", {0.01, 0.02, 0.05}, {20.0, 22.0, 21.0}});
  p.series.push_back({"tv", {0.1, 0.3, 1.0, 3.0}, {21.0, 23.0, 24.0, 24.5}});
  return p;
}

// Number of pixels of `img` within a box that have colour c (each channel within tol).
int CountColour(const RgbImage& img, std::array<std::uint8_t, 3> c, int tol, Index y0, Index x0, Index y1,
                Index x1) {
  int n = 0;
  for (Index y = y0; y < y1; ++y)
    for (Index x = x0; x < x1; ++x) {
      const std::uint8_t* p = &img.rgb[size_t(3 * (y * img.cols + x))];
      if (std::abs(p[0] - c[0]) <= tol && std::abs(p[1] - c[1]) <= tol && std::abs(p[2] - c[2]) <= tol) ++n;
    }
  return n;
}

TEST(PlotTest, PngDecodesWithThePanelGridSize) {
  TempDir dir;
  FigureOptions o;
  o.panel_width = 500;
  o.panel_height = 300;
  o.columns = 2;
  WriteFigure(dir.File("fig.png"), {TwoCurves(), TwoCurves(), TwoCurves()}, o);
  const RgbImage img = ReadRgbImage(dir.File("fig.png"));
  EXPECT_EQ(img.cols, 1000);                                   // 2 columns
  EXPECT_EQ(img.rows, 600);                                    // 3 panels -> 2 rows
  EXPECT_EQ(dir.List(), std::vector<std::string>{"fig.png"});  // no temporary left behind
}

TEST(PlotTest, CurvesAreDrawnInTheirColoursInsideThePlotArea) {
  FigureOptions o;
  o.columns = 1;
  const RgbImage img = RenderFigure({TwoCurves()}, o);
  ASSERT_EQ(img.rows, o.panel_height);
  ASSERT_EQ(img.cols, o.panel_width);
  // The plot area lies roughly in the middle of the panel; the legend is on the right.
  const Index y0 = img.rows / 6, y1 = img.rows * 5 / 6, x0 = img.cols / 8, x1 = img.cols * 3 / 5;
  EXPECT_GT(CountColour(img, SeriesColour(0), 10, y0, x0, y1, x1), 50);
  EXPECT_GT(CountColour(img, SeriesColour(1), 10, y0, x0, y1, x1), 50);
  // Background is white, and most of the panel is background.
  EXPECT_GT(CountColour(img, {255, 255, 255}, 0, 0, 0, img.rows, img.cols), int(img.rows * img.cols / 2));
  // Text (tick labels, axis labels, title) is dark: some near-black pixels outside the plot area.
  EXPECT_GT(CountColour(img, {0, 0, 0}, 60, 0, 0, img.rows / 10, img.cols), 20);  // the title band
}

TEST(PlotTest, ALegendEntryPerDrawableLabelledSeries) {
  FigureOptions o;
  o.columns = 1;
  LinePlot p = TwoCurves();
  const RgbImage with = RenderFigure({p}, o);
  // Series 2 has no finite point: it keeps its colour slot but is neither drawn nor listed.
  p.series.push_back({"nothing", {1.0}, {std::numeric_limits<double>::quiet_NaN()}});
  const RgbImage same = RenderFigure({p}, o);
  EXPECT_EQ(with.rgb, same.rgb);
  EXPECT_EQ(CountColour(same, SeriesColour(2), 10, 0, 0, same.rows, same.cols), 0);
}

TEST(PlotTest, NonFinitePointsBreakTheLineButOthersAreDrawn) {
  LinePlot p = TwoCurves();
  p.series[0].y[1] = std::numeric_limits<double>::infinity();  // e.g. PSNR of a perfect estimate
  const RgbImage img = RenderFigure({p});
  EXPECT_GT(CountColour(img, SeriesColour(0), 10, 0, 0, img.rows, img.cols), 20);
}

TEST(PlotTest, RenderingIsDeterministic) {
  EXPECT_EQ(RenderFigure({TwoCurves()}).rgb, RenderFigure({TwoCurves()}).rgb);
}

TEST(PlotTest, LinearAxesAndEmptyOrConstantDataStillRender) {
  LinePlot p;
  p.x.label = "x";
  p.y.label = "y";
  EXPECT_NO_THROW(RenderFigure({p}));  // no series at all
  p.series.push_back({"one point", {2.0}, {3.0}});
  EXPECT_NO_THROW(RenderFigure({p}));
  p.series.push_back({"negative", {-5.0, 0.0, 5.0}, {-1e6, 0.0, 1e6}});
  EXPECT_NO_THROW(RenderFigure({p}));
  p.y.log = true;
  p.series = {{"constant", {1.0, 2.0}, {7.0, 7.0}}};
  EXPECT_NO_THROW(RenderFigure({p}));
}

TEST(PlotTest, FixedRangesClipPointsOutsideThem) {
  LinePlot p = TwoCurves();
  p.x.min = 0.015;
  p.x.max = 0.5;
  p.y.min = 20.5;
  p.y.max = 23.5;
  EXPECT_NO_THROW(RenderFigure({p}));
}

TEST(PlotTest, LogAxisRejectsNonPositiveValuesByName) {
  LinePlot p = TwoCurves();
  p.series[1].x[2] = 0.0;
  std::string why;
  EXPECT_FALSE(p.IsValid(&why));
  EXPECT_THAT(why, HasSubstr("series[1] ('tv').x[2] = 0"));
  EXPECT_THAT(why, HasSubstr("log x axis needs x > 0"));
  EXPECT_THAT(ErrorOf([&] { RenderFigure({p}); }),
              HasSubstr("RenderFigure: panel 0 ('PSNR against wall time')"));

  LinePlot q = TwoCurves();
  q.y.log = true;
  q.series[0].y[0] = -3.0;
  EXPECT_THAT(ErrorOf([&] { RenderFigure({q}); }), HasSubstr("log y axis needs y > 0"));
  // A NaN is not a value: it is skipped, not refused.
  q.series[0].y[0] = std::numeric_limits<double>::quiet_NaN();
  EXPECT_NO_THROW(RenderFigure({q}));
}

TEST(PlotTest, BadInputGetsAClearError) {
  LinePlot p = TwoCurves();
  p.series[0].y.pop_back();
  EXPECT_THAT(ErrorOf([&] { RenderFigure({p}); }), HasSubstr("x has 3 points, y 2"));
  EXPECT_THAT(ErrorOf([&] { RenderFigure({}); }), HasSubstr("panels"));
  FigureOptions o;
  o.panel_width = 10;
  EXPECT_THAT(ErrorOf([&] { RenderFigure({TwoCurves()}, o); }), HasSubstr("panel_width = 10"));
  o = {};
  o.columns = 0;
  EXPECT_THAT(ErrorOf([&] { RenderFigure({TwoCurves()}, o); }), HasSubstr("columns = 0"));
  LinePlot r = TwoCurves();
  r.y.min = 5;
  r.y.max = 1;
  EXPECT_THAT(ErrorOf([&] { RenderFigure({r}); }), HasSubstr("need min < max"));
  LinePlot l = TwoCurves();
  l.x.min = -1;
  EXPECT_THAT(ErrorOf([&] { RenderFigure({l}); }), HasSubstr("log axis needs a positive fixed range"));
  TempDir dir;
  EXPECT_THAT(ErrorOf([&] { WriteFigure(dir.File("fig.jpg"), {TwoCurves()}); }), HasSubstr("'.jpg'"));
}

TEST(RgbImageTest, RoundTripsThroughPngAndRefusesBadShapes) {
  TempDir dir;
  RgbImage img;
  img.rows = 2;
  img.cols = 3;
  for (int i = 0; i < 18; ++i) img.rgb.push_back(std::uint8_t(i * 13));
  WriteRgbImage(dir.File("a.png"), img);
  const RgbImage back = ReadRgbImage(dir.File("a.png"));
  EXPECT_EQ(back.rows, 2);
  EXPECT_EQ(back.cols, 3);
  EXPECT_EQ(back.rgb, img.rgb);
  img.rgb.pop_back();
  EXPECT_THAT(ErrorOf([&] { WriteRgbImage(dir.File("b.png"), img); }), HasSubstr("rgb.size()"));
  EXPECT_FALSE(std::filesystem::exists(dir.File("b.png")));
}

// Labelled image panels (the `aosr demo` montage): cell geometry, nearest-neighbour zoom, boxes, errors.
TEST(ImagePanelsTest, ZoomedPixelsAreSquaresOfTheirGreyAndBoxesAreOrange) {
  ImagePanel a;
  a.image = Image::Zero(8, 8);
  a.image(2, 3) = 1.0;  // one white pixel
  a.title = "truth";
  a.subtitle = "PSNR 30.0 dB\n1.0 s";
  a.zoom = 4;
  a.boxes = {{4, 4, 3, 3}};
  ImagePanel b;
  b.image = Image::Constant(16, 16, 0.5);
  b.title = "method";
  PanelFigureOptions o;
  o.columns = 2;
  o.gap_px = 10;
  const RgbImage img = RenderImagePanels({a, b}, o);
  // Two cells of 32 px (the widest magnified image), three gaps.
  EXPECT_EQ(img.cols, 2 * 32 + 3 * 10);
  // Find the zoomed white pixel: a 4 x 4 white square in the left cell, whose image starts at x = 10.
  int white = CountColour(img, {255, 255, 255}, 0, 0, 10, img.rows, 42);
  int black = CountColour(img, {0, 0, 0}, 0, 0, 10, img.rows, 42);
  EXPECT_GE(black, 8 * 8 * 16 - 16 - 3 * 3 * 16) << "the dark image, zoomed";
  EXPECT_GT(white, 16) << "background and the white pixel";
  // The grey panel: 16 x 16 pixels of 128 zoomed by 1, centred in its 32 px cell.
  const int grey = CountColour(img, {128, 128, 128}, 0, 0, 52, img.rows, 84);
  EXPECT_GE(grey, 16 * 16);
  EXPECT_LE(grey, 16 * 16 + 20) << "plus a few anti-aliased title pixels";
  // The box outline in orange.
  EXPECT_GT(CountColour(img, {255, 127, 14}, 0, 0, 10, img.rows, 42), 3 * 4 * 4);
  EXPECT_EQ(RenderImagePanels({a, b}, o).rgb, img.rgb);  // deterministic
  // A caption adds a band on top.
  o.caption = "line one\nline two";
  EXPECT_GT(RenderImagePanels({a, b}, o).rows, img.rows);
}

TEST(ImagePanelsTest, BadInputGetsAClearError) {
  ImagePanel p;
  EXPECT_THAT(ErrorOf([&] { RenderImagePanels({p}); }), HasSubstr("panels[0].image"));
  p.image = Image::Zero(4, 4);
  p.zoom = 0;
  EXPECT_THAT(ErrorOf([&] { RenderImagePanels({p}); }), HasSubstr("panels[0].zoom"));
  p.zoom = 1;
  p.boxes = {{2, 2, 3, 1}};
  EXPECT_THAT(ErrorOf([&] { RenderImagePanels({p}); }), HasSubstr("panels[0].boxes"));
  p.boxes.clear();
  EXPECT_THAT(ErrorOf([&] { RenderImagePanels({}); }), HasSubstr("panels"));
  PanelFigureOptions o;
  o.columns = 0;
  EXPECT_THAT(ErrorOf([&] { RenderImagePanels({p}, o); }), HasSubstr("columns = 0"));
}

}  // namespace
}  // namespace aosr
