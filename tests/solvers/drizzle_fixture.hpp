// A registration-only problem shared by the Drizzle tests: the model supplies r and the HR grid (identity
// PSFs), which is all Drizzle reads; the offsets carry the geometry.
#pragma once

#include <memory>
#include <utility>
#include <vector>

#include "aosr/solvers/problem.hpp"

namespace aosr::test {

inline ReconstructionProblem RegistrationProblem(Shape hr, int r, ImageStack frames, std::vector<FrameOffset> offsets,
                                                 ImageStack weights = {}) {
  ReconstructionProblem p;
  p.model = std::make_shared<const MultiFrameModel>(
      MultiFrameModel::FromKernels(hr, r, ImageStack(frames.size(), Image::Ones(1, 1))));
  p.frames = std::move(frames);
  p.offsets = std::move(offsets);
  p.weights = std::move(weights);
  return p;
}

}  // namespace aosr::test
