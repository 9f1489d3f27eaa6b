// Tikhonov's options (names, parsing, IsValid) and its prior: the symbol |Γ̂|² of every prior kind, the prior
// operator Γ, and the symbol image the Fourier engine reads (tikhonov.hpp).
#include "aosr/solvers/tikhonov.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>

#include "aosr/core/error.hpp"
#include "aosr/core/fft.hpp"
#include "aosr/core/operators.hpp"
#include "aosr/core/parallel.hpp"
#include "tikhonov_internal.hpp"

namespace aosr {

const char* ToString(TikhonovPrior p) {
  switch (p) {
    case TikhonovPrior::kIdentity:
      return "identity";
    case TikhonovPrior::kGradient:
      return "gradient";
    case TikhonovPrior::kLaplacian:
      return "laplacian";
    case TikhonovPrior::kPowerSpectrum:
      return "power-spectrum";
    case TikhonovPrior::kFitted:
      return "fitted";
  }
  return "unknown";
}

TikhonovPrior ParseTikhonovPrior(const std::string& name) {
  if (name == "identity") return TikhonovPrior::kIdentity;
  if (name == "gradient") return TikhonovPrior::kGradient;
  if (name == "laplacian") return TikhonovPrior::kLaplacian;
  if (name == "power-spectrum") return TikhonovPrior::kPowerSpectrum;
  if (name == "fitted") return TikhonovPrior::kFitted;
  throw InvalidArgument("ParseTikhonovPrior", "prior", name,
                        "identity, gradient, laplacian, power-spectrum or fitted");
}

const char* ToString(TikhonovLambdaRule rule) {
  switch (rule) {
    case TikhonovLambdaRule::kFixed:
      return "fixed";
    case TikhonovLambdaRule::kGcv:
      return "gcv";
    case TikhonovLambdaRule::kDiscrepancy:
      return "discrepancy";
    case TikhonovLambdaRule::kLcurve:
      return "lcurve";
    case TikhonovLambdaRule::kUpre:
      return "upre";
    case TikhonovLambdaRule::kWiener:
      return "wiener";
  }
  return "unknown";
}

TikhonovLambdaRule ParseTikhonovLambdaRule(const std::string& name) {
  for (TikhonovLambdaRule r : {TikhonovLambdaRule::kFixed, TikhonovLambdaRule::kGcv, TikhonovLambdaRule::kDiscrepancy,
                               TikhonovLambdaRule::kLcurve, TikhonovLambdaRule::kUpre, TikhonovLambdaRule::kWiener})
    if (name == ToString(r)) return r;
  throw InvalidArgument("ParseTikhonovLambdaRule", "lambda_rule", name,
                        "fixed, gcv, discrepancy, lcurve, upre or wiener");
}

bool TikhonovOptions::IsValid(std::string* why) const {
  auto fail = [why](const std::string& m) {
    if (why) *why = m;
    return false;
  };
  if (!(lambda >= 0 && std::isfinite(lambda)))
    return fail("lambda must be finite and >= 0, got " + ToString(lambda));
  if (!(rank_tolerance > 0 && rank_tolerance < 1))
    return fail("rank_tolerance must be in (0, 1), got " + ToString(rank_tolerance));
  const bool searched = lambda_rule == TikhonovLambdaRule::kGcv || lambda_rule == TikhonovLambdaRule::kLcurve ||
                        lambda_rule == TikhonovLambdaRule::kUpre;
  if (searched &&
      !(gcv_decades > 0 && gcv_decades <= 20 && gcv_steps_per_decade >= 1 && gcv_steps_per_decade <= 20))
    return fail("gcv_decades must be in (0, 20] and gcv_steps_per_decade in 1..20");
  if (!(spectrum_slope >= 0 && spectrum_slope <= 8))
    return fail("spectrum_slope must be in [0, 8], got " + ToString(spectrum_slope));
  if (!(spectrum_corner > 0 && spectrum_corner <= 0.5))
    return fail("spectrum_corner must be in (0, 0.5] cycles per HR pixel, got " + ToString(spectrum_corner));
  if (object_power_spectrum.size() > 0) {
    const Image& s = object_power_spectrum;
    if (!AllFinite(s) || !(s.minCoeff() > 0))
      return fail("object_power_spectrum must be finite and > 0 everywhere");
    const Index R = s.rows(), C = s.cols();
    for (Index y = 0; y < R; ++y)
      for (Index x = 0; x < C; ++x) {
        const double t = s((R - y) % R, (C - x) % C);
        if (std::abs(s(y, x) - t) > 1e-12 * std::max(s(y, x), t))
          return fail(
              "object_power_spectrum must be symmetric, S(-f) = S(f) (the spectrum of a real object); "
              "differs at bin (" +
              std::to_string(y) + ", " + std::to_string(x) + ")");
      }
    if (boundary == TikhonovBoundary::kZeroPadded)
      return fail(
          "object_power_spectrum is tied to the model's grid: use boundary kPeriodic or the parametric "
          "spectrum");
  }
  if (!(noise_sigma >= 0 && std::isfinite(noise_sigma)))
    return fail("noise_sigma must be finite and >= 0, got " + ToString(noise_sigma));
  if (lambda_rule == TikhonovLambdaRule::kDiscrepancy && !(noise_sigma > 0))
    return fail("noise_sigma must be > 0 for the discrepancy rule (it sets the target residual)");
  if (lambda_rule == TikhonovLambdaRule::kUpre && !(noise_sigma > 0))
    return fail("noise_sigma must be > 0 for the upre rule (it weighs the trace term; 1 for inverse-variance weights)");
  if (lambda_rule == TikhonovLambdaRule::kWiener && prior != TikhonovPrior::kFitted)
    return fail("lambda_rule kWiener needs prior kFitted (lambda = sigma^2 / s(0) of the spectrum fitted to the "
                "frames), got prior " + std::string(aosr::ToString(prior)));
  if (prior == TikhonovPrior::kFitted) {
    if (object_power_spectrum.size() > 0)
      return fail("object_power_spectrum must be empty for prior kFitted (the spectrum is fitted to the frames)");
    std::string fit_why;
    if (!spectrum_fit.IsValid(&fit_why)) return fail("spectrum_fit." + fit_why);
  }
  if (compute_std && std_samples < 2)
    return fail("std_samples must be >= 2, got " + std::to_string(std_samples));
  if (compute_std && !(noise_sigma > 0))
    return fail("noise_sigma must be > 0 for compute_std (it scales the map)");
  if (lambda_rule == TikhonovLambdaRule::kDiscrepancy) {
    if (!(discrepancy_factor >= 0.1 && discrepancy_factor <= 10))
      return fail("discrepancy_factor must be in [0.1, 10], got " + ToString(discrepancy_factor));
    if (!(discrepancy_tolerance > 0 && discrepancy_tolerance <= 0.1))
      return fail("discrepancy_tolerance must be in (0, 0.1], got " + ToString(discrepancy_tolerance));
    if (discrepancy_max_evaluations < 4 || discrepancy_max_evaluations > 1000)
      return fail("discrepancy_max_evaluations must be in 4..1000, got " +
                  std::to_string(discrepancy_max_evaluations));
  }
  if (padding < -1) return fail("padding must be >= 0, or -1 for automatic, got " + std::to_string(padding));
  if (method == TikhonovMethod::kFourier && boundary == TikhonovBoundary::kZeroPadded)
    return fail("method kFourier needs boundary kPeriodic (zero padding breaks the Fourier structure)");
  std::string cg_why;
  if (!cg.IsValid(&cg_why)) return fail("cg." + cg_why);
  return true;
}

namespace {

double ParametricSpectrum(const TikhonovOptions& o, Shape hr, Index fy, Index fx) {
  const double vy = double(SignedFrequency(fy, hr.rows)) / double(hr.rows);
  const double vx = double(SignedFrequency(fx, hr.cols)) / double(hr.cols);
  const double f0 = o.spectrum_corner;
  return std::pow(1.0 + (vy * vy + vx * vx) / (f0 * f0), -0.5 * o.spectrum_slope);
}

TikhonovOptions WithPrior(TikhonovPrior prior) {
  TikhonovOptions o;
  o.prior = prior;
  return o;
}

}  // namespace

double TikhonovPriorSymbol(const TikhonovOptions& options, Shape hr, Index fy, Index fx) {
  switch (options.prior) {
    case TikhonovPrior::kIdentity:
      return 1.0;
    case TikhonovPrior::kGradient:
    case TikhonovPrior::kLaplacian: {
      const double sy = std::sin(M_PI * double(fy) / double(hr.rows));
      const double sx = std::sin(M_PI * double(fx) / double(hr.cols));
      const double g = 4.0 * (sy * sy + sx * sx);
      return options.prior == TikhonovPrior::kGradient ? g : g * g;
    }
    case TikhonovPrior::kPowerSpectrum:
    case TikhonovPrior::kFitted:
      if (options.object_power_spectrum.size() > 0) {
        if (ShapeOf(options.object_power_spectrum) != hr)
          throw InvalidArgument("TikhonovPriorSymbol", "options.object_power_spectrum shape",
                                ToString(ShapeOf(options.object_power_spectrum)),
                                "the HR grid " + ToString(hr));
        return 1.0 / options.object_power_spectrum(fy, fx);
      }
      return 1.0 / ParametricSpectrum(options, hr, fy, fx);
  }
  throw InvalidArgument("TikhonovPriorSymbol", "prior", "unknown",
                        "identity, gradient, laplacian or power-spectrum");
}

double TikhonovPriorSymbol(TikhonovPrior prior, Shape hr, Index fy, Index fx) {
  return TikhonovPriorSymbol(WithPrior(prior), hr, fy, fx);
}

OperatorPtr TikhonovPriorOperator(Shape hr, const TikhonovOptions& options) {
  switch (options.prior) {
    case TikhonovPrior::kIdentity:
      return Identity(hr.size());
    case TikhonovPrior::kGradient:
      return Gradient(hr, Boundary::kPeriodic);
    case TikhonovPrior::kLaplacian:
      return Normal(Gradient(hr, Boundary::kPeriodic));  // ∇ᵀ∇
    case TikhonovPrior::kPowerSpectrum:
    case TikhonovPrior::kFitted: {
      // Γ = S^(−½)⊛: a real, even transfer function, so a real symmetric kernel.
      ComplexImage t(hr.rows, hr.cols / 2 + 1);
      for (Index fy = 0; fy < hr.rows; ++fy)
        for (Index fx = 0; fx < t.cols(); ++fx)
          t(fy, fx) = std::sqrt(TikhonovPriorSymbol(options, hr, fy, fx));
      return PeriodicConvolution(hr, t);
    }
  }
  throw InvalidArgument("TikhonovPriorOperator", "prior", "unknown",
                        "identity, gradient, laplacian or power-spectrum");
}

OperatorPtr TikhonovPriorOperator(Shape hr, TikhonovPrior prior) {
  return TikhonovPriorOperator(hr, WithPrior(prior));
}

namespace tikhonov_internal {

Image PriorSymbolImage(const TikhonovOptions& options, Shape hr) {
  Image p(hr.rows, hr.cols);
  if (options.prior == TikhonovPrior::kGradient || options.prior == TikhonovPrior::kLaplacian) {
    // Separable: the same arithmetic as TikhonovPriorSymbol (4 (sin²y + sin²x), squared for the Laplacian),
    // with the sines per row and per column instead of per pixel.
    std::vector<double> sy2(hr.rows), sx2(hr.cols);
    for (Index fy = 0; fy < hr.rows; ++fy) {
      const double s = std::sin(M_PI * double(fy) / double(hr.rows));
      sy2[fy] = s * s;
    }
    for (Index fx = 0; fx < hr.cols; ++fx) {
      const double s = std::sin(M_PI * double(fx) / double(hr.cols));
      sx2[fx] = s * s;
    }
    const bool laplacian = options.prior == TikhonovPrior::kLaplacian;
    ParallelFor(hr.rows, [&](Index fy) {
      for (Index fx = 0; fx < hr.cols; ++fx) {
        const double g = 4.0 * (sy2[fy] + sx2[fx]);
        p(fy, fx) = laplacian ? g * g : g;
      }
    });
    return p;
  }
  if (options.object_power_spectrum.size() > 0 || options.prior == TikhonovPrior::kIdentity) {
    ParallelFor(hr.rows, [&](Index fy) {
      for (Index fx = 0; fx < hr.cols; ++fx) p(fy, fx) = TikhonovPriorSymbol(options, hr, fy, fx);
    });
    return p;
  }
  // The parametric spectrum depends on the frequencies' squares only, so frequency k and n − k have the same
  // symbol to the bit: evaluate (one pow each) the quarter 0 <= k <= n/2 on each axis and mirror it. Every tile
  // of a whole detector builds this image for its own grid, and the pow was a sixth of a Tikhonov tile's time.
  const Index qr = hr.rows / 2 + 1, qc = hr.cols / 2 + 1;
  Image quarter(qr, qc);
  ParallelFor(qr, [&](Index fy) {
    for (Index fx = 0; fx < qc; ++fx) quarter(fy, fx) = TikhonovPriorSymbol(options, hr, fy, fx);
  });
  ParallelFor(hr.rows, [&](Index fy) {
    const Index qy = std::min(fy, hr.rows - fy);
    for (Index fx = 0; fx < hr.cols; ++fx) p(fy, fx) = quarter(qy, std::min(fx, hr.cols - fx));
  });
  return p;
}

}  // namespace tikhonov_internal

}  // namespace aosr
