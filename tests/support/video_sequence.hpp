// A small super-resolved video for the streaming tests (video_stream, quick_look, `aosr video`, `aosr watch`):
// 4 DM phases (Gaussian PSFs of σ 1.1 HR px on a raster of shifts), a 48 × 40 HR grid at r = 2, and frame j in
// e⁻ = phase j mod 4 of a background plus a blob moving one HR pixel per frame, with noise of σ 0.01; written as
// ADU (gain 2, bias 100) in a dataset with a WCS. Header-only; include as "support/video_sequence.hpp".
#pragma once

#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <iterator>
#include <string>
#include <thread>
#include <vector>

#include "aosr/core/forward_model.hpp"
#include "aosr/io/fits.hpp"
#include "support/testing.hpp"

namespace aosr::test {

inline constexpr Shape kVideoHr{48, 40};
inline constexpr int kVideoR = 2;
inline constexpr int kVideoFrames = 10;
inline constexpr double kVideoGain = 2.0, kVideoBias = 100.0, kVideoDt = 0.05;
inline const std::vector<std::pair<double, double>> kVideoShifts = {{0, 0}, {0, 1}, {1, 0}, {1, 1.5}};  // HR px

// The phases' PSFs: Gaussians of σ 1.1 HR px shifted by the raster above, 16 x 16, unit sum.
inline ImageStack VideoPsfs() {
  ImageStack psfs;
  for (auto [dy, dx] : kVideoShifts) {
    Image k(16, 16);
    for (Index y = 0; y < 16; ++y)
      for (Index x = 0; x < 16; ++x) {
        const double a = double(y) - 8 - dy, b = double(x) - 8 - dx;
        k(y, x) = std::exp(-(a * a + b * b) / (2 * 1.1 * 1.1));
      }
    psfs.push_back(k / k.sum());
  }
  return psfs;
}

// Frame j in e-: phase j mod 4 of a background plus a blob at x = 10 + j HR px, with noise of σ 0.01.
inline Image VideoFrameE(int j) {
  const auto model = MultiFrameModel::FromKernels(kVideoHr, kVideoR, VideoPsfs());
  Image x = 0.1 * RandomImage(kVideoHr, 11, false);
  for (Index y = 0; y < kVideoHr.rows; ++y)
    for (Index c = 0; c < kVideoHr.cols; ++c) {
      const double dy = double(y) - 20.0, dx = double(c) - 10.0 - j;
      x(y, c) += 3.0 * std::exp(-(dy * dy + dx * dx) / 8.0);
    }
  return model.Render(x)[std::size_t(j % 4)] + 0.01 * RandomImage(model.lr_shape(), 700 + std::uint64_t(j));
}

// A manifest of frames `frames` (ADU, gain 2, bias 100) with PSFs `psfs`, the detector model's noise (uniform
// background weights 1/σ²) and a WCS; `sequence` adds slots and times.
inline nlohmann::json VideoManifest(const nlohmann::json& sequence) {
  nlohmann::json m = {{"format", "aosr-manifest"}, {"version", 1}, {"frames", "frames.fits"}, {"psfs", "psfs.fits"},
                      {"r", kVideoR}, {"gain_e_per_adu", kVideoGain}, {"bias_adu", kVideoBias}};
  m["noise"] = {{"model", "peak-fraction"}, {"sigma_e", 0.01}};
  m["wcs"] = {{"CTYPE1", "RA---TAN"}, {"CTYPE2", "DEC--TAN"}, {"CRPIX1", 10.5}, {"CRPIX2", 12.5},
              {"CRVAL1", 150.1},      {"CRVAL2", 2.2},        {"CD1_1", -1e-5},  {"CD1_2", 0.0},
              {"CD2_1", 0.0},         {"CD2_2", 1e-5}};
  if (!sequence.is_null()) m["sequence"] = sequence;
  return m;
}

inline void WriteVideoDataset(const std::filesystem::path& dir, const std::vector<int>& frames, const ImageStack& psfs,
                       const nlohmann::json& sequence) {
  std::filesystem::create_directories(dir);
  ImageStack adu;
  for (int j : frames) adu.push_back(VideoFrameE(j) / kVideoGain + kVideoBias);
  WriteFitsCube((dir / "frames.fits").string(), adu, {}, FitsType::kFloat64);
  WriteFitsCube((dir / "psfs.fits").string(), psfs, {}, FitsType::kFloat64);
  std::ofstream(dir / "manifest.json") << VideoManifest(sequence).dump(1);
}

// Frame j as a camera writes it for `aosr watch`: ADU (float64) with its DM phase in DMPHASE and its time in
// TSEC (s), written atomically (a temporary name, then a rename).
inline void WriteLiveFrame(const std::string& path, int j, int phase, double time_s) {
  FitsHeader h;
  h.Set("DMPHASE", phase, "DM phase index");
  h.Set("TSEC", time_s, "[s] frame time");
  WriteFits(path, Image(VideoFrameE(j) / kVideoGain + kVideoBias), h, FitsType::kFloat64);
}

// The same file written in place in two parts, closed in between for `pause_s`: a writer a reader must wait for.
inline void WriteLiveFrameInTwoParts(const std::string& path, const std::string& staging, int j, int phase,
                                     double time_s, double pause_s) {
  WriteLiveFrame(staging, j, phase, time_s);
  std::string bytes;
  {
    std::ifstream in(staging, std::ios::binary);
    bytes.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  }
  std::filesystem::remove(staging);
  const std::size_t half = bytes.size() / 2 + 1000;  // inside the data, past the header
  {
    std::ofstream out(path, std::ios::binary);
    out.write(bytes.data(), std::streamsize(half));
  }
  std::this_thread::sleep_for(std::chrono::duration<double>(pause_s));
  std::ofstream out(path, std::ios::binary | std::ios::app);
  out.write(bytes.data() + half, std::streamsize(bytes.size() - half));
}

}  // namespace aosr::test
