// The fast "analytic AO" path: long-exposure PSFs of a single-conjugate AO system from the power
// spectral density (PSD) of its residual phase, in the Fourier style of
//   F. Rigaut, J.-P. Veran, O. Lai, "An analytical model for Shack-Hartmann-based adaptive optics
//     systems", Proc. SPIE 3353, 1038 (1998)   [RVL98], and
//   L. Jolissaint, J.-P. Veran, R. Conan, "Analytical modeling of adaptive optics: foundations of the
//     phase spatial power spectrum approach", J. Opt. Soc. Am. A 23, 382 (2006)   [JVC06].
// Natural guide star, infinitely bright unless a WFS noise is given; the science direction may be off the
// guide star's axis (anisoplanatism, section 2); no scintillation. Everything below is phase at the science wavelength lambda (rad, rad^2, rad^2 m^2),
// spatial frequencies f in cycles per metre in the pupil, temporal frequencies nu in Hz.
//
// 1. Turbulence. von Karman phase PSD at lambda, r0 scaled from the reference wavelength as lambda^(6/5):
//        Phi(f) = c r0(lambda)^(-5/3) (|f|^2 + 1/L0^2)^(-11/6),
//        c = (24/5 Gamma(6/5))^(5/6) Gamma(11/6)^2 / (2 pi^(11/3)) = 0.022896   (often rounded to 0.023).
//    The piston bin f = 0 is always left out (it does not affect images).
//
// 2. Residual PSD = fitting + servo-lag + noise + aliasing (uncorrelated terms, as in JVC06):
//    * Control region: the DM corrects spatial frequencies |fx|, |fy| < f_c = 1/(2 d) (square domain of a
//      DM with actuator pitch d on a square grid; optionally the disk |f| < f_c).
//    * fitting  (outside): Phi(f).
//    * servo    (inside):  Phi(f) sum_l w_l |E(f . v_l)|^2, frozen flow: layer l of Cn^2 fraction w_l and
//      wind velocity v_l makes the Fourier component f oscillate at nu = f . v_l. (Option: average over
//      wind directions instead.) E is the loop's rejection transfer function, section 3.
//    * noise    (inside):  sigma_n^2 (lambda_ref/lambda)^2 / A_c * G_n, a white measurement noise of variance
//      sigma_n^2 per frame spread uniformly over the control region (area A_c = (2 f_c)^2 for the square),
//      filtered by the loop: G_n = T int_{-1/2T}^{1/2T} |H_n(nu)|^2 dnu. This is a deliberate simplification
//      of RVL98, whose Shack-Hartmann noise PSD rises as 1/|f|^2 (gradient sensing): the variance is right,
//      its distribution over the corrected halo is flat. The Monte-Carlo path models the SH noise properly.
//    * aliasing (inside):  sum_l w_l sum_{(m,n) != 0} c_mn(f)^2 Phi(f_mn) |H_n(f_mn . v_l)|^2,
//      f_mn = f + (m, n)/d, |m|, |n| <= aliasing_orders. The Shack-Hartmann measures phase differences across
//      a sub-aperture of side d on a lattice of pitch d: in Fourier, G_x(f) = 2i sin(pi fx d) sinc(fy d),
//      G_y likewise (sinc(u) = sin(pi u)/(pi u)); the least-squares Fourier reconstructor
//      R = G^* / |G|^2 then passes the alias f_mn into f with the coefficient (derived here, cf. RVL98;
//      the unit test re-derives it numerically from G)
//          c_mn(f) = (-1)^(m+n) [ fx^2 fy / (fy + n/d) + fx fy^2 / (fx + m/d) ] / |f|^2
//      (the first term is fx^2 when n = 0, the second fy^2 when m = 0). Each alias travels with its own
//      frozen-flow frequency and enters the loop as a measurement, hence the noise transfer H_n.
//      Approximations: temporal aliasing by the frame rate is ignored (nu = f_mn . v stays well below the
//      Nyquist rate 1/(2T) for any sensible wind and pitch), and the reconstructor is the ideal Fourier one.
//    * anisoplanatism (inside; only when field_direction != 0). The science direction theta sees layer l
//      (altitude h_l) displaced by h_l theta (atmosphere.hpp, "Field directions"), i.e. its Fourier component
//      f multiplied by exp(i a_l), a_l = 2 pi f . (h_l theta), while the DM holds H_n applied to the guide
//      star's phase. With frozen flow the residual of layer l at f is Phi w_l |exp(i a_l) - H_n(f . v_l)|^2
//      (the sign of f . v follows from phi(p - v t): a component's temporal frequency is -f . v, and
//      H_n(-nu) = conj H_n(nu)). Subtracting the on-axis servo term |1 - H_n|^2 leaves
//          aniso(f) = Phi(f) sum_l w_l 2 Re[ H_n(f . v_l) (1 - exp(i a_l)) ],
//      which is kept as its own term so that servo-lag stays the on-axis term. This is the joint
//      "anisoservo" form of the Fourier models (B. Neichel, T. Fusco, J.-M. Conan, JOSA A 26, 219 (2009);
//      TIPTOP/P3's fourierModel, Neichel et al. 2021): it includes the servo x anisoplanatism cross term,
//      which is negative downwind (where h theta ~ v x lag the delayed correction fits the science direction
//      better) and positive upwind, and vanishes for an open loop (no correction, nothing to decorrelate).
//      With anisoplanatism_servo_cross_term = false the perfect-loop form is used instead:
//          aniso(f) = Phi(f) sum_l w_l 2 (1 - cos a_l),
//      the standard anisoplanatism filter (Rigaut/Jolissaint analytic models, TIPTOP), whose variance over
//      the whole plane with no control radius is Fried's (theta / theta0)^(5/3) (anisoplanatism.hpp).
//      Both are even in f, so the structure function stays real, and elongated along theta: the PSF's core
//      stretches along the line to the guide star. Fitting, noise and aliasing do not change with theta
//      (the DM is common to all directions and nothing outside the control region is corrected anyway).
//      The filter oscillates with period 1 / (h theta) in f, which the PSD grid (pitch 1/(K D)) must resolve:
//      IsValid requires h_l |theta| <= K D / 4 for every layer.
//
// 3. Loop (hybrid continuous/discrete model, e.g. E. Gendron & P. Lena, A&A 291, 337 (1994); JVC06).
//    Frame period T = 1 / loop_rate_hz, s = 2 pi i nu, z = exp(s T). The WFS averages the residual over one
//    frame, (1 - z^-1)/(s T); after a pure delay of k = loop_delay_frames frames (read-out + computation)
//    the integrator C(z) = g / (1 - z^-1) updates the DM, which holds each command for one frame (zero-order
//    hold (1 - z^-1)/(s T)). So
//        H_ol(nu) = g exp(-s k T) (1 - z^-1) / (s T)^2,    E = 1 / (1 + H_ol),    H_n = H_ol / (1 + H_ol),
//    and the mean lag of the correction is (k + 1) T: T/2 from the WFS average, k T, T/2 from the hold. In
//    discrete time (integer k) the command computed from frame n acts during frame n + k + 1. Example:
//    k = 1 ("one frame of read-out/compute delay") gives a 2 T total lag. The loop must be stable: the
//    discrete closed-loop poles are the roots of z^(k+2) - z^(k+1) + g (1 - a) z + g a (k split into its
//    integer part and a fraction a); IsValid rejects gains whose poles leave the unit circle (e.g. g >= 1
//    for k = 1, g >= 2 for k = 0). For small nu, |E| ~ 2 pi nu T / g: the loop bandwidth is ~ g / (2 pi T).
//
// 4. Structure function and PSF. D_res(rho) = 2 int Phi_res(f) (1 - cos 2 pi f.rho) d^2f is computed by an
//    FFT of the PSD sampled on a P x P grid of pitch df = 1 / (K D) (K = frequency_padding), P = K n for an
//    n-pixel pupil grid, so the FFT lands exactly on the pupil-separation lattice rho = k D/n that the
//    telescope OTF lives on. The grid keeps the disk |f| < f_t = n/(2D) - df (weights ramp over one cell at
//    every boundary, so domain edges need not fall on cell edges); the fitting tail beyond f_t is added
//    analytically (variance and structure function of a power law outside a disk, section 5).
//    Long-exposure PSF (DESIGN.md sec. 1): with the pupil field E = A exp(i 2 pi w / lambda) (w: the DM
//    offset plus static aberrations) and its autocorrelation Gamma(k) = sum_u E(u + k) E*(u) (the
//    unnormalised telescope OTF, by FFT of |FFT E|^2 on a 2n grid: exact, no wrap-around),
//        PSF(alpha) = s^2 / sum A^2 * (1/n^2) sum_k Gamma(k) T(k) exp(-2 pi i (k D/n).alpha / lambda),
//        T(k) = exp(-D_in(k D/n) / 2) exp(-sigma_t^2),
//    evaluated at the requested pixel centres by the MFT (mft.hpp; s = pixel pitch in lambda/D). D_in is the
//    structure function of the grid part (|f| < f_t) and sigma_t^2 the tail's variance: the tail's light
//    is scattered to angles beyond lambda f_t ~ n/2 lambda/D, outside the band the n-pixel pupil grid
//    represents, so it only attenuates. (Sampling exp(-D_t/2) on the lattice instead would fold that light
//    back as a uniform pedestal over the n lambda/D period, the sampled pupil's aliasing.) Normalisation is
//    psf.hpp's: with D_res = 0 this is exactly PsfCalculator (the whole period, n lambda/D wide, sums to 1);
//    with turbulence one period sums to exp(-sigma_t^2), the light that stays within the band, and a
//    finite window holds less (NormaliseToUnitSum makes convolution kernels).
//    Strehl (long exposure, on axis, relative to the same amplitude without any aberration):
//        S = sum_k Gamma(k) T(k) / (sum A)^2  ~  exp(-sigma^2)   (extended Marechal, halo regime).
//
// 5. Fitting tail beyond the disk of radius f_t (the L0 term is kept in the variance, and neglected in the
//    shape, relative error < (11/6) / (f_t L0)^2):
//        sigma_t^2 = (6 pi / 5) c r0^(-5/3) (f_t^2 + 1/L0^2)^(-5/6),
//        D_t(rho)  = 2 sigma_t^2 q(2 pi f_t |rho|),  q(x) = (5/3) int_1^inf t^(-8/3) (1 - J0(x t)) dt,
//    q(0) = 0, q(inf) = 1; q is computed by quadrature for x < 30 and from its asymptotic expansion
//    q ~ 1 + (5/3) [J1(x)/x - (11/3) J0(x)/x^2 - (121/9) J1(x)/x^3] beyond.
//
// Grid requirements: the control region must fit inside the grid's disk with a cell to spare,
// f_t >= sqrt(2) f_c + df (square) or f_c + df (disk); for the pupil grid this means n >= sqrt(2) D/d + 4/K
// pixels across the pupil (23-24 for 16 actuators across); and n <= 4096/K bounds the (K n)^2 PSD grid.
//
// Cost: building an AnalyticAoResidual evaluates the PSD on (K n)^2 cells (the loop terms only on the
// ~(K D/d)^2 controlled ones) and one FFT; each PSF then costs one 2n x 2n FFT pair and a
// (2n-1)^2 -> rows x cols MFT (one core: ~3 ms for n = 64 and ~10 ms for n = 128 onto 128 x 128, after
// the FFT plans are cached; see the physics test's timing line).
//
// Errors: public functions validate options and arguments and throw aosr::InvalidArgument naming the field.
#pragma once

