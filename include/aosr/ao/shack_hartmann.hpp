// A Shack-Hartmann wavefront sensor (SH-WFS): an M x M lenslet array over the pupil, each lenslet imaging
// the guide star onto its own patch of detector pixels; the spot displacement measures the mean wavefront
// tilt over the lenslet (J. Hartmann 1900; R. V. Shack & B. C. Platt 1971; for the noise and sampling
// trade-offs see G. Rousset, "Wave-front sensors", in F. Roddier (ed.), Adaptive Optics in Astronomy,
// Cambridge (1999), ch. 5, and S. Thomas et al., MNRAS 371, 323 (2006)).
//
// Geometry (pupil.hpp's grid: n x n pixels spanning D, pixel pitch dx = D/n). The lenslets tile the grid:
// M = subapertures_across must divide n, each lenslet is p = n/M pixels (side d = D/M) and lenslet (a, b)
// (row a along y, column b along x) covers pixels [a p, (a+1) p) x [b p, (b+1) p). In Fried geometry with an
// (M+1) x (M+1) DM of pitch d (deformable_mirror.hpp) the actuators sit exactly on the lenslet corners.
// A lenslet is VALID when its illumination fraction sum_{lenslet} A / p^2 (A: the pupil amplitude) is at
// least valid_threshold (default 0.5); only valid lenslets are measured. For an unobstructed 8 m pupil on
// 128 pixels and 16 x 16 lenslets that gives 208 valid lenslets (tested).
//
// Measurements are slopes in radians of wavefront tilt (the angle the spot moves: an OPD w = s x moves the
// spot, like the PSF, by +s rad toward +x, psf.hpp), ordered [x slopes of the valid lenslets; y slopes of the
// valid lenslets], valid lenslets in row-major order (a, then b): 2 x n_valid values.
//
// Geometric mode (kGeometric): the amplitude-weighted mean OPD gradient over each lenslet, by first
// differences between horizontally (vertically) adjacent pixels of the same lenslet,
//     s_x = sum_{(i,k),(i,k+1) in lenslet} A_ik A_i,k+1 (w_i,k+1 - w_ik) / dx  /  sum A_ik A_i,k+1,
// likewise s_y along rows. The pair weight A A' is the intensity at the pair's midpoint to first order, so
// s is the intensity-weighted mean gradient, which is what a spot centroid measures (the centroid of |F E|^2
// is sum |E|^2 grad(phase) / sum |E|^2 in the continuous limit; Teague 1982). It is exact for any linear
// OPD (a pure tilt gives its slope to rounding) and, for a fully lit lenslet, equals the mean of
// (w(right edge) - w(left edge)) / ((p-1) dx) over its rows: the classical "mean gradient = edge difference
// over width" of a geometric SH. This mode is a LinearOperator OPD -> slopes (GeometricSlopeOperator below)
// with an exact adjoint (a scatter of the same weights); stored sparsely (2 p^2 weights per valid lenslet),
// one application costs ~4 p^2 n_valid flops (~0.02 ms for the 208-lenslet example). It is noise-free
// except for an optional white Gaussian slope noise (geometric_noise_rad).
//
// Diffractive mode (kDiffractive): each valid lenslet's field E = A exp(i 2 pi w / lambda_wfs) (p x p
// pixels) is propagated to its focal plane and detected:
//  * Sampling. Spot pixels have a pitch s = pixel_scale_lod in lambda_wfs / d (angular pitch s lambda/d
//    rad); the window is m x m pixels (field_of_view_px; 0 means one full period q, below), the optical axis
//    on the window's centre ((m - 1)/2, (m - 1)/2), so pixel (y, x) sits at angle
//    ((x - (m - 1)/2) s, (y - (m - 1)/2) s) lambda/d: for even m (the usual case) the axis falls on the
//    corner of the four central pixels, as a real SH detector is aligned (a quad cell is the m = 2 case),
//    and for odd m on the central pixel's centre. The window is then symmetric about the axis, so the
//    centre of gravity of a symmetric spot is exactly 0 whatever its width. (Before issue 23 the axis sat on
//    pixel (m/2, m/2), image.hpp's centred-kernel rule: for even m the edge row and column at -m/2 had no
//    partner at +m/2, so the centroid was biased toward -x, -y by (m/2) x the light on them. The flat-
//    wavefront reference removed that for the diffraction-limited spot but not for the broader spots of a
//    turbulent residual, and the closed loop held the difference as a tilt: (0.18, 0.14) lambda/D on the
//    paper's K-band PSF at r0 = 0.15 m, 0.6 at 0.08 m, 0.07 at 0.25 m.) Because the lenslet field is sampled by only p pixels, its
//    focal-plane intensity is periodic with period p lambda/d: the window must not exceed one period,
//    m s <= p (wider windows would alias; a real field stop or the neighbouring lenslets' pixels would catch
//    that light). E.g. p = 8, s = 0.5 (Nyquist for the diffraction-limited spot): q = 16, m <= 16 pixels
//    = 8 lambda/d.
//  * Transform. When q = p/s is an integer (and m <= q) the field is zero-padded to q x q and transformed by
//    an FFT, one small FFT per lenslet (the spot is |FFT|^2, fftshifted and cropped to the window; the sign
//    makes a phase ramp exp(+2 pi i t x) peak at +t, mft.hpp's convention). Otherwise the exact MFT of
//    mft.hpp evaluates the window directly (any s, slower: ~p m (p + m) complex multiply-adds per lenslet).
//    spot_transform forces one or the other; where both apply they agree to rounding (tested).
//  * Photometry. Lenslet v receives N_v = F0 10^(-0.4 mag) tau T sum_{lenslet} A^2 dx^2 photo-electrons per
//    frame (F0: band zero point [photons s^-1 m^-2], mag: guide-star magnitude, tau: throughput including
//    quantum efficiency, T: frame time [s]), spread over the focal plane as N_v |E^|^2 / (sum over one
//    period): the window holds all of them when m s = p and less otherwise (light outside is lost).
//  * Noise (noise.photon_noise / read_noise_e): each pixel's count is Poisson with that mean (Knuth's
//    multiplication method for means < 12, Hörmann's transformed rejection PTRS above; W. Hörmann, "The
//    transformed rejection method for generating Poisson random variables", Insurance: Mathematics and
//    Economics 12, 39 (1993)), plus Gaussian read noise of read_noise_e electrons RMS. Generators are seeded
//    from noise.seed (DeriveSeed, random.hpp): the same seed gives the same noise on every platform.
//  * Centroid. Centre of gravity with a threshold: I' = max(I - t max(I), 0) (t = threshold_fraction), so
//    negative read-noise pixels never count, then c = sum I' (x - (m-1)/2) / sum I' pixels along x (likewise y),
//    and the slope is c s lambda_wfs / d radians (0 when sum I' = 0: a dark lenslet). The centroid's gain
//    (diffractive / geometric slope) is not exactly 1: a lenslet field sampled by p pixels has a spot that is
//    periodic with period p lambda/d, and the plain centre of gravity over one period sees the diffraction
//    wings wrapped around (as a contiguous detector sees its neighbours' wings) and the spot's pixelation.
//    Measured on the paper's sensor (p = 8, tests/ao/shack_hartmann_physics_test.cpp): fully lit lenslets
//    1.033 - 1.035 for small tilts with Nyquist pixels (s = 0.5, 16 px), 1.006 - 1.007 with s = 0.25 (32 px),
//    partially lit lenslets down to ~0.86; the gain stays within 0.92 - 1.035 up to 2 lambda/d (the linear
//    range of a 16 px window), beyond which the spot leaves the window. The interaction matrix calibrates
//    each lenslet's gain.
//    A threshold (t > 0) removes the wings, and the gain bias with them, but makes the response to tilts
//    below ~0.1 lambda/d irregular (pixels cross the threshold): use it against read noise, not for
//    linearity. The photon-noise variance of the plain centroid is sum I (x - c)^2 / N^2 = <(x - c)^2> / N
//    (measured within 0.5% of that and of the 1/N law; tested to 5% and 7%).
//  * Reference: the raw centroids of a flat wavefront, see wavefront_sensor.hpp: the calibration a real
//    system makes. With the symmetric window they are 0 to rounding on every lenslet (a real amplitude's
//    |E^|^2 is centrally symmetric, partially lit lenslets included; tested), so a spot of any width that is
//    symmetric about the axis reads 0 and the closed loop holds no tilt (tests/ao/
//    closed_loop_physics_test.cpp: long-exposure PSF centroid within 0.01 lambda/D).
//  Cost per measurement: one complex exponential per lit pixel (vectorised sin/cos), n_valid FFTs of q x q
//  and the centroids: ~0.24 ms for the paper's 208 lenslets of 16 x 16 on one core, of which the FFTs are
//  ~0.05 ms; with Poisson noise add one Poisson deviate per pixel (~30 ns each).
//
// Thread safety: not thread-safe (scratch buffers and generators); one sensor per thread.
#pragma once

