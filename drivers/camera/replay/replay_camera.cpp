// PLACEHOLDER until the replay backend lands.
#include "drivers/camera/replay/replay_camera.hpp"
namespace fb {
namespace {
Result<std::unique_ptr<DepthCamera>> open_replay(std::string_view) { return fail("replay: not built yet"); }
std::vector<CameraListing> list_replay() { return {}; }
}  // namespace
CameraBackend replay_camera_backend() { return {"replay", &open_replay, &list_replay, "replay:"}; }
}  // namespace fb
