// Where each ARKit curve sits in a stored take's columns: takes name their shapes in ARKit's
// camelCase or in Live Link's capitalised form (algo/tracking/arkit.hpp).
#pragma once

#include <array>
#include <string>
#include <vector>

#include "algo/tracking/arkit.hpp"
#include "storage/session_store.hpp"

namespace fb::cli {

// column[k] = the take column of ARKit curve k, -1 where the take lacks it.
inline std::array<int, kArkitShapeCount> arkit_columns(const std::vector<std::string>& names) {
  std::array<int, kArkitShapeCount> column;
  column.fill(-1);
  for (int k = 0; k < kArkitShapeCount; ++k)
    for (std::size_t i = 0; i < names.size(); ++i)
      if (names[i] == kArkitNames[k] || names[i] == kLiveLinkNames[k]) {
        column[k] = static_cast<int>(i);
        break;
      }
  return column;
}

// Frame f's ARKit curves in Apple's order (0 where the take lacks the curve).
inline std::array<float, kArkitShapeCount> arkit_curves(
    const TakeData& take, const std::array<int, kArkitShapeCount>& column, int f) {
  std::array<float, kArkitShapeCount> out{};
  const auto v = take.frame(f);
  for (int k = 0; k < kArkitShapeCount; ++k)
    out[k] = column[k] >= 0 ? v[kTakePoseValues + column[k]] : 0.0f;
  return out;
}

}  // namespace fb::cli
