#include "aosr/solvers/registration.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <memory>

#include "aosr/core/error.hpp"
#include "aosr/core/metrics.hpp"
#include "aosr/core/operators.hpp"

namespace aosr {
namespace {

constexpr const char* kRegistrationFn = "RegisterFrames";

std::string FrameName(int i) { return "frame " + std::to_string(i); }

}  // namespace

RegistrationAnchor ParseRegistrationAnchor(const std::string& name) {
  if (name == "mean") return RegistrationAnchor::kCommandedMean;
  if (name == "frame0") return RegistrationAnchor::kFrameZero;
  throw InvalidArgument("ParseRegistrationAnchor", "anchor", name, "mean | frame0");
}

const char* ToString(RegistrationAnchor a) {
  return a == RegistrationAnchor::kCommandedMean ? "mean" : "frame0";
}

bool RegistrationOptions::IsValid(std::string* why) const {
  auto fail = [why](const std::string& m) {
    if (why) *why = m;
    return false;
  };
  if (!(search_range_camera_px > 0 && search_range_camera_px <= 4))
    return fail("search_range_camera_px = " + ToString(search_range_camera_px) + ", allowed (0, 4]");
  if (outer_iterations < 1 || outer_iterations > 50)
    return fail("outer_iterations = " + std::to_string(outer_iterations) + ", allowed [1, 50]");
  if (newton_iterations < 1 || newton_iterations > 100)
    return fail("newton_iterations = " + std::to_string(newton_iterations) + ", allowed [1, 100]");
  if (!(tolerance_camera_px > 0 && tolerance_camera_px <= 0.1))
    return fail("tolerance_camera_px = " + ToString(tolerance_camera_px) + ", allowed (0, 0.1]");
  std::string w;
  if (!reconstruction.IsValid(&w)) return fail("reconstruction." + w);
  return true;
}

ReconstructionProblem ShiftProblemFrames(const ReconstructionProblem& p, const std::vector<FrameOffset>& correction) {
  const int n = p.frame_count();
  CheckArgument(p.model != nullptr, "ShiftProblemFrames", "problem.model", "null", "a model");
  CheckArgument(int(correction.size()) == n && p.model->frames() == n, "ShiftProblemFrames", "correction count",
                correction.size(), "one per frame (" + std::to_string(n) + ")");
  const Shape hr = p.model->hr_shape();
  std::vector<ComplexImage> otfs;
  ReconstructionProblem out = p;
  if (out.offsets.empty()) out.offsets.assign(n, FrameOffset{});
  for (int i = 0; i < n; ++i) {
    const FrameOffset& c = correction[i];
    CheckArgument(std::isfinite(c.dy) && std::isfinite(c.dx), "ShiftProblemFrames",
                  "correction[" + std::to_string(i) + "]", ToString(c.dy) + ", " + ToString(c.dx), "finite");
    otfs.push_back(c.dy == 0 && c.dx == 0 ? p.model->otf(i) : ComplexImage(p.model->otf(i) * ShiftTransfer(hr, c.dy, c.dx)));
    out.offsets[i].dy += c.dy;
    out.offsets[i].dx += c.dx;
  }
  out.model = std::make_shared<const MultiFrameModel>(hr, p.model->r(), std::move(otfs));
  return out;
}

RegistrationResult RegisterFrames(const ReconstructionProblem& problem, const RegistrationOptions& options) {
  const auto t0 = std::chrono::steady_clock::now();
  std::string why;
  if (!options.IsValid(&why)) throw InvalidArgument(kRegistrationFn, "options", why, "valid RegistrationOptions");
  problem.Validate(kRegistrationFn);
  const int n = problem.frame_count();
  const Shape hr = problem.model->hr_shape();
  const int r = problem.model->r();
  const double range_hr = options.search_range_camera_px * r;
  const double tol_hr = options.tolerance_camera_px * r;
  const ImageStack frames = problem.CleanFrames();
  ImageStack sqrt_w;
  for (int i = 0; i < n; ++i) sqrt_w.push_back(problem.Weight(i).sqrt());
  const OperatorPtr decimate = Decimate(hr, r);
  const Shape lr = problem.model->lr_shape();
  auto down = [&](const Image& z) { return ToImage(decimate->Apply(AsVector(z)), lr); };

  RegistrationResult out;
  out.commanded = problem.offsets.empty() ? std::vector<FrameOffset>(n) : problem.offsets;
  std::vector<FrameOffset> delta(n);
  out.sigma_hr_px.assign(n, 0.0);
  out.residual_rms.assign(n, 0.0);
  constexpr double kEps = 0.05;  // HR px: central-difference step of the Fourier shift (the error is O(ε²))

  for (int round = 0; round < options.outer_iterations; ++round) {
    const ReconstructionProblem current = ShiftProblemFrames(problem, delta);
    const Image x = ReconstructTikhonov(current, options.reconstruction).image;
    std::vector<FrameOffset> inc(n);
    for (int i = 0; i < n; ++i) {
      const Image z = ToImage(PeriodicConvolution(hr, current.model->otf(i))->Apply(AsVector(x)), hr);
      const Image& w = sqrt_w[i];
      const Index used = (w > 0).count();
      CheckArgument(used > 2, kRegistrationFn, FrameName(i) + " weighted pixels", used,
                    "more than 2 (a frame with no usable pixel has no offset to estimate)");
      double dy = 0, dx = 0;
      if (round == 0) {
        // Coarse: upsampled cross-correlation against the prediction, masked as the frame is.
        const Image pred = (down(z) * (w > 0).cast<double>()).eval();
        ImageOffset c;
        try {
          c = MeasureImageOffset(pred, frames[i]);
        } catch (const InvalidArgument& e) {
          throw InvalidArgument(kRegistrationFn, FrameName(i), "no correlation peak",
                                "a frame and a reconstruction with structure to register on (" + std::string(e.what()) + ")");
        }
        dy = c.dy * r;
        dx = c.dx * r;
        if (std::max(std::abs(dy), std::abs(dx)) > range_hr)
          throw InvalidArgument(kRegistrationFn, FrameName(i) + " offset from the commanded one (cross-correlation)",
                                ToString(dy / r) + ", " + ToString(dx / r) + " camera px",
                                "within the search range ±" + ToString(options.search_range_camera_px) +
                                    " camera px (RegistrationOptions::search_range_camera_px, `aosr reconstruct --registration-range`)");
      }
      // Refined: Gauss-Newton on ‖√w (y − D S_δ z)‖².
      const Image gy = (FourierShiftImage(z, kEps, 0) - FourierShiftImage(z, -kEps, 0)) / (2 * kEps);
      const Image gx = (FourierShiftImage(z, 0, kEps) - FourierShiftImage(z, 0, -kEps)) / (2 * kEps);
      Eigen::Matrix2d jtj = Eigen::Matrix2d::Zero();  // newton_iterations >= 1 sets it
      double rss = 0;
      for (int it = 0; it < options.newton_iterations; ++it) {
        const Image res = (w * (frames[i] - down(FourierShiftImage(z, dy, dx)))).eval();
        const Image jy = (w * down(FourierShiftImage(gy, dy, dx))).eval();
        const Image jx = (w * down(FourierShiftImage(gx, dy, dx))).eval();
        jtj << (jy * jy).sum(), (jy * jx).sum(), (jy * jx).sum(), (jx * jx).sum();
        const Eigen::Vector2d g((jy * res).sum(), (jx * res).sum());
        rss = (res * res).sum();
        const double det = jtj.determinant(), tr = jtj.trace();
        if (!(tr > 0) || !(det > 1e-10 * tr * tr))
          throw InvalidArgument(kRegistrationFn, FrameName(i), "a singular registration system (det JtWJ = " + ToString(det) + ")",
                                "a frame with structure along both axes to register on");
        const Eigen::Vector2d step = jtj.ldlt().solve(g);
        dy += step(0);
        dx += step(1);
        if (!std::isfinite(dy) || !std::isfinite(dx) || std::max(std::abs(dy), std::abs(dx)) > range_hr)
          throw InvalidArgument(kRegistrationFn, FrameName(i) + " offset from the commanded one (refinement)",
                                ToString(dy / r) + ", " + ToString(dx / r) + " camera px",
                                "within the search range ±" + ToString(options.search_range_camera_px) +
                                    " camera px (RegistrationOptions::search_range_camera_px, `aosr reconstruct --registration-range`)");
        if (std::max(std::abs(step(0)), std::abs(step(1))) < 0.1 * tol_hr) break;
      }
      const double s2 = rss / double(std::max<Index>(used - 2, 1));
      const Eigen::Matrix2d cov = s2 * jtj.inverse();
      const double sigma = std::sqrt(std::max(cov(0, 0), cov(1, 1)));
      if (!(sigma <= range_hr))
        throw InvalidArgument(kRegistrationFn, FrameName(i) + " offset standard error", ToString(sigma / r) + " camera px",
                              "below the search range ±" + ToString(options.search_range_camera_px) +
                                  " camera px: the frame has too little structure (or too much noise) to register");
      out.sigma_hr_px[i] = sigma;
      out.residual_rms[i] = std::sqrt(rss / double(used));
      inc[i] = {dy, dx};
    }
    // Anchor: a common shift of every frame is a shift of the scene, not in the data.
    FrameOffset ref;
    if (options.anchor == RegistrationAnchor::kFrameZero) {
      ref = inc[0];
    } else {
      for (const FrameOffset& d : inc) ref.dy += d.dy / n, ref.dx += d.dx / n;
    }
    double moved = 0;
    for (int i = 0; i < n; ++i) {
      const double ddy = inc[i].dy - ref.dy, ddx = inc[i].dx - ref.dx;
      delta[i].dy += ddy;
      delta[i].dx += ddx;
      moved = std::max({moved, std::abs(ddy), std::abs(ddx)});
      if (std::max(std::abs(delta[i].dy), std::abs(delta[i].dx)) > range_hr)
        throw InvalidArgument(kRegistrationFn, FrameName(i) + " offset from the commanded one",
                              ToString(delta[i].dy / r) + ", " + ToString(delta[i].dx / r) + " camera px",
                              "within the search range ±" + ToString(options.search_range_camera_px) + " camera px");
    }
    out.rounds = round + 1;
    if (moved <= tol_hr) {
      out.converged = true;
      break;
    }
  }
  out.correction = delta;
  for (int i = 0; i < n; ++i)
    out.estimated.push_back({out.commanded[i].dy + delta[i].dy, out.commanded[i].dx + delta[i].dx});
  out.problem = ShiftProblemFrames(problem, delta);
  out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return out;
}

}  // namespace aosr
