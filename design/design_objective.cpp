#include "aosr/design/design_objective.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>

#include "aosr/core/error.hpp"
#include "aosr/core/fft.hpp"
#include "design_internal.hpp"

namespace aosr {
namespace {

using design_internal::BoxTransfer;
using design_internal::CheckSpectrumOptions;
using design_internal::PriorSymbol;

// Objective (A) from full-spectrum OTFs (M x M each): h0[i] nominal, real[ρ][i] realised (empty: A = A0).
// P: prior symbol, s: object spectrum (0 where left out), w = λ/r², c = σ²/r². Gradients Γ_H (Wirtinger, of J)
// are written when g0 is non-null (and greal when there are realisations).
double SpectralObjective(Shape hr, int r, const std::vector<ComplexImage>& h0,
                         const std::vector<std::vector<ComplexImage>>& real, const Image& P, const Image& s, double w,
                         double c, std::vector<ComplexImage>* g0, std::vector<std::vector<ComplexImage>>* greal) {
  const Shape lr{hr.rows / r, hr.cols / r};
  const std::vector<Complex> by = BoxTransfer(hr.rows, r), bx = BoxTransfer(hr.cols, r);
  const int n = int(h0.size()), rr = r * r, nreal = int(real.size());
  const bool want = g0 != nullptr;
  if (want) {
    g0->assign(n, ComplexImage::Zero(hr.rows, hr.cols));
    if (greal) greal->assign(nreal, std::vector<ComplexImage>(n, ComplexImage::Zero(hr.rows, hr.cols)));
  }
  const double scale = 1.0 / (double(hr.rows) * double(hr.cols));
  const double per_real = nreal > 0 ? 1.0 / nreal : 1.0;
  Eigen::MatrixXcd a0(n, rr), a(n, rr);
  Eigen::VectorXcd b(rr);
  Eigen::VectorXd pk(rr), sk(rr);
  std::vector<Index> fys(rr), fxs(rr);
  const Eigen::MatrixXcd eye_rr = Eigen::MatrixXcd::Identity(rr, rr);
  const Eigen::MatrixXcd eye_n = Eigen::MatrixXcd::Identity(n, n);
  double total = 0;
  for (Index uy = 0; uy < lr.rows; ++uy)
    for (Index ux = 0; ux < lr.cols; ++ux) {
      for (int ky = 0; ky < r; ++ky)
        for (int kx = 0; kx < r; ++kx) {
          const int k = ky * r + kx;
          const Index fy = uy + ky * lr.rows, fx = ux + kx * lr.cols;
          fys[k] = fy;
          fxs[k] = fx;
          b[k] = by[fy] * bx[fx] / double(rr);
          pk[k] = P(fy, fx);
          sk[k] = s(fy, fx);
          for (int i = 0; i < n; ++i) a0(i, k) = b[k] * h0[i](fy, fx);
        }
      Eigen::MatrixXcd ginv, rm;  // rm: r² x N
      design_internal::BinReconstructor(a0, pk, w, &ginv, &rm);
      double e = c * rm.squaredNorm();
      Eigen::MatrixXcd gamma_r;
      if (want) gamma_r = 2.0 * c * rm;
      Eigen::MatrixXcd ga0 = Eigen::MatrixXcd::Zero(n, rr);
      auto error_term = [&](const Eigen::MatrixXcd& at, double weight, Eigen::MatrixXcd* ga) {
        const Eigen::MatrixXcd f = rm * at - eye_rr;
        e += weight * (f.colwise().squaredNorm().transpose().array() * sk.array()).sum();
        if (want) {
          const Eigen::MatrixXcd fs = f * sk.asDiagonal();
          *ga = (2.0 * weight) * rm.adjoint() * fs;
          gamma_r += (2.0 * weight) * fs * at.adjoint();
        }
      };
      if (nreal == 0) {
        error_term(a0, 1.0, &ga0);
      } else {
        for (int q = 0; q < nreal; ++q) {
          for (int k = 0; k < rr; ++k)
            for (int i = 0; i < n; ++i) a(i, k) = b[k] * real[q][i](fys[k], fxs[k]);
          Eigen::MatrixXcd ga;
          error_term(a, per_real, &ga);
          if (want && greal)
            for (int k = 0; k < rr; ++k)
              for (int i = 0; i < n; ++i) (*greal)[q][i](fys[k], fxs[k]) = std::conj(b[k]) * ga(i, k) * scale;
        }
      }
      if (want) {
        const Eigen::MatrixXcd z = ginv * gamma_r;  // r² x N
        ga0 += (eye_n - a0 * rm) * z.adjoint() - a0 * z * rm.adjoint();
        for (int k = 0; k < rr; ++k)
          for (int i = 0; i < n; ++i) (*g0)[i](fys[k], fxs[k]) = std::conj(b[k]) * ga0(i, k) * scale;
      }
      total += e;
    }
  return total * scale;
}

// The object spectrum actually used: given, or (σ²/λ)/P with the P = 0 components left out.
Image ObjectSpectrum(const Image& given, const Image& p, double lambda, double sigma) {
  if (given.size() > 0) return given;
  Image s(p.rows(), p.cols());
  for (Index k = 0; k < p.size(); ++k) s.data()[k] = p.data()[k] > 0 ? sigma * sigma / (lambda * p.data()[k]) : 0.0;
  return s;
}

}  // namespace

namespace design_internal {

Image PriorSymbol(const TikhonovOptions& o, Shape hr) {
  Image p(hr.rows, hr.cols);
  for (Index fy = 0; fy < hr.rows; ++fy)
    for (Index fx = 0; fx < hr.cols; ++fx) p(fy, fx) = TikhonovPriorSymbol(o, hr, fy, fx);
  return p;
}

void CheckSpectrumOptions(const char* fn, const TikhonovOptions& o, double sigma, const Image& spectrum, Shape hr) {
  std::string why;
  if (!o.IsValid(&why)) throw InvalidArgument(std::string(fn) + ": reconstructor." + why);
  CheckArgument(o.lambda_rule == TikhonovLambdaRule::kFixed, fn, "reconstructor.lambda_rule", ToString(o.lambda_rule),
                "fixed (the design minimises the MSE of one reconstructor)");
  CheckArgument(o.lambda > 0, fn, "reconstructor.lambda", o.lambda, "> 0");
  CheckArgument(std::isfinite(sigma) && sigma > 0, fn, "noise_sigma", sigma, "> 0 and finite");
  if (spectrum.size() > 0) {
    CheckArgument(ShapeOf(spectrum) == hr, fn, "object_power_spectrum shape", ToString(ShapeOf(spectrum)),
                  "the HR design grid " + ToString(hr));
    CheckArgument(AllFinite(spectrum) && (spectrum >= 0).all(), fn, "object_power_spectrum",
                  "negative or non-finite values", "finite values >= 0");
  }
}

}  // namespace design_internal

bool DesignObjectiveOptions::IsValid(std::string* why) const {
  auto fail = [why](const std::string& m) {
    if (why) *why = m;
    return false;
  };
  std::string w;
  if (!reconstructor.IsValid(&w)) return fail("reconstructor." + w);
  if (reconstructor.lambda_rule != TikhonovLambdaRule::kFixed)
    return fail("reconstructor.lambda_rule = " + std::string(ToString(reconstructor.lambda_rule)) + "; allowed: fixed");
  if (!(reconstructor.lambda > 0)) return fail("reconstructor.lambda = " + ToString(reconstructor.lambda) + "; allowed: > 0");
  if (!(std::isfinite(noise_sigma) && noise_sigma > 0))
    return fail("noise_sigma = " + ToString(noise_sigma) + "; allowed: > 0 and finite");
  if (realisations < 0 || realisations > 64) return fail("realisations = " + std::to_string(realisations) + "; allowed: 0 .. 64");
  if (screens < 1 || screens > 256) return fail("screens = " + std::to_string(screens) + "; allowed: 1 .. 256");
  if (threads < 1 || threads > 64) return fail("threads = " + std::to_string(threads) + "; allowed: 1 .. 64");
  return true;
}

namespace {

const DesignObjectiveOptions& ValidatedOptions(const DesignObjectiveOptions& options) {
  std::string why;
  if (!options.IsValid(&why)) throw InvalidArgument("DesignObjective: options." + why);
  return options;
}

}  // namespace

DesignObjective::DesignObjective(const DesignOptics& optics, int frames, const DesignObjectiveOptions& options)
    : options_(ValidatedOptions(options)),
      psf_(optics, frames, options.realisations, options.screens, options.seed, options.threads, "DesignObjective") {
  const char* fn = "DesignObjective";
  const Shape hr{optics.grid, optics.grid};
  CheckSpectrumOptions(fn, options.reconstructor, options.noise_sigma, options.object_power_spectrum, hr);
  p_ = PriorSymbol(options.reconstructor, hr);
  s_ = ObjectSpectrum(options.object_power_spectrum, p_, options.reconstructor.lambda, options.noise_sigma);
  {
    const std::vector<Complex> by = BoxTransfer(hr.rows, optics.r), bx = BoxTransfer(hr.cols, optics.r);
    const double to_m = optics.wavelength_m / (double(optics.grid) * optics.hr_pixel_rad);  // ρ per frequency bin
    for (Index fy = 0; fy < hr.rows; ++fy)
      for (Index fx = 0; fx < hr.cols; ++fx) {
        const double ry = to_m * double(SignedFrequency(fy, hr.rows)), rx = to_m * double(SignedFrequency(fx, hr.cols));
        const bool beyond = std::hypot(ry, rx) >= optics.diameter_m;
        if (beyond || std::abs(by[fy] * bx[fx]) < 1e-9) floor_ += s_(fy, fx);
      }
    floor_ /= double(hr.size());
  }
}

double DesignObjective::EvaluateImpl(const std::vector<Image>& dm_opds, std::vector<Image>* grad) const {
  const DesignPsfModel::Set set = psf_.Compute(dm_opds, "DesignObjective::Evaluate");
  const DesignOptics& optics = psf_.optics();
  const Shape hr{optics.grid, optics.grid};
  const double r2 = double(optics.r * optics.r);
  const double sigma2 = options_.noise_sigma * options_.noise_sigma;
  std::vector<ComplexImage> g0;
  std::vector<std::vector<ComplexImage>> greal;
  const double j = SpectralObjective(hr, optics.r, set.nominal, set.realised, p_, s_, options_.reconstructor.lambda / r2,
                                     sigma2 / r2, grad ? &g0 : nullptr, grad ? &greal : nullptr);
  if (!std::isfinite(j)) throw NumericalError("DesignObjective: objective A is not finite");
  if (grad) psf_.PullBack(set, g0, greal, grad);
  return j;
}

MultiFrameModel DesignObjective::NominalModel(const std::vector<Image>& dm_opds) const {
  // The nominal PSFs only (no realisations computed).
  return psf_.NominalModel(psf_.Compute(dm_opds, "DesignObjective::NominalModel", /*with_realisations=*/false));
}

std::vector<MultiFrameModel> DesignObjective::RealisedModels(const std::vector<Image>& dm_opds) const {
  const DesignPsfModel::Set set = psf_.Compute(dm_opds, "DesignObjective::RealisedModels");
  std::vector<MultiFrameModel> out;
  for (int q = 0; q < psf_.realisations(); ++q) out.push_back(psf_.RealisedModel(set, q));
  return out;
}

double ExpectedTikhonovMse(const MultiFrameModel& nominal, const std::vector<MultiFrameModel>& truths,
                           const TikhonovOptions& reconstructor, double noise_sigma, const Image& object_power_spectrum) {
  const char* fn = "ExpectedTikhonovMse";
  const Shape hr = nominal.hr_shape();
  CheckSpectrumOptions(fn, reconstructor, noise_sigma, object_power_spectrum, hr);
  for (std::size_t q = 0; q < truths.size(); ++q)
    CheckArgument(truths[q].hr_shape() == hr && truths[q].r() == nominal.r() && truths[q].frames() == nominal.frames(), fn,
                  "truths[" + std::to_string(q) + "]", ToString(truths[q].hr_shape()) + ", r " + std::to_string(truths[q].r()),
                  "the nominal model's grid, r and frame count");
  auto full = [&](const MultiFrameModel& m) {
    std::vector<ComplexImage> out;
    for (int i = 0; i < m.frames(); ++i) {
      ComplexImage h(hr.rows, hr.cols);
      for (Index fy = 0; fy < hr.rows; ++fy)
        for (Index fx = 0; fx < hr.cols; ++fx) h(fy, fx) = m.Otf(i, fy, fx);
      out.push_back(h);
    }
    return out;
  };
  std::vector<std::vector<ComplexImage>> real;
  for (const MultiFrameModel& t : truths) real.push_back(full(t));
  const Image p = PriorSymbol(reconstructor, hr);
  const Image s = ObjectSpectrum(object_power_spectrum, p, reconstructor.lambda, noise_sigma);
  const double r2 = double(nominal.r() * nominal.r());
  return SpectralObjective(hr, nominal.r(), full(nominal), real, p, s, reconstructor.lambda / r2,
                           noise_sigma * noise_sigma / r2, nullptr, nullptr);
}

}  // namespace aosr
