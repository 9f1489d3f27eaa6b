// The exact transfer of the linear reconstructors (linear_transfer.hpp): Tikhonov's per-bin response R(u) of
// (1), its diagonal and off-diagonal column norms on the HR grid, and the curves along a direction or radially
// averaged that a slanted edge of the output reads.
#include "aosr/solvers/linear_transfer.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>

#include "aosr/core/error.hpp"
#include "aosr/core/parallel.hpp"

namespace aosr {

namespace {

// Directions of the radial average over [0, π) (Hermitian symmetry gives the other half).
constexpr int kRadialDirections = 180;
// A bin's G(u) whose Cholesky factor has a reciprocal condition estimate below this is solved by the SVD
// (minimum-norm) path instead.
constexpr double kTransferRcondFloor = 1e-12;

double TransferSinc(double z) {
  if (std::abs(z) < 1e-12) return 1.0;
  return std::sin(kPi * z) / (kPi * z);
}

// The frequencies a curve is evaluated at.
std::vector<double> TransferCurveFrequencies(const TransferCurveOptions& o) {
  if (!o.frequencies.empty()) return o.frequencies;
  std::vector<double> f;
  const Index n = Index(std::floor(o.curve_max / o.curve_step + 1e-9));
  for (Index i = 0; i <= n; ++i) f.push_back(double(i) * o.curve_step);
  return f;
}

void CheckTransferCurveOptions(const char* function, const TransferCurveOptions& o) {
  std::string why;
  if (!o.IsValid(&why)) throw InvalidArgument(std::string(function) + ": options." + why);
}

// Bilinear interpolation of a periodic grid at continuous frequency (fy, fx) in cycles per HR px.
template <class Grid>
typename Grid::Scalar InterpolatePeriodic(const Grid& g, double fy, double fx) {
  const Index my = g.rows(), mx = g.cols();
  double gy = fy * double(my), gx = fx * double(mx);
  gy -= std::floor(gy / double(my)) * double(my);
  gx -= std::floor(gx / double(mx)) * double(mx);
  const Index y0 = std::min(my - 1, Index(std::floor(gy))), x0 = std::min(mx - 1, Index(std::floor(gx)));
  const double ty = gy - double(y0), tx = gx - double(x0);
  const Index y1 = (y0 + 1) % my, x1 = (x0 + 1) % mx;
  return (1 - ty) * ((1 - tx) * g(y0, x0) + tx * g(y0, x1)) + ty * ((1 - tx) * g(y1, x0) + tx * g(y1, x1));
}

// The curve from a function value(fy, fx) -> (|T|, alias) (alias < 0: not known).
template <class F>
TransferCurve MakeTransferCurve(const TransferCurveOptions& o, double dc, const F& value) {
  TransferCurve c;
  c.radial = o.radial;
  const double norm = std::hypot(o.direction_y, o.direction_x);
  c.direction_y = o.direction_y / norm;
  c.direction_x = o.direction_x / norm;
  c.dc = dc;
  const double scale = o.normalise_dc ? (dc > 0 ? 1.0 / dc : 0.0) : 1.0;
  c.frequency = TransferCurveFrequencies(o);
  bool with_alias = true;
  for (double f : c.frequency) {
    const int directions = o.radial && f > 0 ? kRadialDirections : 1;
    double m = 0, a = 0;
    for (int d = 0; d < directions; ++d) {
      double ny = c.direction_y, nx = c.direction_x;
      if (o.radial) {
        const double phi = kPi * double(d) / double(kRadialDirections);
        ny = std::sin(phi);
        nx = std::cos(phi);
      }
      const double fy = f * ny, fx = f * nx;
      const double box = o.hr_pixel_box ? std::abs(TransferSinc(fy) * TransferSinc(fx)) : 1.0;
      const auto [t, al] = value(fy, fx);
      m += t * box;
      if (al < 0) with_alias = false;
      a += al * box;
    }
    c.mtf.push_back(m / directions * scale);
    c.alias.push_back(a / directions * scale);
  }
  if (!with_alias) c.alias.clear();
  return c;
}

}  // namespace

bool TransferCurveOptions::IsValid(std::string* why) const {
  auto fail = [why](const std::string& m) {
    if (why) *why = m;
    return false;
  };
  if (!radial && !(std::isfinite(direction_y) && std::isfinite(direction_x) && std::hypot(direction_y, direction_x) > 0))
    return fail("direction = (" + ToString(direction_y) + ", " + ToString(direction_x) +
                "): must be a finite non-zero vector (f_y, f_x)");
  if (!(curve_max > 0 && curve_max <= 1.0)) return fail("curve_max = " + ToString(curve_max) + ": must be in (0, 1]");
  if (radial && curve_max > 0.5)
    return fail("curve_max = " + ToString(curve_max) + ": the radial average stops at the HR Nyquist 0.5");
  if (!(curve_step > 0 && curve_step <= curve_max))
    return fail("curve_step = " + ToString(curve_step) + ": must be in (0, curve_max = " + ToString(curve_max) + "]");
  for (double f : frequencies)
    if (!(f >= 0 && f <= curve_max))
      return fail("frequencies: " + ToString(f) + " is outside [0, curve_max = " + ToString(curve_max) + "]");
  return true;
}

void SetDirectionFromEdge(const SlantedEdgeMtf& edge, TransferCurveOptions* options) {
  if (options == nullptr) throw InvalidArgument("SetDirectionFromEdge", "options", "null", "a TransferCurveOptions");
  if (!std::isfinite(edge.angle_deg))
    throw InvalidArgument("SetDirectionFromEdge", "edge.angle_deg", ToString(edge.angle_deg), "a finite angle");
  // MeasureSlantedEdgeMtf fits x = a + b y across a near-vertical edge (y = a + b x for a near-horizontal one,
  // read transposed), b = tan(angle): the normal is ∇(x − b y) = (f_y, f_x) ∝ (−b, 1), transposed (1, −b).
  const double b = std::tan(edge.angle_deg * kPi / 180.0);
  const double n = std::sqrt(1 + b * b);
  options->radial = false;
  if (edge.vertical) {
    options->direction_y = -b / n;
    options->direction_x = 1 / n;
  } else {
    options->direction_y = 1 / n;
    options->direction_x = -b / n;
  }
}

TransferGrid TikhonovTransferGrid(const MultiFrameModel& model, const std::vector<double>& frame_weights,
                                  const TikhonovOptions& prior, double lambda) {
  constexpr const char* kFn = "TikhonovTransferGrid";
  const int n = model.frames();
  if (!frame_weights.empty() && int(frame_weights.size()) != n)
    throw InvalidArgument(kFn, "frame_weights", std::to_string(frame_weights.size()) + " values",
                          "one per frame (" + std::to_string(n) + ") or none");
  std::vector<double> w(n, 1.0);
  double w_sum = 0;
  for (int i = 0; i < n; ++i) {
    if (!frame_weights.empty()) w[i] = frame_weights[i];
    if (!(std::isfinite(w[i]) && w[i] >= 0))
      throw InvalidArgument(kFn, "frame_weights[" + std::to_string(i) + "]", ToString(w[i]), "finite and >= 0");
    w_sum += w[i];
  }
  if (!(w_sum > 0)) throw InvalidArgument(kFn, "frame_weights", "all 0", "at least one frame of positive weight");
  if (!(std::isfinite(lambda) && lambda >= 0)) throw InvalidArgument(kFn, "lambda", ToString(lambda), "finite and >= 0");
  if (prior.prior == TikhonovPrior::kFitted)
    throw InvalidArgument(kFn, "prior", "fitted",
                          "the spectrum ReconstructTikhonov fitted, as prior power-spectrum with object_power_spectrum "
                          "= PowerSpectrumGrid(summary.fitted_spectrum, hr) (the options do not hold the fit)");
  TikhonovOptions o = prior;
  o.lambda_rule = TikhonovLambdaRule::kFixed;
  o.lambda = lambda;
  {
    std::string why;
    if (!o.IsValid(&why)) throw InvalidArgument(std::string(kFn) + ": prior options: " + why);
  }
  const Shape hr = model.hr_shape(), lr = model.lr_shape();
  if (o.object_power_spectrum.size() > 0 && ShapeOf(o.object_power_spectrum) != hr)
    throw InvalidArgument(kFn, "prior.object_power_spectrum shape", ToString(ShapeOf(o.object_power_spectrum)),
                          "the HR grid " + ToString(hr));
  const int r = model.r(), r2 = r * r;
  const double wp = lambda / double(r2);
  Eigen::VectorXd sqrt_w(n);
  for (int i = 0; i < n; ++i) sqrt_w[i] = std::sqrt(w[i]);

  // The rank floor of the minimum-norm path: 1e-9 x the largest weighted column norm over all bins (the DC
  // column, √Σw, for unit-sum PSFs), as the solver's rank_tolerance scales its floor by the largest singular value.
  double largest = 0;
  for (Index uy = 0; uy < lr.rows; ++uy)
    for (Index ux = 0; ux < lr.cols; ++ux) {
      const Eigen::MatrixXcd a = sqrt_w.asDiagonal() * model.AliasedSystem(uy, ux);
      largest = std::max(largest, a.colwise().norm().maxCoeff());
    }
  const double floor = o.rank_tolerance * largest;

  TransferGrid g;
  g.transfer = ComplexImage::Zero(hr.rows, hr.cols);
  g.alias = Image::Zero(hr.rows, hr.cols);
  ParallelFor(lr.rows, [&](Index uy) {
    for (Index ux = 0; ux < lr.cols; ++ux) {
      const Eigen::MatrixXcd a = sqrt_w.asDiagonal() * model.AliasedSystem(uy, ux);  // W^½ A, N x r²
      const Eigen::MatrixXcd data = a.adjoint() * a;                                  // Aᴴ W A
      Eigen::VectorXd p(r2);
      for (int k = 0; k < r2; ++k)
        p[k] = TikhonovPriorSymbol(o, hr, uy + (k / r) * lr.rows, ux + (k % r) * lr.cols);
      Eigen::MatrixXcd resp;
      bool solved = false;
      if (wp > 0) {
        Eigen::MatrixXcd gm = data;
        gm.diagonal() += (wp * p).cast<Complex>();
        Eigen::LLT<Eigen::MatrixXcd> llt(gm);
        if (llt.info() == Eigen::Success && llt.rcond() > kTransferRcondFloor) {
          resp = llt.solve(data);
          solved = true;
        }
      }
      if (!solved) {
        // Minimum norm: x = pinv(S) [W^½ y; 0], S = [W^½ A; √(λ/r²) P^½]; noise-free y = A x gives R = pinv(S) [W^½A; 0].
        Eigen::MatrixXcd s(n + r2, r2), rhs = Eigen::MatrixXcd::Zero(n + r2, r2);
        s.topRows(n) = a;
        s.bottomRows(r2) = (wp * p).cwiseSqrt().cast<Complex>().asDiagonal();
        rhs.topRows(n) = a;
        Eigen::JacobiSVD<Eigen::MatrixXcd> svd(s, Eigen::ComputeThinU | Eigen::ComputeThinV);
        const Eigen::VectorXd& sv = svd.singularValues();
        Eigen::VectorXd inv = Eigen::VectorXd::Zero(sv.size());
        for (Index j = 0; j < sv.size(); ++j)
          if (sv[j] > floor) inv[j] = 1.0 / sv[j];
        resp = svd.matrixV() * inv.cast<Complex>().asDiagonal() * svd.matrixU().adjoint() * rhs;
      }
      for (int k = 0; k < r2; ++k) {
        const Index fy = uy + (k / r) * lr.rows, fx = ux + (k % r) * lr.cols;
        g.transfer(fy, fx) = resp(k, k);
        g.alias(fy, fx) = std::sqrt(std::max(0.0, resp.col(k).squaredNorm() - std::norm(resp(k, k))));
      }
    }
  });
  return g;
}

TransferCurve GridTransferCurve(const TransferGrid& grid, const TransferCurveOptions& options) {
  constexpr const char* kFn = "GridTransferCurve";
  CheckTransferCurveOptions(kFn, options);
  if (grid.transfer.size() == 0 || ShapeOf(grid.alias) != ShapeOf(grid.transfer))
    throw InvalidArgument(kFn, "grid", ToString(ShapeOf(grid.transfer)) + " transfer, " + ToString(ShapeOf(grid.alias)) + " alias",
                          "a non-empty transfer and an alias grid of its shape (TikhonovTransferGrid)");
  if (!grid.transfer.isFinite().all() || !grid.alias.isFinite().all())
    throw InvalidArgument(kFn, "grid", "non-finite values", "finite transfer and alias");
  const double dc = std::abs(grid.transfer(0, 0));
  return MakeTransferCurve(options, dc, [&](double fy, double fx) {
    return std::pair<double, double>(std::abs(InterpolatePeriodic(grid.transfer, fy, fx)), InterpolatePeriodic(grid.alias, fy, fx));
  });
}

TransferCurve KernelTransferCurve(const Image& kernel, const TransferCurveOptions& options) {
  constexpr const char* kFn = "KernelTransferCurve";
  CheckTransferCurveOptions(kFn, options);
  if (kernel.size() == 0) throw InvalidArgument(kFn, "kernel", "empty", "a centred kernel of size >= 1");
  if (!kernel.isFinite().all()) throw InvalidArgument(kFn, "kernel", "non-finite values", "finite values");
  const double sum = kernel.sum();
  if (!(std::abs(sum) > 0)) throw InvalidArgument(kFn, "kernel sum", ToString(sum), "non-zero (a PSF)");
  const Index ky = kernel.rows(), kx = kernel.cols();
  ComplexVector ey(ky), ex(kx);
  return MakeTransferCurve(options, std::abs(sum), [&](double fy, double fx) {
    // Σ_p k[p] exp(−2πi f·(p − c)), separably; the centre c only sets the phase.
    for (Index y = 0; y < ky; ++y) ey[y] = std::polar(1.0, -kTwoPi * fy * double(y - ky / 2));
    for (Index x = 0; x < kx; ++x) ex[x] = std::polar(1.0, -kTwoPi * fx * double(x - kx / 2));
    Complex t = 0;
    for (Index y = 0; y < ky; ++y) {
      Complex row = 0;
      for (Index x = 0; x < kx; ++x) row += kernel(y, x) * ex[x];
      t += ey[y] * row;
    }
    return std::pair<double, double>(std::abs(t), -1.0);
  });
}

TransferCurve TikhonovTransferCurve(const ReconstructionProblem& problem, const TikhonovOptions& prior, double lambda,
                                    const TransferCurveOptions& options, bool* exact) {
  constexpr const char* kFn = "TikhonovTransferCurve";
  problem.Validate(kFn);
  CheckTransferCurveOptions(kFn, options);
  std::vector<double> w(problem.frame_count());
  bool uniform = true;
  for (int i = 0; i < problem.frame_count(); ++i) {
    const Image wi = problem.Weight(i);
    w[i] = wi.mean();
    if (wi.maxCoeff() != wi.minCoeff()) uniform = false;
  }
  if (exact) *exact = uniform;
  return GridTransferCurve(TikhonovTransferGrid(*problem.model, w, prior, lambda), options);
}

}  // namespace aosr
