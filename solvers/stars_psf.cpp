#include "aosr/solvers/stars_psf.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <memory>

#include "aosr/core/error.hpp"
#include "aosr/core/fft.hpp"
#include "aosr/core/operators.hpp"
#include "aosr/solvers/conjugate_gradient.hpp"
#include "aosr/solvers/dataset_problem.hpp"
#include "star_field_model.hpp"

namespace aosr {
namespace {

using stars_internal::NodeStars;
using stars_internal::Star;
using stars_internal::StarFieldModel;
using stars_internal::StarTransfer;

constexpr const char* kStarsPsfFn = "EstimateStarsPsf";
// A star whose fitted flux is below kDropSnr standard errors, or that moves more than kDropMove camera px
// from where it was detected, is dropped (header).
constexpr double kDropSnr = 3.0;
constexpr double kDropMove = 1.5;
// A peak in the residual is a new star only above this fraction of the model there (and the noise).
constexpr double kResidualFraction = 0.1;
// A fitted star whose own box's χ² per pixel exceeds kRejectFactor times the stars' median (and kRejectFloor) is
// not a point source (a nebular knot, a galaxy, a blend): rejected and masked (header).
constexpr double kRejectFactor = 3.0;
constexpr double kRejectFloor = 2.0;
// ... and whose residual's power on that box is above this fraction of its own model's (a point source under a
// slightly wrong PSF leaves a few per cent; an extended source much more).
constexpr double kRejectRelative = 0.1;

Index FloorDiv(Index a, Index b) { return a >= 0 ? a / b : -((-a + b - 1) / b); }


// A shifted kernel binned onto camera pixels: rows/cols of camera pixels starting at (top, left), and its
// derivatives with respect to the star's HR position.
struct Patch {
  Index top = 0, left = 0;
  Image g, gy, gx;
};

// Renders h shifted to an HR position and integrated over camera pixels (D_r), by Fourier interpolation of the
// K × K kernel (the same band-limited shift the global model applies).
class KernelRenderer {
 public:
  KernelRenderer(const Image& h, int r) : k_(h.rows()), r_(r), spectrum_(FftR2C(h)) {}
  // From the half spectrum of a K x K kernel (a mix of the field nodes' spectra).
  KernelRenderer(ComplexImage spectrum, Index k, int r) : k_(k), r_(r), spectrum_(std::move(spectrum)) {}

  // The star at HR position (py, px) of frame coordinates: patch of f=1.
  void Render(double py, double px, bool derivatives, Patch* out) const {
    const Index iy = Index(std::floor(py + 0.5)), ix = Index(std::floor(px + 0.5));
    const double fy = py - double(iy), fx = px - double(ix);
    const Index half_cols = spectrum_.cols();
    ComplexImage s(k_, half_cols), sy, sx;
    if (derivatives) {
      sy.resize(k_, half_cols);
      sx.resize(k_, half_cols);
    }
    // The phase exp(−2πi (f_y φ_y + f_x φ_x)/K) factors into a row and a column term.
    std::vector<Complex> ey(static_cast<std::size_t>(k_)), ex(static_cast<std::size_t>(half_cols));
    for (Index v = 0; v < k_; ++v) ey[std::size_t(v)] = std::polar(1.0, -2.0 * kPi * double(SignedFrequency(v, k_)) * fy / double(k_));
    for (Index u = 0; u < half_cols; ++u) ex[std::size_t(u)] = std::polar(1.0, -2.0 * kPi * double(u) * fx / double(k_));
    for (Index v = 0; v < k_; ++v) {
      const Index sv = SignedFrequency(v, k_);
      for (Index u = 0; u < half_cols; ++u) {
        const Complex c = spectrum_(v, u) * (ey[std::size_t(v)] * ex[std::size_t(u)]);
        s(v, u) = c;
        if (derivatives) {
          // d/dpy of exp(-2πi f·p/K) = -2πi f/K; 0 at the Nyquist bins (a real kernel cannot carry it).
          const double wy = (2 * sv == k_ || 2 * sv == -k_) ? 0.0 : -2.0 * kPi * double(sv) / double(k_);
          const double wx = (2 * u == k_) ? 0.0 : -2.0 * kPi * double(u) / double(k_);
          sy(v, u) = c * Complex(0, wy);
          sx(v, u) = c * Complex(0, wx);
        }
      }
    }
    const Index c0 = k_ / 2;
    out->top = FloorDiv(iy - c0, r_);
    out->left = FloorDiv(ix - c0, r_);
    const Index rows = FloorDiv(iy + k_ - 1 - c0, r_) - out->top + 1;
    const Index cols = FloorDiv(ix + k_ - 1 - c0, r_) - out->left + 1;
    auto bin = [&](const ComplexImage& spec, Image* dst) {
      const Image hr = FftC2R(spec, k_);
      *dst = Image::Zero(rows, cols);
      for (Index v = 0; v < k_; ++v) {
        const Index yy = FloorDiv(iy + v - c0, r_) - out->top;
        for (Index u = 0; u < k_; ++u) (*dst)(yy, FloorDiv(ix + u - c0, r_) - out->left) += hr(v, u);
      }
    };
    bin(s, &out->g);
    if (derivatives) {
      bin(sy, &out->gy);
      bin(sx, &out->gx);
    }
  }

