#include "sim/camera/render_ahead.hpp"

#include <algorithm>
#include <cmath>
#include <string>

namespace fb {

Result<std::unique_ptr<RenderAhead>> RenderAhead::start(const RenderAheadOptions& options,
                                                        RenderFn render) {
  if (options.frame_count <= 0)
    return fail("render ahead: the stream needs at least one frame (frame_count " +
                std::to_string(options.frame_count) + ")");
  if (!(options.fps > 0.0 && options.fps <= 1000.0))
    return fail("render ahead: the sensor rate must be in (0, 1000] frames/s");
  if (options.queue_frames < 1 || options.max_slots < 2 || options.safety < 1.0)
    return fail("render ahead: queue_frames >= 1, max_slots >= 2 and safety >= 1 are needed");
  if (!render) return fail("render ahead: no render function");
  std::unique_ptr<RenderAhead> out(new RenderAhead(options, std::move(render)));
  out->thread_ = std::thread([self = out.get()] { self->run(); });
  return out;
}

RenderAhead::RenderAhead(const RenderAheadOptions& options, RenderFn render)
    : options_(options), render_(std::move(render)), period_(1.0 / options.fps) {
  // Slots are sized by the renderer on first use; this only reserves their bookkeeping.
  slots_.resize(
      static_cast<std::size_t>(std::min<long long>(options_.max_slots, options_.frame_count)));
  stats_.slots = static_cast<int>(slots_.size());
}

RenderAhead::~RenderAhead() {
  {
    std::lock_guard lock(mutex_);
    stopping_ = true;
  }
  changed_.notify_all();
  if (thread_.joinable()) thread_.join();
}

// Frame k >= R (R rendered so far) is ready at now + (k - R + 1) r and arrives at t0 + k P with
// t0 = now. Both sides are linear in k, so checking the first and the last frame suffices.
bool RenderAhead::lead_reached(long long rendered, double render_ms) const {
  const double r = render_ms * options_.safety;
  const double p = period_.count() * 1000.0;
  const long long n = options_.frame_count;
  return r <= static_cast<double>(rendered) * p &&
         static_cast<double>(n - rendered) * r <= static_cast<double>(n - 1) * p;
}

long long RenderAhead::arrived_by(Clock::time_point now) const {
  if (!clock_started_ || now < t0_) return -1;
  const auto k = static_cast<long long>(std::floor((now - t0_) / period_));
  return std::min(k, options_.frame_count - 1);
}

void RenderAhead::run() {
  const auto k = static_cast<long long>(slots_.size());
  for (long long i = 0; i < options_.frame_count; ++i) {
    {
      std::unique_lock lock(mutex_);
      changed_.wait(lock, [&] { return stopping_ || i - next_ < k; });
      if (stopping_) return;
    }
    // Slot i % k is neither being read (the consumer reads slot next_ % k, and i < next_ + k)
    // nor will be until rendered_ passes i.
    Slot& slot = slots_[static_cast<std::size_t>(i % k)];
    const auto t = Clock::now();
    auto ok = render_(static_cast<std::uint64_t>(i), slot.frame, slot.truth);
    const auto now = Clock::now();
    {
      std::lock_guard lock(mutex_);
      if (!ok) {
        failed_ = true;
        error_ = ok.error();
      } else {
        rendered_ = i + 1;
        render_ms_total_ += std::chrono::duration<double, std::milli>(now - t).count();
        stats_.rendered = rendered_;
        stats_.render_ms_mean = render_ms_total_ / static_cast<double>(rendered_);
        if (!clock_started_) {
          // One frame's time says little (cold caches); decide from two on.
          const bool enough = (rendered_ >= 2 && lead_reached(rendered_, stats_.render_ms_mean)) ||
                              rendered_ == options_.frame_count || rendered_ - next_ >= k;
          if (enough) {
            clock_started_ = true;
            t0_ = now;
            stats_.lead_frames = static_cast<int>(rendered_);
          }
        } else if (now > t0_ + std::chrono::duration_cast<Clock::duration>(static_cast<double>(i) *
                                                                           period_)) {
          ++stats_.late;
        }
      }
    }
    changed_.notify_all();
    if (!ok) return;
  }
}

Result<FrameStatus> RenderAhead::next(RgbdFrame& frame, FrameTruth& truth,
                                      std::chrono::milliseconds timeout) {
  std::unique_lock lock(mutex_);
  const auto deadline = Clock::now() + timeout;
  const long long n = options_.frame_count;
  while (true) {
    if (failed_) return fail(error_);
    if (next_ >= n) return FrameStatus::kEndOfStream;
    const auto now = Clock::now();
    // A frame is there once its sensor time has come and it is rendered: a late renderer
    // delays frames, it never makes the reader lose them.
    const long long arrived = std::min(arrived_by(now), rendered_ - 1);
    if (arrived - next_ + 1 > options_.queue_frames) {
      // The driver kept only the newest queue_frames: the older ones were overwritten.
      const long long skip = arrived - options_.queue_frames + 1 - next_;
      next_ += skip;
      stats_.overwritten += skip;
      changed_.notify_all();
    }
    if (arrived >= next_ && rendered_ > next_) break;
    if (now >= deadline) return FrameStatus::kTimeout;
    auto wake = deadline;
    if (clock_started_ && rendered_ > next_)
      wake = std::min(wake, t0_ + std::chrono::duration_cast<Clock::duration>(
                                      static_cast<double>(next_) * period_));
    changed_.wait_until(lock, wake);
  }
  // The renderer does not touch slot next_ % k until next_ moves on: copy outside the lock.
  const Slot& slot =
      slots_[static_cast<std::size_t>(next_ % static_cast<long long>(slots_.size()))];
  lock.unlock();
  frame = slot.frame;
  truth = slot.truth;
  lock.lock();
  ++next_;
  ++stats_.delivered;
  lock.unlock();
  changed_.notify_all();
  return FrameStatus::kFrame;
}

RenderAhead::Stats RenderAhead::stats() const {
  std::lock_guard lock(mutex_);
  return stats_;
}

}  // namespace fb
