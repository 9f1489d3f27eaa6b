// A calibration measurement set: camera frames of a point source taken while the DM pokes single modes at
// several commanded amplitudes, plus reference frames with the nominal flat; and a generator of synthetic sets
// with known gains, static aberration, non-linearity and noise (the fit's test oracle).
//
// ## On disk (format "aosr-calibration-set-v1", field by field in data/calibration/README.md)
//
// A folder with `calibration-set.json` and the frames it names (FITS, PNG or TIFF; relative paths resolve
// against the folder). Each frame says which mode it pokes (a Noll index >= 2, or the name of an actuator
// pattern listed under "modes") and the commanded amplitude in nm of RMS wavefront OPD, or that it is a
// reference (flat) frame — of one mode's sequence ("mode" given) or shared by every mode (no "mode"). Optional:
// a dark/background frame subtracted from every frame (else the detector's bias is), and a bad-pixel mask.
//
// ## Validation (LoadCalibrationSet and ValidateCalibrationSet)
//
// Before any fit, and with messages that name the frame, file and rule: all frames, the dark and the mask have
// one shape; every mode has at least one poked frame, a non-zero amplitude among them and a reference (its own
// or a shared one); amplitudes are finite; actuator patterns match the DM's active actuators. Non-finite pixels
// (NaN, Inf) are not an error: they are masked (valid = 0) and counted; a frame left with fewer than 16 valid
// pixels is an error.
#pragma once

#include <cstdint>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "aosr/calib/modal_fit.hpp"
#include "aosr/core/image.hpp"
#include "aosr/optics/deformable_mirror.hpp"

namespace aosr {

inline constexpr const char* kCalibrationSetFileName = "calibration-set.json";
inline constexpr const char* kCalibrationSetFormat = "aosr-calibration-set-v1";

struct CalibrationMode {
  int noll = 0;                          // Zernike mode j >= 2, or 0 for an actuator pattern
  std::string name;                      // "Z4", or the actuator pattern's name
  std::vector<double> actuator_pattern;  // pattern modes: commands per unit amplitude (one per active actuator)
};

struct CalibrationFrame {
  std::string file;          // as written in the manifest ("" for an in-memory set)
  int mode = -1;             // index into CalibrationSet::modes; -1: a reference shared by every mode
  bool reference = false;    // a flat (nominal) frame: amplitude 0
  double amplitude_m = 0.0;  // commanded RMS OPD [m]
  Image adu;                 // ADU, dark (or bias) subtracted
  Image valid;               // 1 usable, 0 masked (bad pixel, non-finite)
};

struct CalibrationSet {
  std::string source;     // the manifest file ("<memory>" for a synthetic set not yet written)
  std::string telescope;  // the preset it was taken with (name or path), for the record and the DM
  double diameter_m = 0.0;
  CalibrationOptics optics;
  NoiseModelParameters noise;
  double bias_adu = 0.0;  // subtracted on loading when no dark frame is given
  std::optional<DeformableMirrorOptions> dm;  // needed by actuator-pattern modes
  std::vector<CalibrationMode> modes;
  std::vector<CalibrationFrame> frames;
  Index masked_pixels = 0;  // non-finite pixels masked while loading (over all frames)
  nlohmann::json truth;     // what a synthetic set injected (null for measurements)