#include <cstdint>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "aosr/ao/random.hpp"
#include "aosr/ao/wavefront_sensor.hpp"
#include "aosr/core/linear_operator.hpp"
#include "aosr/optics/mft.hpp"

namespace aosr {

enum class ShackHartmannMode {
  kGeometric,    // mean intensity-weighted OPD gradient per lenslet: linear, exact, fast
  kDiffractive,  // spot images by FFT/MFT and centre-of-gravity centroids, with photon and read noise
};

enum class SpotTransform {
  kAuto,  // FFT when q = p / pixel_scale_lod is an integer and the window fits in q, else MFT
  kFft,   // require the FFT path (throws if q is not an integer or the window exceeds it)
  kMft,   // always the MFT
};

struct ShackHartmannNoise {
  // Poisson photon noise on every spot pixel (diffractive mode only). Default false: a noiseless sensor (a
  // bright guide star), which is what calibration and most physics tests want.
  bool photon_noise = false;
  // Guide-star magnitude in the sensor's band (dimensionless, any finite value). Sets the photon count with
  // the zero point below. Default 10, a moderately bright natural guide star.
  double guide_star_magnitude = 10.0;
  // Photon flux of a magnitude-0 star in the band [photons s^-1 m^-2], > 0 and finite. Default 9.7e9: the
  // commonly tabulated Johnson-Cousins R value (702 photons s^-1 cm^-2 A^-1 over a 1380 A band), for the R
  // band a 640 nm sensor sees. State your filter's value.
  double zero_point_photons_per_s_m2 = 9.7e9;
  // End-to-end throughput to detected photo-electrons (optics x quantum efficiency), in (0, 1]. Default 0.3,
  // typical of a visible SH path including the detector's QE.
  double throughput = 0.3;
  // Integration time of one frame [s], > 0 and finite: 1 / loop rate for a sensor read every frame. Default
  // 1/800 s (the 800 Hz loop of the paper's system). closed_loop.hpp checks it against the loop rate when
  // noise is on.
  double frame_time_s = 1.0 / 800.0;
  // Read noise [electrons RMS per pixel], >= 0 and finite (diffractive mode only). 0: none. EMCCDs reach
  // < 0.1 e- effective, sCMOS ~1 e-, CCDs 3 - 5 e-.
  double read_noise_e = 0.0;
  // White Gaussian noise added to every slope in geometric mode [rad RMS], >= 0 and finite. 0: none. A
  // stand-in for the centroid noise when the spots are not simulated.
  double geometric_noise_rad = 0.0;
  // Master seed of the noise generators (Poisson: DeriveSeed(seed, 0); read and geometric noise:
  // DeriveSeed(seed, 1)). Any value.
  std::uint64_t seed = 1;
};

struct ShackHartmannOptions {
  // Lenslets across the pupil M (M x M lenslets), >= 1; must divide the pupil grid size n with at least 2
  // pixels per lenslet (n / M >= 2), checked at construction. Default 16 (the paper's 16 x 16 on 8 m).
  int subapertures_across = 16;
  // Minimum illumination fraction sum A / p^2 of a valid lenslet, in (0, 1]. Default 0.5: lenslets less
  // than half lit give noisy, rim-biased slopes and are conventionally dropped.
  double valid_threshold = 0.5;
  // Geometric or diffractive (see the header). Default kGeometric.
  ShackHartmannMode mode = ShackHartmannMode::kGeometric;
  // Sensing wavelength lambda_wfs [m], > 0 and finite (diffractive phase and pixel scale). Default 640 nm
  // (R band, the paper's sensor).
  double wavelength_m = 640e-9;
  // Spot pixel pitch s in lambda_wfs / d, in (0, 1]. Default 0.5: Nyquist sampling of the
  // diffraction-limited spot, the usual compromise between linear range and noise.
  double pixel_scale_lod = 0.5;
  // Spot window m x m pixels; 0 means one full period q = p / s (rounded down); otherwise >= 2 and
  // m s <= p (checked at construction). Default 0.
  int field_of_view_px = 0;
  // How the spots are computed (header "Transform"). Default kAuto.
  SpotTransform spot_transform = SpotTransform::kAuto;
  // Centroid threshold t as a fraction of each spot's maximum, in [0, 1). Default 0: the plain centre of
  // gravity, linear and unbiased without noise; with read noise 0.05 - 0.2 suppresses the noise of the
  // empty pixels at the price of a small non-linearity.
  double threshold_fraction = 0.0;
  // Noise model (defaults: none).
  ShackHartmannNoise noise;