#include <string>
#include <vector>

#include "aosr/ao/atmosphere.hpp"
#include "aosr/core/image.hpp"
#include "aosr/optics/mft.hpp"
#include "aosr/optics/psf.hpp"

namespace aosr {

// The set of spatial frequencies the DM/reconstructor corrects.
enum class ControlDomain {
  kSquare,  // |fx|, |fy| < 1/(2d): a square actuator grid (Fried geometry), the usual case.
  kCircle,  // |f| < 1/(2d): for circular-mask reconstructors, and to check against closed forms.
};


struct AnalyticAoOptions {
  // --- Telescope ---
  // Telescope diameter D [m], > 0 and finite. Default 8 m (the VLT/Gemini class the project targets).
  double diameter_m = 8.0;

  // --- Deformable mirror ---
  // Actuator pitch d [m] (projected on the pupil), > 0 and < D/2. Control radius f_c = 1/(2d).
  // Default 0.5 m: 16 actuators across 8 m (17 x 17 in Fried geometry).
  double actuator_pitch_m = 0.5;
  // Shape of the corrected frequency domain. Default kSquare, that of a square actuator grid.
  ControlDomain control_domain = ControlDomain::kSquare;

  // --- Atmosphere ---
  // Fried parameter r0 [m] at reference_wavelength_m, along the line of sight; > 0. +infinity means no
  // turbulence (every PSD term vanishes): a diffraction-limited reference. Default 0.15 m (good site).
  double r0_m = 0.15;
  // Wavelength [m] at which r0_m and wfs_noise_rad2 are given, > 0. r0 scales as lambda^(6/5).
  // Default 0.5 um, where r0 is conventionally quoted (and where visible WFSs work).
  double reference_wavelength_m = 0.5e-6;
  // von Karman outer scale L0 [m], > 0; +infinity gives the Kolmogorov PSD. Default 25 m (median of
  // site measurements). Mostly reduces the low-order errors; the fitting error barely changes.
  double outer_scale_m = 25.0;
  // Turbulent layers, at least one; their cn2_fraction must sum to 1 (within 1e-6). A single layer of
  // fraction 1 is the "effective wind speed" model. Default: one ground layer at 10 m/s along +x.
  std::vector<Layer> layers = {Layer{0.0, 1.0, 10.0, 0.0}};  // atmosphere.hpp; altitude unused on axis
  // When true, the servo-lag and aliasing terms average |E|^2 over wind directions uniformly
  // (directions in `layers` are ignored): a round servo halo for unknown directions. Default false: the
  // layers' directions are used (the halo is elongated along the wind, as in a simulation).
  bool average_wind_direction = false;

