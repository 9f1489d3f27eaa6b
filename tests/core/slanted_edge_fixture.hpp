// Synthetic slanted edges with analytic MTFs, for the slanted-edge tests (core/slanted_edge.hpp).
//
// An edge through the image centre at angle θ from the column direction (one row toward +y moves it tan θ
// columns toward +x), dark (0) on the left, bright (1) on the right: pixel (y, x) has the signed distance
//   d = (x − cx) cos θ − (y − cy) sin θ
// to it and the value E(d), E the edge-spread function of the blur:
//  * Gaussian PSF of standard deviation σ, point-sampled (no pixel box): E = Φ(d/σ), MTF exp(−2π²σ²f²);
//  * Airy pattern (circular pupil, cut-off fc = D/λ cycles/px) times the pixel box: the LSF along the normal
//    is the projection of the Airy PSF convolved with the box's projection, so
//      MTF(f) = OTF_circ(f/fc) · sinc(f cos θ) · sinc(f sin θ),
//      OTF_circ(ν) = (2/π)(acos ν − ν sqrt(1 − ν²)) for ν <= 1, 0 beyond,
//    and E(d) = 1/2 + (1/π) ∫_0^fc MTF(f) sin(2π f d)/f df (the ESF of an even, unit-area LSF), integrated by
//    Simpson's rule (2000 intervals) on a 0.02 px grid of d and interpolated linearly (error < 1e-4).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <functional>
#include <random>
#include <vector>

#include "aosr/core/image.hpp"

namespace aosr::test {

inline double SincPi(double x) { return std::abs(x) < 1e-12 ? 1.0 : std::sin(M_PI * x) / (M_PI * x); }

inline double OtfCircular(double nu) {
  nu = std::abs(nu);
  if (nu >= 1.0) return 0.0;
  return (2.0 / M_PI) * (std::acos(nu) - nu * std::sqrt(1.0 - nu * nu));
}

inline double GaussianMtf(double sigma, double f) { return std::exp(-2.0 * M_PI * M_PI * sigma * sigma * f * f); }

inline double AiryBoxMtf(double fc, double theta_deg, double f) {
  const double t = theta_deg * M_PI / 180.0;
  return OtfCircular(f / fc) * SincPi(f * std::cos(t)) * SincPi(f * std::sin(t));
}

// An edge image of `shape` whose pixel (y, x) holds esf(d) (header).
inline Image EdgeImage(Shape shape, double theta_deg, const std::function<double(double)>& esf) {
  const double t = theta_deg * M_PI / 180.0, cy = 0.5 * (shape.rows - 1), cx = 0.5 * (shape.cols - 1);
  Image img(shape.rows, shape.cols);
  for (Index y = 0; y < shape.rows; ++y)
    for (Index x = 0; x < shape.cols; ++x) img(y, x) = esf((x - cx) * std::cos(t) - (y - cy) * std::sin(t));
  return img;
}

inline Image GaussianEdge(Shape shape, double theta_deg, double sigma) {
  return EdgeImage(shape, theta_deg, [sigma](double d) { return 0.5 * std::erfc(-d / (sigma * std::sqrt(2.0))); });
}

// The ESF of an even LSF whose MTF `mtf` vanishes beyond fmax, tabulated for |d| <= dmax.
class TabulatedEsf {
 public:
  TabulatedEsf(const std::function<double(double)>& mtf, double fmax, double dmax) : dmax_(dmax) {
    const int n = 2000;  // Simpson intervals (even)
    const double h = fmax / n;
    std::vector<double> f(n + 1), m(n + 1), w(n + 1);
    for (int i = 0; i <= n; ++i) {
      f[i] = i * h;
      m[i] = mtf(f[i]);
      w[i] = (i == 0 || i == n ? 1.0 : (i % 2 ? 4.0 : 2.0)) * h / 3.0;
    }
    const int k = int(std::ceil(dmax / kStep));
    table_.resize(2 * k + 1);
    for (int j = -k; j <= k; ++j) {
      const double d = j * kStep;
      double s = 0.0;
      for (int i = 0; i <= n; ++i) s += w[i] * m[i] * (i == 0 ? 2.0 * M_PI * d : std::sin(2.0 * M_PI * f[i] * d) / f[i]);
      table_[j + k] = 0.5 + s / M_PI;
    }
    offset_ = k;
  }
  double operator()(double d) const {
    const double t = std::clamp(d, -dmax_, dmax_) / kStep + offset_;
    const std::size_t i = std::min(std::size_t(t), table_.size() - 2);
    const double w = t - double(i);
    return (1.0 - w) * table_[i] + w * table_[i + 1];
  }

 private:
  static constexpr double kStep = 0.02;
  double dmax_;
  int offset_ = 0;
  std::vector<double> table_;
};

// dmax [px]: the ESF is tabulated for |d| <= dmax and held constant beyond (0: the whole image).
inline Image AiryBoxEdge(Shape shape, double theta_deg, double fc, double dmax = 0.0) {
  if (dmax <= 0) dmax = 0.5 * std::hypot(double(shape.rows), double(shape.cols)) + 2.0;
  const TabulatedEsf esf([&](double f) { return AiryBoxMtf(fc, theta_deg, f); }, fc, dmax);
  return EdgeImage(shape, theta_deg, [&](double d) { return esf(d); });
}

// Adds N(0, sigma²) noise from a fixed seed.
inline Image WithNoise(Image img, double sigma, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> n01;
  for (Index i = 0; i < img.size(); ++i) img.data()[i] += sigma * n01(rng);
  return img;
}

// The image's shape for an edge at theta_deg over `rows` rows that keeps `across` px on the edge's sides.
inline Shape EdgeShape(Index rows, Index across, double theta_deg) {
  return {rows, across + Index(std::ceil(rows * std::tan(std::abs(theta_deg) * M_PI / 180.0)))};
}

}  // namespace aosr::test
