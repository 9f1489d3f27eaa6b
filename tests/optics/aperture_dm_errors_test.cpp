// Bad input at the aperture, orthonormal-Zernike, deformable-mirror and band-PSF entry points throws
// aosr::InvalidArgument naming the function and the bad argument or field.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <functional>
#include <limits>
#include <memory>
#include <string>

#include "aosr/core/error.hpp"
#include "aosr/optics/aperture.hpp"
#include "aosr/optics/deformable_mirror.hpp"
#include "aosr/optics/psf.hpp"
#include "aosr/optics/pupil.hpp"
#include "aosr/optics/zernike.hpp"
#include "support/testing.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

using aosr::test::ErrorOf;

using ::testing::HasSubstr;


constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kInf = std::numeric_limits<double>::infinity();

ApertureGeometry Disk() {
  ApertureGeometry g;
  g.pupil = PupilGeometry{8.0, 0.14};
  return g;
}

ApertureGeometry Segmented() {
  ApertureGeometry g;
  g.pupil = PupilGeometry{11.0, 0.0};
  g.outline = ApertureOutline::kHexSegments;
  g.segments = SegmentGeometry{3, 1.5588, 0.003, false, 0.0};
  return g;
}

TEST(ApertureErrorsTest, GridSizeAndSupersampling) {
  EXPECT_THAT(ErrorOf([] { Aperture(0, Disk()); }), HasSubstr("Aperture: invalid n = 0"));
  EXPECT_THAT(ErrorOf([] { Aperture(16, Disk(), 0); }), HasSubstr("Aperture: invalid supersample = 0"));
  EXPECT_THAT(ErrorOf([] { Aperture(16, Disk(), 65); }), HasSubstr("Aperture: invalid supersample = 65"));
}

TEST(ApertureErrorsTest, GeometryFieldsAreNamed) {
  auto message = [](const std::function<void(ApertureGeometry*)>& edit, ApertureGeometry g) {
    edit(&g);
    std::string why;
    EXPECT_FALSE(g.IsValid(&why));
    return ErrorOf([&] { Aperture(16, g); }) + " | IsValid: " + why;
  };
  EXPECT_THAT(message([](ApertureGeometry* g) { g->pupil.diameter_m = -1.0; }, Disk()),
              HasSubstr("Aperture: invalid geometry.pupil.diameter_m = -1"));
  EXPECT_THAT(message([](ApertureGeometry* g) { g->pupil.obstruction = 1.0; }, Disk()),
              HasSubstr("geometry.pupil.obstruction = 1"));
  EXPECT_THAT(message([](ApertureGeometry* g) { g->spiders.count = -1; }, Disk()),
              HasSubstr("geometry.spiders.count = -1"));
  EXPECT_THAT(message([](ApertureGeometry* g) { g->spiders.count = 65; }, Disk()),
              HasSubstr("spiders.count = 65; allowed: 0 .. 64"));
  EXPECT_THAT(message([](ApertureGeometry* g) { g->spiders.count = 4; }, Disk()),
              HasSubstr("geometry.spiders.width_m = 0"));
  EXPECT_THAT(message(
                  [](ApertureGeometry* g) {
                    g->spiders.count = 4;
                    g->spiders.width_m = kNaN;
                  },
                  Disk()),
              HasSubstr("spiders.width_m = nan"));
  EXPECT_THAT(message(
                  [](ApertureGeometry* g) {
                    g->spiders.count = 4;
                    g->spiders.width_m = 9.0;
                  },
                  Disk()),
              HasSubstr("spiders.width_m = 9; allowed: > 0, finite and < pupil.diameter_m"));
  EXPECT_THAT(message(
                  [](ApertureGeometry* g) {
                    g->spiders.count = 3;
                    g->spiders.width_m = 0.1;
                    g->spiders.angle_offset_rad = kInf;
                  },
                  Disk()),
              HasSubstr("spiders.angle_offset_rad = inf"));
  EXPECT_THAT(message([](ApertureGeometry* g) { g->segments.rings = -1; }, Segmented()),
              HasSubstr("geometry.segments.rings = -1"));
  EXPECT_THAT(message([](ApertureGeometry* g) { g->segments.rings = 51; }, Segmented()),
              HasSubstr("segments.rings = 51; allowed: 0 .. 50"));
  EXPECT_THAT(message([](ApertureGeometry* g) { g->segments.flat_to_flat_m = 0.0; }, Segmented()),
              HasSubstr("segments.flat_to_flat_m = 0"));
  EXPECT_THAT(message([](ApertureGeometry* g) { g->segments.gap_m = -0.001; }, Segmented()),
              HasSubstr("segments.gap_m = -0.001"));
  EXPECT_THAT(message([](ApertureGeometry* g) { g->segments.gap_m = 2.0; }, Segmented()),
              HasSubstr("segments.gap_m = 2; allowed: >= 0, finite and < segments.flat_to_flat_m"));
  EXPECT_THAT(message([](ApertureGeometry* g) { g->segments.rotation_rad = kNaN; }, Segmented()),
              HasSubstr("segments.rotation_rad = nan"));
  EXPECT_THAT(message(
                  [](ApertureGeometry* g) {
                    g->segments.rings = 0;
                    g->segments.central_segment = false;
                  },
                  Segmented()),
              HasSubstr("segments.central_segment = false"));
  EXPECT_THAT(message([](ApertureGeometry* g) { g->pupil.diameter_m = 10.0; }, Segmented()),
              HasSubstr("segments.rings = 3 (outermost corner at 5.48"));
  EXPECT_THAT(message([](ApertureGeometry* g) { g->outline = static_cast<ApertureOutline>(7); }, Disk()),
              HasSubstr("geometry.outline = 7"));
  // Segment fields are ignored (and not validated) for a circular outline.
  ApertureGeometry circular = Disk();
  circular.segments.flat_to_flat_m = -1.0;
  EXPECT_TRUE(circular.IsValid(nullptr));
}

