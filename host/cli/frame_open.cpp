#include "host/cli/frame_open.hpp"

#include <chrono>
#include <iostream>

#include "drivers/camera/common/calibrated_camera.hpp"

namespace fb::cli {

Result<std::unique_ptr<DepthCamera>> open_started_camera(const std::string& uri) {
  auto camera = open_camera(uri);
  if (!camera) return camera.failure();
  // A unit calibrated before (`camera self-calibrate --save`, `camera calibrate --save`)
  // starts from what was learned about it.
  const std::string key = calibration_key((*camera)->info());
  const auto store = CalibrationStore::user_default();
  auto stored = store.load(key);
  if (!stored) return stored.failure();
  if (stored->has_value()) {
    auto wrapped =
        CalibratedCamera::wrap(std::move(*camera), **stored, store.path_for(key).string());
    if (!wrapped) return wrapped.failure();
    std::cerr << "using the stored calibration of " << key << " (" << store.path_for(key).string()
              << ")\n";
    camera = std::unique_ptr<DepthCamera>(std::move(*wrapped));
  }
  if (auto started = (*camera)->start(); !started) {
    return fail("could not start camera '" + uri + "': " + started.error().message);
  }
  return camera;
}

Result<void> read_frame_at(DepthCamera& camera, long long index, RgbdFrame& frame) {
  constexpr auto kTimeout = std::chrono::milliseconds(2000);
  constexpr int kMaxTimeouts = 5;
  int timeouts = 0;
  for (long long read = 0; read <= index;) {
    auto status = camera.next_frame(frame, kTimeout);
    if (!status) return status.failure();
    if (*status == FrameStatus::kEndOfStream) {
      return fail("the camera ended after " + std::to_string(read) + " frames, before frame " +
                  std::to_string(index) + "; choose a smaller --frame");
    }
    if (*status == FrameStatus::kTimeout) {
      if (++timeouts >= kMaxTimeouts) {
        return fail("no frame arrived for " + std::to_string(kMaxTimeouts * 2) +
                    " s; check the camera is connected and streaming");
      }
      continue;
    }
    ++read;
  }
  return success();
}

}  // namespace fb::cli
