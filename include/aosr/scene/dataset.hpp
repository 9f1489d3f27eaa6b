// Datasets on disk: what a simulation writes (WriteSimulation) and what every reconstructor reads
// (LoadDataset), for simulated and measured frames alike. A dataset is a folder of FITS files described by
// one JSON manifest; the manifest, not the file names, says what is where.
//
// ## The manifest (format "aosr-manifest", version 1)
//
// Read strictly (io/config.hpp): unknown fields are errors, keys starting with "comment" are ignored, and
// every error names the manifest and the field. File names are relative to the manifest's folder (absolute
// paths are kept). Cubes are N × rows × cols FITS cubes (fits.hpp: NAXIS3 = N); a 2-D image is N = 1.
//
//   field                  required?            meaning
//   format, version        yes                  "aosr-manifest", 1
//   frames                 yes                  recorded frames, ADU (N × rows × cols). Non-finite pixels (the FITS
//                                               convention for bad ones) become invalid and read bias_adu.
//   psfs | scene           exactly one          psfs: h_i at HR sampling (θ_pix / r), K × K with K even, one plane
//                                               per frame or one plane shared by all; each is renormalised to
//                                               unit sum (error if a sum is <= 0 or not finite).
//                                               scene: an instrument scene file (scene_spec.hpp; its objects are
//                                               ignored): the PSFs are ScenePipeline::ComputePsfs of it (for a
//                                               closed-loop scene NominalPsfs: one loop draw is not the model), and r,
//                                               the offsets, the pixel scale, the wavelength, the trustworthy
//                                               border and the frame shape (checked against `frames`) are the
//                                               scene's.
//   r                      with psfs            super-resolution factor, 1..16; with scene optional, must match
//   gain_e_per_adu         with psfs            e⁻ per ADU (> 0); with scene the scene's detector value by default
//   bias_adu               with psfs            pedestal, ADU (finite); with scene likewise
//   valid                  no                   N-cube of 1 (usable) / 0 (bad, saturated); default all 1
//   weights                no                   N-cube of inverse variances, ADU⁻², finite and >= 0; forced to 0
//                                               where a pixel is invalid (it carries no likelihood)
//   offsets                no (not with scene)  N DM offsets in the scene files' inline-design form
//                                               ({"shift_px": [dy, dx], "zernike": [{"noll", "rms_nm"}],
//                                               "actuators_nm": [...]}); default none. Informational for
//                                               solvers that take the PSFs as given.
//   psf_field              no                   the PSF across the field (core/psf_field.hpp): {"psfs": a cube of
//                                               ny·nx·N planes of the psfs' shape, node-major (plane k·N + i: node
//                                               k, frame i; unit-sum normalised), "grid": [ny, nx] (1..64 each;
//                                               nodes on the HR frame as psf_field.hpp places them),
//                                               "nominal_psfs" (optional, same layout: the model for a closed
//                                               loop), "interpolation": "bilinear" (the only one),
//                                               "guide_star_arcsec": [x, y] (informational)}. Simulations of a
//                                               scene with a psf_field write it; with "scene", a scene psf_field
//                                               gives it (its nominal PSFs for a closed loop). psfs are then the
//                                               guide star's direction
//   nominal_psfs           no                   N PSFs of the psfs' shape: the model a reconstructor would use when
//                                               the psfs are realisations it cannot know (closed-loop simulations
//                                               write the analytic-AO PSFs of the same offsets); unit-sum normalised
//   truth                  no                   the object on the HR grid (r·rows × r·cols), e⁻ per frame per HR px
//   truth_frames           no                   one such object per frame (M planes): the truth at each frame's
//                                               time, for a sequence whose objects change (truth is then their mean)
//   expected               no                   noiseless frames, e⁻ (simulations); must exist, not loaded
//   stars                  no                   [{"y_hr_px", "x_hr_px", "flux_e"}] (HR-frame coordinates, e⁻ per
//                                               frame), optionally with the camera-pixel "y_px", "x_px" (checked
//                                               against them); either pair may be given alone
//                                               (camera c <-> HR (c + ½)·r − ½)
//   trustworthy_border_px  no                   camera pixels of each edge a periodic model cannot reproduce
//                                               (pipeline.hpp); default ceil(K / 2 / r)
//   frame_shape, hr_shape  no                   [rows, cols], and the PSF side K: checked against the files
//   psf_size_px                                 when given
//   pixel_scale            no                   {"camera_rad", "hr_rad", "camera_mas", "hr_mas",
//                                               "camera_lambda_over_d", "hr_lambda_over_d"}: camera_rad is
//                                               required in the section, hr_rad and the mas values are checked
//                                               against it and r, the λ/D values are informational
//   wavelength_m           no                   science wavelength, m
//   wcs                    no                   the sky coordinates of frame 0 (io/wcs.hpp) as FITS keywords, e.g.
//                                               {"CTYPE1": "RA---TAN", "CTYPE2": "DEC--TAN", "CRPIX1": 32.5,
//                                               "CRPIX2": 32.5, "CRVAL1": 150.1, "CRVAL2": 2.2, "CD1_1": -1e-5,
//                                               "CD1_2": 0, "CD2_1": 0, "CD2_2": 1e-5} (or PCi_j + CDELTi, or
//                                               CDELTi with CROTA2); it replaces the frames file's own WCS; null:
//                                               none. Absent: the frames file's header WCS, when it has one
//   sequence               no                   a video: M frames taken while the DM cycles through P phases
//                                               (solvers/video_stream.hpp), {"slots": [M integers in 0..P-1]: the
//                                               phase (slot) of each frame, "times_s": [M non-decreasing times, s]},
//                                               either key optional. With slots, the per-phase inputs (psfs, the
//                                               scene's frames and offsets, offsets, nominal_psfs, psf_field planes)
//                                               have P entries and are expanded on reading to one per frame (frame i
//                                               gets slot i's); valid and weights stay per frame (M). Without slots
//                                               frame i is slot i (M = P, as without the section)
//   software, noise,       no                   provenance written by WriteSimulation (the software version; the
//   simulation                                  detector model; the scene as read, seeds, the compiled plan,
//                                               per-exposure Strehl, PSF window fraction and the closed loop's WFS tilt gain, stage timings); not
//                                               interpreted
//
// A measured dataset needs only a few lines, e.g.
//     {"format": "aosr-manifest", "version": 1, "frames": "night1.fits", "scene": "instrument.json",
//      "valid": "night1_mask.fits"}
// or, with PSFs measured on a star at HR sampling,
//     {"format": "aosr-manifest", "version": 1, "frames": "night1.fits", "psfs": "psf_hr.fits", "r": 2,
//      "gain_e_per_adu": 2.1, "bias_adu": 1000}
//
// ## Files written by WriteSimulation
//
//   frames.fits    N × rows × cols, ADU, float64           valid.fits    N × rows × cols, 1 / 0
//   weights.fits   N × rows × cols, ADU⁻², float64         truth.fits    HR frame, e⁻ per frame per HR pixel
//   psfs.fits      N × K × K, unit sum, HR sampling        expected.fits N × rows × cols, noiseless e⁻
//   manifest.json  the above, all of it referenced by name
// A scene with a sequence (scene_spec.hpp, SequenceSpec) of M exposures writes M frames (frames, valid, weights,
// expected) and the manifest's "sequence" (each frame's phase j mod N and mid-exposure time); psfs.fits (and
// the psf_field's) stay one per phase, N: the mean over the phase's exposures (exact without a closed loop,
// where they are equal; with one, the phase's long exposure, and each exposure's own PSF is in
// exposure_psfs.fits, provenance). When objects change, truth_frames.fits holds the truth at each exposure
// (M × HR frame) and truth.fits their mean.
// Each FITS header carries ORIGIN, the scene name, r, gain, bias, BUNIT, the frame time and the pixel scale
// of its own sampling (camera or HR), in mas. Sky coordinates (io/wcs.hpp, the scene's "sky" pointing): the
// truth carries the HR grid's TAN WCS with the sky position at its centre; frames, valid, weights and expected
// carry frame 0's camera WCS, LrWcs of the truth's with frame 0's image shift (the other frames are displaced
// by their own shifts); the PSFs, kernels rather than sky images, carry none.
//
// Every file is written atomically (io/atomic_file.hpp). An existing manifest.json in the folder is removed
// before anything else is written and the new one is written last, so a folder whose writing was interrupted
// has no manifest rather than one naming a mix of two runs' files. Nothing is written over an input of the
// scene (the scene file, design file, object images, bad-pixel map): InvalidArgument before any write.
#pragma once

