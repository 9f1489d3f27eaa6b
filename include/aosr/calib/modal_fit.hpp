// Modal-gain calibration: the forward model of a camera image of a point source while the DM pokes one mode,
// and its least-squares fit with Ceres (Problem + Levenberg-Marquardt, analytic Jacobian, ceres::Covariance).
//
// ## The measurement
//
// A point source (fibre, pinhole) is imaged through the pupil while the DM applies a_i of mode j (commanded RMS
// OPD in metres; Z_j orthonormal, zernike.hpp, or an actuator pattern's OPD per unit command). The DM applies
// g·a_i instead, g the *modal gain* (applied / commanded power; 1 for a perfectly calibrated DM). The bench
// adds a static non-common-path aberration w_s = Σ_k c_k Z_k (k = 4..K: tip/tilt is the source position), the
// source has a finite size, and the source sits at an unknown sub-pixel position (dy, dx).
//
// ## The model (one image i)
//
//     φ_i(u)  = 2π/λ · (g a_i M_j(u) + Σ_k c_k Z_k(u)) + 2π s (dx u_x + dy u_y)          pupil phase [rad]
//     E_i(u)  = A(u) exp(i φ_i(u))                                                       pupil field
//     I_i     = s_f² n² / Σ A² · |MFT(E_i)|²                                             PSF on the fine grid
//     m_i     = F_i q² K_y(v) I_i K_x(v)ᵀ + b_i                                          camera image [ADU]
//
// u is the pupil coordinate in units of D (mft.hpp), s the camera pixel in λ/D, so the ramp moves the PSF by
// (dy, dx) camera pixels (the MFT's sign rule). The PSF is point-sampled by the MFT on a fine grid of pitch
// s_f = s/q (q ≥ 1 chosen so that s_f ≤ 0.45 λ/D: the fine grid is above Nyquist, so the samples determine the
// band-limited PSF exactly), padded by `padding_px` camera pixels beyond the window on each side. K(v) (W·q_f
// → W rows, separable) is the exact convolution of that band-limited PSF with the camera pixel's box (width q
// fine samples) and the source's Gaussian of variance v = σ² [camera px²], followed by sampling at the camera
// pixel centres: in Fourier space the transfer is
//     H(f) = sinc(q f) · exp(−2π² v q² f²) · T(f)        (f in cycles per fine sample),
// with T a cosine taper from the PSF's cutoff f_c = s_f to 1/2 (T = 1 where the PSF has power, so it changes
// nothing there; it makes the discrete kernel decay fast so the periodic padding does not wrap). F_i is the
// source flux of image i (ADU over the whole focal plane, of which the window holds ≤ 1), b_i its background
// per pixel [ADU]. The window's centre pixel (W_y/2, W_x/2) is the optical axis for (dy, dx) = (0, 0).
//
// ## The fit (one mode j: its images and its reference frames)
//
//     minimise  Σ_i Σ_p ρ( w_ip (m_ip − y_ip)² ),    w_ip = 1 / Var[y_ip]  (0 for masked pixels),
//
// over θ = (g, dy, dx, c_4..c_K, v ≥ 0) shared by all images of the mode and (F_i, b_i) per image. ρ is
// Huber's loss applied per pixel (ρ(s) = s for √s ≤ a, 2a√s − a² beyond; `huber_threshold` a in noise σ),
// implemented by handing Ceres the pseudo-residuals r̃ = sign(r)·√ρ(r²) and their exact derivatives, so the
// Gauss-Newton model of Σρ is Ceres' own (Ceres' LossFunction would act on a whole image's squared norm).
// The variance is the detector model Var = (m − bias)/gain + (read/gain)² ADU²: first from the data (y clipped
// at 0), then, in `reweight_passes` further solves, from the previous fit's model (data-based weights bias the
// flux low by ~1 ADU per pixel at low counts; the model's do not).
//
// Jacobian (analytic, no automatic differentiation over images). For a pupil-phase parameter θ with
// ∂φ/∂θ = P_θ(u):
//     ∂I/∂θ = s_f² n²/ΣA² · 2 Re( conj(Ê) · MFT(i E P_θ) ),      Ê = MFT(E),
//     P_g = 2π/λ · a_i M_j,   P_{c_k} = Z_k (c in radians of RMS phase),   P_dx = 2π s u_x,   P_dy = 2π s u_y,
// one extra MFT per parameter; ∂m/∂v = F q² (K_y' I K_xᵀ + K_y I K_x'ᵀ) with K' the transfer times −2π² q² f²;
// ∂m/∂F = q² K_y I K_xᵀ, ∂m/∂b = 1. The unit tests compare it with central differences.
//
// Degeneracies the parametrisation avoids or states:
//  * tip/tilt static terms equal the position (excluded: the static modes start at Z4);
//  * a per-image position would absorb a tip/tilt poke, so one position is shared by all images of a mode;
//  * twin image: |F{A e^{iφ}}|² is unchanged by φ(u) → −φ(−u) (a 180° rotation), which flips the sign of every
//    even-m term (defocus, astigmatism, spherical) together with g of an even-m mode. The fit starts at g = 1 and
//    c = 0 and stays on the physical branch (g > 0); a static aberration with ±a pokes (phase diversity) breaks
//    the symmetry for everything but the joint sign.
//
// Uncertainties: ceres::Covariance (DENSE_SVD) of the final solve, i.e. (J̃ᵀJ̃)⁻¹ of the whitened, robustified
// residuals, multiplied by max(1, χ²/dof) when `scale_covariance_by_chi2` (a noise model that underestimates
// the scatter then widens the error bars instead of leaving them optimistic).
//
// Conventions written once: amplitudes and static coefficients are RMS OPD in metres in the API (radians only
// inside the solver); positions in camera pixels; images (y, x) row-major in ADU after dark subtraction; a
// pixel with valid = 0 (bad, NaN) is never read. Bad input throws InvalidArgument before Ceres is called;
// non-convergence is reported in the result, not thrown.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "aosr/core/image.hpp"
#include "aosr/optics/mft.hpp"
#include "aosr/solvers/summary.hpp"

