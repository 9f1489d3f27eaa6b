#include "aosr/ao/phase_screen.hpp"

#include <atomic>
#include <algorithm>
#include <array>
#include <cmath>

#include "aosr/ao/random.hpp"
#include "aosr/ao/von_karman.hpp"
#include "aosr/core/error.hpp"
#include "aosr/core/fft.hpp"

namespace aosr {
namespace {

// FFT bins with |k|_inf <= kInnerRing are re-sampled on the level-1 grid of spacing df/3 (header).
constexpr int kInnerRing = 4;
using ComplexMatrix = Eigen::Matrix<Complex, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

// Phi(f) without argument checks, for the inner loops: c r0^(-5/3) (f^2 + 1/L0^2)^(-11/6).
struct Psd {
  double scale;  // c_Phi r0^(-5/3)
  double f02;    // 1/L0^2
  double operator()(double fx, double fy) const {
    return scale * std::pow(fx * fx + fy * fy + f02, -11.0 / 6.0);
  }
};

// 4-point Gauss-Legendre on [-1, 1].
constexpr std::array<double, 4> kGl4Nodes = {-0.8611363115940526, -0.3399810435848563, 0.3399810435848563,
                                             0.8611363115940526};
constexpr std::array<double, 4> kGl4Weights = {0.3478548451374538, 0.6521451548625461, 0.6521451548625461,
                                               0.3478548451374538};

// Second-moment weight of the square cell of side `width` centred on (fx, fy) != 0:
//   integral_cell Phi(f) |f|^2 d^2f / |f_c|^2, on 8 x 8 sub-cells with 4 x 4 Gauss points each.
double SecondMomentWeight(const Psd& psd, double fx, double fy, double width) {
  // Cells within two widths of the origin, where Phi varies by orders of magnitude across the cell, get
  // 8 x 8 sub-cells; the others 2 x 2 (Phi varies by < 2x across them).
  const int kSub = std::max(std::abs(fx), std::abs(fy)) <= 2.01 * width ? 8 : 2;
  const double sub = width / kSub;
  double sum = 0.0;
  for (int a = 0; a < kSub; ++a) {
    for (int b = 0; b < kSub; ++b) {
      const double cy = fy - 0.5 * width + (a + 0.5) * sub;
      const double cx = fx - 0.5 * width + (b + 0.5) * sub;
      for (std::size_t i = 0; i < kGl4Nodes.size(); ++i) {
        const double y = cy + 0.5 * sub * kGl4Nodes[i];
        for (std::size_t k = 0; k < kGl4Nodes.size(); ++k) {
          const double x = cx + 0.5 * sub * kGl4Nodes[k];
          sum += kGl4Weights[i] * kGl4Weights[k] * psd(x, y) * (x * x + y * y);
        }
      }
    }
  }
  return sum * 0.25 * sub * sub / (fx * fx + fy * fy);
}

// integral over the outside of the square of half-width 1 of |g|^(-11/3) d^2g = (24/5) int_0^(pi/4)
// cos^(5/3).
double OutsideSquareIntegral() {
  double s = 0.0;
  constexpr int kPanels = 32;
  const double h = 0.25 * kPi / kPanels;
  for (int p = 0; p < kPanels; ++p) {
    for (std::size_t i = 0; i < kGl4Nodes.size(); ++i) {
      const double t = (p + 0.5 + 0.5 * kGl4Nodes[i]) * h;
      s += 0.5 * h * kGl4Weights[i] * std::pow(std::cos(t), 5.0 / 3.0);
    }
  }
  return 24.0 / 5.0 * s;
}

// Unit phasors exp(2 pi i (j - half) spacing pos_m) for j in [0, 2 half], pos_m = 0 .. n-1 times dx.
ComplexMatrix Phasors(int half, double spacing, Index n, double dx) {
  ComplexMatrix e(2 * half + 1, n);
  for (int j = 0; j <= 2 * half; ++j) {
    const double f = (j - half) * spacing;
    for (Index p = 0; p < n; ++p) {
      const double arg = 2.0 * kPi * f * (static_cast<double>(p) * dx);
      e(j, p) = Complex(std::cos(arg), std::sin(arg));
    }
  }
  return e;
}

}  // namespace

bool PhaseScreenOptions::IsValid(std::string* why) const {
  std::string msg;
  if (!(size >= 16 && size <= 16384)) {
    msg = "size = " + ToString(size) + "; allowed: 16 .. 16384 [pixels]";
  } else if (!(std::isfinite(pixel_scale_m) && pixel_scale_m > 0.0)) {
    msg = "pixel_scale_m = " + ToString(pixel_scale_m) + "; allowed: > 0 and finite [m]";
  } else if (!(std::isfinite(r0_m) && r0_m > 0.0)) {
    msg = "r0_m = " + ToString(r0_m) + "; allowed: > 0 and finite [m]";
  } else if (!(std::isfinite(L0_m) && L0_m > 0.0)) {
    msg = "L0_m = " + ToString(L0_m) + "; allowed: > 0 and finite [m]";
  } else if (!(subharmonic_levels >= -1 && subharmonic_levels <= 20)) {
    msg = "subharmonic_levels = " + ToString(subharmonic_levels) + "; allowed: -1 (automatic) .. 20";
  }
  if (msg.empty()) return true;
  if (why != nullptr) *why = msg;
  return false;
}

PhaseScreenGenerator::PhaseScreenGenerator(const PhaseScreenOptions& options) : options_(options) {
  std::string why;
  if (!options.IsValid(&why)) throw InvalidArgument("PhaseScreenGenerator: invalid options." + why);
  const Index n = options.size;
  const double dx = options.pixel_scale_m;
  const double df = 1.0 / (static_cast<double>(n) * dx);
  const Psd psd{VonKarmanPsdConstant() * std::pow(options.r0_m, -5.0 / 3.0),
                1.0 / (options.L0_m * options.L0_m)};
  if (options.subharmonic_levels >= 0) {
    levels_ = options.subharmonic_levels;
  } else {
    const double ratio = std::max(options.L0_m / (static_cast<double>(n) * dx), 1.0);
    levels_ = std::min(20, 3 + static_cast<int>(std::ceil(std::log(ratio) / std::log(3.0) - 1e-9)));
  }
  const bool refined = levels_ >= 1;

  // FFT bins: point (or second-moment) weight + aliases |m|_inf <= 2 + white tail beyond.
  constexpr int kAlias = 2;
  const double fs = 1.0 / dx;  // sampling frequency
  const double tail = psd.scale * std::pow(dx, 11.0 / 3.0) * std::pow(kAlias + 0.5, -5.0 / 3.0) *
                      OutsideSquareIntegral();  // per bin, in units of df^2
  bin_amplitude_.resize(n, n);
  for (Index i = 0; i < n; ++i) {
    const Index ky = SignedFrequency(i, n);
    const double fy = static_cast<double>(ky) * df;
    for (Index k = 0; k < n; ++k) {
      const Index kx = SignedFrequency(k, n);
      const double fx = static_cast<double>(kx) * df;
      if (kx == 0 && ky == 0) {
        bin_amplitude_(i, k) = 0.0;  // piston
        continue;
      }
      const Index ring = std::max(std::abs(kx), std::abs(ky));
      double p = 0.0;
      if (!refined) {
        p = psd(fx, fy) * df * df;
      } else if (ring == kInnerRing + 1) {
        p = SecondMomentWeight(psd, fx, fy, df);
      } else if (ring > kInnerRing + 1) {
        p = psd(fx, fy) * df * df;
      }  // ring <= kInnerRing with refinement: re-sampled on the fine grid below; only its aliases stay here.
      double alias = 0.0;
      for (int a = -kAlias; a <= kAlias; ++a) {
        for (int b = -kAlias; b <= kAlias; ++b) {
          if (a != 0 || b != 0) alias += psd(fx + b * fs, fy + a * fs);
        }
      }
      p += (alias + tail) * df * df;
      bin_amplitude_(i, k) = std::sqrt(p);
    }
  }

  if (refined) {
    // Level 1: [-4.5 df, 4.5 df]^2 on a 27 x 27 grid of spacing df/3; levels p >= 2: 3 x 3 of spacing df/3^p.
    for (int level = 1; level <= levels_; ++level) {
      FrequencyGrid g;
      g.spacing = df / std::pow(3.0, level);
      g.half = level == 1 ? 3 * kInnerRing + 1 : 1;
      const int m = 2 * g.half + 1;
      g.amplitude.assign(static_cast<std::size_t>(m) * m, 0.0);
      for (int b = -g.half; b <= g.half; ++b) {
        for (int a = -g.half; a <= g.half; ++a) {
          if (a == 0 && b == 0) continue;
          g.amplitude[(b + g.half) * m + (a + g.half)] =
              std::sqrt(SecondMomentWeight(psd, a * g.spacing, b * g.spacing, g.spacing));
        }
      }
      grids_.push_back(std::move(g));
    }
  }
}

namespace {
std::atomic<std::uint64_t> g_screens_generated{0};
}  // namespace

std::uint64_t PhaseScreensGenerated() { return g_screens_generated.load(std::memory_order_relaxed); }

ComplexImage PhaseScreenGenerator::GenerateComplex(std::uint64_t seed) const {
  g_screens_generated.fetch_add(1, std::memory_order_relaxed);
  const Index n = options_.size;
  const double dx = options_.pixel_scale_m;
  NormalGenerator rng(seed);
  ComplexImage coeff(n, n);
  for (Index p = 0; p < coeff.size(); ++p) {
    const double g1 = rng.Next();
    const double g2 = rng.Next();
    coeff.data()[p] = bin_amplitude_.data()[p] * Complex(g1, g2);
  }
  // sum_k c_k exp(-2 pi i k.r / n): the sign of the exponent does not matter for a symmetric random set.
  ComplexImage field = FftForward(coeff);
  Eigen::Map<ComplexMatrix> out(field.data(), n, n);
  for (const FrequencyGrid& g : grids_) {
    const int m = 2 * g.half + 1;
    ComplexMatrix c(m, m);  // (b: y index, a: x index)
    for (int q = 0; q < m * m; ++q) {
      const double g1 = rng.Next();
      const double g2 = rng.Next();
      c.data()[q] = g.amplitude[q] * Complex(g1, g2);
    }
    const ComplexMatrix e = Phasors(g.half, g.spacing, n, dx);  // same frequencies along y and x
    // field(y, x) += sum_{b, a} c(b, a) e(b, y) e(a, x) = (e^T c e)(y, x).
    out.noalias() += e.transpose() * (c * e);
  }
  return field;
}

Image PhaseScreenGenerator::Generate(std::uint64_t seed) const {
  Image screen = GenerateComplex(seed).real();
  screen -= screen.mean();
  return screen;
}

std::pair<Image, Image> PhaseScreenGenerator::GeneratePair(std::uint64_t seed) const {
  const ComplexImage field = GenerateComplex(seed);
  Image re = field.real();
  Image im = field.imag();
  re -= re.mean();
  im -= im.mean();
  return {std::move(re), std::move(im)};
}

double PhaseScreenGenerator::ExpectedStructureFunction(double dy_px, double dx_px) const {
  CheckArgument(std::isfinite(dy_px) && std::isfinite(dx_px), "ExpectedStructureFunction", "separation",
                ToString(dy_px) + ", " + ToString(dx_px), "finite (dy, dx) [pixels]");
  const Index n = options_.size;
  const double dx = options_.pixel_scale_m;
  double sum = 0.0;
  for (Index i = 0; i < n; ++i) {
    const double ty = static_cast<double>(SignedFrequency(i, n)) * dy_px / static_cast<double>(n);
    for (Index k = 0; k < n; ++k) {
      const double p = bin_amplitude_(i, k) * bin_amplitude_(i, k);
      if (p == 0.0) continue;
      const double tx = static_cast<double>(SignedFrequency(k, n)) * dx_px / static_cast<double>(n);
      sum += 2.0 * p * (1.0 - std::cos(2.0 * kPi * (tx + ty)));
    }
  }
  for (const FrequencyGrid& g : grids_) {
    const int m = 2 * g.half + 1;
    for (int b = -g.half; b <= g.half; ++b) {
      for (int a = -g.half; a <= g.half; ++a) {
        const double amp = g.amplitude[(b + g.half) * m + (a + g.half)];
        const double arg = 2.0 * kPi * g.spacing * dx * (a * dx_px + b * dy_px);
        sum += 2.0 * amp * amp * (1.0 - std::cos(arg));
      }
    }
  }
  return sum;
}

}  // namespace aosr