  // True when every field is in range; otherwise false and `why` (if non-null) names the bad field, e.g.
  // "noise.read_noise_e = -1; allowed: >= 0 and finite [e-]". Geometry that depends on the pupil grid
  // (divisibility, window size) is checked by the constructor.
  bool IsValid(std::string* why) const;
};

// The geometric SH as a linear operator: rows() = 2 n_valid (x slopes then y slopes, rad), cols() = n^2 (the
// OPD image, row-major, m). Sparse weights (header "Geometric mode"); exact adjoint.
class GeometricSlopeOperator final : public LinearOperator {
 public:
  // amplitude: the n x n pupil amplitude (finite, >= 0, some > 0); diameter_m: D; options:
  // subapertures_across and valid_threshold are used. Throws InvalidArgument naming the bad argument, or when
  // no lenslet is valid.
  GeometricSlopeOperator(const Image& amplitude, double diameter_m, const ShackHartmannOptions& options);

  Index n_valid() const { return rows() / 2; }
  int subapertures_across() const { return subapertures_across_; }
  Index pixels_per_subaperture() const { return p_; }
  // M x M image of 1 (valid) / 0, and each lenslet's illumination fraction sum A / p^2.
  const Image& valid_mask() const { return valid_mask_; }
  const Image& illumination() const { return illumination_; }
  // Lenslet index a * M + b of each valid lenslet, in measurement order.
  const std::vector<Index>& valid_indices() const { return valid_; }

