// "One rule, one place" (issue 36): each helper below is defined once in the tree. The test reads
// the sources (FB_SOURCE_DIR) and lists every other definition it finds, so a copy pasted back
// in fails here with its file name. Tests are not scanned (they may time things their own way).
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <regex>
#include <set>
#include <sstream>
#include <string>
#include <vector>

namespace fb {
namespace {

namespace fs = std::filesystem;

// Files (relative to the source root) under the product folders whose text matches `pattern`.
std::vector<std::string> files_matching(const std::regex& pattern) {
  std::vector<std::string> out;
  const fs::path root(FB_SOURCE_DIR);
  for (const char* top : {"algo", "drivers", "storage", "firmware", "host", "bench"}) {
    for (const auto& e : fs::recursive_directory_iterator(root / top)) {
      const auto ext = e.path().extension();
      if (!e.is_regular_file() || (ext != ".cpp" && ext != ".hpp" && ext != ".h")) continue;
      std::ifstream in(e.path());
      std::stringstream text;
      text << in.rdbuf();
      if (std::regex_search(text.str(), pattern))
        out.push_back(fs::relative(e.path(), root).generic_string());
    }
  }
  std::sort(out.begin(), out.end());
  return out;
}

std::string joined(const std::vector<std::string>& v) {
  std::string s;
  for (const auto& x : v) s += x + " ";
  return s;
}

// Copies kept on purpose until their owner's step lands (named, so the list only shrinks).
const std::set<std::string> kPendingElsewhere = {};

std::vector<std::string> without_pending(std::vector<std::string> v) {
  std::erase_if(v, [](const std::string& f) { return kPendingElsewhere.count(f) > 0; });
  return v;
}

TEST(OnePlace, MsSinceIsDefinedOnlyInTheClockHeader) {
  const auto found = without_pending(files_matching(std::regex(R"(double\s+ms_since\s*\()")));
  EXPECT_EQ(found, std::vector<std::string>{"algo/core/clock.hpp"}) << joined(found);
}

// Durable writes (temp file, fsync, rename, directory fsync) live in storage/durable_file. The
// camera recorder's dump (drivers/) syncs its own entries: drivers sit below storage and may
// not include it.
TEST(OnePlace, DurableWritesAreStorageDurableFile) {
  const auto found = files_matching(std::regex(R"(::fsync\s*\()"));
  EXPECT_EQ(found, (std::vector<std::string>{"drivers/camera/common/fakenect_dump.cpp",
                                             "storage/durable_file.cpp"}))
      << joined(found);
}

// The frame record (header + depth + disparity + colour) is encoded in one place for the
// store's .fbseq files and the device's spool.
TEST(OnePlace, OneFrameRecordCodec) {
  const auto found = files_matching(std::regex(R"(int32_t\s+depth_w)"));
  EXPECT_EQ(found, std::vector<std::string>{"storage/frame_record.hpp"}) << joined(found);
}

// Which rig serves a session is decided by SessionStore::rig_for; callers do not walk the
// subject's rig list to choose one themselves.
TEST(OnePlace, RigChoiceIsSessionStoreRigFor) {
  const auto found = files_matching(std::regex(R"(\.rigs\s*\()"));
  // The device's offload count of a session's rigs reads the list without choosing from it.
  const std::set<std::string> allowed = {"firmware/daemon/store_records.cpp"};
  std::vector<std::string> choosing;
  for (const auto& f : found)
    if (!allowed.count(f)) choosing.push_back(f);
  EXPECT_TRUE(choosing.empty()) << joined(choosing);
}

// Takes are written through storage's TakeWriter only: nothing else hands frames to
// SessionStore::add_take (the device reaches the writer through SessionRecords).
TEST(OnePlace, TakesAreWrittenByTakeWriter) {
  const auto found = files_matching(std::regex(R"(\bstore_?(\.|->)add_take\s*\()"));
  EXPECT_EQ(found, std::vector<std::string>{"storage/take_writer.cpp"}) << joined(found);
}

}  // namespace
}  // namespace fb
