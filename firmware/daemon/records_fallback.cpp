// Built when this build has no SQLite SessionStore: the plain-file store is the store.
#include "firmware/daemon/session_records.hpp"

namespace fb {

Result<std::unique_ptr<SessionRecords>> open_session_records(
    const std::filesystem::path& data_dir) {
  return open_file_records(data_dir);
}

}  // namespace fb
