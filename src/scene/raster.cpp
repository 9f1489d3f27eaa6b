#include "aosr/scene/raster.hpp"

#include <cmath>

#include "aosr/core/error.hpp"

namespace aosr {

std::vector<FrameOffset> ClassicRaster(int n, int r) {
  CheckArgument(n >= 1, "ClassicRaster", "n", n, ">= 1");
  CheckArgument(r >= 1, "ClassicRaster", "r", r, ">= 1");
  std::vector<FrameOffset> out;
  if (n == 2) {
    out = {{0.0, 0.0}, {r / 2.0, r / 2.0}};
  } else {
    int qy = int(std::floor(std::sqrt(double(n))));
    while (n % qy) --qy;
    const int qx = n / qy;
    for (int i = 0; i < qy; ++i)
      for (int j = 0; j < qx; ++j) out.push_back({i * double(r) / qy, j * double(r) / qx});
  }
  double my = 0, mx = 0;
  for (const auto& o : out) my += o.dy / out.size(), mx += o.dx / out.size();
  for (auto& o : out) o.dy -= my, o.dx -= mx;
  return out;
}

}  // namespace aosr
