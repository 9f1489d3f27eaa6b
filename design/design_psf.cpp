#include "aosr/design/design_psf.hpp"

#include <algorithm>
#include <cmath>
#include <random>

#include "aosr/core/error.hpp"
#include "aosr/core/fft.hpp"
#include "aosr/core/memory.hpp"
#include "aosr/optics/zernike.hpp"
#include "design_internal.hpp"

namespace aosr {


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

namespace {

MftGeometry ObjectiveMft(const DesignOptics& o, const std::string& fn) {
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
    if (!o.ao->IsValid(&why)) throw InvalidArgument(fn + ": optics.ao." + why);
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

MultiFrameModel ModelOf(Shape hr, int r, const std::vector<ComplexImage>& full) {
  std::vector<ComplexImage> half;
  for (const ComplexImage& h : full) half.push_back(h.leftCols(hr.cols / 2 + 1));
  return MultiFrameModel(hr, r, std::move(half));
}

}  // namespace

DesignPsfModel::DesignPsfModel(const DesignOptics& optics, int frames, int realisations, int screens,
                               std::uint64_t seed, int threads, const std::string& fn)
    : optics_(optics), frames_(frames), threads_(threads), n_(optics.amplitude.rows()), mft_(ObjectiveMft(optics, fn)) {
  CheckArgument(frames >= 1 && frames <= 1024, fn, "frames", frames, "1 .. 1024");
  CheckArgument(realisations >= 0 && realisations <= 64, fn, "realisations", realisations, "0 .. 64");
  CheckArgument(screens >= 1 && screens <= 256, fn, "screens", screens, "1 .. 256");
  CheckArgument(threads >= 1 && threads <= 64, fn, "threads", threads, "1 .. 64");
  {
    // The residual screens (n² each, R·N·L of them), the OTFs of the nominal and realised models (M² complex,
    // N·(R+1)) and, per thread, the pupil field and PSF work of one exposure (a few (2n)² complex grids).
    const double n2 = double(n_) * double(n_), m2 = double(optics.grid) * double(optics.grid);
    const double screens_bytes = optics.ao ? 8.0 * n2 * realisations * double(frames) * screens : 0.0;
    CheckMemory(screens_bytes + 16.0 * m2 * frames * (realisations + 1.0) * 2 + 4 * 16.0 * 4 * n2 * threads,
                fn + ": a design of " + std::to_string(frames) + " frames on the " + std::to_string(optics.grid) + "^2 grid with " +
                    std::to_string(realisations) + " realisations x " + std::to_string(screens) + " screens of " +
                    std::to_string(n_) + "^2");
  }
  for (Index p = 0; p < optics.amplitude.size(); ++p)
    if (optics.amplitude.data()[p] > 0) lit_.push_back(p);
  // The periodic path when the sampled pupil's PSF period, Q = n / s pixels (s = θ_hr D / λ), is a whole
  // multiple of M: then the PSF folded onto the M grid is exact (no window), and its DFT samples the OTF.
  {
    const double qd = double(n_) * optics.wavelength_m / (optics.diameter_m * optics.hr_pixel_rad);
    const Index qi = Index(std::llround(qd));
    if (std::abs(qd - double(qi)) < 1e-6 * qd && qi >= optics.grid && qi % optics.grid == 0 && qi <= 8192) period_ = qi;
  }
  t_ = Image::Ones(optics.grid, optics.grid);
  if (optics.ao) {
    const AnalyticAoResidual res(*optics.ao, n_);
    t_ = AoFactor(res, optics);
    if (realisations > 0) {
      const std::vector<Image> all = DrawScreens(res, realisations * frames * screens, seed, optics.wavelength_m);
      screens_.assign(realisations, std::vector<std::vector<Image>>(frames));
      int k = 0;
      for (int q = 0; q < realisations; ++q)
        for (int i = 0; i < frames; ++i)
          for (int l = 0; l < screens; ++l) screens_[q][i].push_back(all[k++]);
    }
  }
}

DesignPsfModel::Psf DesignPsfModel::ComputePsf(const Image& opd, const std::vector<const Image*>& screens) const {
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

DesignPsfModel::Psf DesignPsfModel::ComputePeriodicPsf(const Image& opd, const std::vector<const Image*>& screens) const {
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

void DesignPsfModel::PsfPullBack(const Psf& psf, const ComplexImage& gamma_h, Image* grad) const {
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

DesignPsfModel::Set DesignPsfModel::Compute(const std::vector<Image>& dm_opds, const char* fn,
                                            bool with_realisations) const {
  CheckOpds(fn, dm_opds, frames_, n_, lit_);
  const int nreal = with_realisations ? realisations() : 0;
  std::vector<Image> base(frames_);
  for (int i = 0; i < frames_; ++i) base[i] = optics_.static_opd_m.size() ? Image(dm_opds[i] + optics_.static_opd_m) : dm_opds[i];
  // Task t < N is the nominal PSF of exposure t; task N + q N + i realisation q of exposure i.
  const int tasks = frames_ * (1 + nreal);
  Set set;
  set.psfs.resize(tasks);
  ParallelFor(tasks, threads_, [&](int t) {
    std::vector<const Image*> screens;
    if (t >= frames_) {
      const int q = (t - frames_) / frames_, i = (t - frames_) % frames_;
      for (const Image& s : screens_[q][i]) screens.push_back(&s);
    }
    set.psfs[t] = period_ > 0 ? ComputePeriodicPsf(base[t % frames_], screens) : ComputePsf(base[t % frames_], screens);
  });
  set.nominal.resize(frames_);
  for (int i = 0; i < frames_; ++i) set.nominal[i] = set.psfs[i].otf * t_.cast<Complex>();
  set.realised.assign(nreal, std::vector<ComplexImage>(frames_));
  for (int q = 0; q < nreal; ++q)
    for (int i = 0; i < frames_; ++i) set.realised[q][i] = set.psfs[frames_ + q * frames_ + i].otf;
  return set;
}

void DesignPsfModel::PullBack(const Set& set, const std::vector<ComplexImage>& gamma_nominal,
                              const std::vector<std::vector<ComplexImage>>& gamma_realised,
                              std::vector<Image>* grad) const {
  const int nreal = int(set.realised.size());
  const int tasks = frames_ * (1 + nreal);
  if (int(set.psfs.size()) != tasks || int(gamma_nominal.size()) != frames_ ||
      !(gamma_realised.empty() || int(gamma_realised.size()) == nreal))
    throw InvalidArgument("DesignPsfModel::PullBack", "set or gamma sizes", "inconsistent", "those of Compute()");
  std::vector<Image> parts(tasks, Image::Zero(n_, n_));
  ParallelFor(tasks, threads_, [&](int t) {
    if (t < frames_) {
      PsfPullBack(set.psfs[t], gamma_nominal[t] * t_.cast<Complex>(), &parts[t]);
    } else if (!gamma_realised.empty()) {
      const int q = (t - frames_) / frames_, i = (t - frames_) % frames_;
      PsfPullBack(set.psfs[t], gamma_realised[q][i], &parts[t]);
    }
  });
  grad->assign(frames_, Image::Zero(n_, n_));
  for (int t = 0; t < tasks; ++t) (*grad)[t % frames_] += parts[t];
}

MultiFrameModel DesignPsfModel::NominalModel(const Set& set) const {
  return ModelOf(hr_shape(), optics_.r, set.nominal);
}

MultiFrameModel DesignPsfModel::RealisedModel(const Set& set, int realisation) const {
  CheckArgument(realisation >= 0 && realisation < int(set.realised.size()), "DesignPsfModel::RealisedModel",
                "realisation", realisation, "0 .. " + std::to_string(int(set.realised.size()) - 1));
  return ModelOf(hr_shape(), optics_.r, set.realised[realisation]);
}

}  // namespace aosr
