#include "storage/export/arkit_rig.hpp"

#include "algo/tracking/arkit.hpp"

namespace fb {

Result<ShapeNames> parse_shape_names(std::string_view name) {
  if (name == "arkit") return ShapeNames::kArkit;
  if (name == "model") return ShapeNames::kModel;
  return fail("unknown --names '" + std::string(name) +
              "': use arkit (Apple's 52 ARKit blendshapes) or model (the face model's names)");
}

const char* to_string(ShapeNames names) {
  return names == ShapeNames::kArkit ? "arkit" : "model";
}

Result<ArkitRig> to_arkit_rig(const RigData& rig) {
  std::vector<int> unmapped;
  auto mapping = make_arkit_mapping(rig.shape_names, &unmapped);
  if (!mapping) {
    return fail("the rig's blendshapes cannot be named as ARKit's 52 (" + mapping.error().message +
                "); export them with --names model");
  }
  ArkitRig out;
  out.rig.neutral = rig.neutral;
  out.rig.triangles = rig.triangles;
  for (int j : unmapped) out.dropped.push_back(rig.shape_names[static_cast<std::size_t>(j)]);
  for (int i = 0; i < kArkitShapeCount; ++i) {
    // An ARKit value v sets every source shape to v (ArkitMapping::to_model), so the combined
    // shape is the neutral plus the sum of the sources' deltas.
    std::vector<float> shape = rig.neutral;
    std::string sources;
    for (int s : mapping->sources[static_cast<std::size_t>(i)]) {
      if (s < 0) continue;
      const auto& source = rig.shapes[static_cast<std::size_t>(s)];
      for (std::size_t k = 0; k < shape.size(); ++k) shape[k] += source[k] - rig.neutral[k];
      sources += (sources.empty() ? "" : " + ") + rig.shape_names[static_cast<std::size_t>(s)];
    }
    const std::string name(kArkitNames[static_cast<std::size_t>(i)]);
    if (sources.find(" + ") != std::string::npos) out.combined.push_back(name + " = " + sources);
    out.rig.shapes.push_back(std::move(shape));
    out.rig.shape_names.push_back(name);
  }
  return out;
}

}  // namespace fb
