// A scene: what the sky, the telescope, the AO system, the DM offsets and the camera are, and which physical
// effects matter. Read from a JSON file (data/scenes/README.md documents every field with an example) by
// LoadScene; pipeline.hpp turns it into frames.
//
// ## Rules written once
//
//  * The sky is defined in *camera* pixels (positions, sizes, separations: `…_px` fields of objects are
//    camera pixels, fractional allowed) or as fractions of the frame, never in HR pixels: changing the
//    super-resolution factor r changes how finely the same sky is sampled, not the sky.
//  * Every object is rendered on the detector's field (the HR grid of the frame, r·rows × r·cols); the
//    simulator pads it with dark sky by the PSF's half-width before convolving (pipeline.hpp).
//  * Objects carry electrons per frame: a component's `flux` normalises it (total or peak over the frame,
//    or a magnitude). Without one, native values are used, again independent of r: surface-brightness
//    generators (usaf, demo, dead-leaves, and image with values "surface-brightness") give electrons per
//    frame per *camera-pixel area* (an HR pixel holds 1/r² of it); stars, galaxies and "flux-per-pixel"
//    images give total electrons per frame.
//  * Parsing validates everything, including the files a scene names and the geometry (r against the PSF
//    sampling, the PSF window against the pupil grid), before any computation. Errors are InvalidArgument
//    "<file>: <field path> = <value>; allowed: <range>" (io/config.hpp); unknown fields are errors.
//  * SI inside: nm, mas and camera pixels are converted here.
#pragma once

#include <cstdint>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "aosr/ao/ao_system.hpp"
#include "aosr/core/image.hpp"
#include "aosr/core/psf_field.hpp"
#include "aosr/scene/dead_leaves.hpp"
#include "aosr/scene/detector.hpp"
#include "aosr/scene/galaxy.hpp"
#include "aosr/scene/image_object.hpp"
#include "aosr/scene/objects.hpp"
#include "aosr/scene/photometry.hpp"
#include "aosr/scene/planet.hpp"
#include "aosr/scene/star_field.hpp"
#include "aosr/scene/telescope.hpp"

namespace aosr {

// How a component's brightness is set. kNative keeps the generator's values as electrons per frame per HR
// pixel; the others rescale the component so that, over the detector's field, its
//   kTotalElectrons  sum is `value` electrons per frame,
//   kPeakElectrons   largest HR pixel is `value` electrons per frame,
//   kMagnitude       sum is the electrons per frame of a source of magnitude `value` (photometry section).
struct FluxSpec {
  enum class Kind { kNative, kTotalElectrons, kPeakElectrons, kMagnitude };
  Kind kind = Kind::kNative;
  double value = 0.0;
};

// How a component changes during a sequence (JSON object field "variation"; only with a scene `sequence`).
// The component is rendered at each exposure's mid-time t (SceneSpec::ExposureTime; the motion within one
// exposure is not smeared):
//  * velocity: it moves by (v_y, v_x)·t camera pixels from where its fields put it (stars exactly, as
//    catalogue positions; extended components by a band-limited Fourier shift on the padded convolution grid,
//    so light that leaves the frame is gone and light from outside never arrives: the padded grid's dark
//    border comes in);
//  * light curve: its flux is multiplied by f(t) ≥ 0: "sine" 1 + a·sin(2π t / period + phase), or a table
//    of (times_s, factors) interpolated linearly and held beyond its ends.
// The flux normalisation (`flux`) applies to the component at t = 0 before f(t).
struct ObjectVariation {
  double velocity_y_px_per_s = 0.0, velocity_x_px_per_s = 0.0;
  enum class Curve { kNone, kSine, kTable };
  Curve curve = Curve::kNone;
  double period_s = 0.0, amplitude = 0.0, phase_deg = 0.0;  // kSine
  std::vector<double> times_s, factors;                      // kTable
  bool Moves() const { return velocity_y_px_per_s != 0.0 || velocity_x_px_per_s != 0.0; }
  bool IsStatic() const { return !Moves() && curve == Curve::kNone; }
  double FluxFactor(double t) const;
};

// One object component. Only the fields of its kind are used.
struct ObjectSpec {
  enum class Kind { kUsaf, kDemo, kStars, kGalaxies, kDeadLeaves, kImage, kSlantedEdge, kPlanet };
  Kind kind = Kind::kDemo;
  // the JSON name: "usaf", "demo", "stars", "galaxies", "dead-leaves", "image", "slanted-edge", "planet"
  std::string type;
  FluxSpec flux;
  ObjectVariation variation;
  std::uint64_t seed = 0;  // random components: the component's seed (derived from the scene's if not given)

