#include "storage/export/synthetic_subject.hpp"

#include <algorithm>
#include <random>

namespace fb {

Result<SyntheticSubject> make_synthetic_subject(const FaceModel& model,
                                                const SyntheticSubjectOptions& options) {
  if (model.vertex_count == 0 || model.expression_count == 0) {
    return fail("the face model has no vertices or no expressions");
  }
  if (options.pose_count < 1) return fail("a synthetic subject needs at least one pose");
  SyntheticSubject s;
  std::mt19937_64 rng(options.seed);
  std::normal_distribution<float> normal(0.0f, options.identity_sigma);
  s.identity.resize(static_cast<std::size_t>(model.identity_count));
  for (auto& c : s.identity) c = normal(rng);

  const std::size_t n = static_cast<std::size_t>(model.vertex_count) * 3;
  s.rig.neutral.resize(n);
  model.evaluate(s.identity, {}, s.rig.neutral);
  s.rig.triangles = model.triangles;
  for (int j = 0; j < model.expression_count; ++j) {
    std::vector<float> shape(n);
    const auto delta = model.expression_shape(j);
    for (std::size_t i = 0; i < n; ++i) shape[i] = s.rig.neutral[i] + delta[i];
    s.rig.shapes.push_back(std::move(shape));
    s.rig.shape_names.push_back(model.expression_names[static_cast<std::size_t>(j)]);
  }

  // Pose 0 is the neutral; the others mix one to three expressions at known weights.
  std::uniform_int_distribution<int> pick(0, model.expression_count - 1);
  std::uniform_int_distribution<int> how_many(1, 3);
  std::uniform_real_distribution<float> weight(0.3f, 1.0f);
  for (int p = 0; p < options.pose_count; ++p) {
    std::vector<float> w(static_cast<std::size_t>(model.expression_count), 0.0f);
    std::string name = "neutral";
    if (p > 0) {
      name.clear();
      const int k = how_many(rng);
      for (int i = 0; i < k; ++i) {
        const int j = pick(rng);
        w[static_cast<std::size_t>(j)] = weight(rng);
        name += (name.empty() ? "" : "+") + model.expression_names[static_cast<std::size_t>(j)];
      }
    }
    MeshData mesh;
    mesh.positions.resize(n);
    model.evaluate_expressions(s.rig.neutral, w, mesh.positions);
    mesh.triangles = model.triangles;
    s.poses.push_back(std::move(mesh));
    s.pose_weights.push_back(std::move(w));
    s.pose_names.push_back(std::move(name));
  }
  return s;
}

Result<SessionId> store_synthetic_subject(SessionStore& store, const SyntheticSubject& subject,
                                          const std::string& name,
                                          const SyntheticCaptureOptions& capture) {
  auto subject_id = store.add_subject(name);
  if (!subject_id) return subject_id.failure();
  auto session = store.create_session(*subject_id, subject.pose_names);
  if (!session) return session.failure();
  for (int i = 0; i < static_cast<int>(subject.poses.size()); ++i) {
    if (auto r = store.begin_capture(*session, i); !r) return r.failure();
    CaptureInput input;
    for (int f = 0; f < capture.frames_per_capture; ++f) {
      RgbdFrame frame;
      frame.index = static_cast<std::uint64_t>(f);
      frame.depth_host_time_s = f / 30.0;
      frame.color_host_time_s = f / 30.0;
      frame.depth_mm.resize(capture.width, capture.height);
      frame.color.resize(capture.width, capture.height);
      for (int y = 0; y < capture.height; ++y) {
        for (int x = 0; x < capture.width; ++x) {
          frame.depth_mm.at(x, y) = static_cast<std::uint16_t>(600 + x + y + 10 * i);
          frame.color.at(x, y) = {static_cast<std::uint8_t>(x * 255 / capture.width),
                                  static_cast<std::uint8_t>(y * 255 / capture.height),
                                  static_cast<std::uint8_t>((i * 12 + f * 40) & 0xff)};
        }
      }
      input.frames.push_back(std::move(frame));
    }
    input.fused_depth = input.frames.front().depth_mm;
    for (int k = 0; k < 68; ++k) {
      input.landmarks.push_back({static_cast<float>(capture.width / 4 + k % 17 * 4),
                                 static_cast<float>(capture.height / 4 + k / 17 * 10)});
    }
    input.qa_scores = {{"synthetic", 1.0}};
    if (auto r = store.commit_capture(*session, i, input); !r) return r.failure();
    if (auto r = store.add_mesh(*session, i, i == 0 ? MeshRole::kNeutral : MeshRole::kFitted,
                                subject.pose_names[static_cast<std::size_t>(i)],
                                subject.poses[static_cast<std::size_t>(i)]);
        !r) {
      return r.failure();
    }
  }
  if (auto r = store.add_rig(*subject_id, *session, subject.rig); !r) return r.failure();
  return *session;
}

}  // namespace fb
