// A continuous face-sheet deformable mirror (DM) with Gaussian influence functions on a square actuator grid,
// as a LinearOperator from actuator commands to the pupil OPD, with stroke clipping and a regularised
// least-squares fitter.
//
// Units. Commands and the OPD are WAVEFRONT optical path differences in metres (what the rest of aosr calls
// OPD: phase = 2 pi OPD / lambda). A reflective surface displaced by s adds 2 s of wavefront OPD; callers who
// think in mirror-surface (mechanical) terms multiply by 2. The command of an actuator is the OPD at its own
// position when all other commands are zero (the influence function peaks at 1).
//
// Geometry (pupil.hpp's grid: n x n pixels spanning D, pixel centres at (k - (n-1)/2) D/n, metres from the
// pupil centre). Actuators sit on an N x N square grid of pitch d centred on the pupil:
//     x_b = (b - (N-1)/2) d,   y_a = (a - (N-1)/2) d,      a, b = 0 .. N-1  (a: row/y, b: column/x).
// In Fried geometry with an M x M Shack-Hartmann, N = M + 1 and d = D / M: actuators at the subaperture
// corners, the outer ones exactly on the square circumscribing the pupil (e.g. 17 x 17 actuators for 16 x 16
// subapertures on an 8 m telescope: d = 0.5 m).
//
// Active actuators. Actuator (a, b) at distance r_ab from the pupil centre is active (controlled, i.e. one
// column of the operator) when
//     R_obs - m d  <=  r_ab  <=  R + m d,      R = D/2,  R_obs = obstruction * R,  m = active_margin_pitch,
// i.e. when it lies within m pitches of the illuminated annulus. The default margin 1/sqrt(2) (half a
// subaperture diagonal in Fried geometry) keeps the actuators on and just outside the rim, which the
// subapertures crossed by the rim sense, and drops the corners of the grid, which see no light. For the
// 17 x 17 / 8 m example it gives 241 active actuators (tested). A larger margin on a larger grid (e.g. 19 x
// 19 with margin 1.5: one ring of actuators beyond the rim) fits the rim much better: the fitting tests show
// the bare Fried grid's low-order fits are rim-limited at 1 - 2% RMS, the extended grid's at the
// lattice-ripple floor (below). Inactive actuators are held at 0; they are not part of the command vector.
// Command vectors list the active actuators in row-major grid order (a, then b); ActiveMask() and
// CommandsToGrid() map them back to the N x N grid.
//
// Influence functions. Actuator (a, b) deforms the wavefront by
//     h_ab(x, y) = exp(ln(c) ((x - x_b)^2 + (y - y_a)^2) / d^2),
// a Gaussian whose value one pitch away is the coupling c (typically 0.1 - 0.3 for face-sheet DMs; 0.15 by
// default). Because a 2-D Gaussian factorises, h_ab(x, y) = g(x - x_b) g(y - y_a) with g(t) = exp(ln(c)
// t^2/d^2), and the OPD of commands C (an N x N grid, zeros at inactive actuators) is EXACTLY the matrix
// product
//     W = G_y C G_x^T,      G_y(i, a) = g(y_i - y_a)  (n x N),   G_x(k, b) = g(x_k - x_b)  (n x N),
// costing N n (N + n) multiply-adds (0.3 M for N = 17, n = 128) instead of N^2 n^2 for dense influence
// images, with no truncation error. The adjoint is C' = G_y^T W G_x gathered at the active actuators.
// (G_y = G_x here because grid and pupil are both square and centred; the code keeps one matrix.)
//
// Fitting (DmFitter). For a requested OPD w and pupil weights A (the amplitude, or any weights >= 0), the
// commands minimise the Tikhonov-regularised least-squares cost
//     J(c) = sum_pixels A (H c - w)^2 + mu |c|^2,      mu = regularisation * trace(H^T A H) / n_active,
// i.e. c = (H^T A H + mu I)^-1 H^T A w. The normal matrix is assembled once from the separable factors,
//     (H^T A H)[(a,b),(a',b')] = sum_k G_x(k,b) G_x(k,b') sum_i A(i,k) G_y(i,a) G_y(i,a'),
// in O(N^2 n^2 + N^4 n) operations, and Cholesky-factorised once; each Fit() costs one adjoint and two
// triangular solves. The relative weight makes `regularisation` independent of the grid size and units.
//
// Lattice ripple. Even a constant is not exactly reachable: by Poisson summation a lattice of Gaussians
// sum_k g(x - k d) carries a ripple of relative amplitude 2 G(1/d)/G(0) = 2 exp(-pi^2 / ln(1/c)) per axis (G:
// the Fourier transform of g), which no command pattern removes because it is the alias of the commands' own
// zero frequency. Smooth modes therefore fit to an RMS floor of ~ 2 exp(-pi^2 / ln(1/c)) of their RMS: 2.8%
// for c = 0.1, 1.1% for c = 0.15, 0.16% for 0.25, 0.055% for 0.3 (measured tip/tilt/defocus fits sit at 1.0
// - 1.6x this floor when actuators extend one pitch beyond the rim).
//
// Fitting error. A DM of pitch d cannot follow turbulence finer than ~2d; the residual phase variance of an
// optimal fit to Kolmogorov turbulence is sigma_F^2 = a_F (d / r0)^(5/3) rad^2, with a_F ~ 0.23 - 0.28 for
// Gaussian influence functions (R. H. Hudgin, "Wave-front compensation error due to finite corrector-element
// size", J. Opt. Soc. Am. 67, 393-395 (1977); J. W. Hardy, "Adaptive Optics for Astronomical Telescopes",
// Oxford (1998)). Measured with this fitter (17 x 17 Fried DM, 128 Kolmogorov pupils, whole pupil):
// a_F = 0.352 (c = 0.1), 0.256 (0.15), 0.237 (0.2), 0.231 (0.25), 0.228 (0.3), +-0.002. The corrected PSF's
// halo starts at the control radius lambda / (2 d) = (N - 1)/2 lambda/D along the grid axes (the corrected
// region is a square): measured 7.84 lambda/D for N = 17 (the half-way point of the rise; tests/optics/
// deformable_mirror_physics_test.cpp).
//
// Cost (one core, Release, N = 17, n = 128): Apply ~0.035 ms, ApplyAdjoint ~0.04 ms; DmFitter set-up ~8 ms,
// Fit ~0.1 - 0.2 ms.
//
// Thread safety: both classes are immutable after construction; Apply/Fit may run concurrently.
#pragma once

