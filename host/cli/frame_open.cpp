#include "host/cli/frame_open.hpp"

#include <chrono>

namespace fb::cli {

Result<std::unique_ptr<DepthCamera>> open_started_camera(const std::string& uri) {
  auto camera = open_camera(uri);
  if (!camera) return camera.failure();
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
