// A synthetic take rendered whole for the tracking tests: every frame's depth and truth.
#pragma once

#include <gtest/gtest.h>

#include <chrono>
#include <vector>

#include "sim/camera/synthetic_camera.hpp"
#include "tests/common/test_face_model.hpp"

namespace fb::test {

struct RenderedTake {
  std::vector<DepthImage> depth;
  std::vector<FrameTruth> truth;
  PinholeIntrinsics intrinsics;
};

// Renders every frame of `options` on the committed face model; a camera that cannot be made or
// started fails the calling test and gives what was rendered so far.
inline RenderedTake render(const SyntheticOptions& options) {
  RenderedTake out;
  auto camera = make_synthetic_camera(face_model(), options);
  EXPECT_TRUE(camera.ok()) << (camera.ok() ? "" : camera.error().message);
  if (!camera) return out;
  EXPECT_TRUE((*camera)->start().ok());
  out.intrinsics = (*camera)->info().depth_intrinsics;
  RgbdFrame frame;
  while (true) {
    auto status = (*camera)->next_frame(frame, std::chrono::milliseconds(100));
    if (!status || *status != FrameStatus::kFrame) break;
    out.depth.push_back(frame.depth_mm);
    out.truth.push_back(*frame_truth(**camera));
  }
  return out;
}

}  // namespace fb::test
