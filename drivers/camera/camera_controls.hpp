// Camera controls, as libcamera has them: named values an application sets on a camera instead
// of editing its URI. A backend lists the controls it accepts (CameraBackend::controls); they
// are applied when the camera is opened (open_camera(uri, controls)) and override what the URI
// says. The synthetic camera (sim/camera) takes `expression`, `motion` and `frames`, which is how
// faceboothd asks it for a take of the guide's expression.
#pragma once

#include <string>
#include <string_view>
#include <vector>

namespace fb {

struct CameraControl {
  std::string name;   // e.g. "expression"
  std::string value;  // e.g. "jawOpen:0.6+mouthSmile_L"
};
using CameraControls = std::vector<CameraControl>;

struct FaceModel;  // algo/facemodel/face_model.hpp

// What the application lends a camera at open, as libcamera's pipeline hands its IPA module the
// tuning data: a rendering camera uses the caller's face model instead of loading its own copy
// (21 MB; faceboothd lends its fitter's for every take). Must outlive the camera. Backends
// that need none ignore it.
struct CameraResources {
  const FaceModel* face_model = nullptr;
};

// Control names of the synthetic camera (sim/camera/synthetic_camera.hpp documents the values).
inline constexpr std::string_view kControlExpression = "expression";  // `expr=` syntax
inline constexpr std::string_view kControlMotion = "motion";          // headturn | static
inline constexpr std::string_view kControlFrames = "frames";          // take length
// "1": frames arrive on the sensor's clock (a late reader loses frames, as with a real sensor).
inline constexpr std::string_view kControlRealtime = "realtime";

}  // namespace fb
