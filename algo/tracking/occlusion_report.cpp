#include "algo/tracking/occlusion_report.hpp"

namespace fb {

float hidden_fraction(int hidden, int visible) {
  const int total = hidden + visible;
  return total > 0 ? static_cast<float>(hidden) / static_cast<float>(total) : 0.0f;
}

}  // namespace fb
