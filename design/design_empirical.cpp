#include "aosr/design/design_empirical.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <memory>

#include "aosr/ao/random.hpp"
#include "aosr/core/error.hpp"
#include "aosr/core/fft.hpp"
#include "aosr/core/operators.hpp"
#include "aosr/io/image_io.hpp"
#include "aosr/scene/dead_leaves.hpp"
#include "aosr/scene/image_object.hpp"
#include "aosr/solvers/fourier_normal_system.hpp"
#include "aosr/solvers/tikhonov.hpp"
#include "design_internal.hpp"
#include "solvers/tikhonov_internal.hpp"  // solvers-private: CMakeLists.txt gives aosr_design the root

namespace aosr {

using tikhonov_internal::PriorSymbolImage;

const char* ToString(DesignLoss loss) {
  switch (loss) {
    case DesignLoss::kL2:
      return "l2";
    case DesignLoss::kL1:
      return "l1";
  }
  return "unknown";
}

DesignLoss ParseDesignLoss(const std::string& name) {
  if (name == "l2") return DesignLoss::kL2;
  if (name == "l1") return DesignLoss::kL1;
  throw InvalidArgument("ParseDesignLoss", "loss", name, "l1 or l2");
}

std::vector<Image> DefaultTrainingScenes(Shape hr, int count, std::uint64_t seed) {
  const char* fn = "DefaultTrainingScenes";
  CheckArgument(hr.rows >= 4 && hr.cols >= 4, fn, "hr", ToString(hr), "both sides >= 4");
  CheckArgument(count >= 1 && count <= 64, fn, "count", count, "1 .. 64");
  DeadLeavesOptions o;
  o.r_min_px = 1.0;
  o.r_max_px = std::max(2.0, double(std::min(hr.rows, hr.cols)) / 4.0);
  std::vector<Image> out;
  for (int k = 0; k < count; ++k) out.push_back(DeadLeaves(hr, o, DeriveSeed(seed, std::uint64_t(k))));
  return out;
}

std::vector<Image> TrainingScenesFromFiles(const std::vector<std::string>& paths, Shape hr, double zoom) {
  const char* fn = "TrainingScenesFromFiles";
  CheckArgument(!paths.empty() && paths.size() <= 64, fn, "paths count", paths.size(), "1 .. 64");
  CheckArgument(hr.rows >= 4 && hr.cols >= 4, fn, "hr", ToString(hr), "both sides >= 4");
  CheckArgument(std::isfinite(zoom) && zoom > 0, fn, "zoom", zoom, "> 0 and finite");
  std::vector<Image> out;
  for (const std::string& path : paths) {
    const Image src = ReadImage(path);
    CheckArgument(src.size() > 0 && AllFinite(src), fn, "file " + path, "empty or non-finite pixels", "finite pixels");
    // The centred window of zoom·M source pixels (or the largest centred square that fits).
    const Index want_r = std::max<Index>(1, Index(std::llround(zoom * double(hr.rows))));
    const Index want_c = std::max<Index>(1, Index(std::llround(zoom * double(hr.cols))));
    const Index h = std::min(want_r, Index(src.rows())), w = std::min(want_c, Index(src.cols()));
    const Image window = src.block((src.rows() - h) / 2, (src.cols() - w) / 2, h, w);
    ImageObjectOptions io;
    io.fit = ImageFit::kCrop;
    io.values = PixelValues::kSurfaceBrightness;
    io.clip_negative = true;
    io.normalisation = FluxNormalisation::kPeak;
    io.peak_value = 1.0;
    try {
      out.push_back(MakeImageObject(window, hr, io));
    } catch (const InvalidArgument& e) {
      throw InvalidArgument(std::string(fn) + ": " + path + ": " + e.what());
    }
  }
  return out;
}

bool EmpiricalDesignOptions::IsValid(std::string* why) const {
  auto fail = [why](const std::string& m) {
    if (why) *why = m;
    return false;
  };
  if (training_scenes.empty() || training_scenes.size() > 64)
    return fail("training_scenes count = " + std::to_string(training_scenes.size()) + "; allowed: 1 .. 64");
  for (std::size_t k = 0; k < training_scenes.size(); ++k)
    if (training_scenes[k].size() == 0 || !AllFinite(training_scenes[k]))
      return fail("training_scenes[" + std::to_string(k) + "] is empty or not finite");
  if (!(std::isfinite(noise_sigma) && noise_sigma > 0))
    return fail("noise_sigma = " + ToString(noise_sigma) + "; allowed: > 0 and finite");
  std::string w;
  if (!map.IsValid(&w)) return fail("map." + w);
  if (map.likelihood != MapLikelihood::kGaussian) return fail("map.likelihood = " + std::string(ToString(map.likelihood)) + "; allowed: gaussian");
  if (map.prior != MapPrior::kCharbonnierTv && map.prior != MapPrior::kTikhonov)
    return fail("map.prior = " + std::string(ToString(map.prior)) +
                "; allowed: charbonnier-tv or tikhonov (twice differentiable, for the implicit gradient)");
  if (map.positivity != MapPositivity::kNone)
    return fail("map.positivity = " + std::string(ToString(map.positivity)) +
                "; allowed: none (positivity makes the MAP estimate a non-smooth function of the design)");
  if (map.background != 0) return fail("map.background = " + ToString(map.background) + "; allowed: 0");
  if (!(std::isfinite(loss_epsilon) && loss_epsilon > 0))
    return fail("loss_epsilon = " + ToString(loss_epsilon) + "; allowed: > 0 and finite");
  if (loss != DesignLoss::kL1 && loss != DesignLoss::kL2) return fail("loss must be kL1 or kL2");
  if (realisations < 0 || realisations > 64) return fail("realisations = " + std::to_string(realisations) + "; allowed: 0 .. 64");
  if (screens < 1 || screens > 256) return fail("screens = " + std::to_string(screens) + "; allowed: 1 .. 256");
  if (threads < 1 || threads > 64) return fail("threads = " + std::to_string(threads) + "; allowed: 1 .. 64");
  if (!(map_tolerance > 0 && map_tolerance <= 1e-3))
    return fail("map_tolerance = " + ToString(map_tolerance) + "; allowed: (0, 1e-3]");
  if (newton_iterations < 1 || newton_iterations > 1000)
    return fail("newton_iterations = " + std::to_string(newton_iterations) + "; allowed: 1 .. 1000");
  if (newton_cg_iterations < 1) return fail("newton_cg_iterations = " + std::to_string(newton_cg_iterations) + "; allowed: >= 1");
  if (!adjoint.IsValid(&w)) return fail("adjoint." + w);
  return true;
}

std::string EmpiricalEvaluation::BriefReport() const {
  int warm = 0, newton = 0, lbfgs = 0, cg = 0;
  for (const EmpiricalPairReport& p : pairs) {
    warm += p.warm_started;
    newton += p.newton_steps;
    lbfgs += p.lbfgs_iterations;
    cg += p.adjoint_iterations;
  }
  char buf[400];
  std::snprintf(buf, sizeof buf,
                "J = %.6g over %zu pairs (warm %d), MAP |grad F| <= %.2g (newton %d, lbfgs %d), adjoint residual <= "
                "%.2g (%d CG iterations), %.2f s%s%s",
                objective, pairs.size(), warm, max_map_gradient, newton, lbfgs, max_adjoint_residual, cg, seconds,
                ok ? "" : "; NOT OK: ", ok ? "" : message.c_str());
  return buf;
}

namespace {

// H u = A0ᵀ W A0 u + λ ∇²R(x̂) u at a fixed x̂ (design_empirical.hpp). Self-adjoint.
class MapHessian : public LinearOperator {
 public:
  MapHessian(OperatorPtr a, double weight, const MapOptions& o, Shape hr, const Vector& x)
      : LinearOperator(x.size(), x.size(), "MapHessian"), a_(std::move(a)), w_(weight), lambda_(o.lambda), n_(x.size()) {
    if (o.prior == MapPrior::kTikhonov) {
      if (o.tikhonov_operator != TikhonovPrior::kIdentity) gamma_ = TikhonovPriorOperator(hr, o.tikhonov_operator);
      identity_ = !gamma_;
    } else {
      gamma_ = Gradient(hr, Boundary::kPeriodic);
      const Vector g = gamma_->Apply(x);
      const double eps2 = o.epsilon * o.epsilon;
      b11_.resize(n_);
      b12_.resize(n_);
      b22_.resize(n_);
      for (Index p = 0; p < n_; ++p) {
        const double gy = g[p], gx = g[n_ + p];
        const double rho2 = gy * gy + gx * gx + eps2, rho = std::sqrt(rho2), inv = 1.0 / rho, inv3 = inv / rho2;
        b11_[p] = inv - gy * gy * inv3;
        b12_[p] = -gy * gx * inv3;
        b22_[p] = inv - gx * gx * inv3;
        mean_inv_rho_ += inv;
      }
      mean_inv_rho_ = (mean_inv_rho_ - 1.0) / double(n_);
    }
  }

