// PLACEHOLDER until the synthetic backend lands.
#include "drivers/camera/synthetic/synthetic_camera.hpp"
namespace fb {
namespace {
Result<std::unique_ptr<DepthCamera>> open_synthetic(std::string_view) { return fail("synthetic: not built yet"); }
std::vector<CameraListing> list_synthetic() { return {}; }
}  // namespace
CameraBackend synthetic_camera_backend() { return {"synthetic", &open_synthetic, &list_synthetic, "synthetic:"}; }
}  // namespace fb
