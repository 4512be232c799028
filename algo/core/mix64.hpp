// splitmix64's finaliser: a counter-based generator. Random numbers drawn as
// mix64(seed-and-counter) depend only on their inputs, not on the order they are drawn in, so a
// synthetic scene is the same on every build and every visiting order.
#pragma once

#include <cstdint>

namespace fb {

constexpr std::uint64_t mix64(std::uint64_t x) {
  x += 0x9e3779b97f4a7c15ULL;
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ULL;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebULL;
  return x ^ (x >> 31);
}

}  // namespace fb
