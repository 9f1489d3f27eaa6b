#include "aosr/scene/dataset_memory.hpp"

#include <cmath>
#include <filesystem>
#include <system_error>
#include <string>
#include <utility>

#include "aosr/core/error.hpp"
#include "aosr/io/config.hpp"
#include "aosr/io/wcs.hpp"

namespace aosr {
namespace {

constexpr const char* kFromArrays = "DatasetFromArrays";

// LoadDataset's unit-sum rule: a PSF without positive finite light is meaningless; the division is what
// LoadDataset does, so the bits agree with a dataset read from disk.
void NormalisePsfs(ImageStack* psfs, const std::string& function, const std::string& field) {
  for (std::size_t i = 0; i < psfs->size(); ++i) {
    Image& p = (*psfs)[i];
    const double sum = p.sum();
    CheckArgument(AllFinite(p) && sum > 0, function, field, "plane " + std::to_string(i) + " with sum " + ToString(sum),
                  "PSFs with finite values and a sum > 0");
    p /= sum;
  }
}

// LoadDataset's treatment of non-finite frame pixels (invalid, reading the bias) and of weights (zero where
// invalid).
void NormaliseFrames(Dataset* ds) {
  for (std::size_t i = 0; i < ds->frames.size(); ++i) {
    const auto bad = !ds->frames[i].isFinite();
    ds->valid[i] = bad.select(0.0, ds->valid[i]);
    ds->frames[i] = bad.select(ds->bias_adu, ds->frames[i]);
  }
  if (ds->weights)
    for (std::size_t i = 0; i < ds->frames.size(); ++i) (*ds->weights)[i] *= ds->valid[i];
}

void CheckStack(const ImageStack& s, std::size_t n, Shape shape, const std::string& field, const std::string& rule) {
  bool ok = s.size() == n;
  for (const Image& p : s) ok = ok && ShapeOf(p) == shape;
  CheckArgument(ok, kFromArrays, field,
                std::to_string(s.size()) + " planes" + (s.empty() ? "" : " of " + ToString(ShapeOf(s.front()))),
                std::to_string(n) + " " + rule + " " + ToString(shape));
}

}  // namespace

Dataset DatasetFromSimulation(const SceneSpec& scene, const Simulation& sim) {
  const SceneGeometry& g = sim.geometry;
  const std::size_t n = sim.frames.size();
  CheckArgument(int(n) == scene.Exposures() && sim.psfs.size() == n && g.frame == scene.frame && g.r == scene.r,
                "DatasetFromSimulation", "sim", std::to_string(n) + " frames of " + ToString(g.frame),
                "the simulation of the scene (" + std::to_string(scene.Exposures()) + " frames of " + ToString(scene.frame) + ")");
  Dataset ds;
  ds.r = g.r;
  ds.frame = g.frame;
  ds.hr_frame = g.hr_frame;
  for (const DetectorFrame& f : sim.frames) {
    ds.frames.push_back(f.adu);
    ds.valid.push_back(f.valid);
  }
  ImageStack weights;
  for (const DetectorFrame& f : sim.frames) weights.push_back(f.inverse_variance);
  ds.weights = std::move(weights);
  ds.gain_e_per_adu = scene.detector.gain_e_per_adu;
  ds.bias_adu = scene.detector.bias_adu;
  // A sequence: per-phase PSFs, as WriteSimulation writes them (PerPhase), expanded to the frames below.
  ds.psfs = PerPhase(scene, sim.psfs);
  NormalisePsfs(&ds.psfs, "DatasetFromSimulation", "psfs");
  ds.nominal_psfs = sim.nominal_psfs;
  NormalisePsfs(&ds.nominal_psfs, "DatasetFromSimulation", "nominal_psfs");
  if (!sim.field_psfs.empty()) {
    // The field-varying PSF, as LoadDataset reads it from the manifest's psf_field section.
    ds.psf_field.emplace();
    ds.psf_field->grid = sim.field_grid;
    for (const ImageStack& node : sim.field_psfs) ds.psf_field->psfs.push_back(PerPhase(scene, node));
    ds.psf_field->nominal_psfs = sim.field_nominal_psfs;
    for (ImageStack& node : ds.psf_field->psfs) NormalisePsfs(&node, "DatasetFromSimulation", "field_psfs");
    for (ImageStack& node : ds.psf_field->nominal_psfs) NormalisePsfs(&node, "DatasetFromSimulation", "field_nominal_psfs");
    ds.psf_field->guide_star_x_arcsec = scene.psf_field.guide_star_x_arcsec;
    ds.psf_field->guide_star_y_arcsec = scene.psf_field.guide_star_y_arcsec;
  }
  ds.offsets = scene.offsets.frames;
  if (ds.offsets.empty()) ds.offsets.assign(n, DmOffset{});
  if (scene.sequence.enabled()) {
    // As LoadDataset reads the manifest's sequence: the per-phase inputs become per-frame (frame j: phase j mod N).
    for (int j = 0; j < int(n); ++j) ds.slots.push_back(j % scene.frames);
    ds.slot_count = scene.frames;
    ds.times_s = sim.times_s;
    auto expand = [&](ImageStack* v) {
      if (v->empty()) return;
      const ImageStack per_phase = *v;
      v->clear();
      for (int slot : ds.slots) v->push_back(per_phase[std::size_t(slot)]);
    };
    expand(&ds.psfs);
    expand(&ds.nominal_psfs);
    if (ds.psf_field) {
      for (ImageStack& node : ds.psf_field->psfs) expand(&node);
      for (ImageStack& node : ds.psf_field->nominal_psfs) expand(&node);
    }
    const std::vector<DmOffset> per_phase = ds.offsets;
    ds.offsets.clear();
    for (int slot : ds.slots) ds.offsets.push_back(per_phase[std::size_t(slot)]);
  }
  ds.truth = sim.truth;
  ds.truth_frames = sim.truth_frames;
  ds.stars = sim.stars;
  // The provenance a reconstruction reads from a manifest on disk: the detector model (background weights) and
  // the scene's telescope (the diffraction target), so memory and disk give the same reconstruction.
  ds.manifest = {{"noise", SimulationNoiseJson(scene, sim)}};
  std::error_code ec;
  if (!scene.source.empty() && std::filesystem::is_regular_file(scene.source, ec)) {
    try {
      ds.manifest["simulation"] = {{"scene", {{"name", scene.name}, {"source", scene.source}, {"json", ReadJsonFile(scene.source)}}}};
    } catch (const Error&) {
      // provenance only: without it the diffraction target is refused by name
    }
  }
  ds.trustworthy_border_px = g.trustworthy_border_px;
  ds.camera_pixel_rad = g.camera_pixel_rad;
  ds.wavelength_m = g.wavelength_m;
  // Frame 0's camera WCS, as WriteSimulation writes it into the frames' header (dataset.cpp): the scene's
  // pointing at the HR grid's centre, then the camera grid of frame 0 with its DM image shift.
  const PixelCoord centre{(g.hr_frame.rows - 1) / 2.0, (g.hr_frame.cols - 1) / 2.0};
  const Wcs hr = TangentPlaneWcs(scene.sky.ra_deg, scene.sky.dec_deg, g.hr_pixel_rad, scene.sky.position_angle_deg, centre);
  const DmOffset& first = ds.offsets.front();
  ds.wcs = LrWcs(hr, g.r, first.shift_y_px * g.r, first.shift_x_px * g.r);
  NormaliseFrames(&ds);
  return ds;
}

Dataset DatasetFromArrays(DatasetArrays a) {
  CheckArgument(!a.frames.empty(), kFromArrays, "frames", "(none)", "at least one frame");
  const std::size_t n = a.frames.size();
  const Shape frame = ShapeOf(a.frames.front());
  CheckArgument(frame.rows > 0 && frame.cols > 0, kFromArrays, "frames", ToString(frame), "non-empty frames");
  for (const Image& f : a.frames)
    CheckArgument(ShapeOf(f) == frame, kFromArrays, "frames", ToString(ShapeOf(f)), "frames of one shape " + ToString(frame));
  CheckArgument(a.r >= 1 && a.r <= 16, kFromArrays, "r", a.r, "1..16");
  CheckArgument(a.gain_e_per_adu > 0 && std::isfinite(a.gain_e_per_adu), kFromArrays, "gain_e_per_adu",
                a.gain_e_per_adu, "a finite number > 0");
  CheckArgument(std::isfinite(a.bias_adu), kFromArrays, "bias_adu", a.bias_adu, "a finite number");
  CheckArgument(!a.psfs.empty(), kFromArrays, "psfs", "(none)", "one PSF per frame or one shared");
  const Shape k = ShapeOf(a.psfs.front());
  bool psfs_ok = (a.psfs.size() == n || a.psfs.size() == 1) && k.rows == k.cols && k.rows % 2 == 0 && k.rows > 0;
  for (const Image& p : a.psfs) psfs_ok = psfs_ok && ShapeOf(p) == k;
  CheckArgument(psfs_ok, kFromArrays, "psfs", std::to_string(a.psfs.size()) + " x " + ToString(k),
                std::to_string(n) + " (one per frame) or 1 (shared) square planes K x K with K even");
  if (a.psfs.size() == 1) a.psfs.assign(n, a.psfs.front());

  Dataset ds;
  ds.r = a.r;
  ds.frame = frame;
  ds.hr_frame = {frame.rows * a.r, frame.cols * a.r};
  ds.frames = std::move(a.frames);
  ds.gain_e_per_adu = a.gain_e_per_adu;
  ds.bias_adu = a.bias_adu;
  ds.psfs = std::move(a.psfs);
  NormalisePsfs(&ds.psfs, kFromArrays, "psfs");
  if (!a.nominal_psfs.empty()) {
    CheckStack(a.nominal_psfs, n, k, "nominal_psfs", "planes of the PSFs' shape");
    ds.nominal_psfs = std::move(a.nominal_psfs);
    NormalisePsfs(&ds.nominal_psfs, kFromArrays, "nominal_psfs");
  }
  if (!a.valid.empty()) {
    CheckStack(a.valid, n, frame, "valid", "masks of the frames' shape");
    for (std::size_t i = 0; i < n; ++i)
      CheckArgument(((a.valid[i] == 0) || (a.valid[i] == 1)).all(), kFromArrays, "valid",
                    "plane " + std::to_string(i) + " holds values other than 0 and 1", "1 (usable) or 0 (not)");
    ds.valid = std::move(a.valid);
  } else {
    ds.valid.assign(n, Image::Ones(frame.rows, frame.cols));
  }
  if (!a.weights.empty()) {
    CheckStack(a.weights, n, frame, "weights", "inverse variances of the frames' shape");
    for (std::size_t i = 0; i < n; ++i)
      CheckArgument(AllFinite(a.weights[i]) && !(a.weights[i] < 0).any(), kFromArrays, "weights",
                    "negative or non-finite values in plane " + std::to_string(i), "finite inverse variances >= 0");
    ds.weights = std::move(a.weights);
  }
  if (a.truth) {
    CheckArgument(ShapeOf(*a.truth) == ds.hr_frame, kFromArrays, "truth", ToString(ShapeOf(*a.truth)),
                  "one HR image of r x the frames' shape = " + ToString(ds.hr_frame));
    ds.truth = std::move(a.truth);
  }
  CheckArgument(a.offsets.empty() || a.offsets.size() == n, kFromArrays, "offsets",
                std::to_string(a.offsets.size()) + " entries", "none or one per frame (" + std::to_string(n) + ")");
  ds.offsets = a.offsets.empty() ? std::vector<DmOffset>(n) : std::move(a.offsets);
  ds.stars = std::move(a.stars);
  ds.trustworthy_border_px = a.trustworthy_border_px >= 0 ? a.trustworthy_border_px : (k.rows / 2 + a.r - 1) / a.r;
  CheckArgument(a.camera_pixel_rad >= 0 && std::isfinite(a.camera_pixel_rad), kFromArrays, "camera_pixel_rad",
                a.camera_pixel_rad, "a finite angle >= 0 (0: unknown)");
  CheckArgument(a.wavelength_m >= 0 && std::isfinite(a.wavelength_m), kFromArrays, "wavelength_m", a.wavelength_m,
                "a finite wavelength >= 0 (0: unknown)");
  ds.camera_pixel_rad = a.camera_pixel_rad;
  ds.wavelength_m = a.wavelength_m;
  ds.wcs = std::move(a.wcs);
  NormaliseFrames(&ds);
  return ds;
}

}  // namespace aosr