#include <Eigen/Cholesky>
#include <Eigen/Core>
#include <memory>
#include <string>
#include <vector>

#include "aosr/core/linear_operator.hpp"
#include "aosr/optics/pupil.hpp"

namespace aosr {

struct DeformableMirrorOptions {
  // Actuators across the square grid, N >= 2 (N x N actuators). Fried geometry: subapertures across + 1.
  int actuators_across = 0;
  // Actuator pitch d projected onto the pupil [m]; > 0 and finite. Fried geometry: D / (N - 1).
  double pitch_m = 0.0;
  // Influence of an actuator at its nearest neighbour's position (fraction of its own peak), in (0, 1).
  // Face-sheet DMs: 0.1 - 0.3; 0.15 is a common design value (stiff enough to keep actuators independent,
  // soft enough to avoid a "quilted" surface).
  double coupling = 0.15;
  // Largest |command| an actuator can reach [m of wavefront OPD]; > 0 and finite. The default 5e-6 m is a
  // +-2.5 um mechanical stroke (wavefront = 2 x surface), typical of piezo-stack DMs; Clip() enforces it.
  double stroke_m = 5e-6;
  // Active-actuator margin in pitches (see the header): actuators within active_margin_pitch * d of the
  // illuminated annulus are controlled. >= 0 and finite; default 1/sqrt(2) (the half-diagonal of a
  // subaperture in Fried geometry).
  double active_margin_pitch = 0.70710678118654752;

  // True when every field is in range; otherwise false and, if `why` is non-null, a message naming the bad
  // field, its value and the allowed range.
  bool IsValid(std::string* why) const;
};

// How much Clip() changed a command vector.
struct ClipSummary {
  // Number of actuators whose |command| exceeded the stroke.
  int clipped = 0;
  // RMS over ALL active actuators of the removed part c - clip(c) [m]; 0 when nothing was clipped. Comparable
  // to the RMS of the commands themselves.
  double clipped_rms_m = 0.0;
  // Largest |c| - stroke over the clipped actuators [m]; 0 when nothing was clipped.
  double max_excess_m = 0.0;
};

// The DM as a linear operator: rows() = n^2 (the pupil OPD image, row-major, metres), cols() = the number of
// active actuators (commands, metres of wavefront OPD). The output covers the whole grid (the mirror exists
// beyond the pupil); PSF code reads it only where the amplitude is > 0.
class DeformableMirror final : public LinearOperator {
 public:
  // pupil_n: pupil grid size n >= 1; pupil: its diameter D (grid span) and obstruction, used for the active
  // actuators (see the header). Throws InvalidArgument naming the bad argument or options field, or when no
  // actuator is active.
  DeformableMirror(Index pupil_n, const PupilGeometry& pupil, const DeformableMirrorOptions& options);