namespace aosr {

// The optics a calibration image is formed with.
struct CalibrationOptics {
  // Wavelength λ of the source [m]; > 0.
  double wavelength_m = 0.0;
  // Camera pixel pitch s in λ/D at that wavelength; > 0. The paper bench's unbinned 5.86 µm pixel at f = 400 mm
  // is 0.3115 λ/D (Nyquist: 0.5). Coarser pixels are handled by oversampling the model (q above).
  double pixel_lambda_over_d = 0.0;
  // Central obstruction (fraction of D) of the circular pupil, in [0, 1).
  double obstruction = 0.0;
  // Pupil grid size n of the model, in [16, 512]. 64 samples Z_j up to j ~ 30 and phase slopes of a few radians
  // per pupil pixel's worth of image motion; the fit cost grows as n².
  Index pupil_px = 64;

  bool IsValid(std::string* why) const;
};

// Parameters of the model for one image (see the top of the file).
struct ModalImageParameters {
  double amplitude_m = 0.0;             // applied amplitude g·a_i of the poked mode [m RMS OPD]
  double dy_px = 0.0, dx_px = 0.0;      // source position relative to the window centre [camera px]
  std::vector<double> static_m;         // c_k for the model's static modes [m RMS OPD]
  double source_sigma_px = 0.0;         // Gaussian source σ [camera px], >= 0
  double flux = 1.0;                    // F_i [ADU over the focal plane]
  double background = 0.0;              // b_i [ADU per pixel]
};

// The image model of one mode on one window. Immutable after construction; Render/Jacobian are thread-safe.
class ModalImageModel {
 public:
  // mode_shape: the poked mode's OPD per unit amplitude on the pupil_px grid (Zernike(j, n) or a DM pattern's
  // OPD per unit command); static_modes: Noll indices (each >= 4) of the static aberration terms; window: the
  // camera image shape (both sides in [8, 1024]); padding_px in [0, 256]; oversampling q in [0, 8] (0: the
  // smallest q with s/q <= 0.45). Throws InvalidArgument naming the bad argument.
  ModalImageModel(const CalibrationOptics& optics, const Image& mode_shape, std::vector<int> static_modes,
                  Shape window, int padding_px = 8, int oversampling = 0);

  // The modelled camera image m [ADU] (window-shaped).
  Image Render(const ModalImageParameters& p) const;

  // Render plus the derivatives needed by the fit, each window-shaped (empty Image when not requested):
  // ∂m/∂(applied amplitude in radians of RMS phase), ∂m/∂dy, ∂m/∂dx, ∂m/∂c_k (radians), ∂m/∂v (v = σ²),
  // ∂m/∂F, and ∂m/∂b is 1.
  struct Derivatives {
    Image d_amplitude_rad;
    Image d_dy, d_dx;
    std::vector<Image> d_static_rad;
    Image d_variance;
    Image d_flux;
  };
  struct Request {
    bool amplitude = false, position = false, static_terms = false, variance = false, flux = false;
  };
  Image RenderWithDerivatives(const ModalImageParameters& p, const Request& request, Derivatives* d) const;

  const CalibrationOptics& optics() const { return optics_; }
  const std::vector<int>& static_modes() const { return static_modes_; }
  Shape window() const { return window_; }
  int oversampling() const { return q_; }
  // Radians of RMS phase per metre of RMS OPD: 2π/λ.
  double RadiansPerMetre() const;

 private:
  // K (window side × fine side) and, if wanted, ∂K/∂v for one axis.
  void AxisKernel(Index out, Index fine, double variance_px2, Eigen::MatrixXd* k, Eigen::MatrixXd* dk) const;

