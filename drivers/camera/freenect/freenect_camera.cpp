// PLACEHOLDER until the freenect backend lands.
#include "drivers/camera/freenect/freenect_camera.hpp"
namespace fb {
namespace {
Result<std::unique_ptr<DepthCamera>> open_freenect(std::string_view) { return fail("freenect: not built yet"); }
std::vector<CameraListing> list_freenect() { return {}; }
}  // namespace
CameraBackend freenect_camera_backend() { return {"freenect", &open_freenect, &list_freenect, "freenect:"}; }
}  // namespace fb