#include <filesystem>
#include <nlohmann/json.hpp>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "aosr/core/image.hpp"
#include "aosr/io/wcs.hpp"
#include "aosr/scene/objects.hpp"
#include "aosr/scene/pipeline.hpp"
#include "aosr/scene/scene_spec.hpp"

namespace aosr {

// The manifest's format name and the version this code writes and reads.
inline constexpr const char* kManifestFormat = "aosr-manifest";
inline constexpr int kManifestVersion = 1;
inline constexpr const char* kManifestFileName = "manifest.json";

// Writes `sim` (the result of pipeline.Run() for `scene`) into `dir`, creating it if needed: the files and
// manifest of the top of the file. `scene_json`, when given, is the scene file's JSON exactly as read (kept
// in the manifest for provenance); otherwise the scene's source file is read again if it exists.
// Errors: IoError naming the path (dir not a folder or not writable, a write failure); InvalidArgument if an
// output would overwrite one of the scene's input files, or if `sim` does not match `scene` (frame count or
// shapes).
void WriteSimulation(const std::string& dir, const SceneSpec& scene, const ScenePipeline& pipeline,
                     const Simulation& sim, const nlohmann::json* scene_json = nullptr);

// The manifest's "noise" section WriteSimulation writes for `sim` (the detector model: noise model, read noise,
// sky and dark rates, frame time, quantisation, ...): provenance, which source-independent weights read
// (solvers/dataset_problem.hpp, DatasetWeights::kBackground). DatasetFromSimulation puts it in its manifest.
nlohmann::json SimulationNoiseJson(const SceneSpec& scene, const Simulation& sim);

// What WriteSimulation checks before writing, for callers that want to fail before a long simulation: no
// output file in `dir` is an input of `scene` (InvalidArgument), and `dir` is (or can be created as) a
// writable folder (IoError naming it). Creates `dir` if needed.
void PrepareSimulationOutput(const std::string& dir, const SceneSpec& scene);

// Every file a scene reads (the scene itself, a telescope preset file, a design file, object images, a
// bad-pixel map): what WriteSimulation refuses to overwrite. Absolute or relative as the scene resolved them.
std::vector<std::string> SceneInputFiles(const SceneSpec& scene);

// Dataset::psf_field's contents (below).
struct DatasetFieldPsfs {
  PsfFieldGrid grid;
  std::vector<ImageStack> psfs;
  std::vector<ImageStack> nominal_psfs;
  double guide_star_x_arcsec = 0.0, guide_star_y_arcsec = 0.0;
};

// A dataset as the reconstructors use it. Images are in the manifest's units (top of the file).
struct Dataset {
  std::string manifest_path;  // the manifest that was read
  nlohmann::json manifest;    // its JSON, as read

