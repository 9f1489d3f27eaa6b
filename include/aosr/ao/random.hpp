// Deterministic, portable Gaussian random numbers for the turbulence simulators.
//
// Why not std::normal_distribution: the C++ standard fixes the output of std::mt19937_64 but not the
// algorithm of the distributions, so libstdc++, libc++ and MSVC give different normal deviates for the same
// seed. Here the uniform bits come from std::mt19937_64 and the normal deviates from our own Box-Muller
// transform (Box & Muller 1958):
//     u1 in (0, 1], u2 in [0, 1) from the top 53 bits of two engine outputs,
//     z0 = sqrt(-2 ln u1) cos(2 pi u2),   z1 = sqrt(-2 ln u1) sin(2 pi u2),
// so a seed gives the same sequence on every platform up to the last-bit rounding of log/cos/sin in libm.
//
// Seeds. Every generator takes an explicit uint64 seed (DESIGN.md §4). Independent streams (one per
// turbulent layer, one per screen of a batch) come from DeriveSeed(master, stream), a SplitMix64 hash
// (Steele, Lea & Flood 2014) of the pair: nearby masters and streams give unrelated engine states.
#pragma once

#include <cstdint>
#include <random>

namespace aosr {

// SplitMix64 finaliser of (master, stream): a well-mixed 64-bit seed for sub-stream `stream`.
std::uint64_t DeriveSeed(std::uint64_t master_seed, std::uint64_t stream);

// Standard normal deviates (mean 0, variance 1) by Box-Muller over std::mt19937_64. Not thread-safe; use
// one generator per thread or per stream.
class NormalGenerator {
 public:
  explicit NormalGenerator(std::uint64_t seed) : engine_(seed) {}

  // The next N(0, 1) deviate. Deviates come in Box-Muller pairs; the second of a pair is cached.
  double Next();
  // Fills out[0 .. count-1] with N(0, 1) deviates (the same values as `count` calls to Next()).
  void Fill(double* out, std::int64_t count);

 private:
  std::mt19937_64 engine_;
  bool has_spare_ = false;
  double spare_ = 0.0;
};

}  // namespace aosr
