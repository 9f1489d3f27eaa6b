// The picture of bench/results/design_regimes.md: the gain of the best design over the classic raster against
// the HR pixel in lambda/D (camera pixel / r), from bench/design_regimes.py's build/regimes/results.json.
// Left: objective A's expected gain (the better of tip/tilt and 20-mode Zernike) per (r, N). Right: held-out PSNR
// gains (mean of USAF and the demo truth) of Tikhonov and TV with the best design per (r, N), and at r = 2 with
// the raster moved by half an HR pixel (no optimisation), also with the sky rendered 4x finer than the HR grid
// (sky_oversampling). A gain appears only right of the HR grid's Nyquist limit, 0.5 lambda/D.
//
// Legend: Tik/TV = Tikhonov/TV; design = the best design, shift = the raster moved by half an HR pixel; sky 4x =
// sky_oversampling 4.
//
// Usage: build/bench/design_regimes_plot build/regimes/results.json bench/results/design_regimes.png
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "aosr/io/plot.hpp"

namespace {

struct Cell {
  std::string band;
  double pixel = 0, hr = 0;
  int r = 0, n = 0;
};

Cell Parse(const std::string& key) {  // "J-p1.76-r2-N4"
  Cell c;
  char band[8] = {0};
  std::sscanf(key.c_str(), "%7[^-]-p%lf-r%d-N%d", band, &c.pixel, &c.r, &c.n);
  c.band = band;
  c.hr = c.pixel / c.r;
  return c;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 3) {
    std::fprintf(stderr, "usage: %s results.json out.png\n", argv[0]);
    return 2;
  }
  const nlohmann::json j = nlohmann::json::parse(std::ifstream(argv[1]));
  std::map<std::string, aosr::PlotSeries> a, held;
  for (const auto& row : j["rows"]) {
    const Cell c = Parse(row["cell"].get<std::string>());
    double best = -1e9;
    for (const auto& [param, g] : row["gain"].items()) best = std::max(best, g["db"].get<double>());
    const std::string rn = "r = " + std::to_string(c.r) + ", N = " + std::to_string(c.n);
    a[rn].label = rn;
    a[rn].x.push_back(c.hr);
    a[rn].y.push_back(best);
    for (const std::string label : {"design", "shifted"})
      for (const std::string m : {"tikhonov", "tv"}) {
        double d = 0;
        for (const std::string o : {"usaf", "demo"})
          d += 0.5 * (row["held"][label + "/" + o][m].get<double>() - row["held"]["raster/" + o][m].get<double>());
        if (label == "shifted" && c.r != 2) continue;  // the registration shift is drawn at r = 2 only
        const std::string key = (m == "tv" ? "TV " : "Tik ") + std::string(label == "design" ? "design " : "shift ") +
                                "r" + std::to_string(c.r) + " N" + std::to_string(c.n);
        held[key].label = key;
        held[key].x.push_back(c.hr);
        held[key].y.push_back(d);
      }
  }
  // The fine-sky check (sky_oversampling 4): the raster moved by half an HR pixel, every cell it ran in.
  if (j.contains("fine"))
    for (const auto& row : j["fine"]) {
      if (row["s"].get<int>() != 4) continue;
      const Cell c = Parse(row["cell"].get<std::string>());
      for (const std::string m : {"tikhonov", "tv"}) {
        double d = 0;
        for (const std::string o : {"usaf", "demo"})
          d += 0.5 * (row["held"]["shifted/" + o][m].get<double>() - row["held"]["raster/" + o][m].get<double>());
        const std::string key = (m == "tv" ? "TV " : "Tik ") + std::string("shift, sky 4x, N") + std::to_string(c.n);
        held[key].label = key;
        held[key].x.push_back(c.hr);
        held[key].y.push_back(d);
      }
    }
  aosr::LinePlot left, right;
  left.title = "objective A: expected gain over the raster";
  left.x.label = "HR pixel [lambda/D] (Nyquist 0.5)";
  left.y.label = "gain [dB]";
  // Points are joined in the order given: sort each series by x.
  auto sorted = [](aosr::PlotSeries s) {
    std::vector<std::pair<double, double>> p;
    for (std::size_t i = 0; i < s.x.size(); ++i) p.push_back({s.x[i], s.y[i]});
    std::sort(p.begin(), p.end());
    for (std::size_t i = 0; i < p.size(); ++i) s.x[i] = p[i].first, s.y[i] = p[i].second;
    return s;
  };
  for (const auto& [k, s] : a) left.series.push_back(sorted(s));
  right.title = "held-out PSNR gain (mean of USAF and demo)";
  right.x.label = left.x.label;
  right.y.label = "PSNR - raster's [dB]";
  for (const auto& [k, s] : held) right.series.push_back(sorted(s));
  aosr::PlotSeries nyq{"Nyquist (HR pixel 0.5 lambda/D)", {0.5, 0.5}, {-1.0, 3.5}};
  left.series.push_back(nyq);
  right.series.push_back(nyq);
  aosr::WriteFigure(argv[2], {left, right});
  std::printf("wrote %s\n", argv[2]);
  return 0;
}
