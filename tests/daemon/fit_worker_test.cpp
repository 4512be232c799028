// The fit worker (firmware/daemon/fit_worker.hpp): jobs run in order on its own thread; at stop
// the running job finishes and every queued or later job is told it was not run, so whoever
// waits on one (a landmark correction's promise) is always answered.
#include <gtest/gtest.h>

#include <future>
#include <mutex>
#include <thread>
#include <vector>

#include "firmware/daemon/fit_worker.hpp"

namespace fb {
namespace {

struct Seen {
  std::mutex mutex;
  std::vector<std::pair<int, bool>> jobs;  // (id, run)
  std::vector<std::thread::id> threads;
  void add(int id, bool run) {
    std::lock_guard lock(mutex);
    jobs.emplace_back(id, run);
    threads.push_back(std::this_thread::get_id());
  }
};

TEST(FitWorker, RunsJobsInOrderOnItsOwnThread) {
  FitWorker worker;
  Seen seen;
  std::promise<void> last_ran;
  worker.post([&](bool run) { seen.add(1, run); });  // before start: kept in order
  worker.start();
  worker.post([&](bool run) { seen.add(2, run); });
  worker.post([&](bool run) {
    seen.add(3, run);
    last_ran.set_value();
  });
  last_ran.get_future().wait();
  worker.join();
  const std::vector<std::pair<int, bool>> want = {{1, true}, {2, true}, {3, true}};
  EXPECT_EQ(seen.jobs, want);
  for (const auto& t : seen.threads) EXPECT_NE(t, std::this_thread::get_id());
  EXPECT_EQ(seen.threads.front(), seen.threads.back());
}

TEST(FitWorker, StopFinishesTheRunningJobAndDiscardsTheQueuedOnes) {
  FitWorker worker;
  Seen seen;
  std::promise<void> started, release;
  auto release_future = release.get_future();
  worker.start();
  worker.post([&](bool run) {
    started.set_value();
    release_future.wait();
    seen.add(1, run);
  });
  started.get_future().wait();  // job 1 is running; 2 and 3 wait in the queue
  worker.post([&](bool run) { seen.add(2, run); });
  worker.post([&](bool run) { seen.add(3, run); });
  worker.request_stop();
  release.set_value();
  worker.join();
  const std::vector<std::pair<int, bool>> want = {{1, true}, {2, false}, {3, false}};
  EXPECT_EQ(seen.jobs, want);
}

TEST(FitWorker, JobsPostedAfterStopOrNeverStartedAreAnswered) {
  Seen seen;
  {
    FitWorker never_started;
    never_started.post([&](bool run) { seen.add(1, run); });
  }  // destroyed: the queued job learns it was not run
  FitWorker stopped;
  stopped.start();
  stopped.join();
  stopped.post([&](bool run) { seen.add(2, run); });  // answered at once, on this thread
  const std::vector<std::pair<int, bool>> want = {{1, false}, {2, false}};
  EXPECT_EQ(seen.jobs, want);
  ASSERT_EQ(seen.threads.size(), 2u);
  EXPECT_EQ(seen.threads[1], std::this_thread::get_id());
}

}  // namespace
}  // namespace fb
