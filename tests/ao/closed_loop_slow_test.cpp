// Longer, more precise closed-loop runs of the paper's system (label slow, not run in CI): several seeds of
// 1 s each against the analytic model, the sensors side by side (ideal, geometric SH, diffractive SH at
// several samplings), integrator against pseudo-open-loop, and sub-exposures with DM offsets. Each test
// prints its figures; tolerances are stated at the checks.
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <vector>

#include "aosr/ao/analytic_ao.hpp"
#include "aosr/ao/closed_loop.hpp"
#include "aosr/optics/psf.hpp"
#include "aosr/optics/zernike.hpp"
#include "loop_fixture.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

using test::KBandScience;
using test::kPaperDiameter;
using test::MakePaperSystem;
using test::SensorKind;

struct LoopRun {
  double strehl = 0.0;
  double residual_nm = 0.0;
  double ms_per_frame = 0.0;
};

// One closed-loop run of the paper system with the given sensor (options), 0.2 s settling + `seconds`.
LoopRun RunPaper(SensorKind kind, const ShackHartmannOptions* sensor, const ControllerOptions& control,
                 std::uint64_t seed, double seconds, int psf_every) {
  test::LoopSystem s = MakePaperSystem(kind, true, seed, control);
  if (sensor != nullptr) {  // replace the sensor and recalibrate
    s.wfs = std::make_unique<ShackHartmann>(s.amplitude, kPaperDiameter, *sensor);
    s.interaction_matrix = MeasureInteractionMatrix(*s.dm, s.wfs.get());
    s.control_matrix = ComputeControlMatrix(s.interaction_matrix);
    s.controller = std::make_unique<Controller>(s.control_matrix.matrix, s.interaction_matrix, control);
  }
  ClosedLoop loop(s.amplitude, kPaperDiameter, s.atmosphere.get(), s.dm, s.wfs.get(), s.controller.get(),
                  KBandScience(psf_every));
  const auto t0 = std::chrono::steady_clock::now();
  const ClosedLoopResult r = loop.Run(seconds, 0.2);
  const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  LoopRun out;
  out.strehl = r.long_exposure_strehl;
  out.residual_nm = r.RmsResidualM() * 1e9;
  out.ms_per_frame = 1e3 * wall / (r.steps + r.settling_steps);
  return out;
}

TEST(ClosedLoopSlowTest, IdealSensorMatchesTheAnalyticModel) {
  // Three seeds x 1 s (800 frames, PSF every 2nd): the mean long-exposure K-band Strehl within 0.015 of the
  // analytic model without aliasing, each seed within 0.025.
  ControllerOptions control;  // gain 0.35, 1 frame of delay, 800 Hz
  const ClosedLoopOptions science = KBandScience();
  AnalyticAoPsfCalculator analytic(test::PaperAnalytic(control, false), 128, science.science);
  const double model =
      analytic.Compute(CircularPupil(128, PupilGeometry{kPaperDiameter, 0.0}), Image::Zero(128, 128)).strehl;
  double mean = 0.0;
  for (std::uint64_t seed : {21, 22, 23}) {
    const LoopRun r = RunPaper(SensorKind::kIdeal, nullptr, control, seed, 1.0, 2);
    std::printf("ideal, seed %lu: LE Strehl %.4f (analytic %.4f), residual %.1f nm, %.3f ms/frame\n",
                static_cast<unsigned long>(seed), r.strehl, model, r.residual_nm, r.ms_per_frame);
    EXPECT_NEAR(r.strehl, model, 0.025);
    mean += r.strehl / 3.0;
  }
  std::printf("ideal: mean %.4f, analytic %.4f\n", mean, model);
  EXPECT_NEAR(mean, model, 0.015);
}

