#include "sim/subject/retarget_case.hpp"

#include <array>

#include "algo/tracking/arkit.hpp"
#include "sim/camera/expressive_track.hpp"
#include "sim/subject/synthetic_rigs.hpp"
#include "storage/take_writer.hpp"

namespace fb {

Result<RetargetCase> make_retarget_case(const std::filesystem::path& dir, const FaceModel& model,
                                        int frames) {
  auto recipe = expressive_track(model, frames);
  return make_retarget_case(dir, model, recipe, recipe);
}

Result<RetargetCase> make_retarget_case(const std::filesystem::path& dir, const FaceModel& model,
                                        std::vector<std::vector<float>> truth,
                                        const std::vector<std::vector<float>>& take) {
  if (truth.size() != take.size()) return fail("retarget case: truth and take lengths differ");
  auto store = SessionStore::open(dir);
  if (!store) return store.failure();
  if (auto ok = add_synthetic_rig_subject(*store, model, "A", 1); !ok) return ok.failure();
  if (auto ok = add_synthetic_rig_subject(*store, model, "B", 2); !ok) return ok.failure();
  auto subjects = store->subjects();
  if (!subjects) return subjects.failure();
  RetargetCase c;
  for (const auto& s : *subjects) (s.name == "A" ? c.performer : c.target) = s.id;
  auto mapping = make_arkit_mapping(model);
  if (!mapping) return mapping.failure();
  c.weights = std::move(truth);
  TakeWriter writer(std::vector<std::string>(kArkitNames.begin(), kArkitNames.end()), 30.0);
  std::array<float, kArkitShapeCount> arkit{};
  const auto fitting = static_cast<std::size_t>(model.fitting_expression_count);
  for (std::size_t f = 0; f < take.size(); ++f) {
    c.weights[f].resize(fitting, 0.0f);
    std::vector<float> w = take[f];
    w.resize(fitting, 0.0f);
    mapping->to_arkit(w, arkit);
    RigidPose pose;
    pose.translation = Eigen::Vector3d(0, 0, 700);
    if (auto ok = writer.add_frame(static_cast<double>(f) / 30.0, pose, arkit); !ok)
      return ok.failure();
  }
  auto stored = writer.store(*store, c.performer, std::nullopt);
  if (!stored) return stored.failure();
  c.take = *stored;
  auto rig = store->newest_rig(c.target);
  if (!rig) return rig.failure();
  if (!*rig) return fail("retarget case: subject B has no rig");
  auto data = store->read_rig((*rig)->id);
  if (!data) return data.failure();
  c.target_rig = std::move(*data);
  return c;
}

std::vector<float> retarget_truth(const RetargetCase& c, const FaceModel& model, int f) {
  const RigData& rig = c.target_rig;
  const auto& w = c.weights[static_cast<std::size_t>(f)];
  std::vector<float> mesh = rig.neutral;
  for (std::size_t j = 0; j < rig.shapes.size(); ++j) {
    const int m = model.expression_index(rig.shape_names[j]);
    if (m < 0 || m >= static_cast<int>(w.size()) || w[static_cast<std::size_t>(m)] == 0.0f)
      continue;
    const float wj = w[static_cast<std::size_t>(m)];
    for (std::size_t i = 0; i < mesh.size(); ++i)
      mesh[i] += wj * (rig.shapes[j][i] - rig.neutral[i]);
  }
  return mesh;
}

}  // namespace fb
