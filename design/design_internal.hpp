// Helpers shared by the phase-design sources (not installed: design/ only).
#pragma once

#include <Eigen/Dense>
#include <algorithm>
#include <complex>
#include <vector>

#include "aosr/core/image.hpp"
#include "aosr/core/parallel.hpp"
#include "aosr/solvers/tikhonov.hpp"

namespace aosr::design_internal {


// Σ_{k=0}^{r-1} exp(+2πi f k / n) for every bin f of an axis of length n (forward_model.hpp's B).
inline std::vector<Complex> BoxTransfer(Index n, int r) {
  std::vector<Complex> b(n);
  for (Index f = 0; f < n; ++f) {
    Complex s = 0;
    for (int k = 0; k < r; ++k) s += std::polar(1.0, kTwoPi * double(f) * k / double(n));
    b[f] = s;
  }
  return b;
}

// The reconstructor's prior symbol P(f) on the full HR grid (TikhonovPriorSymbol per bin).
Image PriorSymbol(const TikhonovOptions& o, Shape hr);
// Objective A's argument checks (design_objective.cpp): a fixed-λ reconstructor, σ > 0, a spectrum (if any) on
// the HR grid, finite and >= 0. InvalidArgument naming `fn` and the argument.
void CheckSpectrumOptions(const char* fn, const TikhonovOptions& o, double sigma, const Image& spectrum, Shape hr);

// Objective A's reconstructor in one LR bin (tikhonov.hpp (2)): R = G⁻¹ A0ᴴ, G = A0ᴴA0 + w diag(p), with A0 the
// N x r² aliased nominal system, p the prior symbol at the r² frequencies and w = λ / r². G⁻¹ is returned too
// (the gradient needs it). A G that Cholesky refuses (a zero prior on a frequency no exposure sees) gets the
// pseudo-inverse.
inline void BinReconstructor(const Eigen::MatrixXcd& a0, const Eigen::VectorXd& p, double w, Eigen::MatrixXcd* ginv,
                             Eigen::MatrixXcd* rm) {
  Eigen::MatrixXcd g = a0.adjoint() * a0;
  g.diagonal().array() += w * p.array();
  const Eigen::LLT<Eigen::MatrixXcd> llt(g);
  if (llt.info() == Eigen::Success) {
    *ginv = llt.solve(Eigen::MatrixXcd::Identity(g.rows(), g.cols()));
  } else {
    *ginv = g.completeOrthogonalDecomposition().pseudoInverse();
  }
  *rm = *ginv * a0.adjoint();
}

}  // namespace aosr::design_internal
