#include "aosr/solvers/power_spectrum_model.hpp"

#include <cmath>

#include "aosr/core/error.hpp"
#include "aosr/core/fft.hpp"

namespace aosr {

double PowerSpectrumModel::operator()(double f) const {
  return amplitude * std::pow(corner * corner + f * f, -0.5 * slope) + floor;
}

bool PowerSpectrumModel::IsValid(std::string* why) const {
  auto fail = [why](const std::string& m) {
    if (why) *why = m;
    return false;
  };
  if (!(std::isfinite(amplitude) && amplitude > 0)) return fail("amplitude must be finite and > 0, got " + ToString(amplitude));
  if (!(std::isfinite(corner) && corner > 0)) return fail("corner must be finite and > 0, got " + ToString(corner));
  if (!(slope >= -2.0 && slope <= 12.0)) return fail("slope must be in [-2, 12], got " + ToString(slope));
  if (!(std::isfinite(floor) && floor >= 0)) return fail("floor must be finite and >= 0, got " + ToString(floor));
  return true;
}

Image PowerSpectrumGrid(const PowerSpectrumModel& model, Shape grid) {
  const char* fn = "PowerSpectrumGrid";
  std::string why;
  if (!model.IsValid(&why)) throw InvalidArgument(std::string(fn) + ": model." + why);
  CheckArgument(grid.rows >= 1 && grid.cols >= 1, fn, "grid", ToString(grid), "both sides >= 1");
  Image s(grid.rows, grid.cols);
  for (Index ky = 0; ky < grid.rows; ++ky)
    for (Index kx = 0; kx < grid.cols; ++kx) {
      const double vy = double(SignedFrequency(ky, grid.rows)) / double(grid.rows);
      const double vx = double(SignedFrequency(kx, grid.cols)) / double(grid.cols);
      s(ky, kx) = model(std::sqrt(vy * vy + vx * vx));
    }
  if (!AllFinite(s) || !(s.minCoeff() > 0))
    throw InvalidArgument(fn, "model", "a spectrum that is not finite and > 0 on the grid", "finite, > 0 values");
  return s;
}

Image HannWindowSmooth(const Image& s) {
  const Index r = s.rows(), c = s.cols();
  Image t(r, c), u(r, c);
  for (Index y = 0; y < r; ++y)
    for (Index x = 0; x < c; ++x)
      t(y, x) = (2.0 / 3.0) * s(y, x) + (1.0 / 6.0) * (s(y, (x + 1) % c) + s(y, (x + c - 1) % c));
  for (Index y = 0; y < r; ++y)
    for (Index x = 0; x < c; ++x)
      u(y, x) = (2.0 / 3.0) * t(y, x) + (1.0 / 6.0) * (t((y + 1) % r, x) + t((y + r - 1) % r, x));
  return u;
}

}  // namespace aosr