 private:
  Index k_;
  int r_;
  ComplexImage spectrum_;
};

// Adds alpha · patch.g to a camera frame (non-periodic: outside the frame the light is lost).
void AddPatch(const Patch& p, double alpha, Image* frame) {
  for (Index y = 0; y < p.g.rows(); ++y) {
    const Index fy = p.top + y;
    if (fy < 0 || fy >= frame->rows()) continue;
    for (Index x = 0; x < p.g.cols(); ++x) {
      const Index fx = p.left + x;
      if (fx >= 0 && fx < frame->cols()) (*frame)(fy, fx) += alpha * p.g(y, x);
    }
  }
}

// (Named apart from shift_and_add.cpp's Median(std::vector<double>&): unity batches can put both files in one unit.)
double StarsMedian(std::vector<double> v);

// The background's structure (header): boxes of `mesh` camera px, each the median of its valid pixels after
// three rounds of 3σ clipping (σ = 1.4826 MAD: the stars in a box are clipped), bilinear between box centres.
// No median filter over the boxes, as SExtractor applies: on a few boxes it flattens the structure it should
// follow (a nebula of 8 px on boxes of 8 px lost its peak). Boxes with fewer than half their pixels valid take the
// frame's median.
Image MeshBackground(const Image& y, const Image& valid, int mesh) {
  const Index rows = y.rows(), cols = y.cols();
  const Index by = std::max<Index>(1, (rows + mesh / 2) / mesh), bx = std::max<Index>(1, (cols + mesh / 2) / mesh);
  std::vector<double> all;
  for (Index p = 0; p < y.size(); ++p)
    if (valid(p) > 0) all.push_back(y(p));
  const double global = all.empty() ? 0.0 : StarsMedian(all);
  Image box(by, bx);
  for (Index a = 0; a < by; ++a)
    for (Index b = 0; b < bx; ++b) {
      const Index y0 = a * rows / by, y1 = (a + 1) * rows / by, x0 = b * cols / bx, x1 = (b + 1) * cols / bx;
      std::vector<double> v;
      for (Index yy = y0; yy < y1; ++yy)
        for (Index xx = x0; xx < x1; ++xx)
          if (valid(yy, xx) > 0) v.push_back(y(yy, xx));
      if (2 * v.size() < std::size_t((y1 - y0) * (x1 - x0))) {
        box(a, b) = global;
        continue;
      }
      double med = StarsMedian(v);
      for (int it = 0; it < 3 && v.size() > 4; ++it) {
        std::vector<double> dev;
        for (double q : v) dev.push_back(std::abs(q - med));
        const double sig = 1.4826 * StarsMedian(dev);
        if (!(sig > 0)) break;
        std::vector<double> kept;
        for (double q : v)
          if (std::abs(q - med) <= 3.0 * sig) kept.push_back(q);
        if (kept.size() == v.size() || kept.size() < 4) break;
        v.swap(kept);
        med = StarsMedian(v);
      }
      box(a, b) = med;
    }
  const Image& filtered = box;
  // Bilinear between box centres (clamped beyond the outer ones).
  auto axis = [](Index p, Index n_pix, Index n_box, Index* lo, Index* hi, double* t) {
    const double c = (double(p) + 0.5) * double(n_box) / double(n_pix) - 0.5;  // in box units, centres at integers
    const double cc = std::clamp(c, 0.0, double(n_box - 1));
    *lo = Index(std::floor(cc));
    *hi = std::min(*lo + 1, n_box - 1);
    *t = cc - double(*lo);
  };
  Image out(rows, cols);
  for (Index yy = 0; yy < rows; ++yy) {
    Index a0, a1;
    double ty;
    axis(yy, rows, by, &a0, &a1, &ty);
    for (Index xx = 0; xx < cols; ++xx) {
      Index b0, b1;
      double tx;
      axis(xx, cols, bx, &b0, &b1, &tx);
      out(yy, xx) = (1 - ty) * ((1 - tx) * filtered(a0, b0) + tx * filtered(a0, b1)) +
                    ty * ((1 - tx) * filtered(a1, b0) + tx * filtered(a1, b1));
    }
  }
  return out;
}

double StarsMedian(std::vector<double> v) {
  if (v.empty()) return 0.0;
  const std::size_t h = v.size() / 2;
  std::nth_element(v.begin(), v.begin() + h, v.end());
  return v[h];
}

struct Candidate {
  double y = 0, x = 0;  // camera px (sub-pixel, 3 × 3 centroid)
  double peak = 0;
  bool touches_invalid = false;
};

// Local maxima of the valid pixels of `img` above `threshold` (a pixel's own threshold where `threshold_map`
// is given), not on the outermost ring. `isolation` > 1: the pixel must also be the largest valid one within
// ±isolation px (round 0, before the PSF is known: an Airy ring or speckle of a bright star is then never taken
// for a star; a faint star next to a bright one is found later in the residual).
std::vector<Candidate> Detect(const Image& img, const Image& valid, double threshold, Index isolation = 1,
                              const Image* threshold_map = nullptr) {
  std::vector<Candidate> out;
  for (Index y = 1; y + 1 < img.rows(); ++y)
    for (Index x = 1; x + 1 < img.cols(); ++x) {
      if (valid(y, x) == 0) continue;
      const double v = img(y, x);
      if (!(v > (threshold_map ? (*threshold_map)(y, x) : threshold))) continue;
      bool is_max = true, invalid = false;
      for (Index dy = -isolation; dy <= isolation && is_max && isolation > 1; ++dy)
        for (Index dx = -isolation; dx <= isolation; ++dx) {
          const Index yy = y + dy, xx = x + dx;
          if (yy < 0 || xx < 0 || yy >= img.rows() || xx >= img.cols() || valid(yy, xx) == 0) continue;
          if (img(yy, xx) > v) {
            is_max = false;
            break;
          }
        }
      for (Index dy = -1; dy <= 1 && is_max; ++dy)
        for (Index dx = -1; dx <= 1; ++dx) {
          if (dy == 0 && dx == 0) continue;
          if (valid(y + dy, x + dx) == 0) {
            invalid = true;
            continue;
          }
          const double w = img(y + dy, x + dx);
          // Ties go to the first pixel in raster order, so a flat top gives one detection.
          if (w > v || (w == v && (dy < 0 || (dy == 0 && dx < 0)))) {
            is_max = false;
            break;
          }
        }
      if (!is_max) continue;
      Candidate c;
      c.peak = v;
      c.touches_invalid = invalid;
      double s = 0, sy = 0, sx = 0;
      for (Index dy = -1; dy <= 1; ++dy)
        for (Index dx = -1; dx <= 1; ++dx) {
          if (valid(y + dy, x + dx) == 0) continue;
          const double w = std::max(0.0, img(y + dy, x + dx));
          s += w;
          sy += w * double(dy);
          sx += w * double(dx);
        }
      c.y = double(y) + (s > 0 ? sy / s : 0.0);
      c.x = double(x) + (s > 0 ? sx / s : 0.0);
      out.push_back(c);
    }
  return out;
}

// The first moment of a centred kernel over the pixels within `radius` of its centre (K/2, K/2), about it.
FrameOffset CoreCentroid(const Image& k, double radius) {
  double s = 0, my = 0, mx = 0;
  for (Index y = 0; y < k.rows(); ++y)
    for (Index x = 0; x < k.cols(); ++x) {
      const double dy = double(y - k.rows() / 2), dx = double(x - k.cols() / 2);
      if (dy * dy + dx * dx > radius * radius) continue;
      s += k(y, x);
      my += k(y, x) * dy;
      mx += k(y, x) * dx;
    }
  return s > 0 ? FrameOffset{my / s, mx / s} : FrameOffset{};
}

// Camera coordinate c <-> HR coordinate (c + ½) r − ½ (image.hpp).
double CameraToHr(double c, int r) { return (c + 0.5) * r - 0.5; }
double HrToCamera(double h, int r) { return (h + 0.5) / r - 0.5; }

// AᵀWA + Λ (Λ diagonal) as the LinearOperator conjugate gradients takes.
// With a field grid of G nodes, also the nodes' prior c ⊙ Σ_h Q_gh h_h (c one K² weight map for every node, Q a
// symmetric G x G matrix over the nodes, the same at every pixel: NodePriorMatrix): the gradient of a Gaussian
// prior on how the nodes differ, which ties them together where the stars do not tell them apart (the wings) and
// leaves the core, where the data constrain each node, free. Without a polynomial (grid_degree 0) Q = I − 11ᵀ/G:
// each node's difference from the nodes' mean h̄, computed as c ⊙ (h_g − h̄).
class StarFieldNormal final : public LinearOperator {
 public:
  StarFieldNormal(StarFieldModel* model, const ImageStack* w, Vector ridge, int nodes = 1, Vector coupling = {},
                  Eigen::MatrixXd node_prior = {})
      : LinearOperator(ridge.size(), ridge.size(), "StarFieldNormal"),
        model_(model),
        w_(w),
        ridge_(std::move(ridge)),
        nodes_(nodes),
        coupling_(std::move(coupling)),
        node_prior_(std::move(node_prior)) {}

