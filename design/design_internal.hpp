// Helpers shared by the phase-design sources (not installed: design/ only).
#pragma once

#include <algorithm>
#include <complex>
#include <vector>

#include "aosr/core/image.hpp"
#include "aosr/core/parallel.hpp"

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

}  // namespace aosr::design_internal
