// Private to solvers/ (and its tests): the linear model of the frames in the stars' PSF that
// EstimateStarsPsf (stars_psf.cpp) fits, over one PSF or the nodes of a field grid. Here so that its adjoint and
// its field interpolation are tested directly (tests/solvers/star_field_model_test.cpp).
#pragma once

#include <Eigen/Dense>
#include <cmath>
#include <vector>

#include "aosr/core/fft.hpp"
#include "aosr/core/forward_model.hpp"
#include "aosr/core/image.hpp"
#include "aosr/core/psf_field.hpp"

namespace aosr::stars_internal {

struct Star {
  double y = 0, x = 0, f = 0;  // HR-frame position (HR px) and flux (e⁻ per frame)
  double y_det = 0, x_det = 0;  // where it was detected (HR px)
  double sigma_f = 0;
};

// The half-spectrum transfer of the star field on the padded grid, with the kernel's centre at (P/2, P/2):
// S(f) = Σ_j f_j exp(−2πi f·(p_j − P/2)/P) (a frame's offset is a phase ramp on it, StarFieldModel).
inline ComplexImage StarTransfer(const std::vector<Star>& stars, Shape pad) {
  const Index hc = pad.cols / 2 + 1;
  Eigen::MatrixXcd acc = Eigen::MatrixXcd::Zero(pad.rows, hc);
  Eigen::VectorXcd ey(pad.rows);
  Eigen::RowVectorXcd ex(hc);
  for (const Star& s : stars) {
    const double ay = s.y - double(pad.rows / 2), ax = s.x - double(pad.cols / 2);
    for (Index v = 0; v < pad.rows; ++v) {
      // Signed frequencies: the field is real (Hermitian spectrum) only with them, for non-integer positions.
      const double a = -2.0 * kPi * double(SignedFrequency(v, pad.rows)) * ay / double(pad.rows);
      ey(v) = s.f * Complex(std::cos(a), std::sin(a));
    }
    for (Index u = 0; u < hc; ++u) {
      const double a = -2.0 * kPi * double(u) * ax / double(pad.cols);
      ex(u) = Complex(std::cos(a), std::sin(a));
    }
    acc.noalias() += ey * ex;
  }
  return acc.array();
}

// The stars as node g of a field grid sees them: each scaled by its bilinear weight on the node (core/psf_field.hpp),
// those off the node's support left out. A single node (or no grid) sees every star as it is.
inline std::vector<Star> NodeStars(const std::vector<Star>& stars, const PsfFieldGrid& grid, int g) {
  if (grid.nodes() <= 1) return stars;
  std::vector<Star> out;
  for (const Star& s : stars)
    for (const PsfFieldGrid::Weight& w : grid.Weights(s.y, s.x))
      if (w.node == g) {
        Star t = s;
        t.f *= w.weight;
        out.push_back(t);
      }
  return out;
}

// The frames as a function of u = [h_0 .. h_{G-1} (G K²); b (N)] for fixed stars, G the field grid's nodes (1 without
// a grid): y_i = D_r Crop(Σ_g S_{i,g} ⊛ ZeroPad h_g) + b_i, with S_{i,g} the star field of frame i on the padded grid
// (kernel centre at (P/2, P/2)) weighted by the stars' bilinear weights on node g, so each star is seen through
// the PSF interpolated at its position. The sum over nodes is taken in Fourier space. One object for all frames,
// its FFT buffers reused across calls (the composed LinearOperators allocate per call, and the page faults of
// those allocations cost more than the FFTs): a normal-operator application is 2 (N + G) FFTs. Not thread-safe.
class StarFieldModel {
 public:
  StarFieldModel(const std::vector<Star>& stars, const PsfFieldGrid& grid, const std::vector<FrameOffset>& offsets,
                 Shape pad, Shape hr, int r, Index k)
      : pad_(pad), hr_(hr), r_(r), k_(k), g_(std::max(1, grid.nodes())), top_(pad.rows / 2 - k / 2),
        left_(pad.cols / 2 - k / 2), h_spec_(std::size_t(g_)), acc_(std::size_t(g_)) {
    // The stars' sum is formed once per node (its cost is stars × padded grid); each frame's offset is then
    // a separable phase ramp: S_{i,g}(f) = S_g(f) · exp(−2πi f·o_i / P), signed frequencies as StarTransfer's.
    spectra_.resize(offsets.size() * std::size_t(g_));
    const Index hc = pad.cols / 2 + 1;
    for (int g = 0; g < g_; ++g) {
      const ComplexImage base = StarTransfer(NodeStars(stars, grid, g), pad);
      for (std::size_t i = 0; i < offsets.size(); ++i) {
        Eigen::VectorXcd ey(pad.rows);
        Eigen::RowVectorXcd ex(hc);
        for (Index v = 0; v < pad.rows; ++v)
          ey(v) = std::polar(1.0, -2.0 * kPi * double(SignedFrequency(v, pad.rows)) * offsets[i].dy / double(pad.rows));
        for (Index u = 0; u < hc; ++u) ex(u) = std::polar(1.0, -2.0 * kPi * double(u) * offsets[i].dx / double(pad.cols));
        const ComplexImage ramp = (ey * ex).array();
        spectra_[i * std::size_t(g_) + std::size_t(g)] = HermitianProjection(base * ramp, pad.cols);
      }
    }
  }
  Index unknowns_psf() const { return Index(g_) * k_ * k_; }
  Index frames() const { return Index(spectra_.size()) / g_; }
  Shape lr() const { return {hr_.rows / r_, hr_.cols / r_}; }

