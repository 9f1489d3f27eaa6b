#include "aosr/core/image.hpp"
#include <cstring>
#include <cstdint>

#include "aosr/core/error.hpp"

namespace aosr {

std::string ToString(const Shape& s) { return std::to_string(s.rows) + "x" + std::to_string(s.cols); }

Image ToImage(const Eigen::Ref<const Vector>& v, Shape s) {
  CheckArgument(v.size() == s.size(), "ToImage", "vector size", v.size(),
                "rows*cols = " + std::to_string(s.size()));
  Image img(s.rows, s.cols);
  AsVector(img) = v;
  return img;
}

namespace {

bool AllFiniteDoubles(const double* p, Index n) {
  // A double is NaN or ±Inf exactly when its exponent bits are all ones: an integer OR over the bits, which the
  // compiler vectorises (Eigen's isFinite().all() tests element by element: 4 ns per pixel, a tenth of a second
  // per whole-detector frame, paid at every boundary check).
  std::uint64_t bad = 0;
  for (Index i = 0; i < n; ++i) {
    std::uint64_t bits;
    std::memcpy(&bits, p + i, sizeof bits);
    bad |= std::uint64_t((bits & 0x7ff0000000000000ull) == 0x7ff0000000000000ull);
  }
  return bad == 0;
}

}  // namespace

bool AllFinite(const Image& img) { return AllFiniteDoubles(img.data(), img.size()); }

// std::complex<double> is two doubles in a row (the standard's array-oriented access guarantee).
bool AllFinite(const ComplexImage& img) {
  return AllFiniteDoubles(reinterpret_cast<const double*>(img.data()), 2 * img.size());
}

Image CentredToOrigin(const Image& kernel, Shape s) {
  CheckArgument(kernel.rows() <= s.rows && kernel.cols() <= s.cols, "CentredToOrigin", "kernel shape",
                ToString(ShapeOf(kernel)), "at most the grid shape " + ToString(s));
  Image out = Image::Zero(s.rows, s.cols);
  const Index cy = kernel.rows() / 2, cx = kernel.cols() / 2;
  for (Index y = 0; y < kernel.rows(); ++y) {
    const Index gy = ((y - cy) % s.rows + s.rows) % s.rows;
    for (Index x = 0; x < kernel.cols(); ++x) {
      const Index gx = ((x - cx) % s.cols + s.cols) % s.cols;
      out(gy, gx) += kernel(y, x);
    }
  }
  return out;
}

Image OriginToCentred(const Image& periodic, Shape window) {
  CheckArgument(window.rows <= periodic.rows() && window.cols <= periodic.cols(), "OriginToCentred",
                "window", ToString(window), "at most the grid shape " + ToString(ShapeOf(periodic)));
  Image out(window.rows, window.cols);
  const Index cy = window.rows / 2, cx = window.cols / 2;
  const Index R = periodic.rows(), C = periodic.cols();
  for (Index y = 0; y < window.rows; ++y)
    for (Index x = 0; x < window.cols; ++x)
      out(y, x) = periodic((((y - cy) % R) + R) % R, (((x - cx) % C) + C) % C);
  return out;
}

}  // namespace aosr
