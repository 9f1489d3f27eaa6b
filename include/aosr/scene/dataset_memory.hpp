// Datasets made in memory rather than read from a manifest (scene/dataset.hpp): from a simulation just run,
// or from the caller's own arrays (frames and PSFs measured elsewhere, e.g. handed over by Python).
//
// Both give exactly the Dataset that LoadDataset returns for the same content on disk: the same checks (with
// the manifest's field names in the messages, prefixed by the function) and the same normalisations
// (each PSF divided by its sum, non-finite frame pixels marked invalid and set to the bias, weights zeroed
// where invalid). So a simulation reconstructed in memory and the same simulation written by WriteSimulation
// and read back give bit-identical reconstructions (python/tests/test_scene.py checks it).
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "aosr/scene/dataset.hpp"

namespace aosr {

// The Dataset of `sim` (pipeline.Run() of `scene`) as LoadDataset reads what WriteSimulation(dir, scene,
// pipeline, sim) writes, its sky coordinates (frame 0's camera WCS) included. manifest_path and expected_file are
// empty; manifest holds the provenance reconstructions read: "noise" (SimulationNoiseJson) and, when the scene
// came from a file, "simulation"/"scene" (name, source, json).
// InvalidArgument if `sim` does not match `scene`.
Dataset DatasetFromSimulation(const SceneSpec& scene, const Simulation& sim);

// The arrays of a measured dataset: the fields of the manifest (dataset.hpp) as values instead of files.
struct DatasetArrays {
  ImageStack frames;              // N frames, ADU (required)
  ImageStack psfs;                // N PSFs or 1 shared, at HR sampling, K x K with K even (required)
  int r = 0;                      // 1..16 (required)
  double gain_e_per_adu = 1.0;    // > 0
  double bias_adu = 0.0;          // finite
  ImageStack valid;               // empty (all usable) or N masks of 1 / 0
  ImageStack weights;             // empty or N inverse-variance maps, ADU⁻², >= 0
  ImageStack nominal_psfs;        // empty or N PSFs of the psfs' shape
  std::optional<Image> truth;     // the HR object (r·rows x r·cols), e⁻ per frame per HR pixel
  std::vector<DmOffset> offsets;  // empty (none) or N
  std::vector<PointSource> stars;  // HR-frame coordinates, e⁻ per frame
  Index trustworthy_border_px = -1;  // < 0: ceil(K / 2 / r), the manifest's default
  double camera_pixel_rad = 0.0;  // 0: unknown
  double wavelength_m = 0.0;      // 0: unknown
  std::optional<Wcs> wcs;         // sky coordinates of frame 0's camera pixels (io/wcs.hpp), if known
};

// Validates and normalises `arrays` as LoadDataset does a manifest with "psfs". InvalidArgument
// "DatasetFromArrays: invalid <field> = <value>; allowed: <rule>" otherwise.
Dataset DatasetFromArrays(DatasetArrays arrays);

}  // namespace aosr
