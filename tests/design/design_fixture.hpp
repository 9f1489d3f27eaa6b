// Small optics shared by the phase-design tests: a 32-pixel pupil of an 8 m telescope in K band, camera pixel
// λ/D, r = 2, a 16 x 16 HR design grid, and (optionally) the analytic AO model of a 16-actuator system.
#pragma once

#include <cmath>
#include <functional>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "aosr/core/fft.hpp"
#include "aosr/design/design_objective.hpp"
#include "aosr/design/design_parameterisation.hpp"
#include "aosr/optics/pupil.hpp"

namespace aosr::design_test {

constexpr double kLambda = 2.2e-6;
constexpr double kDiameter = 8.0;

inline DesignOptics SmallOptics(bool ao, Index grid = 16, int r = 2, Index pupil_n = 32) {
  DesignOptics o;
  o.amplitude = CircularPupil(pupil_n, PupilGeometry{kDiameter, 0.0});
  o.diameter_m = kDiameter;
  o.wavelength_m = kLambda;
  o.hr_pixel_rad = kLambda / kDiameter / r;  // camera pixel = λ/D
  o.r = r;
  o.grid = grid;
  if (ao) {
    AnalyticAoOptions a;
    a.diameter_m = kDiameter;
    a.actuator_pitch_m = 1.0;  // 8 actuators across: a coarse, fast AO model
    a.science_wavelength_m = kLambda;
    a.r0_m = 0.12;
    o.ao = a;
  }
  return o;
}

// An object with E|X(f)|² = M² s(f) (M² the pixel count): white noise filtered by √s.
inline Image DrawObject(const Image& s, std::mt19937_64& rng) {
  std::normal_distribution<double> n01;
  Image white(s.rows(), s.cols());
  for (Index k = 0; k < white.size(); ++k) white.data()[k] = n01(rng);
  const ComplexImage w = FftForward(white.cast<Complex>());
  return FftInverse(w * s.sqrt().cast<Complex>()).real();
}

inline DesignPupil SmallPupil(const DesignOptics& o) {
  DesignPupil p;
  p.amplitude = o.amplitude;
  p.diameter_m = o.diameter_m;
  p.wavelength_m = o.wavelength_m;
  p.camera_pixel_rad = o.hr_pixel_rad * o.r;
  DeformableMirrorOptions dm;
  dm.actuators_across = 9;
  dm.pitch_m = 1.0;
  p.dm = std::make_shared<DeformableMirror>(o.amplitude.rows(), PupilGeometry{kDiameter, 0.0}, dm);
  return p;
}

// Remainders |f(x+hd) − f(x) − h<g,d>| for h = h0, h0/2, ...; returns the ratios of consecutive remainders.
inline std::vector<double> TaylorRatios(const std::function<double(const Vector&, Vector*)>& f, const Vector& x,
                                        const Vector& d, double h0, int halvings, std::vector<double>* remainders = nullptr) {
  Vector g;
  const double f0 = f(x, &g);
  const double slope = g.dot(d);
  std::vector<double> rem;
  double h = h0;
  for (int k = 0; k <= halvings; ++k, h /= 2) rem.push_back(std::abs(f(x + h * d, nullptr) - f0 - h * slope));
  std::vector<double> ratios;
  for (std::size_t k = 1; k < rem.size(); ++k) ratios.push_back(rem[k - 1] / rem[k]);
  if (remainders) *remainders = rem;
  return ratios;
}

// J(θ) of a design objective through a parameterisation, with ∂J/∂θ (the chain every Taylor test checks).
inline std::function<double(const Vector&, Vector*)> ThroughParameters(const DesignCriterion& f,
                                                                       const DesignParameterisation& p) {
  return [&f, &p](const Vector& theta, Vector* g) {
    std::vector<Image> grad;
    const double v = f.Evaluate(p.Opds(theta), g ? &grad : nullptr);
    if (g) *g = p.PullBack(theta, grad);
    return v;
  };
}

// Taylor ratios (TaylorRatios, h0 = 0.05, 8 halvings) at a point away from the raster (so every squash is in
// its curved range: θ = θ_raster + 0.3·scale·noise) along a random direction, both seeded.
inline std::vector<double> TaylorAwayFromRaster(const DesignCriterion& f, const DesignParameterisation& p,
                                                std::uint64_t seed, std::vector<double>* remainders) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> n01;
  const Vector theta0 = p.RasterParameters();
  const double scale = theta0.cwiseAbs().maxCoeff();
  Vector theta = theta0, d(theta0.size());
  for (Index k = 0; k < theta.size(); ++k) theta[k] += 0.3 * scale * n01(rng), d[k] = scale * n01(rng);
  return TaylorRatios(ThroughParameters(f, p), theta, d, 0.05, 8, remainders);
}

}  // namespace aosr::design_test