  // usaf: the target's bounding box fills this fraction of the smaller frame side, (0, 1].
  double usaf_fill = 0.9;
  UsafOptions usaf;  // pixels_per_mm is derived from usaf_fill at render time

  // slanted-edge: the knife edge (objects.hpp); its centre in camera pixels of the frame (NaN: the frame's
  // centre), converted to HR pixels at render time.
  SlantedEdgeTargetOptions slanted_edge;

  // stars: either a random field (`stars` with sizes in camera pixels, converted at render time) or an
  // explicit catalogue (`catalogue`, positions in camera pixels of the frame, flux in electrons per frame
  // unless `flux` rescales). `star_magnitudes` says the luminosity function's range was given as
  // magnitudes and already converted to electrons per frame (then `flux` must be native).
  StarFieldOptions stars;
  std::vector<PointSource> catalogue;
  bool star_magnitudes = false;

  // galaxies: sizes and margin in camera pixels (converted at render time).
  GalaxyFieldOptions galaxies;

  // dead-leaves: radii in camera pixels (converted at render time).
  DeadLeavesOptions dead_leaves;

  // image: the file (resolved against the scene's folder) and how it is resampled onto the field.
  std::string image_path;
  ImageObjectOptions image;

  // planet (planet.hpp): a rotating textured sphere; radius and centre in camera pixels here (converted at
  // render time), the procedural texture's options, or `texture_path`, an equirectangular map (latitude +90
  // at row 0, longitude 0..360 along the columns) read as an image file. Its surface brightness is the
  // texture's value (e⁻ per frame per camera-pixel area) times the limb darkening.
  PlanetOptions planet;
  PlanetTextureOptions planet_texture;
  std::string texture_path;