  // --- Control loop (section 3) ---
  // Frame rate 1/T [Hz] of the WFS and controller, > 0 and finite. Default 1000 Hz.
  double loop_rate_hz = 1000.0;
  // Integrator gain g, >= 0 and within the stability limit for the delay (g < 1 for k = 1). 0 means
  // open loop: no correction inside the control region. Default 0.4, a typical robust setting.
  double loop_gain = 0.4;
  // Pure delay k [frames] between the end of the WFS integration and the start of the DM update
  // (read-out + computation), in [0, 20]; fractional values allowed. The total mean lag is (k + 1) T
  // (section 3). Default 1.
  double loop_delay_frames = 1.0;

  // --- Wavefront sensor ---
  // Variance [rad^2 at reference_wavelength_m] of the measurement noise on one frame's reconstructed phase
  // over the control region (before temporal filtering), >= 0. Default 0: a bright guide star.
  double wfs_noise_rad2 = 0.0;
  // Include the Shack-Hartmann aliasing term. Default true (it is ~1/3 of the fitting error).
  bool aliasing = true;

  // --- Science ---
  // Science wavelength lambda [m], > 0. The PSD terms, budget and structure function are phase at this
  // wavelength, and PSFs must be sampled at it. Default 2.2 um (K band).
  double science_wavelength_m = 2.2e-6;