TEST(ClosedLoopSlowTest, SensorsSideBySide) {
  // Same atmosphere seed for every sensor, 1 s. Printed: LE Strehl per sensor and sampling. Checks: the
  // geometric SH within 0.03 of the analytic model with aliasing; the paper's diffractive SH in 0.6 - 0.87.
  ControllerOptions control;
  const ClosedLoopOptions science = KBandScience();
  AnalyticAoPsfCalculator alias(test::PaperAnalytic(control, true), 128, science.science);
  const double model_alias =
      alias.Compute(CircularPupil(128, PupilGeometry{kPaperDiameter, 0.0}), Image::Zero(128, 128)).strehl;
  const std::uint64_t seed = 31;
  const LoopRun geometric = RunPaper(SensorKind::kGeometric, nullptr, control, seed, 1.0, 4);
  std::printf("geometric SH: LE Strehl %.4f (analytic with aliasing %.4f), residual %.1f nm, %.3f ms/frame\n",
              geometric.strehl, model_alias, geometric.residual_nm, geometric.ms_per_frame);
  EXPECT_NEAR(geometric.strehl, model_alias, 0.03);
  struct Variant {
    const char* name;
    double scale;
    int fov;
    double threshold;
  };
  for (const Variant& v :
       {Variant{"Nyquist 16 px (paper)", 0.5, 16, 0.0}, Variant{"2x Nyquist 32 px", 0.25, 32, 0.0},
        Variant{"Nyquist 16 px, threshold 0.1", 0.5, 16, 0.1}, Variant{"Nyquist 12 px", 0.5, 12, 0.0}}) {
    ShackHartmannOptions so = test::PaperSensor(ShackHartmannMode::kDiffractive);
    so.pixel_scale_lod = v.scale;
    so.field_of_view_px = v.fov;
    so.threshold_fraction = v.threshold;
    const LoopRun r = RunPaper(SensorKind::kDiffractive, &so, control, seed, 1.0, 4);
    std::printf("diffractive SH, %s: LE Strehl %.4f, residual %.1f nm, %.3f ms/frame\n", v.name, r.strehl,
                r.residual_nm, r.ms_per_frame);
    if (v.fov == 16 && v.threshold == 0.0) {
      EXPECT_GT(r.strehl, 0.6);
      EXPECT_LT(r.strehl, 0.87);
    }
  }
}

TEST(ClosedLoopSlowTest, IntegratorAndPseudoOpenLoop) {
  // Gain 0.35 and 0.6 with one frame of delay, geometric SH, 0.5 s: printed. With a perfect model POL matches
  // the integrator at low gain and stays stable where the integrator's margin shrinks. Check: both laws
  // within 0.03 of each other at g = 0.35.
  double strehl[2] = {0.0, 0.0};
  for (double gain : {0.35, 0.6}) {
    for (ControlLaw law : {ControlLaw::kIntegrator, ControlLaw::kPseudoOpenLoop}) {
      ControllerOptions control;
      control.gain = gain;
      control.law = law;
      const LoopRun r = RunPaper(SensorKind::kGeometric, nullptr, control, 41, 0.5, 4);
      std::printf("geometric SH, %s, gain %.2f: LE Strehl %.4f, residual %.1f nm\n",
                  law == ControlLaw::kIntegrator ? "integrator" : "POL", gain, r.strehl, r.residual_nm);
      if (gain == 0.35) strehl[law == ControlLaw::kIntegrator ? 0 : 1] = r.strehl;
    }
  }
  EXPECT_NEAR(strehl[0], strehl[1], 0.03);
}

