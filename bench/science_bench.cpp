// Science benchmark: what an astronomer measures on each reconstruction of the same frames.
//
// 1. Resolution against noise (the paper's system, r = 2 and 4): Drizzle's output FWHM and noise, and the
//    target-PSF linear reconstruction (target_psf.hpp) (a) at Drizzle's FWHM: its noise, and (b) at Drizzle's
//    noise: its FWHM. FWHMs are of each method's *effective PSF*, measured the same way for every method:
//    the reconstruction of noiseless frames of one point source, averaged over the sub-pixel phases of the
//    HR cell within a camera pixel (core of psf_metrics.hpp: equivalent-area FWHM). Noise: the same noise
//    realisations (n ~ N(0, 1/w), the dataset's inverse-variance weights) pushed through each method, RMS
//    over the trustworthy region.
// 2. Photometry and astrometry on a crowded star field (crowded-stars, r = 2 and 4): forced PSF-fitting
//    photometry at the catalogue positions with each output's own effective PSF (measured as above, at the
//    catalogue's geometric-mean flux, so non-linear methods are fitted with the PSF they give a typical star),
//    all stars and a constant background fitted jointly by least squares (blends are fitted, not masked).
//    Per magnitude bin: the median of F_fit/F_true − 1 (bias) with its standard error (1.2533 σ/√n), and
//    the robust scatter 1.4826·MAD. Astrometry: one Gauss-Newton refinement of (F, y, x) per star with its
//    neighbours' fitted models subtracted; RMS position error of the stars brighter than the median.
//
// 3. Galaxy sizes and shapes (galaxy-field): Gaussian-weighted second moments of each galaxy on each output
//    against the same moments of the truth seen through that output's effective PSF.
//
// Usage: build/bench/science_bench [--quick] [--part all|resolution|stars|galaxies|defaults] [--out FILE]
//   (defaults: only the photometry of the linear methods with each one's default --weights auto, ~3 min)
//   (FILE: e.g. bench/results/science.md; about 20 minutes for all parts on 2 cores)
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <random>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "aosr/core/memory.hpp"
#include "aosr/core/fft.hpp"
#include "aosr/core/operators.hpp"
#include "aosr/io/config.hpp"
#include "aosr/optics/psf_metrics.hpp"
#include "aosr/scene/dataset.hpp"
#include "aosr/scene/objects.hpp"
#include "aosr/scene/pipeline.hpp"
#include "aosr/scene/scene_spec.hpp"
#include "aosr/scene/telescope.hpp"
#include "aosr/solvers/dataset_problem.hpp"
#include "aosr/solvers/reconstruct.hpp"
#include "aosr/solvers/target_psf.hpp"

namespace {

namespace fs = std::filesystem;
using aosr::Image;
using aosr::ImageStack;
using aosr::Index;
using aosr::Reconstruction;
using aosr::ReconstructionMethod;
using aosr::ReconstructionProblem;
using aosr::ReconstructOptions;

std::string Fmt(const char* f, double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, f, v);
  return buf;
}

struct Loaded {
  aosr::Dataset d;
  aosr::DatasetProblem dp;
  std::string name;
};