 private:
  void ApplyImpl(ConstRef u, Ref out) const override {
    out = w_ * a_->ApplyNormal(u);
    if (identity_) {
      out += lambda_ * u;
    } else if (b11_.size() == 0) {
      out += lambda_ * gamma_->ApplyNormal(u);
    } else {
      Vector g = gamma_->Apply(u);
      for (Index p = 0; p < n_; ++p) {
        const double gy = g[p], gx = g[n_ + p];
        g[p] = b11_[p] * gy + b12_[p] * gx;
        g[n_ + p] = b12_[p] * gy + b22_[p] * gx;
      }
      out += lambda_ * gamma_->ApplyAdjoint(g);
    }
  }
  void ApplyAdjointImpl(ConstRef y, Ref x) const override { ApplyImpl(y, x); }

 public:
  // The prior's curvature scale c for the preconditioner (w A0ᵀA0 + λ c ΓᵀΓ)⁻¹: 1 for Tikhonov (exact), the
  // mean of 1/ρ_p (B's larger eigenvalue) for Charbonnier.
  double CurvatureScale() const { return b11_.size() == 0 ? 1.0 : mean_inv_rho_; }

 private:
  double mean_inv_rho_ = 1.0;

  OperatorPtr a_, gamma_;
  double w_, lambda_;
  Index n_;
  bool identity_ = false;
  Vector b11_, b12_, b22_;
};

// M⁻¹ = (w A0ᵀA0 + λ c ΓᵀΓ)⁻¹ by FFTs and per-bin solves (FourierNormalSystem; tikhonov.hpp (2)), Γ the prior's
// operator (the gradient for Charbonnier TV): exact for the Tikhonov prior (c = 1), a Fourier-diagonal approximation with
// the mean curvature for Charbonnier (it removes the data term's ill-conditioning; the prior's spatial
// variation is what CG then resolves).
class Preconditioner {
 public:
  Preconditioner(const MultiFrameModel& a0, const MapOptions& mo, double weight) : a0_(a0), weight_(weight), lambda_(mo.lambda) {
    TikhonovOptions t;
    t.prior = mo.prior == MapPrior::kTikhonov ? mo.tikhonov_operator : TikhonovPrior::kGradient;
    symbol_ = PriorSymbolImage(t, a0.hr_shape());
  }
  // Valid while the operator lives; a later call while one is still held lays out a new system.
  OperatorPtr At(double c) const {
    if (!system_ || system_.use_count() > 1) system_ = std::make_shared<FourierNormalSystem>(a0_, weight_);
    system_->Factorize(lambda_ * c * symbol_);
    return NormalSystemInverse(system_);
  }

