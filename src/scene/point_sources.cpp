#include "aosr/scene/point_sources.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>

#include "aosr/core/error.hpp"
#include "aosr/core/fft.hpp"
#include "aosr/core/operators.hpp"

namespace aosr {
namespace {

constexpr Index kStarBlock = 256;

void CheckGrid(const std::string& function, Shape hr) {
  CheckArgument(hr.rows >= 1 && hr.cols >= 1, function, "hr", ToString(hr), "rows and cols >= 1");
}

void CheckSources(const std::string& function, Shape hr, const std::vector<PointSource>& sources) {
  for (std::size_t k = 0; k < sources.size(); ++k) {
    const PointSource& s = sources[k];
    const std::string name = "sources[" + std::to_string(k) + "]";
    CheckArgument(std::isfinite(s.flux) && s.flux >= 0.0, function, name + ".flux", s.flux,
                  "finite and >= 0");
    CheckArgument(std::isfinite(s.y) && s.y >= -0.5 && s.y <= hr.rows - 0.5, function, name + ".y", s.y,
                  "[-0.5, rows - 0.5] = [-0.5, " + ToString(hr.rows - 0.5) + "]");
    CheckArgument(std::isfinite(s.x) && s.x >= -0.5 && s.x <= hr.cols - 0.5, function, name + ".x", s.x,
                  "[-0.5, cols - 0.5] = [-0.5, " + ToString(hr.cols - 0.5) + "]");
  }
}

// e^{-2πi f t / n} for the frequencies f of bins 0 .. bins-1 of an n-point transform (signed:
// SignedFrequency), with cos(πt) at the Nyquist bin of an even n (the symmetric convention of
// point_sources.hpp). The phase is reduced modulo n in exact arithmetic on (f t mod n) to keep it accurate
// for large f t.
void Exponentials(double t, Index n, Index bins, Complex* out) {
  for (Index k = 0; k < bins; ++k) {
    const Index f = SignedFrequency(k, n);
    if (n % 2 == 0 && 2 * k == n) {
      out[k] = Complex(std::cos(M_PI * t), 0.0);
      continue;
    }
    const double turns =
        std::fmod(static_cast<double>(f) * t, static_cast<double>(n)) / static_cast<double>(n);
    const double phase = -2.0 * M_PI * turns;
    out[k] = Complex(std::cos(phase), std::sin(phase));
  }
}

// S without validation.
ComplexImage Spectrum(Shape hr, const std::vector<PointSource>& sources) {
  const Index half = hr.cols / 2 + 1;
  Eigen::MatrixXcd s = Eigen::MatrixXcd::Zero(hr.rows, half);
  const Index k_total = static_cast<Index>(sources.size());
  for (Index k0 = 0; k0 < k_total; k0 += kStarBlock) {
    const Index kb = std::min(kStarBlock, k_total - k0);
    // Column-major E_y (rows x kb) scaled by flux, and E_x as (kb x half).
    Eigen::MatrixXcd ey(hr.rows, kb);
    Eigen::Matrix<Complex, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> ex(kb, half);
    for (Index j = 0; j < kb; ++j) {
      const PointSource& p = sources[k0 + j];
      Exponentials(p.y, hr.rows, hr.rows, ey.col(j).data());
      ey.col(j) *= p.flux;
      Exponentials(p.x, hr.cols, half, ex.row(j).data());
    }
    s.noalias() += ey * ex;
  }
  ComplexImage out(hr.rows, half);
  for (Index u = 0; u < hr.rows; ++u)
    for (Index v = 0; v < half; ++v) out(u, v) = s(u, v);
  return out;
}

void CheckOtf(const std::string& function, Shape hr, const ComplexImage& otf_half) {
  const Shape want{hr.rows, hr.cols / 2 + 1};
  if (ShapeOf(otf_half) != want)
    throw InvalidArgument(function, "otf_half shape", ToString(ShapeOf(otf_half)),
                          ToString(want) + " (the half spectrum of hr = " + ToString(hr) + ")");
  CheckArgument(otf_half.isFinite().all(), function, "otf_half", "non-finite values", "finite values");
}

}  // namespace

ComplexImage PointSourceSpectrum(Shape hr, const std::vector<PointSource>& sources) {
  CheckGrid("PointSourceSpectrum", hr);
  CheckSources("PointSourceSpectrum", hr, sources);
  return Spectrum(hr, sources);
}

Image PointSourceImage(Shape hr, const std::vector<PointSource>& sources) {
  CheckGrid("PointSourceImage", hr);
  CheckSources("PointSourceImage", hr, sources);
  return FftC2R(Spectrum(hr, sources), hr.cols);
}

Image RenderPointSources(Shape hr, const std::vector<PointSource>& sources, const ComplexImage& otf_half) {
  const std::string fn = "RenderPointSources";
  CheckGrid(fn, hr);
  CheckOtf(fn, hr, otf_half);
  CheckSources(fn, hr, sources);
  const ComplexImage product = HermitianProjection(otf_half, hr.cols) * Spectrum(hr, sources);
  return FftC2R(product, hr.cols);
}

ImageStack RenderPointSourceFrames(const MultiFrameModel& model, const std::vector<PointSource>& sources) {
  const std::string fn = "RenderPointSourceFrames";
  const Shape hr = model.hr_shape();
  CheckSources(fn, hr, sources);
  const ComplexImage s = Spectrum(hr, sources);
  const OperatorPtr decimate = Decimate(hr, model.r());
  const Shape lr = model.lr_shape();
  ImageStack frames;
  frames.reserve(model.frames());
  for (int i = 0; i < model.frames(); ++i) {
    const Image z = FftC2R(HermitianProjection(model.otf(i), hr.cols) * s, hr.cols);
    frames.push_back(ToImage(decimate->Apply(AsVector(z)), lr));
  }
  return frames;
}

}  // namespace aosr
