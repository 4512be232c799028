#include "algo/tracking/rig_view.hpp"

#include <algorithm>

namespace fb {

int fitting_shape_for_name(const FaceModel& model, const ArkitMapping& mapping,
                           std::string_view name) {
  int index = model.expression_index(name);
  if (index < 0) {
    for (int a = 0; a < kArkitShapeCount; ++a) {
      const auto& src = mapping.sources[static_cast<std::size_t>(a)];
      if ((kArkitNames[static_cast<std::size_t>(a)] == name ||
           kLiveLinkNames[static_cast<std::size_t>(a)] == name) &&
          src[0] >= 0 && src[1] < 0) {
        index = src[0];
      }
    }
  }
  return index >= 0 && index < model.fitting_expression_count ? index : -1;
}

TrackerRig tracker_rig_view(std::span<const float> neutral, std::span<const std::string> names,
                            std::span<const std::vector<float>> shapes, const FaceModel& model,
                            const ArkitMapping& mapping) {
  TrackerRig view;
  view.neutral = neutral;
  const std::size_t count = std::min(names.size(), shapes.size());
  for (std::size_t s = 0; s < count; ++s) {
    const int index = fitting_shape_for_name(model, mapping, names[s]);
    if (index >= 0) view.shapes.emplace_back(index, shapes[s]);
  }
  return view;
}

}  // namespace fb