 private:
  const MultiFrameModel& a0_;
  double weight_, lambda_;
  Image symbol_;
  mutable std::shared_ptr<FourierNormalSystem> system_;
};

// Newton-CG on F from x (in place). Returns true when ||∇F|| <= tol · gref.
bool NewtonPolish(const MapObjective& f, const OperatorPtr& a, double weight, const MapOptions& mo, Shape hr,
                  const Preconditioner& pre, double tol, double gref, int max_steps, int cg_cap, Vector* x,
                  EmpiricalPairReport* rep) {
  Vector g;
  MapObjective::Value v = f.Evaluate(*x, &g);
  if (!v.ok()) {
    rep->message = "MAP objective not finite at the start of the Newton steps";
    return false;
  }
  for (int step = 0;; ++step) {
    const double gn = g.norm();
    rep->map_gradient = gn / gref;
    if (gn <= tol * gref) return true;
    if (step >= max_steps) {
      rep->message = "MAP Newton steps exhausted (" + std::to_string(max_steps) + ") at |grad F| / |grad F(0)| = " +
                     ToString(rep->map_gradient);
      return false;
    }
    const MapHessian h(a, weight, mo, hr, *x);
    Vector p = Vector::Zero(x->size());
    ConjugateGradientOptions co;
    co.max_iterations = cg_cap;
    co.tolerance = std::clamp(std::min(0.5, std::sqrt(gn / gref)), 1e-14, 0.5);
    const SolverSummary cs = PreconditionedConjugateGradient(h, *pre.At(h.CurvatureScale()), -g, &p, co);
    rep->newton_cg_iterations += cs.iterations;
    if (cs.termination == Termination::kFailed || !p.allFinite()) {
      rep->message = "MAP Newton step: CG failed (" + cs.message + ")";
      return false;
    }
    const double slope = g.dot(p);
    if (!(slope < 0)) {
      rep->message = "MAP Newton step is not a descent direction";
      return false;
    }
    // Backtracking: Armijo on F, or, when F changes only at rounding level, a decrease of |∇F|.
    double t = 1.0;
    bool accepted = false;
    for (int k = 0; k < 40 && !accepted; ++k, t *= 0.5) {
      const Vector xn = *x + t * p;
      Vector gn2;
      const MapObjective::Value vn = f.Evaluate(xn, &gn2);
      if (!vn.ok()) continue;
      const bool armijo = vn.total <= v.total + 1e-4 * t * slope;
      const bool flat = std::abs(vn.total - v.total) <= 1e-12 * std::abs(v.total) && gn2.norm() < gn;
      if (armijo || flat) {
        *x = xn;
        g = std::move(gn2);
        v = vn;
        accepted = true;
      }
    }
    ++rep->newton_steps;
    if (!accepted) {
      rep->map_gradient = g.norm() / gref;
      rep->message = "MAP Newton line search failed at |grad F| / |grad F(0)| = " + ToString(rep->map_gradient);
      return false;
    }
  }
}

}  // namespace

namespace {

const EmpiricalDesignOptions& ValidatedEmpiricalOptions(const EmpiricalDesignOptions& o) {
  const char* fn = "EmpiricalDesignObjective";
  std::string why;
  if (!o.IsValid(&why)) throw InvalidArgument(std::string(fn) + ": options." + why);
  return o;
}

}  // namespace

EmpiricalDesignObjective::EmpiricalDesignObjective(const DesignOptics& optics, int frames,
                                                   const EmpiricalDesignOptions& options)
    : options_(ValidatedEmpiricalOptions(options)),
      psf_(optics, frames, options.realisations, options.screens, options.seed, options.threads,
           "EmpiricalDesignObjective") {
  for (std::size_t k = 0; k < options_.training_scenes.size(); ++k)  // after the optics (psf_) are validated
    CheckArgument(ShapeOf(options_.training_scenes[k]) == psf_.hr_shape(), "EmpiricalDesignObjective",
                  "options.training_scenes[" + std::to_string(k) + "] shape",
                  ToString(ShapeOf(options_.training_scenes[k])), "the design grid " + ToString(psf_.hr_shape()));
  for (const Image& x : options_.training_scenes) scene_spectra_.push_back(FftForward(x.cast<Complex>()));
  const int per = std::max(1, psf_.realisations());
  const Index m = optics.grid / optics.r;
  const int pairs = int(options_.training_scenes.size()) * per;
  for (int p = 0; p < pairs; ++p) {
    NormalGenerator gen(DeriveSeed(options_.noise_seed, std::uint64_t(p)));
    ImageStack n;
    for (int i = 0; i < frames; ++i) {
      Image f(m, m);
      gen.Fill(f.data(), f.size());
      n.push_back(f * options_.noise_sigma);
    }
    noise_.push_back(std::move(n));
  }
  warm_.assign(pairs, Image());
}

double EmpiricalDesignObjective::invisible_floor() const { return std::numeric_limits<double>::quiet_NaN(); }

void EmpiricalDesignObjective::ResetWarmStarts() const {
  std::lock_guard<std::mutex> lock(mutex_);
  for (Image& w : warm_) w = Image();
}

EmpiricalEvaluation EmpiricalDesignObjective::last_evaluation() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return last_;
}

