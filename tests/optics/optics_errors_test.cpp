// Bad input at every public optics entry point throws aosr::InvalidArgument naming the argument.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <limits>
#include <string>

#include "aosr/core/error.hpp"
#include "aosr/optics/mft.hpp"
#include "aosr/optics/psf.hpp"
#include "aosr/optics/pupil.hpp"
#include "aosr/optics/zernike.hpp"
#include "support/testing.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

using aosr::test::ErrorOf;

using ::testing::HasSubstr;


constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

TEST(OpticsErrorsTest, NollIndexBelowOne) {
  EXPECT_THAT(ErrorOf([] { NollToNM(0); }), HasSubstr("NollToNM: invalid j = 0"));
  EXPECT_THAT(ErrorOf([] { ZernikeValue(-3, 0.5, 0.0); }), HasSubstr("ZernikeValue: invalid j = -3"));
  EXPECT_THAT(ErrorOf([] { Zernike(0, 32); }), HasSubstr("Zernike: invalid j"));
  EXPECT_THAT(ErrorOf([] { ZernikeUnmasked(0, 32); }), HasSubstr("ZernikeUnmasked: invalid j"));
  EXPECT_THAT(ErrorOf([] { ZernikeBasis(0, 32); }), HasSubstr("ZernikeBasis: invalid J"));
  EXPECT_THAT(ErrorOf([] { ProjectOntoZernike(Image::Zero(8, 8), Image::Ones(8, 8), 0); }),
              HasSubstr("ProjectOntoZernike: invalid J"));
  EXPECT_THAT(ErrorOf([] { NMToNoll(3, 2); }), HasSubstr("NMToNoll: invalid (n, m) = (3, 2)"));
  EXPECT_THAT(ErrorOf([] { ZernikeRadial(4, 6, 0.5); }), HasSubstr("ZernikeRadial: invalid (n, m)"));
  EXPECT_THAT(ErrorOf([] { ZernikeValue(4, -0.1, 0.0); }), HasSubstr("invalid rho"));
}

TEST(OpticsErrorsTest, NegativeOrZeroDiameter) {
  EXPECT_THAT(ErrorOf([] {
                CircularPupil(32, PupilGeometry{-1.0, 0.0});
              }),
              HasSubstr("CircularPupil: invalid geometry.diameter_m = -1"));
  EXPECT_THAT(ErrorOf([] { TiltCoefficientForShift(1e-7, -8.0); }),
              HasSubstr("TiltCoefficientForShift: invalid diameter_m = -8"));
  EXPECT_THAT(ErrorOf([] { ShiftForTiltCoefficient(1e-7, 0.0); }),
              HasSubstr("ShiftForTiltCoefficient: invalid diameter_m = 0"));
  const Image a = Image::Ones(16, 16);
  EXPECT_THAT(ErrorOf([&] {
                PsfFromPupil(a, a * 0.0, -2.0, PsfSampling{1e-6, 1e-8, 8, 8});
              }),
              HasSubstr("PsfFromPupil: invalid diameter_m = -2"));
  EXPECT_THAT(ErrorOf([] {
                PsfCalculator(16, kNaN, PsfSampling{1e-6, 1e-8, 8, 8});
              }),
              HasSubstr("PsfCalculator: invalid diameter_m = nan"));
}

TEST(OpticsErrorsTest, ObstructionOutOfRange) {
  EXPECT_THAT(ErrorOf([] {
                CircularPupil(32, PupilGeometry{8.0, 1.0});
              }),
              HasSubstr("CircularPupil: invalid geometry.obstruction = 1"));
  EXPECT_THAT(ErrorOf([] { CircularPupil(32, PupilGeometry{8.0, -0.2}); }), HasSubstr("obstruction = -0.2"));
  EXPECT_THAT(ErrorOf([] { Zernike(4, 32, 1.5); }), HasSubstr("Zernike: invalid obstruction = 1.5"));
  EXPECT_THAT(ErrorOf([] { ZernikeBasis(4, 32, 1.0); }), HasSubstr("ZernikeBasis: invalid obstruction = 1"));
}

TEST(OpticsErrorsTest, GridSizesAndSupersampling) {
  EXPECT_THAT(ErrorOf([] {
                CircularPupil(0, PupilGeometry{8.0, 0.0});
              }),
              HasSubstr("CircularPupil: invalid n = 0"));
  EXPECT_THAT(ErrorOf([] {
                CircularPupil(8, PupilGeometry{8.0, 0.0}, 0);
              }),
              HasSubstr("invalid supersample = 0"));
  EXPECT_THAT(ErrorOf([] { Zernike(4, 0); }), HasSubstr("Zernike: invalid n_pix = 0"));
  EXPECT_THAT(ErrorOf([] { PupilCoordinates(-1); }), HasSubstr("PupilCoordinates: invalid n = -1"));
}

