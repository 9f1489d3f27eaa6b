#include "aosr/ao/infinite_phase_screen.hpp"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <list>
#include <mutex>
#include <utility>
#include <unordered_map>

#include "aosr/ao/phase_screen.hpp"
#include "aosr/ao/von_karman.hpp"
#include "aosr/core/error.hpp"

namespace aosr {
namespace {

// Smallest 2^a 3^b 5^c >= m (sizes FFTW transforms fastest).
Index NiceFftSize(Index m) {
  for (Index s = std::max<Index>(m, 1);; ++s) {
    Index r = s;
    for (Index p : {2, 3, 5}) {
      while (r % p == 0) r /= p;
    }
    if (r == 1) return s;
  }
}

}  // namespace

bool InfinitePhaseScreenOptions::IsValid(std::string* why) const {
  std::string msg;
  if (!(width >= 4 && width <= 2048)) {
    msg = "width = " + ToString(width) + "; allowed: 4 .. 2048 [pixels]";
  } else if (!(length >= 4 && length <= 2048)) {
    msg = "length = " + ToString(length) + "; allowed: 4 .. 2048 [pixels]";
  } else if (!(std::isfinite(pixel_scale_m) && pixel_scale_m > 0.0)) {
    msg = "pixel_scale_m = " + ToString(pixel_scale_m) + "; allowed: > 0 and finite [m]";
  } else if (!(std::isfinite(r0_m) && r0_m > 0.0)) {
    msg = "r0_m = " + ToString(r0_m) + "; allowed: > 0 and finite [m]";
  } else if (!(std::isfinite(L0_m) && L0_m > 0.0 && L0_m <= 1e6 * pixel_scale_m)) {
    msg = "L0_m = " + ToString(L0_m) + "; allowed: > 0, finite and <= 1e6 pixel_scale_m [m]";
  }
  if (msg.empty()) return true;
  if (why != nullptr) *why = msg;
  return false;
}

struct InfinitePhaseScreen::Stencil {
  struct Point {
    Index distance;  // rows before the new row (>= 1)
    Index column;
  };
  std::vector<Point> points;
  Eigen::MatrixXd a;  // width x |Z|
  Eigen::MatrixXd b;  // width x width