  bool IsPointSources() const { return kind == Kind::kStars; }
  // Whether the component looks different at different times: a variation, or a planet that rotates.
  bool IsTimeVarying() const { return !variation.IsStatic() || (kind == Kind::kPlanet && planet.rotation_period_s != 0.0); }
};

// One exposure's DM offset w_dm,i: an image shift made with tip/tilt, plus Zernike terms, plus optional
// per-actuator commands. All zero: the exposure has no offset.
struct DmOffset {
  double shift_y_px = 0.0;  // image shift in camera pixels (+x: toward larger column)
  double shift_x_px = 0.0;
  struct Term {
    int noll = 2;         // Noll index >= 2
    double rms_m = 0.0;   // wavefront OPD RMS on the pupil [m]
  };
  std::vector<Term> zernike;
  std::vector<double> actuators_m;  // DM commands [m] (one per active actuator), empty for none
  bool IsZero() const;
  bool operator==(const DmOffset& o) const;
};

struct OffsetsSpec {
  enum class Kind { kNone, kRaster, kDesign };
  Kind kind = Kind::kNone;
  std::string source;             // "inline", or the design file's path
  std::vector<DmOffset> frames;   // one per exposure (N entries) after parsing, whatever the kind
};

struct AoSpec {
  enum class Mode { kNone, kAnalytic, kClosedLoop };
  Mode mode = Mode::kNone;
  // Closed loop only: the sensor model, and the telescope time simulated per exposure and before the first.
  // The Monte-Carlo costs ~1 ms per loop step, so a scene simulates a representative stretch of each
  // exposure (default 0.1 s, 80 steps at 800 Hz) rather than its whole integration time.
  SensorKind sensor = SensorKind::kDiffractive;
  double time_per_frame_s = 0.1;
  double settling_s = 0.1;
  int psf_every_steps = 1;
  // Closed loop only: the DM's actual stroke per commanded metre, [0.5, 2] (ClosedLoopOptions::dm_gain): a
  // stroke calibration error of the simulated hardware. NominalPsfs (pipeline.hpp) does not model it: it is
  // an error the observer does not know about. Default 1.
  double dm_gain = 1.0;
  // Closed loop only: how the DM offsets become reference slopes (ClosedLoopOptions::offset_calibration):
  // "on-sky" (default: the tip/tilt gain measured at the operating point, the commanded shift is held) or
  // "flat" (the flat-wavefront slopes: a diffractive SH's images then land 9 - 19 % further out than
  // commanded, bench/results/psf_offsets.md).
  OffsetCalibration offset_calibration = OffsetCalibration::kOnSky;
  // Closed loop only: run the loop twice, on the atmosphere and on its negation (AtmosphereOptions::antithetic),
  // and average each exposure's PSF and Strehl over the pair. The simulated stretch (time_per_frame_s) stands
  // for a whole integration, which would average away the stretch's random residual tilt (the SH senses the
  // mean gradient, the core follows the least-squares tilt: 0.03 - 0.05 lambda/D per 0.1 s that does not
  // average within seconds, bench/results/psf_offsets.md); the tilt is odd in the atmosphere and cancels in
  // the pair exactly, the Strehl and halo are even and stay. Twice the loop's cost. Default true.
  bool antithetic = true;
  std::uint64_t seed = 0;  // atmosphere and WFS noise
};

struct PhotometrySpec {
  std::string band;          // Vega band name (photometry.hpp); empty if no magnitudes are used
  double throughput = 0.3;   // pupil photons -> detected electrons, (0, 1]
  // Instrumental zero point: the magnitude that gives 1 e-/s. When set it replaces band, area and
  // throughput for magnitudes (the sky background still needs the band unless given in e-/s).
  std::optional<double> zero_point_mag;
};

// Where the scene is on the sky: the tangent-plane WCS (io/wcs.hpp) of the simulated files. The sky position
// (ra_deg, dec_deg) is that of the frame's centre on the undithered grid (the truth's centre: aosr pixel
// ((rows − 1)/2, (cols − 1)/2) of the camera grid); the image's +y axis points to position_angle_deg east of
// north (0: north up, east to the left, as the sky is seen). The default, (0°, 0°) ICRS with north up, is a
// placeholder that gives viewers the right scale and orientation; `given` says whether the scene set it.
struct SkySpec {
  double ra_deg = 0.0;               // [0, 360)
  double dec_deg = 0.0;              // [−90, 90]
  double position_angle_deg = 0.0;   // [−360, 360]
  bool given = false;
};

// A PSF that changes across the field (anisoplanatism; issue 31). JSON "psf_field": {"guide_star_arcsec":
// [x, y], "grid": [ny, nx] or n}. A single-conjugate AO system corrects its guide star's direction; a science
// direction θ from it sees each turbulent layer displaced by altitude × θ, so the residual and the PSF change
// across the field (ao/analytic_ao.hpp section 2; closed loop: ao/closed_loop.hpp, "Off axis").
//  * guide_star_arcsec: the guide star's position from the frame's centre (the truth's centre, as SkySpec's),
//    x along columns, y along rows, in arcsec; inside or outside the frame. Default [0, 0].
//  * grid: PSFs are computed at ny x nx field points on the frame (core/psf_field.hpp: the outer nodes on the
//    frame's edges) and interpolated bilinearly between them; each axis 2..33 (1 for an axis along which the
//    PSF is taken as constant). The spacing must be at most Fried's isoplanatic angle θ0 at the science
//    wavelength (the anisoplanatic phase variance over one spacing is then at most 1 rad², and the
//    interpolation's error small: bench/results/wide_field.md measures it against a denser grid).
// Needs ao.mode analytic or closed-loop (a diffraction-limited PSF is the same everywhere). A scene without
// psf_field is isoplanatic: the PSF of the guide star's direction everywhere, with the same bytes as before
// psf_field existed. With it, the frames are rendered through the field-varying PSF, and Simulation::psfs is
// the guide star's (on-axis) PSF: the single-PSF model a reconstructor without field knowledge would use.
struct PsfFieldSpec {
  bool enabled = false;
  double guide_star_x_arcsec = 0.0, guide_star_y_arcsec = 0.0;
  int grid_y = 3, grid_x = 3;
};

// A video (issue 34; JSON "sequence": {"frames": M, "frame_interval_s": Δ, "start_s": t0}): M exposures
// while the DM cycles through the N offsets (exposure j has offset j mod N, phase j mod N). Exposure j starts
// at t0 + j·Δ and lasts the frame time (total_exposure_s / N: total_exposure_s stays one cycle's exposure);
// Δ ≥ the frame time (default: equal, back to back). Objects with a `variation` (or a rotating planet) are
// rendered at each exposure's mid-time. The closed loop runs once, continuously, through all M exposures, as
// it does through N without a sequence: the residual of exposure j + N is not that of exposure j (the loop's
// simulated stretch per exposure is still ao.time_per_frame_s; set it to Δ for the real cadence). The
// dataset records each frame's phase and time (dataset.hpp, "sequence") and the truth at each exposure.
struct SequenceSpec {
  int frames = 0;  // M; 0: no sequence
  double frame_interval_s = 0.0;
  double start_s = 0.0;
  bool enabled() const { return frames > 0; }
};

struct SceneSpec {
  std::string name;
  std::string source;  // the scene file ("<string>" when parsed from memory)

