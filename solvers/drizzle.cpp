#include "aosr/solvers/drizzle.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <sstream>

#include "aosr/core/error.hpp"

namespace aosr {

const char* ToString(DrizzleKernel kernel) {
  switch (kernel) {
    case DrizzleKernel::kSquare:
      return "square";
    case DrizzleKernel::kTurbo:
      return "turbo";
    case DrizzleKernel::kPoint:
      return "point";
    case DrizzleKernel::kGaussian:
      return "gaussian";
    case DrizzleKernel::kLanczos3:
      return "lanczos3";
  }
  return "unknown";
}

namespace {

constexpr const char* kKernelNames = "square, turbo, point, gaussian or lanczos3";

bool KnownKernel(DrizzleKernel k) {
  return k == DrizzleKernel::kSquare || k == DrizzleKernel::kTurbo || k == DrizzleKernel::kPoint ||
         k == DrizzleKernel::kGaussian || k == DrizzleKernel::kLanczos3;
}

}  // namespace

DrizzleKernel ParseDrizzleKernel(const std::string& name) {
  for (DrizzleKernel k : {DrizzleKernel::kSquare, DrizzleKernel::kTurbo, DrizzleKernel::kPoint,
                          DrizzleKernel::kGaussian, DrizzleKernel::kLanczos3})
    if (name == ToString(k)) return k;
  throw InvalidArgument("ParseDrizzleKernel", "kernel", "\"" + name + "\"", kKernelNames);
}

bool DrizzleOptions::IsValid(std::string* why) const {
  auto fail = [why](const std::string& m) {
    if (why) *why = m;
    return false;
  };
  if (!KnownKernel(kernel))
    return fail("kernel must be " + std::string(kKernelNames) + ", got enum value " +
                std::to_string(static_cast<int>(kernel)));
  if (!(pixfrac > 0.0 && pixfrac <= 1.0)) return fail("pixfrac must be in (0, 1], got " + ToString(pixfrac));
  if (std::isinf(fill_value)) return fail("fill_value must be finite or NaN, got " + ToString(fill_value));
  if (boundary != DrizzleBoundary::kPeriodic && boundary != DrizzleBoundary::kClip)
    return fail("boundary must be kPeriodic or kClip, got enum value " +
                std::to_string(static_cast<int>(boundary)));
  return true;
}

bool DrizzleResult::Contributed(int frame, Index y, Index x) const {
  CheckArgument(!context.empty(), "DrizzleResult::Contributed", "context", "empty",
                "a context map (options.compute_context = true)");
  CheckArgument(frame >= 0 && frame < frame_count && frame / 32 < int(context.size()),
                "DrizzleResult::Contributed", "frame", frame, "0 .. " + std::to_string(frame_count - 1));
  const ContextPlane& plane = context[std::size_t(frame / 32)];
  CheckArgument(y >= 0 && y < plane.rows() && x >= 0 && x < plane.cols(), "DrizzleResult::Contributed",
                "pixel", "(" + std::to_string(y) + ", " + std::to_string(x) + ")",
                "inside " + ToString(ShapeOf(image)));
  return (plane(y, x) >> (frame % 32)) & 1u;
}

namespace {

// The kernel of one axis for the drops of one frame. With a pure translation every camera pixel of a
// frame has the same sub-pixel phase, so drop X of the frame (centre c0 + rX) touches HR pixels
// rX + first + j with separable weights factor[j], j = 0 .. size-1, and a = factor_y · factor_x.
struct AxisFootprint {
  Index first = 0;
  std::vector<double> factor;
};

double Sinc(double t) {
  if (t == 0.0) return 1.0;
  const double pt = M_PI * t;
  return std::sin(pt) / pt;
}

// c0: HR coordinate of the centre of the axis' first drop (Y or X = 0), already bounded (see caller).
AxisFootprint Footprint(DrizzleKernel kernel, double pixfrac, int r, double c0) {
  AxisFootprint f;
  const double s = pixfrac * r;  // drop side in HR pixels
  switch (kernel) {
    case DrizzleKernel::kSquare:
    case DrizzleKernel::kTurbo: {
      // Cells [o - 1/2, o + 1/2] meeting the drop [c0 - s/2, c0 + s/2]; weight = overlap length / s.
      const double lo = c0 - 0.5 * s, hi = c0 + 0.5 * s;
      f.first = Index(std::floor(lo + 0.5));
      for (Index o = f.first; double(o) - 0.5 < hi; ++o) {
        const double overlap = std::min(hi, double(o) + 0.5) - std::max(lo, double(o) - 0.5);
        f.factor.push_back(overlap > 0.0 ? overlap / s : 0.0);
      }
      break;
    }
    case DrizzleKernel::kPoint:
      f.first = Index(std::floor(c0 + 0.5));  // the half-open cell [o - 1/2, o + 1/2) holding c0
      f.factor.push_back(1.0);
      break;
    case DrizzleKernel::kGaussian: {
      const double sigma = s / (2.0 * std::sqrt(2.0 * std::log(2.0)));
      const double pfo = std::max(2.5 * sigma, 1.2 * r);
      f.first = Index(std::ceil(c0 - pfo - 0.5));
      const double norm = 1.0 / (std::sqrt(2.0 * M_PI) * sigma);
      for (Index o = f.first; double(o) - c0 <= pfo + 0.5; ++o) {
        const double d = double(o) - c0;
        f.factor.push_back(norm * std::exp(-d * d / (2.0 * sigma * sigma)));
      }
      break;
    }
    case DrizzleKernel::kLanczos3: {
      const double support = 3.0 * s;
      f.first = Index(std::ceil(c0 - support));
      for (Index o = f.first; double(o) - c0 <= support; ++o) {
        const double t = (double(o) - c0) / s;
        f.factor.push_back(std::abs(t) < 3.0 ? Sinc(t) * Sinc(t / 3.0) : 0.0);
      }
      break;
    }
  }
  return f;
}

// Largest reach of a footprint from its drop centre, in HR pixels (bounds the clip test).
double Reach(DrizzleKernel kernel, double pixfrac, int r) {
  const double s = pixfrac * r;
  switch (kernel) {
    case DrizzleKernel::kSquare:
    case DrizzleKernel::kTurbo:
      return 0.5 * s + 1.0;
    case DrizzleKernel::kPoint:
      return 1.0;
    case DrizzleKernel::kGaussian:
      return std::max(2.5 * s / (2.0 * std::sqrt(2.0 * std::log(2.0))), 1.2 * r) + 1.0;
    case DrizzleKernel::kLanczos3:
      return 3.0 * s + 1.0;
  }
  return 0.0;
}

// HR index of `o` on an axis of length n, or -1 when clipped.
inline Index Place(Index o, Index n, bool periodic) {
  if (o >= 0 && o < n) return o;
  if (!periodic) return -1;
  const Index m = o % n;
  return m < 0 ? m + n : m;
}

}  // namespace

DrizzleResult Drizzle(const ReconstructionProblem& problem, const DrizzleOptions& options) {
  const char* fn = "Drizzle";
  std::string why;
  if (!options.IsValid(&why)) throw InvalidArgument(std::string(fn) + ": invalid options: " + why);
  problem.Validate(fn);
  const int n_frames = problem.frame_count();
  CheckArgument(
      problem.offsets.size() == problem.frames.size(), fn, "problem.offsets.size()", problem.offsets.size(),
      "one offset per frame (" + std::to_string(n_frames) + "): drizzle registers frames by their offsets");
  for (int i = 0; i < n_frames; ++i) {
    const FrameOffset& d = problem.offsets[std::size_t(i)];
    CheckArgument(std::isfinite(d.dy) && std::isfinite(d.dx), fn,
                  "problem.offsets[" + std::to_string(i) + "]",
                  "(" + ToString(d.dy) + ", " + ToString(d.dx) + ")", "finite HR-pixel offsets");
  }

  const auto start = std::chrono::steady_clock::now();
  const int r = problem.model->r();
  const Shape hr = problem.model->hr_shape(), lr = problem.model->lr_shape();
  const bool periodic = options.boundary == DrizzleBoundary::kPeriodic;
  const double inv_r2 = 1.0 / double(r * r);  // cdrizzle's iscale: flux per LR pixel -> per HR pixel

  Image num = Image::Zero(hr.rows, hr.cols);  // Σ a w d
  Image den = Image::Zero(hr.rows, hr.cols);  // Σ a w
  std::vector<ContextPlane> context;
  if (options.compute_context)
    context.assign(std::size_t((n_frames + 31) / 32), ContextPlane::Zero(hr.rows, hr.cols));

  DrizzleSummary summary;
  const double reach = Reach(options.kernel, options.pixfrac, r);
  // Centre of drop 0 on an axis: c0 = (r-1)/2 - offset (header). Periodic: the offset only matters modulo
  // the grid, and reducing it keeps the indices small. Clip: a frame whose drops all lie farther than
  // `reach` outside the grid misses entirely (checked before any index is formed).
  auto axis_centre = [&](double offset, Index n, bool* misses) {
    double c0 = 0.5 * (r - 1) - offset;
    if (periodic) {
      c0 = std::fmod(c0, double(n));
      if (c0 < 0) c0 += double(n);
    } else {
      // Drop centres on this axis span [c0, c0 + n - r]; the grid's cells span [-1/2, n - 1/2].
      if (c0 + double(n - r) + reach < -0.5 || c0 - reach > double(n) - 0.5) *misses = true;
    }
    return c0;
  };

  for (int i = 0; i < n_frames; ++i) {
    const Image& y = problem.frames[std::size_t(i)];
    const Image w = problem.Weight(i);
    const FrameOffset& off = problem.offsets[std::size_t(i)];
    bool frame_misses = false;
    const double cy = axis_centre(off.dy, hr.rows, &frame_misses);
    const double cx = axis_centre(off.dx, hr.cols, &frame_misses);
    ContextPlane* plane = options.compute_context ? &context[std::size_t(i / 32)] : nullptr;
    const std::uint32_t bit = std::uint32_t(1) << (i % 32);
    if (frame_misses) {
      const Index weighted = (w > 0.0).count();
      summary.weighted_inputs += weighted;
      summary.missed_inputs += weighted;
      for (Index p = 0; p < y.size(); ++p)
        if (w.data()[p] > 0.0) summary.weighted_flux_in += w.data()[p] * y.data()[p] * inv_r2;
      continue;
    }
    const AxisFootprint fy = Footprint(options.kernel, options.pixfrac, r, cy);
    const AxisFootprint fx = Footprint(options.kernel, options.pixfrac, r, cx);
    for (Index Y = 0; Y < lr.rows; ++Y) {
      for (Index X = 0; X < lr.cols; ++X) {
        const double wp = w(Y, X);
        if (!(wp > 0.0)) continue;  // weight 0: the pixel is never read (it may hold NaN or Inf)
        const double d = y(Y, X) * inv_r2;
        ++summary.weighted_inputs;
        summary.weighted_flux_in += wp * d;
        bool landed = false;
        for (std::size_t jy = 0; jy < fy.factor.size(); ++jy) {
          const Index oy = Place(r * Y + fy.first + Index(jy), hr.rows, periodic);
          if (oy < 0 || fy.factor[jy] == 0.0) continue;
          for (std::size_t jx = 0; jx < fx.factor.size(); ++jx) {
            const Index ox = Place(r * X + fx.first + Index(jx), hr.cols, periodic);
            if (ox < 0 || fx.factor[jx] == 0.0) continue;
            const double aw = fy.factor[jy] * fx.factor[jx] * wp;
            num(oy, ox) += aw * d;
            den(oy, ox) += aw;
            landed = true;
            if (plane && aw > 0.0) (*plane)(oy, ox) |= bit;
          }
        }
        if (!landed) ++summary.missed_inputs;
      }
    }
  }

  DrizzleResult result;
  result.image.resize(hr.rows, hr.cols);
  for (Index p = 0; p < num.size(); ++p) {
    const double W = den.data()[p];
    if (W > 0.0) {
      result.image.data()[p] = num.data()[p] / W;
      ++summary.covered_pixels;
      summary.weighted_flux_out += num.data()[p];
    } else {
      result.image.data()[p] = options.fill_value;
      ++summary.filled_pixels;
    }
  }
  result.weight = std::move(den);
  result.context = std::move(context);
  result.frame_count = n_frames;

  summary.method = "drizzle";
  summary.iterations = 0;
  summary.final_cost = 0.0;
  std::ostringstream msg;
  msg << ToString(options.kernel) << " kernel, pixfrac " << options.pixfrac << ", " << n_frames << " frames; "
      << summary.covered_pixels << " of " << hr.size() << " HR pixels covered";
  if (summary.filled_pixels > 0) msg << ", " << summary.filled_pixels << " set to fill_value";
  if (summary.missed_inputs > 0)
    msg << ", " << summary.missed_inputs << " weighted input pixels missed the grid";
  if (summary.covered_pixels == 0) {
    summary.termination = Termination::kFailed;
    msg << "; no HR pixel received positive weight (all inputs masked or off the grid)";
  }
  summary.message = msg.str();
  summary.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  result.summary = std::move(summary);
  return result;
}

}  // namespace aosr
