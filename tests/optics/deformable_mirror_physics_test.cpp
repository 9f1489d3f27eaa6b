// Physics oracles for the deformable mirror: the fitting-error coefficient a_F against Kolmogorov turbulence,
// and the edge of the corrected PSF's halo at the control radius.
//
// The turbulence screens are generated here (not with ao/phase_screen.hpp: the ao layer depends on optics, so
// the optics tests cannot link it). They are plain FFT screens: complex white noise times the square root of
// the Kolmogorov phase PSD
//     Phi(f) = 0.023 r0^(-5/3) f^(-11/3)   [rad^2 m^2],
// on a 512 x 512 grid of pitch D/128 (a 32 m periodic screen), whose inverse transform's real and imaginary
// parts are two independent screens. Pupils are cropped from non-overlapping 128 x 128 tiles (16 per screen).
// Such screens lack frequencies below 1/32 m^-1 (the DM fits those almost perfectly, so they do not matter
// for the fitting error) and above the grid's Nyquist frequency 8 m^-1 = 4/d (added back analytically below:
// the DM cannot fit them at all).
#include <gtest/gtest.h>

#include <cmath>
#include <iostream>
#include <memory>
#include <random>
#include <vector>

#include "aosr/core/image.hpp"  // kPi
#include "aosr/core/fft.hpp"
#include "aosr/optics/deformable_mirror.hpp"
#include "aosr/optics/psf.hpp"
#include "aosr/optics/pupil.hpp"