 private:
  void ApplyImpl(ConstRef x, Ref y) const override;
  void ApplyAdjointImpl(ConstRef y, Ref x) const override;

  int subapertures_across_ = 0;
  Index p_ = 0;
  Image valid_mask_;
  Image illumination_;
  std::vector<Index> valid_;
  // Sparse rows: entries start_[v] .. start_[v+1]-1 belong to lenslet v: pixel index, x and y weights [1/m].
  std::vector<Index> start_;
  std::vector<Index> pixel_;
  std::vector<double> weight_x_;
  std::vector<double> weight_y_;
};

class ShackHartmann final : public WavefrontSensor {
 public:
  // amplitude: the n x n pupil amplitude (finite, >= 0, some > 0); diameter_m: D spanned by the grid (> 0).
  // Measures the flat-wavefront reference. Throws InvalidArgument naming the bad argument or options field
  // (also: M not dividing n, fewer than 2 pixels per lenslet, a window wider than one period, kFft with a
  // non-integer q, photon or read noise in geometric mode, no valid lenslet).
  ShackHartmann(const Image& amplitude, double diameter_m, const ShackHartmannOptions& options);
  ~ShackHartmann() override;

  std::string Describe() const override;
  const ShackHartmannOptions& options() const { return options_; }
  double diameter_m() const { return diameter_m_; }
  Index n_valid() const { return geometric_->n_valid(); }
  // Lenslet side d = D / M [m] and pixels per lenslet p.
  double subaperture_m() const { return diameter_m_ / options_.subapertures_across; }
  Index pixels_per_subaperture() const { return geometric_->pixels_per_subaperture(); }
  const Image& valid_mask() const { return geometric_->valid_mask(); }
  const std::vector<Index>& valid_indices() const { return geometric_->valid_indices(); }
  // The geometric operator (also built in diffractive mode: it is the sensor's linear model).
  std::shared_ptr<const GeometricSlopeOperator> geometric_operator() const { return geometric_; }