EmpiricalEvaluation EmpiricalDesignObjective::EvaluateWithReport(const std::vector<Image>& dm_opds,
                                                                 std::vector<Image>* grad) const {
  return Run(dm_opds, grad, nullptr);
}

double EmpiricalDesignObjective::EvaluateImpl(const std::vector<Image>& dm_opds, std::vector<Image>* grad) const {
  const EmpiricalEvaluation e = Run(dm_opds, grad, nullptr);
  if (!e.ok) throw NumericalError("EmpiricalDesignObjective: " + e.message);
  return e.objective;
}

std::vector<Image> EmpiricalDesignObjective::Reconstructions(const std::vector<Image>& dm_opds) const {
  std::vector<Image> out;
  const EmpiricalEvaluation e = Run(dm_opds, nullptr, &out);
  if (!e.ok) throw NumericalError("EmpiricalDesignObjective::Reconstructions: " + e.message);
  return out;
}

std::vector<ImageStack> EmpiricalDesignObjective::Frames(const std::vector<Image>& dm_opds) const {
  const DesignPsfModel::Set set = psf_.Compute(dm_opds, "EmpiricalDesignObjective::Frames");
  const MultiFrameModel a0 = psf_.NominalModel(set);
  std::vector<MultiFrameModel> real;
  for (int q = 0; q < psf_.realisations(); ++q) real.push_back(psf_.RealisedModel(set, q));
  const int per = std::max(1, psf_.realisations());
  std::vector<ImageStack> out;
  for (int p = 0; p < pairs(); ++p) {
    const int k = p / per, q = p % per;
    ImageStack y = (real.empty() ? a0 : real[q]).Render(options_.training_scenes[k]);
    for (std::size_t i = 0; i < y.size(); ++i) y[i] += noise_[p][i];
    out.push_back(std::move(y));
  }
  return out;
}

