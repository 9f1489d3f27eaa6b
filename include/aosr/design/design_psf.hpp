// Phase design, shared part: the instrument a design objective sees (DesignOptics), the PSFs of a design on the
// periodic HR design grid, and the one pull-back from a gradient with respect to those PSFs' transfer functions
// to the DM offsets. Objective A (design_objective.hpp) and objective B (design_empirical.hpp) both evaluate
// through DesignPsfModel, so they see the same PSFs and share one (tested) chain rule. DesignCriterion is what
// the optimiser (design_optimizer.hpp) minimises: either objective.
//
// ## The PSFs (DESIGN.md §1)
//
// The HR grid is periodic, M x M pixels (M = DesignOptics::grid, a multiple of r), of pitch θ_hr. Exposure
// i's diffraction PSF with DM offset w_i (and the static aberration w_static) is
//     p_i = Σ_l |MFT(A exp(i 2π (w_i + w_static + ψ_l) / λ))|²,   h_i = p_i / Σ p_i   (unit sum),
// with no screens ψ for the nominal PSF and the L residual screens ψ_{ρ,i,l} of realisation ρ for the realised
// ones. When the sampled pupil's PSF period Q = n λ / (D θ_hr) pixels is a whole multiple of M, the PSF over
// one period is an exact FFT of the Q x Q zero-padded pupil, folded onto M x M (a tilt is then a pure shift);
// otherwise the MFT onto the centred M x M window is used (the window leaks a little light).
//
// Transfer functions (full spectrum, bin (0,0) = zero frequency, FftForward of the origin-layout kernel):
//     nominal   H0_i(f) = DFT(h_i)(f) · T(f),  T(f) = exp(−D_res(λ f / θ_hr) / 2)  (analytic AO long exposure;
//               T = 1 without AO): what a reconstructor uses;
//     realised  H_{ρ,i}(f) = DFT(h_{ρ,i})(f), ρ = 0 .. R−1, the PSFs that make the frames (none when R = 0: the
//               frames then follow the nominal model).
// The screens are drawn once, at construction, from the analytic model's residual PSD (FFT screens on its
// K n x K n grid, cropped to the pupil), so every objective built on the model is a deterministic function of
// the design (a sample-average approximation).
//
// ## The pull-back (Wirtinger convention, stated once for every design objective)
//
// For real J of complex Z, Γ_Z = ∂J/∂Re Z + i ∂J/∂Im Z, so dJ = Re Σ conj(Γ_Z) dZ. Given Γ_{H0,i} and
// Γ_{H_{ρ,i}} (full spectra, M x M), PullBack returns ∂J/∂w_i:
//     Γ_{Hdiff,i} = T Γ_{H0,i};   ∂J/∂h = M² Re IDFT(Γ_H)  (the gradient w.r.t. the origin-layout kernel; for
//     a gradient g already in HR space, Γ_H = DFT(g) / M² gives it back);
//     ∂J/∂p = (∂J/∂h − ⟨∂J/∂h, h⟩) / Σp   (the unit-sum normalisation);
//     Γ_E = 2 MFT^H(∂J/∂p ⊙ Y),  Y = MFT(E)  (mft.hpp's exact adjoint; on the periodic path the Q x Q FFT);
//     ∂J/∂w = k Im(Γ_E conj(E)),  k = 2π/λ,
// summed over the screens of each PSF and over the realisations. design_parameterisation.hpp continues to θ.
//
// API rules: constructors validate (InvalidArgument naming the field); the model is immutable after
// construction and Compute / PullBack are const and thread-safe.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "aosr/ao/analytic_ao.hpp"
#include "aosr/core/forward_model.hpp"
#include "aosr/core/image.hpp"
#include "aosr/optics/mft.hpp"
#include "aosr/scene/scene_spec.hpp"

