// Target-PSF linear reconstruction (target_psf.hpp): the per-bin analysis that sets κ and reports the
// effective PSF, leakage and noise; the exact Fourier solve; the PCG solve and noise probes for weighted data.
#include "aosr/solvers/target_psf.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <sstream>
#include <vector>

#include "aosr/ao/random.hpp"
#include "aosr/core/error.hpp"
#include "aosr/core/fft.hpp"
#include "aosr/core/linear_operator.hpp"
#include "aosr/core/operators.hpp"
#include "aosr/core/parallel.hpp"
#include "aosr/optics/psf_metrics.hpp"
#include "aosr/solvers/fourier_normal_system.hpp"

namespace aosr {
namespace {

constexpr const char* kTargetPsfFn = "ReconstructTargetPsf";
// ℓ threshold of the reported band and of "unreachable" frequencies (target_psf.hpp).
constexpr double kBandLeakage = 1e-3;
// Eigenvalues below this fraction of the largest count as directions the data do not reach (U_min, ℓ_min, and
// the leakage the bound on κ is held to): a singular value 1e-3 of the largest, whose recovery would amplify the
// noise 1000 times beyond the best-seen direction's. Why not the numerical rank (1e-18, tikhonov.hpp's): near the
// optics' cut-off the modes' eigenvalues fall continuously to 0, and an auto target (Gaussian of the PSF's FWHM)
// keeps ~0.2 % of its power there; counting those modes as reachable made the bound U ≤ U_min + 1e-3 chase them
// with a κ set by the MTF's last per mille, where a 0.8 % narrower model PSF moved κ 2.3x and the noise 29 %
// (paper-sim-r4, oracle against nominal PSFs: κ 1.4e-5 / 6.0e-6, noise 34.9 / 44.9). With this floor: κ 1.07e-4 /
// 1.00e-4, noise 21.8 / 22.6 (3.7 %), the effective FWHM 4.24 / 4.22 HR px (was 4.20 / 4.17).
constexpr double kReachFloor = 1e-6;

std::string Fixed(double v, int digits) {
  std::ostringstream s;
  s.setf(std::ios::fixed);
  s.precision(digits);
  s << v;
  return s.str();
}

// The target's transfer function on the HR half spectrum (rows x cols/2+1), T(0) = 1.
struct Target {
  ComplexImage half;
  std::string description;
  double fwhm = 0;  // HR pixels
};

ComplexImage GaussianTransfer(Shape hr, double fwhm) {
  const double sigma = fwhm / (2.0 * std::sqrt(2.0 * std::log(2.0)));
  const double c = -2.0 * M_PI * M_PI * sigma * sigma;
  ComplexImage t(hr.rows, hr.cols / 2 + 1);
  for (Index fy = 0; fy < t.rows(); ++fy) {
    const double sy = double(SignedFrequency(fy, hr.rows)) / double(hr.rows);
    for (Index fx = 0; fx < t.cols(); ++fx) {
      const double sx = double(SignedFrequency(fx, hr.cols)) / double(hr.cols);
      t(fy, fx) = std::exp(c * (sy * sy + sx * sx));
    }
  }
  return t;
}

double KernelFwhm(const Image& centred) {
  try {
    return MeasurePsf(centred).fwhm_px;
  } catch (const InvalidArgument&) {
    return 0.0;
  }
}

Target MakeTarget(const MultiFrameModel& model, const TargetPsfOptions& o) {
  const Shape hr = model.hr_shape();
  Target t;
  switch (o.kind) {
    case TargetPsfKind::kAuto: {
      // The mean FWHM of the frames' model PSFs (the optics without the pixel; each frame on its own, since
      // the frames' offsets would broaden an averaged PSF), at least one camera pixel.
      const Index w = std::min<Index>({hr.rows, hr.cols, 64}) / 2 * 2;
      double psf_fwhm = 0;
      for (int i = 0; i < model.frames(); ++i) psf_fwhm += KernelFwhm(OriginToCentred(FftC2R(model.otf(i), hr.cols), {w, w}));
      psf_fwhm /= double(model.frames());
      t.fwhm = std::max(psf_fwhm, double(model.r()));
      t.half = GaussianTransfer(hr, t.fwhm);
      t.description = "gaussian FWHM " + Fixed(t.fwhm, 2) + " HR px (auto: max(PSF FWHM " +
                      Fixed(psf_fwhm, 2) + ", r = " + std::to_string(model.r()) + "))";
      break;
    }
    case TargetPsfKind::kGaussian:
      t.fwhm = o.fwhm_hr_px;
      t.half = GaussianTransfer(hr, t.fwhm);
      t.description = "gaussian FWHM " + Fixed(t.fwhm, 2) + " HR px";
      break;
    case TargetPsfKind::kImage: {
      if (o.image.rows() > hr.rows || o.image.cols() > hr.cols)
        throw InvalidArgument(std::string(kTargetPsfFn) + ": options.image is " + ToString(ShapeOf(o.image)) +
                              ", larger than the HR grid " + ToString(hr));
      const Image k = o.image / o.image.sum();
      t.half = FftR2C(CentredToOrigin(k, hr));
      t.fwhm = KernelFwhm(k);
      t.description = "image " + ToString(ShapeOf(o.image)) + " (FWHM " + Fixed(t.fwhm, 2) + " HR px)";
      break;
    }
  }
  return t;
}

// Full-spectrum value of a half spectrum of a real signal at HR bin (fy, fx).
Complex FullAt(const ComplexImage& half, Shape hr, Index fy, Index fx) {
  if (fx < half.cols()) return half(fy, fx);
  return std::conj(half((hr.rows - fy) % hr.rows, hr.cols - fx));
}

// One bin's modes: AᴴA = Σ_j e_j v_j v_jᴴ, g_j = √e_j v_j (= Aᴴu_j), and h_j, the vector that turns the data
// coefficient c_j into the ridge solution X = Σ_j h_j c_j / (e_j + κ).
struct Modes {
  Eigen::VectorXd e;
  Eigen::MatrixXcd g;  // r² x q
  Eigen::MatrixXcd h;  // r² x q
  Eigen::MatrixXcd c_map;  // q x N: c = c_map Y
};

Modes Analyse(const Eigen::MatrixXcd& a) {
  const Index n = a.rows(), rr = a.cols();
  Modes m;
  if (n <= rr) {
    const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXcd> es(a * a.adjoint());
    m.e = es.eigenvalues().cwiseMax(0.0);
    m.g = a.adjoint() * es.eigenvectors();
    m.h = m.g;
    m.c_map = es.eigenvectors().adjoint();
  } else {
    const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXcd> es(a.adjoint() * a);
    m.e = es.eigenvalues().cwiseMax(0.0);
    m.h = es.eigenvectors();
    m.g = m.h * m.e.cwiseSqrt().asDiagonal();
    m.c_map = m.h.adjoint() * a.adjoint();
  }
  return m;
}

// The LR bins in rows, with the mirror-pair bookkeeping of FourierSystem::Solve: only the bin of each pair
// {u, −u} with (ux < mux) or (ux == mux and uy <= muy) is computed; the other is its conjugate.
struct BinIndex {
  Index uy, ux;
  bool canonical;
  bool self_mirror;
};
BinIndex Classify(Shape lr, Index uy, Index ux) {
  const Index muy = (lr.rows - uy) % lr.rows, mux = (lr.cols - ux) % lr.cols;
  return {uy, ux, ux < mux || (ux == mux && uy <= muy), ux == mux && uy == muy};
}

// What the κ search needs from every canonical bin: e_j and a_j = Σ_k |T_k|² |g_kj|², plus Σ_k |T_k|²; and, for
// the flux normalisation's factor 1/dc(κ), the zero-frequency row's modes: dc(κ) = Σ_j |g_0j|² / (e_j + κ).
struct SearchData {
  std::vector<double> e, a;        // concatenated over bins
  std::vector<double> bin_weight;  // multiplicity (1 or 2) per entry of e/a
  double target_power = 0;         // Σ_f |T(f)|² over the whole HR grid
  double e_max = 0;
  std::vector<double> dc_e, dc_g2;  // the DC bin's e_j and |g_0j|²

