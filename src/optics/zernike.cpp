#include "aosr/optics/zernike.hpp"

#include <Eigen/QR>
#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <string>
#include <vector>

#include "aosr/core/error.hpp"
#include "aosr/optics/pupil.hpp"

namespace aosr {
namespace {

// Normalisation N_n^m (Noll 1976): RMS 1 over the unit disk.
double NollNorm(const ZernikeNM& nm) {
  return nm.m == 0 ? std::sqrt(nm.n + 1.0) : std::sqrt(2.0 * (nm.n + 1.0));
}

void CheckNoll(int j, const char* function) { CheckArgument(j >= 1, function, "j", j, ">= 1 (Noll index)"); }

void CheckObstruction(double obstruction, const char* function) {
  CheckArgument(obstruction >= 0.0 && obstruction < 1.0, function, "obstruction", obstruction,
                "[0, 1) (obstruction diameter / D)");
}

// Kintner's recurrence over n = m, m+2, ..., n_max at fixed m. Calls out(n, R_n^m(rho)) for each n.
template <typename Out>
void RadialSeries(int m, int n_max, double rho, Out out) {
  const double rho2 = rho * rho;
  double r_prev = std::pow(rho, m);  // R_m^m
  out(m, r_prev);
  if (m + 2 > n_max) return;
  double r_cur = (m + 2.0) * r_prev * rho2 - (m + 1.0) * r_prev;  // R_{m+2}^m
  out(m + 2, r_cur);
  for (int n = m + 4; n <= n_max; n += 2) {
    const double dn = n, dm = m;
    const double k1 = (dn + dm) * (dn - dm) * (dn - 2.0) / 2.0;
    const double k2 = 2.0 * dn * (dn - 1.0) * (dn - 2.0);
    const double k3 = -dm * dm * (dn - 1.0) - dn * (dn - 1.0) * (dn - 2.0);
    const double k4 = -dn * (dn + dm - 2.0) * (dn - dm - 2.0) / 2.0;
    const double r_next = ((k2 * rho2 + k3) * r_cur + k4 * r_prev) / k1;
    r_prev = r_cur;
    r_cur = r_next;
    out(n, r_cur);
  }
}

// Evaluates Z_1..Z_J at one point with O(J) work: one radial recurrence per |m| and the harmonics
// cos(m theta), sin(m theta) by the angle-addition recurrence (no trigonometric calls per mode).
class ModeEvaluator {
 public:
  explicit ModeEvaluator(int J) : modes_(J), norms_(J) {
    for (int j = 1; j <= J; ++j) {
      modes_[j - 1] = NollToNM(j);
      norms_[j - 1] = NollNorm(modes_[j - 1]);
      n_max_ = std::max(n_max_, modes_[j - 1].n);
    }
    radial_.resize(static_cast<std::size_t>(n_max_ + 1) * (n_max_ + 1));
    cos_.resize(n_max_ + 1);
    sin_.resize(n_max_ + 1);
  }

  // (x, y): normalised Cartesian coordinates (rho = sqrt(x^2+y^2)). Writes J values to out[0..J-1].
  void Evaluate(double x, double y, double* out) {
    const double rho = std::sqrt(x * x + y * y);
    const double c1 = rho > 0.0 ? x / rho : 1.0;
    const double s1 = rho > 0.0 ? y / rho : 0.0;
    cos_[0] = 1.0;
    sin_[0] = 0.0;
    for (int m = 1; m <= n_max_; ++m) {
      cos_[m] = cos_[m - 1] * c1 - sin_[m - 1] * s1;
      sin_[m] = sin_[m - 1] * c1 + cos_[m - 1] * s1;
    }
    const int stride = n_max_ + 1;
    for (int m = 0; m <= n_max_; ++m) {
      RadialSeries(m, n_max_, rho, [&](int n, double r) { radial_[n * stride + m] = r; });
    }
    for (std::size_t i = 0; i < modes_.size(); ++i) {
      const ZernikeNM& nm = modes_[i];
      const int am = std::abs(nm.m);
      const double angular = nm.m > 0 ? cos_[am] : (nm.m < 0 ? sin_[am] : 1.0);
      out[i] = norms_[i] * radial_[nm.n * stride + am] * angular;
    }
  }