  CalibrationOptics optics_;
  std::vector<int> static_modes_;
  Shape window_;
  int q_ = 1;
  Shape fine_;                // MFT output (fine samples)
  Image amplitude_;           // A on the pupil grid
  Image mode_shape_;          // M_j
  std::vector<Image> static_shapes_;
  Image u_x_, u_y_;           // pupil coordinates in units of D
  double intensity_scale_ = 1.0;
  std::shared_ptr<MatrixFourierTransform> mft_;
};

// One image of a fit: the frame, its validity mask and the commanded amplitude of the poked mode.
struct ModalFitImage {
  const Image* adu = nullptr;    // ADU after dark subtraction, window-shaped
  const Image* valid = nullptr;  // 1 usable, 0 masked; may be null (all usable)
  double commanded_m = 0.0;      // a_i [m RMS OPD]; 0 for a reference (flat) frame
};

// Detector noise model for the weights (Var = (m − bias)/gain + (read/gain)²; bias already removed here).
struct NoiseModelParameters {
  double gain_e_per_adu = 1.0;  // > 0
  double read_noise_e = 0.0;    // >= 0
};

struct ModalFitOptions {
  // Highest Noll index of the static aberration fitted as c_4..c_K (phase diversity); 0 or 3 fits none. In
  // {0, 3, 4, ..., 37}. Default 8: defocus, astigmatism and coma, the usual non-common-path terms; each one
  // costs an extra MFT per image and iteration.
  int static_max_noll = 8;
  // Fit the source's Gaussian σ (else fixed at `source_sigma_px`). Default on: a fibre or pinhole is rarely a
  // point at 0.3 λ/D pixels, and an unmodelled size looks like defocus.
  bool fit_source_size = true;
  double source_sigma_px = 0.0;  // start (or fixed) value, >= 0
  // Per-pixel Huber threshold a in noise σ (> 0), or 0 for plain least squares. Default 3: hot pixels and
  // cosmic rays stop pulling the fit, Gaussian noise is barely touched (2.7 ‰ of pixels beyond 3σ).
  double huber_threshold = 3.0;
  // Further solves with weights from the previous model (see the top of the file), in [0, 5]. Default 1.
  int reweight_passes = 1;
  // Levenberg-Marquardt iteration limit per solve (>= 1) and Ceres' tolerances (each in [0, 1)).
  int max_iterations = 100;
  double function_tolerance = 1e-12;
  double parameter_tolerance = 1e-10;
  double gradient_tolerance = 1e-12;
  // Widen the covariance by max(1, χ²/dof). Default on (see the top of the file).
  bool scale_covariance_by_chi2 = true;
  // Model sampling (ModalImageModel): padding in camera pixels and oversampling (0: automatic).
  int padding_px = 8;
  int oversampling = 0;

  bool IsValid(std::string* why) const;
};

// Initial or fixed values for a fit (unset optional values are estimated from the data).
struct ModalFitStart {
  double gain = 1.0;
  bool position_given = false;
  double dy_px = 0.0, dx_px = 0.0;
  std::vector<double> static_m;  // empty: zeros
  double source_sigma_px = -1;   // < 0: options.source_sigma_px
  // Hold these at their start values (the per-amplitude fits hold everything but g and the photometry).
  bool fix_position = false, fix_static = false, fix_source_size = false;
};

struct ModalFitResult : SolverSummary {
  // SolverSummary: method "modal-fit"; termination kConverged / kMaxIterations / kFailed (a non-finite cost,
  // a failed covariance: then sigmas are NaN-free zeros and the message says why); final_cost = ½ Σ ρ at the
  // solution (Ceres' cost); frame_residual_rms = RMS of the whitened residual per image (≈ 1 for a good fit).
  double gain = 1.0, gain_sigma = 0.0;
  double dy_px = 0.0, dx_px = 0.0, dy_sigma_px = 0.0, dx_sigma_px = 0.0;
  std::vector<int> static_modes;                         // Noll indices of the static terms
  std::vector<double> static_m, static_sigma_m;          // c_k and σ [m RMS OPD]
  double source_sigma_px = 0.0, source_sigma_sigma_px = 0.0;
  std::vector<double> flux, background;                  // per image [ADU]
  double chi2 = 0.0;       // Σ w r² (not robustified) at the solution
  Index dof = 0;           // valid pixels − free parameters
  double reduced_chi2 = 0.0;
  double covariance_scale = 1.0;  // the factor applied to the covariance
  std::vector<Image> model;       // modelled images (same order as the input)
};

// Fits one mode's images. `mode_shape` as in ModalImageModel (per unit amplitude, metres per metre). Validates
// everything before Ceres: at least one image; equal window shapes; masks of the window's shape; finite pixels
// where valid (non-finite ones must be masked: LoadCalibrationSet does it); at least one image with a non-zero
// amplitude (else g is undetermined); a signal above the background in every image; more valid pixels than
// parameters. Throws InvalidArgument naming the problem.
ModalFitResult FitModalImages(const CalibrationOptics& optics, const Image& mode_shape,
                              const std::vector<ModalFitImage>& images, const NoiseModelParameters& noise,
                              const ModalFitOptions& options, const ModalFitStart& start = ModalFitStart());

}  // namespace aosr
