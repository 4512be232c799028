// Shared by the photo tests: a bootstrap bilinear model with every expression knob, and a
// textured synthetic face (frontal, static) rendered neutral and with an expression, with the
// true landmarks of each render.
#pragma once

#include <array>
#include <vector>

#include <gtest/gtest.h>

#include "algo/bilinear/bootstrap.hpp"
#include "algo/tracking/arkit.hpp"
#include "sim/camera/synthetic_camera.hpp"
#include "sim/camera/world_presets.hpp"
#include "storage/asset_files.hpp"

namespace fb::test {

inline const FaceModel& photo_face_model() {
  static const FaceModel m = [] {
    auto r = load_face_model();
    EXPECT_TRUE(r.ok());
    return r.ok() ? std::move(*r) : FaceModel{};
  }();
  return m;
}

// 80 identities, 40 x 54 knobs: every expression shape exact (eq. 17 reproduces the deltas).
inline const BilinearModel& photo_model() {
  static const BilinearModel m = [] {
    const auto ids = draw_identities(photo_face_model(), 80, 3);
    const FactoredTensor t = bootstrap_tensor(photo_face_model(), ids);
    auto f = mode_factors(t);
    EXPECT_TRUE(f.ok());
    auto tr = truncate(t, *f, 40, 54);
    EXPECT_TRUE(tr.ok());
    return make_bilinear_model(*tr, photo_face_model(),
                               bootstrap_expression_names(photo_face_model()), "{}");
  }();
  return m;
}

struct Render {
  std::vector<ColorImage> frames;
  std::vector<std::array<Eigen::Vector2d, 68>> truth;
};

// One frame per weight vector (face model expression weights), subject `seed`, textured.
inline Render render_faces(std::uint64_t seed, const std::vector<std::vector<float>>& weights) {
  SyntheticOptions so;
  so.seed = seed;
  so.motion = SyntheticMotion::kStatic;
  so.frame_count = static_cast<int>(weights.size());
  so.distance_mm = 550;
  so.sensor.depth_noise = false;
  EXPECT_TRUE(apply_world_preset("texture", seed, so).ok());
  so.expression_track = weights;
  auto camera = make_synthetic_camera(photo_face_model(), so);
  EXPECT_TRUE(camera.ok());
  EXPECT_TRUE((*camera)->start().ok());
  Render out;
  RgbdFrame frame;
  for (std::size_t f = 0; f < weights.size(); ++f) {
    auto st = (*camera)->next_frame(frame, std::chrono::milliseconds(1000));
    EXPECT_TRUE(st.ok());
    out.frames.push_back(frame.color);
    std::array<Eigen::Vector2d, 68> t;
    const auto& l = (*camera)->truth()->landmarks_color_px;
    std::copy(l.begin(), l.end(), t.begin());
    out.truth.push_back(t);
  }
  return out;
}

// Face model weights from ARKit curves by the project's mapping.
inline std::vector<float> model_weights(const std::array<float, kArkitShapeCount>& arkit) {
  auto mapping = make_arkit_mapping(photo_face_model());
  EXPECT_TRUE(mapping.ok());
  std::vector<float> w(photo_face_model().expression_names.size(), 0.0f);
  mapping->to_model(arkit, w);
  return w;
}

inline std::array<float, kArkitShapeCount> arkit_curves(
    std::initializer_list<std::pair<std::string_view, float>> values) {
  std::array<float, kArkitShapeCount> a{};
  for (const auto& [name, v] : values) {
    const auto it = std::find(kArkitNames.begin(), kArkitNames.end(), name);
    EXPECT_NE(it, kArkitNames.end()) << name;
    a[static_cast<std::size_t>(it - kArkitNames.begin())] = v;
  }
  return a;
}

}  // namespace fb::test
