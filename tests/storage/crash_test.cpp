// SIGKILL crash trials (sim/crash/crash_trials.hpp): a forked child commits captures in a loop and
// is killed at random moments; every reopen must find an intact store, complete committed
// captures, no half-written files, and the session resuming where it stopped.
#include <gtest/gtest.h>

#include "sim/crash/crash_trials.hpp"
#include "tests/storage/test_dir.hpp"

namespace fb {
namespace {

TEST(CrashSafety, SurvivesRandomSigkills) {
  test::ScratchDir dir;
  CrashTrialOptions options;
  options.root = dir.path() / "store";
  options.trials = 40;
  options.seed = 7;
  options.guide_count = 20;
  auto report = run_crash_trials(options);
  ASSERT_TRUE(report) << report.error().message;
  for (const auto& f : report->failures) ADD_FAILURE() << f;
  std::string phases;
  for (const auto& [phase, n] : report->killed_in_phase)
    phases += phase + "=" + std::to_string(n) + " ";
  std::cout << "crash trials: " << report->survived << "/" << report->trials << " survived, "
            << report->killed << " killed (" << phases << "), " << report->captures_committed
            << " captures committed, " << report->sessions_completed << " sessions completed, "
            << report->orphans_removed << " orphans removed, " << report->resumes_checked
            << " resumes checked, max kill delay " << report->max_kill_delay_ms << " ms\n";
  EXPECT_EQ(report->trials, 40);
  EXPECT_EQ(report->survived, 40);
  EXPECT_GE(report->killed, 38);  // a child can only exit early on an error, reported above
  EXPECT_GT(report->captures_committed, 0);
  EXPECT_GE(report->resumes_checked, 20);
  // Kills must land inside file writes, not only between captures.
  EXPECT_GE(report->killed_in_phase.size(), 3u);
  EXPECT_GT(report->killed_in_phase["writing_file"] + report->killed_in_phase["fsync_file"], 0);
}

}  // namespace
}  // namespace fb