  Index pupil_n() const { return pupil_n_; }
  const PupilGeometry& pupil() const { return pupil_; }
  const DeformableMirrorOptions& options() const { return options_; }
  Index n_active() const { return cols(); }

  // N x N image of 1 (active) / 0 (inactive), rows along y.
  const Image& ActiveMask() const { return active_mask_; }
  // Grid index a * N + b of each active actuator, in command order.
  const std::vector<Index>& ActiveIndices() const { return active_; }
  // Positions of the active actuators [m], 2 x n_active (row 0: x, row 1: y), in command order.
  Eigen::Matrix2Xd ActuatorPositions() const;
  // The separable influence factor G (n x N): G(i, a) = g(coordinate of pixel i - coordinate of actuator a).
  const Eigen::MatrixXd& InfluenceFactor() const { return g_; }
  // The influence function of one actuator at offset (dx, dy) [m] from it: exp(ln(c) (dx^2 + dy^2) / d^2).
  double Influence(double dx_m, double dy_m) const;

  // The N x N command grid (zeros at inactive actuators) of a command vector, and back (inactive ignored).
  Image CommandsToGrid(const Eigen::Ref<const Vector>& commands) const;
  Vector GridToCommands(const Image& grid) const;
  // The OPD image (n x n, metres) of a command vector: ToImage(Apply(commands), {n, n}).
  Image Opd(const Eigen::Ref<const Vector>& commands) const;

  // Clamps every command to [-stroke_m, +stroke_m] in place and reports what was removed. Throws
  // InvalidArgument for a null pointer, a wrong size or non-finite commands.
  ClipSummary Clip(Vector* commands) const;

 private:
  void ApplyImpl(ConstRef x, Ref y) const override;
  void ApplyAdjointImpl(ConstRef y, Ref x) const override;

  Index pupil_n_;
  PupilGeometry pupil_;
  DeformableMirrorOptions options_;
  int n_act_;          // N
  Image active_mask_;  // N x N
  std::vector<Index> active_;
  Eigen::MatrixXd g_;  // n x N separable influence factor
};

using DeformableMirrorPtr = std::shared_ptr<const DeformableMirror>;

struct DmFitOptions {
  // Tikhonov weight relative to the mean diagonal of the weighted normal matrix H^T A H (see the header):
  // mu = regularisation * trace(H^T A H) / n_active. >= 0 and finite. The default 1e-6 keeps the
  // factorisation positive definite when an actuator sees almost no light (beyond the rim, behind the
  // obstruction) and changes low-order fits by < 0.1% of their residual. Larger values (1e-4 .. 1e-2) trade
  // fit for smaller commands on poorly lit actuators: 1e-3 already raises the rim residual of a tilt fit
  // 5-fold on a 19 x 19 grid with a wide margin. 0 is plain least squares (fails if the normal matrix is
  // singular).
  double regularisation = 1e-6;

  bool IsValid(std::string* why) const;
};

// Regularised least-squares DM fitting for one pupil weighting; the normal matrix is factorised once.
class DmFitter {
 public:
  // dm: the mirror (non-null); weights: n x n pupil weights A (finite, >= 0, some > 0), usually the pupil
  // amplitude. Throws InvalidArgument naming the bad argument or options field, or if the regularised
  // normal matrix is not positive definite (use regularisation > 0).
  DmFitter(DeformableMirrorPtr dm, const Image& weights, const DmFitOptions& options = DmFitOptions());

  // Commands c minimising sum A (H c - w)^2 + mu |c|^2 for the requested OPD w (n x n, metres; finite where
  // A > 0, ignored elsewhere). Commands are not clipped: call DeformableMirror::Clip to apply the stroke.
  Vector Fit(const Image& opd_m) const;
  // Fit(w) followed by w - H c: the residual OPD over the whole grid (meaningful where A > 0).
  Image Residual(const Image& opd_m) const;

  const DeformableMirror& mirror() const { return *dm_; }
  const Image& weights() const { return weights_; }
  // The Tikhonov weight mu actually used (absolute, in the units of H^T A H).
  double mu() const { return mu_; }

 private:
  DeformableMirrorPtr dm_;
  Image weights_;
  double mu_ = 0.0;
  Eigen::LLT<Eigen::MatrixXd> llt_;
};

}  // namespace aosr
