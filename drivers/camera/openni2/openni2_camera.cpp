// PLACEHOLDER until the openni2 backend lands.
#include "drivers/camera/openni2/openni2_camera.hpp"
namespace fb {
namespace {
Result<std::unique_ptr<DepthCamera>> open_openni2(std::string_view) { return fail("openni2: not built yet"); }
std::vector<CameraListing> list_openni2() { return {}; }
}  // namespace
CameraBackend openni2_camera_backend() { return {"openni2", &open_openni2, &list_openni2, "openni2:"}; }
}  // namespace fb