TEST(ApertureErrorsTest, SegmentHelpers) {
  EXPECT_THAT(ErrorOf([] {
                SegmentCount(SegmentGeometry{-2, 1.0, 0.0, true, 0.0});
              }),
              HasSubstr("SegmentCount: invalid segments.rings = -2"));
  EXPECT_THAT(ErrorOf([] {
                SegmentCentres(SegmentGeometry{2, 0.0, 0.0, true, 0.0});
              }),
              HasSubstr("SegmentCentres: invalid segments.flat_to_flat_m = 0"));
  EXPECT_THAT(ErrorOf([] {
                SegmentedOuterRadius(SegmentGeometry{2, 1.0, kInf, true, 0.0});
              }),
              HasSubstr("invalid segments.gap_m = inf"));
}

TEST(ApertureErrorsTest, ResampleMask) {
  EXPECT_THAT(ErrorOf([] { ResampleMask(Image::Ones(8, 8), 0); }), HasSubstr("ResampleMask: invalid n = 0"));
  EXPECT_THAT(ErrorOf([] { ResampleMask(Image(0, 0), 8); }),
              HasSubstr("ResampleMask: invalid mask shape = 0x0"));
  EXPECT_THAT(ErrorOf([] { ResampleMask(Image::Constant(8, 8, 1.5), 4); }),
              HasSubstr("ResampleMask: invalid mask = values outside [0, 1] or non-finite"));
  EXPECT_THAT(ErrorOf([] { ResampleMask(Image::Constant(8, 8, kNaN), 4); }), HasSubstr("invalid mask"));
}

TEST(ZernikeOrthonormalErrorsTest, BadPupilsAndModeCounts) {
  const Image disk = CircularPupil(32, PupilGeometry{8.0, 0.0});
  EXPECT_THAT(ErrorOf([&] { OrthonormalZernikeBasis(disk, 0); }),
              HasSubstr("OrthonormalZernikeBasis: invalid J = 0"));
  EXPECT_THAT(ErrorOf([] { OrthonormalZernikeBasis(Image::Ones(8, 6), 3); }),
              HasSubstr("OrthonormalZernikeBasis: invalid pupil shape = 8x6"));
  EXPECT_THAT(ErrorOf([&] { OrthonormalZernikeBasis(-disk, 3); }),
              HasSubstr("OrthonormalZernikeBasis: invalid pupil = negative or non-finite values"));
  EXPECT_THAT(ErrorOf([] { OrthonormalZernikeBasis(Image::Zero(8, 8), 1); }),
              HasSubstr("invalid J = 1; allowed: at most the number of pupil pixels (0)"));
  // One row of pixels: y is constant, so the y tilt Z3 is a multiple of piston.
  Image row = Image::Zero(16, 16);
  row.row(8).setOnes();
  EXPECT_THAT(ErrorOf([&] { OrthonormalZernikeBasis(row, 3); }),
              HasSubstr("modes that are linearly independent on the pupil (mode 3 is not)"));
}

std::shared_ptr<DeformableMirror> Mirror() {
  DeformableMirrorOptions o;
  o.actuators_across = 9;
  o.pitch_m = 1.0;
  return std::make_shared<DeformableMirror>(32, PupilGeometry{8.0, 0.0}, o);
}