  double Dc(double kappa) const {
    double dc = 0;
    for (std::size_t j = 0; j < dc_e.size(); ++j) dc += dc_g2[j] / (dc_e[j] + kappa);
    return dc;
  }
};

SearchData CollectSearchData(const MultiFrameModel& model, const Target& target) {
  const Shape hr = model.hr_shape(), lr = model.lr_shape();
  const int r = model.r(), rr = r * r;
  struct Row {
    std::vector<double> e, a, w, dc_e, dc_g2;
    double power = 0, e_max = 0;
  };
  std::vector<Row> rows(lr.rows);
  ParallelFor(lr.rows, [&](Index uy) {
    Row& row = rows[uy];
    Eigen::VectorXd t2(rr);
    for (Index ux = 0; ux < lr.cols; ++ux) {
      const BinIndex b = Classify(lr, uy, ux);
      if (!b.canonical) continue;
      const double mult = b.self_mirror ? 1.0 : 2.0;
      for (int ky = 0; ky < r; ++ky)
        for (int kx = 0; kx < r; ++kx)
          t2[ky * r + kx] = std::norm(FullAt(target.half, hr, uy + ky * lr.rows, ux + kx * lr.cols));
      row.power += mult * t2.sum();
      const Modes m = Analyse(model.AliasedSystem(uy, ux));
      if (uy == 0 && ux == 0)
        for (Index j = 0; j < m.e.size(); ++j) {
          row.dc_e.push_back(m.e[j]);
          row.dc_g2.push_back(std::norm(m.g(0, j)));
        }
      for (Index j = 0; j < m.e.size(); ++j) {
        row.e.push_back(m.e[j]);
        row.a.push_back(t2.dot(m.g.col(j).cwiseAbs2()));
        row.w.push_back(mult);
        row.e_max = std::max(row.e_max, m.e[j]);
      }
    }
  });
  SearchData s;
  for (const Row& row : rows) {  // in row order: the same sums for any thread count
    s.e.insert(s.e.end(), row.e.begin(), row.e.end());
    s.a.insert(s.a.end(), row.a.begin(), row.a.end());
    s.bin_weight.insert(s.bin_weight.end(), row.w.begin(), row.w.end());
    s.target_power += row.power;
    s.e_max = std::max(s.e_max, row.e_max);
    s.dc_e.insert(s.dc_e.end(), row.dc_e.begin(), row.dc_e.end());
    s.dc_g2.insert(s.dc_g2.end(), row.dc_g2.begin(), row.dc_g2.end());
  }
  return s;
}

// The search data of the DC bin only, with e_max given: what the flux factor 1/dc(κ) needs when κ is given too.
SearchData DcSearchData(const MultiFrameModel& model, double e_max) {
  SearchData s;
  s.e_max = e_max;
  const Modes m = Analyse(model.AliasedSystem(0, 0));
  for (Index j = 0; j < m.e.size(); ++j) {
    s.dc_e.push_back(m.e[j]);
    s.dc_g2.push_back(std::norm(m.g(0, j)));
  }
  return s;
}

// U(κ) = (Σ|T|² − Σ_j a_j (2s/(e_j + κ) − s² e_j/(e_j + κ)²)) / Σ|T|², s = 1/dc(κ): the leakage of (1) with
// the flux normalisation (ℓ_k = |T_k|² ‖s·row k of RA − e_k‖², summed over the modes; at s = 1 the captured part
// is a_j (e_j + 2κ)/(e_j + κ)²). Why s belongs in the search: it is 1 + κ/e at DC, small at a tight bound but
// not at a loose one (ε = 1e-2 on tests' scene: U 0.010 without it, 0.003 with), and the output carries it.
// kappa = 0: U_min, the modes below the reach floor (kReachFloor) lost and the rest captured. reachable_only:
// the modes below the floor count as lost at any κ (what the bound U ≤ U_min + ε is held to; ≥ the true U,
// since (1) captures a little of them).
double Leakage(const SearchData& s, double kappa, bool reachable_only = false) {
  const double floor = kReachFloor * s.e_max;
  const double dc = kappa > 0 ? s.Dc(kappa) : 1.0;
  const double f = dc > 0 ? 1.0 / dc : 1.0;
  double captured = 0;
  for (std::size_t j = 0; j < s.e.size(); ++j) {
    const double e = s.e[j];
    if (kappa > 0) {
      const double d = e + kappa;
      if (!reachable_only || e > floor) captured += s.bin_weight[j] * s.a[j] * (2.0 * f / d - f * f * e / (d * d));
    } else if (e > floor) {
      captured += s.bin_weight[j] * s.a[j] / e;
    }
  }
  return std::clamp((s.target_power - captured) / s.target_power, 0.0, 1.0);
}

// The preconditioner: (w̄ AᵀA + κ' I)⁻¹ by FourierNormalSystem.
class FourierNormalInverse final : public LinearOperator {
 public:
  FourierNormalInverse(const FourierNormalSystem& sys, Shape hr)
      : LinearOperator(hr.size(), hr.size(), "FourierNormalInverse(" + ToString(hr) + ")"), sys_(sys), hr_(hr) {}

