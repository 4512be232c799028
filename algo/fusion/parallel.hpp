// A tiny fork-join helper owned by the fusion engine: `threads - 1` persistent workers, and
// run(f) calls f(part, parts) once per part (part 0 on the calling thread). No allocation per
// call: the callable is passed by pointer. With threads == 1 it is a plain call.
#pragma once

#include <condition_variable>
#include <mutex>
#include <thread>
#include <vector>

namespace fb {

class ParallelRunner {
 public:
  explicit ParallelRunner(int threads = 1);
  ~ParallelRunner();
  ParallelRunner(const ParallelRunner&) = delete;
  ParallelRunner& operator=(const ParallelRunner&) = delete;

  int parts() const { return static_cast<int>(workers_.size()) + 1; }

  template <class F>
  void run(const F& f) {
    if (workers_.empty()) {
      f(0, 1);
      return;
    }
    dispatch(&invoke<F>, &f);
  }

  // Splits [begin, end) into `parts` contiguous ranges; returns part `part`.
  static void split(int begin, int end, int part, int parts, int& out_begin, int& out_end) {
    const int n = end - begin;
    out_begin = begin + n * part / parts;
    out_end = begin + n * (part + 1) / parts;
  }

 private:
  using Fn = void (*)(const void*, int, int);
  template <class F>
  static void invoke(const void* f, int part, int parts) {
    (*static_cast<const F*>(f))(part, parts);
  }
  void dispatch(Fn fn, const void* ctx);
  void worker_loop(int part);

  std::vector<std::thread> workers_;
  std::mutex mutex_;
  std::condition_variable start_cv_;
  std::condition_variable done_cv_;
  Fn fn_ = nullptr;
  const void* ctx_ = nullptr;
  unsigned long generation_ = 0;
  int pending_ = 0;
  bool stop_ = false;
};

}  // namespace fb