// The scene simulated, written and read back: the path real data take (reconstruct_bench.cpp does the same).
Loaded Simulate(const std::string& scene_file, const nlohmann::json& patch,
                aosr::DatasetWeights weights = aosr::DatasetWeights::kAuto) {
  const std::string path = (fs::path(aosr::DataDirectory()) / "scenes" / scene_file).string();
  nlohmann::json j = aosr::ReadJsonFile(path);
  j.merge_patch(patch);
  const aosr::ScenePipeline pipeline(aosr::ParseScene(j, path));
  const aosr::Simulation sim = pipeline.Run();
  const fs::path dir = fs::temp_directory_path() / ("aosr_science_bench_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  aosr::WriteSimulation(dir.string(), pipeline.scene(), pipeline, sim, &j);
  Loaded l{aosr::LoadDataset(dir.string()), {}, pipeline.scene().name};
  fs::remove_all(dir);
  aosr::DatasetProblemOptions o;
  o.weights = weights;
  l.dp = aosr::ProblemFromDataset(l.d, o);
  return l;
}

struct Method {
  std::string label;
  ReconstructOptions options;
  bool linear_method;  // linear in the data: one PSF for every flux
};

std::vector<Method> Methods() {
  std::vector<Method> m;
  auto add = [&m](const std::string& label, ReconstructionMethod method, bool linear) {
    ReconstructOptions o;
    o.method = method;
    m.push_back({label, o, linear});
  };
  add("drizzle", ReconstructionMethod::kDrizzle, true);
  add("shift-add", ReconstructionMethod::kShiftAddMean, true);
  add("tikhonov (GCV)", ReconstructionMethod::kTikhonov, true);
  add("linear (target PSF)", ReconstructionMethod::kLinear, true);
  add("tv", ReconstructionMethod::kTotalVariation, false);
  add("map", ReconstructionMethod::kMap, false);
  for (Method& x : m) x.options.linear.compute_noise = false;
  return m;
}

// A window of `img` centred on (cy, cx), periodic.
Image Window(const Image& img, Index cy, Index cx, Index side) {
  Image w(side, side);
  for (Index y = 0; y < side; ++y)
    for (Index x = 0; x < side; ++x)
      w(y, x) = img(((cy - side / 2 + y) % img.rows() + img.rows()) % img.rows(),
                    ((cx - side / 2 + x) % img.cols() + img.cols()) % img.cols());
  return w;
}

// The method's response to a point source of the given flux, per unit flux, averaged over `phases`² HR
// positions within one camera pixel: side x side, centred at (side/2, side/2). `fixed` carries the
// regularisation of the data's own reconstruction (non-linear methods are run with it, not re-tuned).
Image MethodPsf(const ReconstructionProblem& p, const ReconstructOptions& fixed, double flux, Index side, int phases) {
  const aosr::MultiFrameModel& model = *p.model;
  const aosr::Shape hr = model.hr_shape();
  const int r = model.r();
  const Index cy = hr.rows / 2 / r * r, cx = hr.cols / 2 / r * r;
  Image acc = Image::Zero(side, side);
  int count = 0;
  for (int i = 0; i < phases; ++i)
    for (int j = 0; j < phases; ++j) {
      const Index py = cy + i * r / phases, px = cx + j * r / phases;
      Image x = Image::Zero(hr.rows, hr.cols);
      x(py, px) = flux;
      ReconstructionProblem q = p;
      q.frames = model.Render(x);
      const Reconstruction rec = aosr::Reconstruct(q, fixed);
      acc += Window(rec.image, py, px, side) / flux;
      ++count;
    }
  return acc / double(count);
}

// Options that reproduce a reconstruction without re-tuning its regularisation.
ReconstructOptions Fixed(const Method& m, const Reconstruction& rec) {
  ReconstructOptions o = m.options;
  if (o.method == ReconstructionMethod::kTikhonov) {
    o.tikhonov.lambda_rule = aosr::TikhonovLambdaRule::kFixed;
    o.tikhonov.lambda = rec.regularisation;
  } else if (o.method == ReconstructionMethod::kTotalVariation) {
    o.auto_regularisation = false;
    o.tv.mu = rec.regularisation;
  } else if (o.method == ReconstructionMethod::kMap) {
    o.auto_regularisation = false;
    o.map.lambda = rec.regularisation;
  }
  return o;
}

double Fwhm(const Image& psf) {
  try {
    return aosr::MeasurePsf(psf).fwhm_px;
  } catch (const std::exception&) {
    return 0;
  }
}

// Noise of a method from noise-only reconstructions (n ~ N(0, 1/w) on the weighted pixels): the RMS per HR
// pixel over the trustworthy region, and the noise of forced PSF photometry with the method's own PSF ψ
// (F̂ = Σ ψ x / Σ ψ² over a stamp, at every stamp of a grid that tiles the region), both pooled in variance
// over the realisations. The second is what correlated noise does to a measurement, which per-pixel RMS hides.
struct Noise {
  double rms = 0;
  double flux = 0;  // standard deviation of F̂, e-
};
Noise MeasureNoise(const ReconstructionProblem& p, const ReconstructOptions& o, const Image& psf, Index stamp,
                   int realisations, int crop, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> n01;
  const Image w_psf = psf.block(psf.rows() / 2 - stamp / 2, psf.cols() / 2 - stamp / 2, stamp, stamp);
  const double norm = w_psf.square().sum();
  double var = 0, fvar = 0;
  Index fcount = 0;
  for (int k = 0; k < realisations; ++k) {
    ReconstructionProblem q = p;
    for (int i = 0; i < q.frame_count(); ++i) {
      const Image w = p.Weight(i);
      for (Index t = 0; t < w.size(); ++t) q.frames[i].data()[t] = w.data()[t] > 0 ? n01(rng) / std::sqrt(w.data()[t]) : 0.0;
    }
    const Image x = aosr::Reconstruct(q, o).image;
    const Image c = x.block(crop, crop, x.rows() - 2 * crop, x.cols() - 2 * crop);
    var += (c - c.mean()).square().mean();
    for (Index y = crop; y + stamp <= x.rows() - crop; y += stamp)
      for (Index xx = crop; xx + stamp <= x.cols() - crop; xx += stamp) {
        const double f = (x.block(y, xx, stamp, stamp) * w_psf).sum() / norm;
        fvar += f * f;
        ++fcount;
      }
  }
  return {std::sqrt(var / realisations), std::sqrt(fvar / double(std::max<Index>(1, fcount)))};
}

// ---------------------------------------------------------------------------------------------------------
// Part 1: resolution against noise.

void ResolutionNoise(const std::string& scene, bool quick, std::ostringstream& md) {
  nlohmann::json patch = nlohmann::json::object();
  if (quick) patch["detector"] = {{"frame_px", 48}};
  const Loaded l = Simulate(scene, patch);
  const ReconstructionProblem& p = l.dp.problem;
  const int r = l.d.r;
  const int crop = int(std::min<Index>(l.d.trustworthy_border_px, 8)) * r;
  const Index side = std::min<Index>(64, p.model->hr_shape().rows / 2 * 2);
  const Index stamp = 4 * r + 1;
  const int realisations = quick ? 2 : 6;
  const std::uint64_t seed = 99;
  auto linear = [&](double fwhm) {
    ReconstructOptions o;
    o.method = ReconstructionMethod::kLinear;
    o.linear.kind = aosr::TargetPsfKind::kGaussian;
    o.linear.fwhm_hr_px = fwhm;
    o.linear.compute_noise = false;
    return o;
  };
  // The Cramér-Rao bound on the flux of a point source at a known position, from the raw frames:
  // σ_F = (Σ_i Σ_p w (A_i δ)²)^(−1/2), averaged in variance over the r² sub-pixel phases. No method beats it.
  double crb_var = 0;
  {
    const aosr::Shape hr = p.model->hr_shape();
    for (int i = 0; i < r; ++i)
      for (int j = 0; j < r; ++j) {
        Image x = Image::Zero(hr.rows, hr.cols);
        x(hr.rows / 2 / r * r + i, hr.cols / 2 / r * r + j) = 1.0;
        const ImageStack f = p.model->Render(x);
        double info = 0;
        for (int k = 0; k < p.frame_count(); ++k) info += (p.Weight(k) * f[k].square()).sum();
        crb_var += 1.0 / info / double(r * r);
      }
  }
  const double crb = std::sqrt(crb_var);
  for (double pixfrac : {1.0, 0.6}) {
    ReconstructOptions drz;
    drz.method = ReconstructionMethod::kDrizzle;
    drz.drizzle.pixfrac = pixfrac;
    const Image drz_psf = MethodPsf(p, drz, 1.0, side, r);
    const double drz_fwhm = Fwhm(drz_psf);
    const Noise drz_noise = MeasureNoise(p, drz, drz_psf, stamp, realisations, crop, seed);
    // (a) the linear reconstruction at Drizzle's FWHM.
    const ReconstructOptions at_fwhm = linear(drz_fwhm);
    const Image lin_psf = MethodPsf(p, at_fwhm, 1.0, side, r);
    const Noise lin_noise = MeasureNoise(p, at_fwhm, lin_psf, stamp, realisations, crop, seed);
    // (b) the FWHM at which its noise equals Drizzle's: noise falls as the target widens; bisection on log FWHM.
    double lo = 0.5, hi = 2 * drz_fwhm;
    for (int it = 0; it < (quick ? 8 : 12); ++it) {
      const double mid = std::sqrt(lo * hi);
      (MeasureNoise(p, linear(mid), lin_psf, stamp, std::max(1, realisations / 2), crop, seed).rms > drz_noise.rms ? lo
                                                                                                                   : hi) = mid;
    }
    const double fwhm_at_noise = Fwhm(MethodPsf(p, linear(hi), 1.0, side, r));
    md << "| " << l.name << " | " << r << " | " << p.frame_count() << " | " << Fmt("%.1f", pixfrac) << " | "
       << Fmt("%.2f", drz_fwhm) << " | " << Fmt("%.3g", drz_noise.rms) << " | " << Fmt("%.3g", drz_noise.flux) << " | "
       << Fmt("%.2f", Fwhm(lin_psf)) << " | " << Fmt("%.3g", lin_noise.rms) << " | " << Fmt("%.3g", lin_noise.flux)
       << " | **" << Fmt("%.2f", drz_noise.rms / lin_noise.rms) << "x** / " << Fmt("%.2f", drz_noise.flux / lin_noise.flux)
       << "x | " << Fmt("%.3g", crb) << " | " << Fmt("%.2f", fwhm_at_noise) << " | **" << Fmt("%.2f", drz_fwhm / fwhm_at_noise)
       << "x** |\n";
    std::fprintf(stderr, "%s pixfrac %.1f: drizzle FWHM %.2f noise %.3g (flux %.3g); linear %.3g (flux %.3g); FWHM at drizzle noise %.2f\n",
                 l.name.c_str(), pixfrac, drz_fwhm, drz_noise.rms, drz_noise.flux, lin_noise.rms, lin_noise.flux, fwhm_at_noise);
  }
}

// ---------------------------------------------------------------------------------------------------------
// Part 2: forced PSF photometry and astrometry on a star field.

struct Stamp {
  Index y0, x0;  // top-left HR pixel of the stamp (may be negative: periodic)
  Image psf;     // the method's PSF at the star's sub-pixel position, stamp-sized
};

// ψ moved by a sub-pixel (dy, dx) (Fourier shift on its own window), then the central stamp.
Image ShiftedPsf(const Image& psf, double dy, double dx, Index stamp) {
  const aosr::Shape s{psf.rows(), psf.cols()};
  const Image moved = aosr::FftC2R(aosr::FftR2C(psf) * aosr::ShiftTransfer(s, dy, dx), s.cols);
  return moved.block(s.rows / 2 - stamp / 2, s.cols / 2 - stamp / 2, stamp, stamp);
}

struct StarFit {
  std::vector<double> flux;
  std::vector<double> dy, dx;  // astrometric offsets (HR px), NaN where not refined
};

StarFit FitStars(const Image& img, const std::vector<aosr::PointSource>& stars, const Image& psf, Index stamp) {
  const Index rows = img.rows(), cols = img.cols();
  const std::size_t n = stars.size();
  std::vector<Stamp> st(n);
  for (std::size_t s = 0; s < n; ++s) {
    const Index iy = Index(std::lround(stars[s].y)), ix = Index(std::lround(stars[s].x));
    st[s] = {iy - stamp / 2, ix - stamp / 2, ShiftedPsf(psf, stars[s].y - double(iy), stars[s].x - double(ix), stamp)};
  }
  auto at = [&](Index y, Index x) { return ((y % rows + rows) % rows) * cols + ((x % cols + cols) % cols); };
  // The fitted pixels: the union of the stamps.
  std::vector<char> used(rows * cols, 0);
  for (const Stamp& s : st)
    for (Index y = 0; y < stamp; ++y)
      for (Index x = 0; x < stamp; ++x) used[at(s.y0 + y, s.x0 + x)] = 1;
  // Model M f: Σ_s f_s ψ_s + b on the used pixels. Normal equations by CG (n + 1 unknowns).
  auto apply = [&](const std::vector<double>& f, std::vector<double>* out) {
    out->assign(rows * cols, 0.0);
    for (std::size_t s = 0; s < n; ++s)
      for (Index y = 0; y < stamp; ++y)
        for (Index x = 0; x < stamp; ++x) (*out)[at(st[s].y0 + y, st[s].x0 + x)] += f[s] * st[s].psf(y, x);
    for (Index k = 0; k < rows * cols; ++k) (*out)[k] = used[k] ? (*out)[k] + f[n] : 0.0;
  };
  auto adjoint = [&](const std::vector<double>& v, std::vector<double>* g) {
    g->assign(n + 1, 0.0);
    for (std::size_t s = 0; s < n; ++s) {
      double acc = 0;
      for (Index y = 0; y < stamp; ++y)
        for (Index x = 0; x < stamp; ++x) acc += v[at(st[s].y0 + y, st[s].x0 + x)] * st[s].psf(y, x);
      (*g)[s] = acc;
    }
    double b = 0;
    for (Index k = 0; k < rows * cols; ++k) b += used[k] ? v[k] : 0.0;
    (*g)[n] = b;
  };
  std::vector<double> data(img.data(), img.data() + img.size()), rhs, f(n + 1, 0.0), tmp, q;
  for (Index k = 0; k < rows * cols; ++k) data[k] = used[k] ? data[k] : 0.0;
  adjoint(data, &rhs);
  std::vector<double> res = rhs, dir = rhs;
  double rr = 0;
  for (double v : res) rr += v * v;
  const double rr0 = rr;
  for (int it = 0; it < 2000 && rr > 1e-24 * rr0; ++it) {
    apply(dir, &tmp);
    adjoint(tmp, &q);
    double dq = 0;
    for (std::size_t k = 0; k <= n; ++k) dq += dir[k] * q[k];
    const double alpha = rr / dq;
    double rr_new = 0;
    for (std::size_t k = 0; k <= n; ++k) {
      f[k] += alpha * dir[k];
      res[k] -= alpha * q[k];
      rr_new += res[k] * res[k];
    }
    for (std::size_t k = 0; k <= n; ++k) dir[k] = res[k] + rr_new / rr * dir[k];
    rr = rr_new;
  }
  StarFit out;
  out.flux.assign(f.begin(), f.begin() + n);
  out.dy.assign(n, NAN);
  out.dx.assign(n, NAN);
  // Astrometry: residual + own model, then F ψ(y − dy) ≈ F ψ − F dy ∂ψ/∂y − F dx ∂ψ/∂x (b fixed), twice.
  std::vector<double> model;
  apply(f, &model);
  for (std::size_t s = 0; s < n; ++s) {
    if (!(out.flux[s] > 0)) continue;
    double dy = 0, dx = 0;
    const Index iy = Index(std::lround(stars[s].y)), ix = Index(std::lround(stars[s].x));
    for (int pass = 0; pass < 2; ++pass) {
      const double fy = stars[s].y - double(iy) + dy, fx = stars[s].x - double(ix) + dx;
      const Image p0 = ShiftedPsf(psf, fy, fx, stamp);
      const double h = 0.05;
      const Image gy = (ShiftedPsf(psf, fy + h, fx, stamp) - ShiftedPsf(psf, fy - h, fx, stamp)) / (2 * h);
      const Image gx = (ShiftedPsf(psf, fy, fx + h, stamp) - ShiftedPsf(psf, fy, fx - h, stamp)) / (2 * h);
      Eigen::Matrix3d a = Eigen::Matrix3d::Zero();
      Eigen::Vector3d b = Eigen::Vector3d::Zero();
      for (Index y = 0; y < stamp; ++y)
        for (Index x = 0; x < stamp; ++x) {
          const Index k = at(st[s].y0 + y, st[s].x0 + x);
          const double own = out.flux[s] * st[s].psf(y, x);
          const double d = img.data()[k] - (model[k] - own);  // model[k] includes the background
          const Eigen::Vector3d g(p0(y, x), gy(y, x), gx(y, x));
          a += g * g.transpose();
          b += g * d;
        }
      const Eigen::Vector3d sol = a.ldlt().solve(b);
      if (!(sol[0] > 0) || !sol.allFinite()) break;
      dy += sol[1] / sol[0];
      dx += sol[2] / sol[0];
      if (std::abs(dy) > 2 || std::abs(dx) > 2) break;
    }
    out.dy[s] = dy;
    out.dx[s] = dx;
  }
  return out;
}

double Median(std::vector<double> v) {
  if (v.empty()) return NAN;
  std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
  return v[v.size() / 2];
}

struct BinStats {
  int n = 0;
  double bias = NAN, bias_se = NAN, scatter = NAN;
};

BinStats Stats(const std::vector<double>& ratio_minus_1) {
  BinStats b;
  b.n = int(ratio_minus_1.size());
  if (b.n < 3) return b;
  b.bias = Median(ratio_minus_1);
  std::vector<double> dev;
  for (double v : ratio_minus_1) dev.push_back(std::abs(v - b.bias));
  b.scatter = 1.4826 * Median(dev);
  b.bias_se = 1.2533 * b.scatter / std::sqrt(double(b.n));
  return b;
}

void Photometry(const std::string& scene, int r, aosr::DatasetWeights weights, bool only_linear, bool quick,
                std::ostringstream& md) {
  // Several realisations of the field (scene seeds) pooled, so that the bright bins hold more than a handful.
  const std::vector<int> seeds = quick ? std::vector<int>{7} : std::vector<int>{7, 8, 9};
  const int bins = 7;
  // Magnitudes from the scene's K zero point (crowded-stars.json: K = 14 gives 6.8e4 e- per 1 s frame).
  auto mag = [](double flux_e) { return 14.0 - 2.5 * std::log10(flux_e / 6.8e4); };
  struct Pooled {
    std::vector<std::vector<double>> per_bin = std::vector<std::vector<double>>(7);
    std::vector<double> pos;
    int bright = 0;
    double fwhm = 0;
  };
  std::vector<Method> methods;
  for (const Method& m : Methods())
    if (!only_linear || m.linear_method) methods.push_back(m);
  std::vector<Pooled> pooled(methods.size());
  std::string header;
  std::size_t total_stars = 0;
  for (int seed : seeds) {
    nlohmann::json patch = {{"r", r}, {"seed", seed}};
    if (quick) {
      patch["detector"] = {{"frame_px", 48}};
      patch["objects"] = nlohmann::json::array({{{"type", "stars"}, {"count", 60}, {"magnitude_range", {14, 21}}}});
    }
    const Loaded l = Simulate(scene, patch, weights);
    const std::vector<aosr::PointSource>& stars = l.d.stars;
    total_stars += stars.size();
    const Index side = std::min<Index>(64, l.dp.problem.model->hr_shape().rows / 2 * 2);
    const Index stamp = std::min<Index>(side - 8, 6 * r + 1);
    // Scored stars keep half a stamp plus up to 4 camera pixels from the edge (the periodic model wraps there);
    // the scene's trustworthy border (set by its 64 λ/D PSF window, mostly faint halo) would leave few stars.
    const double border = double(std::min<Index>(l.d.trustworthy_border_px, 4) * r) + double(stamp) / 2;
    double log_mean = 0;
    std::vector<double> fluxes;
    for (const auto& st : stars) {
      log_mean += std::log(st.flux);
      fluxes.push_back(st.flux);
    }
    const double typical = std::exp(log_mean / double(stars.size()));
    const double median_flux = Median(fluxes);
    header = l.name + ", r = " + std::to_string(r) + ", HR " + std::to_string(l.dp.problem.model->hr_shape().rows) +
             "², N = " + std::to_string(l.dp.problem.frame_count()) + "; weights: " +
             (weights == aosr::DatasetWeights::kAuto ? std::string("each method's default (--weights auto)")
                                                     : l.dp.weights_source);
    const Index hr = l.dp.problem.model->hr_shape().rows;
    for (std::size_t mi = 0; mi < methods.size(); ++mi) {
      const Method& m = methods[mi];
      // kAuto: the problem `aosr reconstruct -m METHOD` builds (--weights auto resolves per method).
      aosr::DatasetProblemOptions dpo;
      dpo.weights = weights;
      dpo.method = m.options.method;
      const aosr::DatasetProblem own = weights == aosr::DatasetWeights::kAuto ? aosr::ProblemFromDataset(l.d, dpo) : l.dp;
      const ReconstructionProblem& p = own.problem;
      if (weights == aosr::DatasetWeights::kAuto && seed == seeds.front())
        std::fprintf(stderr, "%s: weights %s\n", m.label.c_str(), own.weights_source.c_str());
      const Reconstruction rec = aosr::Reconstruct(p, m.options);
      // The PSF over all r² sub-pixel phases: Drizzle's and shift-and-add's response depends on the phase when
      // N < r², and stars sit at every phase. TV and MAP (a full solve per phase) over 2 x 2 of them.
      const Image psf = MethodPsf(p, Fixed(m, rec), typical, side, m.linear_method ? r : std::min(r, 2));
      const StarFit fit = FitStars(rec.image, stars, psf, stamp);
      Pooled& pl = pooled[mi];
      pl.fwhm = Fwhm(psf);
      for (std::size_t k = 0; k < stars.size(); ++k) {
        if (stars[k].y < border || stars[k].x < border || stars[k].y > double(hr) - border ||
            stars[k].x > double(hr) - border)
          continue;
        const int b = int(std::floor(mag(stars[k].flux) - 14.0));
        if (b >= 0 && b < bins) pl.per_bin[b].push_back(fit.flux[k] / stars[k].flux - 1.0);
        if (stars[k].flux >= median_flux) {
          ++pl.bright;
          if (std::isfinite(fit.dy[k]) && std::hypot(fit.dy[k], fit.dx[k]) <= 2.0)
            pl.pos.push_back(std::hypot(fit.dy[k], fit.dx[k]));
        }
      }
      std::fprintf(stderr, "%s seed %d %s done\n", header.c_str(), seed, m.label.c_str());
    }
  }
  md << "\n### " << header << " (" << seeds.size() << " realisations of the field, " << total_stars << " stars)\n\n"
     << "Bias = median(F_fit/F_true − 1) ± its standard error; scatter = 1.4826 MAD of F_fit/F_true; per K bin, "
        "(count) of stars scored (stars within half a fitting stamp + 4 camera pixels of the edge are fitted but not "
        "scored). Astrometry: median position error |Δr| of the stars brighter than the median, HR px, and the share "
        "whose position fit ran off (|Δ| > 2 HR px). FWHM: of the method's effective PSF (at the catalogue's "
        "geometric-mean flux, averaged over the r² sub-pixel phases; TV and MAP over 2 x 2 of them).\n\n| method | FWHM (HR px) | astrometry (HR px) |";
  for (int b = 0; b < bins; ++b) md << " K " << 14 + b << "–" << 15 + b << ": bias / scatter |";
  md << "\n|---|---|---|";
  for (int b = 0; b < bins; ++b) md << "---|";
  md << "\n";
  std::vector<double> drizzle_scatter(bins, NAN);
  for (std::size_t mi = 0; mi < methods.size(); ++mi) {
    const Method& m = methods[mi];
    const Pooled& pl = pooled[mi];
    md << "| " << m.label << " | " << Fmt("%.2f", pl.fwhm) << " | " << Fmt("%.4f", Median(pl.pos)) << " / "
       << Fmt("%.0f", 100.0 * double(pl.bright - int(pl.pos.size())) / double(std::max(1, pl.bright))) << "% |";
    for (int b = 0; b < bins; ++b) {
      const BinStats st = Stats(pl.per_bin[b]);
      if (m.options.method == ReconstructionMethod::kDrizzle) drizzle_scatter[b] = st.scatter;
      if (st.n < 3) {
        md << " (" << st.n << " stars) |";
        continue;
      }
      const bool unbiased = std::abs(st.bias) <= std::max(0.005, st.bias_se);
      const bool beats = m.options.method != ReconstructionMethod::kDrizzle && st.scatter < drizzle_scatter[b];
      md << " " << (unbiased ? "" : "⚠") << Fmt("%+.2f", 100 * st.bias) << "±" << Fmt("%.2f", 100 * st.bias_se)
         << "% / " << (beats ? "**" : "") << Fmt("%.2f", 100 * st.scatter) << "%" << (beats ? "**" : "") << " (" << st.n
         << ") |";
    }
    md << "\n";
  }
}

// ---------------------------------------------------------------------------------------------------------
// Part 3: galaxy sizes and shapes.

// Connected components (4-neighbour) of mask, as lists of pixel indices.
std::vector<std::vector<Index>> Components(const std::vector<char>& mask, Index rows, Index cols) {
  std::vector<int> label(mask.size(), -1);
  std::vector<std::vector<Index>> out;
  for (Index start = 0; start < Index(mask.size()); ++start) {
    if (!mask[start] || label[start] >= 0) continue;
    std::vector<Index> comp, stack{start};
    label[start] = int(out.size());
    while (!stack.empty()) {
      const Index k = stack.back();
      stack.pop_back();
      comp.push_back(k);
      const Index y = k / cols, x = k % cols;
      const Index nb[4] = {y > 0 ? k - cols : -1, y + 1 < rows ? k + cols : -1, x > 0 ? k - 1 : -1, x + 1 < cols ? k + 1 : -1};
      for (Index n : nb)
        if (n >= 0 && mask[n] && label[n] < 0) {
          label[n] = int(out.size());
          stack.push_back(n);
        }
    }
    out.push_back(std::move(comp));
  }
  return out;
}

struct Moments {
  double flux = 0, size = 0, e1 = 0, e2 = 0;  // size: Iyy + Ixx (HR px²)
};

// Gaussian-weighted second moments about (cy, cx) with weight width sigma_w (HR px).
Moments WeightedMoments(const Image& img, double cy, double cx, double sigma_w) {
  Moments m;
  double iyy = 0, ixx = 0, ixy = 0;
  const Index rad = Index(std::ceil(4 * sigma_w));
  for (Index y = Index(cy) - rad; y <= Index(cy) + rad; ++y)
    for (Index x = Index(cx) - rad; x <= Index(cx) + rad; ++x) {
      if (y < 0 || x < 0 || y >= img.rows() || x >= img.cols()) continue;
      const double dy = double(y) - cy, dx = double(x) - cx;
      const double w = std::exp(-0.5 * (dy * dy + dx * dx) / (sigma_w * sigma_w)) * img(y, x);
      m.flux += w;
      iyy += w * dy * dy;
      ixx += w * dx * dx;
      ixy += w * dy * dx;
    }
  if (!(m.flux > 0)) return m;
  iyy /= m.flux;
  ixx /= m.flux;
  ixy /= m.flux;
  m.size = iyy + ixx;
  m.e1 = (ixx - iyy) / m.size;
  m.e2 = 2 * ixy / m.size;
  return m;
}

void Galaxies(const std::string& scene, bool quick, std::ostringstream& md) {
  (void)quick;  // the field is small already (128² camera pixels, 15 galaxies)
  const Loaded l = Simulate(scene, nlohmann::json::object(), aosr::DatasetWeights::kMask);
  const ReconstructionProblem& p = l.dp.problem;
  const Image& truth = *l.d.truth;
  const int r = l.d.r;
  const aosr::Shape hr = p.model->hr_shape();
  const Index side = std::min<Index>(64, hr.rows / 2 * 2);
  // Galaxies: components of the star-free truth smoothed by a Gaussian of FWHM r HR px above 1 % of its
  // maximum, away from the catalogue's stars and the border.
  Image g = aosr::GaussianTargetKernel(2.3548 * r, side);
  Image galaxies_only = truth;  // the stars removed exactly as they were deposited (objects.hpp, bilinear)
  std::vector<aosr::PointSource> negative = l.d.stars;
  for (auto& st : negative) st.flux = -st.flux;
  aosr::AddPointSources(&galaxies_only, negative);
  const Image smooth =
      aosr::ToImage(aosr::PeriodicConvolutionFromKernel(hr, g)->Apply(aosr::AsVector(galaxies_only)), hr);
  std::vector<char> mask(smooth.size());
  const double thr = 0.01 * smooth.maxCoeff();
  for (Index k = 0; k < smooth.size(); ++k) mask[k] = smooth.data()[k] > thr;
  struct Gal {
    double cy, cx, sigma_w;
  };
  std::vector<Gal> gals;
  const double border = double(std::min<Index>(l.d.trustworthy_border_px, 4) * r);
  for (const auto& comp : Components(mask, hr.rows, hr.cols)) {
    if (comp.size() < 8) continue;
    double f = 0, cy = 0, cx = 0;
    for (Index k : comp) {
      f += smooth.data()[k];
      cy += smooth.data()[k] * double(k / hr.cols);
      cx += smooth.data()[k] * double(k % hr.cols);
    }
    cy /= f;
    cx /= f;
    bool star = false;
    for (const auto& s : l.d.stars) star = star || std::hypot(s.y - cy, s.x - cx) < 3.0 * r;
    const double sigma_w = std::max(2.0 * r, 0.6 * std::sqrt(double(comp.size()) / M_PI));
    if (star || cy < border + 3 * sigma_w || cx < border + 3 * sigma_w || cy > double(hr.rows) - border - 3 * sigma_w ||
        cx > double(hr.cols) - border - 3 * sigma_w)
      continue;
    gals.push_back({cy, cx, sigma_w});
  }
  md << "\n## Galaxy sizes and shapes (" << l.name << ", r = " << r << ", " << gals.size()
     << " galaxies away from stars and border; weights: " << l.dp.weights_source << ")\n\n"
     << "Gaussian-weighted second moments (weight σ = max(2r HR px, 0.6 √(area/π)) about the galaxy's centroid) on "
        "each output and on the truth seen through that output's effective PSF (what the method should show): size "
        "error = median |T_out/T_ref − 1| (T = I_yy + I_xx), shape error = median |e_out − e_ref| (e = (I_xx − I_yy, "
        "2 I_xy)/T), flux error = median |F_out/F_ref − 1| of the weighted flux; each image's median (the sky) "
        "subtracted first; 'lost': galaxies whose weighted flux or size came out non-positive (noise over a faint "
        "galaxy), left out of the medians.\n\n"
     << "| method | FWHM (HR px) | size error | shape error | flux error | lost |\n|---|---|---|---|---|---|\n";
  for (const Method& m : Methods()) {
    const Reconstruction rec = aosr::Reconstruct(p, m.options);
    const Image psf = MethodPsf(p, Fixed(m, rec), 1000.0, side, 2);
    Image ref = aosr::ToImage(aosr::PeriodicConvolutionFromKernel(hr, psf)->Apply(aosr::AsVector(truth)), hr);
    // The outputs carry the sky; the truth does not. Subtract each image's median (the field is mostly sky).
    const Image out = rec.image - Median(std::vector<double>(rec.image.data(), rec.image.data() + rec.image.size()));
    ref -= Median(std::vector<double>(ref.data(), ref.data() + ref.size()));
    std::vector<double> size_err, flux_err, shape_err;
    int failed = 0;
    for (const Gal& gl : gals) {
      const Moments a = WeightedMoments(out, gl.cy, gl.cx, gl.sigma_w);
      const Moments b = WeightedMoments(ref, gl.cy, gl.cx, gl.sigma_w);
      // A moment ratio of a non-positive weighted flux or size means nothing (noise over a faint galaxy).
      if (!(a.flux > 0 && a.size > 0 && b.flux > 0 && b.size > 0)) {
        ++failed;
        continue;
      }
      size_err.push_back(std::abs(a.size / b.size - 1));
      flux_err.push_back(std::abs(a.flux / b.flux - 1));
      shape_err.push_back(std::hypot(a.e1 - b.e1, a.e2 - b.e2));
    }
    md << "| " << m.label << " | " << Fmt("%.2f", Fwhm(psf)) << " | " << Fmt("%.2f", 100 * Median(size_err)) << "% | "
       << Fmt("%.3f", Median(shape_err)) << " | " << Fmt("%.2f", 100 * Median(flux_err)) << "% | " << failed
       << " |\n";
    std::fprintf(stderr, "%s %s done\n", l.name.c_str(), m.label.c_str());
  }
}

}  // namespace

