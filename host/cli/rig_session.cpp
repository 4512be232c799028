#include "host/cli/rig_session.hpp"

#include <map>

namespace fb::cli {

Result<SessionExamples> load_session_examples(const SessionStore& store, SessionId session,
                                              const FaceModel& model, const GuideSet& guide,
                                              bool allow_missing) {
  auto info = store.session(session);
  if (!info) return info.failure();
  auto captures = store.captures(session);
  if (!captures) return captures.failure();
  auto meshes = store.meshes(session);
  if (!meshes) return meshes.failure();
  // Newest fitted (or neutral) mesh per capture index.
  std::map<int, MeshId> by_capture;
  for (const auto& m : *meshes) {
    if (!m.capture_index || m.role == MeshRole::kScan) continue;
    auto& id = by_capture[*m.capture_index];
    id = std::max(id, m.id);
  }
  SessionExamples out;
  out.subject = info->subject;
  std::vector<std::pair<int, std::string>> present;
  for (const auto& c : *captures) {
    if (by_capture.count(c.index) == 0) {
      out.missing.push_back(c.expression + " (capture " + std::to_string(c.index) + ")");
      continue;
    }
    present.emplace_back(c.index, c.expression);
  }
  if (present.empty() || present.front().first != 0) {
    return fail("session " + std::to_string(session) +
                " has no fitted neutral (capture 0); rigging starts from it: fit the session's "
                "neutral capture first");
  }
  if (!out.missing.empty() && !allow_missing) {
    std::string list;
    for (const auto& m : out.missing) list += (list.empty() ? "" : ", ") + m;
    return fail("session " + std::to_string(session) + " is missing fitted meshes for " +
                std::to_string(out.missing.size()) + " of " + std::to_string(captures->size()) +
                " expressions: " + list + ". Fit them first, or pass --allow-missing to rig from " +
                "the " + std::to_string(present.size()) + " that are there");
  }
  if (present.size() < 2)
    return fail("session " + std::to_string(session) +
                " has only the neutral fitted; rigging needs at least one expression");
  const int n = model.fitting_expression_count;
  for (const auto& [index, expression] : present) {
    const int g = guide.find(expression);
    if (g < 0)
      return fail("session " + std::to_string(session) + ", capture " + std::to_string(index) +
                  ": expression '" + expression +
                  "' is not a guide recipe, so its weights are unknown (rigging needs the "
                  "guide's known weights; was the session captured with another guide file?)");
    auto w = guide_weights(guide.expressions[static_cast<std::size_t>(g)], model);
    if (!w) return w.failure();
    w->resize(static_cast<std::size_t>(n));
    auto mesh = store.read_mesh(by_capture[index]);
    if (!mesh) return mesh.failure();
    if (mesh->vertex_count() != model.vertex_count)
      return fail("session " + std::to_string(session) + ", capture " + std::to_string(index) +
                  ": the fitted mesh has " + std::to_string(mesh->vertex_count()) +
                  " vertices, the face model " + std::to_string(model.vertex_count) +
                  " (rigging needs meshes in the model's topology)");
    out.names.push_back(expression);
    out.capture_indices.push_back(index);
    out.meshes.push_back(std::move(mesh->positions));
    out.weights.push_back(std::move(*w));
  }
  return out;
}

Result<SessionRig> rig_examples(const SessionExamples& examples, const FaceModel& model,
                                const RigOptions& options) {
  std::vector<std::vector<float>> generic;
  RigInput input = generic_rig_input(model, generic);
  for (const auto& m : examples.meshes) input.examples.emplace_back(m);
  input.example_weights = examples.weights;
  auto rig = rig_subject(input, options);
  if (!rig) return rig.failure();
  SessionRig out;
  out.data.neutral = rig->neutral;
  out.data.shapes = rig->shapes;
  for (int j = 0; j < model.fitting_expression_count; ++j)
    out.data.shape_names.push_back(model.expression_names[static_cast<std::size_t>(j)]);
  out.data.triangles = model.triangles;
  out.result = std::move(*rig);
  return out;
}

RigInput generic_rig_input(const FaceModel& model, std::vector<std::vector<float>>& storage) {
  const std::size_t floats = static_cast<std::size_t>(model.vertex_count) * 3;
  storage.assign(static_cast<std::size_t>(model.fitting_expression_count) + 1,
                 std::vector<float>(floats));
  model.evaluate({}, {}, storage[0]);
  for (int j = 0; j < model.fitting_expression_count; ++j) {
    const auto delta = model.expression_shape(j);
    auto& s = storage[static_cast<std::size_t>(j) + 1];
    for (std::size_t k = 0; k < floats; ++k) s[k] = storage[0][k] + delta[k];
  }
  RigInput in;
  in.triangles = model.triangles;
  in.generic_neutral = storage[0];
  for (std::size_t j = 1; j < storage.size(); ++j) in.generic_shapes.emplace_back(storage[j]);
  return in;
}

}  // namespace fb::cli
