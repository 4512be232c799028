#include "storage/export/gltf_animation.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <string>

#include "storage/export/gltf_animation_json.hpp"

namespace fb {

RigidPose scene_from_camera_pose(const RigidPose& camera_from_model) {
  const Eigen::Quaterniond flip(Eigen::AngleAxisd(std::numbers::pi, Eigen::Vector3d::UnitX()));
  RigidPose out;
  out.rotation = (flip * camera_from_model.rotation).normalized();
  out.translation = flip * camera_from_model.translation * 0.001;
  return out;
}

void append_head_pose(const RigidPose& camera_from_model, GlbAnimation& animation) {
  const RigidPose scene = scene_from_camera_pose(camera_from_model);
  Eigen::Vector4d q(scene.rotation.x(), scene.rotation.y(), scene.rotation.z(), scene.rotation.w());
  const std::size_t n = animation.rotations.size();
  if (n >= 4) {
    const Eigen::Vector4d previous(animation.rotations[n - 4], animation.rotations[n - 3],
                                   animation.rotations[n - 2], animation.rotations[n - 1]);
    if (previous.dot(q) < 0.0) q = -q;
  } else if (q.w() < 0.0) {
    q = -q;
  }
  for (int k = 0; k < 3; ++k) animation.translations_m.push_back(float(scene.translation[k]));
  for (int k = 0; k < 4; ++k) animation.rotations.push_back(float(q[k]));
}

namespace {

Result<void> finite(const std::vector<float>& values, std::size_t per_frame, const char* what) {
  for (std::size_t i = 0; i < values.size(); ++i)
    if (!std::isfinite(values[i]))
      return fail("frame " + std::to_string(i / per_frame) + "'s " + what +
                  " is not a number; the take is damaged there (re-record it, or export its "
                  "Live Link CSV alone)");
  return success();
}

}  // namespace

Result<void> check_animation(const GlbAnimation& a, int targets) {
  const std::size_t frames = a.times_s.size();
  if (frames == 0) return fail("the take has no frames to animate");
  if (targets <= 0) return fail("the rig has no morph targets to animate");
  if (a.weights.size() != frames * static_cast<std::size_t>(targets))
    return fail("the animation has " + std::to_string(a.weights.size()) + " weights for " +
                std::to_string(frames) + " frames of " + std::to_string(targets) + " targets");
  const bool pose = !a.translations_m.empty() || !a.rotations.empty();
  if (pose && (a.translations_m.size() != 3 * frames || a.rotations.size() != 4 * frames))
    return fail("the animation's head poses are not one per frame");
  for (const auto& e : a.extras)
    if (e.values.size() != frames * e.columns.size())
      return fail("the animation's " + e.key + " are not one row per frame");
  if (auto r = finite(a.times_s, 1, "time"); !r) return r;
  for (std::size_t f = 1; f < frames; ++f)
    if (!(a.times_s[f] > a.times_s[f - 1]))
      return fail("frame " + std::to_string(f) + "'s time (" + std::to_string(a.times_s[f]) +
                  " s) is not after frame " + std::to_string(f - 1) + "'s (" +
                  std::to_string(a.times_s[f - 1]) + " s); glTF animations need increasing times");
  if (auto r = finite(a.weights, static_cast<std::size_t>(targets), "blendshape weight"); !r)
    return r;
  if (auto r = finite(a.translations_m, 3, "head position"); !r) return r;
  if (auto r = finite(a.rotations, 4, "head rotation"); !r) return r;
  for (const auto& e : a.extras)
    if (auto r = finite(e.values, std::max<std::size_t>(1, e.columns.size()), e.key.c_str()); !r)
      return r;
  return success();
}

void add_animation(nlohmann::json& gltf, GlbBuffer& buffer, const GlbAnimation& a,
                   const GlbAnimationNodes& nodes) {
  const int input = buffer.add_floats(a.times_s, 1, "SCALAR", GlbBuffer::kNoTarget);
  nlohmann::json samplers = nlohmann::json::array(), channels = nlohmann::json::array();
  auto channel = [&](int output, int node, const char* path) {
    samplers.push_back({{"input", input}, {"output", output}, {"interpolation", "LINEAR"}});
    channels.push_back(
        {{"sampler", samplers.size() - 1}, {"target", {{"node", node}, {"path", path}}}});
  };
  channel(buffer.add_floats(a.weights, 1, "SCALAR", GlbBuffer::kNoTarget), nodes.mesh, "weights");
  if (!a.translations_m.empty()) {
    channel(buffer.add_floats(a.translations_m, 3, "VEC3", GlbBuffer::kNoTarget), nodes.head,
            "translation");
    channel(buffer.add_floats(a.rotations, 4, "VEC4", GlbBuffer::kNoTarget), nodes.head,
            "rotation");
  }
  nlohmann::json animation = {{"name", a.name}, {"samplers", samplers}, {"channels", channels}};
  for (const auto& e : a.extras) {
    const double scale = std::pow(10.0, e.decimals);
    nlohmann::json rows = nlohmann::json::array();
    const std::size_t width = e.columns.size();
    for (std::size_t f = 0; width > 0 && f < e.values.size() / width; ++f) {
      nlohmann::json row = nlohmann::json::array();
      for (std::size_t c = 0; c < width; ++c)
        row.push_back(std::round(double{e.values[f * width + c]} * scale) / scale);
      rows.push_back(std::move(row));
    }
    animation["extras"][e.key] = {
        {"description", e.description}, {"columns", e.columns}, {"values", std::move(rows)}};
  }
  gltf["animations"].push_back(std::move(animation));
}

}  // namespace fb
