// Unit tests of the Shack-Hartmann sensor and the ideal sensor (shack_hartmann.hpp, wavefront_sensor.hpp):
// lenslet geometry, exact slopes of a tilt, the adjoint, references and offsets, FFT/MFT agreement,
// photometry and deterministic noise.
#include "aosr/ao/shack_hartmann.hpp"

#include <gtest/gtest.h>

#include <cmath>

#include "aosr/ao/wavefront_sensor.hpp"
#include "aosr/core/adjoint_test.hpp"
#include "aosr/optics/deformable_mirror.hpp"
#include "aosr/optics/pupil.hpp"
#include "aosr/optics/zernike.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

constexpr double kD = 8.0;

Image Pupil(Index n, double obstruction = 0.0, int supersample = 1) {
  return CircularPupil(n, PupilGeometry{kD, obstruction}, supersample);
}

// OPD = sx x + sy y [m], x, y the pixel-centre positions of pupil.hpp's grid.
Image TiltOpd(Index n, double sx, double sy) {
  Image w(n, n);
  const double dx = kD / n;
  for (Index i = 0; i < n; ++i) {
    for (Index k = 0; k < n; ++k) w(i, k) = sx * (k - 0.5 * (n - 1)) * dx + sy * (i - 0.5 * (n - 1)) * dx;
  }
  return w;
}

TEST(ShackHartmannTest, ValidLensletsOfThePaperSystem) {
  ShackHartmannOptions o;  // 16 x 16, threshold 0.5
  ShackHartmann sh(Pupil(128), kD, o);
  EXPECT_EQ(sh.pixels_per_subaperture(), 8);
  EXPECT_DOUBLE_EQ(sh.subaperture_m(), 0.5);
  EXPECT_EQ(sh.n_valid(), 208);
  EXPECT_EQ(sh.n_measurements(), 2 * 208);
  EXPECT_EQ(sh.valid_mask().sum(), 208.0);
  // The mask is symmetric under both flips (the pupil grid is).
  EXPECT_TRUE((sh.valid_mask() == sh.valid_mask().rowwise().reverse()).all());
  EXPECT_TRUE((sh.valid_mask() == sh.valid_mask().colwise().reverse()).all());
  // A stricter threshold drops rim lenslets; an obstruction drops central ones.
  o.valid_threshold = 0.9;
  EXPECT_LT(ShackHartmann(Pupil(128), kD, o).n_valid(), 208);
  o.valid_threshold = 0.5;
  EXPECT_LT(ShackHartmann(Pupil(128, 0.3), kD, o).n_valid(), 208);
}

TEST(ShackHartmannTest, GeometricSlopesOfATiltAreExact) {
  for (int supersample : {1, 4}) {
    for (double obstruction : {0.0, 0.25}) {
      const Image a = Pupil(64, obstruction, supersample);
      ShackHartmannOptions o;
      o.subapertures_across = 8;
      ShackHartmann sh(a, kD, o);
      const double sx = 3.1e-7, sy = -1.7e-7;  // rad
      const Vector s = sh.Measure(TiltOpd(64, sx, sy));
      const Index nv = sh.n_valid();
      for (Index v = 0; v < nv; ++v) {
        EXPECT_NEAR(s[v], sx, 1e-12 * std::abs(sx)) << "lenslet " << v << " supersample " << supersample;
        EXPECT_NEAR(s[nv + v], sy, 1e-12 * std::abs(sy)) << "lenslet " << v;
      }
    }
  }
}

TEST(ShackHartmannTest, GeometricOperatorHasAnExactAdjoint) {
  for (int supersample : {1, 8}) {
    ShackHartmannOptions o;
    GeometricSlopeOperator g(Pupil(128, 0.14, supersample), kD, o);
    EXPECT_EQ(g.rows(), 2 * g.n_valid());
    EXPECT_EQ(g.cols(), 128 * 128);
    const AdjointTestResult r = AdjointTest(g, 7);
    EXPECT_LT(r.adjoint_error, 1e-10) << "supersample " << supersample;
    EXPECT_LT(r.normal_error, 1e-10);
  }
}

