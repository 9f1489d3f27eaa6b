#include "aosr/core/levenberg_marquardt.hpp"

#include <algorithm>
#include <cmath>

#include "aosr/core/error.hpp"

namespace aosr {

LevenbergMarquardtResult LevenbergMarquardt(const LeastSquaresResiduals& residuals, const Eigen::VectorXd& theta0,
                                            const LeastSquaresProjection& project,
                                            const LevenbergMarquardtOptions& options) {
  CheckArgument(options.max_iterations >= 0, "LevenbergMarquardt", "options.max_iterations", options.max_iterations,
                ">= 0");
  CheckArgument(options.tolerance >= 0, "LevenbergMarquardt", "options.tolerance", options.tolerance, ">= 0");
  LevenbergMarquardtResult out;
  out.theta = theta0;
  Eigen::MatrixXd jac;
  Eigen::VectorXd res = residuals(out.theta, &jac);
  double cost = 0.5 * res.squaredNorm(), mu = 1e-3;
  for (int it = 0; it < options.max_iterations; ++it) {
    out.iterations = it + 1;
    const Eigen::MatrixXd jtj = jac.transpose() * jac;
    const Eigen::VectorXd g = jac.transpose() * res;
    bool accepted = false;
    for (int tries = 0; tries < 40 && !accepted; ++tries) {
      Eigen::MatrixXd a = jtj;
      for (Eigen::Index j = 0; j < a.rows(); ++j) a(j, j) += mu * std::max(jtj(j, j), 1e-12);
      const Eigen::VectorXd step = a.ldlt().solve(-g);
      const Eigen::VectorXd trial = project ? project(out.theta + step) : Eigen::VectorXd(out.theta + step);
      Eigen::MatrixXd trial_jac;
      const Eigen::VectorXd trial_res = residuals(trial, &trial_jac);
      const double trial_cost = 0.5 * trial_res.squaredNorm();
      if (std::isfinite(trial_cost) && trial_cost <= cost) {
        out.converged = cost - trial_cost <= options.tolerance * std::max(cost, 1e-300) ||
                        (trial - out.theta).norm() < 1e-12;
        out.theta = trial, res = trial_res, jac = trial_jac, cost = trial_cost;
        accepted = true;
        mu = std::max(mu / 3, 1e-12);
      } else {
        mu *= 4;
      }
    }
    if (!accepted) out.converged = true;  // no step decreases the cost: a minimum to the damping's resolution
    if (out.converged) break;
  }
  out.cost = cost;
  return out;
}

}  // namespace aosr
