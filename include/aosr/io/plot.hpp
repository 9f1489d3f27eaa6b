// Line plots for reports: one or more panels of (x, y) series, each a coloured polyline with a marker at
// every point, with axes, ticks, tick labels, axis labels, a title and a legend, rendered into an RgbImage
// (image_io.hpp) and written as PNG. Made for the accuracy-against-time pictures of `aosr tradeoff` and the
// reconstruction benchmark, and small enough to reuse for any "curve per method" figure.
//
// API rules for this header (stated once):
//  * A figure is a grid of panels (LinePlot), filled left to right then top to bottom in `columns` columns;
//    every panel has the same size in pixels (FigureOptions).
//  * Series i of every panel is drawn in colour SeriesColour(i) (a 10-colour qualitative palette, cycled),
//    so the same method keeps its colour across panels when callers keep the same series order. A series with
//    no drawable point keeps its colour slot but is left out of the legend.
//  * Points are joined in the order given (not sorted): for a knob sweep the line follows the knob.
//    A point whose x or y is not finite is skipped and breaks the line there (e.g. PSNR = +inf for a perfect
//    estimate, or a metric that does not exist for that row).
//  * Axes are linear or logarithmic (base 10). On a log axis every finite value must be > 0: InvalidArgument
//    names the panel, the series, the point and the value otherwise (plot log10 of it yourself, or drop it).
//  * Ranges are the finite data's, widened by 5 % of the span on each side (log axes: of the decades), unless
//    PlotAxis::min / max fix them; points outside a fixed range are clipped at the plot area's edge. A
//    constant range is widened to a unit span (log: one decade) around the value, an empty one is [0, 1]
//    (log: [1, 10]).
//  * Ticks: linear axes at 1, 2 or 5 x 10^k steps (4-8 ticks); log axes at decades (every k-th decade when
//    there are many), with 2 and 5 added when fewer than three decades show, and plain 1-2-5 steps when the
//    range lies within less than one decade. Labels are printf %g with 3 significant digits (exponents
//    shortened: 1e+06 -> 1e6).
//  * Text is drawn with OpenCV's Hershey font, which has ASCII glyphs only: a few common UTF-8 symbols are
//    spelled out (λ lambda, μ mu, σ sigma, × x, ² ^2, ³ ^3, — and – -, ≈ ~, ≤ <=, ≥ >=) and any other
//    non-ASCII character becomes '?'.
//  * Deterministic: the same input gives the same pixels.
#pragma once

#include <array>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include "aosr/io/image_io.hpp"

namespace aosr {

struct PlotSeries {
  std::string label;      // legend entry; empty: the series is drawn but not listed
  std::vector<double> x;  // abscissae, same length as y
  std::vector<double> y;  // ordinates
  // Optional text beside each point (e.g. the knob's value): empty, or one entry per point ("" for none).
  std::vector<std::string> point_labels = {};  // (the initializer keeps {label, x, y} aggregates warning-free)
};

struct PlotAxis {
  std::string label;  // axis label, e.g. "wall time [s]"; drawn along the axis (rotated for y)
  bool log = false;   // base-10 logarithmic axis; every finite value must then be > 0
  // Fixed range ends in data units; NaN (the default): from the data (see the top of the file). When both are
  // given, min < max (and both > 0 on a log axis).
  double min = std::numeric_limits<double>::quiet_NaN();
  double max = std::numeric_limits<double>::quiet_NaN();
};

struct LinePlot {
  std::string title;  // above the plot area; may be empty
  PlotAxis x;
  PlotAxis y;
  std::vector<PlotSeries> series;

  // False, and the offending field in *why when why != nullptr, if a series' x and y differ in length, a log
  // axis holds a finite value <= 0, or a fixed range is inverted or not positive on a log axis.
  bool IsValid(std::string* why) const;
};

struct FigureOptions {
  // Size of one panel in pixels: [240, 4000] x [180, 4000]. 720 x 460 fits a title, a legend of about ten
  // entries of up to 24 characters and readable tick labels.
  int panel_width = 720;
  int panel_height = 460;
  // Panels per row, >= 1 (fewer if there are fewer panels).
  int columns = 2;

  bool IsValid(std::string* why) const;
};

// The colour of series i as R, G, B (the "tab10" palette of matplotlib, cycled).
std::array<std::uint8_t, 3> SeriesColour(int i);

// Renders the panels on a white background. InvalidArgument (naming the panel and field) for no panel, an
// invalid panel or invalid options.
RgbImage RenderFigure(const std::vector<LinePlot>& panels, const FigureOptions& options = {});

// RenderFigure, then WriteRgbImage(path, ...): an 8-bit RGB PNG (or TIFF by extension), written atomically.
void WriteFigure(const std::string& path, const std::vector<LinePlot>& panels,
                 const FigureOptions& options = {});

// ---- Labelled image panels (pictures rather than curves) ---------------------------------------------------
// A grid of grey-scale images, each magnified by an integer factor (nearest neighbour, so every pixel stays a
// visible square), with a title and subtitle lines above it and optional outlined boxes on it: the figure of
// `aosr demo` (truth, an input frame, each reconstruction with its name and score, zoomed insets).
// Cells are filled left to right then top to bottom in `columns` columns; every cell is as wide as the widest
// magnified image and as tall as the tallest, plus the title band; an image sits centred at the top of its
// cell's image area, on the background.

struct PanelBox {
  // In the panel image's pixels (before magnification): rows [top, top + height), cols [left, left + width).
  Index top = 0, left = 0, height = 0, width = 0;
};

struct ImagePanel {
  Image image;             // display values in [0, 1] (0 black, 1 white; NaN black), row 0 at the top, non-empty
  std::string title;       // first text line (bold), e.g. the method; may be empty
  std::string subtitle;    // text below the title, e.g. "PSNR 30.4 dB"; '\n' starts another line; may be empty
  int zoom = 1;            // integer magnification, 1..64
  std::vector<PanelBox> boxes;  // outlined in the figure's box colour (orange), e.g. where an inset comes from
};

struct PanelFigureOptions {
  int columns = 4;         // >= 1 (fewer if there are fewer panels)
  int gap_px = 8;          // white space between cells and around the figure, 0..200
  double text_scale = 0.5; // Hershey font scale of the titles, (0, 4]; subtitles and caption are drawn at 0.9x
  std::string caption;     // text above the whole figure, left-aligned; '\n' starts another line; may be empty
  bool IsValid(std::string* why) const;
};

// InvalidArgument (naming the panel and field) for no panel, an empty image, a zoom out of range, a box
// outside its image, or invalid options.
RgbImage RenderImagePanels(const std::vector<ImagePanel>& panels, const PanelFigureOptions& options = {});

}  // namespace aosr
