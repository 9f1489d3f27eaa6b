#include "aosr/design/design_continuous_sky.hpp"

#include <Eigen/Dense>
#include <cmath>
#include <string>

#include "aosr/core/error.hpp"
#include "aosr/core/fft.hpp"
#include "design_internal.hpp"

namespace aosr {

SkySpectrum SkySpectrumOfPrior(const TikhonovOptions& reconstructor, double noise_sigma) {
  const char* fn = "SkySpectrumOfPrior";
  std::string why;
  if (!reconstructor.IsValid(&why)) throw InvalidArgument(std::string(fn) + ": reconstructor." + why);
  CheckArgument(reconstructor.lambda > 0, fn, "reconstructor.lambda", reconstructor.lambda, "> 0");
  CheckArgument(std::isfinite(noise_sigma) && noise_sigma > 0, fn, "noise_sigma", noise_sigma, "> 0 and finite");
  const double level = noise_sigma * noise_sigma / reconstructor.lambda;
  const double two_pi2 = 4.0 * M_PI * M_PI;
  switch (reconstructor.prior) {
    case TikhonovPrior::kIdentity:
      return [level](double, double) { return level; };
    case TikhonovPrior::kGradient:
    case TikhonovPrior::kLaplacian: {
      const int power = reconstructor.prior == TikhonovPrior::kGradient ? 1 : 2;
      return [level, two_pi2, power](double vy, double vx) {
        const double g = two_pi2 * (vy * vy + vx * vx);
        return g > 0 ? level / std::pow(g, power) : 0.0;
      };
    }
    case TikhonovPrior::kPowerSpectrum:
    case TikhonovPrior::kFitted: {
      CheckArgument(reconstructor.object_power_spectrum.size() == 0, fn, "reconstructor.object_power_spectrum",
                    "a sampled spectrum", "the parametric prior (a sampled spectrum has no values beyond the HR band)");
      const double f0 = reconstructor.spectrum_corner, beta = reconstructor.spectrum_slope;
      return [level, f0, beta](double vy, double vx) {
        return level * std::pow(1.0 + (vy * vy + vx * vx) / (f0 * f0), -0.5 * beta);
      };
    }
  }
  throw InvalidArgument(fn, "reconstructor.prior", "unknown", "identity, gradient, laplacian or power-spectrum");
}

SkySpectrum SkySpectrumOfModel(const PowerSpectrumModel& model) {
  std::string why;
  if (!model.IsValid(&why)) throw InvalidArgument("SkySpectrumOfModel: model." + why);
  return [model](double vy, double vx) { return model(std::hypot(vy, vx)); };
}

int TruthOversamplingFor(const DesignOptics& optics) {
  const double cutoff = optics.hr_pixel_rad * optics.diameter_m / optics.wavelength_m;  // cycles per HR pixel
  CheckArgument(std::isfinite(cutoff) && cutoff > 0, "TruthOversamplingFor", "optics",
                "hr_pixel_rad " + ToString(optics.hr_pixel_rad), "finite, positive pitch, diameter and wavelength");
  // The grid of pitch θ_hr / t has its Nyquist at t/2 cycles per HR pixel.
  return std::max(1, int(std::ceil(2.0 * cutoff - 1e-9)));
}

DesignOptics OversampledOptics(const DesignOptics& optics, int t) {
  CheckArgument(t >= 1 && t <= 16, "OversampledOptics", "t", t, "1 .. 16");
  DesignOptics fine = optics;
  fine.hr_pixel_rad = optics.hr_pixel_rad / t;
  fine.r = optics.r * t;
  fine.grid = optics.grid * t;
  return fine;
}

double ExpectedTikhonovMseOnContinuousSky(const MultiFrameModel& nominal, const std::vector<MultiFrameModel>& truths,
                                          int truth_oversampling, int sky_oversampling,
                                          const TikhonovOptions& reconstructor, double noise_sigma,
                                          const SkySpectrum& sky) {
  const char* fn = "ExpectedTikhonovMseOnContinuousSky";
  const Shape hr = nominal.hr_shape();
  const int r = nominal.r(), n = nominal.frames();
  const int t = truth_oversampling, s = sky_oversampling;
  design_internal::CheckSpectrumOptions(fn, reconstructor, noise_sigma, Image(), hr);
  CheckArgument(t >= 1 && t <= 16, fn, "truth_oversampling", t, "1 .. 16");
  CheckArgument(s >= t && s <= 64, fn, "sky_oversampling", s, "truth_oversampling .. 64");
  CheckArgument(!truths.empty(), fn, "truths", "none", "one model per realisation (the nominal one, refined, without)");
  CheckArgument(bool(sky), fn, "sky", "empty", "a spectrum");
  const Shape tg{hr.rows * t, hr.cols * t};
  for (std::size_t q = 0; q < truths.size(); ++q)
    CheckArgument(truths[q].hr_shape() == tg && truths[q].r() == r * t && truths[q].frames() == n, fn,
                  "truths[" + std::to_string(q) + "]",
                  ToString(truths[q].hr_shape()) + ", r " + std::to_string(truths[q].r()) + ", " +
                      std::to_string(truths[q].frames()) + " frames",
                  "the grid " + ToString(tg) + ", r " + std::to_string(r * t) + " and " + std::to_string(n) + " frames");

  const Shape lr{hr.rows / r, hr.cols / r};
  const Shape fine{hr.rows * s, hr.cols * s};
  const int rs = r * s, rr = r * r, nreal = int(truths.size());
  // The sky's spectrum on the fine grid, checked once.
  Image sigma(fine.rows, fine.cols);
  for (Index gy = 0; gy < fine.rows; ++gy)
    for (Index gx = 0; gx < fine.cols; ++gx) {
      const double v = sky(double(SignedFrequency(gy, fine.rows)) / double(hr.rows),
                           double(SignedFrequency(gx, fine.cols)) / double(hr.cols));
      CheckArgument(std::isfinite(v) && v >= 0, fn, "sky",
                    ToString(v) + " at frequency bin (" + std::to_string(gy) + ", " + std::to_string(gx) + ")",
                    "finite values >= 0");
      sigma(gy, gx) = v;
    }
  const Image p = design_internal::PriorSymbol(reconstructor, hr);
  const std::vector<Complex> by = design_internal::BoxTransfer(hr.rows, r), bx = design_internal::BoxTransfer(hr.cols, r);
  const std::vector<Complex> cy = design_internal::BoxTransfer(fine.rows, rs), cx = design_internal::BoxTransfer(fine.cols, rs);
  const std::vector<Complex> hy = design_internal::BoxTransfer(fine.rows, s), hx = design_internal::BoxTransfer(fine.cols, s);
  // Where a fine frequency falls on the truth grid (signed frequency inside its band), or -1 beyond it.
  auto on_truth = [](Index g, Index fine_n, Index truth_n) -> Index {
    const Index v = SignedFrequency(g, fine_n);
    const Index idx = ((v % truth_n) + truth_n) % truth_n;
    return SignedFrequency(idx, truth_n) == v ? idx : -1;
  };
  const double w = reconstructor.lambda / double(rr), c = noise_sigma * noise_sigma / double(rr);
  const double per_real = 1.0 / nreal;
  Eigen::MatrixXcd a0(n, rr), ginv, rm;
  Eigen::VectorXd pk(rr);
  Eigen::VectorXcd col(n), fcol(rr);
  double total = 0;
  for (Index uy = 0; uy < lr.rows; ++uy)
    for (Index ux = 0; ux < lr.cols; ++ux) {
      for (int ky = 0; ky < r; ++ky)
        for (int kx = 0; kx < r; ++kx) {
          const int k = ky * r + kx;
          const Index fy = uy + ky * lr.rows, fx = ux + kx * lr.cols;
          pk[k] = p(fy, fx);
          const Complex b = by[fy] * bx[fx] / double(rr);
          for (int i = 0; i < n; ++i) a0(i, k) = b * nominal.Otf(i, fy, fx);
        }
      design_internal::BinReconstructor(a0, pk, w, &ginv, &rm);
      double e = c * rm.squaredNorm();
      for (int ay = 0; ay < rs; ++ay)
        for (int ax = 0; ax < rs; ++ax) {
          const Index gy = uy + ay * lr.rows, gx = ux + ax * lr.cols;
          const double sg = sigma(gy, gx);
          if (sg == 0) continue;
          const int k = (ay % r) * r + (ax % r);
          const Complex truth_box = hy[gy] * hx[gx] / double(s * s);
          const Index ty = on_truth(gy, fine.rows, tg.rows), tx = on_truth(gx, fine.cols, tg.cols);
          if (ty < 0 || tx < 0) {
            e += sg * std::norm(truth_box);  // no exposure sees it: only the truth carries it
            continue;
          }
          const Complex camera_box = cy[gy] * cx[gx] / double(rs * rs);
          double err = 0;
          for (int q = 0; q < nreal; ++q) {
            for (int i = 0; i < n; ++i) col[i] = camera_box * truths[q].Otf(i, ty, tx);
            fcol = rm * col;
            fcol[k] -= truth_box;
            err += fcol.squaredNorm();
          }
          e += sg * err * per_real;
        }
      total += e;
    }
  const double j = total / (double(hr.rows) * double(hr.cols));
  if (!std::isfinite(j)) throw NumericalError(std::string(fn) + ": the expected MSE is not finite");
  return j;
}

}  // namespace aosr
