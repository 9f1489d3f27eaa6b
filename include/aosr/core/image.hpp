// Image and grid types, and the one statement of aosr's geometric conventions.
//
// Conventions (every module follows these; tests check them):
//  * Images are row-major Eigen arrays of double, indexed (y, x) = (row, column).
//  * Pixel centres sit at integer coordinates: pixel (y, x) covers [y-1/2, y+1/2) x [x-1/2, x+1/2).
//  * A shift of +dx moves the scene toward +x (larger column index); +dy toward larger row index.
//  * Centred kernels (PSFs) of size (p, q) have their centre at pixel (p/2, q/2) (integer division),
//    the convention of an fftshift-ed array, so an even-sized PSF is centred on a pixel, not a corner.
//  * The high-resolution (HR) grid is r times finer than the camera's. Camera pixel (Y, X) integrates
//    HR pixels (rY .. rY+r-1, rX .. rX+r-1); its centre is at HR coordinate (rY + (r-1)/2, rX + (r-1)/2).
//  * Models and solvers use double precision; float appears only in files.
#pragma once

#include <Eigen/Core>
#include <complex>
#include <string>
#include <vector>

namespace aosr {

// π and 2π in double precision (one definition for every file).
inline constexpr double kPi = 3.14159265358979323846;
inline constexpr double kTwoPi = 2.0 * kPi;

using Index = Eigen::Index;
using Complex = std::complex<double>;
using Image = Eigen::Array<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
using ComplexImage = Eigen::Array<Complex, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
using Vector = Eigen::VectorXd;
using ComplexVector = Eigen::VectorXcd;

// A stack of equally sized images (frames of a sequence, planes of a cube).
using ImageStack = std::vector<Image>;

// The shape of a 2-D grid: rows (y) by cols (x).
struct Shape {
  Index rows = 0;
  Index cols = 0;
  Index size() const { return rows * cols; }
  bool operator==(const Shape& o) const { return rows == o.rows && cols == o.cols; }
  bool operator!=(const Shape& o) const { return !(*this == o); }
};

inline Shape ShapeOf(const Image& img) { return {img.rows(), img.cols()}; }
inline Shape ShapeOf(const ComplexImage& img) { return {img.rows(), img.cols()}; }
std::string ToString(const Shape& s);  // "RxC"

// Views of an image as a flat vector (row-major order) and back; no copy.
inline Eigen::Map<Vector> AsVector(Image& img) { return {img.data(), img.size()}; }
inline Eigen::Map<const Vector> AsVector(const Image& img) { return {img.data(), img.size()}; }
inline Eigen::Map<const Image> AsImage(const Vector& v, Shape s) { return {v.data(), s.rows, s.cols}; }
inline Eigen::Map<Image> AsImage(Vector& v, Shape s) { return {v.data(), s.rows, s.cols}; }

// Copies a flat vector into an image of the given shape (sizes must agree).
Image ToImage(const Eigen::Ref<const Vector>& v, Shape s);

// True when every value is finite (no NaN, no Inf).
bool AllFinite(const Image& img);
bool AllFinite(const ComplexImage& img);

// Places a centred kernel (centre at (p/2, q/2)) into a periodic grid of shape `s` with its centre
// at (0, 0), wrapping negative offsets: the layout an FFT convolution expects. Kernel must fit.
Image CentredToOrigin(const Image& kernel, Shape s);

// Inverse of CentredToOrigin for a (p, q) window: extracts the kernel centred on (0, 0).
Image OriginToCentred(const Image& periodic, Shape window);

}  // namespace aosr