int main(int argc, char** argv) {
  aosr::TuneAllocatorForLargeArrays();  // as the CLI does (memory.hpp)
  bool quick = false;
  std::string out_file, part = "all";
  std::string command = "build/bench/science_bench";
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--quick") {
      quick = true;
      command += " --quick";
    } else if (a == "--part" && i + 1 < argc) {
      part = argv[++i];
      command += " --part " + part;
    } else if (a == "--out" && i + 1 < argc) {
      out_file = argv[++i];
      command += " --out " + out_file;
    } else {
      std::fprintf(stderr, "usage: science_bench [--quick] [--part all|resolution|stars|galaxies|defaults] [--out FILE]\n");
      return 2;
    }
  }
  const auto t0 = std::chrono::steady_clock::now();
  std::ostringstream md;
  md << "<!-- produced by: " << command << " -->\n# Science: resolution, noise, photometry and astrometry by method\n\n"
     << "Command: `" << command << "` (Release build, " << std::thread::hardware_concurrency()
     << " hardware threads). What each column means is at the top of bench/science_bench.cpp.\n\n"
     ;
  if (part == "all" || part == "resolution") {
  md << "## Resolution against noise (the paper's system)\n\n"
     << "Drizzle (square kernel, pixfrac 1 and 0.6) against the target-PSF linear reconstruction (Gaussian target): (a) at "
        "Drizzle's FWHM, the noise ratio Drizzle / linear; (b) at Drizzle's noise, the FWHM ratio Drizzle / linear. "
        "FWHM of the effective PSF (HR px, measured from point-source reconstructions); noise RMS per HR pixel "
        "(e-), and the noise of forced PSF photometry with each method's own PSF (e-), from the same noise "
        "realisations; the flux noise floor is the Cramér-Rao bound of a point source's flux from the raw frames.\n\n"
     << "| scene | r | N | pixfrac | Drizzle FWHM | Drizzle noise: pixel / PSF flux | | linear FWHM | linear noise: "
        "pixel / PSF flux | | (a) noise ratio: pixel / PSF flux | flux noise floor (CRB) | linear FWHM at Drizzle's pixel "
        "noise | (b) FWHM ratio |\n|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n";
  ResolutionNoise("paper-sim-r2.json", quick, md);
  ResolutionNoise("paper-sim-r4.json", quick, md);
  }
  if (part == "all" || part == "stars") {
  md << "\n## Photometry and astrometry (crowded star field)\n\n"
     << "Weights that do not depend on the sources (the validity mask: uniform on usable pixels, as Drizzle's "
        "exposure/sky weighting is) keep every linear method linear. The last table repeats the linear methods with "
        "the dataset's inverse variances at the *expected* signal (source photon noise included): the weights then "
        "fall in bright stars' cores and the combination turns flux-dependent, biasing bright stars low.\n";
  Photometry("crowded-stars.json", 2, aosr::DatasetWeights::kMask, false, quick, md);
  if (!quick) Photometry("crowded-stars.json", 4, aosr::DatasetWeights::kMask, false, quick, md);
  Photometry("crowded-stars.json", 2, aosr::DatasetWeights::kDataset, true, quick, md);
  }
  if (part == "defaults") {
    md << "\n## Photometry with the default weights (crowded star field)\n\n"
       << "The linear methods as `aosr reconstruct -m METHOD` runs them with `--weights auto`: source-independent "
          "background (sky + read-noise) inverse variances, one per frame, for every linear method "
          "(include/aosr/solvers/dataset_problem.hpp; here from the simulation's detector model, so uniform). The "
          "same methods with the dataset's Poisson inverse variances (`--weights poisson`, what `auto` meant before): "
          "bench/results/science.md, last table.\n";
    Photometry("crowded-stars.json", 2, aosr::DatasetWeights::kAuto, true, quick, md);
  }
  if (part == "all" || part == "galaxies") Galaxies("galaxy-field.json", quick, md);
  const double total = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  md << "\nTotal " << Fmt("%.0f", total) << " s. ⚠: bias beyond ±0.5 % and beyond one standard error; **bold** "
        "scatter: below Drizzle's in that bin.\n";
  std::printf("%s", md.str().c_str());
  if (!out_file.empty()) std::ofstream(out_file) << md.str();
  return 0;
}
