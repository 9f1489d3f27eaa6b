#include "aosr/solvers/problem.hpp"

#include <cmath>

#include "aosr/core/error.hpp"

namespace aosr {

void ReconstructionProblem::Validate(const std::string& function) const {
  if (!model) throw InvalidArgument(function + ": problem.model is null; allowed: a MultiFrameModel");
  const Shape lr = model->lr_shape();
  CheckArgument(int(frames.size()) == model->frames(), function, "problem.frames.size()", frames.size(),
                "the model's frame count " + std::to_string(model->frames()));
  CheckArgument(weights.empty() || weights.size() == frames.size(), function, "problem.weights.size()", weights.size(),
                "0 or the frame count " + std::to_string(frames.size()));
  CheckArgument(offsets.empty() || offsets.size() == frames.size(), function, "problem.offsets.size()", offsets.size(),
                "0 or the frame count " + std::to_string(frames.size()));
  const LrRegion& g = residual_region;
  if (!g.all() && !(g.rows > 0 && g.cols > 0 && g.y0 >= 0 && g.x0 >= 0 && g.y0 + g.rows <= lr.rows &&
                    g.x0 + g.cols <= lr.cols))
    throw InvalidArgument(function + ": problem.residual_region = " + std::to_string(g.rows) + " x " +
                          std::to_string(g.cols) + " at (" + std::to_string(g.y0) + ", " + std::to_string(g.x0) +
                          "); allowed: 0 x 0 (every pixel) or a non-empty rectangle inside " + ToString(lr));
  for (std::size_t i = 0; i < frames.size(); ++i) {
    const std::string f = "problem.frames[" + std::to_string(i) + "]";
    CheckArgument(ShapeOf(frames[i]) == lr, function, f + " shape", ToString(ShapeOf(frames[i])), "the model's LR shape " + ToString(lr));
    if (!weights.empty()) {
      const std::string w = "problem.weights[" + std::to_string(i) + "]";
      CheckArgument(ShapeOf(weights[i]) == lr, function, w + " shape", ToString(ShapeOf(weights[i])), ToString(lr));
      CheckArgument(AllFinite(weights[i]) && weights[i].minCoeff() >= 0, function, w, "(negative or non-finite values)",
                    "finite weights >= 0 (0 masks a pixel)");
    }
    for (Index y = 0; y < lr.rows; ++y)
      for (Index x = 0; x < lr.cols; ++x)
        if (!std::isfinite(frames[i](y, x)) && (weights.empty() || weights[i](y, x) > 0))
          throw InvalidArgument(function + ": " + f + "(" + std::to_string(y) + ", " + std::to_string(x) + ") = " +
                                ToString(frames[i](y, x)) + "; allowed: finite values, or weight 0 at that pixel (mask it)");
  }
}

Image ReconstructionProblem::Weight(int i) const {
  if (weights.empty()) return Image::Ones(frames.at(i).rows(), frames.at(i).cols());
  return weights.at(i);
}

bool ReconstructionProblem::HasUniformWeights() const {
  if (weights.empty()) return true;
  const double w0 = weights.front()(0, 0);
  if (!(w0 > 0)) return false;
  for (const Image& w : weights)
    if ((w.array() != w0).any()) return false;
  return true;
}

ImageStack ReconstructionProblem::CleanFrames() const {
  ImageStack out;
  for (std::size_t i = 0; i < frames.size(); ++i) {
    Image f = frames[i];
    if (!weights.empty()) f = (weights[i].array() > 0).select(f, 0.0);
    out.push_back(f);
  }
  return out;
}

double WeightedDataMisfit(const ReconstructionProblem& problem, const Image& x, std::vector<double>* frame_rms) {
  problem.Validate("WeightedDataMisfit");
  const ImageStack predicted = problem.model->Render(x);
  const ImageStack clean = problem.CleanFrames();
  double cost = 0;
  if (frame_rms) frame_rms->clear();
  for (int i = 0; i < problem.frame_count(); ++i) {
    const Image w = problem.Weight(i);
    const Image r = (w.array() > 0).select(clean[i] - predicted[i], 0.0);
    cost += 0.5 * (w.array() * r.array().square()).sum();
    if (frame_rms) {
      const LrRegion& g = problem.residual_region;
      double n = 0, ss = 0;
      if (g.all()) {
        n = double((w.array() > 0).count());
        ss = r.array().square().sum();
      } else {
        n = double((w.block(g.y0, g.x0, g.rows, g.cols) > 0).count());
        ss = r.block(g.y0, g.x0, g.rows, g.cols).square().sum();
      }
      frame_rms->push_back(n > 0 ? std::sqrt(ss / n) : 0.0);
    }
  }
  return cost;
}

}  // namespace aosr
