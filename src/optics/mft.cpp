#include "aosr/optics/mft.hpp"

#include <cmath>

#include "aosr/core/error.hpp"

namespace aosr {
namespace {

// W(p, k) = exp(-2 pi i alpha(p) u(k)) with alpha(p) = (p - n_out/2) s and u(k) = (k - (n_in-1)/2) / span.
// The phase is reduced modulo one cycle before multiplying by 2 pi, so large arguments keep full precision.
Eigen::MatrixXcd DftMatrix(Index n_out, double pitch_lod, Index n_in, double span) {
  constexpr double kTwoPi = 6.283185307179586476925286766559;
  Eigen::MatrixXcd w(n_out, n_in);
  const double half_in = 0.5 * static_cast<double>(n_in - 1);
  for (Index p = 0; p < n_out; ++p) {
    const double alpha = static_cast<double>(p - n_out / 2) * pitch_lod;
    for (Index k = 0; k < n_in; ++k) {
      const double cycles = alpha * ((static_cast<double>(k) - half_in) / span);
      const double frac = cycles - std::round(cycles);
      w(p, k) = std::polar(1.0, -kTwoPi * frac);
    }
  }
  return w;
}

}  // namespace

bool MftGeometry::IsValid(std::string* why) const {
  std::string msg;
  if (input.rows < 1 || input.cols < 1) {
    msg = "input = " + ToString(input) + "; allowed: at least 1x1";
  } else if (!(std::isfinite(pupil_span_px) && pupil_span_px > 0.0)) {
    msg = "pupil_span_px = " + ToString(pupil_span_px) + "; allowed: > 0 and finite (input pixels across D)";
  } else if (output.rows < 1 || output.cols < 1) {
    msg = "output = " + ToString(output) + "; allowed: at least 1x1";
  } else if (!(std::isfinite(pixel_scale_lod) && pixel_scale_lod > 0.0)) {
    msg = "pixel_scale_lod = " + ToString(pixel_scale_lod) + "; allowed: > 0 and finite (lambda/D)";
  }
  if (msg.empty()) return true;
  if (why != nullptr) *why = msg;
  return false;
}

MatrixFourierTransform::MatrixFourierTransform(const MftGeometry& geometry) : geometry_(geometry) {
  std::string why;
  if (!geometry.IsValid(&why)) throw InvalidArgument("MatrixFourierTransform: invalid geometry." + why);
  const Shape in = geometry.input, out = geometry.output;
  w_y_ = DftMatrix(out.rows, geometry.pixel_scale_lod, in.rows, geometry.pupil_span_px);
  w_x_t_ = DftMatrix(out.cols, geometry.pixel_scale_lod, in.cols, geometry.pupil_span_px).transpose();
  scale_ = 1.0 / (geometry.pupil_span_px * geometry.pupil_span_px);
  // Flop counts of the two association orders of W_y E W_x^T.
  const double rows_first =
      static_cast<double>(out.rows) * in.rows * in.cols + static_cast<double>(out.rows) * in.cols * out.cols;
  const double cols_first =
      static_cast<double>(in.rows) * in.cols * out.cols + static_cast<double>(out.rows) * in.rows * out.cols;
  rows_first_ = rows_first <= cols_first;
}

ComplexImage MatrixFourierTransform::Apply(const ComplexImage& field) const {
  CheckArgument(ShapeOf(field) == geometry_.input, "MatrixFourierTransform::Apply", "field shape",
                ToString(ShapeOf(field)), ToString(geometry_.input) + " (the plan's input shape)");
  Eigen::MatrixXcd out;
  if (rows_first_) {
    const Eigen::MatrixXcd tmp = w_y_ * field.matrix();
    out.noalias() = tmp * w_x_t_;
  } else {
    const Eigen::MatrixXcd tmp = field.matrix() * w_x_t_;
    out.noalias() = w_y_ * tmp;
  }
  ComplexImage result = out.array() * scale_;
  return result;
}

ComplexImage MatrixFourierTransform::ApplyAdjoint(const ComplexImage& image) const {
  CheckArgument(ShapeOf(image) == geometry_.output, "MatrixFourierTransform::ApplyAdjoint", "image shape",
                ToString(ShapeOf(image)), ToString(geometry_.output) + " (the plan's output shape)");
  // Adjoint of E -> W_y E W_x^T: Y -> W_y^H Y conj(W_x), and conj(W_x) = (W_x^T)^H = w_x_t_.adjoint().
  Eigen::MatrixXcd out;
  if (rows_first_) {  // the cheaper order mirrors the forward one
    const Eigen::MatrixXcd tmp = image.matrix() * w_x_t_.adjoint();
    out.noalias() = w_y_.adjoint() * tmp;
  } else {
    const Eigen::MatrixXcd tmp = w_y_.adjoint() * image.matrix();
    out.noalias() = tmp * w_x_t_.adjoint();
  }
  ComplexImage result = out.array() * scale_;
  return result;
}

ComplexImage Mft(const ComplexImage& pupil_field, double pupil_span_px, double pixel_scale_lod,
                 Shape output) {
  MftGeometry g;
  g.input = ShapeOf(pupil_field);
  g.pupil_span_px = pupil_span_px;
  g.output = output;
  g.pixel_scale_lod = pixel_scale_lod;
  std::string why;
  if (!g.IsValid(&why)) throw InvalidArgument("Mft: invalid " + why);
  return MatrixFourierTransform(g).Apply(pupil_field);
}

}  // namespace aosr