TEST(ShackHartmannTest, GeometricSlopeIsTheEdgeDifferenceOverTheWidth) {
  // A fully lit lenslet's x slope is the mean over its rows of (w(last col) - w(first col)) / ((p-1) dx).
  ShackHartmannOptions o;
  o.subapertures_across = 4;
  const Index n = 32, p = 8;
  const Image a = Image::Ones(n, n);
  ShackHartmann sh(a, kD, o);
  Image w = Image::Zero(n, n);
  for (Index i = 0; i < n; ++i)
    for (Index k = 0; k < n; ++k) w(i, k) = 1e-7 * std::sin(0.3 * i + 0.7 * k * k / n);
  const Vector s = sh.Measure(w);
  const double dx = kD / n;
  double expected = 0.0;  // lenslet (1, 2): rows 8..15, cols 16..23
  for (Index i = p; i < 2 * p; ++i) expected += (w(i, 3 * p - 1) - w(i, 2 * p)) / ((p - 1) * dx);
  expected /= p;
  EXPECT_NEAR(s[1 * 4 + 2], expected, 1e-12 * std::abs(expected));
}

TEST(ShackHartmannTest, ReferenceAndOffsets) {
  for (ShackHartmannMode mode : {ShackHartmannMode::kGeometric, ShackHartmannMode::kDiffractive}) {
    ShackHartmannOptions o;
    o.subapertures_across = 8;
    o.mode = mode;
    ShackHartmann sh(Pupil(64, 0.2), kD, o);
    // A flat wavefront measures zero once the reference is subtracted.
    EXPECT_LT(sh.Measure(Image::Zero(64, 64)).cwiseAbs().maxCoeff(), 1e-15);
    // The offset for an OPD cancels that OPD's measurement, and is the sensor's linear response for the
    // geometric mode.
    const Image w = 30e-9 * Zernike(5, 64, 0.2) + 20e-9 * Zernike(8, 64, 0.2);
    const Vector offset = sh.ReferenceOffsetForOpd(w);
    if (mode == ShackHartmannMode::kGeometric) {
      EXPECT_LT((offset - sh.geometric_operator()->Apply(AsVector(w))).norm(), 1e-12 * offset.norm());
    }
    sh.SetReferenceOffset(offset);
    EXPECT_LT(sh.Measure(w).norm(), 1e-12 * offset.norm());
    EXPECT_LT((sh.Measure(Image::Zero(64, 64)) + offset).norm(), 1e-12 * offset.norm());
    sh.ClearReferenceOffset();
    EXPECT_EQ(sh.reference_offset().norm(), 0.0);
  }
}

