// Internal helpers shared by the analytic AO sources (not installed; see include/aosr/ao/analytic_ao.hpp
// for the maths).
#pragma once

#include <string>

#include "aosr/ao/analytic_ao.hpp"

namespace aosr {
namespace analytic_ao_internal {


// Throws InvalidArgument("<function>: invalid options. <why>") unless options.IsValid().
void CheckOptions(const AnalyticAoOptions& options, const char* function);

// The loop of section 3 with the validation already done: squared moduli of E and H_n at the reduced
// frequency x = 2 pi nu T (any sign).
struct LoopModel {
  double gain = 0.0;
  double delay_frames = 0.0;

  struct Squares {
    double rejection = 1.0;  // |E|^2
    double noise = 0.0;      // |H_n|^2
  };
  Squares At(double x) const;
};

// q(x) = (5/3) int_1^inf t^(-8/3) (1 - J0(x t)) dt for x >= 0 (section 5 of the header): 0 at 0, -> 1.
double TailShape(double x);

}  // namespace analytic_ao_internal
}  // namespace aosr
