#include "sim/camera/frame_truth.hpp"

#include "drivers/camera/common/calibrated_camera.hpp"

namespace fb {

const FrameTruth* frame_truth(const DepthCamera& camera) {
  if (const auto* source = dynamic_cast<const GroundTruthCamera*>(&camera)) return source->truth();
  if (const auto* wrapped = dynamic_cast<const CalibratedCamera*>(&camera))
    return frame_truth(wrapped->inner());
  return nullptr;
}

}  // namespace fb
