#include "aosr/optics/pupil.hpp"

#include <cmath>
#include <vector>

#include "aosr/core/error.hpp"

namespace aosr {

bool PupilGeometry::IsValid(std::string* why) const {
  std::string msg;
  if (!(std::isfinite(diameter_m) && diameter_m > 0.0)) {
    msg = "diameter_m = " + ToString(diameter_m) + "; allowed: > 0 and finite [m]";
  } else if (!(obstruction >= 0.0 && obstruction < 1.0)) {
    msg = "obstruction = " + ToString(obstruction) + "; allowed: [0, 1) (obstruction diameter / D)";
  }
  if (msg.empty()) return true;
  if (why != nullptr) *why = msg;
  return false;
}

PolarCoordinates PupilCoordinates(Index n) {
  CheckArgument(n >= 1, "PupilCoordinates", "n", n, ">= 1");
  PolarCoordinates c{Image(n, n), Image(n, n)};
  for (Index i = 0; i < n; ++i) {
    const double y = NormalisedPupilPosition(i, n);
    for (Index k = 0; k < n; ++k) {
      const double x = NormalisedPupilPosition(k, n);
      c.rho(i, k) = std::sqrt(x * x + y * y);
      c.theta(i, k) = std::atan2(y, x);
    }
  }
  return c;
}

Image CircularPupil(Index n, const PupilGeometry& geometry, int supersample) {
  CheckArgument(n >= 1, "CircularPupil", "n", n, ">= 1");
  std::string why;
  if (!geometry.IsValid(&why)) throw InvalidArgument("CircularPupil: invalid geometry." + why);
  CheckArgument(supersample >= 1 && supersample <= 64, "CircularPupil", "supersample", supersample,
                "1 .. 64");
  // Sub-pixel centre offsets in normalised units: pixel pitch is 2/n, sub-pitch 2/(n s).
  const int s = supersample;
  const double sub_pitch = 2.0 / (static_cast<double>(n) * s);
  std::vector<double> offsets(s);
  for (int q = 0; q < s; ++q) offsets[q] = (q + 0.5 - 0.5 * s) * sub_pitch;
  const double inner2 = geometry.obstruction * geometry.obstruction;
  // A pixel entirely inside the annulus or entirely outside needs no sub-sampling: the half-diagonal of a
  // pixel in normalised units is sqrt(2)/n.
  const double half_diag = std::sqrt(2.0) / static_cast<double>(n);
  const double inv_count = 1.0 / (static_cast<double>(s) * s);

  Image a(n, n);
  for (Index i = 0; i < n; ++i) {
    const double yc = NormalisedPupilPosition(i, n);
    for (Index k = 0; k < n; ++k) {
      const double xc = NormalisedPupilPosition(k, n);
      const double rc = std::sqrt(xc * xc + yc * yc);
      if (s > 1 && rc + half_diag < 1.0 && rc - half_diag > geometry.obstruction) {
        a(i, k) = 1.0;
        continue;
      }
      if (s > 1 && (rc - half_diag > 1.0 || rc + half_diag < geometry.obstruction)) {
        a(i, k) = 0.0;
        continue;
      }
      int inside = 0;
      for (int qy = 0; qy < s; ++qy) {
        const double y = yc + offsets[qy];
        for (int qx = 0; qx < s; ++qx) {
          const double x = xc + offsets[qx];
          const double r2 = x * x + y * y;
          inside += (r2 <= 1.0 && r2 >= inner2) ? 1 : 0;
        }
      }
      a(i, k) = inside * inv_count;
    }
  }
  return a;
}

void CheckPupilAmplitude(const Image& amplitude, double diameter_m, const std::string& function) {
  CheckArgument(amplitude.rows() >= 2 && amplitude.rows() == amplitude.cols(), function, "amplitude shape",
                ToString(ShapeOf(amplitude)), "a square n x n pupil grid, n >= 2");
  CheckArgument(amplitude.isFinite().all() && (amplitude >= 0.0).all(), function, "amplitude",
                "negative or non-finite values", "finite values >= 0");
  CheckArgument(amplitude.sum() > 0.0, function, "amplitude", "all zero", "some pixel > 0 (an open aperture)");
  CheckArgument(std::isfinite(diameter_m) && diameter_m > 0.0, function, "diameter_m", diameter_m,
                "> 0 and finite [m]");
}

}  // namespace aosr