 private:
  std::vector<ZernikeNM> modes_;
  std::vector<double> norms_;
  int n_max_ = 0;
  std::vector<double> radial_;
  std::vector<double> cos_, sin_;
};

}  // namespace

ZernikeNM NollToNM(int j) {
  CheckNoll(j, "NollToNM");
  // Radial order: the largest n with n(n+1)/2 < j; j - n(n+1)/2 - 1 = k is the position within the order.
  long long n = 0;
  while ((n + 1) * (n + 2) / 2 < j) ++n;
  const long long k = j - n * (n + 1) / 2 - 1;
  // |m| runs (n mod 2), then pairs of each larger |m|: for even n 0,2,2,4,4,...; for odd n 1,1,3,3,...
  const long long am = (n % 2 == 0) ? 2 * ((k + 1) / 2) : 2 * (k / 2) + 1;
  ZernikeNM nm{static_cast<int>(n), static_cast<int>(am)};
  if (am != 0 && j % 2 == 1) nm.m = -nm.m;  // odd j: sin
  return nm;
}

int NMToNoll(int n, int m) {
  const int am = std::abs(m);
  CheckArgument(n >= 0 && am <= n && (n - am) % 2 == 0, "NMToNoll", "(n, m)",
                "(" + std::to_string(n) + ", " + std::to_string(m) + ")", "n >= 0, |m| <= n, n - |m| even");
  const int base = n * (n + 1) / 2;  // modes of orders < n
  if (am == 0) return base + 1;
  // Within order n the pair for |m| > 0 occupies positions |m| - 1 and |m| (0-based) after `base`: for even
  // n position 0 is m = 0 and pairs follow; for odd n pairs start at position 0 with |m| = 1. Of the two
  // indices the even one carries cos (m > 0), the odd one sin (m < 0).
  const int j1 = base + am, j2 = base + am + 1;
  const int j_cos = (j1 % 2 == 0) ? j1 : j2;
  const int j_sin = (j1 % 2 == 0) ? j2 : j1;
  return m > 0 ? j_cos : j_sin;
}

double ZernikeRadial(int n, int m, double rho) {
  CheckArgument(n >= 0 && m >= 0 && m <= n && (n - m) % 2 == 0, "ZernikeRadial", "(n, m)",
                "(" + std::to_string(n) + ", " + std::to_string(m) + ")", "n >= 0, 0 <= m <= n, n - m even");
  CheckArgument(rho >= 0.0, "ZernikeRadial", "rho", rho, ">= 0");
  double value = 0.0;
  RadialSeries(m, n, rho, [&](int k, double r) {
    if (k == n) value = r;
  });
  return value;
}

double ZernikeValue(int j, double rho, double theta) {
  CheckNoll(j, "ZernikeValue");
  CheckArgument(rho >= 0.0, "ZernikeValue", "rho", rho, ">= 0");
  const ZernikeNM nm = NollToNM(j);
  const int am = std::abs(nm.m);
  const double angular = nm.m > 0 ? std::cos(am * theta) : (nm.m < 0 ? std::sin(am * theta) : 1.0);
  return NollNorm(nm) * ZernikeRadial(nm.n, am, rho) * angular;
}

namespace {

// Mode j at the pixel centres of the n x n grid; pixels whose centre lies outside obstruction <= rho <= 1 are
// set to 0 when `masked` (CircularPupil's centre rule), evaluated otherwise.
Image SampleMode(int j, Index n_pix, double obstruction, bool masked) {
  const ZernikeNM nm = NollToNM(j);
  const int am = std::abs(nm.m);
  const double norm = NollNorm(nm);
  const double inner2 = obstruction * obstruction;
  Image z = Image::Zero(n_pix, n_pix);
  for (Index i = 0; i < n_pix; ++i) {
    const double y = NormalisedPupilPosition(i, n_pix);
    for (Index k = 0; k < n_pix; ++k) {
      const double x = NormalisedPupilPosition(k, n_pix);
      const double r2 = x * x + y * y;
      if (masked && (r2 > 1.0 || r2 < inner2)) continue;
      const double rho = std::sqrt(r2);
      const double theta = std::atan2(y, x);
      const double angular = nm.m > 0 ? std::cos(am * theta) : (nm.m < 0 ? std::sin(am * theta) : 1.0);
      double radial = 0.0;
      RadialSeries(am, nm.n, rho, [&](int n, double r) {
        if (n == nm.n) radial = r;
      });
      z(i, k) = norm * radial * angular;
    }
  }
  return z;
}

}  // namespace

Image Zernike(int j, Index n_pix, double obstruction) {
  CheckNoll(j, "Zernike");
  CheckArgument(n_pix >= 1, "Zernike", "n_pix", n_pix, ">= 1");
  CheckObstruction(obstruction, "Zernike");
  return SampleMode(j, n_pix, obstruction, true);
}

Image ZernikeUnmasked(int j, Index n_pix) {
  CheckNoll(j, "ZernikeUnmasked");
  CheckArgument(n_pix >= 1, "ZernikeUnmasked", "n_pix", n_pix, ">= 1");
  return SampleMode(j, n_pix, 0.0, false);
}

ImageStack ZernikeBasis(int J, Index n_pix, double obstruction) {
  CheckArgument(J >= 1, "ZernikeBasis", "J", J, ">= 1 (number of modes)");
  CheckArgument(n_pix >= 1, "ZernikeBasis", "n_pix", n_pix, ">= 1");
  CheckObstruction(obstruction, "ZernikeBasis");
  ImageStack basis(J, Image::Zero(n_pix, n_pix));
  ModeEvaluator eval(J);
  std::vector<double> values(J);
  const double inner2 = obstruction * obstruction;
  for (Index i = 0; i < n_pix; ++i) {
    const double y = NormalisedPupilPosition(i, n_pix);
    for (Index k = 0; k < n_pix; ++k) {
      const double x = NormalisedPupilPosition(k, n_pix);
      const double r2 = x * x + y * y;
      if (r2 > 1.0 || r2 < inner2) continue;
      eval.Evaluate(x, y, values.data());
      for (int q = 0; q < J; ++q) basis[q](i, k) = values[q];
    }
  }
  return basis;
}

Vector ProjectOntoZernike(const Image& phase, const Image& pupil, int J) {
  CheckArgument(J >= 1, "ProjectOntoZernike", "J", J, ">= 1 (number of modes)");
  CheckArgument(pupil.rows() >= 1 && pupil.rows() == pupil.cols(), "ProjectOntoZernike", "pupil shape",
                ToString(ShapeOf(pupil)), "square n x n pupil grid, n >= 1");
  CheckArgument(ShapeOf(phase) == ShapeOf(pupil), "ProjectOntoZernike", "phase shape",
                ToString(ShapeOf(phase)), "the pupil's shape " + ToString(ShapeOf(pupil)));
  CheckArgument(pupil.isFinite().all() && (pupil >= 0.0).all(), "ProjectOntoZernike", "pupil",
                "negative or non-finite values", "finite weights >= 0");
  const Index n = pupil.rows();
  std::vector<Index> pixels;
  for (Index p = 0; p < pupil.size(); ++p) {
    if (pupil.data()[p] > 0.0) pixels.push_back(p);
  }
  CheckArgument(static_cast<Index>(pixels.size()) >= J, "ProjectOntoZernike", "J", J,
                "at most the number of pupil pixels (" + std::to_string(pixels.size()) + ")");
  // Weighted least squares: rows scaled by sqrt(w). The modes are near-orthogonal on a disk, so the system
  // is well conditioned; column-pivoting QR also reports the rank for annuli with too few pixels.
  Eigen::MatrixXd a(pixels.size(), J);
  Vector b(pixels.size());
  ModeEvaluator eval(J);
  std::vector<double> values(J);
  for (std::size_t r = 0; r < pixels.size(); ++r) {
    const Index p = pixels[r];
    const double v = phase.data()[p];
    CheckArgument(std::isfinite(v), "ProjectOntoZernike", "phase", v, "finite values on the pupil");
    const double w = std::sqrt(pupil.data()[p]);
    eval.Evaluate(NormalisedPupilPosition(p % n, n), NormalisedPupilPosition(p / n, n), values.data());
    for (int q = 0; q < J; ++q) a(r, q) = w * values[q];
    b(r) = w * v;
  }
  const Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(a);
  CheckArgument(qr.rank() == J, "ProjectOntoZernike", "J", J,
                "modes that are linearly independent on the sampled pupil (rank " +
                    std::to_string(qr.rank()) + "); use fewer modes or a finer grid");
  return qr.solve(b);
}

ImageStack OrthonormalZernikeBasis(const Image& pupil, int J, Eigen::MatrixXd* zernike_to_mode) {
  CheckArgument(J >= 1, "OrthonormalZernikeBasis", "J", J, ">= 1 (number of modes)");
  CheckArgument(pupil.rows() >= 1 && pupil.rows() == pupil.cols(), "OrthonormalZernikeBasis", "pupil shape",
                ToString(ShapeOf(pupil)), "square n x n pupil grid, n >= 1");
  CheckArgument(pupil.isFinite().all() && (pupil >= 0.0).all(), "OrthonormalZernikeBasis", "pupil",
                "negative or non-finite values", "finite weights >= 0");
  const Index n = pupil.rows();
  std::vector<Index> pixels;
  double total = 0.0;
  for (Index p = 0; p < pupil.size(); ++p) {
    if (pupil.data()[p] > 0.0) {
      pixels.push_back(p);
      total += pupil.data()[p];
    }
  }
  CheckArgument(static_cast<Index>(pixels.size()) >= J, "OrthonormalZernikeBasis", "J", J,
                "at most the number of pupil pixels (" + std::to_string(pixels.size()) + ")");
  // Z (P x J), unweighted, and its row-weighted copy sqrt(A) Z.
  const Index rows = static_cast<Index>(pixels.size());
  Eigen::MatrixXd z(rows, J);
  Vector sqrt_w(rows);
  ModeEvaluator eval(J);
  std::vector<double> values(J);
  for (Index r = 0; r < rows; ++r) {
    const Index p = pixels[r];
    eval.Evaluate(NormalisedPupilPosition(p % n, n), NormalisedPupilPosition(p / n, n), values.data());
    for (int q = 0; q < J; ++q) z(r, q) = values[q];
    sqrt_w[r] = std::sqrt(pupil.data()[p] / total);  // weights normalised: <f, g>_A = sum (w f)(w g)
  }
  // Two passes of "M <- M R^-1" with R from the QR of diag(sqrt_w) M (Householder, no pivoting so the Noll
  // order and the triangular structure are kept). T accumulates the product of the R^-1.
  Eigen::MatrixXd m = z;
  Eigen::MatrixXd t = Eigen::MatrixXd::Identity(J, J);
  for (int pass = 0; pass < 2; ++pass) {
    const Eigen::HouseholderQR<Eigen::MatrixXd> qr(sqrt_w.asDiagonal() * m);
    Eigen::MatrixXd r = qr.matrixQR().topRows(J).triangularView<Eigen::Upper>();
    // Positive diagonal: flip the sign of rows of R (and so of columns of Q) where needed.
    for (int q = 0; q < J; ++q) {
      if (r(q, q) < 0.0) r.row(q) *= -1.0;
    }
    const double largest = r.diagonal().cwiseAbs().maxCoeff();
    for (int q = 0; q < J; ++q) {
      CheckArgument(r(q, q) > 1e-10 * largest, "OrthonormalZernikeBasis", "J", J,
                    "modes that are linearly independent on the pupil (mode " + std::to_string(q + 1) +
                        " is not); use fewer modes or a finer grid");
    }
    const Eigen::MatrixXd r_inv = r.triangularView<Eigen::Upper>().solve(Eigen::MatrixXd::Identity(J, J));
    m = m * r_inv;
    t = t * r_inv;
  }
  if (zernike_to_mode != nullptr) *zernike_to_mode = t;
  ImageStack modes(J, Image::Zero(n, n));
  for (Index r = 0; r < rows; ++r) {
    for (int q = 0; q < J; ++q) modes[q].data()[pixels[r]] = m(r, q);
  }
  return modes;
}

double TiltCoefficientForShift(double shift_rad, double diameter_m) {
  CheckArgument(std::isfinite(diameter_m) && diameter_m > 0.0, "TiltCoefficientForShift", "diameter_m",
                diameter_m, "> 0 and finite [m]");
  CheckArgument(std::isfinite(shift_rad), "TiltCoefficientForShift", "shift_rad", shift_rad, "finite [rad]");
  return shift_rad * diameter_m / 4.0;
}

double ShiftForTiltCoefficient(double coefficient_m, double diameter_m) {
  CheckArgument(std::isfinite(diameter_m) && diameter_m > 0.0, "ShiftForTiltCoefficient", "diameter_m",
                diameter_m, "> 0 and finite [m]");
  CheckArgument(std::isfinite(coefficient_m), "ShiftForTiltCoefficient", "coefficient_m", coefficient_m,
                "finite [m]");
  return 4.0 * coefficient_m / diameter_m;
}

}  // namespace aosr
