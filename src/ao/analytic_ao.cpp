// Analytic AO: structure function of the residual and long-exposure PSFs (header sections 4, 5).
#include "aosr/ao/analytic_ao.hpp"

#include <cmath>
#include <vector>

#include "analytic_ao_internal.hpp"
#include "aosr/core/error.hpp"
#include "aosr/core/fft.hpp"

namespace aosr {


namespace {

Index CheckedPupilN(const AnalyticAoOptions& options, Index pupil_n, const char* fn) {
  analytic_ao_internal::CheckOptions(options, fn);
  // f_t = n/(2D) - 1/(K D) must reach sqrt(2) f_c + 1/(K D) (square) or f_c + 1/(K D) (disk).
  const double k = options.frequency_padding;
  const double reach =
      (options.control_domain == ControlDomain::kSquare ? std::sqrt(2.0) : 1.0) * options.ControlRadius();
  const Index needed = static_cast<Index>(std::ceil(2.0 * options.diameter_m * reach + 4.0 / k - 1e-9));
  // The PSD grid is (K n)^2 cells, six images of it live at once: cap K n at 4096 (~0.8 GB).
  const Index largest = 4096 / options.frequency_padding;
  CheckArgument(
      pupil_n >= needed && pupil_n <= largest, fn, "pupil_n", pupil_n,
      "[" + std::to_string(needed) + ", " + std::to_string(largest) +
          "]: at least sqrt(2) D/d + 4/K pixels across the pupil, so the PSD grid holds the control "
          "region, and at most 4096/K (frequency_padding K) to bound the (K n)^2 PSD grid");
  return pupil_n;
}

}  // namespace

AnalyticAoResidual::AnalyticAoResidual(const AnalyticAoOptions& options, Index pupil_n)
    : options_(options), pupil_n_(CheckedPupilN(options, pupil_n, "AnalyticAoResidual")) {
  const Index n = pupil_n_;
  const Index k = options_.frequency_padding;
  const Index grid = k * n;
  const double df = 1.0 / (static_cast<double>(k) * options_.diameter_m);
  psd_ = ComputeResidualPsd(options_, grid, df);
  budget_ = psd_.Budget();

  // C(rho) = df^2 sum_f Phi(f) cos(2 pi f.rho): with f = j df and rho = k D/n, f.rho = j k / (K n), so a
  // DFT of the PSD (zero frequency moved to index 0) gives C on the lattice exactly. Phi is even, so the
  // transform is real; D = 2 (C(0) - C(rho)).
  const Image total = psd_.Total();
  Image shifted(grid, grid);
  const Index c = grid / 2;
  for (Index i = 0; i < grid; ++i)
    for (Index j = 0; j < grid; ++j) shifted((i + grid - c) % grid, (j + grid - c) % grid) = total(i, j);
  const ComplexImage spectrum = FftR2C(shifted);  // grid x (grid/2 + 1)
  const double cell = df * df;
  const double c0 = spectrum(0, 0).real();

  const double f_t = psd_.tail_radius_per_m;
  const double tail = psd_.fitting_tail_rad2;
  const double step = separation_step_m();
  structure_function_.resize(2 * n - 1, 2 * n - 1);
  in_band_structure_function_.resize(2 * n - 1, 2 * n - 1);
  // The tail term depends on |k|^2 = kx^2 + ky^2 only: evaluate q once per distinct integer |k|^2.
  std::vector<double> tail_cache(static_cast<std::size_t>(2 * (n - 1) * (n - 1) + 1), -1.0);
  for (Index ky = -(n - 1); ky <= n - 1; ++ky) {
    for (Index kx = -(n - 1); kx <= n - 1; ++kx) {
      // Real part of X(ky, kx); for kx < 0 use X(-ky, -kx) = conj X(ky, kx) (Hermitian, real signal).
      const Index sy = kx >= 0 ? ky : -ky;
      const Index sx = kx >= 0 ? kx : -kx;
      const double ck = spectrum((sy + grid) % grid, sx).real();
      const std::size_t k2 = static_cast<std::size_t>(kx * kx + ky * ky);
      if (tail_cache[k2] < 0.0) {
        const double rho = step * std::sqrt(static_cast<double>(k2));
        tail_cache[k2] = 2.0 * tail * analytic_ao_internal::TailShape(kTwoPi * f_t * rho);
      }
      const double grid_part = 2.0 * cell * (c0 - ck);
      const double tail_part = tail_cache[k2];
      structure_function_(ky + n - 1, kx + n - 1) = grid_part + tail_part;
      in_band_structure_function_(ky + n - 1, kx + n - 1) = grid_part;
    }
  }
  structure_function_(n - 1, n - 1) = 0.0;
  in_band_structure_function_(n - 1, n - 1) = 0.0;
}

namespace {

PsfSampling CheckedSampling(const AnalyticAoOptions& options, const PsfSampling& sampling) {
  const char* fn = "AnalyticAoPsfCalculator";
  std::string why;
  if (!sampling.IsValid(&why)) throw InvalidArgument(std::string(fn) + ": invalid sampling." + why);
  analytic_ao_internal::CheckOptions(options, fn);
  CheckArgument(
      std::abs(sampling.wavelength_m - options.science_wavelength_m) <= 1e-9 * options.science_wavelength_m,
      fn, "sampling.wavelength_m", sampling.wavelength_m,
      "options.science_wavelength_m = " + ToString(options.science_wavelength_m) +
          " (the residual is computed at the science wavelength)");
  return sampling;
}

MftGeometry LatticeMftGeometry(Index pupil_n, double diameter_m, const PsfSampling& sampling) {
  MftGeometry g;
  g.input = {2 * pupil_n - 1, 2 * pupil_n - 1};
  g.pupil_span_px = static_cast<double>(pupil_n);
  g.output = {sampling.rows, sampling.cols};
  g.pixel_scale_lod = sampling.PixelScaleLambdaOverD(diameter_m);
  return g;
}

}  // namespace

AnalyticAoPsfCalculator::AnalyticAoPsfCalculator(const AnalyticAoOptions& options, Index pupil_n,
                                                 const PsfSampling& sampling)
    : residual_(options, CheckedPupilN(options, pupil_n, "AnalyticAoPsfCalculator")),
      sampling_(CheckedSampling(options, sampling)),
      mft_(LatticeMftGeometry(pupil_n, options.diameter_m, sampling)) {
  // exp(-D_in/2) exp(-sigma_t^2): the fitting tail beyond f_t scatters its light beyond the band the
  // pupil grid represents, so it only attenuates (header section 4).
  attenuation_ =
      (-0.5 * residual_.in_band_structure_function()).exp() * std::exp(-residual_.psd().fitting_tail_rad2);
}

AnalyticAoPsf AnalyticAoPsfCalculator::Compute(const Image& amplitude, const Image& opd_m) const {
  const char* fn = "AnalyticAoPsfCalculator::Compute";
  const Index n = residual_.pupil_n();
  CheckArgument(amplitude.rows() == n && amplitude.cols() == n, fn, "amplitude shape",
                ToString(ShapeOf(amplitude)), ToString(Shape{n, n}) + " (the calculator's pupil grid)");
  CheckArgument(ShapeOf(opd_m) == ShapeOf(amplitude), fn, "opd_m shape", ToString(ShapeOf(opd_m)),
                "the amplitude's shape " + ToString(ShapeOf(amplitude)));
  CheckArgument(amplitude.isFinite().all() && (amplitude >= 0.0).all(), fn, "amplitude",
                "negative or non-finite values", "finite values >= 0");
  const double energy = amplitude.square().sum();
  CheckArgument(energy > 0.0, fn, "amplitude", "all zero", "some pixel > 0 (an open aperture)");

  // Pupil field, zero-padded to 2n so that the autocorrelation (support |k| <= n-1) does not wrap.
  const Index m = 2 * n;
  const double wavenumber = kTwoPi / sampling_.wavelength_m;
  ComplexImage field = ComplexImage::Zero(m, m);
  for (Index i = 0; i < n; ++i) {
    for (Index j = 0; j < n; ++j) {
      const double a = amplitude(i, j);
      if (a <= 0.0) continue;
      const double w = opd_m(i, j);
      CheckArgument(std::isfinite(w), fn, "opd_m", w, "finite values where amplitude > 0");
      field(i, j) = std::polar(a, wavenumber * w);
    }
  }
  // Gamma(k) = sum_u E(u + k) E*(u) = IDFT(|DFT E|^2) (header section 4).
  const ComplexImage spectrum = FftForward(field);
  const ComplexImage gamma = FftInverse(ComplexImage(spectrum.abs2().cast<Complex>()));

  ComplexImage weighted(2 * n - 1, 2 * n - 1);
  Complex on_axis(0.0, 0.0);
  for (Index ky = -(n - 1); ky <= n - 1; ++ky) {
    for (Index kx = -(n - 1); kx <= n - 1; ++kx) {
      const Complex v = gamma((ky + m) % m, (kx + m) % m) * attenuation_(ky + n - 1, kx + n - 1);
      weighted(ky + n - 1, kx + n - 1) = v;
      on_axis += v;
    }
  }
  // PSF = s^2 / sum A^2 * MFT(weighted), the MFT carrying the 1/n^2 (header section 4, psf.hpp).
  const double s = mft_.geometry().pixel_scale_lod;
  AnalyticAoPsf out;
  out.psf = mft_.Apply(weighted).real() * (s * s / energy);
  const double sum_a = amplitude.sum();
  out.strehl = on_axis.real() / (sum_a * sum_a);
  const AnalyticAoErrorBudget& budget = residual_.budget();
  out.residual_variance_rad2 = budget.TotalRad2();
  out.residual_rms_nm = budget.TotalNm();
  return out;
}

AnalyticAoPsf AnalyticAoPsfFromPupil(const AnalyticAoOptions& options, const Image& amplitude,
                                     const Image& opd_m, const PsfSampling& sampling) {
  CheckArgument(amplitude.rows() >= 1 && amplitude.rows() == amplitude.cols(), "AnalyticAoPsfFromPupil",
                "amplitude shape", ToString(ShapeOf(amplitude)), "a square n x n pupil grid");
  return AnalyticAoPsfCalculator(options, amplitude.rows(), sampling).Compute(amplitude, opd_m);
}

}  // namespace aosr