  // --- Science direction (anisoplanatism, section 2) ---
  // Direction of the science target from the guide star [rad] (x along columns, y along rows); finite, and
  // with altitude * |direction| <= frequency_padding * diameter_m / 4 for every layer (the PSD grid must
  // resolve the anisoplanatism filter). Default (0, 0): on axis, exactly the model without anisoplanatism.
  FieldDirection field_direction;
  // Off axis: include the servo-lag x anisoplanatism cross term (true, default: the joint form, section 2)
  // or use the perfect-loop filter 2 (1 - cos) (false: the issue's / the usual budget's anisoplanatism term).
  bool anisoplanatism_servo_cross_term = true;

  // --- Numerics (GalSim-style accuracy knobs) ---
  // Frequency padding K, in [2, 64]: the PSD grid pitch is 1/(K D), i.e. the covariance is periodic over
  // K D. Larger K resolves the low frequencies (servo, L0) better at (K n)^2 cost. Default 4: the
  // budget changes by < 1% from K = 4 to 8 for typical systems (unit test).
  int frequency_padding = 4;
  // Aliasing orders M in [1, 10]: the sum runs over |m|, |n| <= M. The alias terms fall as |f_mn|^(-11/3),
  // so M = 3 leaves < 1% of the aliasing variance out. Default 3.
  int aliasing_orders = 3;

  // r0 [m] at `wavelength_m`: r0_m (wavelength_m / reference_wavelength_m)^(6/5).
  double R0At(double wavelength_m) const;
  // Control radius f_c = 1/(2 d) [cycles/m].
  double ControlRadius() const { return 0.5 / actuator_pitch_m; }

