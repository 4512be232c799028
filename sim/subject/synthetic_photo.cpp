#include "sim/subject/synthetic_photo.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>

#include "sim/camera/synthetic_camera.hpp"

namespace fb {

namespace {

struct Frame {
  ColorImage color;
  Landmarks68 points{};
};

Result<Frame> render_frame(const FaceModel& model, const PhotoSpec& spec,
                           const std::vector<float>& weights) {
  SyntheticOptions o;
  o.seed = spec.subject;
  o.motion = SyntheticMotion::kStatic;
  o.frame_count = 1;
  o.distance_mm = spec.distance_mm;
  o.sensor.depth_noise = false;
  o.world.texture = true;
  o.world.seed = spec.subject;
  o.expression_weights = weights;
  auto camera = make_synthetic_camera(model, o);
  if (!camera) return camera.failure();
  if (auto ok = (*camera)->start(); !ok) return ok.failure();
  RgbdFrame frame;
  if (auto st = (*camera)->next_frame(frame, std::chrono::milliseconds(0)); !st)
    return st.failure();
  const FrameTruth* truth = (*camera)->truth();
  if (truth == nullptr || truth->landmarks_color_px.size() != 68)
    return fail("synthetic photo: the camera gave no landmark truth");
  Frame f;
  f.color = std::move(frame.color);
  for (std::size_t k = 0; k < 68; ++k) f.points[k] = truth->landmarks_color_px[k];
  return f;
}

}  // namespace

Result<FacePhoto> render_photo(const FaceModel& model, const PhotoSpec& spec) {
  auto neutral = render_frame(model, spec, {});
  if (!neutral) return neutral.failure();
  const bool expressive =
      std::any_of(spec.expression_weights.begin(), spec.expression_weights.end(),
                  [](float w) { return w != 0; });
  Frame f = std::move(*neutral);
  Eigen::Vector2d c = Eigen::Vector2d::Zero();
  for (const auto& p : f.points) c += p;
  c /= 68.0;
  if (expressive) {
    auto e = render_frame(model, spec, spec.expression_weights);
    if (!e) return e.failure();
    f = std::move(*e);
  }
  const int w = spec.width, h = spec.height;
  if (w > f.color.width || h > f.color.height)
    return fail("synthetic photo: the crop is larger than the colour frame");
  // The face a little below the crop's centre: room for the forehead.
  const int x0 = std::clamp(static_cast<int>(std::lround(c.x() - w / 2.0)), 0, f.color.width - w);
  const int y0 = std::clamp(static_cast<int>(std::lround(c.y() - 0.55 * h)), 0, f.color.height - h);
  FacePhoto photo;
  photo.image.resize(w, h);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) photo.image.at(x, y) = f.color.at(x0 + x, y0 + y);
  for (std::size_t k = 0; k < 68; ++k) photo.points[k] = f.points[k] - Eigen::Vector2d(x0, y0);
  return photo;
}

std::vector<std::pair<std::string, std::vector<float>>> photo_expressions(const FaceModel& model) {
  const std::vector<std::pair<std::string, std::string>> recipes = {
      {"smile", "mouthSmile_L+mouthSmile_R+cheekSquint_L:0.5+cheekSquint_R:0.5"},
      {"jaw_open_brows_up",
       "jawOpen:0.6+browInnerUp_L+browInnerUp_R+browOuterUp_L:0.6+"
       "browOuterUp_R:0.6"},
      {"frown_blink", "browDown_L+browDown_R+eyeBlink_L+eyeBlink_R+mouthFrown_L+mouthFrown_R"},
      {"pucker", "mouthPucker+mouthFunnel:0.5+noseSneer_L:0.5+noseSneer_R:0.5"}};
  std::vector<std::pair<std::string, std::vector<float>>> out;
  for (const auto& [name, spec] : recipes) {
    auto w = parse_expression_spec(spec, model);
    if (w) out.emplace_back(name, std::move(*w));
  }
  return out;
}

}  // namespace fb
