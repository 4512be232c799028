// The one writer of tracking takes, for `facebooth track` and the device's tracking mode alike:
// frames go in as the tracker reports them (camera time, camera_from_model pose, weights) and
// the store gets one layout (see TakeData): times relative to the first frame, unit
// quaternions, one weight per named shape.
#pragma once

#include <optional>
#include <span>
#include <string>
#include <vector>

#include "algo/core/camera_model.hpp"
#include "algo/core/result.hpp"
#include "storage/session_store.hpp"

namespace fb {

class TakeWriter {
 public:
  TakeWriter(std::vector<std::string> shape_names, double fps);

  // Room for `frames` frames up front, so a real-time loop does not grow the buffers.
  void reserve(int frames);
  // Appends a frame at camera time `time_s` (any origin; stored relative to the first frame).
  // The rotation is normalised here, so every take holds unit quaternions. Fails when the
  // weights are not one per shape.
  Result<void> add_frame(double time_s, const RigidPose& camera_from_model,
                         std::span<const float> weights);
  int frame_count() const { return data_.info.frame_count; }
  const TakeData& data() const { return data_; }

  // Stores the take under `subject`, recording `session` (the session whose subject or rig was
  // tracked, when there is one). Returns the take's id.
  Result<TakeId> store(SessionStore& store, SubjectId subject, std::optional<SessionId> session);

 private:
  TakeData data_;
  double first_time_s_ = 0.0;
};

}  // namespace fb
