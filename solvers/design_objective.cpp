#include "aosr/solvers/design_objective.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <random>
#include <mutex>
#include <thread>

#include "aosr/core/error.hpp"
#include "aosr/core/fft.hpp"
#include "aosr/optics/zernike.hpp"

namespace aosr {
namespace {

constexpr double kTwoPi = 6.283185307179586476925286766559;

// Σ_{k=0}^{r-1} exp(+2πi f k / n) for every bin f of an axis of length n (forward_model.hpp's B).
std::vector<Complex> BoxTransfer(Index n, int r) {
  std::vector<Complex> b(n);
  for (Index f = 0; f < n; ++f) {
    Complex s = 0;
    for (int k = 0; k < r; ++k) s += std::polar(1.0, kTwoPi * double(f) * k / double(n));
    b[f] = s;
  }
  return b;
}

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
      Eigen::MatrixXcd g = a0.adjoint() * a0;
      g.diagonal().array() += w * pk.array();
      Eigen::MatrixXcd ginv;
      const Eigen::LLT<Eigen::MatrixXcd> llt(g);
      if (llt.info() == Eigen::Success) {
        ginv = llt.solve(eye_rr);
      } else {
        ginv = g.completeOrthogonalDecomposition().pseudoInverse();
      }
      const Eigen::MatrixXcd rm = ginv * a0.adjoint();  // r² x N
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

Image PriorSymbol(const TikhonovOptions& o, Shape hr) {
  Image p(hr.rows, hr.cols);
  for (Index fy = 0; fy < hr.rows; ++fy)
    for (Index fx = 0; fx < hr.cols; ++fx) p(fy, fx) = TikhonovPriorSymbol(o, hr, fy, fx);
  return p;
}

// The object spectrum actually used: given, or (σ²/λ)/P with the P = 0 components left out.
Image ObjectSpectrum(const Image& given, const Image& p, double lambda, double sigma) {
  if (given.size() > 0) return given;
  Image s(p.rows(), p.cols());
  for (Index k = 0; k < p.size(); ++k) s.data()[k] = p.data()[k] > 0 ? sigma * sigma / (lambda * p.data()[k]) : 0.0;
  return s;
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

// Runs fn(0..count-1) on up to `threads` threads.
template <typename F>
void ParallelFor(int count, int threads, F fn) {
  threads = std::max(1, std::min(threads, count));
  if (threads == 1) {
    for (int k = 0; k < count; ++k) fn(k);
    return;
  }
  std::vector<std::thread> pool;
  std::exception_ptr error;
  std::mutex m;
  for (int t = 0; t < threads; ++t)
    pool.emplace_back([&, t] {
      try {
        for (int k = t; k < count; k += threads) fn(k);
      } catch (...) {
        std::lock_guard<std::mutex> lock(m);
        if (!error) error = std::current_exception();
      }
    });
  for (std::thread& th : pool) th.join();
  if (error) std::rethrow_exception(error);
}

}  // namespace

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

DesignOptics DesignOpticsFromScene(const SceneSpec& scene) {
  DesignOptics o;
  const Index n = scene.telescope.pupil_px;
  o.amplitude = scene.telescope.PupilAmplitude();
  o.diameter_m = scene.telescope.aperture.pupil.diameter_m;
  o.wavelength_m = scene.telescope.science_wavelength_m;
  o.hr_pixel_rad = scene.HrPixelRad();
  o.r = scene.r;
  const Index step = 2 * scene.r;
  o.grid = std::max<Index>(step, (scene.psf_size_px + step - 1) / step * step);
  if (!scene.static_aberrations.empty()) {
    o.static_opd_m = Image::Zero(n, n);
    for (const DmOffset::Term& t : scene.static_aberrations)
      o.static_opd_m += t.rms_m * Zernike(t.noll, n, scene.telescope.aperture.pupil.obstruction);
  }
  if (scene.ao.mode != AoSpec::Mode::kNone && scene.telescope.atmosphere && scene.telescope.ao)
    o.ao = scene.telescope.ToAnalyticAo();
  return o;
}

struct DesignObjective::Psf {
  std::vector<ComplexImage> fields;  // E_l (n x n)
  std::vector<ComplexImage> y;       // MFT(E_l) (M x M)
  Image h;                           // unit-sum PSF, centred
  double sum = 0;                    // Σ p
  ComplexImage otf;                  // full spectrum of h (origin at (0,0))
};

namespace {

MftGeometry ObjectiveMft(const DesignOptics& o) {
  const char* fn = "DesignObjective";
  const Index n = o.amplitude.rows();
  CheckArgument(n >= 8 && o.amplitude.cols() == n, fn, "optics.amplitude shape", ToString(ShapeOf(o.amplitude)),
                "square n x n with n >= 8");
  CheckArgument(AllFinite(o.amplitude) && (o.amplitude >= 0).all() && o.amplitude.sum() > 0, fn, "optics.amplitude",
                "negative, non-finite or all zero", "finite values >= 0, some > 0");
  CheckArgument(std::isfinite(o.diameter_m) && o.diameter_m > 0, fn, "optics.diameter_m", o.diameter_m, "> 0 [m]");
  CheckArgument(std::isfinite(o.wavelength_m) && o.wavelength_m > 0, fn, "optics.wavelength_m", o.wavelength_m, "> 0 [m]");
  CheckArgument(o.r >= 1 && o.r <= 16, fn, "optics.r", o.r, "1 .. 16");
  const double lod = o.wavelength_m / o.diameter_m;
  CheckArgument(std::isfinite(o.hr_pixel_rad) && o.hr_pixel_rad > 0 && o.hr_pixel_rad <= lod * (1 + 1e-9), fn,
                "optics.hr_pixel_rad", o.hr_pixel_rad, "> 0 and <= lambda/D = " + ToString(lod) + " rad");
  CheckArgument(o.grid >= 4 && o.grid % 2 == 0 && o.grid % o.r == 0 && o.grid <= 4096, fn, "optics.grid", o.grid,
                "even, a multiple of r, in [4, 4096]");
  if (o.static_opd_m.size() > 0)
    CheckArgument(ShapeOf(o.static_opd_m) == ShapeOf(o.amplitude) && AllFinite(o.static_opd_m), fn,
                  "optics.static_opd_m", ToString(ShapeOf(o.static_opd_m)), "empty or finite, the pupil's shape");
  if (o.ao) {
    std::string why;
    if (!o.ao->IsValid(&why)) throw InvalidArgument(std::string(fn) + ": optics.ao." + why);
    CheckArgument(std::abs(o.ao->science_wavelength_m / o.wavelength_m - 1) < 1e-9, fn, "optics.ao.science_wavelength_m",
                  o.ao->science_wavelength_m, "the optics' wavelength " + ToString(o.wavelength_m));
    CheckArgument(std::abs(o.ao->diameter_m / o.diameter_m - 1) < 1e-9, fn, "optics.ao.diameter_m", o.ao->diameter_m,
                  "the optics' diameter " + ToString(o.diameter_m));
  }
  MftGeometry g;
  g.input = {n, n};
  g.pupil_span_px = double(n);
  g.output = {o.grid, o.grid};
  g.pixel_scale_lod = o.hr_pixel_rad / lod;
  return g;
}

// exp(−D_in/2) at every HR frequency of the M x M grid, bilinear on the (2n−1)² separation lattice (clamped).
Image AoFactor(const AnalyticAoResidual& res, const DesignOptics& o) {
  const Image& d = res.in_band_structure_function();
  const Index n = res.pupil_n(), lat = d.rows();
  const double step = res.separation_step_m(), M = double(o.grid);
  Image t(o.grid, o.grid);
  for (Index fy = 0; fy < o.grid; ++fy)
    for (Index fx = 0; fx < o.grid; ++fx) {
      // Pupil separation ρ = λ f [m], f in cycles per radian.
      const double ry = o.wavelength_m * double(SignedFrequency(fy, o.grid)) / (M * o.hr_pixel_rad);
      const double rx = o.wavelength_m * double(SignedFrequency(fx, o.grid)) / (M * o.hr_pixel_rad);
      const double py = std::clamp(double(n - 1) + ry / step, 0.0, double(lat - 1));
      const double px = std::clamp(double(n - 1) + rx / step, 0.0, double(lat - 1));
      const Index y0 = std::min<Index>(Index(py), lat - 2), x0 = std::min<Index>(Index(px), lat - 2);
      const double ay = py - y0, ax = px - x0;
      const double v = (1 - ay) * ((1 - ax) * d(y0, x0) + ax * d(y0, x0 + 1)) +
                       ay * ((1 - ax) * d(y0 + 1, x0) + ax * d(y0 + 1, x0 + 1));
      t(fy, fx) = std::exp(-0.5 * v);
    }
  return t;
}

// Residual OPD screens [m] (n x n) from the PSD grid of the analytic model: FFT screens on its K n x K n grid
// of pitch D/n, both real and imaginary parts used.
std::vector<Image> DrawScreens(const AnalyticAoResidual& res, int count, std::uint64_t seed, double wavelength_m) {
  const ResidualPsd& psd = res.psd();
  const Image phi = psd.Total();
  const Index p = phi.rows(), n = res.pupil_n();
  const double df = psd.frequency_step_per_m;
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> n01;
  std::vector<Image> out;
  while (int(out.size()) < count) {
    ComplexImage z(p, p);
    for (Index i = 0; i < p; ++i)
      for (Index j = 0; j < p; ++j) {
        const double amp = std::sqrt(std::max(0.0, phi(i, j))) * df;
        const double re = n01(rng), im = n01(rng);
        z((i + p / 2) % p, (j + p / 2) % p) = Complex(re, im) * amp;
      }
    const ComplexImage w = FftInverse(z) * (double(p) * double(p));
    const double to_m = wavelength_m / kTwoPi;
    out.push_back(w.real().topLeftCorner(n, n) * to_m);
    if (int(out.size()) < count) out.push_back(w.imag().topLeftCorner(n, n) * to_m);
  }
  return out;
}

}  // namespace

DesignObjective::DesignObjective(const DesignOptics& optics, int frames, const DesignObjectiveOptions& options)
    : optics_(optics), frames_(frames), options_(options), n_(optics.amplitude.rows()), mft_(ObjectiveMft(optics)) {
  const char* fn = "DesignObjective";
  CheckArgument(frames >= 1 && frames <= 1024, fn, "frames", frames, "1 .. 1024");
  std::string why;
  if (!options.IsValid(&why)) throw InvalidArgument(std::string(fn) + ": options." + why);
  const Shape hr{optics.grid, optics.grid};
  CheckSpectrumOptions(fn, options.reconstructor, options.noise_sigma, options.object_power_spectrum, hr);
  for (Index p = 0; p < optics.amplitude.size(); ++p)
    if (optics.amplitude.data()[p] > 0) lit_.push_back(p);
  // The periodic path when the sampled pupil's PSF period, Q = n / s pixels (s = θ_hr D / λ), is a whole
  // multiple of M: then the PSF folded onto the M grid is exact (no window), and its DFT samples the OTF.
  {
    const double qd = double(n_) * optics.wavelength_m / (optics.diameter_m * optics.hr_pixel_rad);
    const Index qi = Index(std::llround(qd));
    if (std::abs(qd - double(qi)) < 1e-6 * qd && qi >= optics.grid && qi % optics.grid == 0 && qi <= 8192) period_ = qi;
  }
  p_ = PriorSymbol(options.reconstructor, hr);
  s_ = ObjectSpectrum(options.object_power_spectrum, p_, options.reconstructor.lambda, options.noise_sigma);
  t_ = Image::Ones(hr.rows, hr.cols);
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
  if (optics.ao) {
    const AnalyticAoResidual res(*optics.ao, n_);
    t_ = AoFactor(res, optics);
    if (options.realisations > 0) {
      const int per = options.screens;
      const std::vector<Image> all = DrawScreens(res, options.realisations * frames * per, options.seed, optics.wavelength_m);
      screens_.assign(options.realisations, std::vector<std::vector<Image>>(frames));
      int k = 0;
      for (int q = 0; q < options.realisations; ++q)
        for (int i = 0; i < frames; ++i)
          for (int l = 0; l < per; ++l) screens_[q][i].push_back(all[k++]);
    }
  }
}

DesignObjective::Psf DesignObjective::ComputePsf(const Image& opd, const std::vector<const Image*>& screens) const {
  Psf psf;
  const double k = kTwoPi / optics_.wavelength_m;
  const Index m = optics_.grid;
  Image p = Image::Zero(m, m);
  const std::size_t count = std::max<std::size_t>(1, screens.size());
  for (std::size_t l = 0; l < count; ++l) {
    ComplexImage e = ComplexImage::Zero(n_, n_);
    for (Index q : lit_) {
      const double w = opd.data()[q] + (screens.empty() ? 0.0 : screens[l]->data()[q]);
      e.data()[q] = std::polar(optics_.amplitude.data()[q], k * w);
    }
    ComplexImage y = mft_.Apply(e);
    p += y.abs2();
    psf.fields.push_back(std::move(e));
    psf.y.push_back(std::move(y));
  }
  psf.sum = p.sum();
  if (!(psf.sum > 0) || !std::isfinite(psf.sum)) throw NumericalError("DesignObjective: a PSF has no light in the window");
  psf.h = p / psf.sum;
  psf.otf = FftForward(CentredToOrigin(psf.h, {m, m}).cast<Complex>());
  return psf;
}

DesignObjective::Psf DesignObjective::ComputePeriodicPsf(const Image& opd, const std::vector<const Image*>& screens) const {
  Psf psf;
  const double k = kTwoPi / optics_.wavelength_m;
  const Index m = optics_.grid, q = period_;
  Image p = Image::Zero(m, m);
  const std::size_t count = std::max<std::size_t>(1, screens.size());
  for (std::size_t l = 0; l < count; ++l) {
    ComplexImage e = ComplexImage::Zero(q, q);  // the field at the top left of the Q x Q grid
    for (Index idx : lit_) {
      const double w = opd.data()[idx] + (screens.empty() ? 0.0 : screens[l]->data()[idx]);
      e(idx / n_, idx % n_) = std::polar(optics_.amplitude.data()[idx], k * w);
    }
    ComplexImage y = FftForward(e);
    // |Y|² is the PSF at α = j·s over one whole period (origin at (0,0)); fold it onto the M x M grid.
    for (Index a = 0; a < q; ++a)
      for (Index b = 0; b < q; ++b) p(a % m, b % m) += std::norm(y(a, b));
    psf.fields.push_back(std::move(e));
    psf.y.push_back(std::move(y));
  }
  psf.sum = p.sum();
  if (!(psf.sum > 0) || !std::isfinite(psf.sum)) throw NumericalError("DesignObjective: a PSF has no light");
  psf.h = p / psf.sum;  // origin layout
  psf.otf = FftForward(psf.h.cast<Complex>());
  return psf;
}

void DesignObjective::PsfPullBack(const Psf& psf, const ComplexImage& gamma_h, Image* grad) const {
  const Index m = optics_.grid;
  const double k = kTwoPi / optics_.wavelength_m;
  const Image gt = FftInverse(gamma_h).real() * (double(m) * double(m));
  if (period_ > 0) {
    const Index q = period_;
    const Image gp = (gt - (gt * psf.h).sum()) / psf.sum;
    ComplexImage tiled(q, q);
    for (Index a = 0; a < q; ++a)
      for (Index b = 0; b < q; ++b) tiled(a, b) = gp(a % m, b % m);
    for (std::size_t l = 0; l < psf.fields.size(); ++l) {
      // Γ_E = 2 F^H(G ⊙ Y), F^H the unnormalised inverse DFT.
      const ComplexImage ge = FftInverse(tiled * psf.y[l]) * (2.0 * double(q) * double(q));
      const ComplexImage& e = psf.fields[l];
      for (Index idx : lit_) {
        const Index i = idx / n_, j = idx % n_;
        grad->data()[idx] += k * std::imag(ge(i, j) * std::conj(e(i, j)));
      }
    }
    return;
  }
  const Image gh = OriginToCentred(gt, {m, m});
  const Image gp = (gh - (gh * psf.h).sum()) / psf.sum;
  const ComplexImage gpc = gp.cast<Complex>();
  for (std::size_t l = 0; l < psf.fields.size(); ++l) {
    const ComplexImage ge = 2.0 * mft_.ApplyAdjoint(gpc * psf.y[l]);
    const ComplexImage& e = psf.fields[l];
    for (Index q : lit_) grad->data()[q] += k * std::imag(ge.data()[q] * std::conj(e.data()[q]));
  }
}

namespace {

void CheckOpds(const char* fn, const std::vector<Image>& opds, int frames, Index n, const std::vector<Index>& lit) {
  CheckArgument(int(opds.size()) == frames, fn, "dm_opds count", opds.size(), std::to_string(frames));
  for (std::size_t i = 0; i < opds.size(); ++i) {
    CheckArgument(ShapeOf(opds[i]) == Shape{n, n}, fn, "dm_opds[" + std::to_string(i) + "] shape",
                  ToString(ShapeOf(opds[i])), ToString(Shape{n, n}) + " (the pupil grid)");
    for (Index q : lit)
      if (!std::isfinite(opds[i].data()[q]))
        throw InvalidArgument(fn, "dm_opds[" + std::to_string(i) + "]", "non-finite", "finite values where the pupil transmits");
  }
}

}  // namespace

double DesignObjective::Evaluate(const std::vector<Image>& dm_opds, std::vector<Image>* grad) const {
  const char* fn = "DesignObjective::Evaluate";
  CheckOpds(fn, dm_opds, frames_, n_, lit_);
  const int nreal = realisations();
  std::vector<Image> base(frames_);
  for (int i = 0; i < frames_; ++i) base[i] = optics_.static_opd_m.size() ? Image(dm_opds[i] + optics_.static_opd_m) : dm_opds[i];
  // PSFs: task t < N is the nominal PSF of exposure t; task N + q N + i realisation q of exposure i.
  const int tasks = frames_ * (1 + nreal);
  std::vector<Psf> psfs(tasks);
  ParallelFor(tasks, options_.threads, [&](int t) {
    std::vector<const Image*> screens;
    if (t >= frames_) {
      const int q = (t - frames_) / frames_, i = (t - frames_) % frames_;
      for (const Image& s : screens_[q][i]) screens.push_back(&s);
    }
    psfs[t] = period_ > 0 ? ComputePeriodicPsf(base[t % frames_], screens) : ComputePsf(base[t % frames_], screens);
  });
  std::vector<ComplexImage> h0(frames_);
  for (int i = 0; i < frames_; ++i) h0[i] = psfs[i].otf * t_.cast<Complex>();
  std::vector<std::vector<ComplexImage>> real(nreal, std::vector<ComplexImage>(frames_));
  for (int q = 0; q < nreal; ++q)
    for (int i = 0; i < frames_; ++i) real[q][i] = psfs[frames_ + q * frames_ + i].otf;
  const Shape hr{optics_.grid, optics_.grid};
  const double r2 = double(optics_.r * optics_.r);
  const double sigma2 = options_.noise_sigma * options_.noise_sigma;
  std::vector<ComplexImage> g0;
  std::vector<std::vector<ComplexImage>> greal;
  const double j = SpectralObjective(hr, optics_.r, h0, real, p_, s_, options_.reconstructor.lambda / r2, sigma2 / r2,
                                     grad ? &g0 : nullptr, grad ? &greal : nullptr);
  if (!std::isfinite(j)) throw NumericalError("DesignObjective: objective A is not finite");
  if (grad) {
    std::vector<Image> parts(tasks, Image::Zero(n_, n_));
    ParallelFor(tasks, options_.threads, [&](int t) {
      if (t < frames_) {
        PsfPullBack(psfs[t], g0[t] * t_.cast<Complex>(), &parts[t]);
      } else {
        const int q = (t - frames_) / frames_, i = (t - frames_) % frames_;
        PsfPullBack(psfs[t], greal[q][i], &parts[t]);
      }
    });
    grad->assign(frames_, Image::Zero(n_, n_));
    for (int t = 0; t < tasks; ++t) (*grad)[t % frames_] += parts[t];
  }
  return j;
}

namespace {

MultiFrameModel ModelOf(Shape hr, int r, const std::vector<ComplexImage>& full) {
  std::vector<ComplexImage> half;
  for (const ComplexImage& h : full) half.push_back(h.leftCols(hr.cols / 2 + 1));
  return MultiFrameModel(hr, r, std::move(half));
}

}  // namespace

MultiFrameModel DesignObjective::NominalModel(const std::vector<Image>& dm_opds) const {
  CheckOpds("DesignObjective::NominalModel", dm_opds, frames_, n_, lit_);
  std::vector<ComplexImage> h;
  for (int i = 0; i < frames_; ++i) {
    const Image w = optics_.static_opd_m.size() ? Image(dm_opds[i] + optics_.static_opd_m) : dm_opds[i];
    h.push_back((period_ > 0 ? ComputePeriodicPsf(w, {}) : ComputePsf(w, {})).otf * t_.cast<Complex>());
  }
  return ModelOf({optics_.grid, optics_.grid}, optics_.r, h);
}

std::vector<MultiFrameModel> DesignObjective::RealisedModels(const std::vector<Image>& dm_opds) const {
  CheckOpds("DesignObjective::RealisedModels", dm_opds, frames_, n_, lit_);
  std::vector<MultiFrameModel> out;
  for (int q = 0; q < realisations(); ++q) {
    std::vector<ComplexImage> h;
    for (int i = 0; i < frames_; ++i) {
      const Image w = optics_.static_opd_m.size() ? Image(dm_opds[i] + optics_.static_opd_m) : dm_opds[i];
      std::vector<const Image*> screens;
      for (const Image& s : screens_[q][i]) screens.push_back(&s);
      h.push_back((period_ > 0 ? ComputePeriodicPsf(w, screens) : ComputePsf(w, screens)).otf);
    }
    out.push_back(ModelOf({optics_.grid, optics_.grid}, optics_.r, h));
  }
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
