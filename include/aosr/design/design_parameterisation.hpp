// Phase design, part 1: how the N per-exposure DM offsets w_dm,i are parameterised, and how their bounds are
// kept by smooth reparameterisation (never by clipping, so the optimiser sees a smooth unconstrained problem).
//
// Kinds (each exposure i has its own block of parameters; θ stacks the blocks, exposure-major):
//   kRaster     the classic sub-pixel tip/tilt dither (scene/raster.hpp, ClassicRaster(N, r) / r camera pixels).
//               No free parameters: the reference every other kind starts from.
//   kTipTilt    2 per exposure: the image shift (dy, dx) in camera pixels, made with Z3/Z2 exactly as the
//               scene pipeline does (ExposureOpd: a = shift·θ_pix·D/4).
//   kZernike    J per exposure: Noll modes 2 .. J+1 (piston excluded; tip/tilt included, so the raster is a
//               point of the space), coefficients in metres of wavefront OPD RMS (zernike.hpp, orthonormal).
//   kActuators  one per active DM actuator: commands in metres of wavefront OPD through the Gaussian
//               influence functions (deformable_mirror.hpp); the raster is reached by a regularised DM fit.
//
// Maths. Exposure i's "physical" coefficients c_i (the numbers written to the design file) make the OPD
//     w_i = B c_i,          B: n² x P, the OPD of a unit coefficient (columns: modes or influence functions),
// and c_i is a smooth bijection of the free parameters v_i (θ = (v_0, .., v_{N-1})), the composition of
//     1. stroke (kActuators, when bound_stroke):  c_j = s · tanh(v_j / s),  s = the DM's stroke_m,
//     2. Strehl (strehl_min > 0):  c ← g_ρS(t_S(c)) c,  t_S(c)² = cᵀ Q_S c  the pupil-weighted variance of the
//        OPD with piston, tip and tilt removed (the part that costs Strehl), ρ_S = (λ/2π)·sqrt(−ln S_min)
//        (Maréchal: S ≈ exp(−(2π t_S/λ)²) ≥ S_min),
//     3. RMS (rms_max_m > 0):  c ← g_ρ(t(c)) c,  t(c)² = cᵀ Q c  the pupil-weighted variance with piston
//        removed, ρ = rms_max_m,
// with the radial squash g_ρ(t) = ρ tanh(t/ρ) / t (g → 1 as t → 0), so t(g_ρ(t) c) = ρ tanh(t/ρ) < ρ. Each
// step only shrinks c, so the bounds of the earlier steps still hold after the later ones; each step is a
// bijection onto its open bounded set, so every feasible design (strictly inside the bounds) has exactly one
// θ (ToParameters inverts the chain). Q = Bᵀ(I − Π₁)ᵀ W (I − Π₁) B / ΣW and Q_S likewise with Π₁ replaced
// by the W-weighted projection onto {1, Z2, Z3}, W the pupil amplitude: the RMS and the Strehl cost are
// those of the OPD on the pupil, whatever the basis. Note that g_ρS scales the whole offset, tip/tilt
// included: the bound is on the non-tilt part, the map stays a bijection.
//
// Gradients. PullBack maps ∂J/∂w_i (n x n) to ∂J/∂θ through Bᵀ and the Jacobians of the squashes,
//     ∂(g(t) c)/∂c · x = g x + g'(t)/t · (cᵀ x ... ) Q c   (transposed: g G + (g'(t)/t) (cᵀG) Q c, Q symmetric),
// and of tanh (elementwise). Tested by Taylor tests through the whole objective.
//
// API rules: constructors validate and throw InvalidArgument naming the argument or option field; the class
// is immutable after construction and its methods are const and thread-safe.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "aosr/core/image.hpp"
#include "aosr/optics/deformable_mirror.hpp"
#include "aosr/scene/scene_spec.hpp"

namespace aosr {

enum class DesignParameterisationKind { kRaster, kTipTilt, kZernike, kActuators };
const char* ToString(DesignParameterisationKind kind);
// "raster" | "tiptilt" | "zernike" | "actuators"; InvalidArgument otherwise.
DesignParameterisationKind ParseDesignParameterisation(const std::string& name);

struct DesignParameterisationOptions {
  DesignParameterisationKind kind = DesignParameterisationKind::kZernike;
  // kZernike: J modes per exposure, Noll 2 .. J+1, in [2, 200]. Default 20 (the paper's system: radial orders
  // up to 5, enough for the low-order PSF diversity the pixel transfer lets through).
  int zernike_modes = 20;
  // Bound on the pupil RMS (piston removed) of each offset [m of wavefront OPD]; 0 = none, else > 0. The
  // raster must lie inside it (a quarter-pixel tilt on the paper system is 0.1 λ ~ 190 nm RMS at K).
  double rms_max_m = 0.0;
  // Lower bound on the Strehl kept by each offset (piston, tip and tilt removed: a shift costs nothing), in
  // [0, 1); 0 = none. The bound is Maréchal's exp(−σ²); the file reports the exact Strehl.
  double strehl_min = 0.0;
  // kActuators: keep every command within the DM's stroke by the tanh map. Default true.
  bool bound_stroke = true;