  // Frame i without background, camera px.
  Image Render(const Vector& h, Index i) {
    Forward(h);
    Image out;
    FrameFromSpectrum(i, &out);
    return out;
  }
  // Σ_i Aᵢᵀ c_i (camera images c_i): the h parts into z.head(G K²), Σ c_i into the b part.
  void Backward(const ImageStack& c, Eigen::Ref<Vector> z) {
    for (ComplexImage& a : acc_) a.setZero(pad_.rows, pad_.cols / 2 + 1);
    const Index gk2 = unknowns_psf();
    for (Index i = 0; i < frames(); ++i) {
      BackProject(c[std::size_t(i)], i);
      z(gk2 + i) = c[std::size_t(i)].sum();
    }
    for (int g = 0; g < g_; ++g) {
      FftC2RInto(acc_[std::size_t(g)], pad_.cols, &real_);
      const Index base = Index(g) * k_ * k_;
      for (Index v = 0; v < k_; ++v)
        for (Index u = 0; u < k_; ++u) z(base + v * k_ + u) = real_(top_ + v, left_ + u);
    }
  }
  // (AᵀWA) u for the weights w_i.
  void Normal(const Eigen::Ref<const Vector>& u, const ImageStack& w, Eigen::Ref<Vector> z) {
    const Index gk2 = unknowns_psf();
    Forward(u.head(gk2));
    if (cam_.size() != std::size_t(frames())) cam_.resize(std::size_t(frames()));
    for (Index i = 0; i < frames(); ++i) {
      FrameFromSpectrum(i, &cam_[std::size_t(i)]);
      cam_[std::size_t(i)] = (cam_[std::size_t(i)] + u(gk2 + i)) * w[std::size_t(i)];
    }
    Backward(cam_, z);
  }

 private:
  void Forward(const Eigen::Ref<const Vector>& h) {
    for (int g = 0; g < g_; ++g) {
      real_.setZero(pad_.rows, pad_.cols);
      const Index base = Index(g) * k_ * k_;
      for (Index v = 0; v < k_; ++v)
        for (Index u = 0; u < k_; ++u) real_(top_ + v, left_ + u) = h(base + v * k_ + u);
      FftR2CInto(real_, &h_spec_[std::size_t(g)]);
    }
  }
  const ComplexImage& Spectrum(Index i, int g) const { return spectra_[std::size_t(i * g_ + g)]; }
  void FrameFromSpectrum(Index i, Image* out) {
    prod_ = h_spec_[0] * Spectrum(i, 0);
    for (int g = 1; g < g_; ++g) prod_ += h_spec_[std::size_t(g)] * Spectrum(i, g);
    FftC2RInto(prod_, pad_.cols, &frame_);
    const Shape m = lr();
    out->setZero(m.rows, m.cols);
    for (Index yy = 0; yy < m.rows; ++yy)
      for (int a = 0; a < r_; ++a) {
        const double* row = &frame_(yy * r_ + a, 0);
        double* o = &(*out)(yy, 0);
        for (Index xx = 0; xx < m.cols; ++xx)
          for (int b = 0; b < r_; ++b) o[xx] += row[xx * r_ + b];
      }
  }
  void BackProject(const Image& c, Index i) {
    frame_.setZero(pad_.rows, pad_.cols);
    for (Index y = 0; y < hr_.rows; ++y) {
      const double* src = &c(y / r_, 0);
      double* dst = &frame_(y, 0);
      for (Index x = 0; x < hr_.cols; ++x) dst[x] = src[x / r_];
    }
    FftR2CInto(frame_, &prod_);
    for (int g = 0; g < g_; ++g) acc_[std::size_t(g)] += prod_ * Spectrum(i, g).conjugate();
  }

  Shape pad_, hr_;
  int r_;
  Index k_;
  int g_;
  Index top_, left_;
  std::vector<ComplexImage> spectra_;  // frame-major: [i · G + g]
  Image real_, frame_;
  std::vector<ComplexImage> h_spec_, acc_;
  ComplexImage prod_;
  ImageStack cam_;
};

}  // namespace aosr::stars_internal
