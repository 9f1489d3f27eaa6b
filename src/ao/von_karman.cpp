#include "aosr/ao/von_karman.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

#include "aosr/core/error.hpp"
#include "aosr/optics/zernike.hpp"

namespace aosr {
namespace {

constexpr double kNu = 5.0 / 6.0;
constexpr double kInf = std::numeric_limits<double>::infinity();

void CheckR0(const char* function, double r0_m) {
  CheckArgument(std::isfinite(r0_m) && r0_m > 0.0, function, "r0_m", r0_m, "> 0 and finite [m]");
}

void CheckL0(const char* function, double L0_m, bool allow_infinite) {
  const bool ok = L0_m > 0.0 && (std::isfinite(L0_m) || (allow_infinite && L0_m == kInf));
  CheckArgument(ok, function, "L0_m", L0_m,
                allow_infinite ? "> 0 [m], finite or +inf" : "> 0 and finite [m]");
}

void CheckDiameter(const char* function, double diameter_m) {
  CheckArgument(std::isfinite(diameter_m) && diameter_m > 0.0, function, "diameter_m", diameter_m,
                "> 0 and finite [m]");
}

// sigma^2 / (L0/r0)^(5/3) = (6/5) pi c_Phi.
double VarianceConstant() { return 1.2 * kPi * VonKarmanPsdConstant(); }

// g(x) = 1 - x^nu K_nu(x) / (2^(nu-1) Gamma(nu)) for nu = 5/6, so that D(r) = 2 sigma^2 g(2 pi r / L0).
// For x <= 2 from the ascending series of K_nu = pi / (2 sin(nu pi)) (I_-nu - I_nu):
//   g(x) = Gamma(1-nu) [ (x/2)^(2 nu) sum_{k>=0} (x/2)^(2k) / (k! Gamma(k+nu+1))
//                        - sum_{k>=1} (x/2)^(2k) / (k! Gamma(k-nu+1)) ],
// whose leading term Gamma(1-nu)/Gamma(1+nu) (x/2)^(5/3) is the Kolmogorov law (no cancellation as x -> 0).
double StructureShape(double x) {
  if (x <= 2.0) {
    const double h = 0.5 * x;
    const double h2 = h * h;
    // Terms t_k = h2^k / (k! Gamma(k + nu + 1)) and s_k = h2^k / (k! Gamma(k - nu + 1)).
    double t = 1.0 / std::tgamma(kNu + 1.0);
    double s = 1.0 / std::tgamma(1.0 - kNu);  // k = 0 term (excluded from the second sum)
    double sum_t = t;
    double sum_s = 0.0;
    for (int k = 1; k < 60; ++k) {
      t *= h2 / (k * (k + kNu));
      s *= h2 / (k * (k - kNu));
      sum_t += t;
      sum_s += s;
      if (t < 1e-18 * sum_t && std::abs(s) < 1e-18 * std::abs(sum_s)) break;
    }
    return std::tgamma(1.0 - kNu) * (std::pow(h, 2.0 * kNu) * sum_t - sum_s);
  }
  return 1.0 - std::pow(x, kNu) * ModifiedBesselK(kNu, x) / (std::pow(2.0, kNu - 1.0) * std::tgamma(kNu));
}

// Gauss-Legendre nodes and weights on [-1, 1], 10 points.
constexpr std::array<double, 5> kGlNodes = {0.1488743389816312, 0.4333953941292472, 0.6794095682990244,
                                            0.8650633666889845, 0.9739065285171717};
constexpr std::array<double, 5> kGlWeights = {0.2955242247147529, 0.2692667193099963, 0.2190863625159820,
                                              0.1494513491505806, 0.0666713443086881};

template <typename F>
double GaussLegendre(const F& f, double a, double b) {
  const double c = 0.5 * (a + b);
  const double h = 0.5 * (b - a);
  double s = 0.0;
  for (std::size_t i = 0; i < kGlNodes.size(); ++i) {
    s += kGlWeights[i] * (f(c - h * kGlNodes[i]) + f(c + h * kGlNodes[i]));
  }
  return s * h;
}

// I_n(u0) = int_0^inf (u^2 + u0^2)^(-11/6) J_{n+1}(u)^2 / u du (header: Zernike variances).
double ZernikeIntegral(int n, double u0) {
  const double order = n + 1.0;
  const double u02 = u0 * u0;
  auto f = [&](double u) {
    const double j = std::cyl_bessel_j(order, u);
    return std::pow(u * u + u02, -11.0 / 6.0) * j * j / u;
  };
  double sum = 0.0;
  // [2^-100, 1]: geometric panels [2^-(k+1), 2^-k] resolve both the u^(2n - 8/3) power law of Kolmogorov
  // and the knee at u ~ u0 of von Kármán; below 2^-100 the integrand's contribution is < 1e-30 relative.
  for (int k = 0; k < 100; ++k) sum += GaussLegendre(f, std::ldexp(1.0, -(k + 1)), std::ldexp(1.0, -k));
  // [1, U] in panels of width 1/2 (J^2 oscillates with period pi), then the tail with <J^2> = 1/(pi u).
  const double u_max = std::max(400.0, 8.0 * order + 200.0);
  for (double a = 1.0; a < u_max; a += 0.5) sum += GaussLegendre(f, a, a + 0.5);
  sum += std::pow(u_max, -14.0 / 3.0) / (kPi * 14.0 / 3.0);
  return sum;
}

// 8 pi^(8/3) c_Phi: <a_j^2> = ZernikePrefactor (n+1) (D/r0)^(5/3) I_n(u0).
double ZernikePrefactor() { return 8.0 * std::pow(kPi, 8.0 / 3.0) * VonKarmanPsdConstant(); }

// Kolmogorov <a_j^2> / (D/r0)^(5/3) for radial order n >= 1.
double KolmogorovModeCoefficient(int n) {
  const double kz = ZernikePrefactor() * std::tgamma(14.0 / 3.0) /
                    (std::pow(2.0, 14.0 / 3.0) * std::pow(std::tgamma(17.0 / 6.0), 2));
  return kz * (n + 1.0) * std::exp(std::lgamma(n - 5.0 / 6.0) - std::lgamma(n + 23.0 / 6.0));
}

// sum_{n > N} (n+1) KolmogorovModeCoefficient(n): explicit to n = 20000 by the ratio recurrence, then the
// Euler-Maclaurin tail of a term ~ n^(-8/3) (relative error of the tail ~1/n, i.e. < 1e-14 absolute).
double KolmogorovOrderTail(int N) {
  const int n_explicit = std::max(N + 1, 20000);
  double term = (N + 2.0) * KolmogorovModeCoefficient(N + 1);  // t_n = (n+1) c_n at n = N+1
  double sum = 0.0;
  int n = N + 1;
  for (; n < n_explicit; ++n) {
    sum += term;
    // c_{n+1}/c_n = ((n+2)/(n+1)) (n - 5/6) / (n + 23/6); t carries one more (n+2)/(n+1).
    const double r = (n + 2.0) / (n + 1.0);
    term *= r * r * (n - 5.0 / 6.0) / (n + 23.0 / 6.0);
  }
  // Remaining sum_{m >= n} t_m with t_m ~ t_n (m/n)^(-8/3): integral from n - 1/2 (midpoint rule).
  sum += term * (n - 0.5) * 0.6 * std::pow((n - 0.5) / n, -8.0 / 3.0);
  return sum;
}

}  // namespace

double VonKarmanPsdConstant() {
  static const double c = std::pow(std::tgamma(11.0 / 6.0), 2) / (2.0 * std::pow(kPi, 11.0 / 3.0)) *
                          std::pow(24.0 / 5.0 * std::tgamma(6.0 / 5.0), 5.0 / 6.0);
  return c;
}

double KolmogorovStructureConstant() {
  static const double c = 2.0 * std::pow(24.0 / 5.0 * std::tgamma(6.0 / 5.0), 5.0 / 6.0);
  return c;
}

double VonKarmanPsd(double f_cycles_per_m, double r0_m, double L0_m) {
  CheckArgument(std::isfinite(f_cycles_per_m) && f_cycles_per_m >= 0.0, "VonKarmanPsd", "f_cycles_per_m",
                f_cycles_per_m, ">= 0 and finite [cycles/m]");
  CheckR0("VonKarmanPsd", r0_m);
  CheckL0("VonKarmanPsd", L0_m, true);
  const double f02 = std::isfinite(L0_m) ? 1.0 / (L0_m * L0_m) : 0.0;
  return VonKarmanPsdConstant() * std::pow(r0_m, -5.0 / 3.0) *
         std::pow(f_cycles_per_m * f_cycles_per_m + f02, -11.0 / 6.0);
}

double VonKarmanPhaseVariance(double r0_m, double L0_m) {
  CheckR0("VonKarmanPhaseVariance", r0_m);
  CheckL0("VonKarmanPhaseVariance", L0_m, false);
  return VarianceConstant() * std::pow(L0_m / r0_m, 5.0 / 3.0);
}

double VonKarmanCovariance(double r_m, double r0_m, double L0_m) {
  CheckArgument(std::isfinite(r_m) && r_m >= 0.0, "VonKarmanCovariance", "r_m", r_m, ">= 0 and finite [m]");
  CheckR0("VonKarmanCovariance", r0_m);
  CheckL0("VonKarmanCovariance", L0_m, false);
  const double sigma2 = VarianceConstant() * std::pow(L0_m / r0_m, 5.0 / 3.0);
  return sigma2 * (1.0 - StructureShape(2.0 * kPi * r_m / L0_m));
}

double VonKarmanStructureFunction(double r_m, double r0_m, double L0_m) {
  CheckArgument(std::isfinite(r_m) && r_m >= 0.0, "VonKarmanStructureFunction", "r_m", r_m,
                ">= 0 and finite [m]");
  CheckR0("VonKarmanStructureFunction", r0_m);
  CheckL0("VonKarmanStructureFunction", L0_m, true);
  if (!std::isfinite(L0_m)) return KolmogorovStructureConstant() * std::pow(r_m / r0_m, 5.0 / 3.0);
  return 2.0 * VarianceConstant() * std::pow(L0_m / r0_m, 5.0 / 3.0) * StructureShape(2.0 * kPi * r_m / L0_m);
}

double KolmogorovStructureFunction(double r_m, double r0_m) {
  CheckArgument(std::isfinite(r_m) && r_m >= 0.0, "KolmogorovStructureFunction", "r_m", r_m,
                ">= 0 and finite [m]");
  CheckR0("KolmogorovStructureFunction", r0_m);
  return KolmogorovStructureConstant() * std::pow(r_m / r0_m, 5.0 / 3.0);
}

double ScaleR0(double r0_m, double reference_wavelength_m, double wavelength_m) {
  CheckR0("ScaleR0", r0_m);
  CheckArgument(std::isfinite(reference_wavelength_m) && reference_wavelength_m > 0.0, "ScaleR0",
                "reference_wavelength_m", reference_wavelength_m, "> 0 and finite [m]");
  CheckArgument(std::isfinite(wavelength_m) && wavelength_m > 0.0, "ScaleR0", "wavelength_m", wavelength_m,
                "> 0 and finite [m]");
  return r0_m * std::pow(wavelength_m / reference_wavelength_m, 6.0 / 5.0);
}

double ModifiedBesselK(double nu, double x) {
  CheckArgument(std::isfinite(nu), "ModifiedBesselK", "nu", nu, "finite");
  CheckArgument(std::isfinite(x) && x > 0.0, "ModifiedBesselK", "x", x, "> 0 and finite");
  // Trapezoidal rule on t in [0, inf): h (f(0)/2 + sum_{k>=1} f(k h)), f(t) = exp(-x cosh t) cosh(nu t).
  // Factor exp(-x) out so that large x does not underflow before the sum is formed.
  // Step: 1/8 resolves the strip of analyticity; for large x the integrand is a Gaussian of width
  // 1/sqrt(x) near t = 0, which needs h <= 0.4/sqrt(x) (error ~ exp(-2 pi^2 (0.4)^-2 ... ) < 1e-17).
  const double h = std::min(1.0 / 8.0, 0.4 / std::sqrt(x));
  double sum = 0.5;  // f(0) e^x / 2 (cosh 0 = 1)
  for (int k = 1; k < 100000; ++k) {
    const double t = k * h;
    const double term = std::exp(-x * (std::cosh(t) - 1.0) + std::abs(nu) * t) * 0.5 *
                        (1.0 + std::exp(-2.0 * std::abs(nu) * t));
    sum += term;
    // Past the maximum the terms decay faster than geometrically; stop when negligible.
    if (term < 1e-18 * sum && x * std::sinh(t) > std::abs(nu)) break;
  }
  return h * sum * std::exp(-x);
}

double KolmogorovZernikeVariance(int j, double diameter_m, double r0_m) {
  CheckArgument(j >= 1, "KolmogorovZernikeVariance", "j", j, ">= 1 (Noll index)");
  CheckDiameter("KolmogorovZernikeVariance", diameter_m);
  CheckR0("KolmogorovZernikeVariance", r0_m);
  if (j == 1) return kInf;
  const ZernikeNM nm = NollToNM(j);
  return KolmogorovModeCoefficient(nm.n) * std::pow(diameter_m / r0_m, 5.0 / 3.0);
}

double VonKarmanZernikeVariance(int j, double diameter_m, double r0_m, double L0_m) {
  CheckArgument(j >= 1, "VonKarmanZernikeVariance", "j", j, ">= 1 (Noll index)");
  CheckDiameter("VonKarmanZernikeVariance", diameter_m);
  CheckR0("VonKarmanZernikeVariance", r0_m);
  CheckL0("VonKarmanZernikeVariance", L0_m, true);
  if (j == 1 && !std::isfinite(L0_m)) return kInf;
  const ZernikeNM nm = NollToNM(j);
  const double u0 = std::isfinite(L0_m) ? kPi * diameter_m / L0_m : 0.0;
  return ZernikePrefactor() * (nm.n + 1.0) * std::pow(diameter_m / r0_m, 5.0 / 3.0) *
         ZernikeIntegral(nm.n, u0);
}

double NollResidualCoefficient(int J) {
  CheckArgument(J >= 1, "NollResidualCoefficient", "J", J, ">= 1 (number of removed modes)");
  // Modes J+1.. of the radial order of J, then all higher orders.
  const ZernikeNM nm = NollToNM(J);
  const int last_in_order = (nm.n + 1) * (nm.n + 2) / 2;  // Noll index of the last mode of order n
  double sum = 0.0;
  if (nm.n >= 1) sum += (last_in_order - J) * KolmogorovModeCoefficient(nm.n);
  return sum + KolmogorovOrderTail(nm.n);
}

double NollResidualVariance(int J, double diameter_m, double r0_m) {
  CheckArgument(J >= 1, "NollResidualVariance", "J", J, ">= 1 (number of removed modes)");
  CheckDiameter("NollResidualVariance", diameter_m);
  CheckR0("NollResidualVariance", r0_m);
  return NollResidualCoefficient(J) * std::pow(diameter_m / r0_m, 5.0 / 3.0);
}

}  // namespace aosr
