// Private to solvers/: the finished tiles of a tiled run kept in a folder (TilingOptions::checkpoint_dir), so
// that a killed run resumes from them with the bytes of an uninterrupted run. A tile file holds the exact
// doubles of the tile's Reconstruction (image, aux, the linear method's kernels and summary) and the run's
// fingerprint; a file with another fingerprint belongs to another run and is refused, never mixed in.
#pragma once

#include <cstdint>
#include <string>

#include "aosr/solvers/tiling.hpp"

namespace aosr::tiling_internal {

// A 64-bit FNV-1a hash of what decides the tiles' bytes, but for each window's pixels: the offsets, the model's
// OTFs, the tile geometry, the method and its options with the regularisation already fixed, and the caller's
// TilingOptions::checkpoint_key (what the hash cannot see: local PSFs, options not listed).
std::uint64_t RunFingerprint(const ReconstructionProblem& problem, const ReconstructOptions& fixed,
                             const TilingOptions& tiling, int overlap);
// The same for a field without a whole-grid model: its kernels instead of the model's OTFs.
std::uint64_t RunFingerprint(const FieldData& field, const ReconstructOptions& fixed, const TilingOptions& tiling,
                             int overlap);
// One tile's: the run's, continued over its window's data (the weighted frame pixels and the weights). Per window,
// so that a job that reads only its window (FieldData::sections) can check a tile without the whole field.
std::uint64_t TileFingerprint(std::uint64_t run, const ImageStack& frames, const ImageStack& weights);

// dir/tile_<index>.bin.
std::string TilePath(const std::string& dir, int index);

// Writes the tile atomically (write then rename: a kill leaves either no file or a whole one).
// `misfit` (optional): what the engine measured of the tile's residual over its core (per frame Σ r², then per
// frame the pixel count), kept so that a resumed tile need not render its frames again.
void WriteTile(const std::string& path, std::uint64_t fingerprint, int index, const Reconstruction& tile,
               const std::vector<double>& misfit = {});

// Reads a tile written by WriteTile: false if there is no file; InvalidArgument (naming ReconstructTiled and
// tiling.checkpoint_dir) if it is another run's or not a tile file.
bool ReadTile(const std::string& path, std::uint64_t fingerprint, int index, Reconstruction* tile,
              std::vector<double>* misfit = nullptr);

}  // namespace aosr::tiling_internal
