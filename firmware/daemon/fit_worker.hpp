// Private: the fit worker, one thread that runs the daemon's jobs after a take (landmarks, quick
// fit, QA, the commit; the operator's landmark corrections) one at a time and in order, so a fit
// never blocks the take's frame loop or the HTTP threads. It owns its thread, its queue and the
// lock that guards them; what the jobs touch is theirs to guard (daemon_pipeline.cpp).
#pragma once

#include <condition_variable>
#include <deque>
#include <functional>
#include <mutex>
#include <thread>

namespace fb {

class FitWorker {
 public:
  // run = false: the job is discarded (the worker is stopping); it must answer whoever waits
  // for it (a promise) and do nothing else.
  using Job = std::function<void(bool run)>;

  FitWorker() = default;
  ~FitWorker() { join(); }
  FitWorker(const FitWorker&) = delete;
  FitWorker& operator=(const FitWorker&) = delete;

  // Starts the thread (at the background priority: the frame loop comes first). Jobs posted
  // before run then in order.
  void start();
  // Queues a job. Once stopping, the job is discarded at once (called with run = false on the
  // caller's thread).
  void post(Job job);
  // Any thread: the worker finishes the job it runs, discards the queued ones and ends.
  void request_stop();
  // request_stop(), then waits for the thread (a no-op when it never started: the queued jobs
  // are discarded here).
  void join();

 private:
  void loop();

  std::mutex mutex_;
  std::condition_variable cv_;
  std::deque<Job> jobs_;   // guarded by mutex_
  bool stopping_ = false;  // guarded by mutex_
  std::thread thread_;
};

}  // namespace fb
