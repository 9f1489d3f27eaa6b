#include "aosr/scene/image_object.hpp"

#include <Eigen/SparseCore>
#include <algorithm>
#include <cmath>
#include <vector>

#include "aosr/core/error.hpp"
#include "aosr/io/image_io.hpp"

namespace aosr {
namespace {

using SparseRows = Eigen::SparseMatrix<double, Eigen::RowMajor>;
using RowMatrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;


// The (bins x n) overlap matrix of `bins` equal intervals tiling the window [w0, w0 + length] with the unit
// source intervals [j, j + 1), j = 0 .. n-1. Edges are computed once each, so adjacent bins share them and
// the overlaps of a source interval telescope to its covered length.
SparseRows OverlapMatrix(Index n, Index bins, double w0, double length) {
  std::vector<double> edges(bins + 1);
  for (Index k = 0; k <= bins; ++k)
    edges[k] = w0 + length * (static_cast<double>(k) / static_cast<double>(bins));
  edges[bins] = w0 + length;
  std::vector<Eigen::Triplet<double>> triplets;
  triplets.reserve(static_cast<std::size_t>(bins + n) * 2);
  for (Index k = 0; k < bins; ++k) {
    const double a = edges[k], b = edges[k + 1];
    const Index j0 = std::max<Index>(0, static_cast<Index>(std::floor(a)));
    const Index j1 = std::min<Index>(n - 1, static_cast<Index>(std::ceil(b)) - 1);
    for (Index j = j0; j <= j1; ++j) {
      const double overlap = std::min(b, static_cast<double>(j + 1)) - std::max(a, static_cast<double>(j));
      if (overlap > 0.0) triplets.emplace_back(k, j, overlap);
    }
  }
  SparseRows m(bins, n);
  m.setFromTriplets(triplets.begin(), triplets.end());
  return m;
}

double Median(std::vector<double> v) {
  const std::size_t mid = v.size() / 2;
  std::nth_element(v.begin(), v.begin() + mid, v.end());
  const double upper = v[mid];
  if (v.size() % 2 == 1) return upper;
  const double lower = *std::max_element(v.begin(), v.begin() + mid);
  return 0.5 * (lower + upper);
}

double Background(const Image& src, ImageBackground mode) {
  switch (mode) {
    case ImageBackground::kNone:
      return 0.0;
    case ImageBackground::kMinimum:
      return src.minCoeff();
    case ImageBackground::kMedian:
      return Median(std::vector<double>(src.data(), src.data() + src.size()));
    case ImageBackground::kBorderMedian: {
      const Index h = src.rows(), w = src.cols();
      const Index k = std::max<Index>(1, std::min(h, w) / 20);
      std::vector<double> ring;
      for (Index i = 0; i < h; ++i)
        for (Index j = 0; j < w; ++j)
          if (i < k || i >= h - k || j < k || j >= w - k) ring.push_back(src(i, j));
      return Median(std::move(ring));
    }
  }
  return 0.0;
}

void CheckSource(const std::string& function, const Image& source) {
  CheckArgument(source.size() > 0, function, "source", ToString(ShapeOf(source)), "a non-empty image");
  if (!source.isFinite().all()) {
    const Index bad = source.size() - source.isFinite().count();
    throw InvalidArgument(function, "source", std::to_string(bad) + " non-finite pixels",
                          "finite pixel values");
  }
}

void CheckShape(const std::string& function, const std::string& name, Shape s) {
  CheckArgument(s.rows >= 1 && s.cols >= 1, function, name, ToString(s), "rows and cols >= 1");
}

Image Resample(const Image& source, Shape out, ImageFit fit, PixelValues values) {
  const Index h = source.rows(), w = source.cols();
  double len_y = static_cast<double>(h), len_x = static_cast<double>(w);
  if (fit == ImageFit::kCrop) {
    // Compare aspect ratios h/w and H/W exactly in integers.
    const long long lhs = static_cast<long long>(h) * out.cols, rhs = static_cast<long long>(w) * out.rows;
    if (lhs > rhs)
      len_y = static_cast<double>(w) * out.rows / out.cols;  // source taller: crop rows
    else if (lhs < rhs)
      len_x = static_cast<double>(h) * out.cols / out.rows;  // source wider: crop columns
  }
  const SparseRows a = OverlapMatrix(h, out.rows, 0.5 * (h - len_y), len_y);
  const SparseRows b = OverlapMatrix(w, out.cols, 0.5 * (w - len_x), len_x);
  const Eigen::Map<const RowMatrix> src(source.data(), h, w);
  const RowMatrix tmp = a * src;           // out.rows x w
  RowMatrix result = tmp * b.transpose();  // out.rows x out.cols
  if (values == PixelValues::kSurfaceBrightness) {
    result /= (len_y / static_cast<double>(out.rows)) * (len_x / static_cast<double>(out.cols));
  }
  return result.array();
}

}  // namespace

bool ImageObjectOptions::IsValid(std::string* why) const {
  if (fit != ImageFit::kCrop && fit != ImageFit::kStretch)
    return Fail(why, "fit = " + std::to_string(static_cast<int>(fit)) + " (must be kCrop or kStretch)");
  if (values != PixelValues::kSurfaceBrightness && values != PixelValues::kFluxPerPixel)
    return Fail(why, "values = " + std::to_string(static_cast<int>(values)) +
                         " (must be kSurfaceBrightness or kFluxPerPixel)");
  if (static_cast<int>(background) < 0 || static_cast<int>(background) > 3)
    return Fail(why,
                "background = " + std::to_string(static_cast<int>(background)) + " (not an ImageBackground)");
  if (static_cast<int>(normalisation) < 0 || static_cast<int>(normalisation) > 2)
    return Fail(why, "normalisation = " + std::to_string(static_cast<int>(normalisation)) +
                         " (not a FluxNormalisation)");
  if (!std::isfinite(total_flux) || total_flux <= 0.0)
    return Fail(why, "total_flux = " + ToString(total_flux) + " (must be finite and > 0)");
  if (!std::isfinite(peak_value) || peak_value <= 0.0)
    return Fail(why, "peak_value = " + ToString(peak_value) + " (must be finite and > 0)");
  return true;
}

Image ResampleArea(const Image& source, Shape out, ImageFit fit, PixelValues values) {
  CheckSource("ResampleArea", source);
  CheckShape("ResampleArea", "out", out);
  CheckArgument(fit == ImageFit::kCrop || fit == ImageFit::kStretch, "ResampleArea", "fit",
                static_cast<int>(fit), "kCrop or kStretch");
  CheckArgument(values == PixelValues::kSurfaceBrightness || values == PixelValues::kFluxPerPixel,
                "ResampleArea", "values", static_cast<int>(values), "kSurfaceBrightness or kFluxPerPixel");
  return Resample(source, out, fit, values);
}

Image MakeImageObject(const Image& source, Shape hr, const ImageObjectOptions& options) {
  const std::string fn = "MakeImageObject";
  CheckSource(fn, source);
  CheckShape(fn, "hr", hr);
  std::string why;
  if (!options.IsValid(&why)) throw InvalidArgument(fn + ": invalid options: " + why);

  const double background = Background(source, options.background);
  Image out = Resample(source - background, hr, options.fit, options.values);
  if (options.clip_negative) out = out.max(0.0);
  switch (options.normalisation) {
    case FluxNormalisation::kKeep:
      break;
    case FluxNormalisation::kTotalFlux: {
      const double sum = out.sum();
      CheckArgument(sum > 0.0, fn, "image sum", sum,
                    "> 0 to normalise to total_flux (after background and clipping)");
      out *= options.total_flux / sum;
      break;
    }
    case FluxNormalisation::kPeak: {
      const double peak = out.maxCoeff();
      CheckArgument(peak > 0.0, fn, "image maximum", peak,
                    "> 0 to normalise to peak_value (after background)");
      out *= options.peak_value / peak;
      break;
    }
  }
  return out;
}

Image LoadImageObject(const std::string& path, Shape hr, const ImageObjectOptions& options) {
  const std::string fn = "LoadImageObject";
  CheckShape(fn, "hr", hr);
  std::string why;
  if (!options.IsValid(&why)) throw InvalidArgument(fn + "(" + path + "): invalid options: " + why);
  const Image source = ReadImage(path);  // IoError names the path
  try {
    return MakeImageObject(source, hr, options);
  } catch (const InvalidArgument& e) {
    throw InvalidArgument(fn + "(" + path + "): " + e.what());
  }
}

}  // namespace aosr