  Shape shape() const { return frames.empty() ? Shape{} : ShapeOf(frames[0].adu); }
  // Frame indices of mode m's sequence: its poked frames, its own references and the shared references.
  std::vector<int> FramesOfMode(int m) const;
  // The mode's OPD per unit amplitude on the optics' pupil grid: Zernike(j) or the pattern's DM OPD.
  Image ModeShape(int m) const;
};

// Checks the rules at the top of the file (also masks non-finite pixels and builds absent masks). Throws
// InvalidArgument naming the frame and the rule.
void ValidateCalibrationSet(CalibrationSet* set);

// Reads `path` (the folder or its calibration-set.json), the frames, dark and mask; validates. IoError for
// unreadable files, InvalidArgument (file and field path) for bad content.
CalibrationSet LoadCalibrationSet(const std::string& path);

// The files a set read from disk came from: its manifest and every frame file (resolved against the manifest's
// folder); empty for an in-memory set. Outputs must not be one of them (io/atomic_file.hpp, CheckNotSameFile):
// `aosr calibrate` and Python's aosr.calibrate both refuse to overwrite an input.
std::vector<std::string> CalibrationSetInputFiles(const CalibrationSet& set);

// Writes the set into `dir` (created if needed): one FITS file per frame (frames/NNN.fits), the mask
// (valid.fits when any pixel is masked) and calibration-set.json, each atomically. Frames are written as they
// are (dark already subtracted: bias 0, no dark).
void WriteCalibrationSet(const std::string& dir, const CalibrationSet& set);

// ---------------------------------------------------------------------------------------------------------
// Synthetic sets.
//
// Each frame is rendered by ModalImageModel (the fit's model: an "inverse crime" for the model, not for the
// noise, non-linearity or outliers) with the true applied amplitude
//     applied(a) = g a                                               |a| <= a_nl (or no non-linearity)
//     applied(a) = g sign(a) (a_nl + (1 − k)(|a| − a_nl))            |a| >  a_nl   (saturation, 0 < k <= 1)
//     applied(a) = g sign(a) (a_nl − k'(|a| − a_nl))                 k > 1: the response folds back ("wraps")
// (k' = k − 1), the static aberration and a Gaussian source, then recorded by aosr::Detector (Poisson photon
// noise, Gaussian read noise, gain) with a per-frame flux jitter and optional hot pixels (outliers).
struct SyntheticCalibrationOptions {
  std::string telescope = "paper-bench";  // preset name or path (D, obstruction, wavelength, DM)
  // Camera pixel in λ/D (> 0). The bench's unbinned 5.86 µm pixel at f = 400 mm, 635 nm, D = 13.5 mm: 0.3115.
  double pixel_lambda_over_d = 0.3115;
  Index pupil_px = 64;                     // model pupil grid (as the fit's default)
  Shape window{48, 48};                    // frame size [camera px]; 48 px = 15 λ/D on the bench
  std::vector<int> modes{2, 3, 4, 5, 6, 7, 8, 9, 10, 11};  // Noll indices >= 2, distinct (may be empty)
  // Actuator-pattern modes poked after the Zernike ones: name (distinct, not "Z<j>") and commands per unit
  // amplitude, one per active actuator of the telescope's DM (CalibrationMode with noll = 0). At least one
  // mode in all.
  std::vector<CalibrationMode> patterns;
  std::vector<double> gains;               // true gain per mode, Zernike modes then patterns (> 0); empty: all 1
  // Commanded amplitude levels [m RMS OPD], each > 0 and poked at + and −; increasing.
  std::vector<double> amplitudes_m{20e-9, 40e-9, 60e-9, 80e-9, 100e-9};
  int references_per_mode = 1;             // flat frames per mode's sequence, >= 0 (0 needs shared_references)
  int shared_references = 0;               // flat frames shared by all modes, >= 0
  std::vector<int> static_modes{4, 5, 6, 7, 8};                      // static aberration terms (Noll >= 4)
  std::vector<double> static_m{25e-9, -15e-9, 10e-9, 12e-9, -8e-9};  // their RMS OPD [m]
  double source_sigma_px = 0.4;            // Gaussian source σ [camera px], >= 0
  double dy_px = 0.3, dx_px = -0.2;        // source position relative to the window centre [camera px]
  double flux_e = 2e5;                     // source electrons per frame (whole focal plane), > 0
  double flux_jitter = 0.02;               // relative RMS frame-to-frame flux variation, in [0, 0.5)
  double background_e = 20.0;              // electrons per pixel per frame, >= 0
  double gain_e_per_adu = 7.81;            // detector gain, > 0
  double read_noise_e = 7.0;               // e- RMS, >= 0
  bool photon_noise = true;
  double nonlinear_above_m = 0.0;          // a_nl [m] (0: linear everywhere)
  double nonlinear_strength = 0.5;         // k in (0, 2]
  int hot_pixels = 0;                      // outlier pixels per frame (value + 50 σ), >= 0
  // The renderer's sampling: by default the fit's own (q automatic, 8 px padding). Measured: rendering with
  // q = 2 and 12 px padding instead leaves the gains within their σ but made the trial-to-trial scatter 1.5-2x
  // smaller than the reported σ on a 10-trial run (unexplained; the same sampling gives σ/scatter 0.87-1.25 over
  // 30 trials). The model itself is checked against an independent fine-grid PSF in modal_fit_test.cpp.
  int oversampling = 0, padding_px = 8;
  std::uint64_t seed = 1;

  bool IsValid(std::string* why) const;
};

// The commanded → applied amplitude law above.
double AppliedAmplitude(double commanded_m, double gain, double nonlinear_above_m, double nonlinear_strength);

// Renders and records the set (in memory; source "<memory>"). set.truth holds the injected gains, static
// aberration, source, flux, noise and non-linearity. Throws InvalidArgument naming the bad option.
CalibrationSet SynthesizeCalibrationSet(const SyntheticCalibrationOptions& options);

// Reads a synthetic-set spec (data/calibration/*.json: the fields of SyntheticCalibrationOptions, amplitudes and
// static terms in nm), or a bare telescope preset name/path (then the defaults with that telescope; the pixel
// stays the bench's unless a spec says otherwise). Unknown fields are errors.
SyntheticCalibrationOptions LoadSyntheticCalibrationSpec(const std::string& name_or_path);

}  // namespace aosr
