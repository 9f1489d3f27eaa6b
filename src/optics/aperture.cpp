#include "aosr/optics/aperture.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <vector>

#include "aosr/core/error.hpp"

namespace aosr {
namespace {

constexpr double kSqrt3 = 1.7320508075688772935;

// cos/sin with values within 1e-15 of 0 or +-1 snapped, so vanes and lattices at multiples of 90° are exactly
// symmetric on the grid (cos(pi/2) is 6e-17 in floating point, not 0).
void SnappedDirection(double angle, double* c, double* s) {
  auto snap = [](double v) {
    if (std::abs(v) < 1e-15) return 0.0;
    if (std::abs(v - 1.0) < 1e-15) return 1.0;
    if (std::abs(v + 1.0) < 1e-15) return -1.0;
    return v;
  };
  *c = snap(std::cos(angle));
  *s = snap(std::sin(angle));
}


// Everything in normalised pupil units (radius D/2 = 1), see pupil.hpp.
class ApertureModel {
 public:
  explicit ApertureModel(const ApertureGeometry& g) {
    const double radius = 0.5 * g.pupil.diameter_m;
    circular_ = g.outline == ApertureOutline::kCircular;
    inner_ = g.pupil.obstruction;
    inner2_ = inner_ * inner_;
    if (!circular_) {
      const SegmentGeometry& s = g.segments;
      rings_ = s.rings;
      central_ = s.central_segment;
      half_flat_ = 0.5 * s.flat_to_flat_m / radius;
      pitch_ = (s.flat_to_flat_m + s.gap_m) / radius;
      SnappedDirection(s.rotation_rad, &rot_c_, &rot_s_);
    }
    half_width_ = 0.5 * g.spiders.width_m / radius;
    for (int k = 0; k < g.spiders.count; ++k) {
      double c, s;
      SnappedDirection(g.spiders.angle_offset_rad + 2.0 * kPi * k / g.spiders.count, &c, &s);
      vanes_.push_back({c, s});
    }
  }

  // Transmission (true/false) at normalised (x, y); if `edge` is non-null, also a lower bound on the distance
  // to the nearest edge of any component (exact for the circles).
  bool Transmits(double x, double y, double* edge) const {
    double dist = std::numeric_limits<double>::infinity();
    const double r2 = x * x + y * y;
    bool open = r2 >= inner2_;
    if (edge != nullptr) dist = std::abs(std::sqrt(r2) - inner_);
    if (circular_) {
      open = open && r2 <= 1.0;
      if (edge != nullptr) dist = std::min(dist, std::abs(std::sqrt(r2) - 1.0));
    } else {
      double seg_dist;
      open = InSegment(x, y, &seg_dist) && open;
      dist = std::min(dist, seg_dist);
    }
    for (const auto& v : vanes_) {
      const double t = x * v[0] + y * v[1];   // along the vane
      const double s = -x * v[1] + y * v[0];  // across the vane
      const double as = std::abs(s);
      if (t >= 0.0 && as <= half_width_) open = false;
      if (edge != nullptr) {
        // Distance to the vane's boundary: its two long edges (rays from t = 0 at s = +-h) and its end cap.
        const double ds = as - half_width_;
        const double long_edges = t >= 0.0 ? std::abs(ds) : std::hypot(t, ds);
        const double cap = as <= half_width_ ? std::abs(t) : std::hypot(t, ds);
        dist = std::min(dist, std::min(long_edges, cap));
      }
    }
    if (edge != nullptr) *edge = dist;
    return open;
  }

 private:
  // Whether (x, y) lies on a segment; *dist: lower bound on the distance to any segment edge.
  bool InSegment(double x, double y, double* dist) const {
    // Rotate into the lattice frame, where the lattice vectors are p (1, 0) and p (1/2, sqrt(3)/2).
    const double xr = x * rot_c_ + y * rot_s_;
    const double yr = -x * rot_s_ + y * rot_c_;
    // Axial coordinates and cube rounding: the nearest lattice point, i.e. the hexagonal Voronoi cell.
    const double bf = 2.0 * yr / (pitch_ * kSqrt3);
    const double af = xr / pitch_ - 0.5 * bf;
    const double cf = -af - bf;
    double a = std::round(af), b = std::round(bf), c = std::round(cf);
    const double da = std::abs(a - af), db = std::abs(b - bf), dc = std::abs(c - cf);
    if (da > db && da > dc) {
      a = -b - c;
    } else if (db > dc) {
      b = -a - c;
    }
    const double dx = xr - pitch_ * (a + 0.5 * b);
    const double dy = yr - pitch_ * (0.5 * kSqrt3 * b);
    const double m = std::max(
        {std::abs(dx), std::abs(0.5 * dx + 0.5 * kSqrt3 * dy), std::abs(-0.5 * dx + 0.5 * kSqrt3 * dy)});
    const int ring = static_cast<int>(std::max({std::abs(a), std::abs(b), std::abs(a + b)}));
    const bool exists = ring <= rings_ && (central_ || ring > 0);
    const double to_cell_edge = 0.5 * pitch_ - m;
    if (!exists) {
      *dist = to_cell_edge;
      return false;
    }
    *dist = std::min(std::abs(m - half_flat_), to_cell_edge);
    return m <= half_flat_;
  }

