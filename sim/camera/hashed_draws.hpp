// Counter-based random draws for the synthetic world: a draw depends only on (seed, stream, k),
// not on the order of drawing, so a subject's camera and captures are the same on every build.
#pragma once

#include <cmath>
#include <cstdint>
#include <numbers>

#include "algo/core/mix64.hpp"

namespace fb {

// Uniform in (0, 1).
inline double hashed_uniform(std::uint64_t seed, std::uint64_t stream, std::uint64_t k) {
  const auto bits = mix64(mix64(seed ^ (stream << 56)) + k);
  return (static_cast<double>(bits >> 11) + 0.5) * 0x1.0p-53;
}

// Standard normal: Box-Muller from two counter-based uniforms.
inline double hashed_gaussian(std::uint64_t seed, std::uint64_t stream, std::uint64_t k) {
  const double u1 = hashed_uniform(seed, stream, 2 * k),
               u2 = hashed_uniform(seed, stream, 2 * k + 1);
  return std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * std::numbers::pi * u2);
}

}  // namespace fb