TEST(DeformableMirrorErrorsTest, ConstructorArgumentsAndOptions) {
  const DeformableMirrorOptions good = Mirror()->options();
  auto with = [&](const std::function<void(DeformableMirrorOptions*)>& edit) {
    DeformableMirrorOptions o = good;
    edit(&o);
    std::string why;
    EXPECT_FALSE(o.IsValid(&why));
    return ErrorOf([&] { DeformableMirror(32, PupilGeometry{8.0, 0.0}, o); }) + " | IsValid: " + why;
  };
  EXPECT_THAT(with([](DeformableMirrorOptions* o) { o->actuators_across = 1; }),
              HasSubstr("DeformableMirror: invalid options.actuators_across = 1"));
  EXPECT_THAT(with([](DeformableMirrorOptions* o) { o->pitch_m = 0.0; }), HasSubstr("options.pitch_m = 0"));
  EXPECT_THAT(with([](DeformableMirrorOptions* o) { o->coupling = 0.0; }), HasSubstr("options.coupling = 0"));
  EXPECT_THAT(with([](DeformableMirrorOptions* o) { o->coupling = 1.0; }),
              HasSubstr("options.coupling = 1; allowed: (0, 1)"));
  EXPECT_THAT(with([](DeformableMirrorOptions* o) { o->stroke_m = -1e-6; }),
              HasSubstr("options.stroke_m = -1e-06"));
  EXPECT_THAT(with([](DeformableMirrorOptions* o) { o->active_margin_pitch = kNaN; }),
              HasSubstr("options.active_margin_pitch = nan"));
  EXPECT_THAT(ErrorOf([&] {
                DeformableMirror(0, PupilGeometry{8.0, 0.0}, good);
              }),
              HasSubstr("DeformableMirror: invalid pupil_n = 0"));
  EXPECT_THAT(ErrorOf([&] {
                DeformableMirror(32, PupilGeometry{8.0, 1.2}, good);
              }),
              HasSubstr("DeformableMirror: invalid pupil.obstruction = 1.2"));
  // A 2 x 2 grid of 100 m pitch: every actuator ~70 m from the 8 m pupil.
  DeformableMirrorOptions far = good;
  far.actuators_across = 2;
  far.pitch_m = 100.0;
  far.active_margin_pitch = 0.0;
  EXPECT_THAT(ErrorOf([&] {
                DeformableMirror(32, PupilGeometry{8.0, 0.0}, far);
              }),
              HasSubstr("DeformableMirror: invalid options = no active actuator"));
}

TEST(DeformableMirrorErrorsTest, CommandSizesAndValues) {
  const auto dm = Mirror();
  const Index na = dm->n_active();
  EXPECT_THAT(
      ErrorOf([&] { dm->Apply(Vector::Zero(na + 1)); }),
      HasSubstr("DeformableMirror(9x9, n=32) Apply: invalid x = " + std::to_string(na + 1) + " elements"));
  EXPECT_THAT(ErrorOf([&] { dm->ApplyAdjoint(Vector::Zero(10)); }),
              HasSubstr("ApplyAdjoint: invalid y = 10"));
  EXPECT_THAT(ErrorOf([&] { dm->Opd(Vector::Zero(3)); }),
              HasSubstr("DeformableMirror::Opd: invalid commands size = 3"));
  EXPECT_THAT(ErrorOf([&] { dm->CommandsToGrid(Vector::Zero(3)); }),
              HasSubstr("DeformableMirror::CommandsToGrid: invalid commands size = 3"));
  EXPECT_THAT(ErrorOf([&] { dm->GridToCommands(Image::Zero(8, 9)); }),
              HasSubstr("DeformableMirror::GridToCommands: invalid grid shape = 8x9"));
  EXPECT_THAT(ErrorOf([&] { dm->Clip(nullptr); }),
              HasSubstr("DeformableMirror::Clip: invalid commands = null"));
  Vector wrong = Vector::Zero(2);
  EXPECT_THAT(ErrorOf([&] { dm->Clip(&wrong); }),
              HasSubstr("DeformableMirror::Clip: invalid commands size = 2"));
  Vector nan = Vector::Constant(na, kNaN);
  EXPECT_THAT(ErrorOf([&] { dm->Clip(&nan); }),
              HasSubstr("DeformableMirror::Clip: invalid commands = non-finite"));
}