  int r = 1;
  Shape frame;     // camera frame, rows × cols
  Shape hr_frame;  // r · frame

  ImageStack frames;                 // N recorded frames, ADU
  ImageStack valid;                  // N masks, 1 usable / 0 not
  std::optional<ImageStack> weights;  // N inverse-variance maps, ADU⁻² (0 where invalid), when given
  double gain_e_per_adu = 1.0;
  double bias_adu = 0.0;

  ImageStack psfs;                // N PSFs at HR sampling, K × K (K even), each of unit sum
  ImageStack nominal_psfs;        // N nominal model PSFs (closed-loop simulations: analytic AO), or empty
  // The PSF across the field (core/psf_field.hpp), when the manifest has a psf_field section or its scene a
  // psf_field: the grid on the HR frame, per node k the frames' PSFs psfs[k][i] (unit sum, the psfs' shape) and,
  // when given, the nominal model's. psfs above are then the guide star's direction (a single-PSF model).
  // (Defined before Dataset: a nested struct with member initialisers is not yet default-constructible inside
  // its enclosing class, which std::optional's traits see there; clang rejects emplace() on it.)
  using PsfField = DatasetFieldPsfs;
  std::optional<PsfField> psf_field;
  std::vector<DmOffset> offsets;  // N DM offsets (all zero when unknown)
  // The phase (slot) of each frame, 0..slot_count-1 (the manifest's sequence.slots; else slots[i] = i and
  // slot_count = N), and the frames' times in seconds (sequence.times_s; empty when the manifest has none).
  // The per-frame PSFs, offsets and nominal PSFs above are those of the frame's slot.
  std::vector<int> slots;
  int slot_count = 0;
  std::vector<double> times_s;
  std::optional<Image> truth;     // the HR object, e⁻ per frame per HR pixel, when given
  ImageStack truth_frames;        // the truth at each frame's time (manifest truth_frames), or empty
  std::string expected_file;      // resolved path of the noiseless frames, empty when absent
  std::vector<PointSource> stars;  // HR-frame coordinates, e⁻ per frame
  Index trustworthy_border_px = 0;

  // 0 when the manifest (or its scene) does not say.
  double camera_pixel_rad = 0.0;
  double wavelength_m = 0.0;