  // Diffractive mode: spot window size m, FFT period q (0 on the MFT path) and whether the FFT path is used.
  Index spot_size_px() const { return m_; }
  Index fft_size_px() const { return use_fft_ ? q_ : 0; }
  bool uses_fft() const { return use_fft_; }
  // Spot pixel pitch [rad]: s lambda_wfs / d.
  double spot_pixel_scale_rad() const;
  // Expected photo-electrons per frame of each valid lenslet (N_v above), in measurement order.
  const Vector& photons_per_subaperture() const { return photons_; }
  // The m x m spot of valid lenslet v (0-based, measurement order) from the last diffractive measurement, in
  // detected electrons (noise included if that measurement had noise; noise-free spots are scaled to N_v).
  // Throws InvalidArgument in geometric mode or for v out of range.
  Image LastSpot(Index v) const;

 private:
  ShackHartmann(std::shared_ptr<const GeometricSlopeOperator> geometric, const Image& amplitude,
                double diameter_m, const ShackHartmannOptions& options);
  void MeasureRaw(const Image& opd_m, bool noisy, Eigen::Ref<Vector> raw) override;
  void MeasureDiffractive(const Image& opd_m, bool noisy, Eigen::Ref<Vector> raw);

  ShackHartmannOptions options_;
  double diameter_m_;
  std::shared_ptr<const GeometricSlopeOperator> geometric_;
  Vector photons_;
  // Diffractive state.
  Index m_ = 0, q_ = 0;
  bool use_fft_ = false;
  std::vector<Index> lit_start_;      // per valid lenslet: range into the lit_* arrays
  std::vector<Index> lit_pupil_;      // pupil pixel index of each lit pixel
  std::vector<Index> lit_local_;      // index in the lenslet's q x q (FFT) or p x p (MFT) field
  std::vector<double> lit_amp_;       // its amplitude
  std::vector<double> lit_ramp_;      // its phase [rad] of the half-pixel centring tilt (0 for odd m)
  std::vector<double> norm_;          // per lenslet: photons per unit |E^|^2
  std::vector<Index> window_bin_;     // FFT path: bin index in the q x q spectrum of each window pixel
  Vector window_x_, window_y_;        // window pixel offsets from the axis [px]
  std::vector<ComplexImage> fields_;  // per valid lenslet: the (padded) field buffer
  ComplexImage spectrum_;             // FFT path: one lenslet's spectrum, reused for every lenslet
  std::unique_ptr<MatrixFourierTransform> mft_;
  Image spots_;                            // n_valid x m^2, the last measurement's spots [e-]
  std::vector<double> phase_, cos_, sin_;  // per lit pixel: phase [rad] and its cos, sin (scratch)
  std::mt19937_64 poisson_engine_;
  NormalGenerator normal_;
};

}  // namespace aosr