namespace aosr {
namespace {

constexpr double kDiameter = 8.0;
constexpr Index kPupilN = 128;
constexpr double kPixel = kDiameter / kPupilN;  // 1/16 m
constexpr Index kScreenN = 512;

// Two independent Kolmogorov screens [rad] of size kScreenN at pitch kPixel.
std::pair<Image, Image> KolmogorovScreens(double r0_m, std::mt19937_64& rng) {
  std::normal_distribution<double> normal;
  const double df = 1.0 / (kScreenN * kPixel);
  ComplexImage spectrum(kScreenN, kScreenN);
  for (Index u = 0; u < kScreenN; ++u) {
    const double fy = SignedFrequency(u, kScreenN) * df;
    for (Index v = 0; v < kScreenN; ++v) {
      const double fx = SignedFrequency(v, kScreenN) * df;
      const double f = std::hypot(fx, fy);
      const double amplitude =
          f > 0.0 ? std::sqrt(0.023 * std::pow(r0_m, -5.0 / 3.0) * std::pow(f, -11.0 / 3.0)) * df : 0.0;
      spectrum(u, v) = Complex(normal(rng), normal(rng)) * amplitude;
    }
  }
  // FftInverse divides by N^2; the screen is the plain sum over frequencies.
  const ComplexImage screen = FftInverse(spectrum) * static_cast<double>(kScreenN * kScreenN);
  return {screen.real(), screen.imag()};
}

// Kolmogorov phase variance [rad^2] outside the square [-f_N, f_N]^2 of the screen's frequency grid: what the
// sampled screens miss. Polar integral of Phi beyond the square, 8 octants of width pi/4:
//     sigma^2 = 8 int_0^{pi/4} int_{f_N / cos t}^inf Phi(f) f df dt = 8 * 0.023 (3/5) (f_N r0)^(-5/3) int
//     cos^(5/3) t dt.
double MissingHighFrequencyVariance(double r0_m) {
  const double f_n = 0.5 / kPixel;
  double integral = 0.0;
  const int steps = 2000;
  for (int s = 0; s < steps; ++s) {
    const double t = (s + 0.5) / steps * kPi / 4.0;
    integral += std::pow(std::cos(t), 5.0 / 3.0) * (kPi / 4.0) / steps;
  }
  return 8.0 * 0.023 * 0.6 * std::pow(f_n * r0_m, -5.0 / 3.0) * integral;
}

// 16 non-overlapping kPupilN x kPupilN tiles of a screen.
std::vector<Image> Tiles(const Image& screen) {
  std::vector<Image> tiles;
  for (Index ty = 0; ty + kPupilN <= kScreenN; ty += kPupilN) {
    for (Index tx = 0; tx + kPupilN <= kScreenN; tx += kPupilN)
      tiles.push_back(screen.block(ty, tx, kPupilN, kPupilN));
  }
  return tiles;
}

double PupilVariance(const Image& x, const Image& pupil) {
  const double w = pupil.sum();
  const double mean = (pupil * x).sum() / w;
  return (pupil * (x - mean).square()).sum() / w;
}

// The 8 m telescope, 16 x 16 subapertures in Fried geometry: 17 x 17 actuators of pitch d = 0.5 m.
std::shared_ptr<DeformableMirror> FriedMirror(double coupling) {
  DeformableMirrorOptions o;
  o.actuators_across = 17;
  o.pitch_m = kDiameter / 16.0;
  o.coupling = coupling;
  return std::make_shared<DeformableMirror>(kPupilN, PupilGeometry{kDiameter, 0.0}, o);
}

// Structure function D(r) = <(phi(x + r) - phi(x))^2> of the screens at r = d/2, d and 2d. This checks the
// generator's normalisation, on which a_F depends: the expectation for the screen's own (truncated) spectrum
// is
//     D_grid(r) = 2 sum_f Phi(f) df^2 (1 - cos(2 pi f_x r))
// over the same frequency grid, and the measured D must match it (tolerance 10%; 8 screens, seed 99; measured
// ratios 0.97, 0.96, 0.94 at 0.25, 0.5, 1 m: the low frequencies that dominate D vary from screen to screen).
// Against the continuous Kolmogorov 6.88 (r / r0)^(5/3) these screens fall short by 20 - 35% at 0.25 - 1 m:
// the missing frequencies below 1/(32 m) contribute ~ 0.023 4 pi^3 r^2 r0^(-5/3) 3 f_min^(1/3), a deficit
// that decays only as (r f_min)^(1/3) (the well-known weakness of FFT screens without subharmonics). It does
// not matter for the fitting error, which lives above 1/(2d) = 1 m^-1 where the spectrum is exact; it is
// printed for the record.
TEST(DeformableMirrorPhysicsTest, ScreensHaveTheirSpectrumsStructureFunction) {
  std::mt19937_64 rng(99);
  const double r0 = 0.5;
  std::vector<Image> screens;
  for (int f = 0; f < 4; ++f) {
    auto pair = KolmogorovScreens(r0, rng);
    screens.push_back(std::move(pair.first));
    screens.push_back(std::move(pair.second));
  }
  const double df = 1.0 / (kScreenN * kPixel);
  for (Index lag : {4, 8, 16}) {
    const double r = lag * kPixel;
    double sum = 0.0;
    long count = 0;
    for (const Image& sc : screens) {
      for (Index y = 0; y < kScreenN; ++y) {
        for (Index x = 0; x < kScreenN; ++x) {
          const double dx = sc(y, (x + lag) % kScreenN) - sc(y, x);
          const double dy = sc((y + lag) % kScreenN, x) - sc(y, x);
          sum += dx * dx + dy * dy;
          count += 2;
        }
      }
    }
    const double measured = sum / count;
    double expected = 0.0;
    for (Index u = 0; u < kScreenN; ++u) {
      for (Index v = 0; v < kScreenN; ++v) {
        const double fy = SignedFrequency(u, kScreenN) * df, fx = SignedFrequency(v, kScreenN) * df;
        const double f = std::hypot(fx, fy);
        if (f == 0.0) continue;
        const double phi = 0.023 * std::pow(r0, -5.0 / 3.0) * std::pow(f, -11.0 / 3.0);
        expected += 2.0 * phi * df * df * (1.0 - std::cos(2.0 * kPi * fx * r));
      }
    }
    const double kolmogorov = 6.88 * std::pow(r / r0, 5.0 / 3.0);
    std::cout << "D(" << r << " m) = " << measured << " rad^2; expected for the grid's spectrum " << expected
              << " (ratio " << measured / expected << "); continuous Kolmogorov " << kolmogorov << "\n";
    EXPECT_NEAR(measured / expected, 1.0, 0.1) << "lag " << lag << " px, seed 99";
  }
}

// Fitting error: sigma_F^2 = a_F (d / r0)^(5/3). With r0 = d the residual variance over the pupil (piston
// removed) is a_F itself. 4 FFTs -> 8 screens -> 128 pupils; seed 2024. The residual variance adds the
// missing high-frequency variance (0.0073 rad^2 here, ~3% of a_F), which no DM could fit. Statistical error
// of the mean: ~1% (printed). The whole-pupil value includes the Fried-geometry rim (the actuator grid ends
// at the rim; the rim's partly constrained actuators follow the local turbulence slightly better), the
// inner-disk value (rho < 0.8) is the infinite-mirror figure. Measured (seed 2024), whole pupil / rho < 0.8:
//     coupling 0.10: 0.352 / 0.367     (stiff: the lattice leaves gaps, ripple floor 2.7% even for piston)
//     coupling 0.15: 0.256 / 0.268     (statistical error of each mean: +-0.002)
//     coupling 0.20: 0.237 / 0.245
//     coupling 0.25: 0.231 / 0.237
//     coupling 0.30: 0.228 / 0.234
// a_F must lie in [0.23, 0.29] (Hudgin 1977; Hardy 1998) for the usual face-sheet couplings 0.15 - 0.25 and
// falls monotonically as the coupling rises from 0.1 to 0.3 (softer influence functions follow the in-band
// turbulence better); the extreme couplings are printed, and their values bracket the tabulated range.
TEST(DeformableMirrorPhysicsTest, FittingErrorCoefficientOfGaussianInfluenceFunctions) {
  const std::uint64_t seed = 2024;
  std::mt19937_64 rng(seed);
  const double d = kDiameter / 16.0;
  const double r0 = d;
  const Image pupil = CircularPupil(kPupilN, PupilGeometry{kDiameter, 0.0});
  const PolarCoordinates polar = PupilCoordinates(kPupilN);
  const Image inner = (polar.rho < 0.8).cast<double>();
  std::vector<Image> samples;
  for (int f = 0; f < 4; ++f) {
    const auto screens = KolmogorovScreens(r0, rng);
    for (const Image* s : {&screens.first, &screens.second}) {
      for (Image& t : Tiles(*s)) samples.push_back(std::move(t));
    }
  }
  const double missing = MissingHighFrequencyVariance(r0);
  std::cout << "seed " << seed << ": " << samples.size() << " pupils; missing high-frequency variance "
            << missing << " rad^2\n";
  double previous = 1e9;
  for (double coupling : {0.1, 0.15, 0.2, 0.25, 0.3}) {
    const auto dm = FriedMirror(coupling);
    const DmFitter fitter(dm, pupil);
    std::vector<double> whole, centre;
    for (const Image& s : samples) {
      const Image residual = fitter.Residual(s);
      whole.push_back(PupilVariance(residual, pupil) + missing);
      centre.push_back(PupilVariance(residual, inner) + missing);
    }
    auto mean_and_error = [](const std::vector<double>& v) {
      double m = 0.0, m2 = 0.0;
      for (double x : v) m += x, m2 += x * x;
      m /= v.size();
      m2 /= v.size();
      return std::make_pair(m, std::sqrt((m2 - m * m) / (v.size() - 1)));
    };
    const auto [a_whole, e_whole] = mean_and_error(whole);
    const auto [a_centre, e_centre] = mean_and_error(centre);
    std::cout << "coupling " << coupling << ": a_F = " << a_whole << " +- " << e_whole << " (whole pupil), "
              << a_centre << " +- " << e_centre << " (rho < 0.8)\n";
    if (coupling >= 0.15 && coupling <= 0.25) {
      EXPECT_GE(a_whole, 0.23) << "coupling " << coupling << ", seed " << seed;
      EXPECT_LE(a_whole, 0.29) << "coupling " << coupling << ", seed " << seed;
      EXPECT_GE(a_centre, 0.23) << "coupling " << coupling << ", seed " << seed;
      EXPECT_LE(a_centre, 0.29) << "coupling " << coupling << ", seed " << seed;
    }
    EXPECT_LT(a_centre, previous) << "coupling " << coupling;
    previous = a_centre;
  }
}

// The corrected PSF's halo. The DM controls spatial frequencies |f_x|, |f_y| < 1/(2d), so the residual PSD
// drops inside a square of half-width lambda/(2d) = (N_act - 1)/2 lambda/D = 8 lambda/D in the focal plane
// and rises to the uncorrected Kolmogorov halo beyond it. Set-up: d/r0 = 1 at the imaging wavelength
// (residual ~0.26 rad^2, Strehl ~0.78), 64 fitted screens (seed 7), long-exposure PSF at 0.25 lambda/D on
// +-16 lambda/D. The coherent core S * PSF_perfect (S: mean Strehl) is subtracted so the Airy rings do not
// mask the halo, and the profile is taken along the grid axes (band |y| <= 3 lambda/D, averaged over +-x and
// +-y; the corrected region is a square, so an azimuthal average would smear the edge between 8 and 8 sqrt(2)
// lambda/D). The halo rises from a floor (mean over 2 - 5 lambda/D) to a peak just outside the control radius
// and then falls as the Kolmogorov f^(-11/3); the edge is where it crosses half-way (linear) between floor
// and peak, the 50% point of a blurred step (the blur: ~1 lambda/D from the pupil's transfer function, and
// the Gaussian DM's response rolling off below the cut-off). Measured (seed 7): edge at 7.84 lambda/D,
// steepest rise at 8.4, peak / floor 12.5 (printed). Tolerance: the edge within 10% of 8 lambda/D; peak /
// floor > 5.
TEST(DeformableMirrorPhysicsTest, CorrectedHaloStartsAtTheControlRadius) {
  std::mt19937_64 rng(7);
  const double d = kDiameter / 16.0;
  const double lambda = 1.65e-6;
  const double s = 0.25;  // lambda/D per pixel
  const Index rows = 128;
  const Image pupil = CircularPupil(kPupilN, PupilGeometry{kDiameter, 0.0});
  const auto dm = FriedMirror(0.15);
  const DmFitter fitter(dm, pupil);
  const PsfCalculator calc(kPupilN, kDiameter, PsfSampling{lambda, s * lambda / kDiameter, rows, rows});
  Image long_exposure = Image::Zero(rows, rows);
  int count = 0;
  double strehl = 0.0;
  for (int f = 0; f < 2; ++f) {
    const auto screens = KolmogorovScreens(d, rng);
    for (const Image* sc : {&screens.first, &screens.second}) {
      for (const Image& t : Tiles(*sc)) {
        const Image opd = fitter.Residual(t) * (lambda / (2.0 * kPi));
        long_exposure += calc.Compute(pupil, opd);
        strehl += StrehlFromPupil(pupil, opd, lambda);
        ++count;
      }
    }
  }
  long_exposure /= count;
  strehl /= count;
  const Image halo = long_exposure - strehl * calc.Compute(pupil, Image::Zero(kPupilN, kPupilN));
  // Axis profile: P(x) for x = 0 .. rows/2 - 1 pixels from the centre.
  const Index c = rows / 2, band = static_cast<Index>(3.0 / s);
  std::vector<double> profile(c, 0.0);
  for (Index x = 0; x < c; ++x) {
    double sum = 0.0;
    int n = 0;
    for (Index y = -band; y <= band; ++y) {
      sum += halo(c + y, c + x) + halo(c + y, c - x) + halo(c + x, c + y) + halo(c - x, c + y);
      n += 4;
    }
    profile[x] = sum / n;
  }
  auto px = [&](double lod) { return static_cast<Index>(std::lround(lod / s)); };
  double floor = 0.0;
  for (Index x = px(2.0); x <= px(5.0); ++x) floor += profile[x] / (px(5.0) - px(2.0) + 1);
  Index peak_x = px(5.0);
  for (Index x = px(5.0); x <= px(12.0); ++x) {
    if (profile[x] > profile[peak_x]) peak_x = x;
  }
  const double peak = profile[peak_x];
  const double half = 0.5 * (floor + peak);
  double edge = -1.0;  // last upward crossing of `half` before the peak, linearly interpolated
  for (Index x = px(2.0); x < peak_x; ++x) {
    if (profile[x] < half && profile[x + 1] >= half)
      edge = (x + (half - profile[x]) / (profile[x + 1] - profile[x])) * s;
  }
  Index steepest_x = px(4.0);
  for (Index x = px(4.0); x < px(12.0); ++x) {
    if (profile[x + 1] - profile[x] > profile[steepest_x + 1] - profile[steepest_x]) steepest_x = x;
  }
  std::cout << "mean Strehl " << strehl << "; halo floor " << floor << ", peak " << peak << " at "
            << peak_x * s << " lambda/D; half-way edge at " << edge << " lambda/D, steepest rise at "
            << (steepest_x + 0.5) * s << " (control radius " << (17 - 1) / 2.0 << " lambda/D)\n";
  EXPECT_NEAR(edge, 8.0, 0.8);
  EXPECT_GT(peak / floor, 5.0);
  EXPECT_NEAR(strehl, std::exp(-0.26), 0.05);  // extended Marechal with a_F ~ 0.26, d = r0
}

}  // namespace
}  // namespace aosr