  TelescopePreset telescope;
  int frames = 4;       // N sub-exposures
  int r = 2;            // super-resolution factor: HR pixel = camera pixel / r
  Shape frame;          // camera frame, rows x cols (camera pixels)
  std::uint64_t seed = 1;

  std::vector<ObjectSpec> objects;  // at least one; summed
  AoSpec ao;
  std::vector<DmOffset::Term> static_aberrations;  // w_static (science path only)
  OffsetsSpec offsets;
  SkySpec sky;
  PhotometrySpec photometry;
  PsfFieldSpec psf_field;
  SequenceSpec sequence;

  DetectorOptions detector;        // exposure_time_s = total exposure / N (the frame time)
  double total_exposure_s = 1.0;   // the whole sequence; each frame gets total / N
  std::uint64_t noise_seed = 0;
  std::uint64_t bad_pixel_seed = 0;
  double bad_pixel_fraction = 0.0;  // > 0: a random map; the file, when given, is in detector.bad_pixel_mask
  std::string bad_pixel_file;

  Index psf_size_px = 0;  // PSF kernel side at HR sampling (even)

  // The sky's sampling against the HR grid, s in [1, 16] (JSON `sky_oversampling`, default 1). 1: the sky is
  // a grid of HR pixels and the PSFs are sampled at the HR pitch (the reconstructors' model, exactly). s > 1:
  // the frames are rendered from a sky s times finer than the HR grid (objects at r·s per camera pixel, PSFs
  // sampled at HR pitch / s, each camera pixel integrating its (r·s)² fine pixels): a stand-in for a
  // continuous sky, for measuring what the HR grid's discretisation itself does. The outputs stay on the HR
  // grid: the truth is the fine sky integrated over each HR pixel, the PSFs are the same PSFs sampled at the
  // HR pitch (what a reconstructor uses). Cost: the object, PSF and convolution stages at s² times the pixels.
  int sky_oversampling = 1;

  // The exposures the simulator makes: M with a sequence, else N; exposure j's DM offset (phase j mod N)
  // and its mid-exposure time in seconds (without a sequence: frame j's, though nothing then changes in time).
  // InvalidArgument for j outside 0..Exposures()-1.
  int Exposures() const { return sequence.enabled() ? sequence.frames : frames; }
  const DmOffset& ExposureOffset(int j) const;
  double ExposureTime(int j) const;
  // Whether any component changes during the sequence (false without one: objects are then rendered at t = 0).
  bool TimeVarying() const;

  // Derived geometry.
  Shape HrFrame() const { return {frame.rows * r, frame.cols * r}; }
  // psf_field's grid over the HR frame (empty without psf_field), and node k's direction from the guide star.
  PsfFieldGrid FieldGrid() const;
  FieldDirection FieldNodeDirection(int k) const;
  double CameraPixelRad() const { return telescope.camera_pixel_rad; }
  double HrPixelRad() const { return telescope.camera_pixel_rad / r; }
  // HR pixel in lambda/D at the science wavelength.
  double HrPixelLambdaOverD() const { return HrPixelRad() / telescope.LambdaOverD(); }
  // The light collector of the photometry (telescope area, throughput).
  LightCollectorOptions Collector() const;
  // Electrons per frame of a source of `magnitude` (zero point or band/area/throughput; frame time).
  double ElectronsPerFrameForMagnitude(double magnitude) const;
};

// The USAF target options a usaf or demo object renders with on the HR grid `hr` (its pixels_per_mm from `fill`
// for usaf; DemoUsafOptions for demo). InvalidArgument for another kind of object.
UsafOptions ObjectUsafOptions(const ObjectSpec& object, Shape hr);

// Reads and validates a scene file. Relative paths inside (telescope preset files, design files, images,
// bad-pixel maps) are resolved against the scene's folder; a bare telescope name is a preset of
// data/telescopes/.
SceneSpec LoadScene(const std::string& path);
// The same from an already-read JSON object; `source` names it in messages and its folder resolves paths.
SceneSpec ParseScene(const nlohmann::json& json, const std::string& source);

// The DM offsets of a design file (the phase-design output, or hand-written): {"frames": [ {...}, ... ]}
// with each frame as in a scene's inline design (data/scenes/README.md). `frames` entries are required.
std::vector<DmOffset> LoadDesignFile(const std::string& path);

// JSON forms used by manifests (round-trip with the parser's inline design format).
nlohmann::json DmOffsetToJson(const DmOffset& offset);

}  // namespace aosr
