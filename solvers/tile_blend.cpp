#include "tile_blend.hpp"

#include <algorithm>
#include <cmath>

#include "aosr/core/image.hpp"

namespace aosr {
namespace tiling_internal {

std::vector<double> AxisWeight(Index start, Index rows, Index core0, Index core1, int r, int overlap, int tiles) {
  std::vector<double> w(rows * r, 0.0);
  if (tiles == 1) {
    std::fill(w.begin(), w.end(), 1.0);
    return w;
  }
  const double h = 0.5 * double(overlap) * r;
  const double lo = double(core0 * r), hi = double(core1 * r);
  for (Index j = 0; j < rows * r; ++j) {
    const double x = double(start * r + j) + 0.5;  // pixel centre, HR px
    double v;
    if (h == 0) {
      v = (x >= lo && x < hi) ? 1.0 : 0.0;
    } else if (x <= lo - h || x >= hi + h) {
      v = 0.0;
    } else if (x < lo + h) {
      const double t = (x - (lo - h)) / (2 * h);
      v = 1.0 - 0.5 * (1.0 + std::cos(kPi * t));  // rising: the complement of the left neighbour's fall
    } else if (x > hi - h) {
      const double t = (x - (hi - h)) / (2 * h);
      v = 0.5 * (1.0 + std::cos(kPi * t));
    } else {
      v = 1.0;
    }
    w[j] = v;
  }
  return w;
}

std::vector<int> LastTileRow(const std::vector<TileWindow>& tiles, int tiles_x, int r, int overlap, int tiles_y,
                             Index hr_rows) {
  std::vector<int> last(hr_rows, 0);
  for (std::size_t k = 0; k < tiles.size(); k += tiles_x) {
    const TileWindow& t = tiles[k];
    const std::vector<double> wy =
        AxisWeight(t.y0, t.rows, t.core_y0, t.core_y0 + t.core_rows, r, overlap, tiles_y);
    for (Index y = 0; y < Index(wy.size()); ++y)
      if (wy[y] != 0) {
        int& l = last[WrapIndex(t.y0 * r + y, hr_rows)];
        l = std::max(l, t.ty);
      }
  }
  return last;
}

}  // namespace tiling_internal

Image TileBlendWeight(const TileWindow& tile, int r, int overlap, int tiles_y, int tiles_x) {
  const std::vector<double> wy =
      tiling_internal::AxisWeight(tile.y0, tile.rows, tile.core_y0, tile.core_y0 + tile.core_rows, r, overlap, tiles_y);
  const std::vector<double> wx =
      tiling_internal::AxisWeight(tile.x0, tile.cols, tile.core_x0, tile.core_x0 + tile.core_cols, r, overlap, tiles_x);
  Image w(tile.rows * r, tile.cols * r);
  for (Index y = 0; y < w.rows(); ++y)
    for (Index x = 0; x < w.cols(); ++x) w(y, x) = wy[y] * wx[x];
  return w;
}

}  // namespace aosr
