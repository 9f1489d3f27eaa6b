// The modal image model (derivatives against central differences, flux and pixel integration) and the fit on
// noiseless data.
#include "aosr/calib/modal_fit.hpp"

#include <gtest/gtest.h>

#include <cmath>

#include "aosr/optics/psf.hpp"
#include "aosr/optics/pupil.hpp"
#include "aosr/optics/zernike.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

CalibrationOptics BenchOptics() {
  CalibrationOptics o;
  o.wavelength_m = 635e-9;
  o.pixel_lambda_over_d = 0.3115;
  o.pupil_px = 64;
  return o;
}

ModalImageParameters SomeParameters() {
  ModalImageParameters p;
  p.amplitude_m = 40e-9;
  p.dy_px = 0.3, p.dx_px = -0.45;
  p.static_m = {20e-9, -10e-9, 8e-9};
  p.source_sigma_px = 0.5;
  p.flux = 1e5;
  p.background = 3.0;
  return p;
}

double MaxAbs(const Image& a) { return a.abs().maxCoeff(); }

// Every analytic derivative agrees with a central difference of Render to ~1e-5 of its size.
TEST(ModalImageModel, DerivativesMatchCentralDifferences) {
  const CalibrationOptics o = BenchOptics();
  const ModalImageModel model(o, Zernike(7, 64), {4, 5, 6}, {24, 28}, 6);
  const ModalImageParameters p = SomeParameters();
  ModalImageModel::Request req{true, true, true, true, true};
  ModalImageModel::Derivatives d;
  (void)model.RenderWithDerivatives(p, req, &d);
  const double rpm = model.RadiansPerMetre();
  auto check = [&](const char* name, const Image& analytic, auto perturb, double h) {
    ModalImageParameters a = p, b = p;
    perturb(a, +h);
    perturb(b, -h);
    const Image fd = (model.Render(a) - model.Render(b)) / (2 * h);
    EXPECT_LT(MaxAbs(fd - analytic), 2e-5 * MaxAbs(analytic)) << name;
  };
  check("amplitude", d.d_amplitude_rad, [&](ModalImageParameters& q, double h) { q.amplitude_m += h / rpm; }, 1e-4);
  check("dy", d.d_dy, [](ModalImageParameters& q, double h) { q.dy_px += h; }, 1e-4);
  check("dx", d.d_dx, [](ModalImageParameters& q, double h) { q.dx_px += h; }, 1e-4);
  for (int k = 0; k < 3; ++k)
    check("static", d.d_static_rad[k], [&](ModalImageParameters& q, double h) { q.static_m[k] += h / rpm; }, 1e-4);
  check("variance", d.d_variance,
        [](ModalImageParameters& q, double h) { q.source_sigma_px = std::sqrt(q.source_sigma_px * q.source_sigma_px + h); }, 1e-4);
  check("flux", d.d_flux, [](ModalImageParameters& q, double h) { q.flux += h; }, 1.0);
}

// The camera image integrates the PSF over each pixel: compare with a direct PSF on a 5x finer grid summed in
// 5x5 blocks (point source, no blur).
TEST(ModalImageModel, PixelIntegrationMatchesAFineGridSum) {
  const CalibrationOptics o = BenchOptics();
  const Shape w{20, 20};
  const ModalImageModel model(o, Zernike(4, 64), {}, w, 10);
  ModalImageParameters p;
  p.amplitude_m = 30e-9;
  p.flux = 1.0;
  const Image m = model.Render(p);
  const int f = 5;
  PsfSampling s;
  s.wavelength_m = o.wavelength_m;
  s.pixel_scale_rad = o.pixel_lambda_over_d / f * o.wavelength_m / 1.0;  // D = 1 m
  s.rows = s.cols = w.rows * f;
  const Image pupil = CircularPupil(64, PupilGeometry{1.0, 0.0}, 1);
  const Image psf = PsfFromPupil(pupil, Image(30e-9 * Zernike(4, 64)), 1.0, s);
  // Fine pixel (w*f/2) is the axis; camera pixel w/2 is centred on it: block of camera pixel Y spans fine rows
  // f*Y - (f-1)/2 + ... i.e. starting at f*Y + (f*w/2 - f*(w/2)) - f/2.
  Image binned = Image::Zero(w.rows, w.cols);
  for (Index y = 0; y < w.rows * f; ++y)
    for (Index x = 0; x < w.cols * f; ++x) {
      const Index Y = (y + f / 2) / f, X = (x + f / 2) / f;
      if (Y < w.rows && X < w.cols) binned(Y, X) += psf(y, x);
    }
  const double peak = m.maxCoeff();
  EXPECT_NEAR(m(10, 10), binned(10, 10), 2e-3 * peak);
  EXPECT_LT(MaxAbs((m - binned).block(2, 2, 16, 16)), 5e-3 * peak);
  EXPECT_NEAR(m.sum(), binned.sum(), 5e-3);
}

// Noiseless images with known gain, static aberration, position and size: the fit returns them.
TEST(FitModalImages, RecoversTheTruthFromNoiselessImages) {
  const CalibrationOptics o = BenchOptics();
  const Shape w{32, 32};
  const Image z = Zernike(6, 64);
  const ModalImageModel truth(o, z, {4, 5, 6, 7, 8}, w, 8);
  const double g = 0.83;
  std::vector<Image> frames;
  std::vector<double> amps = {0.0, 30e-9, -30e-9, 60e-9, -60e-9};
  for (double a : amps) {
    ModalImageParameters p;
    p.amplitude_m = g * a;
    p.dy_px = 0.2, p.dx_px = -0.3;
    p.static_m = {15e-9, -10e-9, 5e-9, 8e-9, -6e-9};
    p.source_sigma_px = 0.4;
    p.flux = 2e5;
    p.background = 10;
    frames.push_back(truth.Render(p));
  }
  std::vector<ModalFitImage> images;
  for (std::size_t i = 0; i < frames.size(); ++i) images.push_back({&frames[i], nullptr, amps[i]});
  NoiseModelParameters noise{1.0, 5.0};
  ModalFitOptions opt;
  opt.source_sigma_px = 0.2;
  const ModalFitResult r = FitModalImages(o, z, images, noise, opt);
  ASSERT_NE(r.termination, Termination::kFailed) << r.message;
  EXPECT_NEAR(r.gain, g, 1e-5) << r.message;
  EXPECT_NEAR(r.dy_px, 0.2, 1e-4);
  EXPECT_NEAR(r.dx_px, -0.3, 1e-4);
  EXPECT_NEAR(r.static_m[0], 15e-9, 1e-11);
  EXPECT_NEAR(r.source_sigma_px, 0.4, 1e-3);
  EXPECT_LT(r.reduced_chi2, 1e-6);
  EXPECT_GT(r.gain_sigma, 0.0);
  std::printf("noiseless fit: %d iterations, %.3f s; %s\n", r.iterations, r.seconds, r.message.c_str());
}

}  // namespace
}  // namespace aosr
