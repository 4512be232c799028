#include "sim/subject/synthetic_rigs.hpp"

#include <random>
#include <vector>

namespace fb {

RigData synthetic_rig(const FaceModel& model, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<float> n(0, 1);
  std::uniform_real_distribution<float> amp(0.6f, 1.4f);
  std::vector<float> id(static_cast<std::size_t>(model.identity_count));
  for (auto& c : id) c = n(rng);
  RigData r;
  r.neutral.resize(static_cast<std::size_t>(model.vertex_count) * 3);
  model.evaluate(id, {}, r.neutral);
  for (int j = 0; j < model.fitting_expression_count; ++j) {
    const float a = amp(rng);
    const auto delta = model.expression_shape(j);
    std::vector<float> s(r.neutral.size());
    for (std::size_t k = 0; k < s.size(); ++k) s[k] = r.neutral[k] + a * delta[k];
    r.shapes.push_back(std::move(s));
    r.shape_names.push_back(model.expression_names[static_cast<std::size_t>(j)]);
  }
  r.triangles = model.triangles;
  return r;
}

Result<void> add_synthetic_rig_subject(SessionStore& store, const FaceModel& model,
                                       const std::string& name, std::uint64_t seed) {
  auto subject = store.add_subject(name);
  if (!subject) return subject.failure();
  auto session = store.create_session(*subject, {"neutral"});
  if (!session) return session.failure();
  if (auto r = store.add_rig(*subject, *session, synthetic_rig(model, seed)); !r)
    return r.failure();
  return success();
}

}  // namespace fb
