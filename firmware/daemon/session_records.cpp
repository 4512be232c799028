// RecordState's names (the one store, store_records.cpp, implements SessionRecords).
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

}  // namespace fb
