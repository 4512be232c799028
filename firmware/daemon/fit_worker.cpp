#include "firmware/daemon/fit_worker.hpp"

#include "firmware/daemon/daemon_impl.hpp"

namespace fb {

void FitWorker::start() {
  if (thread_.joinable()) return;
  thread_ = std::thread([this] {
    run_in_background();
    loop();
  });
}

void FitWorker::post(Job job) {
  {
    std::lock_guard lock(mutex_);
    if (!stopping_) {
      jobs_.push_back(std::move(job));
      cv_.notify_all();
      return;
    }
  }
  job(false);
}

void FitWorker::request_stop() {
  {
    std::lock_guard lock(mutex_);
    stopping_ = true;
  }
  cv_.notify_all();
}

void FitWorker::join() {
  request_stop();
  if (thread_.joinable()) thread_.join();
  // Never started, or jobs posted while the last one ran: each learns it was not run.
  std::deque<Job> left;
  {
    std::lock_guard lock(mutex_);
    left.swap(jobs_);
  }
  for (auto& j : left) j(false);
}

void FitWorker::loop() {
  while (true) {
    Job job;
    {
      std::unique_lock lock(mutex_);
      cv_.wait(lock, [&] { return !jobs_.empty() || stopping_; });
      if (stopping_) {
        // Discard what is queued (each job learns it was not run: promises are answered).
        auto jobs = std::move(jobs_);
        jobs_.clear();
        lock.unlock();
        for (auto& j : jobs) j(false);
        return;
      }
      job = std::move(jobs_.front());
      jobs_.pop_front();
    }
    job(true);
  }
}

}  // namespace fb
