// Phase design, part 4: the design file, what an AO real-time controller (and `aosr simulate` / `reconstruct`)
// loads. Format (read by scene_spec.hpp's LoadDesignFile, documented in data/scenes/README.md "Design files"):
//
//   {
//     "name": "paper-sim-r2-zernike",
//     "frames": [ {"shift_px": [dy, dx], "zernike": [{"noll": j, "rms_nm": a}, ...], "actuators_nm": [...]}, ... ],
//     "design": {                                  (provenance; LoadDesignFile keeps it, unchecked)
//       "method": "expected-mse" (objective A) | "empirical-map-loss" (objective B),
//       "parameterisation": "zernike", "scene": "...", "reconstructor": {...},
//       "objective": {"raster": J_r, "start": J_0, "final": J, "units": "..."}, "summary": "...",
//       "wfs": {"model": "shack-hartmann-geometric", "lenslets_across": M, "valid_subapertures": V,
//               "pupil_grid_px": n_s, "slope_order": "...", "units": "rad"},
//       "frames": [ {"rms_nm": ..., "strehl": ..., "strehl_cost": ..., "reference_slopes_rad": [...]}, ... ],
//       "modal_content": {"noll": [2, ..., 36], "units": "nm of wavefront OPD RMS", "frames": [[c_2, ...], ...],
//                         "beyond_nm": [...], "sum_abs_nm": [...], "power_nm2": [...], "rms_over_frames_nm": [...]}
//     }
//   }
//
// Per exposure: the offset as the scene reads it (tip/tilt as an image shift in camera pixels, Zernike
// coefficients in nm of wavefront OPD RMS, or DM commands in nm of wavefront OPD, one per active actuator);
// its pupil RMS (piston removed); the Strehl it keeps, exact, tip/tilt removed (a shift costs nothing), and the
// cost 1 − S; and the Shack-Hartmann reference-slope offsets that make the closed loop hold it: the noise-free
// slopes of the offset OPD on the telescope's lenslet geometry, minus those of a flat wavefront
// (WavefrontSensor::ReferenceOffsetForOpd with the geometric model; closed_loop.hpp applies offsets this way).
// Slopes are listed as the sensor orders them (all x slopes of the valid lenslets, then all y slopes).
//
// Modal content (the seed paper's picture of which aberrations a design uses): each offset's OPD fitted by least
// squares over the pupil with Noll's Zernike modes 1..kModalContentNoll (optics/zernike.hpp ProjectOntoZernike;
// each mode of unit RMS over the unobstructed disc, so a coefficient is the nm RMS that mode puts on the full
// circle), piston dropped; what the fit leaves (higher modes, actuator ripple) is each offset's "beyond_nm", the
// pupil RMS of the residual. Per mode over the N offsets: the sum of |c| (the paper's absolute power), Σ c² and
// its RMS sqrt(Σ c² / N). A raster's content is tip and tilt only (Z2, Z3: the shifts); a design's shows which
// higher modes the reconstructor exploits.
#pragma once

#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "aosr/design/design_optimizer.hpp"
#include "aosr/scene/scene_spec.hpp"

namespace aosr {

// Highest Noll index of the modal content (radial orders 0..7).
inline constexpr int kModalContentNoll = 36;

struct DesignFrameReport {
  double rms_m = 0.0;        // pupil RMS of the offset, piston removed [m]
  Vector zernike_m;          // least-squares Zernike coefficients of the offset, Noll 1..kModalContentNoll [m]
  double beyond_m = 0.0;     // pupil RMS of the offset minus that fit [m] (modes above kModalContentNoll)
  double strehl = 1.0;       // Strehl kept (tip/tilt removed), exact, at the science wavelength
  double strehl_cost = 0.0;  // 1 − strehl
  Vector reference_slopes_rad;  // SH reference-slope offsets [rad]; empty without a Shack-Hartmann
};

// Per exposure reports for the OPDs of a design (n x n [m] each) and the same exposures' offsets (the design
// result's `offsets`). The slopes use the scene's telescope's Shack-Hartmann geometry (geometric model,
// noise-free) when it has an AO section; otherwise they are empty. The sensor samples the pupil on the
// telescope's grid when its lenslets divide it, else on the smallest multiple of the lenslet count above it
// (the file's "wfs.pupil_grid_px"), with each offset rendered afresh there (scene/pipeline.hpp ExposureOpd).
std::vector<DesignFrameReport> DescribeDesign(const SceneSpec& scene, const DesignParameterisation& parameterisation,
                                              const std::vector<Image>& opds, const std::vector<DmOffset>& offsets);

// The "modal_content" record of the design file (format above) from the reports' Zernike fits (InvalidArgument
// when a report's zernike_m is not Noll 1..kModalContentNoll), or from OPDs on the pupil's grid (InvalidArgument
// naming the OPD of another shape): the fit alone, without DescribeDesign's Strehl and slopes.
nlohmann::json ModalContentJson(const std::vector<DesignFrameReport>& frames);
nlohmann::json ModalContentJson(const DesignPupil& pupil, const std::vector<Image>& opds);

// The whole design file as JSON (format above). `scene` names the scene file; `frames` the per-exposure reports.
nlohmann::json DesignFileJson(const std::string& name, const SceneSpec& scene, const DesignResult& result,
                              const DesignCriterion& objective, const std::vector<DesignFrameReport>& frames);

// Writes the JSON atomically (write then rename). IoError naming the path if it cannot be written.
void WriteDesignFile(const std::string& path, const nlohmann::json& design);

}  // namespace aosr