  bool IsValid(std::string* why) const;
};

// The optics a parameterisation needs: the pupil grid and the camera's pixel (for shifts).
struct DesignPupil {
  Image amplitude;              // n x n pupil amplitude (pupil.hpp), n >= 8
  double diameter_m = 0.0;      // D spanned by the grid
  double obstruction = 0.0;     // central obstruction (Zernike masks), [0, 1)
  double wavelength_m = 0.0;    // science wavelength (Strehl bound)
  double camera_pixel_rad = 0.0;  // camera pixel [rad] (shifts in camera pixels)
  DeformableMirrorPtr dm;       // required for kActuators (on the same n grid), else may be null
};

// The pupil of a scene (telescope preset) and its DM (if the preset has one).
DesignPupil DesignPupilFromScene(const SceneSpec& scene);

class DesignParameterisation {
 public:
  // frames N >= 1 and r >= 1 (the raster is ClassicRaster(N, r)). Throws InvalidArgument naming the bad
  // argument or option, also when the raster itself violates the bounds.
  DesignParameterisation(const DesignPupil& pupil, int frames, int r, const DesignParameterisationOptions& options);

  const DesignParameterisationOptions& options() const { return options_; }
  const DesignPupil& pupil() const { return pupil_; }
  int frames() const { return frames_; }
  Index pupil_n() const { return n_; }
  // Coefficients per exposure (P) and free parameters in total (N·P; 0 for kRaster).
  int coefficients_per_frame() const { return int(basis_.cols()); }
  int parameters() const;

  // θ → per exposure coefficients c_i (the chain above) and OPDs w_i = B c_i (n x n, metres). θ.size() must
  // be parameters() (ignored for kRaster: the raster).
  std::vector<Vector> Coefficients(const Vector& theta) const;
  std::vector<Image> Opds(const Vector& theta) const;
  // ∂J/∂θ from ∂J/∂w_i (one n x n image per exposure) at θ.
  Vector PullBack(const Vector& theta, const std::vector<Image>& d_opd) const;
  // θ of given coefficients (the inverse chain); each must lie strictly inside the bounds, else
  // InvalidArgument. For kActuators the coefficients are commands.
  Vector ToParameters(const std::vector<Vector>& coefficients) const;
  // The raster in this parameterisation's coefficients (kActuators: DM fits of the raster's tilts, scaled
  // into the bounds if the fit's ripple crosses them) and its θ.
  std::vector<Vector> RasterCoefficients() const;
  Vector RasterParameters() const;
  // The exact classic raster's OPDs (tip/tilt), whatever the kind: the reference designs are compared with.
  std::vector<Image> RasterOpds() const;
  // A typical magnitude of one parameter (camera pixels for tip/tilt, metres otherwise): the optimiser's
  // scale and the size of its start perturbations.
  double ParameterScale() const;

  // The design as scene offsets: kRaster/kTipTilt as shifts, kZernike as Z2/Z3 shifts plus Zernike terms,
  // kActuators as actuator commands. ExposureOpd(scene, offset) reproduces Opds(θ) to rounding.
  std::vector<DmOffset> Offsets(const Vector& theta) const;
  // Pupil RMS (piston removed) and the Strehl kept (tip/tilt removed, exact, at the wavelength) of each OPD.
  double OpdRms(const Image& opd) const;
  double StrehlOf(const Image& opd) const;

 private:
  Vector Squash(const Vector& v) const;  // one exposure's v -> c
  Vector SquashPullBack(const Vector& v, const Vector& dc) const;

  DesignParameterisationOptions options_;
  DesignPupil pupil_;
  int frames_, r_;
  Index n_;
  Eigen::MatrixXd basis_;    // B, n² x P (row-major image order)
  Eigen::MatrixXd q_rms_;    // Q, P x P
  Eigen::MatrixXd q_strehl_;  // Q_S, P x P
  double rho_rms_ = 0, rho_strehl_ = 0, stroke_ = 0;
  double shift_coefficient_ = 0;  // Z2/Z3 coefficient [m] per camera pixel of shift
};

}  // namespace aosr