  // Sky coordinates of frame 0's camera pixels (the manifest's "wcs", else the frames file's header), when
  // known. Frame i's image is displaced from the HR (object) grid by its DM shift, offsets[i].shift_px.
  std::optional<Wcs> wcs;
  // The WCS of the HR grid every reconstructor estimates x on (the truth's grid): HrWcs(wcs, r, d0) with d0
  // frame 0's commanded image shift in HR pixels (offsets[0].shift_px · r; tilt given as Zernike terms is
  // not counted, as in the registration offsets of solvers/dataset_problem.hpp). Empty without a wcs.
  std::optional<Wcs> HrWcs() const;

  // LoadDataset(..., DatasetPixels::kSections): the files whose sections ReadDatasetSection reads, and the frame
  // count; frames, valid, weights and truth are then empty. Unset: the pixels are held above.
  struct PixelFiles {
    std::string frames, valid, weights;  // valid, weights: "" when the manifest has none
    int count = 0;
  };
  std::optional<PixelFiles> pixel_files;

  int size() const { return pixel_files ? pixel_files->count : int(frames.size()); }
  Index psf_size() const { return psfs.empty() ? 0 : psfs.front().rows(); }
  // The frames in electrons: (ADU − bias) · gain.
  ImageStack FramesElectrons() const;
};

// A sequence's per-exposure PSFs (M, e.g. Simulation::psfs) as the dataset's per-phase ones (N): the mean over
// each phase's exposures (exposure j has phase j mod N). Without a closed loop these are all equal (the same
// offset, the same PSF); with one, the mean is the phase's long exposure over the sequence, what a star in the
// data would show. Without a sequence: the PSFs as given. InvalidArgument unless there is one per exposure.
ImageStack PerPhase(const SceneSpec& scene, const ImageStack& per_exposure);

// Reads a dataset from a manifest path, or from a folder holding manifest.json. Validates the manifest and
// every file's shape (see the top of the file) before returning. Errors: IoError naming the path for a
// missing manifest or an unreadable / non-FITS file; InvalidArgument "<manifest>: <field> = <value>; allowed:
// <rule>" for everything else, including a file the manifest names that does not exist (the value shows the
// resolved path). With "scene", the scene's own errors name the scene file.
// How much of the pixels LoadDataset reads:
//   kAll       the frames, masks, weights and truth, held whole (their values checked);
//   kSections  none of them: their headers only (shapes checked), Dataset::pixel_files set. Each job then reads
//              the section it needs with ReadDatasetSection, which checks that section's values: a tile of a
//              detector too large to hold, or one of many jobs that each solve one tile (aosr.distributed).
enum class DatasetPixels { kAll, kSections };
Dataset LoadDataset(const std::string& manifest_or_dir, DatasetPixels pixels = DatasetPixels::kAll);

// The manifest and every file it names (frames, valid, weights, psfs, nominal_psfs, truth, truth_frames,
// expected, scene), resolved (weakly canonical): what an output must never replace. The second form reads only
// the manifest (of a folder or a path) and gives an empty set for one it cannot read, which LoadDataset then
// reports by name.
std::set<std::filesystem::path> DatasetInputFiles(const Dataset& d);
std::set<std::filesystem::path> DatasetInputFiles(const std::string& manifest_or_dir);

// Camera px rows [y0, y0 + rows) x cols [x0, x0 + cols) of every frame, its mask and its weights, as LoadDataset
// holds them (a non-finite pixel invalid and read as the bias, weights times the mask): read from the files
// (cfitsio reads the section only) for a dataset loaded by sections, else cut from memory; the same values either
// way. InvalidArgument for a section outside the frames, or bad values in it (naming the manifest); IoError for
// an unreadable file.
struct DatasetSection {
  ImageStack frames, valid;            // ADU; 1 usable / 0 not
  std::optional<ImageStack> weights;   // ADU⁻², when the dataset has them
};
DatasetSection ReadDatasetSection(const Dataset& d, Index y0, Index x0, Index rows, Index cols);

// The dataset of frames `frames` (indices into d's frames, each once, in the order given) of `d`: an ordinary
// dataset (slots 0..K-1 in that order, slot_count K) whose PSFs, offsets, masks, weights and times are those
// frames'; the rest (manifest, truth, WCS, stars, ...) is d's. What a video's window is reconstructed from in
// batch (solvers/video_stream.hpp). InvalidArgument for an empty list, an index out of range or a repeat.
Dataset SelectFrames(const Dataset& d, const std::vector<int>& frames);

// What every image on a dataset's HR grid written to FITS carries (reconstructions and their maps): the
// dataset's HR WCS when it has one (Dataset::HrWcs) and BUNIT = `bunit` when not empty. The one place the
// commands take it from.
void SetHrImageKeywords(const Dataset& dataset, const std::string& bunit, FitsHeader* header);

}  // namespace aosr
