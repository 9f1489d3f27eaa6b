#include "aosr/scene/dead_leaves.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include "aosr/ao/random.hpp"
#include "aosr/core/error.hpp"
#include "object_random.hpp"

namespace aosr {
namespace {

constexpr std::uint64_t kLeavesStream = 3;
constexpr Index kTile = 16;
constexpr double kMaxRadius = 1e4;


// Distance² from (y, x) to the rectangle [y0, y1] x [x0, x1] (0 inside).
double DistanceToRect2(double y, double x, double y0, double y1, double x0, double x1) {
  const double dy = y < y0 ? y0 - y : (y > y1 ? y - y1 : 0.0);
  const double dx = x < x0 ? x0 - x : (x > x1 ? x - x1 : 0.0);
  return dy * dy + dx * dx;
}

}  // namespace

bool DeadLeavesOptions::IsValid(std::string* why) const {
  if (!std::isfinite(r_min_px) || r_min_px <= 0.0)
    return Fail(why, "r_min_px = " + ToString(r_min_px) + " (must be finite and > 0)");
  if (!std::isfinite(r_max_px) || r_max_px <= r_min_px || r_max_px > kMaxRadius)
    return Fail(why, "r_max_px = " + ToString(r_max_px) + " (must be > r_min_px = " + ToString(r_min_px) +
                         " and <= 10000)");
  if (!std::isfinite(radius_exponent) || radius_exponent < 1.0 || radius_exponent > 6.0)
    return Fail(why, "radius_exponent = " + ToString(radius_exponent) + " (must be in [1, 6])");
  if (!std::isfinite(grey_min)) return Fail(why, "grey_min = " + ToString(grey_min) + " (must be finite)");
  if (!std::isfinite(grey_max) || grey_max <= grey_min)
    return Fail(why, "grey_max = " + ToString(grey_max) +
                         " (must be finite and > grey_min = " + ToString(grey_min) + ")");
  if (supersample < 1 || supersample > 16)
    return Fail(why, "supersample = " + std::to_string(supersample) + " (must be in [1, 16])");
  if (max_leaves < 1) return Fail(why, "max_leaves = " + std::to_string(max_leaves) + " (must be >= 1)");
  return true;
}

Image DeadLeaves(Shape hr, const DeadLeavesOptions& options, std::uint64_t seed, DeadLeavesSummary* summary) {
  const std::string fn = "DeadLeaves";
  CheckArgument(hr.rows >= 1 && hr.cols >= 1, fn, "hr", ToString(hr), "rows and cols >= 1");
  std::string why;
  if (!options.IsValid(&why)) throw InvalidArgument(fn + ": invalid options: " + why);

  const int s = options.supersample;
  const Index fine_rows = hr.rows * s, fine_cols = hr.cols * s;
  const double nan = std::numeric_limits<double>::quiet_NaN();
  Image fine = Image::Constant(fine_rows, fine_cols, nan);  // NaN: not yet painted
  const Index tiles_y = (fine_rows + kTile - 1) / kTile, tiles_x = (fine_cols + kTile - 1) / kTile;
  std::vector<std::int64_t> tile_uncovered(tiles_y * tiles_x);
  for (Index ty = 0; ty < tiles_y; ++ty)
    for (Index tx = 0; tx < tiles_x; ++tx)
      tile_uncovered[ty * tiles_x + tx] = (std::min(fine_rows, (ty + 1) * kTile) - ty * kTile) *
                                          (std::min(fine_cols, (tx + 1) * kTile) - tx * kTile);
  std::int64_t uncovered = static_cast<std::int64_t>(fine_rows) * fine_cols;

  DeadLeavesSummary stats;
  stats.samples = uncovered;
  // Window in HR coordinates.
  const double wy0 = -0.5, wy1 = hr.rows - 0.5, wx0 = -0.5, wx1 = hr.cols - 0.5;
  const double height = wy1 - wy0, width = wx1 - wx0;
  // Proposal for the leaves that can meet the window (dead_leaves.hpp): r with density
  // ∝ r^-alpha (H + 2r)(W + 2r) = HW r^-alpha + 2(H + W) r^(1-alpha) + 4 r^(2-alpha), a mixture of three
  // truncated power laws with weights HW J(-alpha), 2(H + W) J(1-alpha), 4 J(2-alpha), J(k) = ∫ r^k dr.
  const double alpha = options.radius_exponent, r_lo = options.r_min_px, r_hi = options.r_max_px;
  const auto integral = [r_lo, r_hi](double k) {  // ∫_{r_lo}^{r_hi} r^k dr
    const double lr = std::log(r_hi / r_lo);
    const double scaled = std::abs(k + 1.0) < 1e-12 ? lr : std::expm1((k + 1.0) * lr) / (k + 1.0);
    return std::pow(r_lo, k + 1.0) * scaled;
  };
  const double w0 = height * width * integral(-alpha), w1 = 2.0 * (height + width) * integral(1.0 - alpha);
  const double w2 = 4.0 * integral(2.0 - alpha);
  const double p0 = w0 / (w0 + w1 + w2), p1 = (w0 + w1) / (w0 + w1 + w2);
  scene_internal::UniformGenerator rng(DeriveSeed(seed, kLeavesStream));
  // Fine sample (i, j) sits at HR coordinate ((i + 1/2)/s - 1/2, (j + 1/2)/s - 1/2); its inverse below.
  const auto fine_coordinate = [s](Index i) { return (static_cast<double>(i) + 0.5) / s - 0.5; };
  const auto first_fine = [s](double t) { return static_cast<Index>(std::ceil((t + 0.5) * s - 0.5)); };
  const auto last_fine = [s](double t) { return static_cast<Index>(std::floor((t + 0.5) * s - 0.5)); };

  while (uncovered > 0 && stats.leaves_drawn < options.max_leaves) {
    // Five deviates per proposal: mixture component, radius, centre y, centre x, grey.
    const double pick = rng.Next();
    const double exponent = pick < p0 ? alpha : (pick < p1 ? alpha - 1.0 : alpha - 2.0);
    const double r = scene_internal::PowerLawQuantile(rng.Next(), exponent, r_lo, r_hi);
    const double cy = rng.Uniform(wy0 - r, wy1 + r);
    const double cx = rng.Uniform(wx0 - r, wx1 + r);
    const double grey = rng.Uniform(options.grey_min, options.grey_max);
    // Centres in the corners of the dilated rectangle may still miss the window: reject the whole proposal.
    if (DistanceToRect2(cy, cx, wy0, wy1, wx0, wx1) > r * r) continue;
    ++stats.leaves_drawn;
    const Index i0 = std::max<Index>(0, first_fine(cy - r)),
                i1 = std::min<Index>(fine_rows - 1, last_fine(cy + r));
    const Index j0 = std::max<Index>(0, first_fine(cx - r)),
                j1 = std::min<Index>(fine_cols - 1, last_fine(cx + r));
    if (i0 > i1 || j0 > j1) continue;
    bool painted = false;
    const double r2 = r * r;
    for (Index ty = i0 / kTile; ty <= i1 / kTile; ++ty) {
      for (Index tx = j0 / kTile; tx <= j1 / kTile; ++tx) {
        std::int64_t& tile = tile_uncovered[ty * tiles_x + tx];
        if (tile == 0) continue;
        const Index ia = std::max(i0, ty * kTile), ib = std::min(i1, ty * kTile + kTile - 1);
        const Index ja = std::max(j0, tx * kTile), jb = std::min(j1, tx * kTile + kTile - 1);
        for (Index i = ia; i <= ib; ++i) {
          const double dy = fine_coordinate(i) - cy;
          const double rest = r2 - dy * dy;
          if (rest < 0.0) continue;
          double* row = &fine(i, 0);
          for (Index j = ja; j <= jb; ++j) {
            if (!std::isnan(row[j])) continue;
            const double dx = fine_coordinate(j) - cx;
            if (dx * dx > rest) continue;
            row[j] = grey;
            --tile;
            --uncovered;
            painted = true;
          }
        }
      }
    }
    if (painted) ++stats.leaves_visible;
  }
  stats.uncovered_samples = uncovered;
  if (uncovered > 0) {
    const double mean_grey = 0.5 * (options.grey_min + options.grey_max);
    fine = fine.isNaN().select(mean_grey, fine);
  }
  if (summary != nullptr) *summary = stats;

  Image out(hr.rows, hr.cols);
  const double inv = 1.0 / (s * s);
  for (Index y = 0; y < hr.rows; ++y)
    for (Index x = 0; x < hr.cols; ++x) out(y, x) = fine.block(y * s, x * s, s, s).sum() * inv;
  return out;
}

}  // namespace aosr