MultiFrameModel EmpiricalDesignObjective::NominalModel(const std::vector<Image>& dm_opds) const {
  return psf_.NominalModel(psf_.Compute(dm_opds, "EmpiricalDesignObjective::NominalModel", false));
}

std::vector<MultiFrameModel> EmpiricalDesignObjective::RealisedModels(const std::vector<Image>& dm_opds) const {
  const DesignPsfModel::Set set = psf_.Compute(dm_opds, "EmpiricalDesignObjective::RealisedModels");
  std::vector<MultiFrameModel> out;
  for (int q = 0; q < psf_.realisations(); ++q) out.push_back(psf_.RealisedModel(set, q));
  return out;
}

EmpiricalEvaluation EmpiricalDesignObjective::Run(const std::vector<Image>& dm_opds, std::vector<Image>* grad,
                                                  std::vector<Image>* reconstructions) const {
  const auto t0 = std::chrono::steady_clock::now();
  const DesignPsfModel::Set set = psf_.Compute(dm_opds, "EmpiricalDesignObjective::Evaluate");
  const DesignOptics& optics = psf_.optics();
  const Shape hr = psf_.hr_shape();
  const int n = frames(), nreal = psf_.realisations(), per = std::max(1, nreal), np = pairs();
  const double m2 = double(hr.size());
  const double weight = 1.0 / (options_.noise_sigma * options_.noise_sigma);
  auto a0 = std::make_shared<const MultiFrameModel>(psf_.NominalModel(set));
  std::vector<MultiFrameModel> real;
  for (int q = 0; q < nreal; ++q) real.push_back(psf_.RealisedModel(set, q));
  const OperatorPtr decimate = Decimate(hr, optics.r);
  const Shape lr{hr.rows / optics.r, hr.cols / optics.r};
  const bool want = grad != nullptr;

  std::vector<Image> warm;
  if (options_.warm_start) {
    std::lock_guard<std::mutex> lock(mutex_);
    warm = warm_;
  } else {
    warm.assign(np, Image());
  }

  EmpiricalEvaluation ev;
  ev.gradient = want;
  ev.pairs.resize(np);
  std::vector<Image> xhat(np);
  std::vector<std::vector<ComplexImage>> g0(np), gr(np);  // per pair Γ contributions (summed after)
  ParallelFor(np, options_.threads, [&](int p) {
    const int k = p / per, q = p % per;
    EmpiricalPairReport& rep = ev.pairs[p];
    rep.scene = k;
    rep.realisation = nreal > 0 ? q : 0;
    const Image& x_true = options_.training_scenes[k];
    ReconstructionProblem problem;
    problem.model = a0;
    problem.frames = (nreal > 0 ? real[q] : *a0).Render(x_true);
    for (int i = 0; i < n; ++i) {
      problem.frames[i] += noise_[p][i];
      problem.weights.push_back(Image::Constant(lr.rows, lr.cols, weight));
    }
    const MapObjective f(problem, options_.map);
    const OperatorPtr& a = a0->Operator();
    const Preconditioner pre(*a0, options_.map, weight);
    // The reference ||∇F(0)|| = ||A0ᵀ W y|| (∇R(0) = 0 for both priors).
    Vector g_zero;
    f.Evaluate(Vector::Zero(hr.size()), &g_zero);
    const double gref = g_zero.norm();
    if (!(gref > 0) || !std::isfinite(gref)) {
      rep.message = "scene " + std::to_string(k) + ": the data are zero or not finite (|A0^T W y| = " + ToString(gref) + ")";
      return;
    }
    // MAP: warm Newton, else (or if that fails) L-BFGS from cold then Newton.
    Vector x;
    bool converged = false;
    if (warm[p].size() > 0) {
      rep.warm_started = true;
      x = AsVector(warm[p]);
      converged = NewtonPolish(f, a, weight, options_.map, hr, pre, options_.map_tolerance, gref, options_.newton_iterations,
                               options_.newton_cg_iterations, &x, &rep);
    }
    if (!converged) {
      rep.message.clear();
      const MapResult cold = MapReconstruct(problem, options_.map);
      rep.lbfgs_iterations += cold.summary.iterations;
      x = AsVector(cold.image);
      converged = NewtonPolish(f, a, weight, options_.map, hr, pre, options_.map_tolerance, gref, options_.newton_iterations,
                               options_.newton_cg_iterations, &x, &rep);
    }
    rep.map_converged = converged;
    if (!converged) {
      rep.message = "scene " + std::to_string(k) + ", realisation " + std::to_string(rep.realisation) +
                    ": MAP solve did not reach |grad F| <= " + ToString(options_.map_tolerance) + " |grad F(0)|: " +
                    rep.message;
      return;
    }
    xhat[p] = AsImage(x, hr);
    // The loss and ∂ℓ/∂x̂.
    const Vector e = x - AsVector(x_true);
    Vector dl(e.size());
    double loss = 0;
    if (options_.loss == DesignLoss::kL2) {
      loss = e.squaredNorm() / m2;
      dl = 2.0 * e / m2;
    } else {
      const double eta = options_.loss_epsilon;
      for (Index i = 0; i < e.size(); ++i) {
        const double s = std::sqrt(e[i] * e[i] + eta * eta);
        loss += (e[i] * e[i]) / (s + eta);  // = s − η without cancellation
        dl[i] = e[i] / s;
      }
      loss /= m2;
      dl /= m2;
    }
    rep.loss = loss;
    if (!want) return;
    // Adjoint: H v = ∂ℓ/∂x̂.
    const MapHessian h(a, weight, options_.map, hr, x);
    Vector v = Vector::Zero(x.size());
    const SolverSummary cs = PreconditionedConjugateGradient(h, *pre.At(h.CurvatureScale()), dl, &v, options_.adjoint);
    rep.adjoint_iterations = cs.iterations;
    const double dln = dl.norm();
    rep.adjoint_residual = dln > 0 ? (dl - h.Apply(v)).norm() / dln : 0.0;
    rep.adjoint_converged = v.allFinite() && std::isfinite(rep.adjoint_residual) &&
                            rep.adjoint_residual <= 10 * options_.adjoint.tolerance;
    if (!rep.adjoint_converged) {
      rep.message = "scene " + std::to_string(k) + ", realisation " + std::to_string(rep.realisation) +
                    ": adjoint CG residual " + ToString(rep.adjoint_residual) + " after " +
                    std::to_string(cs.iterations) + " iterations (tolerance " + ToString(options_.adjoint.tolerance) +
                    "; " + cs.message + ")";
      return;
    }
    // Γ contributions (header): per frame i, with U1 = DFT(D_rᵀ W e_i), U2 = DFT(D_rᵀ W (A0 v)_i).
    const Vector resid = a->Apply(x) - a0->Flatten(problem.frames);
    const Vector av = a->Apply(v);
    const ComplexImage vs = FftForward(AsImage(v, hr).cast<Complex>()).conjugate();
    const ComplexImage xs = FftForward(xhat[p].cast<Complex>()).conjugate();
    const ComplexImage ts = scene_spectra_[k].conjugate();
    const Index lrn = lr.size();
    const double c = 1.0 / (double(np) * m2);
    g0[p].assign(n, ComplexImage());
    if (nreal > 0) gr[p].assign(n, ComplexImage());
    for (int i = 0; i < n; ++i) {
      const Vector up1 = decimate->ApplyAdjoint(weight * resid.segment(i * lrn, lrn));
      const Vector up2 = decimate->ApplyAdjoint(weight * av.segment(i * lrn, lrn));
      const ComplexImage u1 = FftForward(AsImage(up1, hr).cast<Complex>());
      const ComplexImage u2 = FftForward(AsImage(up2, hr).cast<Complex>());
      g0[p][i] = -c * (vs * u1 + xs * u2);
      const ComplexImage through_frames = c * (ts * u2);
      if (nreal > 0) {
        gr[p][i] = through_frames;
      } else {
        g0[p][i] += through_frames;
      }
    }
  });

  // Collect: the first failure, the objective, the warm starts.
  double total = 0;
  for (int p = 0; p < np; ++p) {
    const EmpiricalPairReport& rep = ev.pairs[p];
    ev.max_map_gradient = std::max(ev.max_map_gradient, rep.map_gradient);
    ev.max_adjoint_residual = std::max(ev.max_adjoint_residual, rep.adjoint_residual);
    if (ev.ok && (!rep.map_converged || !rep.adjoint_converged)) {
      ev.ok = false;
      ev.message = rep.message;
    }
    total += rep.loss;
  }
  ev.objective = total / double(np);
  if (ev.ok && !std::isfinite(ev.objective)) {
    ev.ok = false;
    ev.message = "the loss is not finite";
  }
  if (ev.ok && options_.warm_start) {
    std::lock_guard<std::mutex> lock(mutex_);
    warm_ = xhat;
  }
  if (grad) grad->clear();
  if (ev.ok && want) {
    std::vector<ComplexImage> gam0(n, ComplexImage::Zero(hr.rows, hr.cols));
    std::vector<std::vector<ComplexImage>> gamr(nreal, std::vector<ComplexImage>(n, ComplexImage::Zero(hr.rows, hr.cols)));
    for (int p = 0; p < np; ++p)
      for (int i = 0; i < n; ++i) {
        gam0[i] += g0[p][i];
        if (nreal > 0) gamr[p % per][i] += gr[p][i];
      }
    psf_.PullBack(set, gam0, gamr, grad);
    for (const Image& g : *grad)
      if (!AllFinite(g)) {
        ev.ok = false;
        ev.message = "the gradient is not finite";
        grad->clear();
        break;
      }
  }
  if (ev.ok) ev.message = "ok";
  if (reconstructions) *reconstructions = xhat;
  ev.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  {
    std::lock_guard<std::mutex> lock(mutex_);
    last_ = ev;
  }
  return ev;
}

}  // namespace aosr
