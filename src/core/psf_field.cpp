#include "aosr/core/psf_field.hpp"

#include <algorithm>
#include <cmath>
#include <string>

#include "aosr/core/error.hpp"

namespace aosr {

PsfFieldGrid::PsfFieldGrid(Shape hr, int ny, int nx, const char* function) : hr_(hr), ny_(ny), nx_(nx) {
  if (hr.rows < 1 || hr.cols < 1)
    throw InvalidArgument(function, "hr_shape", ToString(hr), "both sides >= 1");
  if (ny < 1 || ny > 64 || nx < 1 || nx > 64)
    throw InvalidArgument(function, "grid", std::to_string(ny) + " x " + std::to_string(nx), "1..64 nodes per axis");
  if ((ny > 1 && hr.rows < 2) || (nx > 1 && hr.cols < 2))
    throw InvalidArgument(function, "grid", std::to_string(ny) + " x " + std::to_string(nx),
                          "one node along an axis of one pixel (frame " + ToString(hr) + ")");
}

std::array<double, 2> PsfFieldGrid::Node(int k) const {
  if (k < 0 || k >= nodes())
    throw InvalidArgument("PsfFieldGrid::Node", "k", std::to_string(k), "0.." + std::to_string(nodes() - 1));
  const int j = k / nx_, i = k % nx_;
  auto at = [](int index, int n, Index side) {
    return n == 1 ? 0.5 * double(side - 1) : double(index) * double(side - 1) / double(n - 1);
  };
  return {at(j, ny_, hr_.rows), at(i, nx_, hr_.cols)};
}

std::array<double, 2> PsfFieldGrid::Spacing() const {
  return {ny_ > 1 ? double(hr_.rows - 1) / double(ny_ - 1) : 0.0,
          nx_ > 1 ? double(hr_.cols - 1) / double(nx_ - 1) : 0.0};
}

// The position in node units along one axis, clamped to [0, n − 1].
double PsfFieldGrid::AxisCoordinate(double p, Index side, int n) const {
  if (n == 1) return 0.0;
  const double u = p * double(n - 1) / double(side - 1);
  return std::clamp(u, 0.0, double(n - 1));
}

std::vector<PsfFieldGrid::Weight> PsfFieldGrid::Weights(double y, double x) const {
  if (empty()) throw InvalidArgument("PsfFieldGrid::Weights", "grid", "(empty)", "a grid with nodes");
  if (!std::isfinite(y) || !std::isfinite(x))
    throw InvalidArgument("PsfFieldGrid::Weights", "position", ToString(y) + ", " + ToString(x), "finite");
  const double u = AxisCoordinate(y, hr_.rows, ny_), v = AxisCoordinate(x, hr_.cols, nx_);
  // The lower node and the fraction toward the next; at the last node the fraction is 0 (no node beyond).
  const int j0 = std::min(int(std::floor(u)), ny_ - 1), i0 = std::min(int(std::floor(v)), nx_ - 1);
  const double fy = u - j0, fx = v - i0;
  std::vector<Weight> w;
  for (int dj = 0; dj < 2; ++dj)
    for (int di = 0; di < 2; ++di) {
      const double wy = dj == 0 ? 1.0 - fy : fy, wx = di == 0 ? 1.0 - fx : fx;
      const double ww = wy * wx;
      if (ww > 0.0) w.push_back({(j0 + dj) * nx_ + (i0 + di), ww});
    }
  return w;
}

Image PsfFieldGrid::WeightMap(int k, int s) const {
  if (k < 0 || k >= nodes())
    throw InvalidArgument("PsfFieldGrid::WeightMap", "k", std::to_string(k), "0.." + std::to_string(nodes() - 1));
  if (s < 1) throw InvalidArgument("PsfFieldGrid::WeightMap", "s", std::to_string(s), ">= 1");
  const int j = k / nx_, i = k % nx_;
  const double half = 0.5 * double(s - 1);
  // Separable: the tent of node j along y times that of node i along x.
  auto axis = [&](Index side, int n, int node) {
    Eigen::VectorXd t(side * s);
    for (Index a = 0; a < side * s; ++a) {
      const double u = AxisCoordinate((double(a) - half) / double(s), side, n);
      t[a] = std::max(0.0, 1.0 - std::abs(u - double(node)));
    }
    return t;
  };
  const Eigen::VectorXd ty = axis(hr_.rows, ny_, j), tx = axis(hr_.cols, nx_, i);
  return ty * tx.transpose();
}

Image PsfFieldGrid::Interpolate(const ImageStack& psfs, double y, double x) const {
  if (int(psfs.size()) != nodes())
    throw InvalidArgument("PsfFieldGrid::Interpolate", "psfs", std::to_string(psfs.size()) + " images",
                          std::to_string(nodes()) + " (one per node)");
  for (const Image& p : psfs)
    if (p.rows() != psfs.front().rows() || p.cols() != psfs.front().cols() || p.size() == 0)
      throw InvalidArgument("PsfFieldGrid::Interpolate", "psfs", ToString(ShapeOf(p)),
                            "non-empty images of one shape " + ToString(ShapeOf(psfs.front())));
  Image out = Image::Zero(psfs.front().rows(), psfs.front().cols());
  for (const Weight& w : Weights(y, x)) out += w.weight * psfs[w.node];
  return out;
}

}  // namespace aosr