 private:
  void ApplyImpl(ConstRef x, Ref y) const override {
    model_->Normal(x, *w_, y);
    y += ridge_.cwiseProduct(x);
    if (nodes_ <= 1) return;
    const Index k2 = coupling_.size();
    if (node_prior_.size() > 0) {
      const Eigen::Map<const Eigen::MatrixXd> xs(x.data(), k2, nodes_);
      Eigen::Map<Eigen::MatrixXd> ys(y.data(), k2, nodes_);
      ys += coupling_.asDiagonal() * (xs * node_prior_);
      return;
    }
    Vector mean = Vector::Zero(k2);
    for (int g = 0; g < nodes_; ++g) mean += x.segment(Index(g) * k2, k2);
    mean /= double(nodes_);
    for (int g = 0; g < nodes_; ++g)
      y.segment(Index(g) * k2, k2) += coupling_.cwiseProduct(x.segment(Index(g) * k2, k2) - mean);
  }
  void ApplyAdjointImpl(ConstRef y, Ref x) const override { ApplyImpl(y, x); }  // symmetric
  StarFieldModel* model_;
  const ImageStack* w_;
  Vector ridge_;
  int nodes_;
  Vector coupling_;
  Eigen::MatrixXd node_prior_;
};

// The nodes' prior matrix Q (StarFieldNormal) for grid_degree d >= 1, in units of 1/τ_variation²: with P_d the
// orthogonal projection of a node vector onto the polynomials of degree <= d in the nodes' positions (monomials
// u^a v^b, a + b <= d, a below the grid's nodes in x and b in y; u, v in [-1, 1] over the frame) and P_0 onto the
// constants, Q = (P_d − P_0) + (I − P_d) · (variation / roughness)²: the smooth part of the field's variation
// departs from the mean with scale grid_variation, the nodes depart from that surface with grid_roughness.
Eigen::MatrixXd NodePriorMatrix(const PsfFieldGrid& grid, int degree, double variation, double roughness) {
  const int g = grid.nodes();
  std::vector<std::array<int, 2>> powers;
  for (int total = 0; total <= degree; ++total)
    for (int b = 0; b <= total; ++b)
      if (total - b < grid.nx() && b < grid.ny()) powers.push_back({total - b, b});
  Eigen::MatrixXd v(g, Index(powers.size()));
  for (int n = 0; n < g; ++n) {
    const int iy = n / grid.nx(), ix = n % grid.nx();
    const double u = grid.nx() > 1 ? 2.0 * ix / (grid.nx() - 1) - 1.0 : 0.0;
    const double w = grid.ny() > 1 ? 2.0 * iy / (grid.ny() - 1) - 1.0 : 0.0;
    for (std::size_t p = 0; p < powers.size(); ++p) v(n, Index(p)) = std::pow(u, powers[p][0]) * std::pow(w, powers[p][1]);
  }
  const Eigen::MatrixXd vt = v.transpose();
  const Eigen::MatrixXd pd = v * (vt * v).ldlt().solve(vt);
  const Eigen::MatrixXd p0 = Eigen::MatrixXd::Constant(g, g, 1.0 / g);
  const Eigen::MatrixXd id = Eigen::MatrixXd::Identity(g, g);
  const double ratio = variation / roughness;
  return (pd - p0) + (id - pd) * (ratio * ratio);
}

// The diagonal of AᵀWA over each node's K² pixels, with the stars at their nearest HR pixel (the model
// interpolates them; the preconditioner needs the shape, not the value): d_g(v, u) = Σ_i Σ_j w_g(p_j)² f_j²
// W_i(the camera pixel of p_j + o_i + (v, u) − K/2), normalised to 1 at the centre. The stars' own photon noise
// in W makes it 10-20x smaller in the core than in the wings for bright stars.
Eigen::MatrixXd DataDiagonalShape(const std::vector<Star>& stars, const PsfFieldGrid& grid, int nodes,
                                  const std::vector<FrameOffset>& offsets, const ImageStack& w, Shape hr, int r, Index k) {
  Eigen::MatrixXd out = Eigen::MatrixXd::Zero(k * k, nodes);
  Vector one(k * k);
  for (const Star& st : stars) {
    one.setZero();
    for (std::size_t i = 0; i < offsets.size(); ++i) {
      const Image& wi = w[i];
      const Index py = Index(std::lround(st.y + offsets[i].dy)) - k / 2, px = Index(std::lround(st.x + offsets[i].dx)) - k / 2;
      for (Index v = 0; v < k; ++v) {
        const Index yy = py + v;
        if (yy < 0 || yy >= hr.rows) continue;
        const Index cy = yy / r;
        for (Index u = std::max<Index>(0, -px); u < std::min<Index>(k, hr.cols - px); ++u) one(v * k + u) += wi(cy, (px + u) / r);
      }
    }
    one *= st.f * st.f;
    if (nodes <= 1) {
      out.col(0) += one;
      continue;
    }
    for (const PsfFieldGrid::Weight& wt : grid.Weights(st.y, st.x)) out.col(wt.node) += wt.weight * wt.weight * one;
  }
  const Index centre = (k / 2) * k + k / 2;
  for (int g = 0; g < nodes; ++g) out.col(g) /= std::max(out(centre, g), 1e-300);
  return out;
}

// The preconditioner of the h solve, node by node: for many stars at random sub-pixel phases AᵀWA acts on a
// node's PSF nearly as a convolution with the pixel box's autocorrelation, D_g β(f) in Fourier (β = |B(f)|² / r⁴,
// mean 1; D_g the centre pixel's diagonal), so with the centre's ridge R_g and prior weight c₀ Q_gg its inverse is
// one K x K FFT pair per node. The operator's diagonal is far from constant over the window, though: the stars' own
// photon noise makes the data's 10-20x smaller in the core than in the wings (DataDiagonalShape), and the ridge and
// the prior grow into the wings as s(p) and s(p)², s = 1 + (ρ / 2r)². So the circulant sits between two diagonal
// scalings, P = Σ^-½ F⁻¹ [1 / (D_g β + R_g + c₀ Q_gg)] F Σ^-½ with Σ(p) the diagonal at p over the centre's: the
// standard preconditioner for a convolution with a slowly varying coefficient. The nodes' coupling, through the
// stars they share and through the prior, is left out: a preconditioner that keeps it (a G x G generalised
// eigenproblem over the nodes) took more iterations than this one (bench/results/wide_field.md, "Stop 61").
// The backgrounds get 1 / Σ w_i.
class PsfPreconditioner final : public LinearOperator {
 public:
  // Per node g: data D_g, ridge R_g and prior c₀ Q_gg at the centre; shape: s(p); data_shape: the data's diagonal
  // over its centre value (K² x G).
  PsfPreconditioner(Index k, int r, const Vector& data, const Vector& ridge, const Vector& prior, const Vector& shape,
                    const Eigen::MatrixXd& data_shape, std::vector<double> background_diag)
      : LinearOperator(data.size() * k * k + Index(background_diag.size()),
                       data.size() * k * k + Index(background_diag.size()), "PsfPreconditioner"),
        k_(k),
        background_diag_(std::move(background_diag)) {
    auto box2 = [&](Index f) {
      const double a = kPi * double(f) / double(k);
      if (f == 0) return double(r) * r;
      const double sn = std::sin(a * r) / std::sin(a);
      return sn * sn;
    };
    scale_.resize(k * k, data.size());
    for (Index g = 0; g < data.size(); ++g) {
      const double centre = data(g) + ridge(g) + prior(g);
      for (Index p = 0; p < k * k; ++p) {
        const double dp = data(g) * data_shape(p, g) + ridge(g) * shape(p) + prior(g) * shape(p) * shape(p);
        scale_(p, g) = 1.0 / std::sqrt(std::max(dp / centre, 1e-300));
      }
      Image inverse(k, k / 2 + 1);
      for (Index fy = 0; fy < k; ++fy)
        for (Index fx = 0; fx <= k / 2; ++fx)
          inverse(fy, fx) = 1.0 / (data(g) * box2(fy) * box2(fx) / double(r * r) / double(r * r) + ridge(g) + prior(g));
      inverse_.push_back(std::move(inverse));
    }
  }

