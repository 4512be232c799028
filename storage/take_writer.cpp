#include "storage/take_writer.hpp"

namespace fb {

TakeWriter::TakeWriter(std::vector<std::string> shape_names, double fps) {
  data_.info.shape_names = std::move(shape_names);
  data_.info.fps = fps > 0 ? fps : 30.0;  // a camera that does not say: the tracker's rate
}

void TakeWriter::reserve(int frames) {
  const auto n = static_cast<std::size_t>(std::max(frames, 0));
  data_.times_s.reserve(n);
  data_.values.reserve(n * static_cast<std::size_t>(data_.info.stride()));
}

Result<void> TakeWriter::add_frame(double time_s, const RigidPose& camera_from_model,
                                   std::span<const float> weights) {
  if (weights.size() != data_.info.shape_names.size())
    return fail("a take frame has " + std::to_string(weights.size()) + " weights for " +
                std::to_string(data_.info.shape_names.size()) + " shapes");
  if (data_.info.frame_count == 0) first_time_s_ = time_s;
  const Eigen::Quaterniond q = camera_from_model.rotation.normalized();
  const Eigen::Vector3d& t = camera_from_model.translation;
  const float pose[kTakePoseValues] = {static_cast<float>(t.x()), static_cast<float>(t.y()),
                                       static_cast<float>(t.z()), static_cast<float>(q.x()),
                                       static_cast<float>(q.y()), static_cast<float>(q.z()),
                                       static_cast<float>(q.w())};
  data_.values.insert(data_.values.end(), pose, pose + kTakePoseValues);
  data_.values.insert(data_.values.end(), weights.begin(), weights.end());
  data_.times_s.push_back(time_s - first_time_s_);
  ++data_.info.frame_count;
  return success();
}

Result<TakeId> TakeWriter::store(SessionStore& store, SubjectId subject,
                                 std::optional<SessionId> session) {
  // No copy: a device take can be tens of megabytes.
  data_.info.subject = subject;
  data_.info.session = session;
  return store.add_take(data_);
}

}  // namespace fb
