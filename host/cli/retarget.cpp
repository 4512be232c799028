#include "host/cli/retarget.hpp"

#include <algorithm>
#include <cstdlib>

#include "algo/tracking/arkit.hpp"

namespace fb::cli {

Result<std::vector<int>> take_columns_for_rig(const std::vector<std::string>& take_names,
                                              const std::vector<std::string>& rig_shapes) {
  auto column = [&](const std::string& name) {
    const auto it = std::find(take_names.begin(), take_names.end(), name);
    return it == take_names.end() ? -1 : static_cast<int>(it - take_names.begin());
  };
  std::vector<int> columns;
  int driven = 0;
  for (const std::string& shape : rig_shapes) {
    int c = column(shape);
    if (c < 0) c = column(arkit_name_of(shape));
    columns.push_back(c);
    driven += c >= 0 ? 1 : 0;
  }
  if (driven == 0)
    return fail("none of the rig's " + std::to_string(rig_shapes.size()) +
                " shapes has a curve in the take (the take has " +
                std::to_string(take_names.size()) +
                " curves): the rig needs the face model's or ARKit's shape names");
  return columns;
}

std::vector<float> retarget_frame(const TakeData& take, int f, const RigData& rig,
                                  const std::vector<int>& columns) {
  const auto values = take.frame(f);
  std::vector<float> mesh = rig.neutral;
  for (std::size_t j = 0; j < rig.shapes.size(); ++j) {
    if (columns[j] < 0) continue;
    const float w = values[static_cast<std::size_t>(kTakePoseValues + columns[j])];
    if (w == 0.0f) continue;
    const auto& s = rig.shapes[j];
    for (std::size_t i = 0; i < mesh.size(); ++i) mesh[i] += w * (s[i] - rig.neutral[i]);
  }
  return mesh;
}

Result<RigInfo> rig_for_target(const SessionStore& store, const std::string& to) {
  auto number = [](const std::string& text) -> long long {
    char* end = nullptr;
    const long long v = std::strtoll(text.c_str(), &end, 10);
    return text.empty() || *end != '\0' || v <= 0 ? -1 : v;
  };
  const bool session = to.rfind("session:", 0) == 0;
  const std::string id_text =
      session ? to.substr(8) : (to.rfind("subject:", 0) == 0 ? to.substr(8) : to);
  const long long id = number(id_text);
  if (id < 0)
    return fail("--to " + to + ": write session:ID or subject:ID (or just the subject's ID)");
  auto rig = session ? store.rig_for(id) : store.newest_rig(id);
  if (!rig) return rig.failure();
  if (!*rig)
    return fail(std::string(session ? "session " : "subject ") + std::to_string(id) +
                " has no rig: build one with `facebooth rig --store STORE --session ID --save`");
  return **rig;
}

}  // namespace fb::cli