  bool circular_ = true;
  double inner_ = 0.0, inner2_ = 0.0;
  int rings_ = 0;
  bool central_ = true;
  double half_flat_ = 0.0, pitch_ = 1.0, rot_c_ = 1.0, rot_s_ = 0.0;
  double half_width_ = 0.0;
  std::vector<std::array<double, 2>> vanes_;
};

}  // namespace

int SegmentCount(const SegmentGeometry& segments) {
  CheckArgument(segments.rings >= 0 && segments.rings <= 50, "SegmentCount", "segments.rings", segments.rings,
                "0 .. 50");
  return 1 + 3 * segments.rings * (segments.rings + 1) - (segments.central_segment ? 0 : 1);
}

Eigen::Matrix2Xd SegmentCentres(const SegmentGeometry& segments) {
  const int count = SegmentCount(segments);
  CheckArgument(std::isfinite(segments.flat_to_flat_m) && segments.flat_to_flat_m > 0.0, "SegmentCentres",
                "segments.flat_to_flat_m", segments.flat_to_flat_m, "> 0 and finite [m]");
  CheckArgument(std::isfinite(segments.gap_m) && segments.gap_m >= 0.0, "SegmentCentres", "segments.gap_m",
                segments.gap_m, ">= 0 and finite [m]");
  CheckArgument(std::isfinite(segments.rotation_rad), "SegmentCentres", "segments.rotation_rad",
                segments.rotation_rad, "finite [rad]");
  const double p = segments.flat_to_flat_m + segments.gap_m;
  double c, s;
  SnappedDirection(segments.rotation_rad, &c, &s);
  Eigen::Matrix2Xd centres(2, count);
  int q = 0;
  for (int ring = segments.central_segment ? 0 : 1; ring <= segments.rings; ++ring) {
    for (int a = -ring; a <= ring; ++a) {
      for (int b = -ring; b <= ring; ++b) {
        if (std::max({std::abs(a), std::abs(b), std::abs(a + b)}) != ring) continue;
        const double xr = p * (a + 0.5 * b), yr = p * 0.5 * kSqrt3 * b;
        centres(0, q) = xr * c - yr * s;
        centres(1, q) = xr * s + yr * c;
        ++q;
      }
    }
  }
  return centres;
}

double SegmentedOuterRadius(const SegmentGeometry& segments) {
  const Eigen::Matrix2Xd centres = SegmentCentres(segments);
  // Corners of a hexagon of flat-to-flat f sit at distance f / sqrt(3) from its centre, at 30° + k 60° from
  // the lattice direction.
  const double circumradius = segments.flat_to_flat_m / kSqrt3;
  double outer = 0.0;
  for (Index q = 0; q < centres.cols(); ++q) {
    for (int k = 0; k < 6; ++k) {
      const double angle = segments.rotation_rad + kPi / 6.0 + k * kPi / 3.0;
      outer = std::max(outer, std::hypot(centres(0, q) + circumradius * std::cos(angle),
                                         centres(1, q) + circumradius * std::sin(angle)));
    }
  }
  return outer;
}

bool ApertureGeometry::IsValid(std::string* why) const {
  std::string msg;
  if (!pupil.IsValid(&msg)) return Fail(why, "pupil." + msg);
  if (outline != ApertureOutline::kCircular && outline != ApertureOutline::kHexSegments) {
    return Fail(why,
                "outline = " + ToString(static_cast<int>(outline)) + "; allowed: kCircular, kHexSegments");
  }
  if (outline == ApertureOutline::kHexSegments) {
    const SegmentGeometry& s = segments;
    if (!(s.rings >= 0 && s.rings <= 50)) {
      return Fail(why, "segments.rings = " + ToString(s.rings) + "; allowed: 0 .. 50");
    }
    if (!(std::isfinite(s.flat_to_flat_m) && s.flat_to_flat_m > 0.0)) {
      return Fail(
          why, "segments.flat_to_flat_m = " + ToString(s.flat_to_flat_m) + "; allowed: > 0 and finite [m]");
    }
    if (!(std::isfinite(s.gap_m) && s.gap_m >= 0.0 && s.gap_m < s.flat_to_flat_m)) {
      return Fail(why, "segments.gap_m = " + ToString(s.gap_m) +
                           "; allowed: >= 0, finite and < segments.flat_to_flat_m [m]");
    }
    if (!std::isfinite(s.rotation_rad)) {
      return Fail(why, "segments.rotation_rad = " + ToString(s.rotation_rad) + "; allowed: finite [rad]");
    }
    if (s.rings == 0 && !s.central_segment) {
      return Fail(
          why, "segments.central_segment = false; allowed: true when segments.rings = 0 (else no segment)");
    }
    const double outer = SegmentedOuterRadius(s);
    if (outer > 0.5 * pupil.diameter_m * (1.0 + 1e-12)) {
      return Fail(why,
                  "segments.rings = " + ToString(s.rings) + " (outermost corner at " + ToString(outer) +
                      " m); allowed: segments inside the grid, i.e. outer radius <= pupil.diameter_m / 2 = " +
                      ToString(0.5 * pupil.diameter_m) + " m");
    }
  }
  const SpiderGeometry& sp = spiders;
  if (!(sp.count >= 0 && sp.count <= 64)) {
    return Fail(why, "spiders.count = " + ToString(sp.count) + "; allowed: 0 .. 64");
  }
  if (sp.count > 0) {
    if (!(std::isfinite(sp.width_m) && sp.width_m > 0.0 && sp.width_m < pupil.diameter_m)) {
      return Fail(why, "spiders.width_m = " + ToString(sp.width_m) +
                           "; allowed: > 0, finite and < pupil.diameter_m when spiders.count > 0 [m]");
    }
    if (!std::isfinite(sp.angle_offset_rad)) {
      return Fail(why,
                  "spiders.angle_offset_rad = " + ToString(sp.angle_offset_rad) + "; allowed: finite [rad]");
    }
  }
  return true;
}

Image Aperture(Index n, const ApertureGeometry& geometry, int supersample) {
  CheckArgument(n >= 1, "Aperture", "n", n, ">= 1");
  std::string why;
  if (!geometry.IsValid(&why)) throw InvalidArgument("Aperture: invalid geometry." + why);
  CheckArgument(supersample >= 1 && supersample <= 64, "Aperture", "supersample", supersample, "1 .. 64");
  const ApertureModel model(geometry);
  // Sub-pixel centre offsets in normalised units, exactly as CircularPupil computes them.
  const int s = supersample;
  const double sub_pitch = 2.0 / (static_cast<double>(n) * s);
  std::vector<double> offsets(s);
  for (int q = 0; q < s; ++q) offsets[q] = (q + 0.5 - 0.5 * s) * sub_pitch;
  const double half_diag = std::sqrt(2.0) / static_cast<double>(n);
  const double inv_count = 1.0 / (static_cast<double>(s) * s);

  Image a(n, n);
  for (Index i = 0; i < n; ++i) {
    const double yc = NormalisedPupilPosition(i, n);
    for (Index k = 0; k < n; ++k) {
      const double xc = NormalisedPupilPosition(k, n);
      double edge = 0.0;
      const bool centre_open = model.Transmits(xc, yc, s > 1 ? &edge : nullptr);
      if (s == 1 || edge > half_diag) {
        a(i, k) = centre_open ? 1.0 : 0.0;
        continue;
      }
      int inside = 0;
      for (int qy = 0; qy < s; ++qy) {
        const double y = yc + offsets[qy];
        for (int qx = 0; qx < s; ++qx) inside += model.Transmits(xc + offsets[qx], y, nullptr) ? 1 : 0;
      }
      a(i, k) = inside * inv_count;
    }
  }
  return a;
}

namespace {

// R(i, j) = n |[i/n, (i+1)/n) ∩ [j/m, (j+1)/m)| in units of the span: rows of R sum to 1. Computed in integer
// arithmetic on the common refinement (boundaries i*m and j*n on a grid of n*m cells), so it is exact.
Eigen::MatrixXd OverlapMatrix(Index n, Index m) {
  Eigen::MatrixXd r = Eigen::MatrixXd::Zero(n, m);
  for (Index i = 0; i < n; ++i) {
    const Index lo = i * m, hi = (i + 1) * m;  // output pixel in units of 1/(n m)
    for (Index j = lo / n; j < m && j * n < hi; ++j) {
      const Index overlap = std::min(hi, (j + 1) * n) - std::max(lo, j * n);
      if (overlap > 0) r(i, j) = static_cast<double>(overlap) / static_cast<double>(m);
    }
  }
  return r;
}

}  // namespace

Image ResampleMask(const Image& mask, Index n) {
  CheckArgument(n >= 1, "ResampleMask", "n", n, ">= 1");
  CheckArgument(mask.size() > 0, "ResampleMask", "mask shape", ToString(ShapeOf(mask)), "non-empty");
  CheckArgument(mask.isFinite().all() && (mask >= 0.0).all() && (mask <= 1.0).all(), "ResampleMask", "mask",
                "values outside [0, 1] or non-finite", "finite transmissions in [0, 1]");
  if (mask.rows() == n && mask.cols() == n) return mask;
  const Eigen::MatrixXd ry = OverlapMatrix(n, mask.rows());
  const Eigen::MatrixXd rx = OverlapMatrix(n, mask.cols());
  Image out(n, n);
  out.matrix().noalias() = ry * mask.matrix() * rx.transpose();
  // Rounding can push a fully covered pixel a hair above 1.
  return out.min(1.0).max(0.0);
}

}  // namespace aosr
