// Small dense non-linear least squares, min_θ ½ ||r(θ)||², by Levenberg-Marquardt (Marquardt 1963, SIAM J. Appl.
// Math. 11, 431): each step solves (JᵀJ + μ diag(JᵀJ)) δ = −Jᵀr (a diagonal floor of 1e-12 keeps it definite), the
// trial point is projected onto the feasible set (box bounds of the caller; a projected step, not an active-set
// method, so on an active bound it converges slowly), and is accepted when its cost is finite
// and not larger (then μ ← max(μ/3, 1e-12)); otherwise μ ← 4μ, at most 40 tries per iteration. Converged when an
// accepted step lowers the cost by at most tolerance × cost or moves θ by less than 1e-12, or when no try decreases
// the cost (a minimum to the damping's resolution). For the few-parameter spectrum fits of the design and solvers
// layers (power_spectrum_fit.hpp, frame_power_spectrum.hpp); the problems are tiny, so dense and serial.
#pragma once

#include <functional>

#include <Eigen/Dense>

namespace aosr {

// r(θ) and, when `jacobian` is not null, J = ∂r/∂θ (rows: residuals, columns: parameters).
using LeastSquaresResiduals = std::function<Eigen::VectorXd(const Eigen::VectorXd& theta, Eigen::MatrixXd* jacobian)>;
// The projection of a trial point onto the feasible set (e.g. clamping to bounds); identity if none.
using LeastSquaresProjection = std::function<Eigen::VectorXd(Eigen::VectorXd theta)>;

struct LevenbergMarquardtOptions {
  int max_iterations = 100;  // >= 0
  double tolerance = 1e-10;  // relative cost decrease that ends the fit, >= 0
};

struct LevenbergMarquardtResult {
  Eigen::VectorXd theta;  // the last accepted point (the start if none was)
  double cost = 0;        // ½ ||r(theta)||²
  int iterations = 0;     // iterations run
  bool converged = false;
};

// theta0 must be feasible and give a finite cost (the caller's start); InvalidArgument for negative options.
LevenbergMarquardtResult LevenbergMarquardt(const LeastSquaresResiduals& residuals, const Eigen::VectorXd& theta0,
                                            const LeastSquaresProjection& project,
                                            const LevenbergMarquardtOptions& options);

}  // namespace aosr