TEST(ShackHartmannTest, WindowIsCentredOnTheOpticalAxis) {
  // The optical axis sits on the window's centre ((m-1)/2, (m-1)/2): a pixel corner for even m, a pixel centre
  // for odd m. A flat wavefront's spot (|E^|^2 of a real amplitude: centrally symmetric, partially lit and
  // obstructed lenslets included) is then symmetric on the window and its raw centroid is 0 to rounding on
  // every lenslet, for both transforms and for full and partial windows. Tolerance 1e-12 px.
  const Image a = Pupil(64, 0.2, 4);  // grey edges: many partially lit lenslets
  struct Case {
    double s;
    int m;
    SpotTransform t;
  };
  for (const Case& c : {Case{0.5, 16, SpotTransform::kFft}, Case{0.5, 16, SpotTransform::kMft},
                        Case{0.5, 11, SpotTransform::kFft}, Case{0.5, 10, SpotTransform::kMft},
                        Case{0.3, 0, SpotTransform::kMft}, Case{0.5, 15, SpotTransform::kMft}}) {
    ShackHartmannOptions o;
    o.subapertures_across = 8;
    o.mode = ShackHartmannMode::kDiffractive;
    o.pixel_scale_lod = c.s;
    o.field_of_view_px = c.m;
    o.spot_transform = c.t;
    ShackHartmann sh(a, kD, o);
    EXPECT_LT(sh.reference().cwiseAbs().maxCoeff(), 1e-12 * sh.spot_pixel_scale_rad())
        << "s " << c.s << ", m " << sh.spot_size_px() << (sh.uses_fft() ? " FFT" : " MFT");
    sh.MeasureNoiseless(Image::Zero(64, 64));
    for (Index v = 0; v < sh.n_valid(); v += 5) {
      const Image spot = sh.LastSpot(v);
      EXPECT_LT((spot - spot.reverse()).abs().maxCoeff(), 1e-9 * spot.maxCoeff()) << "lenslet " << v;
    }
  }
  // A small tilt moves the spot off the corner in its direction: the centroid keeps the tilt's sign.
  ShackHartmannOptions o;
  o.subapertures_across = 8;
  o.mode = ShackHartmannMode::kDiffractive;
  ShackHartmann sh(Pupil(64), kD, o);
  const double lod = o.wavelength_m / sh.subaperture_m();
  const Vector s = sh.Measure(TiltOpd(64, 0.1 * lod, -0.05 * lod));
  const Index nv = sh.n_valid();
  for (Index v = 0; v < nv; ++v) {
    EXPECT_GT(s[v], 0.0);
    EXPECT_LT(s[nv + v], 0.0);
  }
}

TEST(ShackHartmannTest, FftAndMftSpotsAgree) {
  ShackHartmannOptions o;
  o.subapertures_across = 8;
  o.mode = ShackHartmannMode::kDiffractive;
  o.pixel_scale_lod = 0.5;
  o.field_of_view_px = 12;
  o.threshold_fraction = 0.1;
  const Image a = Pupil(64, 0.15, 4);
  o.spot_transform = SpotTransform::kFft;
  ShackHartmann fft(a, kD, o);
  o.spot_transform = SpotTransform::kMft;
  ShackHartmann mft(a, kD, o);
  EXPECT_TRUE(fft.uses_fft());
  EXPECT_EQ(fft.fft_size_px(), 16);
  EXPECT_FALSE(mft.uses_fft());
  const Image w = 80e-9 * Zernike(4, 64) + 60e-9 * Zernike(7, 64) + 40e-9 * Zernike(12, 64);
  const Vector sf = fft.Measure(w), sm = mft.Measure(w);
  EXPECT_LT((sf - sm).cwiseAbs().maxCoeff(), 1e-12 * sf.cwiseAbs().maxCoeff());
  for (Index v : {Index{0}, fft.n_valid() / 2}) {
    EXPECT_LT((fft.LastSpot(v) - mft.LastSpot(v)).abs().maxCoeff(), 1e-10 * fft.LastSpot(v).maxCoeff());
  }
  // kAuto picks the FFT when p / s is an integer and the MFT otherwise.
  o.spot_transform = SpotTransform::kAuto;
  EXPECT_TRUE(ShackHartmann(a, kD, o).uses_fft());
  o.pixel_scale_lod = 0.3;
  o.field_of_view_px = 0;
  ShackHartmann odd(a, kD, o);
  EXPECT_FALSE(odd.uses_fft());
  EXPECT_EQ(odd.spot_size_px(), 26);  // floor(8 / 0.3)
}

