#include "algo/fusion/fusion_maps.hpp"

#include <algorithm>

namespace fb {

FaceBox default_face_box(int width, int height) {
  const int w = width * 200 / 640, h = height * 240 / 480;
  FaceBox box;
  box.rect = PixelRect::from_size((width - w) / 2, (height - h) / 2, w, h);
  return box;
}

const char* to_string(TrackingState state) {
  switch (state) {
    case TrackingState::kNotStarted:
      return "not_started";
    case TrackingState::kStarted:
      return "started";
    case TrackingState::kTracking:
      return "tracking";
    case TrackingState::kLost:
      return "lost";
    case TrackingState::kRecovered:
      return "recovered";
    case TrackingState::kBadInput:
      return "bad_input";
  }
  return "unknown";
}

void MapLevel::allocate(const LevelIntrinsics& intrinsics, const PixelRect& face_rect) {
  k = intrinsics;
  box = face_rect.clipped(k.width, k.height);
  depth.resize(k.width, k.height);
  std::fill(depth.pixels.begin(), depth.pixels.end(), 0.0f);
  vertices.resize(k.width, k.height);
  std::fill(vertices.pixels.begin(), vertices.pixels.end(), Eigen::Vector3f::Zero());
  normals.resize(k.width, k.height);
  std::fill(normals.pixels.begin(), normals.pixels.end(), Eigen::Vector3f::Zero());
}

namespace {

// Zeroes `image` over `box` grown by one pixel (clipped to the image).
template <typename T>
void clear_box(Image<T>& image, const PixelRect& box, const T& zero) {
  if (image.empty()) return;
  const PixelRect b = box.grown(1).clipped(image.width, image.height);
  for (int y = b.y0; y < b.y1; ++y) std::fill_n(&image.at(b.x0, y), b.width(), zero);
}

}  // namespace

void MapLevel::move_box(const PixelRect& face_rect) {
  clear_box(depth, box, 0.0f);
  clear_box(vertices, box, Eigen::Vector3f(Eigen::Vector3f::Zero()));
  clear_box(normals, box, Eigen::Vector3f(Eigen::Vector3f::Zero()));
  box = face_rect.clipped(k.width, k.height);
}

void DepthPyramid::move_box(const PixelRect& face_rect) {
  clear_box(raw, levels[0].box, 0.0f);
  clear_box(fused, levels[0].box, 0.0f);
  for (int l = 0; l < kPyramidLevels; ++l) levels[l].move_box(face_rect.at_level(l));
}

void ModelView::move_box(const PixelRect& face_rect) {
  for (int j = 0; j < kPyramidLevels; ++j) levels[j].move_box(face_rect.at_level(first_level + j));
}

void DepthPyramid::allocate(const PinholeIntrinsics& intrinsics, const PixelRect& face_rect) {
  raw.resize(intrinsics.width, intrinsics.height);
  std::fill(raw.pixels.begin(), raw.pixels.end(), 0.0f);
  fused = raw;
  LevelIntrinsics k = LevelIntrinsics::from(intrinsics);
  for (int l = 0; l < kPyramidLevels; ++l) {
    levels[l].allocate(k, face_rect.at_level(l));
    k = k.averaged_half();
  }
  valid_pixels = 0;
}

void ModelView::allocate(const PinholeIntrinsics& intrinsics, const PixelRect& face_rect,
                         int first) {
  first_level = std::clamp(first, 0, kPyramidLevels - 1);
  LevelIntrinsics k = LevelIntrinsics::from(intrinsics);
  for (int l = 0; l < first_level; ++l) k = k.subsampled_half();
  for (int j = 0; j < kPyramidLevels; ++j) {
    levels[j].allocate(k, face_rect.at_level(first_level + j));
    k = k.subsampled_half();
  }
  valid = false;
}

}  // namespace fb