  // True when all fields are in range and the loop is stable; otherwise false and `why` (if non-null)
  // names the bad field ("layers[1].cn2_fraction = ...", "loop_gain = ...").
  bool IsValid(std::string* why) const;
};

// The closed-loop transfer functions at one temporal frequency (section 3).
struct LoopTransfer {
  Complex open_loop;  // H_ol(nu); infinite at nu = 0 for g > 0 (reported as a huge value)
  Complex rejection;  // E(nu) = 1 / (1 + H_ol): residual / turbulence
  Complex noise;      // H_n(nu) = H_ol / (1 + H_ol) = 1 - E: DM / measurement
};

// Loop transfer functions at temporal frequency nu_hz (finite; any sign). Throws InvalidArgument for
// invalid options or a non-finite frequency.
LoopTransfer AnalyticAoLoopTransfer(const AnalyticAoOptions& options, double nu_hz);

// Noise propagation gain G_n = T int_{-1/(2T)}^{1/(2T)} |H_n(nu)|^2 dnu: the closed-loop residual variance
// per unit variance of white per-frame measurement noise (~ g/2 for small gains, 0 for g = 0).
double AnalyticAoNoiseGain(const AnalyticAoOptions& options);

// Largest modulus of the discrete closed-loop poles (section 3) for gain g >= 0 and delay k in [0, 20]
// frames: the loop is stable when < 1.
double AnalyticAoLoopSpectralRadius(double gain, double delay_frames);

// The error budget: variances [rad^2] of the residual phase at `wavelength_m`, term by term.
struct AnalyticAoErrorBudget {
  double wavelength_m = 0.0;
  double fitting_rad2 = 0.0;   // outside the control region, including the analytic tail
  double servo_rad2 = 0.0;     // servo-lag (temporal) error inside the control region
  double noise_rad2 = 0.0;     // propagated WFS noise
  double aliasing_rad2 = 0.0;  // propagated WFS aliasing
  double anisoplanatism_rad2 = 0.0;  // off axis only (section 2): the increase over the on-axis residual

  double TotalRad2() const {
    return fitting_rad2 + servo_rad2 + noise_rad2 + aliasing_rad2 + anisoplanatism_rad2;
  }
  // RMS optical path [nm] of a phase variance at wavelength_m: sqrt(rad2) lambda / (2 pi) * 1e9.
  double Nm(double rad2) const;
  double TotalNm() const { return Nm(TotalRad2()); }
  // exp(-total): the extended Marechal Strehl.
  double MarechalStrehl() const;
  // One line per term in nm RMS and rad^2, then the total and exp(-sigma^2).
  std::string BriefReport() const;
};

// The residual phase PSD terms [rad^2 m^2 at the science wavelength] on a centred P x P frequency grid:
// cell (i, j) holds f = ((j - P/2) df, (i - P/2) df) = (fx, fy) (x along columns, image.hpp's layout),
// zero frequency at (P/2, P/2). Cells outside the disk |f| < tail_radius_per_m are 0 (ramped over one
// cell); the fitting PSD beyond it is represented by fitting_tail_rad2 and the analytic D_t of section 5.
struct ResidualPsd {
  double wavelength_m = 0.0;
  double frequency_step_per_m = 0.0;  // df [cycles/m]
  double tail_radius_per_m = 0.0;     // f_t [cycles/m]
  Image fitting;
  Image servo;
  Image noise;
  Image aliasing;
  Image anisoplanatism;  // off axis only (section 2); empty on axis
  double fitting_tail_rad2 = 0.0;  // variance of the fitting PSD beyond f_t [rad^2]

