// Private to solvers/: the tiles' raised-cosine blend (tiling.hpp, "Blending"), shared by the tile engine
// (tiling.cpp) and TileBlendWeight.
#pragma once

#include <memory>
#include <vector>

#include "aosr/core/parallel.hpp"
#include "aosr/solvers/tiling.hpp"
#include "tile_overlap.hpp"

namespace aosr::tiling_internal {

// One axis of a tile's blending weight over its window (HR pixels j = 0 .. rows·r − 1 at field HR position
// (start·r + j), unwrapped). With one tile on the axis: 1. Otherwise the raised-cosine ramps of half-width
// h = P·r/2 centred on both core boundaries (the field is periodic: the first core's left boundary is the last
// core's right one). The falling ramp is f(t) = ½(1 + cos πt); the rising ramp of the neighbour at the same
// boundary is 1 − f(t) with the same t, so the pair sums to 1 up to one rounding.
std::vector<double> AxisWeight(Index start, Index rows, Index core0, Index core1, int r, int overlap, int tiles);

// Per HR row, the last tile row whose window has a non-zero blend weight on it (the row is final once that tile
// row has been added).
std::vector<int> LastTileRow(const std::vector<TileWindow>& tiles, int tiles_x, int r, int overlap, int tiles_y,
                             Index hr_rows);

// The raised-cosine blend of finished tiles, kept row by row: a row exists from the first tile that touches
// it until the last one (in tile order) has been added, then it is handed on and freed.
class RowBlend {
 public:
  RowBlend(Shape hr, bool aux) : hr_(hr), aux_(aux), rows_(hr.rows) {}

  // The tile's blend weight is wy[y] · wx[x] (TileBlendWeight's product, formed here: no window-sized image).
  // Rows in parallel: a window's rows are distinct field rows, and each pixel still adds its tiles in tile
  // order, so the bytes do not depend on the threads.
  void Add(const TileWindow& t, int r, const std::vector<double>& wy, const std::vector<double>& wx,
           const Image& image, const Image* aux_image) {
    const Index rows = Index(wy.size()), cols = Index(wx.size());
    std::vector<Index> fx(static_cast<std::size_t>(cols));  // the field column of each window column (wrapped)
    for (Index x = 0; x < cols; ++x) fx[std::size_t(x)] = WrapIndex(t.x0 * r + x, hr_.cols);
    ParallelFor(rows, [&](Index y) {
      const double wyy = wy[std::size_t(y)];
      if (wyy == 0) return;
      const Index fy = WrapIndex(t.y0 * r + y, hr_.rows);
      Row* row = nullptr;
      const double* iy = &image(y, 0);
      const double* ay = aux_image ? &(*aux_image)(y, 0) : nullptr;
      for (Index x = 0; x < cols; ++x) {
        const double wk = wyy * wx[std::size_t(x)];
        if (wk == 0) continue;
        if (!row) row = Get(fy);
        const Index c = fx[std::size_t(x)];
        row->num[c] += wk * iy[x];
        row->den[c] += wk;
        if (ay) {
          row->anum[c] += wk * ay[x];
          row->aden[c] += wk;
        }
      }
    });
  }

  // Rows [y0, y1) as blended images (num / den; the second map 0 where no tile had one), freed afterwards.
  void Take(Index y0, Index y1, Image* image, Image* aux) {
    *image = Image::Zero(y1 - y0, hr_.cols);
    *aux = aux_ ? Image::Zero(y1 - y0, hr_.cols) : Image();
    ParallelFor(y1 - y0, [&](Index j) {
      const Index y = y0 + j;
      std::unique_ptr<Row> row = std::move(rows_[y]);
      if (!row) return;
      for (Index x = 0; x < hr_.cols; ++x) {
        if (row->den[x] > 0) (*image)(j, x) = row->num[x] / row->den[x];
        if (aux_ && row->aden[x] > 0) (*aux)(j, x) = row->anum[x] / row->aden[x];
      }
    });
  }

 private:
  struct Row {
    std::vector<double> num, den, anum, aden;
  };
  Row* Get(Index y) {
    if (!rows_[y]) {
      rows_[y] = std::make_unique<Row>();
      rows_[y]->num.assign(hr_.cols, 0.0);
      rows_[y]->den.assign(hr_.cols, 0.0);
      if (aux_) rows_[y]->anum.assign(hr_.cols, 0.0), rows_[y]->aden.assign(hr_.cols, 0.0);
    }
    return rows_[y].get();
  }
  Shape hr_;
  bool aux_;
  std::vector<std::unique_ptr<Row>> rows_;
};

}  // namespace aosr::tiling_internal
