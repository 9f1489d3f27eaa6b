#include "aosr/solvers/padded_model.hpp"

#include <algorithm>
#include <cmath>

#include "aosr/core/error.hpp"
#include "aosr/core/fft.hpp"
#include "aosr/core/operators.hpp"

namespace aosr {
namespace {

// The padded LR grid: the window plus `padding` on each side, rounded up to an FFT-friendly size.
Shape PaddedLr(Shape frame_lr, int padding) {
  return {NextFastFftSize(frame_lr.rows + 2 * Index(padding)),
          NextFastFftSize(frame_lr.cols + 2 * Index(padding))};
}

void CheckCommon(const char* function, Shape frame_hr, int r, int padding) {
  CheckArgument(r >= 1, function, "r", r, ">= 1");
  CheckArgument(frame_hr.rows > 0 && frame_hr.cols > 0 && frame_hr.rows % r == 0 && frame_hr.cols % r == 0,
                function, "frame HR shape", ToString(frame_hr),
                "positive and divisible by r = " + std::to_string(r));
  CheckArgument(padding >= 0 && padding <= 1 << 16, function, "padding", padding, "0 .. 65536 camera pixels");
}

}  // namespace

PaddedModel::PaddedModel(Shape frame_lr, int padding, std::vector<ComplexImage> padded_otfs, int r,
                         Shape padded_hr)
    : frame_lr_(frame_lr), padding_(padding) {
  periodic_ = std::make_shared<const MultiFrameModel>(padded_hr, r, std::move(padded_otfs));
  const OperatorPtr crop = Crop(periodic_->lr_shape(), frame_lr_, padding_, padding_);
  std::vector<OperatorPtr> parts;
  for (int i = 0; i < periodic_->frames(); ++i) parts.push_back(Compose(crop, periodic_->FrameOperator(i)));
  op_ = Stack(parts);
}

PaddedModel PaddedModel::FromKernels(Shape frame_hr, int r, const ImageStack& centred_psfs, int padding) {
  CheckCommon("PaddedModel::FromKernels", frame_hr, r, padding);
  CheckArgument(!centred_psfs.empty(), "PaddedModel::FromKernels", "centred_psfs", "empty",
                "at least one frame");
  const Shape frame_lr{frame_hr.rows / r, frame_hr.cols / r};
  const Shape lr = PaddedLr(frame_lr, padding);
  const Shape hr{lr.rows * r, lr.cols * r};
  std::vector<ComplexImage> otfs;
  for (std::size_t i = 0; i < centred_psfs.size(); ++i) {
    const Image& k = centred_psfs[i];
    if (k.rows() > hr.rows || k.cols() > hr.cols || k.size() == 0)
      throw InvalidArgument("PaddedModel::FromKernels", "centred_psfs[" + std::to_string(i) + "] shape",
                            ToString(ShapeOf(k)), "non-empty and within the padded HR grid " + ToString(hr));
    otfs.push_back(TransferFunction(hr, k));
  }
  return PaddedModel(frame_lr, padding, std::move(otfs), r, hr);
}

PaddedModel PaddedModel::FromPeriodicModel(const MultiFrameModel& model, int padding) {
  const int r = model.r();
  const Shape m_hr = model.hr_shape();
  CheckCommon("PaddedModel::FromPeriodicModel", m_hr, r, padding);
  if (model.space_variant())
    throw InvalidArgument("PaddedModel::FromPeriodicModel", "model", "space-variant",
                          "an isoplanatic model (the zero-padded grid is built from one PSF per frame; use the periodic "
                          "boundary with a space-variant model)");
  const Shape lr = PaddedLr(model.lr_shape(), padding);
  const Shape hr{lr.rows * r, lr.cols * r};
  std::vector<ComplexImage> otfs;
  for (int i = 0; i < model.frames(); ++i) {
    // The periodic kernel, origin at (0, 0), re-placed with signed offsets on the larger grid.
    const Image k = FftC2R(model.otf(i), m_hr.cols);
    Image kp = Image::Zero(hr.rows, hr.cols);
    for (Index y = 0; y < m_hr.rows; ++y)
      for (Index x = 0; x < m_hr.cols; ++x)
        kp((SignedFrequency(y, m_hr.rows) + hr.rows) % hr.rows,
           (SignedFrequency(x, m_hr.cols) + hr.cols) % hr.cols) = k(y, x);
    otfs.push_back(FftR2C(kp));
  }
  return PaddedModel(model.lr_shape(), padding, std::move(otfs), r, hr);
}

int PaddedModel::SuggestPadding(const MultiFrameModel& model, double tail_fraction) {
  CheckArgument(tail_fraction > 0 && tail_fraction < 1, "PaddedModel::SuggestPadding", "tail_fraction",
                tail_fraction, "(0, 1)");
  const Shape hr = model.hr_shape(), lr = model.lr_shape();
  const Index max_radius = std::max(hr.rows, hr.cols) / 2 + 1;
  Index radius = 0;
  for (int i = 0; i < model.frames(); ++i) {
    const Image k = FftC2R(model.otf(i), hr.cols);
    std::vector<double> by_radius(max_radius + 1, 0.0);  // Σk² at each Chebyshev radius
    for (Index y = 0; y < hr.rows; ++y)
      for (Index x = 0; x < hr.cols; ++x) {
        const Index d =
            std::max(std::abs(SignedFrequency(y, hr.rows)), std::abs(SignedFrequency(x, hr.cols)));
        by_radius[d] += k(y, x) * k(y, x);
      }
    double total = 0;
    for (double v : by_radius) total += v;
    double tail = total;  // Σk² at radii >= R
    Index R = 0;
    while (R < max_radius && tail - by_radius[R] > tail_fraction * total) tail -= by_radius[R++];
    radius = std::max(radius, R);
  }
  const Index cap = std::max<Index>(1, std::max(lr.rows, lr.cols) / 2);
  return int(std::clamp<Index>((radius + model.r() - 1) / model.r(), 1, cap));
}

ImageStack PaddedModel::Render(const Image& padded_x) const {
  CheckArgument(ShapeOf(padded_x) == padded_hr_shape(), "PaddedModel::Render", "object shape",
                ToString(ShapeOf(padded_x)), "the padded HR shape " + ToString(padded_hr_shape()));
  const Vector y = op_->Apply(AsVector(padded_x));
  ImageStack out;
  for (int i = 0; i < frames(); ++i)
    out.push_back(ToImage(y.segment(i * frame_lr_.size(), frame_lr_.size()), frame_lr_));
  return out;
}

ImageStack PaddedModel::EmbedFrames(const ImageStack& frames) const {
  CheckArgument(int(frames.size()) == this->frames(), "PaddedModel::EmbedFrames", "frame count",
                frames.size(), std::to_string(this->frames()));
  ImageStack out;
  for (std::size_t i = 0; i < frames.size(); ++i) {
    CheckArgument(ShapeOf(frames[i]) == frame_lr_, "PaddedModel::EmbedFrames",
                  "frame " + std::to_string(i) + " shape", ToString(ShapeOf(frames[i])), ToString(frame_lr_));
    Image f = Image::Zero(padded_lr_shape().rows, padded_lr_shape().cols);
    f.block(padding_, padding_, frame_lr_.rows, frame_lr_.cols) = frames[i];
    out.push_back(std::move(f));
  }
  return out;
}

ImageStack PaddedModel::EmbedWeights(const ImageStack& weights) const {
  if (weights.empty()) return EmbedFrames(ImageStack(frames(), Image::Ones(frame_lr_.rows, frame_lr_.cols)));
  return EmbedFrames(weights);
}

Image PaddedModel::CropObject(const Image& padded_x) const {
  CheckArgument(ShapeOf(padded_x) == padded_hr_shape(), "PaddedModel::CropObject", "object shape",
                ToString(ShapeOf(padded_x)), "the padded HR shape " + ToString(padded_hr_shape()));
  const Shape s = frame_hr_shape();
  return padded_x.block(Index(padding_) * r(), Index(padding_) * r(), s.rows, s.cols);
}

Image PaddedModel::EmbedObject(const Image& x) const {
  CheckArgument(ShapeOf(x) == frame_hr_shape(), "PaddedModel::EmbedObject", "object shape",
                ToString(ShapeOf(x)), "the frames' HR shape " + ToString(frame_hr_shape()));
  Image out = Image::Zero(padded_hr_shape().rows, padded_hr_shape().cols);
  out.block(Index(padding_) * r(), Index(padding_) * r(), x.rows(), x.cols()) = x;
  return out;
}

}  // namespace aosr