 private:
  void ApplyImpl(ConstRef x, Ref y) const override {
    const Index k2 = k_ * k_, gk2 = Index(inverse_.size()) * k2;
    for (std::size_t g = 0; g < inverse_.size(); ++g) {
      const auto sg = scale_.col(Index(g));
      ComplexImage s = FftR2C(ToImage(x.segment(Index(g) * k2, k2).cwiseProduct(sg), {k_, k_}));
      s *= inverse_[g].cast<Complex>();
      y.segment(Index(g) * k2, k2) = AsVector(FftC2R(s, k_)).cwiseProduct(sg);
    }
    for (std::size_t i = 0; i < background_diag_.size(); ++i)
      y(gk2 + Index(i)) = x(gk2 + Index(i)) / background_diag_[i];
  }
  void ApplyAdjointImpl(ConstRef y, Ref x) const override { ApplyImpl(y, x); }  // symmetric
  Index k_;
  Eigen::MatrixXd scale_;  // Σ(p)^-½, K² x G
  std::vector<Image> inverse_;
  std::vector<double> background_diag_;
};

}  // namespace

bool StarsPsfOptions::IsValid(std::string* why) const {
  auto fail = [why](const std::string& m) {
    if (why) *why = m;
    return false;
  };
  if (psf_size_hr_px < 0 || psf_size_hr_px % 2)
    return fail("psf_size_hr_px = " + std::to_string(psf_size_hr_px) + ", allowed 0 (auto) or an even size >= 4 r");
  if (!(detection_sigma > 0) || !std::isfinite(detection_sigma))
    return fail("detection_sigma = " + ToString(detection_sigma) + ", allowed > 0");
  if (min_stars < 1) return fail("min_stars = " + std::to_string(min_stars) + ", allowed >= 1");
  if (rounds < 1 || rounds > 50) return fail("rounds = " + std::to_string(rounds) + ", allowed [1, 50]");
  if (!(regularisation >= 0) || !std::isfinite(regularisation))
    return fail("regularisation = " + ToString(regularisation) + ", allowed >= 0");
  if (fit_radius_px < 1 || fit_radius_px > 16)
    return fail("fit_radius_px = " + std::to_string(fit_radius_px) + ", allowed [1, 16]");
  if (cg_iterations < 1) return fail("cg_iterations = " + std::to_string(cg_iterations) + ", allowed >= 1");
  if (!(cg_tolerance > 0 && cg_tolerance < 1))
    return fail("cg_tolerance = " + ToString(cg_tolerance) + ", allowed (0, 1)");
  if (max_stars < 1) return fail("max_stars = " + std::to_string(max_stars) + ", allowed >= 1");
  if (!(grid_variation > 0) || !std::isfinite(grid_variation))
    return fail("grid_variation = " + ToString(grid_variation) + ", allowed > 0");
  if (grid_degree < 0 || grid_degree > 4)
    return fail("grid_degree = " + std::to_string(grid_degree) + ", allowed [0, 4] (0: each node tied to the nodes' mean)");
  if (!(grid_roughness > 0) || !std::isfinite(grid_roughness))
    return fail("grid_roughness = " + ToString(grid_roughness) + ", allowed > 0");
  if (grid_ny < 1 || grid_ny > 16 || grid_nx < 1 || grid_nx > 16)
    return fail("grid " + std::to_string(grid_ny) + " x " + std::to_string(grid_nx) + ", allowed [1, 16] nodes per axis");
  if (background_mesh_px != 0 && (background_mesh_px < 4 || background_mesh_px > 4096))
    return fail("background_mesh_px = " + std::to_string(background_mesh_px) + ", allowed 0 (none) or [4, 4096]");
  if (!(max_chi2_near_stars >= 0) || !std::isfinite(max_chi2_near_stars))
    return fail("max_chi2_near_stars = " + ToString(max_chi2_near_stars) + ", allowed >= 0 (0: no check)");
  return true;
}

std::string StarsPsfResult::BriefReport() const {
  char buf[256];
  std::snprintf(buf, sizeof buf,
                "stars PSF: %d stars (%d saturated, %d dropped, %d not point-like), K = %lld HR px, chi2/dof %.3f (%.3f "
                "per pixel near the stars), %d rounds",
                used, saturated, dropped, rejected, static_cast<long long>(psf.rows()), chi2_per_dof, chi2_near_stars, rounds);
  std::string out = buf;
  if (!cg_converged) {
    std::snprintf(buf, sizeof buf, "; the final h solve NOT converged (%d CG iterations: raise cg_iterations)", cg_iterations_last);
    out += buf;
  }
  if (grid.nodes() > 1) {
    double least = node_stars.empty() ? 0.0 : *std::min_element(node_stars.begin(), node_stars.end());
    std::snprintf(buf, sizeof buf, "; varying over a %d x %d grid (fewest stars at a node %.1f)", grid.ny(), grid.nx(), least);
    out += buf;
    if (grid_degree > 0) {
      std::snprintf(buf, sizeof buf, ", the nodes on a degree-%d surface (roughness %g)", grid_degree, grid_roughness);
      out += buf;
    }
  }
  return out;
}

Image FourierShiftKernel(const Image& k, double dy, double dx) {
  CheckArgument(k.size() > 0, "FourierShiftKernel", "kernel", "empty", "a non-empty kernel");
  CheckArgument(std::isfinite(dy) && std::isfinite(dx), "FourierShiftKernel", "shift", ToString(dy) + ", " + ToString(dx),
                "finite");
  ComplexImage s = FftR2C(k);
  for (Index v = 0; v < s.rows(); ++v)
    for (Index u = 0; u < s.cols(); ++u) {
      const double a = -2.0 * kPi * (double(SignedFrequency(v, k.rows())) * dy / double(k.rows()) +
                                     double(u) * dx / double(k.cols()));
      s(v, u) *= Complex(std::cos(a), std::sin(a));
    }
  return FftC2R(s, k.cols());
}

StarsPsfResult EstimateStarsPsf(const ImageStack& y_in, const ImageStack& valid_in, const ImageStack& weights_in,
                                const std::vector<FrameOffset>& offsets, int r, const StarsPsfOptions& options) {
  const auto t0 = std::chrono::steady_clock::now();
  std::string why;
  if (!options.IsValid(&why)) throw InvalidArgument(kStarsPsfFn, "options", why, "valid StarsPsfOptions");
  const Index n = Index(y_in.size());
  CheckArgument(n > 0, kStarsPsfFn, "frames", 0, "at least one frame");
  CheckArgument(r >= 1 && r <= 16, kStarsPsfFn, "r", r, "1..16");
  const Shape lr = ShapeOf(y_in[0]);
  CheckArgument(Index(valid_in.size()) == n, kStarsPsfFn, "valid count", valid_in.size(), "one per frame (" + std::to_string(n) + ")");
  CheckArgument(weights_in.empty() || Index(weights_in.size()) == n, kStarsPsfFn, "weights count", weights_in.size(),
                "0 (from the background and the model) or one per frame (" + std::to_string(n) + ")");
  CheckArgument(Index(offsets.size()) == n, kStarsPsfFn, "offsets count", offsets.size(), "one per frame (" + std::to_string(n) + ")");
  for (Index i = 0; i < n; ++i) {
    const std::string tag = "[" + std::to_string(i) + "]";
    CheckArgument(ShapeOf(y_in[i]) == lr, kStarsPsfFn, "frames" + tag + " shape", ToString(ShapeOf(y_in[i])), "frame 0's " + ToString(lr));
    CheckArgument(ShapeOf(valid_in[i]) == lr, kStarsPsfFn, "valid" + tag + " shape", ToString(ShapeOf(valid_in[i])), ToString(lr));
    CheckArgument(std::isfinite(offsets[i].dy) && std::isfinite(offsets[i].dx), kStarsPsfFn, "offsets" + tag,
                  ToString(offsets[i].dy) + ", " + ToString(offsets[i].dx), "finite HR px");
    if (!weights_in.empty()) {
      CheckArgument(ShapeOf(weights_in[i]) == lr, kStarsPsfFn, "weights" + tag + " shape", ToString(ShapeOf(weights_in[i])), ToString(lr));
      CheckArgument(AllFinite(weights_in[i]) && (weights_in[i] >= 0).all(), kStarsPsfFn, "weights" + tag, "negative or non-finite",
                    "finite inverse variances >= 0");
    }
  }
  const Shape hr{lr.rows * r, lr.cols * r};
  Index k = options.psf_size_hr_px > 0 ? options.psf_size_hr_px : std::min<Index>({32 * Index(r), hr.rows, hr.cols});
  k -= k % 2;
  const Index rfit = options.fit_radius_px;
  const Index k_min = std::max<Index>(4 * r, 2 * r * (rfit + 1));
  CheckArgument(k >= k_min && k <= std::min(hr.rows, hr.cols), kStarsPsfFn, "psf_size_hr_px", k,
                "even, >= max(4 r, 2 r (fit_radius_px + 1)) = " + std::to_string(k_min) + " and <= the HR frame " +
                    ToString(hr));

  StarsPsfResult res;
  res.offsets = offsets;
  res.min_required = std::max<int>(options.min_stars, int((r * r + n - 1) / n));
  // The field grid (one node: a single PSF for the field). The first `rounds` rounds fit one PSF for the whole
  // field, as without a grid, and the grid takes over for `rounds` more (activate_field below), every node
  // starting from that PSF. Solved from early rounds' stars instead, the nodes' scales and shifts absorb the
  // fluxes' and positions' errors (a node's scale and its stars' fluxes are nearly degenerate, as are its shift
  // and their positions) and the alternation swings: measured on a 2 x 2 grid with the same PSF at every node,
  // node scales 0.6-1.6 from round 1's stars and χ² near the stars 2.2 after 4 rounds; 0.94 from converged ones.
  PsfFieldGrid field_grid;
  if (options.grid_ny * options.grid_nx > 1) field_grid = PsfFieldGrid(hr, options.grid_ny, options.grid_nx, kStarsPsfFn);
  const int field_nodes = std::max(1, field_grid.nodes());
  // The grid's unknowns (G K²) must leave the data room to constrain them: at most a quarter of the frames'
  // pixels (a node's stars cover a fraction of the field, and the stars' own parameters come on top).
  if (field_nodes > 1) {
    const double unknowns = double(field_nodes) * double(k) * double(k), pixels = double(n) * double(lr.rows * lr.cols);
    CheckArgument(4.0 * unknowns <= pixels, kStarsPsfFn, "grid",
                  std::to_string(options.grid_ny) + " x " + std::to_string(options.grid_nx) + " nodes of K = " +
                      std::to_string(k) + " HR px: " + ToString(unknowns) + " unknowns for " + ToString(pixels) +
                      " frame pixels",
                  "nodes x K^2 <= a quarter of the frames' pixels: a coarser grid or a smaller psf_size_hr_px");
  }
  PsfFieldGrid grid;  // the model's grid now: empty (one PSF) until the field is activated
  int nodes = 1;
  Index gk2 = k * k;

  // ---- Frames: valid pixels, background structure, background, noise. ---------------------------------------------
  ImageStack valid(n), mask(n), y(n);
  res.background_mesh_px = options.background_mesh_px;
  for (Index i = 0; i < n; ++i) {
    valid[i] = ((valid_in[i] != 0) && y_in[i].isFinite()).cast<double>();
    if (!weights_in.empty()) valid[i] *= (weights_in[i] > 0).cast<double>();
    y[i] = (valid[i] > 0).select(y_in[i], 0.0);
    if (options.background_mesh_px > 0) {
      // The structure only: its median level stays, and the fitted constant b_i carries it.
      const Image map = MeshBackground(y[i], valid[i], options.background_mesh_px);
      std::vector<double> v(map.data(), map.data() + map.size());
      y[i] -= map - StarsMedian(v);
    }
  }
  std::vector<double> sigma(n), bg(n), var_floor(n), sigma_floor(n);
  for (Index i = 0; i < n; ++i) {
    const Image yi = (valid[i] > 0).select(y[i], 0.0);
    std::vector<double> v;
    for (Index p = 0; p < yi.size(); ++p)
      if (valid[i](p) > 0) v.push_back(yi(p));
    CheckArgument(v.size() >= 16, kStarsPsfFn, "valid[" + std::to_string(i) + "]", std::to_string(v.size()) + " valid pixels",
                  "at least 16 valid pixels per frame");
    bg[i] = StarsMedian(v);
    sigma[i] = EstimateBackgroundSigma(yi, valid[i]);
    double peak = 0;
    for (double a : v) peak = std::max(peak, a - bg[i]);
    // Noise-free data have σ = 0: a floor keeps thresholds and weights finite without mattering for real data.
    sigma_floor[i] = 1e-4 * peak + 1e-300;
    sigma[i] = std::max(sigma[i], sigma_floor[i]);
    var_floor[i] = sigma[i] * sigma[i];
    mask[i] = Image::Ones(lr.rows, lr.cols);
  }

  // ---- Detection on frame 0. --------------------------------------------------------------------------------
  auto det_image = [&](Index i) {
    Image d = y[i] - bg[i];
    return Image((valid[i] > 0).select(d, 0.0));
  };
  const double threshold0 = options.detection_sigma * sigma[0];
  std::vector<Candidate> cands = Detect(det_image(0), valid[0], threshold0, rfit);
  std::vector<Star> stars;
  std::vector<Candidate> saturated;
  for (const Candidate& c : cands) {
    if (c.touches_invalid) {
      bool merged = false;
      for (const Candidate& s : saturated) merged = merged || std::hypot(s.y - c.y, s.x - c.x) < 3.0;
      if (!merged) saturated.push_back(c);
      continue;
    }
    Star s;
    s.y = s.y_det = CameraToHr(c.y, r) - offsets[0].dy;
    s.x = s.x_det = CameraToHr(c.x, r) - offsets[0].dx;
    double f = 0;
    for (Index dy = -rfit; dy <= rfit; ++dy)
      for (Index dx = -rfit; dx <= rfit; ++dx) {
        const Index yy = Index(std::lround(c.y)) + dy, xx = Index(std::lround(c.x)) + dx;
        if (yy >= 0 && yy < lr.rows && xx >= 0 && xx < lr.cols && valid[0](yy, xx) > 0) f += y[0](yy, xx) - bg[0];
      }
    s.f = std::max(f, c.peak);
    stars.push_back(s);
  }
  if (!options.known_stars.empty()) {
    stars.clear();
    for (const PointSource& p : options.known_stars) {
      CheckArgument(std::isfinite(p.y) && std::isfinite(p.x) && p.flux > 0 && std::isfinite(p.flux), kStarsPsfFn,
                    "known_stars", ToString(p.y) + ", " + ToString(p.x) + ", flux " + ToString(p.flux),
                    "finite positions and positive fluxes");
      Star s;
      s.y = s.y_det = p.y;
      s.x = s.x_det = p.x;
      s.f = p.flux;
      stars.push_back(s);
    }
  }
  res.saturated = int(saturated.size());
  res.detected = int(stars.size());
  // Saturated (or bad-pixel-touching) detections: their unmodelled light must not enter h.
  const Index rmask = 2 * rfit + 2;
  for (const Candidate& c : saturated)
    for (Index i = 0; i < n; ++i) {
      const double cy = HrToCamera(CameraToHr(c.y, r) - offsets[0].dy + offsets[i].dy, r);
      const double cx = HrToCamera(CameraToHr(c.x, r) - offsets[0].dx + offsets[i].dx, r);
      for (Index yy = std::max<Index>(0, Index(cy) - rmask); yy <= std::min<Index>(lr.rows - 1, Index(cy) + rmask); ++yy)
        for (Index xx = std::max<Index>(0, Index(cx) - rmask); xx <= std::min<Index>(lr.cols - 1, Index(cx) + rmask); ++xx)
          mask[i](yy, xx) = 0;
    }
  const std::string threshold_text = ToString(options.detection_sigma) + " sigma = " + ToString(threshold0) +
                                     " e- above the background " + ToString(bg[0]) + " e- of frame 0";
  if (stars.empty() && saturated.empty())
    throw InvalidArgument(kStarsPsfFn, "frames", "no point source above " + threshold_text,
                          "frames with at least " + std::to_string(res.min_required) +
                              " unsaturated point sources above the threshold (detection_sigma)");
  if (stars.empty())
    throw InvalidArgument(kStarsPsfFn, "frames",
                          "only saturated stars (" + std::to_string(saturated.size()) +
                              " detections touch invalid or saturated pixels, none above " + threshold_text + " is unsaturated)",
                          "at least " + std::to_string(res.min_required) +
                              " unsaturated point sources: a saturated core cannot constrain the PSF's core");
  auto too_few = [&](std::size_t count, const char* stage) {
    return InvalidArgument(
        kStarsPsfFn, "usable stars", std::to_string(count) + " " + stage + " (" + std::to_string(saturated.size()) +
                                 " saturated excluded; threshold " + threshold_text + ")",
        ">= " + std::to_string(res.min_required) + " = max(min_stars " + std::to_string(options.min_stars) +
            ", ceil(r^2/N) = " + std::to_string((r * r + n - 1) / n) +
            ": N frames sample N of the r^2 sub-pixel phases per star, and no single star may define the PSF)");
  };
  if (int(stars.size()) < res.min_required) throw too_few(stars.size(), "detected");
  // A field grid needs stars near every node: a node's count is Σ_j w_g(p_j), the stars' bilinear weights on it
  // (a star on the node counts 1, one half way to the next node ½), and each node needs what one PSF needs.
  auto check_nodes = [&](const char* stage) {
    if (field_nodes <= 1) return;
    std::vector<double> count(std::size_t(field_nodes), 0.0);
    for (const Star& st : stars)
      for (const PsfFieldGrid::Weight& w : field_grid.Weights(st.y, st.x)) count[std::size_t(w.node)] += w.weight;
    res.node_stars = count;
    for (int g = 0; g < field_nodes; ++g) {
      if (count[std::size_t(g)] >= double(res.min_required)) continue;
      const auto at = field_grid.Node(g);
      throw InvalidArgument(
          kStarsPsfFn, "grid",
          std::to_string(options.grid_ny) + " x " + std::to_string(options.grid_nx) + ": node " + std::to_string(g) +
              " at HR (" + ToString(at[0]) + ", " + ToString(at[1]) + ") has " + ToString(count[std::size_t(g)]) +
              " stars (their bilinear weights on it) " + stage + ", of " + std::to_string(stars.size()) +
              " usable stars in the field",
          ">= " + std::to_string(res.min_required) + " per node (so >= " + std::to_string(res.min_required * field_nodes) +
              " stars spread over the field): use a coarser grid (grid_ny, grid_nx; 1 x 1 is one PSF for the field)");
    }
  };
  auto by_flux = [](const Star& a, const Star& b) { return a.f > b.f; };
  std::sort(stars.begin(), stars.end(), by_flux);
  if (int(stars.size()) > options.max_stars) stars.resize(std::size_t(options.max_stars));

  // ---- The global model of h: frames = D_r Crop (S_i ⊛ ZeroPad h). ----------------------------------------------
  const Shape kk{k, k};
  const Shape pad{NextFastFftSize(hr.rows + k), NextFastFftSize(hr.cols + k)};
  ImageStack w(n);
  auto update_weights = [&](const ImageStack* model) {
    for (Index i = 0; i < n; ++i) {
      if (!weights_in.empty()) {
        w[i] = weights_in[i] * valid[i] * mask[i];
      } else {
        const Image m = model ? (*model)[i].max(0.0) : Image((y[i] - bg[i]).max(0.0));
        w[i] = valid[i] * mask[i] / (var_floor[i] + m);
      }
    }
  };
  update_weights(nullptr);

  Vector h = Vector::Zero(gk2);
  Vector u;  // [h_0 .. h_{G-1}; b] of the last solve (warm start)
  ImageStack model(n), resid(n);
  // Ridge: λ(ρ) = regularisation · d_c · (1 + (ρ / 2r)²), d_c the centre pixel's diagonal of AᵀWA and ρ the
  // distance from the centre in HR px: light in the core is shrunk by ~regularisation, the far wings (where
  // few photons and the unmodelled faint stars are) more, toward 0; the background is not regularised.
  Image ridge_shape(1, k * k);
  for (Index v = 0; v < k; ++v)
    for (Index q = 0; q < k; ++q) {
      const double rho2 = double((v - k / 2) * (v - k / 2) + (q - k / 2) * (q - k / 2)) / double(4 * r * r);
      ridge_shape(0, v * k + q) = 1.0 + rho2;
    }
  std::unique_ptr<StarFieldModel> field;  // the stars of the current round
  Vector coupling;  // with the grid: 1/τ² per pixel of a node's difference from the mean (header, grid_variation)
  Eigen::MatrixXd node_prior;  // grid_degree >= 1: the nodes' prior matrix (NodePriorMatrix); empty: the mean's
  // `final_solve`: false for the grid's intermediate solves, which stop at a relative residual of 1e-3: their stars
  // move again after them (measured on a 256² crop of the wide scene, 3 x 3: 40.7 s instead of 54.8, the nodes as
  // accurate: worst 3.5 % RMS of the peak, against 3.6).
  auto solve_h = [&](bool final_solve) {
    field = std::make_unique<StarFieldModel>(stars, grid, offsets, pad, hr, int(r), k);
    Vector rhs(gk2 + n);
    ImageStack wy(n);
    for (Index i = 0; i < n; ++i) wy[i] = (valid[i] > 0).select(y[i], 0.0) * w[i];
    field->Backward(wy, rhs);
    // Each node's ridge scales with its own centre diagonal (its stars' light), the backgrounds get none.
    Vector data(nodes), ridge(nodes), ridge_vector = Vector::Zero(gk2 + n);
    for (int g = 0; g < nodes; ++g) {
      Vector delta = Vector::Zero(gk2 + n), column(gk2 + n);
      const Index centre = Index(g) * k * k + (k / 2) * k + k / 2;
      delta(centre) = 1.0;
      field->Normal(delta, w, column);
      data(g) = column(centre);
      ridge(g) = options.regularisation * data(g);
      ridge_vector.segment(Index(g) * k * k, k * k) = ridge(g) * AsVector(ridge_shape);
    }
    // The nodes' coupling (StarFieldNormal, header: a Gaussian prior on each node's difference from the mean).
    const StarFieldNormal normal(field.get(), &w, ridge_vector, nodes, coupling, node_prior);
    Vector prior = Vector::Zero(nodes);  // c₀ Q_gg
    if (nodes > 1)
      for (int g = 0; g < nodes; ++g)
        prior(g) = coupling((k / 2) * k + k / 2) * (node_prior.size() > 0 ? node_prior(g, g) : 1.0 - 1.0 / nodes);
    if (u.size() != gk2 + n) {
      u = Vector::Zero(gk2 + n);
      for (Index i = 0; i < n; ++i) u(gk2 + i) = bg[i];
    }
    u.head(gk2) = h;
    ConjugateGradientOptions cg;
    cg.max_iterations = options.cg_iterations;
    cg.tolerance = options.cg_tolerance;
    if (nodes > 1 && !final_solve) cg.tolerance = std::max(options.cg_tolerance, 1e-3);
    std::vector<double> bdiag(n);
    for (Index i = 0; i < n; ++i) bdiag[i] = std::max(w[i].sum(), 1e-300);
    const PsfPreconditioner pre(k, r, data, ridge, prior, AsVector(ridge_shape),
                                DataDiagonalShape(stars, grid, nodes, offsets, w, hr, int(r), k), bdiag);
    const SolverSummary sum = PreconditionedConjugateGradient(normal, pre, rhs, &u, cg);
    res.cg_iterations_total += sum.iterations;
    res.cg_iterations_last = sum.iterations;
    res.cg_converged = sum.termination == Termination::kConverged;
    h = u.head(gk2);
    for (Index i = 0; i < n; ++i) bg[i] = u(gk2 + i);
  };
  // Unit sum and the core's first moment at the centre; the stars take the inverse scale and the opposite shift.
  // With a field grid, node by node: a star takes its nodes' scales and shifts weighted as it sees them (exact
  // for equal scales; the next round's fits absorb the rest).
  auto normalise_and_centre = [&]() {
    std::vector<double> scale(std::size_t(nodes), 1.0);
    std::vector<FrameOffset> shift(static_cast<std::size_t>(nodes));
    for (int g = 0; g < nodes; ++g) {
      Image img = ToImage(h.segment(Index(g) * k * k, k * k), kk);
      const double s = img.sum();
      if (!(s > 0) || !std::isfinite(s))
        throw InvalidArgument(kStarsPsfFn, nodes > 1 ? "fitted PSF sum at grid node " + std::to_string(g) : std::string("fitted PSF sum"),
                              ToString(s),
                              "> 0: the stars' pixels do not determine a PSF (too faint or too few stars for K = " +
                                  std::to_string(k) + (nodes > 1 ? " near this node: use a coarser grid)" : ")"));
      img /= s;
      scale[std::size_t(g)] = s;
      const FrameOffset c = CoreCentroid(img, 3.0 * r);
      if (std::hypot(c.dy, c.dx) < double(k) / 4) {
        img = FourierShiftKernel(img, -c.dy, -c.dx);
        shift[std::size_t(g)] = c;
      }
      h.segment(Index(g) * k * k, k * k) = AsVector(img);
    }
    for (Star& st : stars) {
      if (nodes <= 1) {
        st.f *= scale[0];
        st.y += shift[0].dy;
        st.x += shift[0].dx;
        continue;
      }
      double sc = 0, dy = 0, dx = 0;
      for (const PsfFieldGrid::Weight& w : grid.Weights(st.y, st.x)) {
        sc += w.weight * scale[std::size_t(w.node)];
        dy += w.weight * shift[std::size_t(w.node)].dy;
        dx += w.weight * shift[std::size_t(w.node)].dx;
      }
      st.f *= sc;
      st.y += dy;
      st.x += dx;
    }
  };
  // The renderer of a star at HR position (y, x): the PSF interpolated there (the single PSF without a grid).
  std::vector<ComplexImage> node_spectra;
  auto renderer_at = [&](double py, double px) {
    if (nodes <= 1) return KernelRenderer(node_spectra[0], k, r);
    ComplexImage mix = ComplexImage::Zero(k, k / 2 + 1);
    for (const PsfFieldGrid::Weight& w : grid.Weights(py, px)) mix += w.weight * node_spectra[std::size_t(w.node)];
    return KernelRenderer(std::move(mix), k, r);
  };
  auto render_model = [&]() {
    // The stars as normalise_and_centre left them (scaled fluxes, shifted positions).
    field = std::make_unique<StarFieldModel>(stars, grid, offsets, pad, hr, int(r), k);
    for (Index i = 0; i < n; ++i) {
      model[i] = field->Render(h, i);
      resid[i] = (valid[i] > 0).select(Image(y[i] - bg[i] - model[i]), 0.0);
      // The background noise again from the residual: with the stars subtracted, their gradients no longer
      // inflate the neighbour differences the first estimate was made from (crowded or small frames), and only
      // pixels where the stars' photon noise is below the background's (model < σ²) enter, so it does not either.
      if (weights_in.empty()) {
        const Image quiet = valid[i] * mask[i] * (model[i] < var_floor[i]).cast<double>();
        const double s = EstimateBackgroundSigma(resid[i], quiet);
        if (s > 0) var_floor[i] = std::max(s, sigma_floor[i]) * std::max(s, sigma_floor[i]);
      }
    }
  };

  // Every node starts from the single PSF of round 0.
  auto activate_field = [&]() {
    if (field_nodes <= 1 || nodes == field_nodes) return;
    check_nodes("after the single-PSF rounds");
    const Vector single = h;
    // The prior's scale: τ(ρ) = grid_variation · peak / (1 + (ρ/2r)²), the single PSF's peak; in the weights'
    // units (inverse variances), so bright stars override it and faint ones lean on it.
    const double tau0 = options.grid_variation * single.maxCoeff();
    coupling = AsVector(ridge_shape).array().square() / (tau0 * tau0);
    if (options.grid_degree > 0)
      node_prior = NodePriorMatrix(field_grid, options.grid_degree, options.grid_variation, options.grid_roughness);
    grid = field_grid;
    nodes = field_nodes;
    gk2 = Index(nodes) * k * k;
    h.resize(gk2);
    for (int g = 0; g < nodes; ++g) h.segment(Index(g) * k * k, k * k) = single;
    u.resize(0);  // solve_h starts again from [h; b]
  };

  const int total_rounds = field_nodes > 1 ? 2 * options.rounds : options.rounds;
  for (int round = 0;; ++round) {
    if (round == options.rounds) activate_field();
    solve_h(round == total_rounds);
    normalise_and_centre();
    render_model();
    update_weights(&model);
    if (round == total_rounds) break;
    res.rounds = round + 1;
    node_spectra.clear();
    for (int g = 0; g < nodes; ++g) node_spectra.push_back(FftR2C(ToImage(h.segment(Index(g) * k * k, k * k), kk)));
    Patch patch;
    // New stars in frame 0's residual (stars hidden by brighter ones, or dropped too early).
    if (round > 0) {
      // A residual peak counts when it stands out from the noise there (background and the model's photon
      // noise) and from the model's own imperfection (kResidualFraction of the model at that pixel): an
      // imperfectly subtracted bright star is not a new star.
      Image thr(lr.rows, lr.cols);
      const double k2 = options.detection_sigma * options.detection_sigma;
      for (Index p = 0; p < thr.size(); ++p)
        thr(p) = std::max(std::sqrt(k2 * (var_floor[0] + std::max(0.0, model[0](p)))), kResidualFraction * model[0](p));
      for (const Candidate& c : Detect(resid[0], valid[0], 0.0, 1, &thr)) {
        if (c.touches_invalid || mask[0](Index(std::lround(c.y)), Index(std::lround(c.x))) == 0) continue;
        const double py = CameraToHr(c.y, r) - offsets[0].dy, px = CameraToHr(c.x, r) - offsets[0].dx;
        bool near = false;
        for (const Star& s : stars) near = near || std::hypot(s.y - py, s.x - px) < 2.0 * r;
        if (near || int(stars.size()) >= options.max_stars) continue;
        Star s;
        s.y = s.y_det = py;
        s.x = s.x_det = px;
        // The least-squares flux on the 3 × 3 pixels around the peak.
        const KernelRenderer renderer = renderer_at(py, px);
        renderer.Render(py + offsets[0].dy, px + offsets[0].dx, false, &patch);
        double num = 0, den = 0;
        for (Index dy = -1; dy <= 1; ++dy)
          for (Index dx = -1; dx <= 1; ++dx) {
            const Index yy = Index(std::lround(c.y)) + dy, xx = Index(std::lround(c.x)) + dx;
            const Index gy = yy - patch.top, gx = xx - patch.left;
            if (gy < 0 || gx < 0 || gy >= patch.g.rows() || gx >= patch.g.cols()) continue;
            num += patch.g(gy, gx) * resid[0](yy, xx);
            den += patch.g(gy, gx) * patch.g(gy, gx);
          }
        if (!(den > 0) || !(num > 0)) continue;
        s.f = num / den;
        for (Index i = 0; i < n; ++i) {
          renderer.Render(s.y + offsets[i].dy, s.x + offsets[i].dx, false, &patch);
          AddPatch(patch, -s.f, &resid[i]);
        }
        stars.push_back(s);
        ++res.detected;
      }
      std::sort(stars.begin(), stars.end(), by_flux);
    }
    // Positions and fluxes: Gauss-Newton per star on its own box, all frames jointly, the others subtracted.
    std::vector<bool> keep(stars.size(), true);
    for (std::size_t j = 0; j < stars.size(); ++j) {
      Star& s = stars[j];
      const KernelRenderer renderer = renderer_at(s.y, s.x);  // its PSF stays the one at its detection this round
      for (Index i = 0; i < n; ++i) {  // put the star back: the data its fit sees
        renderer.Render(s.y + offsets[i].dy, s.x + offsets[i].dx, false, &patch);
        AddPatch(patch, s.f, &resid[i]);
      }
      bool ok = true;
      for (int it = 0; it < 3 && ok; ++it) {
        Eigen::Matrix3d jtj = Eigen::Matrix3d::Zero();
        Eigen::Vector3d jte = Eigen::Vector3d::Zero();
        for (Index i = 0; i < n; ++i) {
          const double py = s.y + offsets[i].dy, px = s.x + offsets[i].dx;
          renderer.Render(py, px, true, &patch);
          const Index cy = Index(std::lround(HrToCamera(py, r))), cx = Index(std::lround(HrToCamera(px, r)));
          for (Index yy = std::max<Index>(0, cy - rfit); yy <= std::min<Index>(lr.rows - 1, cy + rfit); ++yy)
            for (Index xx = std::max<Index>(0, cx - rfit); xx <= std::min<Index>(lr.cols - 1, cx + rfit); ++xx) {
              const double wt = w[i](yy, xx);
              const Index gy = yy - patch.top, gx = xx - patch.left;
              if (wt <= 0 || gy < 0 || gx < 0 || gy >= patch.g.rows() || gx >= patch.g.cols()) continue;
              const Eigen::Vector3d jac(patch.g(gy, gx), s.f * patch.gy(gy, gx), s.f * patch.gx(gy, gx));
              jtj.noalias() += wt * jac * jac.transpose();
              jte.noalias() += wt * jac * (resid[i](yy, xx) - s.f * patch.g(gy, gx));
            }
        }
        const Eigen::LDLT<Eigen::Matrix3d> ldlt(jtj);
        if (ldlt.info() != Eigen::Success || !(jtj(0, 0) > 0) || ldlt.vectorD().minCoeff() <= 0) {
          ok = false;
          break;
        }
        const Eigen::Vector3d step = ldlt.solve(jte);
        const double lim = 0.5 * r;
        s.f += step(0);
        s.y += std::clamp(step(1), -lim, lim);
        s.x += std::clamp(step(2), -lim, lim);
        s.sigma_f = std::sqrt(std::max(0.0, ldlt.solve(Eigen::Vector3d::UnitX())(0)));
        if (!(s.f > 0) || !std::isfinite(s.f)) ok = false;
      }
      ok = ok && s.f > kDropSnr * s.sigma_f && std::hypot(s.y - s.y_det, s.x - s.x_det) <= kDropMove * r;
      keep[j] = ok;
      if (!ok) {
        ++res.dropped;
        continue;  // left in the residual: its light is data the others see
      }
      for (Index i = 0; i < n; ++i) {
        renderer.Render(s.y + offsets[i].dy, s.x + offsets[i].dx, false, &patch);
        AddPatch(patch, -s.f, &resid[i]);
      }
    }
    std::vector<Star> kept;
    for (std::size_t j = 0; j < stars.size(); ++j)
      if (keep[j]) kept.push_back(stars[j]);
    stars.swap(kept);
    if (round > 0 && options.reject_extended) {
      // Point sources only: each star's χ² per pixel on its own box (every star subtracted), against the stars'
      // median, and its residual's power against its own model's there. A nebular knot or a galaxy leaves a
      // residual no PSF can remove, large against its own light; a bright star under a slightly wrong PSF has a
      // large χ² but a small relative residual, and stays. A rejected one's box is masked in every frame, so its
      // light enters neither h nor the noise estimate.
      std::vector<double> c(stars.size(), 0.0), rel(stars.size(), 0.0);
      for (std::size_t j = 0; j < stars.size(); ++j) {
        double sum = 0, res2 = 0, mod2 = 0;
        Index cnt = 0;
        const KernelRenderer renderer = renderer_at(stars[j].y, stars[j].x);
        for (Index i = 0; i < n; ++i) {
          const double py = stars[j].y + offsets[i].dy, px = stars[j].x + offsets[i].dx;
          renderer.Render(py, px, false, &patch);
          const Index cy = Index(std::lround(HrToCamera(py, r))), cx = Index(std::lround(HrToCamera(px, r)));
          for (Index yy = std::max<Index>(0, cy - rfit); yy <= std::min<Index>(lr.rows - 1, cy + rfit); ++yy)
            for (Index xx = std::max<Index>(0, cx - rfit); xx <= std::min<Index>(lr.cols - 1, cx + rfit); ++xx)
              if (w[i](yy, xx) > 0) {
                sum += w[i](yy, xx) * resid[i](yy, xx) * resid[i](yy, xx);
                ++cnt;
                res2 += resid[i](yy, xx) * resid[i](yy, xx);
                const Index gy = yy - patch.top, gx = xx - patch.left;
                if (gy >= 0 && gx >= 0 && gy < patch.g.rows() && gx < patch.g.cols())
                  mod2 += std::pow(stars[j].f * patch.g(gy, gx), 2);
              }
        }
        c[j] = cnt > 0 ? sum / double(cnt) : 0.0;
        rel[j] = mod2 > 0 ? res2 / mod2 : 0.0;
      }
      const double limit = std::max(kRejectFloor, kRejectFactor * StarsMedian(c));
      std::vector<Star> point;
      for (std::size_t j = 0; j < stars.size(); ++j) {
        if (c[j] <= limit || rel[j] <= kRejectRelative) {
          point.push_back(stars[j]);
          continue;
        }
        ++res.rejected;
        for (Index i = 0; i < n; ++i) {
          const double cy = HrToCamera(stars[j].y + offsets[i].dy, r), cx = HrToCamera(stars[j].x + offsets[i].dx, r);
          for (Index yy = std::max<Index>(0, Index(cy) - rmask); yy <= std::min<Index>(lr.rows - 1, Index(cy) + rmask); ++yy)
            for (Index xx = std::max<Index>(0, Index(cx) - rmask); xx <= std::min<Index>(lr.cols - 1, Index(cx) + rmask); ++xx)
              mask[i](yy, xx) = 0;
        }
      }
      stars.swap(point);
      update_weights(&model);
    }
    std::sort(stars.begin(), stars.end(), by_flux);
    if (int(stars.size()) < res.min_required) throw too_few(stars.size(), "left after fitting");
    if (nodes > 1) check_nodes("left after fitting");
  }

  // ---- Result. ----------------------------------------------------------------------------------------------
  // The field's nodes; the PSF of the field's centre stands for the field where one PSF is wanted (it is what
  // the regularisation is chosen with, as for a dataset's psf_field).
  res.grid = grid;
  if (nodes > 1) {
    res.grid_degree = options.grid_degree;
    res.grid_roughness = options.grid_roughness;
  }
  for (int g = 0; g < nodes && nodes > 1; ++g) res.node_psfs.push_back(ToImage(h.segment(Index(g) * k * k, k * k), kk));
  res.psf = nodes > 1 ? grid.Interpolate(res.node_psfs, 0.5 * double(hr.rows - 1), 0.5 * double(hr.cols - 1))
                      : ToImage(h, kk);
  double chi2 = 0, chi2_near = 0;
  Index npix = 0, nnear = 0;
  for (Index i = 0; i < n; ++i) {
    Image near = Image::Zero(lr.rows, lr.cols);
    for (const Star& s : stars) {
      const Index cy = Index(std::lround(HrToCamera(s.y + offsets[i].dy, r)));
      const Index cx = Index(std::lround(HrToCamera(s.x + offsets[i].dx, r)));
      for (Index yy = std::max<Index>(0, cy - rfit); yy <= std::min<Index>(lr.rows - 1, cy + rfit); ++yy)
        for (Index xx = std::max<Index>(0, cx - rfit); xx <= std::min<Index>(lr.cols - 1, cx + rfit); ++xx)
          near(yy, xx) = 1;
    }
    for (Index p = 0; p < near.size(); ++p)
      if (w[i](p) > 0) {
        const double c = w[i](p) * resid[i](p) * resid[i](p);
        chi2 += c;
        ++npix;
        if (near(p) > 0) {
          chi2_near += c;
          ++nnear;
        }
      }
  }
  res.dof = npix - gk2 - 3 * Index(stars.size()) - n;
  res.chi2_per_dof = res.dof > 0 ? chi2 / double(res.dof) : 0.0;
  res.chi2_near_stars = nnear > 0 ? chi2_near / double(nnear) : 0.0;
  if (options.max_chi2_near_stars > 0 && res.chi2_near_stars > options.max_chi2_near_stars)
    throw InvalidArgument(
        kStarsPsfFn, "fit",
        "chi2 per pixel near the stars " + ToString(res.chi2_near_stars) + " (chi2/dof " + ToString(res.chi2_per_dof) +
            ") with " + std::to_string(stars.size()) + " stars kept (" + std::to_string(res.rejected) +
            " rejected as not point-like, " + std::to_string(res.dropped) + " dropped): the frames are not point sources "
            "on a smooth background (structured emission, extended sources, or a PSF that varies across the field)",
        "<= max_chi2_near_stars = " + ToString(options.max_chi2_near_stars) +
            ": give model PSFs instead (a file, or nominal), or mask the extended emission");
  // Per-frame PSFs: h shifted by o_i on a window padded so the shift does not wrap the wings.
  double omax = 0;
  for (const FrameOffset& o : offsets) omax = std::max({omax, std::abs(o.dy), std::abs(o.dx)});
  const Index margin = Index(std::ceil(omax)) + (Index(std::ceil(omax)) > 0 ? 1 : 0);
  auto per_frame = [&](const Image& kernel) {
    Image padded = Image::Zero(k + 2 * margin, k + 2 * margin);
    padded.block(margin, margin, k, k) = kernel;
    ImageStack out;
    for (const FrameOffset& o : offsets) {
      Image p = FourierShiftKernel(padded, o.dy, o.dx);
      p /= p.sum();
      out.push_back(p);
    }
    return out;
  };
  res.psfs = per_frame(res.psf);
  for (const Image& node : res.node_psfs) res.field_psfs.push_back(per_frame(node));
  for (const Star& s : stars) res.stars.push_back({s.y, s.x, s.f});
  res.used = int(stars.size());
  res.background_e = bg;
  res.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return res;
}

StarsPsfResult EstimateStarsPsf(const Dataset& d, const StarsPsfOptions& options) {
  const std::size_t n = d.frames.size();
  CheckArgument(n > 0, kStarsPsfFn, "dataset frames", 0, "at least one frame");
  std::vector<FrameOffset> offsets(n);
  for (std::size_t i = 0; i < n && i < d.offsets.size(); ++i) {
    const DmOffset& o = d.offsets[i];
    bool shape = !o.zernike.empty();
    for (double a : o.actuators_m) shape = shape || a != 0;
    CheckArgument(!shape, kStarsPsfFn, "dataset offsets[" + std::to_string(i) + "]", "Zernike or actuator terms",
                  "tip/tilt shifts only (shift_px): the stars PSF is one shape shared by all frames, and these "
                  "offsets change the PSF's shape from frame to frame");
    offsets[i] = {o.shift_y_px * d.r, o.shift_x_px * d.r};
  }
  ImageStack weights;
  if (d.weights) {
    const double g2 = d.gain_e_per_adu * d.gain_e_per_adu;
    for (std::size_t i = 0; i < n; ++i) weights.push_back((*d.weights)[i] * d.valid[i] / g2);
  }
  return EstimateStarsPsf(d.FramesElectrons(), d.valid, weights, offsets, d.r, options);
}

}  // namespace aosr
