#include "aosr/scene/pipeline.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <functional>
#include <limits>
#include <map>
#include <memory>

#include "aosr/ao/analytic_ao.hpp"
#include "aosr/ao/ao_system.hpp"
#include "aosr/ao/phase_screen.hpp"
#include "aosr/core/error.hpp"
#include "aosr/core/fft.hpp"
#include "aosr/core/memory.hpp"
#include "aosr/core/metrics.hpp"
#include "aosr/core/operators.hpp"
#include "aosr/optics/psf.hpp"
#include "aosr/io/image_io.hpp"
#include "aosr/optics/zernike.hpp"
#include "aosr/scene/dead_leaves.hpp"
#include "aosr/scene/galaxy.hpp"
#include "aosr/scene/image_object.hpp"
#include "aosr/scene/point_sources.hpp"
#include "aosr/scene/preset_psf.hpp"
#include "aosr/scene/star_field.hpp"

namespace aosr {
namespace {

// ---- Cost model (PipelineStage::estimated_s) --------------------------------------------------------------
// Nominal single-core rates of the development machine (a shared 2-core VM), rounded; the benchmark
// (bench/simulate_bench.cpp) prints the model beside the measured time of every stage.
constexpr double kFftFlopsPerS = 1.5e9;    // FFTW r2c/c2r, counting 2.5 N log2 N flops
constexpr double kGemmFlopsPerS = 8e9;     // Eigen complex matrix products (MFT, point-source spectra)
constexpr double kRenderSPerPixel = 5e-9;   // exact-area USAF / demo rendering per HR pixel
constexpr double kLoopStepS128 = 0.9e-3;    // one closed-loop frame for a 128-px pupil, science PSF excluded
constexpr double kDetectorNoiseSPerPixel = 60e-9;  // Poisson + read noise per pixel
constexpr double kDetectorPlainSPerPixel = 5e-9;   // conversion, masks, weights only

double FftSeconds(Shape s) {
  const double n = double(s.rows) * double(s.cols);
  return 2.5 * n * std::log2(std::max(2.0, n)) / kFftFlopsPerS;
}
// Diffraction PSF by the MFT: two complex products (K x n)(n x n) and (K x n)(n x K), 8 flops per complex
// multiply-add.
double MftSeconds(Index pupil, Index k) {
  return 8.0 * (double(k) * pupil * pupil + double(k) * k * pupil) / kGemmFlopsPerS;
}

double Seconds(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

std::string Fmt(const char* format, double a) {
  char buf[64];
  std::snprintf(buf, sizeof buf, format, a);
  return buf;
}

const char* ModeName(AoSpec::Mode m) {
  return m == AoSpec::Mode::kNone ? "diffraction" : m == AoSpec::Mode::kAnalytic ? "analytic AO" : "closed-loop AO";
}

bool NeedsDm(const SceneSpec& s) {
  for (const DmOffset& o : s.offsets.frames)
    if (!o.actuators_m.empty()) return true;
  return false;
}

// Surface-brightness generators give electrons per frame per *camera* pixel area (scene_spec.hpp); the HR
// pixel holds 1/r² of that.
bool IsSurfaceBrightness(const ObjectSpec& o) {
  switch (o.kind) {
    case ObjectSpec::Kind::kUsaf:
    case ObjectSpec::Kind::kDemo:
    case ObjectSpec::Kind::kDeadLeaves:
    case ObjectSpec::Kind::kSlantedEdge:
    case ObjectSpec::Kind::kPlanet:
      return true;
    case ObjectSpec::Kind::kImage:
      return o.image.values == PixelValues::kSurfaceBrightness;
    default:
      return false;
  }
}

// The normalisation factor of a component whose values over the frame sum to `sum` with maximum `peak`.
double FluxScale(const SceneSpec& scene, const ObjectSpec& o, std::size_t index, double sum, double peak) {
  const std::string where = scene.source + ": objects[" + std::to_string(index) + "] (" + o.type + ")";
  switch (o.flux.kind) {
    case FluxSpec::Kind::kNative:
      return 1.0;
    case FluxSpec::Kind::kPeakElectrons:
      if (!(peak > 0)) throw InvalidArgument(where + ": flux.peak_e needs a component with a positive maximum");
      return o.flux.value / peak;
    case FluxSpec::Kind::kTotalElectrons:
    case FluxSpec::Kind::kMagnitude: {
      if (!(sum > 0)) throw InvalidArgument(where + ": a total flux needs a component whose sum over the frame is > 0");
      const double target = o.flux.kind == FluxSpec::Kind::kTotalElectrons ? o.flux.value
                                                                          : scene.ElectronsPerFrameForMagnitude(o.flux.value);
      return target / sum;
    }
  }
  return 1.0;
}

// A planet component's disc on the HR frame at time t: its camera-pixel geometry in HR pixels (camera pixel
// centre c is HR coordinate (c + 0.5) r − 0.5), moved by its velocity.
PlanetOptions PlanetOnHr(const SceneSpec& scene, const ObjectSpec& o, Shape hr, double t) {
  const double r = scene.r;
  PlanetOptions p = o.planet;
  p.radius_px *= r;
  p.centre_y = std::isnan(p.centre_y) ? 0.5 * double(hr.rows - 1) : (p.centre_y + 0.5) * r - 0.5;
  p.centre_x = std::isnan(p.centre_x) ? 0.5 * double(hr.cols - 1) : (p.centre_x + 0.5) * r - 0.5;
  p.centre_y += o.variation.velocity_y_px_per_s * t * r;
  p.centre_x += o.variation.velocity_x_px_per_s * t * r;
  return p;
}

Image PlanetTextureOf(const ObjectSpec& o) {
  return o.texture_path.empty() ? PlanetTexture(o.planet_texture, o.seed) : ReadImage(o.texture_path);
}

// A planet component at time t on the HR frame, before FluxScale: surface brightness per camera-pixel area, so an
// HR pixel holds 1/r² of it (IsSurfaceBrightness).
Image RenderPlanetAt(const SceneSpec& scene, const ObjectSpec& o, Shape hr, const Image& texture, double t) {
  return RenderPlanet(hr, PlanetOnHr(scene, o, hr, t), texture, t) / double(scene.r * scene.r);
}

// Renders one extended component on the HR frame, in electrons per frame per HR pixel before FluxScale.
Image RenderExtended(const SceneSpec& scene, const ObjectSpec& o, Shape hr) {
  const double r = scene.r;
  Image img;
  switch (o.kind) {
    case ObjectSpec::Kind::kUsaf:
      img = UsafTarget(hr, ObjectUsafOptions(o, hr));
      break;
    case ObjectSpec::Kind::kDemo:
      img = DemoObject(hr);
      break;
    case ObjectSpec::Kind::kGalaxies: {
      GalaxyFieldOptions g = o.galaxies;  // sizes in camera pixels -> HR pixels
      g.re_min_px *= r;
      g.re_max_px *= r;
      g.margin_px *= r;
      img = RenderGalaxies(hr, GalaxyField(hr, g, o.seed));
      break;
    }
    case ObjectSpec::Kind::kDeadLeaves: {
      DeadLeavesOptions d = o.dead_leaves;
      d.r_min_px *= r;
      d.r_max_px *= r;
      img = DeadLeaves(hr, d, o.seed);
      break;
    }
    case ObjectSpec::Kind::kImage:
      img = LoadImageObject(o.image_path, hr, o.image);
      break;
    case ObjectSpec::Kind::kSlantedEdge: {
      SlantedEdgeTargetOptions e = o.slanted_edge;  // camera pixel c covers HR pixels c r .. c r + r - 1
      if (!std::isnan(e.centre_y)) e.centre_y = (e.centre_y + 0.5) * r - 0.5;
      if (!std::isnan(e.centre_x)) e.centre_x = (e.centre_x + 0.5) * r - 0.5;
      img = SlantedEdgeTarget(hr, e);
      break;
    }
    case ObjectSpec::Kind::kPlanet:
      return RenderPlanetAt(scene, o, hr, PlanetTextureOf(o), 0.0);
    case ObjectSpec::Kind::kStars:
      throw InvalidArgument("RenderExtended: stars are point sources");
  }
  if (IsSurfaceBrightness(o)) img /= r * r;
  return img;
}

// The stars of one component in HR-frame coordinates, electrons per frame before FluxScale.
std::vector<PointSource> StarsOf(const SceneSpec& scene, const ObjectSpec& o, Shape hr) {
  const double r = scene.r;
  if (!o.catalogue.empty()) {
    std::vector<PointSource> out = o.catalogue;
    for (PointSource& p : out) {  // camera pixel centre c covers HR pixels c r .. c r + r - 1
      p.y = (p.y + 0.5) * r - 0.5;
      p.x = (p.x + 0.5) * r - 0.5;
    }
    return out;
  }
  StarFieldOptions s = o.stars;
  s.min_separation_px *= r;
  s.margin_px *= r;
  return StarField(hr, s, o.seed);
}

// The stars as they go into the truth image: bilinear deposition (non-negative, flux- and centroid-preserving;
// positions within half a pixel of the edge are moved onto the outermost pixel centres). A band-limited point
// (PointSourceImage) would be exact for the frames' model but rings with lobes of ~10% of the star, useless
// for PSNR or photometry; the frames use the exact sub-pixel PSFs and the catalogue is the exact truth.
Image StarTruth(Shape hr, std::vector<PointSource> stars) {
  for (PointSource& p : stars) {
    p.y = std::clamp(p.y, 0.0, double(hr.rows - 1));
    p.x = std::clamp(p.x, 0.0, double(hr.cols - 1));
  }
  Image img = Image::Zero(hr.rows, hr.cols);
  AddPointSources(&img, stars);
  return img;
}

// The sum of each s x s block (the HR pixel of a sky s times finer); the sides are multiples of s.
Image BlockSum(const Image& fine, int s) {
  Image out = Image::Zero(fine.rows() / s, fine.cols() / s);
  for (Index i = 0; i < fine.rows(); ++i)
    for (Index j = 0; j < fine.cols(); ++j) out(i / s, j / s) += fine(i, j);
  return out;
}

// A centred PSF sampled at pitch θ/s (size k·s) at the HR pitch θ (size k): sample k·s/2 + (j − k/2)·s = j·s
// lies at the same angle as HR sample j (centre at size/2, image.hpp), renormalised to unit sum.
Image SubsamplePsf(const Image& fine, int s) {
  Image out(fine.rows() / s, fine.cols() / s);
  for (Index i = 0; i < out.rows(); ++i)
    for (Index j = 0; j < out.cols(); ++j) out(i, j) = fine(i * s, j * s);
  return NormaliseToUnitSum(out);
}

// A star at fine-grid coordinate c (s fine pixels per HR pixel): fine pixel s·J .. s·J + s − 1 is HR pixel J,
// whose centre is fine coordinate s·J + (s − 1)/2.
PointSource StarToHr(PointSource p, int s) {
  p.y = (p.y + 0.5) / s - 0.5;
  p.x = (p.x + 0.5) / s - 0.5;
  return p;
}

// The OPD with its tip and tilt removed: Strehl about the PSF's own centre, so a designed image shift does
// not read as a loss of image quality.
Image WithoutTilt(const Image& opd, const Image& amplitude) {
  const Vector c = ProjectOntoZernike(opd, amplitude, 3);
  const Index n = opd.rows();
  Image out = opd;
  for (Index i = 0; i < n; ++i)
    for (Index j = 0; j < n; ++j)
      if (amplitude(i, j) <= 0) out(i, j) = 0.0;
  const Image z2 = Zernike(2, n), z3 = Zernike(3, n);  // the modes ProjectOntoZernike fits
  return out - c[1] * z2 - c[2] * z3;
}

// The components of a sequence that change in time (ObjectVariation, a rotating planet), rendered at any t:
// each is normalised once, at t = 0, as a static component is, then moved and scaled. An extended component
// that moves is Fourier-shifted on a grid padded by its largest displacement over the sequence, so that
// nothing wraps around into the frame; a planet is re-rendered at its moved centre (exact, no shift).
class ChangingComponents {
 public:
  ChangingComponents(const SceneSpec& scene, Shape hr, int flux_binning) : scene_(scene), hr_(hr) {
    double t_max = 0;
    for (int j = 0; j < scene.Exposures(); ++j) t_max = std::max(t_max, std::abs(scene.ExposureTime(j)));
    for (std::size_t i = 0; i < scene.objects.size(); ++i) {
      const ObjectSpec& o = scene.objects[i];
      if (!o.IsTimeVarying()) continue;
      Item c;
      c.spec = &o;
      if (o.IsPointSources()) {
        c.stars = StarsOf(scene, o, hr);
        double sum = 0, peak = 0;
        for (const PointSource& p : c.stars) sum += p.flux, peak = std::max(peak, p.flux);
        const double scale = FluxScale(scene, o, i, sum, peak);
        for (PointSource& p : c.stars) p.flux *= scale;
      } else {
        // A planet's map is read (or made) once, for its t = 0 normalisation and every exposure.
        if (o.kind == ObjectSpec::Kind::kPlanet) c.texture = PlanetTextureOf(o);
        Image base = o.kind == ObjectSpec::Kind::kPlanet ? RenderPlanetAt(scene, o, hr, c.texture, 0.0) : RenderExtended(scene, o, hr);
        if (!AllFinite(base)) throw NumericalError("ScenePipeline: objects[" + std::to_string(i) + "] rendered non-finite values");
        c.scale = FluxScale(scene, o, i, base.sum(), flux_binning > 1 ? BlockSum(base, flux_binning).maxCoeff() : base.maxCoeff());
        if (o.kind != ObjectSpec::Kind::kPlanet && o.variation.Moves()) {
          // Padded by its largest displacement, but never by more than the frame: a component moved farther
          // than that has left the frame entirely (AddAt skips it), and a shift of at most the frame's side
          // on this grid wraps nothing into the frame.
          const double r = scene.r;
          auto margin = [&](double v, Index side) {
            return Index(std::min(std::ceil(std::abs(v) * t_max * r), double(side))) + 2;
          };
          c.margin_y = margin(o.variation.velocity_y_px_per_s, hr.rows);
          c.margin_x = margin(o.variation.velocity_x_px_per_s, hr.cols);
          c.base = Image::Zero(hr.rows + 2 * c.margin_y, hr.cols + 2 * c.margin_x);
          c.base.block(c.margin_y, c.margin_x, hr.rows, hr.cols) = c.scale * base;
        } else if (o.kind != ObjectSpec::Kind::kPlanet) {  // a planet is re-rendered per exposure from c.texture
          c.base = c.scale * base;
        }
      }
      items_.push_back(std::move(c));
    }
  }

  // Adds the changing components at time t to the extended image (HR frame) and the stars (HR coordinates).
  void AddAt(double t, Image* extended, std::vector<PointSource>* stars) const {
    const double r = scene_.r;
    for (const Item& c : items_) {
      const ObjectVariation& v = c.spec->variation;
      const double f = v.FluxFactor(t);
      const double dy = v.velocity_y_px_per_s * t * r, dx = v.velocity_x_px_per_s * t * r;
      if (c.spec->IsPointSources()) {
        // A star is on the sky while it is on the frame, as a catalogue's must be (scene_spec.cpp: camera pixel
        // centres within half a pixel of the edge); once it has left, its light is gone (on the periodic padded
        // grid it would otherwise come back from the other side).
        for (PointSource p : c.stars) {
          p.y += dy, p.x += dx, p.flux *= f;
          if (p.y >= -0.5 && p.y <= double(hr_.rows) - 0.5 && p.x >= -0.5 && p.x <= double(hr_.cols) - 0.5) stars->push_back(p);
        }
      } else if (c.spec->kind == ObjectSpec::Kind::kPlanet) {
        *extended += (f * c.scale) * RenderPlanetAt(scene_, *c.spec, hr_, c.texture, t);
      } else if (v.Moves()) {
        if (std::abs(dy) >= double(hr_.rows) || std::abs(dx) >= double(hr_.cols)) continue;  // off the frame
        *extended += f * FourierShiftImage(c.base, dy, dx).block(c.margin_y, c.margin_x, hr_.rows, hr_.cols);
      } else {
        *extended += f * c.base;
      }
    }
  }

 private:
  struct Item {
    const ObjectSpec* spec = nullptr;
    double scale = 1.0;
    Image base;       // extended (not planets): normalised, on the padded shift grid when it moves
    Index margin_y = 0, margin_x = 0;
    Image texture;    // planets
    std::vector<PointSource> stars;  // normalised, at t = 0
  };
  const SceneSpec& scene_;
  Shape hr_;
  std::vector<Item> items_;
};

}  // namespace

Image ExposureOpd(const SceneSpec& scene, const DmOffset& offset, const Image& static_opd_m, const DeformableMirror* dm) {
  const Index n = scene.telescope.pupil_px;
  const double obstruction = scene.telescope.aperture.pupil.obstruction;
  const double diameter = scene.telescope.aperture.pupil.diameter_m;
  Image opd = static_opd_m.size() ? static_opd_m : Image(Image::Zero(n, n));
  // +x shift needs a positive x-slope (Z2), +y a positive y-slope (Z3): zernike.hpp, a = shift·D/4.
  if (offset.shift_x_px != 0.0)
    opd += TiltCoefficientForShift(offset.shift_x_px * scene.CameraPixelRad(), diameter) * Zernike(2, n, obstruction);
  if (offset.shift_y_px != 0.0)
    opd += TiltCoefficientForShift(offset.shift_y_px * scene.CameraPixelRad(), diameter) * Zernike(3, n, obstruction);
  for (const DmOffset::Term& t : offset.zernike)
    if (t.rms_m != 0.0) opd += t.rms_m * Zernike(t.noll, n, obstruction);
  if (!offset.actuators_m.empty()) {
    if (!dm) throw InvalidArgument("ExposureOpd: actuator commands need the deformable mirror");
    opd += dm->Opd(Eigen::Map<const Vector>(offset.actuators_m.data(), Index(offset.actuators_m.size())));
  }
  return opd;
}

ScenePipeline::ScenePipeline(SceneSpec scene) : scene_(std::move(scene)) { Compile(); }

// The peak of the large arrays Run() holds at once (pipeline.hpp, Cost), in bytes, from sizes alone: the HR
// object, truth and star truth; every exposure's PSF (twice for the closed loop: the nominal model too); the
// padded grid, its spectrum and one transfer function with its product; the convolved HR image of each
// distinct PSF; the LR frames (expected, and the detector's electrons, ADU, weights and valid map); the star
// catalogue (and its shifted copy); the pupil-plane work of one PSF (analytic AO: a few 2n x 2n complex
// grids; closed loop: the layers' screens and the WFS as well).
namespace {
double EstimatePeakBytes(const SceneSpec& s, const SceneGeometry& g) {
  const double hr = double(g.hr_frame.rows) * double(g.hr_frame.cols);
  const double lr = double(g.frame.rows) * double(g.frame.cols);
  const double padded = double(g.padded.rows) * double(g.padded.cols);
  const double half = double(g.padded.rows) * double(g.padded.cols / 2 + 1);
  const double k2 = double(g.psf_size) * double(g.psf_size);
  const double n2 = double(s.telescope.pupil_px) * double(s.telescope.pupil_px);
  const bool loop = s.ao.mode == AoSpec::Mode::kClosedLoop;
  double stars = 0;
  for (const ObjectSpec& o : s.objects)
    if (o.IsPointSources()) stars += o.catalogue.empty() ? o.stars.count : double(o.catalogue.size());
  // Distinct PSFs are at most the exposure count; the count itself is known only after compiling, so the bound.
  const double exposures = s.Exposures();
  const double distinct = exposures;
  const double layers = s.telescope.atmosphere ? double(s.telescope.atmosphere->layers.size()) : 0.0;
  const double pupil_work = 4 * 16 * (4 * n2) + (loop ? (layers + 4) * 8 * (4 * n2) : 0.0) + 2 * 16 * k2 * std::sqrt(n2);
  const double nodes = s.psf_field.enabled ? double(s.psf_field.grid_y) * s.psf_field.grid_x : 0.0;
  // psf_field: every node's PSFs (and the nominal ones), one weighted object image and the spectra summed
  // per distinct PSF.
  const double field = nodes * 8 * k2 * exposures * (loop ? 2 : 1) + (nodes > 0 ? 8 * padded + 16 * half * distinct : 0.0);
  // A sequence whose objects change: the truth at every exposure, and per exposure the object (its spectrum and
  // a shift grid) instead of one spectrum per distinct PSF.
  const double varying = s.TimeVarying() ? 8 * hr * exposures + 8 * 2 * padded : 0.0;
  return field + varying + 8 * 3 * hr + 8 * k2 * exposures * (loop ? 2 : 1) + 16 * 3 * half + 8 * 2 * padded +
         8 * (s.TimeVarying() ? 1.0 : distinct) * hr + 8 * lr * (distinct + 6.0 * exposures) +
         2 * sizeof(PointSource) * stars + pupil_work;
}
}  // namespace

void ScenePipeline::Compile() {
  const SceneSpec& s = scene_;
  SceneGeometry& g = geometry_;
  g.r = s.r;
  g.frame = s.frame;
  g.hr_frame = s.HrFrame();
  g.psf_size = s.psf_size_px;
  g.camera_pixel_rad = s.CameraPixelRad();
  g.hr_pixel_rad = s.HrPixelRad();
  g.hr_pixel_lambda_over_d = s.HrPixelLambdaOverD();
  g.wavelength_m = s.telescope.science_wavelength_m;
  // Half a window of dark sky on each side at least: the linear convolution of the frame with the window
  // then never wraps around (pipeline.hpp, Boundaries).
  g.padded = {NextFastFftSize(g.hr_frame.rows + g.psf_size), NextFastFftSize(g.hr_frame.cols + g.psf_size)};
  g.pad_top = g.psf_size / 2;
  g.pad_left = g.psf_size / 2;
  g.trustworthy_border_px = (g.psf_size / 2 + s.r - 1) / s.r;
  if (s.psf_field.enabled) {
    field_grid_ = s.FieldGrid();
    field_directions_.clear();
    field_max_angle_rad_ = 0.0;
    for (int k = 0; k < field_grid_.nodes(); ++k) {
      field_directions_.push_back(s.FieldNodeDirection(k));
      field_max_angle_rad_ = std::max(field_max_angle_rad_, field_directions_.back().Norm());
    }
  }
  // Before anything is built (the DM below, later the PSFs): can this run fit in memory at all?
  estimated_peak_bytes_ = EstimatePeakBytes(s, g);
  if (s.sky_oversampling > 1) {
    // The frames come from the same scene on the fine grid (pipeline.hpp); its constructor checks its own
    // memory and builds the plan this pipeline reports.
    SceneSpec fine = s;
    fine.r = s.r * s.sky_oversampling;
    fine.psf_size_px = s.psf_size_px * s.sky_oversampling;
    fine.sky_oversampling = 1;
    auto p = std::make_shared<ScenePipeline>(std::move(fine));
    p->flux_binning_ = s.sky_oversampling;
    // The field points stay where the HR grid puts them (the fine frame's own grid would move them by a
    // fraction of an HR pixel).
    p->field_grid_ = field_grid_;
    p->field_directions_ = field_directions_;
    p->field_scale_ = s.sky_oversampling;
    estimated_peak_bytes_ = std::max(estimated_peak_bytes_, p->estimated_peak_bytes_);
    fine_ = std::move(p);
  }
  CheckMemory(estimated_peak_bytes_, s.source + ": simulating " + std::to_string(s.Exposures()) + " frames of " +
                                         ToString(g.frame) + " at r = " + std::to_string(s.r) + " (HR " +
                                         ToString(g.hr_frame) + ", convolution grid " + ToString(g.padded) +
                                         ", PSF " + std::to_string(g.psf_size) + "^2, pupil " +
                                         std::to_string(s.telescope.pupil_px) + "^2)");

  // Only what is needed to validate: the DM (for the actuator count), not the PSFs.
  if (NeedsDm(s)) {
    if (!s.telescope.ao)
      throw InvalidArgument(s.source + ": offsets.frames[].actuators_nm need a telescope with an \"ao.dm\" section");
    const DeformableMirror dm(s.telescope.pupil_px, s.telescope.aperture.pupil, s.telescope.ao->dm);
    for (std::size_t i = 0; i < s.offsets.frames.size(); ++i) {
      const std::size_t a = s.offsets.frames[i].actuators_m.size();
      if (a != 0 && Index(a) != dm.n_active())
        throw InvalidArgument(s.source + ": offsets.frames[" + std::to_string(i) + "].actuators_nm has " + std::to_string(a) +
                              " values; allowed: one per active actuator (" + std::to_string(dm.n_active()) + ")");
    }
  }

  for (const ObjectSpec& o : s.objects) (o.IsPointSources() ? has_stars_ : has_extended_) = true;

  // Distinct pupil OPDs: exposures with the same offset share one PSF, except in the closed loop, where
  // every exposure is its own stretch of turbulence.
  // (A sequence's M exposures cycle through the N offsets: at most N distinct PSFs.)
  const int exposures = s.Exposures();
  distinct_.assign(exposures, 0);
  distinct_count_ = 0;
  if (s.ao.mode == AoSpec::Mode::kClosedLoop) {
    for (int i = 0; i < exposures; ++i) distinct_[i] = distinct_count_++;
  } else {
    std::vector<int> first;  // exposure index of each distinct group
    for (int i = 0; i < exposures; ++i) {
      int found = -1;
      for (int d = 0; d < int(first.size()) && found < 0; ++d)
        if (s.ExposureOffset(i) == s.ExposureOffset(first[d])) found = d;
      if (found < 0) {
        found = int(first.size());
        first.push_back(i);
      }
      distinct_[i] = found;
    }
    distinct_count_ = int(first.size());
  }

  // ---- The plan -------------------------------------------------------------------------------------------
  const Index n = s.telescope.pupil_px;
  const Index k = g.psf_size;
  const double hr_pixels = double(g.hr_frame.rows) * g.hr_frame.cols;
  auto add = [this](std::string name, std::string detail, int count, double est) {
    stages_.push_back({std::move(name), std::move(detail), count, est});
  };
  {
    std::string detail;
    double est = 0;
    int stars = 0;
    for (const ObjectSpec& o : s.objects) {
      detail += (detail.empty() ? "" : " + ") + o.type;
      if (o.IsPointSources()) {
        stars += o.catalogue.empty() ? o.stars.count : int(o.catalogue.size());
      } else {
        const int ss = o.kind == ObjectSpec::Kind::kDeadLeaves ? o.dead_leaves.supersample
                       : o.kind == ObjectSpec::Kind::kPlanet   ? o.planet.supersample
                                                               : 1;
        est += kRenderSPerPixel * hr_pixels * ss * ss * (o.kind == ObjectSpec::Kind::kGalaxies ? o.galaxies.count : 1);
      }
    }
    if (stars) detail += " (" + std::to_string(stars) + " stars kept as a catalogue)";
    add("object", detail + " on the " + ToString(g.hr_frame) + " HR frame", int(s.objects.size()), est);
  }
  if (!s.static_aberrations.empty())
    add("static-aberrations", std::to_string(s.static_aberrations.size()) + " Zernike terms on the " + std::to_string(n) + "^2 pupil", 1,
        1e-7 * n * n * s.static_aberrations.size());
  bool any_offset = false;
  for (const DmOffset& o : s.offsets.frames) any_offset = any_offset || !o.IsZero();
  if (any_offset)
    add("dm-offsets", std::string(s.offsets.kind == OffsetsSpec::Kind::kRaster ? "tip/tilt raster" : "designed offsets") +
                          ", " + std::to_string(distinct_count_) + " distinct pupil OPDs",
        s.frames, 1e-7 * n * n * s.frames);  // the N phases' OPDs (a sequence repeats them)
  const double psf_each = s.ao.mode == AoSpec::Mode::kAnalytic ? 2 * FftSeconds({2 * n, 2 * n}) + MftSeconds(2 * n, k)
                                                               : MftSeconds(n, k);
  if (s.ao.mode == AoSpec::Mode::kClosedLoop) {
    const double rate = s.telescope.ao->loop.rate_hz;
    const int steps = int(std::ceil((s.ao.time_per_frame_s + s.ao.settling_s) * rate - 1e-9));
    const int psf_steps = int(std::ceil(s.ao.time_per_frame_s * rate / s.ao.psf_every_steps - 1e-9));
    const char* sensor = s.ao.sensor == SensorKind::kIdeal ? "ideal" : s.ao.sensor == SensorKind::kGeometric ? "geometric SH" : "diffractive SH";
    const std::string atmosphere = s.telescope.atmosphere ? std::to_string(s.telescope.atmosphere->layers.size()) + "-layer atmosphere"
                                                          : "no atmosphere";
    const int runs = s.ao.antithetic && s.telescope.atmosphere ? 2 : 1;
    add("ao-loop", atmosphere + ", " + sensor + " WFS, " + std::to_string(steps) + " steps per exposure (" +
                       std::to_string(psf_steps) + " PSF frames) at " + Fmt("%g", rate) + " Hz" +
                       (runs == 2 ? ", twice (antithetic pair)" : "") +
                       (s.sequence.enabled() ? ", one loop through the sequence's " + std::to_string(exposures) + " exposures" : ""),
        exposures * runs, runs * exposures * (steps * kLoopStepS128 * (n * n) / (128.0 * 128.0) + psf_steps * psf_each));
  }
  add("psf", std::string(ModeName(s.ao.mode)) + " PSF, " + std::to_string(k) + "^2 at " + Fmt("%.3g", g.hr_pixel_lambda_over_d) +
                 " lambda/D from a " + std::to_string(n) + "^2 pupil; " + std::to_string(distinct_count_) + " distinct of " +
                 std::to_string(exposures) + " exposures",
      distinct_count_, s.ao.mode == AoSpec::Mode::kClosedLoop ? 0.0 : distinct_count_ * psf_each);
  if (s.ao.mode == AoSpec::Mode::kClosedLoop) {
    // Closed-loop PSFs are one realisation each; a reconstructor cannot know them. The analytic long-exposure
    // PSFs of the same offsets are the model it would use (Simulation::nominal_psfs).
    int groups = 0;
    for (int i = 0; i < s.frames; ++i) {
      bool seen = false;
      for (int j = 0; j < i; ++j) seen = seen || s.offsets.frames[j] == s.offsets.frames[i];
      groups += seen ? 0 : 1;
    }
    add("nominal-psf", "analytic-AO PSFs of the same offsets (the reconstructor's nominal model), " + std::to_string(groups) +
                           " distinct",
        groups, groups * (2 * FftSeconds({2 * n, 2 * n}) + MftSeconds(2 * n, k)));
  }
  const int nodes = field_grid_.nodes();
  if (nodes > 0) {
    const PsfFieldSpec& f = s.psf_field;
    double est = nodes * distinct_count_ * psf_each;
    for (const PipelineStage& st : stages_)
      if (st.name == "ao-loop" || st.name == "nominal-psf") est += nodes * st.estimated_s;
    add("psf-field", std::to_string(f.grid_y) + " x " + std::to_string(f.grid_x) + " field points, guide star at (" +
                         Fmt("%g", f.guide_star_x_arcsec) + ", " + Fmt("%g", f.guide_star_y_arcsec) +
                         ") arcsec from the centre, up to " + Fmt("%.3g", field_max_angle_rad_ * 180 * 3600 / M_PI) +
                         " arcsec from it; " + std::to_string(distinct_count_) + " PSFs per point" +
                         (s.ao.mode == AoSpec::Mode::kClosedLoop ? " (one loop per point, and the nominal model)" : ""),
        nodes * distinct_count_, est);
  }
  const double fft = FftSeconds(g.padded);
  const int weighted = nodes > 0 ? nodes : 1;  // object spectra: one per field point (core/psf_field.hpp)
  if (has_extended_)
    add("convolution", "FFT on the padded " + ToString(g.padded) + " grid: " + std::to_string(weighted) + " object r2c" +
                           (nodes > 0 ? " (one per field point) + " + std::to_string(weighted * distinct_count_) + " PSF r2c + " +
                                            std::to_string(distinct_count_) + " c2r"
                                      : " + " + std::to_string(distinct_count_) + " x (PSF r2c + c2r)"),
        distinct_count_, fft * (weighted + (weighted + 1) * distinct_count_));
  if (has_stars_) {
    int stars = 0;
    for (const ObjectSpec& o : s.objects)
      if (o.IsPointSources()) stars += o.catalogue.empty() ? o.stars.count : int(o.catalogue.size());
    add("point-sources", std::to_string(stars) + " exact sub-pixel PSFs in the Fourier domain of the padded " + ToString(g.padded) +
                             " grid" + (has_extended_ ? " (added to the object's spectrum)" : "; no object FFT") +
                             ", " + std::to_string(distinct_count_) + " x (PSF r2c + c2r)",
        distinct_count_,
        8.0 * stars * double(g.padded.rows) * (g.padded.cols / 2 + 1) / kGemmFlopsPerS + (has_extended_ ? 0.0 : fft * 2 * distinct_count_));
  }
  if (s.TimeVarying()) {
    int changing = 0, shifted = 0, planets = 0;
    double planet_samples = 0;  // per HR pixel, over the changing planets (each re-rendered per exposure)
    for (const ObjectSpec& o : s.objects) {
      changing += o.IsTimeVarying() ? 1 : 0;
      shifted += o.variation.Moves() && !o.IsPointSources() && o.kind != ObjectSpec::Kind::kPlanet ? 1 : 0;
      if (o.kind == ObjectSpec::Kind::kPlanet && o.IsTimeVarying()) {
        ++planets;
        planet_samples += double(o.planet.supersample) * o.planet.supersample;
      }
    }
    add("sequence", std::to_string(changing) + " changing component(s) rendered at each of the " + std::to_string(exposures) +
                        " exposures' mid-times (" + std::to_string(shifted) + " Fourier-shifted, " + std::to_string(planets) +
                        " planet(s) re-rendered); per exposure " + std::to_string(weighted) + " object r2c, " +
                        std::to_string(weighted) + " PSF r2c and one c2r instead of one per distinct PSF",
        exposures,
        exposures * (fft * (2 * weighted + 1 + 2 * shifted) + kRenderSPerPixel * hr_pixels * planet_samples));
  }
  add("pixel-integration", "crop to " + ToString(g.hr_frame) + ", D_" + std::to_string(s.r) + " to " + ToString(g.frame) +
                               (s.detector.fill_factor < 1 ? ", fill factor " + Fmt("%g", s.detector.fill_factor) : std::string()),
      exposures, 3e-9 * hr_pixels * (s.TimeVarying() ? exposures : distinct_count_));
  {
    const Detector detector(s.detector);
    std::string detail;
    for (const std::string& line : detector.Plan()) detail += (detail.empty() ? "" : "; ") + line;
    const bool noisy = s.detector.noise_model == NoiseModel::kPeakFraction ? s.detector.peak_noise_fraction > 0
                                                                            : s.detector.enable_photon_noise || s.detector.enable_read_noise;
    add("detector", detail, exposures,
        exposures * double(g.frame.rows) * g.frame.cols * (noisy ? kDetectorNoiseSPerPixel : kDetectorPlainSPerPixel));
  }
  if (fine_) {
    // The fine grid does the work: its stages, marked as such.
    stages_ = fine_->stages_;
    const std::string note = " (sky_oversampling " + std::to_string(s.sky_oversampling) + ": " +
                             std::to_string(s.sky_oversampling) + "x finer than the HR grid)";
    for (PipelineStage& st : stages_)
      if (st.name == "object" || st.name == "psf" || st.name == "convolution" || st.name == "point-sources" ||
          st.name == "pixel-integration")
        st.detail += note;
  }
}

std::string ScenePipeline::PlanReport() const {
  std::string out = "scene " + scene_.name + ": N = " + std::to_string(scene_.frames) +
                    (scene_.sequence.enabled() ? " (a sequence of " + std::to_string(scene_.sequence.frames) + " exposures)" : "") +
                    ", r = " + std::to_string(scene_.r) +
                    ", frames " + ToString(geometry_.frame) + " -> HR " + ToString(geometry_.hr_frame) + ", PSF " +
                    std::to_string(geometry_.psf_size) + "^2, border " + std::to_string(geometry_.trustworthy_border_px) + " px" +
                    (fine_ ? ", sky rendered on the " + ToString(fine_->geometry_.hr_frame) + " grid (sky_oversampling " +
                                 std::to_string(scene_.sky_oversampling) + ")"
                           : std::string()) +
                    "\n";
  double total = 0;
  for (const PipelineStage& st : stages_) {
    char buf[96];
    std::snprintf(buf, sizeof buf, "  %-19s x%-3d ~%9.4f s  ", st.name.c_str(), st.count, st.estimated_s);
    out += buf + st.detail + "\n";
    total += st.estimated_s;
  }
  out += "  total estimate ~" + Fmt("%.3f", total) + " s (cost model of src/scene/pipeline.cpp, one core), peak memory ~" +
         FormatBytes(estimated_peak_bytes_) + "\n";
  return out;
}

Image ScenePipeline::RenderTruth(std::vector<PointSource>* stars) const {
  if (fine_) {
    std::vector<PointSource> fine_stars;
    const Image truth = BlockSum(fine_->RenderTruth(&fine_stars), scene_.sky_oversampling);
    if (stars) {
      stars->clear();
      for (const PointSource& p : fine_stars) stars->push_back(StarToHr(p, scene_.sky_oversampling));
    }
    return truth;
  }
  std::vector<PointSource> all;
  Image truth = RenderObject(&all);
  if (!all.empty()) truth += StarTruth(geometry_.hr_frame, all);
  if (stars) *stars = std::move(all);
  return truth;
}

Image ScenePipeline::RenderObject(std::vector<PointSource>* stars) const {
  const Shape hr = geometry_.hr_frame;
  Image extended = Image::Zero(hr.rows, hr.cols);
  std::vector<PointSource> all;
  const bool sequence = scene_.TimeVarying();
  for (std::size_t i = 0; i < scene_.objects.size(); ++i) {
    const ObjectSpec& o = scene_.objects[i];
    if (sequence && o.IsTimeVarying()) continue;  // rendered per exposure (ChangingComponents)
    if (o.IsPointSources()) {
      std::vector<PointSource> s = StarsOf(scene_, o, hr);
      double sum = 0, peak = 0;
      for (const PointSource& p : s) sum += p.flux, peak = std::max(peak, p.flux);
      const double scale = FluxScale(scene_, o, i, sum, peak);
      for (PointSource& p : s) p.flux *= scale;
      all.insert(all.end(), s.begin(), s.end());
    } else {
      Image c = RenderExtended(scene_, o, hr);
      if (!AllFinite(c)) throw NumericalError("ScenePipeline: objects[" + std::to_string(i) + "] rendered non-finite values");
      // On the fine grid of sky_oversampling, a peak is that of the sky over HR pixels (flux_binning_²).
      c *= FluxScale(scene_, o, i, c.sum(), flux_binning_ > 1 ? BlockSum(c, flux_binning_).maxCoeff() : c.maxCoeff());
      extended += c;
    }
  }
  *stars = std::move(all);
  return extended;
}

ImageStack ScenePipeline::ComputePsfs(std::vector<int>* distinct, std::vector<double>* window_fraction,
                                      std::vector<double>* strehl, SimulationCounters* counters) const {
  std::vector<std::vector<double>> st;
  std::vector<ImageStack> out = ComputeDirectionPsfs({FieldDirection{}}, distinct, window_fraction, strehl ? &st : nullptr,
                                                     counters, {}, nullptr);
  if (strehl) *strehl = std::move(st.front());
  return std::move(out.front());
}

std::vector<ImageStack> ScenePipeline::ComputeDirectionPsfs(const std::vector<FieldDirection>& directions,
                                                           std::vector<int>* distinct,
                                                           std::vector<double>* window_fraction,
                                                           std::vector<std::vector<double>>* strehl,
                                                           SimulationCounters* counters,
                                                           const std::function<bool(int)>& step,
                                                           std::vector<std::array<double, 2>>* tilt_gain) const {
  const int D = int(directions.size());
  const SceneSpec& s = scene_;
  const Index n = s.telescope.pupil_px;
  const Image amplitude = s.telescope.PupilAmplitude();
  Image static_opd;
  if (!s.static_aberrations.empty()) {
    static_opd = Image::Zero(n, n);
    for (const DmOffset::Term& t : s.static_aberrations)
      static_opd += t.rms_m * Zernike(t.noll, n, s.telescope.aperture.pupil.obstruction);
  }
  std::unique_ptr<DeformableMirror> dm;
  if (NeedsDm(s)) dm = std::make_unique<DeformableMirror>(n, s.telescope.aperture.pupil, s.telescope.ao->dm);

  PsfSampling sampling;
  sampling.wavelength_m = s.telescope.science_wavelength_m;
  sampling.pixel_scale_rad = geometry_.hr_pixel_rad;
  sampling.rows = sampling.cols = geometry_.psf_size;

  // raw[k][d], raw_strehl[k][d]: direction k's distinct PSF d.
  std::vector<std::vector<Image>> raw(D, std::vector<Image>(distinct_count_));
  std::vector<std::vector<double>> raw_strehl(D, std::vector<double>(distinct_count_));
  if (s.ao.mode == AoSpec::Mode::kClosedLoop) {
    // Static aberrations are non-common-path (science camera only); the DM offsets go through the WFS
    // reference, as a real-time computer applies them.
    AoSystemSpec spec = s.telescope.ToAoSystemSpec(s.ao.sensor, s.ao.seed);
    // psf_field: every direction's loop on the screens of the widest one, so that all see one atmosphere and
    // one correction (the loop does not depend on the science direction: closed_loop.hpp, "Off axis").
    if (spec.atmosphere && field_max_angle_rad_ > 0.0) spec.atmosphere->max_field_angle_rad = field_max_angle_rad_;
    ClosedLoopOptions lo;
    lo.science = sampling;
    // Every direction in one loop (closed_loop.hpp, "Off axis"): the loop does not depend on them.
    lo.science_direction = directions.front();
    lo.extra_science_directions.assign(directions.begin() + 1, directions.end());
    lo.psf_every_steps = s.ao.psf_every_steps;
    lo.science_static_opd_m = static_opd;
    lo.dm_gain = s.ao.dm_gain;
    lo.offset_calibration = s.ao.offset_calibration;
    std::vector<Image> offsets;
    for (int i = 0; i < s.Exposures(); ++i) offsets.push_back(ExposureOpd(s, s.ExposureOffset(i), Image(), dm.get()));
    // One continuous run over the exposures, or (antithetic) two: the atmosphere and its negation, each
    // exposure's PSF and Strehl averaged over the pair (scene_spec.hpp, AoSpec::antithetic).
    const int runs = s.ao.antithetic && spec.atmosphere ? 2 : 1;
    if (tilt_gain) tilt_gain->assign(s.Exposures(), {0.0, 0.0});
    for (int run = 0; run < runs; ++run) {
      if (run == 1) spec.atmosphere->antithetic = true;
      AoSystem system = BuildAoSystem(spec);
      std::unique_ptr<ClosedLoop> loop = system.MakeLoop(lo);
      bool go = true;
      const std::vector<ClosedLoopResult> results = loop->RunSubExposures(
          offsets, s.ao.time_per_frame_s, s.ao.settling_s,
          step ? std::function<bool(int)>([&](int) { return go = step(D); }) : std::function<bool(int)>());
      if (!go) return {};
      const double w = 1.0 / runs;
      for (int i = 0; i < s.Exposures(); ++i) {
        if (tilt_gain) {
          (*tilt_gain)[i][0] += w * results[i].tilt_gain[0];
          (*tilt_gain)[i][1] += w * results[i].tilt_gain[1];
        }
        for (int k = 0; k < D; ++k) {
          const ClosedLoopResult& res = k == 0 ? results[i] : results[i].extra_directions[std::size_t(k - 1)];
          raw[k][i] = run == 0 ? Image(w * res.psf) : Image(raw[k][i] + w * res.psf);
          raw_strehl[k][i] += w * res.psf_strehl;
        }
        if (counters) counters->loop_steps += results[i].steps + results[i].settling_steps;
      }
    }
    if (tilt_gain && s.ao.offset_calibration != OffsetCalibration::kOnSky) tilt_gain->clear();
  } else {
    for (int k = 0; k < D; ++k) {
      std::unique_ptr<PsfCalculator> diffraction;
      std::unique_ptr<AnalyticAoPsfCalculator> analytic;
      if (s.ao.mode == AoSpec::Mode::kAnalytic)
        analytic = std::make_unique<AnalyticAoPsfCalculator>(
            AnalyticAoAt(s.telescope, directions[std::size_t(k)], "ScenePipeline", "psf_field"), n, sampling);
      else diffraction = std::make_unique<PsfCalculator>(n, s.telescope.aperture.pupil.diameter_m, sampling);
      const double residual_strehl = analytic ? analytic->Compute(amplitude, Image::Zero(n, n)).strehl : 1.0;
      for (int d = 0; d < distinct_count_; ++d) {
        const int i = int(std::find(distinct_.begin(), distinct_.end(), d) - distinct_.begin());
        const Image opd = ExposureOpd(s, s.ExposureOffset(i), static_opd, dm.get());
        if (analytic) {
          AnalyticAoPsf p = analytic->Compute(amplitude, opd);
          raw[k][d] = std::move(p.psf);
          // The residual's long-exposure Strehl times that of the static OPD about its own centre.
          raw_strehl[k][d] = residual_strehl * StrehlFromPupil(amplitude, WithoutTilt(opd, amplitude), sampling.wavelength_m);
        } else {
          raw[k][d] = diffraction->Compute(amplitude, opd);
          raw_strehl[k][d] = StrehlFromPupil(amplitude, WithoutTilt(opd, amplitude), sampling.wavelength_m);
        }
        if (step && !step(1)) return {};
      }
    }
  }
  if (counters) counters->psfs_computed += D * distinct_count_;
  std::vector<ImageStack> out(D);
  if (window_fraction) window_fraction->clear();
  if (strehl) strehl->assign(D, {});
  for (int k = 0; k < D; ++k) {
    for (int i = 0; i < s.Exposures(); ++i) {
      const Image& p = raw[k][distinct_[i]];
      if (p.size() == 0 || !AllFinite(p) || !(p.sum() > 0))
        throw NumericalError("ScenePipeline: the PSF of exposure " + std::to_string(i) + " is empty, not finite or has no light");
      // An intensity is >= 0; the analytic model's PSF (an MFT of a truncated OTF) has wings that dip below 0
      // by ~1e-7 of the peak. Left in, they make frames slightly negative and the detector would clip them,
      // breaking flux conservation at that level.
      out[k].push_back(NormaliseToUnitSum(p.cwiseMax(0.0)));
      if (window_fraction && k == 0) window_fraction->push_back(p.sum());
      if (strehl) (*strehl)[k].push_back(raw_strehl[k][distinct_[i]]);
    }
  }
  if (distinct) *distinct = distinct_;
  return out;
}

std::vector<ImageStack> ScenePipeline::ComputeFieldPsfs(std::vector<std::vector<double>>* strehl,
                                                       SimulationCounters* counters) const {
  return ComputeFieldPsfs(strehl, counters, {});
}

std::vector<ImageStack> ScenePipeline::ComputeFieldPsfs(std::vector<std::vector<double>>* strehl,
                                                       SimulationCounters* counters,
                                                       const std::function<bool(int)>& step) const {
  std::vector<std::vector<double>> st;
  std::vector<ImageStack> out = ComputeDirectionPsfs(field_directions_, nullptr, nullptr, &st, counters, step, nullptr);
  if (out.empty()) return {};  // stopped
  if (strehl) *strehl = std::move(st);
  return out;
}

Simulation ScenePipeline::Run(const ProgressCallback& progress) const {
  if (fine_) {
    // The fine grid renders everything; its outputs go back to the HR grid (pipeline.hpp).
    const int so = scene_.sky_oversampling;
    Simulation sim = fine_->Run(progress);
    sim.geometry = geometry_;
    if (sim.truth.size()) sim.truth = BlockSum(sim.truth, so);
    for (Image& x : sim.truth_frames) x = BlockSum(x, so);
    for (PointSource& p : sim.stars) p = StarToHr(p, so);
    for (Image& p : sim.psfs) p = SubsamplePsf(p, so);
    for (Image& p : sim.nominal_psfs) p = SubsamplePsf(p, so);
    for (ImageStack& node : sim.field_psfs)
      for (Image& p : node) p = SubsamplePsf(p, so);
    for (ImageStack& node : sim.field_nominal_psfs)
      for (Image& p : node) p = SubsamplePsf(p, so);
    return sim;
  }
  using Clock = std::chrono::steady_clock;
  const auto t_run = Clock::now();
  // Steps: the object, each distinct PSF, the nominal PSFs (closed loop), convolution, pixels, detector.
  const bool closed_loop = scene_.ao.mode == AoSpec::Mode::kClosedLoop;
  const int loop_runs = closed_loop && scene_.ao.antithetic && scene_.telescope.atmosphere ? 2 : 1;
  const int nodes = field_grid_.nodes();
  const int exposures = scene_.Exposures();
  const bool varying = scene_.TimeVarying();
  const int total = 4 + (1 + nodes) * distinct_count_ * loop_runs + (closed_loop ? 1 + nodes : 0);
  ProgressReporter reporter(progress, "simulate", total, "");
  int done = 0;
  // Counts `n` steps done; false when the caller asked to stop (or its callback threw: `stop` rethrows that).
  auto advance = [&](int n) {
    done += n;
    return reporter.Report(done, std::numeric_limits<double>::quiet_NaN(), done == total);
  };
  auto stop = [&](Simulation* sim) {
    reporter.RethrowIfThrown();
    sim->cancelled = true;
    sim->seconds = Seconds(t_run);
  };
  const std::uint64_t fft0 = FftExecutionCount();
  const std::uint64_t screens0 = PhaseScreensGenerated();
  const SceneGeometry& g = geometry_;
  Simulation sim;
  sim.geometry = g;
  if (scene_.sequence.enabled())
    for (int i = 0; i < exposures; ++i) sim.times_s.push_back(scene_.ExposureTime(i));
  SimulationCounters& c = sim.counters;
  auto timed = [&sim](const std::string& name, Clock::time_point start) { sim.timings.push_back({name, Seconds(start)}); };

  auto t = Clock::now();
  // (A sequence's changing components are not in it: they are added per exposure below.)
  const Image extended = RenderObject(&sim.stars);
  // The truth holds the stars deposited bilinearly (StarTruth); the frames below use the catalogue itself.
  if (!varying) sim.truth = sim.stars.empty() ? extended : Image(extended + StarTruth(g.hr_frame, sim.stars));
  c.object_components = int(scene_.objects.size());
  timed("object", t);
  if (!advance(1)) {
    stop(&sim);
    return sim;
  }

  // PSFs (static aberrations, offsets and the loop are inside; their time is the PSF stage's).
  t = Clock::now();
  const int steps0 = c.loop_steps;
  bool go = true;
  {
    std::vector<std::vector<double>> st;
    std::vector<ImageStack> on_axis = ComputeDirectionPsfs(
        {FieldDirection{}}, &sim.distinct_psf, &sim.psf_window_fraction, &st, &c,
        progress ? std::function<bool(int)>([&](int n) { return go = advance(n); }) : std::function<bool(int)>(),
        &sim.tilt_gain);
    if (go) {
      sim.psfs = std::move(on_axis.front());
      sim.strehl = std::move(st.front());
    }
  }
  if (!go) {
    stop(&sim);
    return sim;
  }
  timed(c.loop_steps > steps0 ? "ao-loop+psf" : "psf", t);
  if (closed_loop) {
    t = Clock::now();
    sim.nominal_psfs = NominalPsfs(scene_);
    timed("nominal-psf", t);
    if (!advance(1)) {
      stop(&sim);
      return sim;
    }
  }
  if (nodes > 0) {
    t = Clock::now();
    sim.field_grid = field_grid_;
    sim.field_directions = field_directions_;
    sim.field_psfs = ComputeFieldPsfs(&sim.field_strehl, &c,
                                      progress ? std::function<bool(int)>([&](int n) { return go = advance(n); })
                                               : std::function<bool(int)>());
    if (!go) {
      stop(&sim);
      return sim;
    }
    if (closed_loop) {
      sim.field_nominal_psfs = NominalFieldPsfs(scene_);
      if (!advance(nodes)) {
        stop(&sim);
        return sim;
      }
    }
    timed("psf-field", t);
  }

  // Convolution on the padded grid: the object's spectrum (extended part by FFT, stars exactly), times each
  // distinct transfer function, back to the image domain. With a psf_field, the object weighted by each
  // node's interpolation weight through that node's PSF, summed (core/psf_field.hpp): y = Σ_k h_k ⊛ (w_k x).
  // A sequence whose objects change: the same per exposure, for the object at the exposure's mid-time.
  t = Clock::now();
  const Shape P = g.padded;
  // The spectrum on the padded grid of the object (`ext`, `stars`), weighted by `weight` (extended part) and
  // `star_weight` (stars, at their positions) when given.
  auto object_spectrum = [&](const Image& ext, const std::vector<PointSource>& stars, const Image* weight,
                             const std::function<double(const PointSource&)>& star_weight) {
    ComplexImage spectrum;
    if (has_extended_) {
      Image padded = Image::Zero(P.rows, P.cols);
      padded.block(g.pad_top, g.pad_left, g.hr_frame.rows, g.hr_frame.cols) = weight ? Image(ext.cwiseProduct(*weight)) : ext;
      spectrum = FftR2C(padded);
      ++c.object_transforms;
    }
    if (!stars.empty()) {
      std::vector<PointSource> shifted;
      for (PointSource p : stars) {
        if (star_weight) p.flux *= star_weight(p);
        if (p.flux == 0.0 && star_weight) continue;
        p.y += double(g.pad_top), p.x += double(g.pad_left);
        shifted.push_back(p);
      }
      const ComplexImage spectrum_stars = PointSourceSpectrum(P, shifted);
      spectrum = spectrum.size() ? ComplexImage(spectrum + spectrum_stars) : spectrum_stars;
    }
    if (spectrum.size() == 0) spectrum = ComplexImage::Zero(P.rows, P.cols / 2 + 1);
    return spectrum;
  };
  auto transfer = [&](const Image& psf) { return HermitianProjection(TransferFunction(P, psf), P.cols); };
  // Node k's interpolation weight of a star (its HR-grid position: a fine grid's pixel centres, pipeline.hpp).
  const int so = field_scale_;
  auto node_weight = [&](int k) {
    return [this, k, so](const PointSource& p) {
      const double half = 0.5 * double(so - 1);
      for (const PsfFieldGrid::Weight& w : field_grid_.Weights((p.y - half) / so, (p.x - half) / so))
        if (w.node == k) return w.weight;
      return 0.0;
    };
  };
  // The product spectrum to a convolved HR image: c2r, crop, clip at 0. Clipped: FFT rounding (~1e-16 of the
  // peak) and, for stars, the ringing of a window-truncated PSF shifted by a fraction of a pixel (~1e-6 of the
  // star's flux per pixel) dip below 0; an intensity cannot, and the detector rejects negative signal.
  auto to_image = [&](const ComplexImage& product) {
    const Image full = FftC2R(product, P.cols);
    ++c.frame_transforms;
    return Image(full.block(g.pad_top, g.pad_left, g.hr_frame.rows, g.hr_frame.cols).cwiseMax(0.0));
  };
  const OperatorPtr pixels = PixelResponse(g.hr_frame, g.r, scene_.detector.fill_factor);
  auto integrate = [&](const Image& convolved) { return ToImage(pixels->Apply(AsVector(convolved)), g.frame); };
  double pixel_seconds = 0;
  if (!varying) {
    std::vector<int> first(distinct_count_);  // an exposure of each distinct PSF
    for (int d = 0; d < distinct_count_; ++d)
      first[d] = int(std::find(sim.distinct_psf.begin(), sim.distinct_psf.end(), d) - sim.distinct_psf.begin());
    // Each distinct PSF's product of spectra; without a field made one at a time below (one spectrum held).
    std::vector<ComplexImage> products(distinct_count_);
    ComplexImage spectrum;
    if (nodes == 0) {
      spectrum = object_spectrum(extended, sim.stars, nullptr, {});
    } else {
      // Node by node, so that only one weighted spectrum is held; the sum over nodes in node order.
      for (int k = 0; k < nodes; ++k) {
        const Image weight = has_extended_ ? field_grid_.WeightMap(k, so) : Image();
        const ComplexImage spectrum_k = object_spectrum(extended, sim.stars, has_extended_ ? &weight : nullptr, node_weight(k));
        for (int d = 0; d < distinct_count_; ++d) {
          const ComplexImage term = spectrum_k * transfer(sim.field_psfs[k][first[d]]);
          products[d] = k == 0 ? term : ComplexImage(products[d] + term);
        }
      }
    }
    std::vector<Image> convolved(distinct_count_);
    for (int d = 0; d < distinct_count_; ++d) {
      if (nodes == 0) products[d] = spectrum * transfer(sim.psfs[first[d]]);
      convolved[d] = to_image(products[d]);
      products[d] = ComplexImage();
    }
    timed(has_extended_ ? "convolution" : "point-sources", t);
    if (!advance(1)) {
      stop(&sim);
      return sim;
    }
    t = Clock::now();
    std::vector<Image> lr(distinct_count_);
    for (int d = 0; d < distinct_count_; ++d) lr[d] = integrate(convolved[d]);
    for (int i = 0; i < exposures; ++i) sim.expected_e.push_back(lr[sim.distinct_psf[i]]);
    pixel_seconds = Seconds(t);
  } else {
    // Exposure by exposure: the object at its mid-time, its truth, and its frame. Without a field the
    // transfer function of each distinct PSF is made once (at most N of them; the closed loop's are all
    // distinct and made as they come).
    const ChangingComponents changing(scene_, g.hr_frame, flux_binning_);
    const bool cache = nodes == 0 && distinct_count_ < exposures;
    std::vector<ComplexImage> transfers(cache ? distinct_count_ : 0);
    Image truth_sum = Image::Zero(g.hr_frame.rows, g.hr_frame.cols);
    for (int i = 0; i < exposures; ++i) {
      const double time = scene_.ExposureTime(i);
      Image ext = extended;
      std::vector<PointSource> stars = sim.stars;
      changing.AddAt(time, &ext, &stars);
      Image truth_i = stars.empty() ? ext : Image(ext + StarTruth(g.hr_frame, stars));
      truth_sum += truth_i;
      sim.truth_frames.push_back(std::move(truth_i));
      ComplexImage product;
      if (nodes == 0) {
        const int d = sim.distinct_psf[i];
        if (cache && transfers[d].size() == 0) transfers[d] = transfer(sim.psfs[i]);
        product = object_spectrum(ext, stars, nullptr, {}) * (cache ? transfers[d] : transfer(sim.psfs[i]));
      } else {
        for (int k = 0; k < nodes; ++k) {
          const Image weight = has_extended_ ? field_grid_.WeightMap(k, so) : Image();
          const ComplexImage term =
              object_spectrum(ext, stars, has_extended_ ? &weight : nullptr, node_weight(k)) * transfer(sim.field_psfs[k][i]);
          product = k == 0 ? term : ComplexImage(product + term);
        }
      }
      const auto t_pixels = Clock::now();
      sim.expected_e.push_back(integrate(to_image(product)));
      pixel_seconds += Seconds(t_pixels);
    }
    // The time-averaged object: what a reconstruction of the whole sequence at once estimates.
    sim.truth = truth_sum / double(exposures);
    timed("sequence", t);
    if (!advance(1)) {
      stop(&sim);
      return sim;
    }
  }
  sim.timings.push_back({"pixel-integration", pixel_seconds});
  if (!advance(1)) {
    stop(&sim);
    return sim;
  }

  t = Clock::now();
  const Detector detector(scene_.detector);
  sim.frames = detector.RecordSequence(sim.expected_e, scene_.noise_seed);
  for (const DetectorFrame& f : sim.frames) c.noise_draws += f.uniform_draws + f.normal_draws;
  timed("detector", t);
  advance(1);  // the last step: nothing is left to cut short
  reporter.RethrowIfThrown();

  c.fft_executions = FftExecutionCount() - fft0;
  c.phase_screens = PhaseScreensGenerated() - screens0;
  sim.seconds = Seconds(t_run);
  return sim;
}

namespace {
// The analytic-AO twin of a closed-loop scene: the reconstructor's nominal model (NominalPsfs).
SceneSpec NominalScene(const SceneSpec& scene) {
  SceneSpec analytic = scene;
  analytic.ao.mode = AoSpec::Mode::kAnalytic;
  analytic.ao.dm_gain = 1.0;  // the stroke error is the hardware's, unknown to the model (and analytic has none)
  analytic.sequence = SequenceSpec{};  // one model PSF per phase (N), whatever the sequence's length
  // Only the diffractive sensor simulates photon and read noise (shack_hartmann.hpp): with the others the
  // truth's WFS is noiseless, and so is the model (TelescopePreset::ToAnalyticAo measures the noise otherwise).
  if (scene.ao.sensor != SensorKind::kDiffractive && analytic.telescope.ao) {
    analytic.telescope.ao->wfs.photon_noise = false;
    analytic.telescope.ao->wfs.read_noise_e = 0.0;
  }
  return analytic;
}
}  // namespace

ImageStack NominalPsfs(const SceneSpec& scene) {
  if (scene.ao.mode != AoSpec::Mode::kClosedLoop) return {};
  return ScenePipeline(NominalScene(scene)).ComputePsfs(nullptr, nullptr, nullptr);
}

std::vector<ImageStack> NominalFieldPsfs(const SceneSpec& scene) {
  if (scene.ao.mode != AoSpec::Mode::kClosedLoop || !scene.psf_field.enabled) return {};
  return ScenePipeline(NominalScene(scene)).ComputeFieldPsfs(nullptr);
}

}  // namespace aosr
