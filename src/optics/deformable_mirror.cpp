#include "aosr/optics/deformable_mirror.hpp"

#include <algorithm>
#include <cmath>

#include "aosr/core/error.hpp"

namespace aosr {
namespace {

using RowMatrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;


// Validates everything DeformableMirror needs, then returns the active actuators' grid indices.
std::vector<Index> ActiveActuators(Index pupil_n, const PupilGeometry& pupil,
                                   const DeformableMirrorOptions& o) {
  CheckArgument(pupil_n >= 1, "DeformableMirror", "pupil_n", pupil_n, ">= 1");
  std::string why;
  if (!pupil.IsValid(&why)) throw InvalidArgument("DeformableMirror: invalid pupil." + why);
  if (!o.IsValid(&why)) throw InvalidArgument("DeformableMirror: invalid options." + why);
  const int n_act = o.actuators_across;
  const double radius = 0.5 * pupil.diameter_m;
  const double margin = o.active_margin_pitch * o.pitch_m;
  const double outer = radius + margin, inner = pupil.obstruction * radius - margin;
  std::vector<Index> active;
  for (int a = 0; a < n_act; ++a) {
    const double y = (a - 0.5 * (n_act - 1)) * o.pitch_m;
    for (int b = 0; b < n_act; ++b) {
      const double x = (b - 0.5 * (n_act - 1)) * o.pitch_m;
      const double r = std::hypot(x, y);
      // A relative tolerance keeps actuators that sit exactly on the boundary (e.g. margin 0 in Fried
      // geometry) active despite rounding.
      const double tol = 1e-12 * radius;
      if (r <= outer + tol && r >= inner - tol) active.push_back(a * n_act + b);
    }
  }
  if (active.empty()) {
    throw InvalidArgument(
        "DeformableMirror", "options", "no active actuator",
        "an actuator grid (actuators_across, pitch_m, active_margin_pitch) that reaches the pupil");
  }
  return active;
}

}  // namespace

bool DeformableMirrorOptions::IsValid(std::string* why) const {
  if (actuators_across < 2 || actuators_across > 1000) {
    return Fail(why, "actuators_across = " + ToString(actuators_across) + "; allowed: 2 .. 1000");
  }
  if (!(std::isfinite(pitch_m) && pitch_m > 0.0)) {
    return Fail(why, "pitch_m = " + ToString(pitch_m) + "; allowed: > 0 and finite [m]");
  }
  if (!(coupling > 0.0 && coupling < 1.0)) {
    return Fail(why,
                "coupling = " + ToString(coupling) + "; allowed: (0, 1) (influence at the next actuator)");
  }
  if (!(std::isfinite(stroke_m) && stroke_m > 0.0)) {
    return Fail(why, "stroke_m = " + ToString(stroke_m) + "; allowed: > 0 and finite [m of wavefront OPD]");
  }
  if (!(std::isfinite(active_margin_pitch) && active_margin_pitch >= 0.0)) {
    return Fail(why, "active_margin_pitch = " + ToString(active_margin_pitch) + "; allowed: >= 0 and finite");
  }
  return true;
}

bool DmFitOptions::IsValid(std::string* why) const {
  if (!(std::isfinite(regularisation) && regularisation >= 0.0)) {
    return Fail(why, "regularisation = " + ToString(regularisation) + "; allowed: >= 0 and finite");
  }
  return true;
}

DeformableMirror::DeformableMirror(Index pupil_n, const PupilGeometry& pupil,
                                   const DeformableMirrorOptions& options)
    : LinearOperator(pupil_n * pupil_n, static_cast<Index>(ActiveActuators(pupil_n, pupil, options).size()),
                     "DeformableMirror(" + std::to_string(options.actuators_across) + "x" +
                         std::to_string(options.actuators_across) + ", n=" + std::to_string(pupil_n) + ")"),
      pupil_n_(pupil_n),
      pupil_(pupil),
      options_(options),
      n_act_(options.actuators_across),
      active_mask_(Image::Zero(options.actuators_across, options.actuators_across)),
      active_(ActiveActuators(pupil_n, pupil, options)),
      g_(pupil_n, options.actuators_across) {
  for (Index q : active_) active_mask_.data()[q] = 1.0;
  const double log_c = std::log(options_.coupling);
  const double pixel = pupil_.diameter_m / static_cast<double>(pupil_n_);
  for (Index i = 0; i < pupil_n_; ++i) {
    const double u = (static_cast<double>(i) - 0.5 * static_cast<double>(pupil_n_ - 1)) * pixel;
    for (int a = 0; a < n_act_; ++a) {
      const double t = (u - (a - 0.5 * (n_act_ - 1)) * options_.pitch_m) / options_.pitch_m;
      g_(i, a) = std::exp(log_c * t * t);
    }
  }
}

Eigen::Matrix2Xd DeformableMirror::ActuatorPositions() const {
  Eigen::Matrix2Xd p(2, active_.size());
  for (std::size_t q = 0; q < active_.size(); ++q) {
    const Index a = active_[q] / n_act_, b = active_[q] % n_act_;
    p(0, q) = (static_cast<double>(b) - 0.5 * (n_act_ - 1)) * options_.pitch_m;
    p(1, q) = (static_cast<double>(a) - 0.5 * (n_act_ - 1)) * options_.pitch_m;
  }
  return p;
}

double DeformableMirror::Influence(double dx_m, double dy_m) const {
  const double d2 = (dx_m * dx_m + dy_m * dy_m) / (options_.pitch_m * options_.pitch_m);
  return std::exp(std::log(options_.coupling) * d2);
}

Image DeformableMirror::CommandsToGrid(const Eigen::Ref<const Vector>& commands) const {
  CheckArgument(commands.size() == cols(), "DeformableMirror::CommandsToGrid", "commands size",
                commands.size(), std::to_string(cols()) + " (active actuators)");
  Image grid = Image::Zero(n_act_, n_act_);
  for (std::size_t q = 0; q < active_.size(); ++q) grid.data()[active_[q]] = commands[q];
  return grid;
}

Vector DeformableMirror::GridToCommands(const Image& grid) const {
  CheckArgument(grid.rows() == n_act_ && grid.cols() == n_act_, "DeformableMirror::GridToCommands",
                "grid shape", ToString(ShapeOf(grid)),
                std::to_string(n_act_) + "x" + std::to_string(n_act_) + " (the actuator grid)");
  Vector c(active_.size());
  for (std::size_t q = 0; q < active_.size(); ++q) c[q] = grid.data()[active_[q]];
  return c;
}

Image DeformableMirror::Opd(const Eigen::Ref<const Vector>& commands) const {
  CheckArgument(commands.size() == cols(), "DeformableMirror::Opd", "commands size", commands.size(),
                std::to_string(cols()) + " (active actuators)");
  Image opd(pupil_n_, pupil_n_);
  Apply(commands, AsVector(opd));
  return opd;
}

void DeformableMirror::ApplyImpl(ConstRef x, Ref y) const {
  // W = G C G^T with C the N x N command grid (row-major like every image).
  RowMatrix c = RowMatrix::Zero(n_act_, n_act_);
  for (std::size_t q = 0; q < active_.size(); ++q) c.data()[active_[q]] = x[q];
  const RowMatrix c_gt = c * g_.transpose();  // N x n
  Eigen::Map<RowMatrix> w(y.data(), pupil_n_, pupil_n_);
  w.noalias() = g_ * c_gt;
}

void DeformableMirror::ApplyAdjointImpl(ConstRef y, Ref x) const {
  // C' = G^T W G, gathered at the active actuators.
  const Eigen::Map<const RowMatrix> w(y.data(), pupil_n_, pupil_n_);
  const RowMatrix gt_w = g_.transpose() * w;  // N x n
  const RowMatrix c = gt_w * g_;              // N x N
  for (std::size_t q = 0; q < active_.size(); ++q) x[q] = c.data()[active_[q]];
}

ClipSummary DeformableMirror::Clip(Vector* commands) const {
  CheckArgument(commands != nullptr, "DeformableMirror::Clip", "commands", "null", "a command vector");
  CheckArgument(commands->size() == cols(), "DeformableMirror::Clip", "commands size", commands->size(),
                std::to_string(cols()) + " (active actuators)");
  CheckArgument(commands->allFinite(), "DeformableMirror::Clip", "commands", "non-finite values",
                "finite values [m]");
  ClipSummary summary;
  const double s = options_.stroke_m;
  double sum2 = 0.0;
  for (Index q = 0; q < commands->size(); ++q) {
    double& c = (*commands)[q];
    if (std::abs(c) <= s) continue;
    const double excess = std::abs(c) - s;
    ++summary.clipped;
    sum2 += excess * excess;
    summary.max_excess_m = std::max(summary.max_excess_m, excess);
    c = c > 0.0 ? s : -s;
  }
  summary.clipped_rms_m = std::sqrt(sum2 / static_cast<double>(commands->size()));
  return summary;
}

DmFitter::DmFitter(DeformableMirrorPtr dm, const Image& weights, const DmFitOptions& options)
    : dm_(std::move(dm)), weights_(weights) {
  CheckArgument(dm_ != nullptr, "DmFitter", "dm", "null", "a deformable mirror");
  const Index n = dm_->pupil_n();
  CheckArgument(weights.rows() == n && weights.cols() == n, "DmFitter", "weights shape",
                ToString(ShapeOf(weights)),
                std::to_string(n) + "x" + std::to_string(n) + " (the DM's pupil grid)");
  CheckArgument(weights.isFinite().all() && (weights >= 0.0).all(), "DmFitter", "weights",
                "negative or non-finite values", "finite values >= 0");
  CheckArgument(weights.sum() > 0.0, "DmFitter", "weights", "all zero", "some pixel > 0");
  std::string why;
  if (!options.IsValid(&why)) throw InvalidArgument("DmFitter: invalid options." + why);

  // Separable assembly of H^T A H over the full N x N grid (see the header), then the active block.
  const Eigen::MatrixXd& g = dm_->InfluenceFactor();
  const int big_n = dm_->options().actuators_across;
  const Index pairs = static_cast<Index>(big_n) * big_n;
  // P(i, a N + a') = G(i, a) G(i, a'): products of the factor's columns (n x N^2).
  Eigen::MatrixXd p(n, pairs);
  for (int a = 0; a < big_n; ++a) {
    for (int a2 = 0; a2 < big_n; ++a2) p.col(a * big_n + a2) = g.col(a).cwiseProduct(g.col(a2));
  }
  // T = P^T A: T(a N + a', k) = sum_i G(i,a) G(i,a') A(i,k); then M_full = T P (x uses the same factor).
  const Eigen::MatrixXd t = p.transpose() * weights.matrix();
  const Eigen::MatrixXd m_full = t * p;  // (a N + a', b N + b')
  const std::vector<Index>& act = dm_->ActiveIndices();
  const Index na = static_cast<Index>(act.size());
  Eigen::MatrixXd normal(na, na);
  for (Index r = 0; r < na; ++r) {
    const Index a = act[r] / big_n, b = act[r] % big_n;
    for (Index s = 0; s < na; ++s) {
      const Index a2 = act[s] / big_n, b2 = act[s] % big_n;
      normal(r, s) = m_full(a * big_n + a2, b * big_n + b2);
    }
  }
  mu_ = options.regularisation * normal.trace() / static_cast<double>(na);
  normal.diagonal().array() += mu_;
  llt_.compute(normal);
  // Cholesky reports failure on an indefinite matrix; a numerically singular one can slip through with a tiny
  // pivot, so the reciprocal condition estimate is checked too.
  if (llt_.info() != Eigen::Success || !(llt_.rcond() > 1e-15)) {
    throw InvalidArgument("DmFitter", "options.regularisation", ToString(options.regularisation),
                          "a value > 0 large enough to make the normal matrix positive definite");
  }
}

Vector DmFitter::Fit(const Image& opd_m) const {
  const Index n = dm_->pupil_n();
  CheckArgument(opd_m.rows() == n && opd_m.cols() == n, "DmFitter::Fit", "opd_m shape",
                ToString(ShapeOf(opd_m)),
                std::to_string(n) + "x" + std::to_string(n) + " (the DM's pupil grid)");
  Image weighted(n, n);
  for (Index p = 0; p < weighted.size(); ++p) {
    const double a = weights_.data()[p];
    if (a > 0.0) {
      const double w = opd_m.data()[p];
      CheckArgument(std::isfinite(w), "DmFitter::Fit", "opd_m", w, "finite values where the weights are > 0");
      weighted.data()[p] = a * w;
    } else {
      weighted.data()[p] = 0.0;
    }
  }
  const Vector rhs = dm_->ApplyAdjoint(AsVector(weighted));
  return llt_.solve(rhs);
}

Image DmFitter::Residual(const Image& opd_m) const {
  const Vector c = Fit(opd_m);
  return opd_m - dm_->Opd(c);
}

}  // namespace aosr
