// Real-time delivery for a rendering camera (the synthetic camera's `realtime=1`): a thread
// renders the stream ahead into a ring of slots while frames arrive on the sensor's clock (frame
// i at t0 + i / fps) and are handed out as a Kinect driver hands them out: a consumer that falls
// more than `queue_frames` behind loses the oldest frames (RgbdFrame::index shows the gap), as
// with the freenect backend's double buffer. So a consumer's dropped frames measure the consumer,
// not the renderer.
//
// The renderer may be slower than the sensor (the synthetic camera needs about 43 ms a frame on
// one core against the 33 ms period). The clock therefore starts only once enough frames are
// rendered that the rest can follow in time (the lead, from the measured render time), within
// `max_slots` frames of memory. A frame rendered after its sensor time anyway is delivered late
// and counted (Stats::late), never silently passed off as on time.
#pragma once

#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <mutex>
#include <thread>
#include <vector>

#include "algo/core/frame.hpp"
#include "algo/core/result.hpp"
#include "drivers/camera/depth_camera.hpp"
#include "sim/camera/frame_truth.hpp"

namespace fb {

struct RenderAheadOptions {
  long long frame_count = 0;  // frames in the stream (> 0)
  double fps = 30.0;          // the sensor's clock
  int queue_frames = 1;       // frames the driver keeps for a late consumer (freenect: 1)
  int max_slots = 32;         // at most this many frames rendered ahead (each ~2 MB)
  double safety = 1.15;       // the lead assumes rendering this much slower than measured
};

class RenderAhead {
 public:
  // Renders frame `index` into `frame` and `truth`; called on the render thread only.
  using RenderFn =
      std::function<Result<void>(std::uint64_t index, RgbdFrame& frame, FrameTruth& truth)>;

  struct Stats {
    long long rendered = 0;     // frames rendered so far
    long long delivered = 0;    // frames handed to the consumer
    long long overwritten = 0;  // frames the consumer was too late for (sensor semantics)
    long long late = 0;         // frames rendered after their sensor time (renderer too slow)
    int lead_frames = 0;        // frames rendered before the clock started
    int slots = 0;              // slots allocated (peak frames held)
    double render_ms_mean = 0;  // mean render time of one frame
  };

  // Starts the render thread. Fails on a bad frame count, rate or slot count.
  static Result<std::unique_ptr<RenderAhead>> start(const RenderAheadOptions& options,
                                                    RenderFn render);
  ~RenderAhead();  // stops the render thread and joins it
  RenderAhead(const RenderAhead&) = delete;
  RenderAhead& operator=(const RenderAhead&) = delete;

  // Waits up to `timeout` for the next frame on the sensor's clock and copies it (reusing the
  // buffers of `frame` and `truth`). kEndOfStream after the last frame; a render error is a
  // failure.
  Result<FrameStatus> next(RgbdFrame& frame, FrameTruth& truth, std::chrono::milliseconds timeout);

  Stats stats() const;

 private:
  using Clock = std::chrono::steady_clock;
  struct Slot {
    RgbdFrame frame;
    FrameTruth truth;
  };
  RenderAhead(const RenderAheadOptions& options, RenderFn render);
  void run();
  bool lead_reached(long long rendered, double render_ms) const;
  // The newest frame index that has arrived by `now` (-1 before the clock starts).
  long long arrived_by(Clock::time_point now) const;

  RenderAheadOptions options_;
  RenderFn render_;
  std::chrono::duration<double> period_;

  mutable std::mutex mutex_;
  std::condition_variable changed_;
  std::vector<Slot> slots_;  // ring: frame i lives in slot i % slots_.size()
  long long rendered_ = 0;   // frames [0, rendered_) are rendered
  long long next_ = 0;       // the next frame the consumer may get
  bool clock_started_ = false;
  Clock::time_point t0_;  // arrival time of frame 0
  bool stopping_ = false;
  Error error_;
  bool failed_ = false;
  Stats stats_;
  double render_ms_total_ = 0;
  std::thread thread_;
};

}  // namespace fb
