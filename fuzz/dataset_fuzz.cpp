// Fuzz target: dataset manifests (dataset.hpp LoadDataset), then one step past loading: the dataset turned
// into a reconstruction problem (solvers/dataset_problem.hpp ProblemFromDataset, default options, and with the
// nominal PSFs when the dataset has them), and for small problems (HR grid up to 64x64, up to 16 frames) two
// fast reconstructions of it (reconstruct.hpp: shift-and-add, Tikhonov with GCV).
//
// The input is written as manifest.json in the scratch folder next to small FITS files it may name (written
// once, below): consistent ones (4 frames of 8x8, r = 2, PSFs 4x4) and inconsistent ones (one plane, odd or
// zero-sum PSFs, PSFs larger than the HR grid, NaN frames, a 2-plane cube, a mask that is not 0/1), plus a tiny
// instrument scene (scene.json) for the "scene" form. The corpus manifests reference them by name and the
// driver's dictionary swaps those names between fields.
//
// With AOSR_FUZZ_WRITE_COMPANIONS=DIR set, the companion files are also written to DIR (to inspect them).
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <limits>
#include <stdexcept>
#include <string>

#include "aosr/core/image.hpp"
#include "aosr/io/fits.hpp"
#include "aosr/scene/dataset.hpp"
#include "aosr/solvers/dataset_problem.hpp"
#include "aosr/solvers/reconstruct.hpp"
#include "fuzz_common.hpp"

namespace {

aosr::ImageStack Cube(int planes, aosr::Index rows, aosr::Index cols, double base) {
  aosr::ImageStack out;
  for (int p = 0; p < planes; ++p) {
    aosr::Image img(rows, cols);
    for (aosr::Index y = 0; y < rows; ++y)
      for (aosr::Index x = 0; x < cols; ++x) img(y, x) = base + double((x * 5 + y * 3 + p * 7) % 13);
    out.push_back(img);
  }
  return out;
}

aosr::ImageStack Psfs(int planes, aosr::Index k) {
  aosr::ImageStack out;
  for (int p = 0; p < planes; ++p) {
    aosr::Image img = aosr::Image::Constant(k, k, 0.01);
    img(k / 2, k / 2) = 1.0;
    if (p % 2 == 1) img(k / 2, k / 2 - 1) = 0.5;  // off-centre light: non-zero centroid offsets
    out.push_back(img / img.sum());
  }
  return out;
}

void WriteCompanions(const std::string& dir) {
  using aosr::WriteFits;
  using aosr::WriteFitsCube;
  aosr::FitsHeader h;
  h.Set("ORIGIN", "aosr fuzz companion");
  WriteFitsCube(dir + "/frames.fits", Cube(4, 8, 8, 100.0), h, aosr::FitsType::kFloat64);
  WriteFits(dir + "/frame1.fits", Cube(1, 8, 8, 100.0)[0]);
  WriteFitsCube(dir + "/frames2.fits", Cube(2, 8, 8, 100.0));
  aosr::ImageStack nan = Cube(4, 8, 8, 100.0);
  nan[1](2, 3) = std::numeric_limits<double>::quiet_NaN();
  nan[2].setConstant(std::numeric_limits<double>::infinity());
  WriteFitsCube(dir + "/frames_nan.fits", nan, {}, aosr::FitsType::kFloat64);
  WriteFitsCube(dir + "/psfs.fits", Psfs(4, 4));
  WriteFits(dir + "/psf1.fits", Psfs(1, 4)[0]);
  WriteFits(dir + "/psf_odd.fits", Psfs(1, 3)[0]);
  WriteFits(dir + "/psf_zero.fits", aosr::Image::Zero(4, 4));
  WriteFitsCube(dir + "/psfs_big.fits", Psfs(4, 32));
  aosr::ImageStack valid = Cube(4, 8, 8, 0.0);
  for (aosr::Image& v : valid) v = (v.array() > 1.0).cast<double>().matrix();
  WriteFitsCube(dir + "/valid.fits", valid);
  WriteFitsCube(dir + "/mask_bad.fits", Cube(4, 8, 8, 0.5));
  WriteFitsCube(dir + "/weights.fits", Cube(4, 8, 8, 0.01));
  WriteFits(dir + "/truth.fits", Cube(1, 16, 16, 1.0)[0]);
  WriteFitsCube(dir + "/expected.fits", Cube(4, 8, 8, 90.0));
  const std::string scene =
      R"({"name": "fuzz-instrument", "seed": 1, "telescope": "paper-bench", "frames": 4, "r": 4,)"
      R"( "ao": {"mode": "none"}, "offsets": {"type": "raster"}, "psf": {"size_px": 8},)"
      R"( "objects": [{"type": "stars", "count": 1, "flux": {"peak_e": 100}}],)"
      R"( "detector": {"frame_px": 8, "noise": "none", "saturation": false}})";
  std::ofstream(dir + "/scene.json") << scene;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static const bool companions = [] {
    WriteCompanions(aosr::fuzz::ScratchDir());
    if (const char* out = std::getenv("AOSR_FUZZ_WRITE_COMPANIONS")) {
      std::filesystem::create_directories(out);
      WriteCompanions(out);
    }
    return true;
  }();
  (void)companions;
  const std::string path = aosr::fuzz::WriteScratch("manifest.json", data, size);
  aosr::fuzz::ExpectAosrErrors([&] {
    const aosr::Dataset dataset = aosr::LoadDataset(path);
    (void)dataset.FramesElectrons();
    aosr::fuzz::ExpectAosrErrors([&] {
      const aosr::DatasetProblem p = aosr::ProblemFromDataset(dataset);
      if (dataset.hr_frame.rows * dataset.hr_frame.cols <= 64 * 64 && dataset.size() <= 16) {
        for (aosr::ReconstructionMethod m : {aosr::ReconstructionMethod::kShiftAddMean, aosr::ReconstructionMethod::kTikhonov}) {
          aosr::ReconstructOptions options;
          options.method = m;
          aosr::fuzz::ExpectAosrErrors([&] {
            // reconstruct.hpp: never returns NaN (a non-finite estimate is reported as failed, zeroed).
            if (!aosr::Reconstruct(p.problem, options).image.allFinite())
              throw std::logic_error("fuzz_dataset: Reconstruct returned a non-finite image");
          });
        }
      }
    });
    if (!dataset.nominal_psfs.empty()) {
      aosr::DatasetProblemOptions options;
      options.nominal_psfs = true;
      options.offsets = aosr::DatasetOffsets::kPsfCentroids;
      aosr::fuzz::ExpectAosrErrors([&] { (void)aosr::ProblemFromDataset(dataset, options); });
    }
  });
  return 0;
}