TEST(OpticsErrorsTest, AmplitudeAndOpdShapeMismatch) {
  const Image a = Image::Ones(16, 16);
  const PsfSampling sampling{1e-6, 1e-8, 8, 8};
  EXPECT_THAT(ErrorOf([&] { PsfFromPupil(a, Image::Zero(16, 15), 8.0, sampling); }),
              HasSubstr("PsfFromPupil: invalid opd_m shape = 16x15"));
  EXPECT_THAT(ErrorOf([&] { PsfFromPupil(Image::Ones(16, 12), Image::Zero(16, 12), 8.0, sampling); }),
              HasSubstr("invalid amplitude shape = 16x12"));
  const PsfCalculator calc(16, 8.0, sampling);
  EXPECT_THAT(ErrorOf([&] { calc.Compute(a, Image::Zero(8, 8)); }),
              HasSubstr("PsfCalculator::Compute: invalid opd_m shape = 8x8"));
  EXPECT_THAT(ErrorOf([&] { calc.Compute(Image::Ones(8, 8), Image::Zero(8, 8)); }),
              HasSubstr("PsfCalculator::Compute: invalid amplitude shape = 8x8"));
  EXPECT_THAT(ErrorOf([&] { StrehlFromPupil(a, Image::Zero(4, 4), 1e-6); }),
              HasSubstr("StrehlFromPupil: invalid opd_m shape = 4x4"));
  EXPECT_THAT(ErrorOf([&] { ProjectOntoZernike(Image::Zero(4, 4), a, 3); }),
              HasSubstr("ProjectOntoZernike: invalid phase shape = 4x4"));
  EXPECT_THAT(ErrorOf([&] { calc.Compute(a * 0.0, Image::Zero(16, 16)); }),
              HasSubstr("invalid amplitude = all zero"));
  EXPECT_THAT(ErrorOf([&] { calc.Compute(-a, Image::Zero(16, 16)); }), HasSubstr("invalid amplitude"));
  EXPECT_THAT(ErrorOf([&] { calc.Compute(a, Image::Constant(16, 16, kNaN)); }),
              HasSubstr("invalid opd_m = nan"));
}

TEST(OpticsErrorsTest, NonPositiveWavelengthOrPixelScale) {
  const Image a = Image::Ones(16, 16), w = Image::Zero(16, 16);
  EXPECT_THAT(ErrorOf([&] {
                PsfFromPupil(a, w, 8.0, PsfSampling{0.0, 1e-8, 8, 8});
              }),
              HasSubstr("PsfFromPupil: invalid sampling.wavelength_m = 0"));
  EXPECT_THAT(ErrorOf([&] {
                PsfFromPupil(a, w, 8.0, PsfSampling{1e-6, -1e-8, 8, 8});
              }),
              HasSubstr("PsfFromPupil: invalid sampling.pixel_scale_rad = -1e-08"));
  EXPECT_THAT(ErrorOf([&] {
                PsfCalculator(16, 8.0, PsfSampling{1e-6, 0.0, 8, 8});
              }),
              HasSubstr("PsfCalculator: invalid sampling.pixel_scale_rad = 0"));
  EXPECT_THAT(ErrorOf([&] {
                PsfCalculator(16, 8.0, PsfSampling{1e-6, 1e-8, 8, 0});
              }),
              HasSubstr("invalid sampling.cols = 0"));
  EXPECT_THAT(ErrorOf([&] { StrehlFromPupil(a, w, -1e-6); }),
              HasSubstr("StrehlFromPupil: invalid wavelength_m = -1e-06"));
  EXPECT_THAT(ErrorOf([&] {
                Mft(ComplexImage::Ones(8, 8), 8.0, 0.0, {4, 4});
              }),
              HasSubstr("Mft: invalid pixel_scale_lod = 0"));
  EXPECT_THAT(ErrorOf([&] {
                Mft(ComplexImage::Ones(8, 8), -8.0, 0.5, {4, 4});
              }),
              HasSubstr("Mft: invalid pupil_span_px = -8"));
  EXPECT_THAT(ErrorOf([&] {
                MatrixFourierTransform(MftGeometry{{8, 8}, 8.0, {0, 4}, 0.5});
              }),
              HasSubstr("MatrixFourierTransform: invalid geometry.output = 0x4"));
  const MatrixFourierTransform mft(MftGeometry{{8, 8}, 8.0, {4, 4}, 0.5});
  EXPECT_THAT(ErrorOf([&] { mft.Apply(ComplexImage::Ones(8, 7)); }), HasSubstr("invalid field shape = 8x7"));
  EXPECT_THAT(ErrorOf([&] { mft.ApplyAdjoint(ComplexImage::Ones(8, 8)); }),
              HasSubstr("invalid image shape = 8x8"));
}

TEST(OpticsErrorsTest, KernelsAndStrehlInputs) {
  EXPECT_THAT(ErrorOf([] { NormaliseToUnitSum(Image::Zero(3, 3)); }),
              HasSubstr("NormaliseToUnitSum: invalid kernel sum = 0"));
  EXPECT_THAT(ErrorOf([] { PeakStrehl(Image::Ones(3, 3), Image::Zero(3, 3)); }),
              HasSubstr("PeakStrehl: invalid reference_psf maximum = 0"));
  EXPECT_THAT(ErrorOf([] { PeakStrehl(Image(0, 0), Image::Ones(3, 3)); }),
              HasSubstr("PeakStrehl: invalid psf"));
  EXPECT_THAT(ErrorOf([] { ProjectOntoZernike(Image::Zero(4, 4), Image::Ones(4, 4), 20); }),
              HasSubstr("ProjectOntoZernike: invalid J = 20"));
}

}  // namespace
}  // namespace aosr