  Index grid_n() const { return fitting.rows(); }
  // fitting + servo + noise + aliasing (+ anisoplanatism off axis) on the grid (without the tail).
  Image Total() const;
  // Sums times df^2 (plus the tail for fitting).
  AnalyticAoErrorBudget Budget() const;
};

// The PSD terms on a grid_n x grid_n grid of pitch frequency_step_per_m (grid_n even, >= 8; pitch > 0).
// The grid's disk f_t = (grid_n/2 - 1) df must hold the control region with a cell to spare (see the
// grid requirements above). Throws InvalidArgument for invalid options or grids.
ResidualPsd ComputeResidualPsd(const AnalyticAoOptions& options, Index grid_n, double frequency_step_per_m);

// The error budget on a grid chosen from the options alone: df = 1/(K D), f_t ~ sqrt(2) f_c + 2 df (the
// analytic tail covers the rest). Independent of any pupil sampling; an AnalyticAoResidual's budget, on
// its pupil-matched grid, agrees to ~1e-4 (the grids differ only in where the analytic tail starts).
AnalyticAoErrorBudget ComputeAnalyticAoErrorBudget(const AnalyticAoOptions& options);

// The residual statistics of one AO configuration on the separation lattice of an n-pixel pupil grid
// (pupil.hpp): the PSD on a (K n)^2 grid of pitch 1/(K D) and the structure function D_res. Immutable.
class AnalyticAoResidual {
 public:
  // pupil_n: pixels across D (see the grid requirements above). Throws InvalidArgument for invalid
  // options or a pupil grid too coarse for the control region.
  AnalyticAoResidual(const AnalyticAoOptions& options, Index pupil_n);

  const AnalyticAoOptions& options() const { return options_; }
  Index pupil_n() const { return pupil_n_; }
  const ResidualPsd& psd() const { return psd_; }
  const AnalyticAoErrorBudget& budget() const { return budget_; }
  // Total residual variance [rad^2 at the science wavelength], all terms and the tail.
  double variance_rad2() const { return budget_.TotalRad2(); }
  // D_res [rad^2 at the science wavelength] on the (2n-1) x (2n-1) lattice of separations
  // rho = ((j - (n-1)) D/n, (i - (n-1)) D/n) for pixel (i, j): rho = 0 at the centre (n-1, n-1),
  // image.hpp's centred-kernel rule. D_res(0) = 0; D_res -> 2 variance_rad2() where the residual
  // decorrelates.
  const Image& structure_function() const { return structure_function_; }
  // The part of D_res from the PSD grid alone (|f| < f_t, without the analytic tail), same lattice. The
  // PSF uses exp(-D_in/2) exp(-sigma_t^2) (header section 4).
  const Image& in_band_structure_function() const { return in_band_structure_function_; }
  // Lattice pitch D/n [m].
  double separation_step_m() const { return options_.diameter_m / static_cast<double>(pupil_n_); }

 private:
  AnalyticAoOptions options_;
  Index pupil_n_;
  ResidualPsd psd_;
  AnalyticAoErrorBudget budget_;  // psd_.Budget()
  Image structure_function_;
  Image in_band_structure_function_;
};

// One long-exposure PSF and its summary numbers.
struct AnalyticAoPsf {
  Image psf;                            // sampling.rows x sampling.cols, psf.hpp's normalisation
  double strehl = 0.0;                  // on-axis long-exposure Strehl (section 4), w included
  double residual_variance_rad2 = 0.0;  // AO residual only (w excluded), at the science wavelength
  double residual_rms_nm = 0.0;         // the same as optical path [nm RMS]
};

// Long-exposure PSFs for one AO configuration, pupil grid and focal-plane sampling; the residual
// statistics and the MFT are computed once. Immutable and thread-safe after construction.
class AnalyticAoPsfCalculator {
 public:
  // The pupil grid spans options.diameter_m with pupil_n pixels. sampling.wavelength_m must equal
  // options.science_wavelength_m (relative 1e-9). Throws InvalidArgument naming the bad argument.
  AnalyticAoPsfCalculator(const AnalyticAoOptions& options, Index pupil_n, const PsfSampling& sampling);

  // PSF of amplitude A and OPD w = w_dm,i + w_static [m] (both pupil_n x pupil_n, w read where A > 0)
  // under the AO residual. A finite, >= 0, not all zero. Throws InvalidArgument otherwise.
  AnalyticAoPsf Compute(const Image& amplitude, const Image& opd_m) const;

  const AnalyticAoResidual& residual() const { return residual_; }
  const PsfSampling& sampling() const { return sampling_; }

 private:
  AnalyticAoResidual residual_;
  PsfSampling sampling_;
  MatrixFourierTransform mft_;
  Image attenuation_;  // exp(-D_in/2 - sigma_t^2) on the (2n-1)^2 separation lattice
};

// One-shot AnalyticAoPsfCalculator(options, amplitude.rows(), sampling).Compute(amplitude, opd_m).
AnalyticAoPsf AnalyticAoPsfFromPupil(const AnalyticAoOptions& options, const Image& amplitude,
                                     const Image& opd_m, const PsfSampling& sampling);

}  // namespace aosr