TEST(ShackHartmannTest, PhotometryOfAFullyLitLenslet) {
  ShackHartmannOptions o;
  o.subapertures_across = 8;
  o.mode = ShackHartmannMode::kDiffractive;
  o.noise.guide_star_magnitude = 5.0;
  o.noise.zero_point_photons_per_s_m2 = 1e10;
  o.noise.throughput = 0.5;
  o.noise.frame_time_s = 1e-3;
  ShackHartmann sh(Pupil(64), kD, o);
  // N = F0 10^(-0.4 mag) tau T d^2 for a fully lit 1 m lenslet.
  const double expected = 1e10 * std::pow(10.0, -2.0) * 0.5 * 1e-3 * 1.0;
  double largest = 0.0;
  for (Index v = 0; v < sh.n_valid(); ++v) largest = std::max(largest, sh.photons_per_subaperture()[v]);
  EXPECT_NEAR(largest, expected, 1e-9 * expected);
  // With the full-period window (the default) every photon lands in the window, whatever the aberration.
  sh.Measure(60e-9 * Zernike(6, 64));
  for (Index v = 0; v < sh.n_valid(); ++v) {
    EXPECT_NEAR(sh.LastSpot(v).sum(), sh.photons_per_subaperture()[v], 1e-9 * expected);
  }
}

TEST(ShackHartmannTest, NoiseIsDeterministicPerSeed) {
  ShackHartmannOptions o;
  o.subapertures_across = 8;
  o.mode = ShackHartmannMode::kDiffractive;
  o.noise.photon_noise = true;
  o.noise.read_noise_e = 1.0;
  o.noise.guide_star_magnitude = 12.0;
  o.noise.seed = 42;
  const Image a = Pupil(64);
  const Image w = Image::Zero(64, 64);
  ShackHartmann s1(a, kD, o), s2(a, kD, o);
  const Vector m1 = s1.Measure(w), m2 = s2.Measure(w);
  EXPECT_EQ((m1 - m2).cwiseAbs().maxCoeff(), 0.0);
  EXPECT_GT(m1.norm(), 0.0);                                   // noise is there
  EXPECT_NE((s1.Measure(w) - m1).cwiseAbs().maxCoeff(), 0.0);  // and the generator advances
  o.noise.seed = 43;
  ShackHartmann s3(a, kD, o);
  EXPECT_GT((s3.Measure(w) - m1).cwiseAbs().maxCoeff(), 0.0);
  // MeasureNoiseless does not advance the generator.
  ShackHartmann s4(a, kD, o), s5(a, kD, o);
  s4.MeasureNoiseless(w);
  EXPECT_EQ((s4.Measure(w) - s5.Measure(w)).cwiseAbs().maxCoeff(), 0.0);
  // Geometric white noise: deterministic, of the stated RMS.
  ShackHartmannOptions g;
  g.subapertures_across = 8;
  g.noise.geometric_noise_rad = 1e-6;
  ShackHartmann gs(a, kD, g);
  double sum2 = 0.0;
  const int frames = 50;
  for (int f = 0; f < frames; ++f) sum2 += gs.Measure(w).squaredNorm();
  EXPECT_NEAR(std::sqrt(sum2 / (frames * gs.n_measurements())), 1e-6, 0.03e-6);
}

TEST(ShackHartmannTest, IdealSensorSeesTheMirrorCommands) {
  DeformableMirrorOptions dmo;
  dmo.actuators_across = 9;
  dmo.pitch_m = 1.0;
  auto dm = std::make_shared<const DeformableMirror>(64, PupilGeometry{kD, 0.0}, dmo);
  const Image a = Pupil(64);
  IdealWavefrontSensor ideal(dm, a);
  EXPECT_EQ(ideal.n_measurements(), dm->n_active());
  EXPECT_EQ(ideal.reference().norm(), 0.0);
  Vector c(dm->n_active());
  for (Index j = 0; j < c.size(); ++j) c[j] = 1e-7 * std::cos(0.37 * j);
  const Vector m = ideal.Measure(dm->Opd(c));
  EXPECT_LT((m - c).norm(), 1e-3 * c.norm());  // the fit recovers the commands up to its regularisation
  EXPECT_NE(ideal.Describe().find("ideal"), std::string::npos);
}

}  // namespace
}  // namespace aosr