TEST(ClosedLoopSlowTest, SubExposuresWithDmOffsets) {
  // Three sub-exposures of 0.25 s with tip/tilt offsets of 0, +1 and -1 lambda/D at 2.2 um along x, 20 ms of
  // settling each, diffractive SH (Nyquist, 16 px), with the offsets' reference slopes taken on a flat
  // wavefront (OffsetCalibration::kFlat) and calibrated on sky (kOnSky, the default). Checks: the
  // long-exposure PSF's centroid moves by the offset within 0.15 lambda/D, and its peak (the offset moves it by
  // ~2 pixels) stays within 8% of the unshifted exposure's (each exposure sees 0.25 s of different turbulence:
  // measured 0.84, 0.85, 0.84). The on-axis Strehl is not the figure here: the offset moves the peak off
  // axis. The mean shift magnitude: kFlat 1.0 .. 1.15 (measured +1.14, -1.05 lambda/D: the offset slopes are
  // computed on the diffraction-limited spot, whose small-tilt centroid gain is 1.035, while in closed loop
  // the spots are broadened by the residual and the gain is lower, ~0.87, so the loop needs a larger tilt to
  // reach them: the SH's "optical gain"); kOnSky 0.9 .. 1.05 (measured +0.985, -0.908: the probe measures the
  // small-signal gain, and a 1 lambda/D offset moves the R-band spots by 0.2 of their width, where the
  // truncated centroid's gain is a little lower; each 0.25 s exposure also carries its own random tilt of a
  // few 0.01).
  for (OffsetCalibration calibration : {OffsetCalibration::kFlat, OffsetCalibration::kOnSky}) {
    const bool flat = calibration == OffsetCalibration::kFlat;
    ControllerOptions control;
    test::LoopSystem s = MakePaperSystem(SensorKind::kDiffractive, true, 51, control);
    ClosedLoopOptions options = KBandScience(2);
    options.offset_calibration = calibration;
    ClosedLoop loop(s.amplitude, kPaperDiameter, s.atmosphere.get(), s.dm, s.wfs.get(), s.controller.get(),
                    options);
    const double lod = 2.2e-6 / kPaperDiameter;
    std::vector<Image> offsets;
    for (double shift : {0.0, 1.0, -1.0}) {
      offsets.push_back(TiltCoefficientForShift(shift * lod, kPaperDiameter) * ZernikeUnmasked(2, 128));
    }
    const std::vector<ClosedLoopResult> r = loop.RunSubExposures(offsets, 0.25, 0.02);
    ASSERT_EQ(r.size(), 3u);
    const double pixel_lod = options.science.PixelScaleLambdaOverD(kPaperDiameter);
    const Image perfect =
        PsfCalculator(128, kPaperDiameter, options.science).Compute(s.amplitude, Image::Zero(128, 128));
    double centroid[3], peak[3];
    for (int i = 0; i < 3; ++i) {
      const Image& psf = r[i].psf;
      double sum = 0.0, cx = 0.0;
      for (Index y = 0; y < psf.rows(); ++y) {
        for (Index x = 0; x < psf.cols(); ++x) {
          sum += psf(y, x);
          cx += psf(y, x) * (x - psf.cols() / 2);
        }
      }
      centroid[i] = cx / sum * pixel_lod;
      peak[i] = PeakStrehl(psf, perfect);
      std::printf("%s: sub-exposure %d: %s; tilt gain %.3f, %.3f; PSF centroid x %.3f lambda/D, peak Strehl %.4f\n",
                  flat ? "flat" : "on-sky", i, r[i].BriefReport().c_str(), r[i].tilt_gain[0], r[i].tilt_gain[1],
                  centroid[i], peak[i]);
    }
    EXPECT_NEAR(centroid[1] - centroid[0], 1.0, 0.15);
    EXPECT_NEAR(centroid[2] - centroid[0], -1.0, 0.15);
    EXPECT_GT(0.5 * (centroid[1] - centroid[2]), flat ? 1.0 : 0.9);
    EXPECT_LT(0.5 * (centroid[1] - centroid[2]), flat ? 1.15 : 1.05);
    EXPECT_NEAR(peak[1] / peak[0], 1.0, 0.08);
    EXPECT_NEAR(peak[2] / peak[0], 1.0, 0.08);
  }
}

}  // namespace
}  // namespace aosr
