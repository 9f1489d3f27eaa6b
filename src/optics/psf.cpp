#include "aosr/optics/psf.hpp"

#include <cmath>

#include "aosr/core/error.hpp"

namespace aosr {
namespace {


void CheckDiameter(double diameter_m, const char* function) {
  CheckArgument(std::isfinite(diameter_m) && diameter_m > 0.0, function, "diameter_m", diameter_m,
                "> 0 and finite [m]");
}

// Checks A (finite, >= 0, some > 0) and that w has A's shape and is finite where A > 0. Returns sum A^2.
double CheckPupil(const Image& amplitude, const Image& opd_m, const char* function) {
  CheckArgument(amplitude.size() > 0, function, "amplitude shape", ToString(ShapeOf(amplitude)),
                "a non-empty pupil grid");
  CheckArgument(ShapeOf(opd_m) == ShapeOf(amplitude), function, "opd_m shape", ToString(ShapeOf(opd_m)),
                "the amplitude's shape " + ToString(ShapeOf(amplitude)));
  CheckArgument(amplitude.isFinite().all() && (amplitude >= 0.0).all(), function, "amplitude",
                "negative or non-finite values", "finite values >= 0");
  const double energy = amplitude.square().sum();
  CheckArgument(energy > 0.0, function, "amplitude", "all zero", "some pixel > 0 (an open aperture)");
  for (Index p = 0; p < amplitude.size(); ++p) {
    if (amplitude.data()[p] > 0.0 && !std::isfinite(opd_m.data()[p])) {
      throw InvalidArgument(function, "opd_m", ToString(opd_m.data()[p]),
                            "finite values where amplitude > 0");
    }
  }
  return energy;
}

}  // namespace

bool PsfSampling::IsValid(std::string* why) const {
  std::string msg;
  if (!(std::isfinite(wavelength_m) && wavelength_m > 0.0)) {
    msg = "wavelength_m = " + ToString(wavelength_m) + "; allowed: > 0 and finite [m]";
  } else if (!(std::isfinite(pixel_scale_rad) && pixel_scale_rad > 0.0)) {
    msg = "pixel_scale_rad = " + ToString(pixel_scale_rad) + "; allowed: > 0 and finite [rad]";
  } else if (rows < 1) {
    msg = "rows = " + ToString(rows) + "; allowed: >= 1";
  } else if (cols < 1) {
    msg = "cols = " + ToString(cols) + "; allowed: >= 1";
  }
  if (msg.empty()) return true;
  if (why != nullptr) *why = msg;
  return false;
}

namespace {

MftGeometry PsfMftGeometry(Index pupil_n, double diameter_m, const PsfSampling& sampling) {
  CheckArgument(pupil_n >= 1, "PsfCalculator", "pupil_n", pupil_n, ">= 1");
  CheckDiameter(diameter_m, "PsfCalculator");
  std::string why;
  if (!sampling.IsValid(&why)) throw InvalidArgument("PsfCalculator: invalid sampling." + why);
  MftGeometry g;
  g.input = {pupil_n, pupil_n};
  g.pupil_span_px = static_cast<double>(pupil_n);
  g.output = {sampling.rows, sampling.cols};
  g.pixel_scale_lod = sampling.PixelScaleLambdaOverD(diameter_m);
  return g;
}

}  // namespace

PsfCalculator::PsfCalculator(Index pupil_n, double diameter_m, const PsfSampling& sampling)
    : pupil_n_(pupil_n),
      diameter_m_(diameter_m),
      sampling_(sampling),
      mft_(PsfMftGeometry(pupil_n, diameter_m, sampling)) {}

Image PsfCalculator::Compute(const Image& amplitude, const Image& opd_m) const {
  CheckArgument(amplitude.rows() == pupil_n_ && amplitude.cols() == pupil_n_, "PsfCalculator::Compute",
                "amplitude shape", ToString(ShapeOf(amplitude)),
                std::to_string(pupil_n_) + "x" + std::to_string(pupil_n_) + " (the calculator's pupil grid)");
  const double energy = CheckPupil(amplitude, opd_m, "PsfCalculator::Compute");
  const double k = kTwoPi / sampling_.wavelength_m;
  ComplexImage field(pupil_n_, pupil_n_);
  for (Index p = 0; p < field.size(); ++p) {
    const double a = amplitude.data()[p];
    field.data()[p] = a > 0.0 ? std::polar(a, k * opd_m.data()[p]) : Complex(0.0, 0.0);
  }
  // |out|^2 s^2 / (pupil energy in D^2 units = sum A^2 / n^2); the MFT already divides by n^2.
  const double s = mft_.geometry().pixel_scale_lod;
  const double n2 = static_cast<double>(pupil_n_) * static_cast<double>(pupil_n_);
  const double scale = s * s * n2 / energy;
  Image psf = mft_.Apply(field).abs2() * scale;
  return psf;
}

Image PsfFromPupil(const Image& amplitude, const Image& opd_m, double diameter_m,
                   const PsfSampling& sampling) {
  CheckArgument(amplitude.rows() >= 1 && amplitude.rows() == amplitude.cols(), "PsfFromPupil",
                "amplitude shape", ToString(ShapeOf(amplitude)), "square n x n pupil grid, n >= 1");
  CheckArgument(ShapeOf(opd_m) == ShapeOf(amplitude), "PsfFromPupil", "opd_m shape", ToString(ShapeOf(opd_m)),
                "the amplitude's shape " + ToString(ShapeOf(amplitude)));
  CheckDiameter(diameter_m, "PsfFromPupil");
  std::string why;
  if (!sampling.IsValid(&why)) throw InvalidArgument("PsfFromPupil: invalid sampling." + why);
  return PsfCalculator(amplitude.rows(), diameter_m, sampling).Compute(amplitude, opd_m);
}

Image NormaliseToUnitSum(const Image& kernel) {
  CheckArgument(kernel.size() > 0, "NormaliseToUnitSum", "kernel shape", ToString(ShapeOf(kernel)),
                "non-empty");
  CheckArgument(kernel.isFinite().all(), "NormaliseToUnitSum", "kernel", "non-finite values",
                "finite values");
  const double sum = kernel.sum();
  CheckArgument(sum > 0.0, "NormaliseToUnitSum", "kernel sum", sum, "> 0");
  return kernel / sum;
}

double StrehlFromPupil(const Image& amplitude, const Image& opd_m, double wavelength_m) {
  CheckArgument(std::isfinite(wavelength_m) && wavelength_m > 0.0, "StrehlFromPupil", "wavelength_m",
                wavelength_m, "> 0 and finite [m]");
  CheckPupil(amplitude, opd_m, "StrehlFromPupil");
  const double k = kTwoPi / wavelength_m;
  double re = 0.0, im = 0.0, sum_a = 0.0;
  for (Index p = 0; p < amplitude.size(); ++p) {
    const double a = amplitude.data()[p];
    if (a <= 0.0) continue;
    const double phi = k * opd_m.data()[p];
    re += a * std::cos(phi);
    im += a * std::sin(phi);
    sum_a += a;
  }
  return (re * re + im * im) / (sum_a * sum_a);
}

bool SpectralBand::IsValid(std::string* why) const {
  std::string msg;
  if (wavelengths_m.empty()) {
    msg = "wavelengths_m = (empty); allowed: at least one wavelength";
  } else if (weights.size() != wavelengths_m.size()) {
    msg = "weights = (" + std::to_string(weights.size()) + " values); allowed: one per wavelength (" +
          std::to_string(wavelengths_m.size()) + ")";
  }
  double sum = 0.0;
  for (std::size_t k = 0; msg.empty() && k < wavelengths_m.size(); ++k) {
    if (!(std::isfinite(wavelengths_m[k]) && wavelengths_m[k] > 0.0)) {
      msg = "wavelengths_m[" + std::to_string(k) + "] = " + ToString(wavelengths_m[k]) +
            "; allowed: > 0 and finite [m]";
    } else if (!(std::isfinite(weights[k]) && weights[k] >= 0.0)) {
      msg = "weights[" + std::to_string(k) + "] = " + ToString(weights[k]) + "; allowed: >= 0 and finite";
    } else {
      sum += weights[k];
    }
  }
  if (msg.empty() && !(sum > 0.0)) msg = "weights = (all zero); allowed: sum > 0";
  if (msg.empty()) return true;
  if (why != nullptr) *why = msg;
  return false;
}

SpectralBand UniformBand(double centre_m, double width_m, int samples) {
  CheckArgument(std::isfinite(centre_m) && centre_m > 0.0, "UniformBand", "centre_m", centre_m,
                "> 0 and finite [m]");
  CheckArgument(std::isfinite(width_m) && width_m >= 0.0 && width_m < 2.0 * centre_m, "UniformBand",
                "width_m", width_m, ">= 0 and < 2 centre_m [m]");
  CheckArgument(samples >= 1, "UniformBand", "samples", samples, ">= 1");
  SpectralBand band;
  for (int k = 0; k < samples; ++k) {
    band.wavelengths_m.push_back(centre_m + width_m * ((k + 0.5) / samples - 0.5));
    band.weights.push_back(1.0);
  }
  return band;
}

namespace {

std::vector<PsfCalculator> BandCalculators(Index pupil_n, double diameter_m, const SpectralBand& band,
                                           double pixel_scale_rad, Index rows, Index cols) {
  std::string why;
  if (!band.IsValid(&why)) throw InvalidArgument("BandPsfCalculator: invalid band." + why);
  CheckArgument(pupil_n >= 1, "BandPsfCalculator", "pupil_n", pupil_n, ">= 1");
  CheckDiameter(diameter_m, "BandPsfCalculator");
  CheckArgument(std::isfinite(pixel_scale_rad) && pixel_scale_rad > 0.0, "BandPsfCalculator",
                "pixel_scale_rad", pixel_scale_rad, "> 0 and finite [rad]");
  CheckArgument(rows >= 1, "BandPsfCalculator", "rows", rows, ">= 1");
  CheckArgument(cols >= 1, "BandPsfCalculator", "cols", cols, ">= 1");
  std::vector<PsfCalculator> calculators;
  calculators.reserve(band.wavelengths_m.size());
  for (double lambda : band.wavelengths_m) {
    calculators.emplace_back(pupil_n, diameter_m, PsfSampling{lambda, pixel_scale_rad, rows, cols});
  }
  return calculators;
}

}  // namespace

BandPsfCalculator::BandPsfCalculator(Index pupil_n, double diameter_m, const SpectralBand& band,
                                     double pixel_scale_rad, Index rows, Index cols)
    : band_(band), calculators_(BandCalculators(pupil_n, diameter_m, band, pixel_scale_rad, rows, cols)) {
  double sum = 0.0;
  for (double w : band_.weights) sum += w;
  for (double w : band_.weights) weights_.push_back(w / sum);
}

BandPsf BandPsfCalculator::Compute(const Image& amplitude, const Image& opd_m) const {
  BandPsf out;
  double num = 0.0, den = 0.0;
  for (std::size_t k = 0; k < calculators_.size(); ++k) {
    // PsfCalculator::Compute validates the shapes and values (its messages name it).
    Image psf_k = calculators_[k].Compute(amplitude, opd_m);
    if (k == 0) {
      out.psf = weights_[k] * psf_k;
    } else {
      out.psf += weights_[k] * psf_k;
    }
    const double lambda = band_.wavelengths_m[k];
    const double strehl = StrehlFromPupil(amplitude, opd_m, lambda);
    out.strehl.push_back(strehl);
    num += weights_[k] / (lambda * lambda) * strehl;
    den += weights_[k] / (lambda * lambda);
  }
  out.band_strehl = num / den;
  return out;
}

double PeakStrehl(const Image& psf, const Image& reference_psf) {
  CheckArgument(psf.size() > 0 && psf.isFinite().all(), "PeakStrehl", "psf", ToString(ShapeOf(psf)),
                "a non-empty image of finite values");
  CheckArgument(reference_psf.size() > 0 && reference_psf.isFinite().all(), "PeakStrehl", "reference_psf",
                ToString(ShapeOf(reference_psf)), "a non-empty image of finite values");
  const double ref_max = reference_psf.maxCoeff();
  CheckArgument(ref_max > 0.0, "PeakStrehl", "reference_psf maximum", ref_max, "> 0");
  return psf.maxCoeff() / ref_max;
}

}  // namespace aosr