TEST(DeformableMirrorErrorsTest, Fitter) {
  const auto dm = Mirror();
  const Image pupil = CircularPupil(32, PupilGeometry{8.0, 0.0});
  EXPECT_THAT(ErrorOf([&] { DmFitter(nullptr, pupil); }), HasSubstr("DmFitter: invalid dm = null"));
  EXPECT_THAT(ErrorOf([&] { DmFitter(dm, Image::Ones(16, 16)); }),
              HasSubstr("DmFitter: invalid weights shape = 16x16"));
  EXPECT_THAT(ErrorOf([&] { DmFitter(dm, -pupil); }), HasSubstr("DmFitter: invalid weights = negative"));
  EXPECT_THAT(ErrorOf([&] { DmFitter(dm, pupil * 0.0); }), HasSubstr("DmFitter: invalid weights = all zero"));
  DmFitOptions bad;
  bad.regularisation = -1.0;
  std::string why;
  EXPECT_FALSE(bad.IsValid(&why));
  EXPECT_THAT(ErrorOf([&] { DmFitter(dm, pupil, bad); }),
              HasSubstr("DmFitter: invalid options.regularisation = -1"));
  // Light on one pixel cannot determine 69 actuators: singular without regularisation.
  Image one = Image::Zero(32, 32);
  one(16, 16) = 1.0;
  DmFitOptions plain;
  plain.regularisation = 0.0;
  EXPECT_THAT(ErrorOf([&] { DmFitter(dm, one, plain); }),
              HasSubstr("DmFitter: invalid options.regularisation = 0; allowed: a value > 0"));
  const DmFitter fitter(dm, pupil);
  EXPECT_THAT(ErrorOf([&] { fitter.Fit(Image::Zero(31, 32)); }),
              HasSubstr("DmFitter::Fit: invalid opd_m shape = 31x32"));
  Image opd = Image::Zero(32, 32);
  opd(16, 16) = kNaN;
  EXPECT_THAT(ErrorOf([&] { fitter.Fit(opd); }), HasSubstr("DmFitter::Fit: invalid opd_m = nan"));
  opd(16, 16) = 0.0;
  opd(0, 0) = kNaN;  // outside the pupil: ignored
  EXPECT_TRUE(fitter.Fit(opd).allFinite());
}

TEST(BandPsfErrorsTest, BandAndSampling) {
  auto band_error = [](const SpectralBand& band) {
    std::string why;
    EXPECT_FALSE(band.IsValid(&why));
    return ErrorOf([&] { BandPsfCalculator(16, 8.0, band, 1e-8, 8, 8); }) + " | IsValid: " + why;
  };
  EXPECT_THAT(band_error(SpectralBand{}),
              HasSubstr("BandPsfCalculator: invalid band.wavelengths_m = (empty)"));
  EXPECT_THAT(band_error(SpectralBand{{1e-6, 2e-6}, {1.0}}),
              HasSubstr("band.weights = (1 values); allowed: one per"));
  EXPECT_THAT(band_error(SpectralBand{{1e-6, -2e-6}, {1.0, 1.0}}),
              HasSubstr("band.wavelengths_m[1] = -2e-06"));
  EXPECT_THAT(band_error(SpectralBand{{1e-6}, {kNaN}}), HasSubstr("band.weights[0] = nan"));
  EXPECT_THAT(band_error(SpectralBand{{1e-6, 2e-6}, {0.0, 0.0}}), HasSubstr("band.weights = (all zero)"));
  const SpectralBand good{{1e-6}, {1.0}};
  EXPECT_THAT(ErrorOf([&] { BandPsfCalculator(0, 8.0, good, 1e-8, 8, 8); }),
              HasSubstr("BandPsfCalculator: invalid pupil_n = 0"));
  EXPECT_THAT(ErrorOf([&] { BandPsfCalculator(16, -8.0, good, 1e-8, 8, 8); }),
              HasSubstr("BandPsfCalculator: invalid diameter_m = -8"));
  EXPECT_THAT(ErrorOf([&] { BandPsfCalculator(16, 8.0, good, 0.0, 8, 8); }),
              HasSubstr("BandPsfCalculator: invalid pixel_scale_rad = 0"));
  EXPECT_THAT(ErrorOf([&] { BandPsfCalculator(16, 8.0, good, 1e-8, 0, 8); }),
              HasSubstr("BandPsfCalculator: invalid rows = 0"));
  EXPECT_THAT(ErrorOf([&] { BandPsfCalculator(16, 8.0, good, 1e-8, 8, -1); }),
              HasSubstr("BandPsfCalculator: invalid cols = -1"));
  const BandPsfCalculator calc(16, 8.0, good, 1e-8, 8, 8);
  EXPECT_THAT(ErrorOf([&] { calc.Compute(Image::Ones(8, 8), Image::Zero(8, 8)); }),
              HasSubstr("PsfCalculator::Compute: invalid amplitude shape = 8x8"));
  EXPECT_THAT(ErrorOf([&] { calc.Compute(Image::Ones(16, 16), Image::Zero(16, 8)); }),
              HasSubstr("invalid opd_m shape = 16x8"));
  EXPECT_THAT(ErrorOf([] { UniformBand(0.0, 1e-7, 3); }), HasSubstr("UniformBand: invalid centre_m = 0"));
  EXPECT_THAT(ErrorOf([] { UniformBand(1e-6, 2e-6, 3); }), HasSubstr("UniformBand: invalid width_m = 2e-06"));
  EXPECT_THAT(ErrorOf([] { UniformBand(1e-6, 1e-7, 0); }), HasSubstr("UniformBand: invalid samples = 0"));
}

}  // namespace
}  // namespace aosr