  explicit Stencil(const InfinitePhaseScreenOptions& options);
  std::size_t Bytes() const {
    return sizeof(Point) * points.size() + sizeof(double) * static_cast<std::size_t>(a.size() + b.size());
  }
};

InfinitePhaseScreen::Stencil::Stencil(const InfinitePhaseScreenOptions& options) {
  const Index w = options.width;
  const Index len = options.length;

  // Stencil: every row at distance d = 1 .. length; rows 1 and 2 whole, row d >= 3 at column stride
  // s(d) = 2^ceil(log2 d) (4 for d = 3..4, 8 for d = 5..8, ...) from column 0, plus the last column. s(d) is
  // a power of two that never decreases with d, so the next row's stencil lies inside {new row} + {this
  // stencil}: the stencil is a Markov state (header).
  for (Index d = 1; d <= len; ++d) {
    Index stride = 1;
    if (d >= 3) {
      while (stride < d) stride *= 2;
    }
    for (Index c = 0; c < w; c += stride) points.push_back({d, c});
    if ((w - 1) % stride != 0) points.push_back({d, w - 1});
  }
  const Index nz = static_cast<Index>(points.size());

  // Covariance of two pixels (drow, dcol) apart, memoised (many pairs share a separation).
  std::unordered_map<std::int64_t, double> cache;
  auto cov = [&](Index drow, Index dcol) {
    drow = std::abs(drow);
    dcol = std::abs(dcol);
    const std::int64_t key = static_cast<std::int64_t>(drow) * 4096 + dcol;
    auto it = cache.find(key);
    if (it != cache.end()) return it->second;
    const double r =
        options.pixel_scale_m * std::hypot(static_cast<double>(drow), static_cast<double>(dcol));
    const double v = VonKarmanCovariance(r, options.r0_m, options.L0_m);
    cache.emplace(key, v);
    return v;
  };
  Eigen::MatrixXd czz(nz, nz), cxz(w, nz), cxx(w, w);
  for (Index p = 0; p < nz; ++p) {
    for (Index q = p; q < nz; ++q) {
      czz(p, q) = czz(q, p) =
          cov(points[p].distance - points[q].distance, points[p].column - points[q].column);
    }
  }
  for (Index c = 0; c < w; ++c) {
    for (Index p = 0; p < nz; ++p) cxz(c, p) = cov(points[p].distance, c - points[p].column);
    for (Index k = c; k < w; ++k) cxx(c, k) = cxx(k, c) = cov(0, c - k);
  }
  // A = C_XZ C_ZZ^-1 (C_ZZ is SPD for distinct points; LDLT if round-off makes Cholesky fail).
  Eigen::LLT<Eigen::MatrixXd> llt(czz);
  Eigen::MatrixXd at;
  if (llt.info() == Eigen::Success) {
    at = llt.solve(cxz.transpose());
  } else {
    at = czz.ldlt().solve(cxz.transpose());
  }
  a = at.transpose();
  Eigen::MatrixXd bbt = cxx - a * cxz.transpose();
  bbt = 0.5 * (bbt + bbt.transpose());
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(bbt);
  if (eig.info() != Eigen::Success)
    throw NumericalError("InfinitePhaseScreen: eigendecomposition of B B^T failed");
  b = eig.eigenvectors() * eig.eigenvalues().cwiseMax(0.0).cwiseSqrt().asDiagonal();
}

namespace {

// Screens with the same options share their stencil: a simulation builds the same screens again (the two runs
// of an antithetic pair, a test's reference run), and the set-up is O(width^3): ~0.25 s for 184 columns, about
// 8x that under the sanitizers, where it was most of some tests' time. The cache holds the most recently used
// stencils up to kStencilCacheBytes, so a run through many screen shapes keeps a bounded amount alive. A
// stencil is computed by the same code whether or not it is cached, so the bytes do not depend on the cache.
constexpr std::size_t kStencilCacheBytes = std::size_t{32} << 20;

bool SameOptions(const InfinitePhaseScreenOptions& a, const InfinitePhaseScreenOptions& b) {
  return a.width == b.width && a.length == b.length && a.pixel_scale_m == b.pixel_scale_m && a.r0_m == b.r0_m &&
         a.L0_m == b.L0_m;
}

}  // namespace

InfinitePhaseScreen::InfinitePhaseScreen(const InfinitePhaseScreenOptions& options, std::uint64_t seed)
    : options_(options), noise_(DeriveSeed(seed, 1)) {
  std::string why;
  if (!options.IsValid(&why)) throw InvalidArgument("InfinitePhaseScreen: invalid options." + why);
  const Index w = options.width;
  const Index len = options.length;

  // Most recently used first. Built outside the lock: two threads may build the same stencil at once, and
  // either copy has the same bytes.
  static std::mutex mutex;
  static std::list<std::pair<InfinitePhaseScreenOptions, std::shared_ptr<const Stencil>>> cache;
  {
    const std::lock_guard<std::mutex> lock(mutex);
    for (auto it = cache.begin(); it != cache.end(); ++it) {
      if (SameOptions(it->first, options)) {
        stencil_ = it->second;
        cache.splice(cache.begin(), cache, it);
        break;
      }
    }
  }
  if (stencil_ == nullptr) {
    auto built = std::make_shared<const Stencil>(options);
    stencil_ = built;
    if (built->Bytes() <= kStencilCacheBytes) {
      const std::lock_guard<std::mutex> lock(mutex);
      cache.emplace_front(options, std::move(built));
      std::size_t bytes = 0;
      for (auto it = cache.begin(); it != cache.end();) {
        bytes += it->second->Bytes();
        it = bytes > kStencilCacheBytes ? cache.erase(it) : std::next(it);
      }
    }
  }

  // Initial window from an FFT screen twice the larger side (its large-scale bias is smallest well inside).
  PhaseScreenOptions fft;
  fft.size = NiceFftSize(std::max<Index>(2 * std::max(w, len), 16));
  fft.pixel_scale_m = options.pixel_scale_m;
  fft.r0_m = options.r0_m;
  fft.L0_m = options.L0_m;
  const Image initial = PhaseScreenGenerator(fft).Generate(DeriveSeed(seed, 0));
  buffer_.resize(2 * len, w);
  buffer_.topRows(len) = initial.topLeftCorner(len, w);
  buffer_.bottomRows(len).setZero();
  start_ = 0;
  z_.resize(stencil_size());
  g_.resize(w);
}

void InfinitePhaseScreen::Extrude(Index rows) {
  CheckArgument(rows >= 0, "InfinitePhaseScreen::Extrude", "rows", rows, ">= 0");
  const Index w = options_.width;
  const Index len = options_.length;
  for (Index r = 0; r < rows; ++r) {
    if (start_ + len == buffer_.rows()) {
      // Compact: move the window to the top (no overlap because capacity >= 2 length).
      buffer_.topRows(len) = buffer_.middleRows(start_, len).eval();
      start_ = 0;
    }
    const Index e = start_ + len;  // the new row
    const auto& points = stencil_->points;
    for (std::size_t i = 0; i < points.size(); ++i) {
      z_(static_cast<Index>(i)) = buffer_(e - points[i].distance, points[i].column);
    }
    noise_.Fill(g_.data(), w);
    Eigen::Map<Vector> row(buffer_.data() + e * w, w);
    row.noalias() = stencil_->a * z_;
    row.noalias() += stencil_->b * g_;
    ++start_;
    ++rows_extruded_;
  }
}

Index InfinitePhaseScreen::stencil_size() const { return static_cast<Index>(stencil_->points.size()); }

}  // namespace aosr
