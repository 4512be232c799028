// RecordState's names and the SessionRecords base class's answers for what a store does not
// keep. The SQLite store (store_records.cpp) overrides them all.
#include "firmware/daemon/session_records.hpp"

namespace fb {

const char* to_string(RecordState state) {
  switch (state) {
    case RecordState::kPending:
      return "pending";
    case RecordState::kCapturing:
      return "capturing";
    case RecordState::kRejected:
      return "rejected";
    case RecordState::kDone:
      return "done";
  }
  return "?";
}

namespace {
Error unsupported(const SessionRecords& r, const char* what) {
  return Error{"the '" + r.backend() + "' session store does not keep " + what +
               " (use storage/'s SQLite SessionStore)"};
}
}  // namespace

Result<void> SessionRecords::add_fit(std::int64_t, int, const FitRecord&) {
  return fail(unsupported(*this, "fitted meshes"));
}
Result<std::optional<MeshData>> SessionRecords::neutral_mesh(std::int64_t) {
  return std::optional<MeshData>{};
}
Result<void> SessionRecords::set_operator_landmarks(std::int64_t, int,
                                                    const std::vector<Landmark>&) {
  return fail(unsupported(*this, "landmark corrections"));
}
Result<std::int64_t> SessionRecords::add_take(const TakeRecord&, std::span<const float>) {
  return fail(unsupported(*this, "tracking takes"));
}
Result<OffloadInfo> SessionRecords::offload_info(std::int64_t) {
  return OffloadInfo{};
}
Result<std::int64_t> SessionRecords::add_rig(std::int64_t, const RigData&) {
  return fail(unsupported(*this, "rigs"));
}
Result<std::optional<StoredRig>> SessionRecords::subject_rig(std::int64_t) {
  return std::optional<StoredRig>{};
}

}  // namespace fb