namespace aosr {

// The instrument a design objective sees.
struct DesignOptics {
  Image amplitude;             // n x n pupil amplitude (pupil.hpp), spanning diameter_m
  double diameter_m = 0.0;
  double wavelength_m = 0.0;   // science wavelength
  double hr_pixel_rad = 0.0;   // θ_hr = camera pixel / r; at most λ/D (the PSF must fit its samples)
  int r = 1;
  Index grid = 0;              // M: HR grid side, even and a multiple of r (the PSF window)
  Image static_opd_m;          // w_static (science path), n x n; empty: none
  std::optional<AnalyticAoOptions> ao;  // the AO residual model; none: diffraction only (and R is ignored)
};

// The optics of a scene: its pupil, wavelength, r, PSF window (rounded up to a multiple of 2r), static
// aberrations, and the analytic AO model of its telescope when the scene has AO (analytic or closed-loop)
// and the preset has an atmosphere and an AO system.
DesignOptics DesignOpticsFromScene(const SceneSpec& scene);

// What the design optimiser minimises: objective A (DesignObjective) or objective B (EmpiricalDesignObjective).
// Evaluate(w, grad) is J of the N DM offsets w_i (n x n images, metres) and, if grad is non-null, ∂J/∂w_i
// (zero outside the pupil). It throws InvalidArgument for bad offsets and NumericalError when J or its
// gradient cannot be trusted (never a NaN).
class DesignCriterion {
 public:
  virtual ~DesignCriterion() = default;
  double Evaluate(const std::vector<Image>& dm_opds, std::vector<Image>* grad = nullptr) const {
    return EvaluateImpl(dm_opds, grad);
  }
  virtual int frames() const = 0;
  virtual const DesignOptics& optics() const = 0;
  // AO PSF realisations the frames are made with (0: the nominal model).
  virtual int realisations() const = 0;
  // The part of J no design can change, or NaN where none is known (objective B).
  virtual double invisible_floor() const = 0;
  // "expected-mse" (objective A) or "empirical-map-loss" (objective B): the design file's "method".
  virtual const char* method() const = 0;

 private:
  virtual double EvaluateImpl(const std::vector<Image>& dm_opds, std::vector<Image>* grad) const = 0;
};

class DesignPsfModel {
 public:
  // One exposure's PSF with what its pull-back needs.
  struct Psf {
    std::vector<ComplexImage> fields;  // E_l (n x n; Q x Q zero-padded on the periodic path)
    std::vector<ComplexImage> y;       // MFT(E_l) (M x M), or the Q x Q FFT
    Image h;                           // unit-sum PSF (centred window; origin layout on the periodic path)
    double sum = 0;                    // Σ p
    ComplexImage otf;                  // full spectrum of h (origin at (0,0)), without T
  };
  // The PSFs of one design: psfs[t], t < N the nominal exposure t (diffraction part), t = N + ρ N + i
  // realisation ρ of exposure i; and the transfer functions defined at the top of the file.
  struct Set {
    std::vector<Psf> psfs;
    std::vector<ComplexImage> nominal;               // H0_i, M x M (T applied)
    std::vector<std::vector<ComplexImage>> realised;  // H_{ρ,i}, [ρ][i], M x M (empty when R = 0)
  };

  // frames N in 1 .. 1024; realisations R in 0 .. 64 and screens L in 1 .. 256 (R is set to 0 without AO);
  // threads 1 .. 64 (results do not depend on it). `function` names the caller in error messages.
  DesignPsfModel(const DesignOptics& optics, int frames, int realisations, int screens, std::uint64_t seed,
                 int threads, const std::string& function);

  // The PSFs of the DM offsets (N images n x n, metres, finite where the pupil transmits; InvalidArgument
  // naming `function` otherwise). NumericalError if a PSF has no light. Without realisations only the nominal
  // PSFs are computed (set.realised is then empty).
  Set Compute(const std::vector<Image>& dm_opds, const char* function, bool with_realisations = true) const;
  // ∂J/∂w_i (N images n x n, overwritten) from Γ_{H0,i} (N, M x M) and Γ_{H_{ρ,i}} ([R][N], M x M, R the
  // set's realisations; empty: no gradient through the realised PSFs), as at the top of the file.
  void PullBack(const Set& set, const std::vector<ComplexImage>& gamma_nominal,
                const std::vector<std::vector<ComplexImage>>& gamma_realised, std::vector<Image>* grad) const;

  // The systems of a set: the nominal model and realisation ρ's, on the M x M grid.
  MultiFrameModel NominalModel(const Set& set) const;
  MultiFrameModel RealisedModel(const Set& set, int realisation) const;

  const DesignOptics& optics() const { return optics_; }
  int frames() const { return frames_; }
  int realisations() const { return int(screens_.size()); }
  Index pupil_n() const { return n_; }
  Shape hr_shape() const { return {optics_.grid, optics_.grid}; }
  // T(f) on the M x M grid (all ones without AO).
  const Image& ao_factor() const { return t_; }
  // True when the PSFs are the exact periodic ones, false on the windowed MFT path.
  bool periodic() const { return period_ > 0; }

 private:
  Psf ComputePsf(const Image& opd, const std::vector<const Image*>& screens) const;
  Psf ComputePeriodicPsf(const Image& opd, const std::vector<const Image*>& screens) const;
  void PsfPullBack(const Psf& psf, const ComplexImage& gamma_h, Image* grad) const;

  DesignOptics optics_;
  int frames_;
  int threads_;
  Index n_;
  MatrixFourierTransform mft_;
  std::vector<Index> lit_;
  Index period_ = 0;  // Q of the periodic path (0: the windowed MFT path)
  Image t_;
  std::vector<std::vector<std::vector<Image>>> screens_;  // [ρ][i][l] OPD [m]
};

}  // namespace aosr