 private:
  void ApplyImpl(ConstRef b, Ref x) const override {
    const Image out = sys_.Solve(ToImage(b, hr_));
    x = AsVector(out);
  }
  void ApplyAdjointImpl(ConstRef y, Ref x) const override { ApplyImpl(y, x); }
  const FourierNormalSystem& sys_;
  Shape hr_;
};

// x ↦ T ⊛ x / dc (the flux normalisation, target_psf.hpp "Flux": every frequency, so the filter stays smooth).
Image ApplyTarget(const Image& x, const ComplexImage& t_half, double dc) {
  ComplexImage s = FftR2C(x);
  s *= t_half * (1.0 / dc);
  return FftC2R(s, x.cols());
}

Index EvenSize(double v) { return std::max<Index>(2, Index(std::ceil(v / 2.0)) * 2); }

}  // namespace

bool TargetPsfOptions::IsValid(std::string* why) const {
  auto fail = [why](const std::string& m) {
    if (why) *why = m;
    return false;
  };
  if (kind == TargetPsfKind::kGaussian && !(std::isfinite(fwhm_hr_px) && fwhm_hr_px >= 0.5))
    return fail("fwhm_hr_px = " + std::to_string(fwhm_hr_px) + "; allowed: >= 0.5 HR pixels for a Gaussian target");
  if (kind == TargetPsfKind::kImage) {
    if (image.size() == 0) return fail("image is empty; allowed: a centred kernel for an image target");
    if (!AllFinite(image)) return fail("image has non-finite values");
    if (!(image.sum() > 0)) return fail("image sum = " + std::to_string(image.sum()) + "; allowed: > 0");
  }
  if (!(std::isfinite(leakage) && leakage > 0 && leakage < 1))
    return fail("leakage = " + std::to_string(leakage) + "; allowed: (0, 1)");
  if (!(std::isfinite(kappa) && kappa >= 0))
    return fail("kappa = " + std::to_string(kappa) + "; allowed: 0 (by the leakage bound) or > 0");
  if (!(std::isfinite(e_max) && e_max >= 0))
    return fail("e_max = " + std::to_string(e_max) + "; allowed: 0 (this problem's own) or > 0 and finite");
  if (e_max > 0 && !(kappa > 0))
    return fail("e_max = " + std::to_string(e_max) + " without kappa; allowed: e_max only with a given kappa > 0");
  if (!(std::isfinite(noise_sigma) && noise_sigma > 0))
    return fail("noise_sigma = " + std::to_string(noise_sigma) + "; allowed: > 0");
  if (noise_probes < 2) return fail("noise_probes = " + std::to_string(noise_probes) + "; allowed: >= 2");
  std::string cg_why;
  if (!cg.IsValid(&cg_why)) return fail("cg." + cg_why);
  if (psf_size != 0 && (psf_size < 4 || psf_size % 2))
    return fail("psf_size = " + std::to_string(psf_size) + "; allowed: 0 (automatic) or even >= 4");
  if (correlation_radius < -1)
    return fail("correlation_radius = " + std::to_string(correlation_radius) + "; allowed: -1 (2r) or >= 0");
  return true;
}

Image GaussianTargetKernel(double fwhm_px, Index size) {
  if (!(std::isfinite(fwhm_px) && fwhm_px > 0) || size < 2 || size % 2)
    throw InvalidArgument("GaussianTargetKernel", "fwhm_px, size",
                          std::to_string(fwhm_px) + ", " + std::to_string(size), "fwhm > 0, size even >= 2");
  const Shape s{size, size};
  return OriginToCentred(FftC2R(GaussianTransfer(s, fwhm_px), size), s);
}

namespace {

void CheckInputs(const ReconstructionProblem& problem, const TargetPsfOptions& options) {
  problem.Validate(kTargetPsfFn);
  // The target-PSF output is a per-frequency design: it needs one PSF per frame over its field. A PSF that
  // varies over the field is served by tiles (solvers/psf_field_model.hpp), each with its local PSFs.
  if (problem.model->space_variant())
    throw InvalidArgument(kTargetPsfFn, "problem.model", "space-variant",
                          "an isoplanatic model: reconstruct a varying PSF by tiles (psf_field tiles), each with "
                          "its local PSFs and the same target");
  std::string why;
  if (!options.IsValid(&why)) throw InvalidArgument(std::string(kTargetPsfFn) + ": options." + why);
}

// The target and κ: by the leakage bound's search over every bin's modes, or given. κ and e_max given (a tile
// of a field, tiling.hpp): no search, so the bins are analysed once, in ReconstructTargetPsf's pass, which then
// sums U and U_min; only the DC bin's modes (for the flux factor) are needed before it.
struct KappaChoice {
  Target target;
  SearchData sd;
  bool given = false;
  double kappa = 0, goal = 0, leakage_unreachable = 0, leakage = 0;
  bool leakage_met = false;
};

KappaChoice ChooseKappa(const MultiFrameModel& model, const TargetPsfOptions& options) {
  KappaChoice c;
  c.target = MakeTarget(model, options);
  c.given = options.kappa > 0 && options.e_max > 0;
  c.sd = c.given ? DcSearchData(model, options.e_max) : CollectSearchData(model, c.target);
  const SearchData& sd = c.sd;
  if (!(sd.e_max > 0)) throw InvalidArgument(std::string(kTargetPsfFn) + ": the model's transfer functions are all zero");
  if (c.given) {
    c.kappa = options.kappa;
    return c;
  }
  c.leakage_unreachable = Leakage(sd, 0.0);
  c.goal = c.leakage_unreachable + options.leakage;
  double lo = std::log(1e-14 * sd.e_max), hi = std::log(1e4 * sd.e_max);
  if (options.kappa > 0) {
    lo = hi = std::log(options.kappa);  // given: no search
  } else if (Leakage(sd, std::exp(hi), true) <= c.goal) {
    lo = hi;
  } else if (Leakage(sd, std::exp(lo), true) > c.goal) {
    hi = lo;
  } else {
    while (hi - lo > 1e-9) {
      const double mid = 0.5 * (lo + hi);
      (Leakage(sd, std::exp(mid), true) <= c.goal ? lo : hi) = mid;
    }
  }
  c.kappa = options.kappa > 0 ? options.kappa : std::exp(lo);
  c.leakage = Leakage(sd, c.kappa);
  c.leakage_met = c.leakage <= c.goal * (1 + 1e-9);
  return c;
}

}  // namespace

TargetPsfChoice ChooseTargetPsf(const ReconstructionProblem& problem, const TargetPsfOptions& options) {
  CheckInputs(problem, options);
  const KappaChoice c = ChooseKappa(*problem.model, options);
  return {c.kappa, c.sd.e_max, c.target.fwhm};
}

TargetPsfResult ReconstructTargetPsf(const ReconstructionProblem& problem, const TargetPsfOptions& options) {
  const auto start = std::chrono::steady_clock::now();
  CheckInputs(problem, options);
  const MultiFrameModel& model = *problem.model;
  const Shape hr = model.hr_shape(), lr = model.lr_shape();
  const int r = model.r(), rr = r * r, n = model.frames();
  const Index half_cols = hr.cols / 2 + 1;

  TargetPsfResult result;
  TargetPsfSummary& s = result.summary;
  s.fourier_exact = problem.HasUniformWeights();
  s.method = s.fourier_exact ? "target-psf-fourier" : "target-psf-cg";
  s.noise_sigma = options.noise_sigma;

  // --- the target and κ ---------------------------------------------------------------------------------
  KappaChoice choice = ChooseKappa(model, options);
  const Target& target = choice.target;
  SearchData& sd = choice.sd;
  const bool given = choice.given;
  s.target = target.description;
  s.target_fwhm_hr_px = target.fwhm;
  s.e_max = sd.e_max;
  s.kappa = choice.kappa;
  s.leakage_unreachable = choice.leakage_unreachable;
  s.leakage = choice.leakage;
  s.leakage_met = choice.leakage_met;
  double goal = choice.goal;
  const double kappa = s.kappa;

  // DC transfer e/(e + κ) of the zero-frequency row, divided out for flux conservation.
  const double dc = sd.Dc(kappa);
  if (!(dc > 0)) throw InvalidArgument(std::string(kTargetPsfFn) + ": the frames carry no flux information (zero DC transfer)");
  s.dc_transfer = dc;
  const double flux = 1.0 / dc;  // every output frequency's gain (target_psf.hpp, "Flux")

  // --- per-bin pass: effective transfer, leakage, noise spectrum and cell, and (Fourier path) the solution --
  const double null_floor = kReachFloor * sd.e_max;
  std::vector<ComplexImage> y_half;
  if (s.fourier_exact) {
    const ImageStack clean = problem.CleanFrames();
    for (int i = 0; i < n; ++i) y_half.push_back(FftR2C(clean[i]));
  }
  ComplexImage teff(hr.rows, half_cols), x_half(hr.rows, half_cols), ridge_half(hr.rows, half_cols);
  Image leak(hr.rows, hr.cols), leak_min(hr.rows, hr.cols), noise_s(hr.rows, hr.cols);
  teff.setZero();
  x_half.setZero();
  ridge_half.setZero();
  std::vector<Image> cell_rows(lr.rows, Image::Zero(r, r));
  // Twiddles e^{2πi k p / r}.
  Eigen::MatrixXcd tw(r, r);
  for (int k = 0; k < r; ++k)
    for (int p = 0; p < r; ++p) tw(k, p) = std::polar(1.0, 2.0 * M_PI * double(k * p) / r);
  const bool want_cell = options.compute_noise && s.fourier_exact;
  // κ given with e_max: the search's sums, per row (combined in row order: the same bytes for any thread count).
  struct RowSums {
    double power = 0, captured_min = 0, captured = 0;
  };
  std::vector<RowSums> row_sums(given ? lr.rows : 0);
  ParallelFor(lr.rows, [&](Index uy) {
    Eigen::VectorXcd t(rr), x(rr), ridge_x(rr), c;
    Eigen::MatrixXcd z(r, r), gt(rr, 1);
    Image& cell = cell_rows[uy];
    for (Index ux = 0; ux < lr.cols; ++ux) {
      const BinIndex b = Classify(lr, uy, ux);
      if (!b.canonical) continue;
      const double mult = b.self_mirror ? 1.0 : 2.0;
      for (int ky = 0; ky < r; ++ky)
        for (int kx = 0; kx < r; ++kx) t[ky * r + kx] = FullAt(target.half, hr, uy + ky * lr.rows, ux + kx * lr.cols);
      const Eigen::MatrixXcd a = model.AliasedSystem(uy, ux);
      const Modes m = Analyse(a);
      const Index q = m.e.size();
      Eigen::VectorXd inv1(q), inv2(q), lmin(q);
      for (Index j = 0; j < q; ++j) {
        const double d = m.e[j] + kappa;
        inv1[j] = 1.0 / d;
        inv2[j] = 1.0 / (d * d);
        lmin[j] = m.e[j] > null_floor ? 1.0 / m.e[j] : 0.0;
      }
      const Eigen::MatrixXd g2 = m.g.cwiseAbs2();  // r² x q
      // ‖row k of RA‖² = Σ_j |g_kj|² e_j/(e_j + κ)² (RA = G diag(1/(e + κ)) Gᴴ, GᴴG = diag(e)).
      const Eigen::VectorXd rkk = g2 * inv1, skk = g2 * inv2, r2k = g2 * m.e.cwiseProduct(inv2), lmk = g2 * lmin;
      if (given) {  // CollectSearchData's a_j = Σ_k |T_k|² |g_kj|², and Leakage's sums at 0 and at κ
        RowSums& rs = row_sums[uy];
        const Eigen::VectorXd t2 = t.cwiseAbs2();
        rs.power += mult * t2.sum();
        for (Index j = 0; j < q; ++j) {
          const double aj = t2.dot(g2.col(j)), d = m.e[j] + kappa;
          rs.captured_min += mult * aj * lmin[j];
          rs.captured += mult * aj * (2.0 * flux / d - flux * flux * m.e[j] / (d * d));
        }
      }
      if (s.fourier_exact) {
        Eigen::VectorXcd yv(n);
        for (int i = 0; i < n; ++i) yv[i] = y_half[i](uy, ux);
        c = m.c_map * yv;
        x.setZero();
        for (Index j = 0; j < q; ++j) x += m.h.col(j) * (c[j] * inv1[j]);
        ridge_x = x;
        for (int k = 0; k < rr; ++k) x[k] *= t[k] * flux;
        if (b.self_mirror) {  // exactly Hermitian within the bin (FourierSystem::Solve)
          for (Eigen::VectorXcd* v : {&x, &ridge_x}) {
            const Eigen::VectorXcd v0 = *v;
            for (int ky = 0; ky < r; ++ky)
              for (int kx = 0; kx < r; ++kx) {
                const Index my = (hr.rows - (uy + ky * lr.rows)) % hr.rows;
                const Index mx = (hr.cols - (ux + kx * lr.cols)) % hr.cols;
                (*v)[ky * r + kx] =
                    0.5 * (v0[ky * r + kx] + std::conj(v0[int(my / lr.rows) * r + int(mx / lr.cols)]));
              }
          }
        }
      }
      for (int ky = 0; ky < r; ++ky)
        for (int kx = 0; kx < r; ++kx) {
          const int k = ky * r + kx;
          const Index fy = uy + ky * lr.rows, fx = ux + kx * lr.cols;
          const Index my = (hr.rows - fy) % hr.rows, mx = (hr.cols - fx) % hr.cols;
          const double t2 = std::norm(t[k]);
          // ℓ = |T_k|² ‖s·row k of RA − e_k‖² = |T_k|² (s² ‖row‖² − 2 s (RA)_kk + 1), s = 1/dc.
          const double l = std::max(t2 * (flux * flux * r2k[k] - 2.0 * flux * rkk[k] + 1.0), 0.0);
          const Complex te = t[k] * (rkk[k] * flux);
          const double sn = t2 * skk[k] * (flux * flux);
          const double lm = std::max(t2 * (1.0 - lmk[k]), 0.0);
          leak(fy, fx) = leak(my, mx) = l;
          leak_min(fy, fx) = leak_min(my, mx) = lm;
          noise_s(fy, fx) = noise_s(my, mx) = sn;
          if (fx < half_cols) {
            teff(fy, fx) = te;
            if (s.fourier_exact) {
              x_half(fy, fx) = x[k];
              ridge_half(fy, fx) = ridge_x[k];
            }
          }
          if (mx < half_cols) {
            teff(my, mx) = std::conj(te);
            if (s.fourier_exact) {
              x_half(my, mx) = std::conj(x[k]);
              ridge_half(my, mx) = std::conj(ridge_x[k]);
            }
          }
        }
      if (want_cell) {
        // Σ_j |Σ_k e^{2πi k·p/r} T_k g_kj/(e_j+κ)|² for the r x r phases p, separably (2r³ per mode).
        for (Index j = 0; j < q; ++j) {
          for (int ky = 0; ky < r; ++ky)
            for (int kx = 0; kx < r; ++kx) {
              const int k = ky * r + kx;
              z(ky, kx) = t[k] * m.g(k, j) * (inv1[j] * flux);
            }
          const Eigen::MatrixXcd zx = z * tw;          // (ky, px)
          const Eigen::MatrixXcd zz = tw.transpose() * zx;  // (py, px)
          for (int py = 0; py < r; ++py)
            for (int px = 0; px < r; ++px) cell(py, px) += mult * std::norm(zz(py, px));
        }
      }
    }
  });

  // --- leakage report ---------------------------------------------------------------------------------
  if (given) {
    double power = 0, captured_min = 0, captured = 0;
    for (const RowSums& rs : row_sums) {
      power += rs.power;
      captured_min += rs.captured_min;
      captured += rs.captured;
    }
    sd.target_power = power;
    s.leakage_unreachable = std::clamp((power - captured_min) / power, 0.0, 1.0);
    goal = s.leakage_unreachable + options.leakage;
    s.leakage_met = std::clamp((power - captured) / power, 0.0, 1.0) <= goal * (1 + 1e-9);
  }
  {
    // U from the per-frequency map (each frequency's ℓ clamped at 0; the search sums the modes unclamped).
    s.leakage = leak.sum() / sd.target_power;
    // The band: the largest radius below which every HR frequency has ℓ ≤ 1e-3.
    double band = 0.5 * std::sqrt(2.0) + 1e-12, in_band_max = 0;
    for (Index fy = 0; fy < hr.rows; ++fy)
      for (Index fx = 0; fx < hr.cols; ++fx) {
        if (leak(fy, fx) <= kBandLeakage) continue;
        const double sy = double(SignedFrequency(fy, hr.rows)) / double(hr.rows);
        const double sx = double(SignedFrequency(fx, hr.cols)) / double(hr.cols);
        band = std::min(band, std::hypot(sy, sx));
      }
    Index unreachable = 0;
    for (Index fy = 0; fy < hr.rows; ++fy)
      for (Index fx = 0; fx < hr.cols; ++fx) {
        unreachable += leak_min(fy, fx) > kBandLeakage;
        const double sy = double(SignedFrequency(fy, hr.rows)) / double(hr.rows);
        const double sx = double(SignedFrequency(fx, hr.cols)) / double(hr.cols);
        if (std::hypot(sy, sx) < band) in_band_max = std::max(in_band_max, leak(fy, fx));
      }
    s.band_cycles_per_hr_px = std::min(band, 0.5 * std::sqrt(2.0));
    s.leakage_max_in_band = in_band_max;
    s.unreachable_frequencies = unreachable;
    // fftshift for viewing: zero frequency at (M_y/2, M_x/2).
    result.leakage_spectrum.resize(hr.rows, hr.cols);
    for (Index fy = 0; fy < hr.rows; ++fy)
      for (Index fx = 0; fx < hr.cols; ++fx)
        result.leakage_spectrum((fy + hr.rows / 2) % hr.rows, (fx + hr.cols / 2) % hr.cols) = leak(fy, fx);
  }

  // --- effective and target PSF images ----------------------------------------------------------------
  const Index max_side = std::min(hr.rows, hr.cols) / 2 * 2;
  const Index psf_side = options.psf_size > 0 ? std::min<Index>(options.psf_size, max_side)
                                              : std::clamp<Index>(EvenSize(16.0 * target.fwhm), 32, max_side);
  result.effective_psf = OriginToCentred(FftC2R(teff, hr.cols), {psf_side, psf_side});
  result.target_psf = OriginToCentred(FftC2R(target.half, hr.cols), {psf_side, psf_side});
  s.effective_fwhm_hr_px = KernelFwhm(result.effective_psf);
  s.effective_psf_window_fraction = result.effective_psf.sum();

  // --- the estimate --------------------------------------------------------------------------------------
  Image ridge;  // the ridge part y of (1), for the residual report
  const ConjugateGradientOptions cg = options.cg;
  std::vector<double> w_flat;
  OperatorPtr normal, precond;
  std::unique_ptr<FourierNormalSystem> fns;
  Image w_stack;
  double w_bar = 1;
  if (s.fourier_exact) {
    result.image = FftC2R(x_half, hr.cols);
    ridge = FftC2R(ridge_half, hr.cols);
  } else {
    w_stack.resize(Index(n) * lr.rows, lr.cols);
    for (int i = 0; i < n; ++i) w_stack.middleRows(Index(i) * lr.rows, lr.rows) = problem.Weight(i);
    const Index n_w = (w_stack > 0).count();
    w_bar = w_stack.sum() / double(std::max<Index>(1, n_w));
    const double kappa_spatial = kappa * double(rr) * w_bar;
    fns = std::make_unique<FourierNormalSystem>(model, w_bar);
    fns->Factorize(0.0, kappa_spatial);
    const OperatorPtr& a = model.Operator();
    normal = Sum({Compose(Adjoint(a), Compose(Mask(w_stack), a)), Scale(kappa_spatial, Identity(hr.size()))});
    precond = std::make_shared<FourierNormalInverse>(*fns, hr);
    const Vector d = model.Flatten(problem.CleanFrames());
    const Vector rhs = a->ApplyAdjoint(AsVector(w_stack).cwiseProduct(d));
    Vector y = Vector::Zero(hr.size());
    const SolverSummary solve = PreconditionedConjugateGradient(*normal, *precond, rhs, &y, cg);
    s.iterations += solve.iterations;
    if (solve.termination != Termination::kConverged) {
      s.termination = solve.termination;
      s.message = "ridge solve: " + solve.message + "; ";
    }
    ridge = ToImage(y, hr);
    result.image = ApplyTarget(ridge, target.half, dc);
  }
  if (!AllFinite(result.image)) {
    result.image = Image::Zero(hr.rows, hr.cols);
    s.termination = Termination::kFailed;
    s.message += "non-finite estimate (zeroed); ";
  }
  if (ridge.size()) WeightedDataMisfit(problem, ridge, &s.frame_residual_rms);

  // --- noise -------------------------------------------------------------------------------------------
  if (options.compute_noise) {
    const Index rad = std::min<Index>(options.correlation_radius >= 0 ? options.correlation_radius : 2 * r,
                                      (std::min(hr.rows, hr.cols) - 1) / 2);
    const Shape corr_window{2 * rad + 1, 2 * rad + 1};
    if (s.fourier_exact) {
      const double w0 = problem.weights.empty() ? 1.0 : problem.weights.front()(0, 0);
      const double v = options.noise_sigma * options.noise_sigma / w0;  // frame-pixel variance
      Image cell = Image::Zero(r, r);
      for (const Image& c : cell_rows) cell += c;
      cell *= v / (double(rr) * double(rr) * double(lr.size()));
      result.noise_std.resize(hr.rows, hr.cols);
      for (Index yy = 0; yy < hr.rows; ++yy)
        for (Index xx = 0; xx < hr.cols; ++xx) result.noise_std(yy, xx) = std::sqrt(std::max(0.0, cell(yy % r, xx % r)));
      // ξ(Δ) = (v / r²) IFFT(S)(Δ) (target_psf.hpp).
      // S is real and even, so its left half is the half spectrum FftC2R inverts (dividing by M²).
      const Image xi = FftC2R(noise_s.leftCols(half_cols).cast<Complex>(), hr.cols) * (v / double(rr));
      result.noise_correlation = OriginToCentred(xi, corr_window);
      s.noise_rms = std::sqrt(std::max(0.0, cell.mean()));
    } else {
      // Probes: n = σ z / √w on weighted pixels, x̂_n = T ⊛ (AᵀWA + κ'I)⁻¹ AᵀW n, so AᵀW n = σ Aᵀ(√w z).
      const int k_probes = options.noise_probes;
      // A probe only feeds a variance estimate whose own error is √(2/K) ~ 0.25: a relative residual of 1e-6 is
      // far below that (and about 3x fewer iterations than the data solve's default 1e-9).
      ConjugateGradientOptions probe_cg = cg;
      probe_cg.tolerance = std::max(cg.tolerance, 1e-6);
      const OperatorPtr& a = model.Operator();
      Image sum2 = Image::Zero(hr.rows, hr.cols), sum4 = Image::Zero(hr.rows, hr.cols);
      Image corr_sum = Image::Zero(hr.rows, hr.cols);
      std::vector<double> probe_means;
      Vector sqrt_w = AsVector(w_stack).cwiseMax(0.0).cwiseSqrt();
      for (int p = 0; p < k_probes; ++p) {
        NormalGenerator gen(DeriveSeed(options.seed, std::uint64_t(p)));
        Vector z(sqrt_w.size());
        gen.Fill(z.data(), z.size());
        const Vector rhs = a->ApplyAdjoint(options.noise_sigma * sqrt_w.cwiseProduct(z));
        Vector y = Vector::Zero(hr.size());
        const SolverSummary ps = PreconditionedConjugateGradient(*normal, *precond, rhs, &y, probe_cg);
        s.iterations += ps.iterations;
        if (ps.termination != Termination::kConverged && s.termination == Termination::kConverged) {
          s.termination = ps.termination;
          s.message += "noise probe: " + ps.message + "; ";
        }
        const Image xn = ApplyTarget(ToImage(y, hr), target.half, dc);
        const Image x2 = xn.square();
        sum2 += x2;
        sum4 += x2.square();
        probe_means.push_back(x2.mean());
        ComplexImage f = FftR2C(xn);
        f = f.abs2().cast<Complex>();
        corr_sum += FftC2R(f, hr.cols);  // = Σ_p x(p) x(p+Δ)
      }
      const double kk = double(k_probes);
      const Image var = sum2 / kk;
      // Per-pixel standard error of the variance (spread of x̂_n² over the probes) and of σ = √var.
      const Image var_se = ((sum4 / kk - var.square()).max(0.0) / (kk - 1.0)).sqrt();
      result.noise_std = var.sqrt();
      result.noise_std_error = (var > 0).select(var_se / (2.0 * result.noise_std), 0.0);
      // IFFT(|X|²) = (1/M²) Σ_f |X|² e^{...} = Σ_p x(p) x(p+Δ): divide by M² for the average over p.
      result.noise_correlation = OriginToCentred(corr_sum / (kk * double(hr.size())), corr_window);
      double mean = 0, m2 = 0;
      for (double m : probe_means) mean += m;
      mean /= kk;
      for (double m : probe_means) m2 += (m - mean) * (m - mean);
      s.noise_rms = std::sqrt(std::max(0.0, mean));
      const double se_mean = std::sqrt(m2 / (kk - 1.0) / kk);
      s.noise_rms_error = s.noise_rms > 0 ? se_mean / (2.0 * s.noise_rms) : 0.0;
      s.noise_probes = k_probes;
    }
  }

  // --- summary -------------------------------------------------------------------------------------------
  std::ostringstream msg;
  msg.precision(3);
  msg << s.message << "target " << s.target << "; κ = " << kappa << (options.kappa > 0 ? " (given)" : "")
      << ", leakage U = " << s.leakage
      << " (unreachable " << s.leakage_unreachable << ", bound +" << options.leakage << ")";
  if (!s.leakage_met) msg << (options.kappa > 0 ? " NOT MET at the given κ" : " NOT MET: κ at its search floor");
  msg << "; ℓ ≤ 1e-3 for |f| < " << s.band_cycles_per_hr_px << " cycles/HR px";
  if (s.unreachable_frequencies > 0) msg << "; " << s.unreachable_frequencies << " HR frequencies unreachable";
  if (options.compute_noise) {
    msg << "; noise RMS " << s.noise_rms;
    if (s.noise_probes) msg << " ± " << s.noise_rms_error << " (" << s.noise_probes << " probes)";
  }
  s.message = msg.str();
  s.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return result;
}

}  // namespace aosr
