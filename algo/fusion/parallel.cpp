#include "algo/fusion/parallel.hpp"

namespace fb {

ParallelRunner::ParallelRunner(int threads) {
  for (int part = 1; part < threads; ++part) {
    workers_.emplace_back([this, part] { worker_loop(part); });
  }
}

ParallelRunner::~ParallelRunner() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stop_ = true;
  }
  start_cv_.notify_all();
  for (auto& worker : workers_) worker.join();
}

void ParallelRunner::dispatch(Fn fn, const void* ctx) {
  const int parts = this->parts();
  {
    std::lock_guard<std::mutex> lock(mutex_);
    fn_ = fn;
    ctx_ = ctx;
    pending_ = parts - 1;
    ++generation_;
  }
  start_cv_.notify_all();
  fn(ctx, 0, parts);
  std::unique_lock<std::mutex> lock(mutex_);
  done_cv_.wait(lock, [this] { return pending_ == 0; });
}

void ParallelRunner::worker_loop(int part) {
  unsigned long seen = 0;
  for (;;) {
    Fn fn;
    const void* ctx;
    {
      std::unique_lock<std::mutex> lock(mutex_);
      start_cv_.wait(lock, [&] { return stop_ || generation_ != seen; });
      if (stop_) return;
      seen = generation_;
      fn = fn_;
      ctx = ctx_;
    }
    fn(ctx, part, parts());
    {
      std::lock_guard<std::mutex> lock(mutex_);
      --pending_;
    }
    done_cv_.notify_one();
  }
}

}  // namespace fb
