// Crash trials for the session store: a forked child writes captures in a loop and is killed
// with SIGKILL at random moments; after every kill the parent reopens the store and checks that
// it is intact, that every committed capture is complete and that the session resumes where it
// stopped. Used by the storage tests and by `facebooth-lab eval storage`.
#pragma once

#include <cstdint>
#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include "algo/core/result.hpp"
#include "storage/session_store.hpp"

namespace fb {

struct CrashTrialOptions {
  std::filesystem::path root;  // store folder; created, and reused across trials
  int trials = 30;
  std::uint64_t seed = 1;
  int guide_count = 20;  // captures per session
  // Size of each synthetic capture: enough bytes that kills land inside file writes too.
  int frames_per_capture = 4;
  int width = 160;
  int height = 120;
  // Kill delays are uniform in [0, max_kill_delay_ms]; 0 = from a calibration run (about three
  // capture commits plus the time to open the store).
  double max_kill_delay_ms = 0.0;
};

struct CrashTrialReport {
  int trials = 0;
  int survived = 0;                            // trials whose every check passed
  int killed = 0;                              // trials where SIGKILL hit a running child
  std::map<std::string, int> killed_in_phase;  // where the child was when killed
  int captures_committed = 0;                  // done captures in the store at the end
  int sessions_completed = 0;
  int orphans_removed = 0;  // data files the reopen cleaned up, over all trials
  int resumes_checked = 0;  // trials whose child started at the expected capture
  double max_kill_delay_ms = 0.0;
  double capture_commit_ms = 0.0;     // calibration: mean commit time of one trial capture
  std::vector<std::string> failures;  // one line per failed check
};

Result<CrashTrialReport> run_crash_trials(const CrashTrialOptions& options);

// Deterministic synthetic capture content for (session, index), so a reader can check every
// byte of what was committed.
CaptureInput make_test_capture(SessionId session, int index, int frames, int width, int height);
// Empty string when `data` is exactly make_test_capture(session, index, ...), else what differs.
std::string compare_test_capture(const CaptureData& data, SessionId session, int index, int frames,
                                 int width, int height);

}  // namespace fb
