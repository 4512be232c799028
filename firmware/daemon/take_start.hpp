// The start of a take, beside its frame loop: finding the face box (dlib on a whole frame,
// 50-170 ms on the board) and fusing the first frame with it (the slowest fusion frame: on
// the first take it touches the volume's pages for the first time, ~300 ms). Run on the frame
// loop, both made the sensor overwrite the frames behind them; here they run on a thread of
// their own on copies of one frame, while the loop goes on reading and holds the frames that
// arrive meanwhile (FusionBacklog). The loop owns fusion again once poll() says so.
#pragma once

#include <cstdint>
#include <functional>
#include <future>
#include <optional>
#include <string>
#include <utility>

#include "algo/core/frame.hpp"
#include "algo/core/result.hpp"
#include "algo/fusion/fusion_types.hpp"

namespace fb {

struct StartedTake {
  FaceBox box;
  std::uint64_t frame_index = 0;  // the frame the box was found on, fused first
  FrameReport first_frame;
};

class TakeStart {
 public:
  // Finds the box on one frame and starts fusion with it (empty: no detector; the caller
  // starts fusion on its fallback box).
  using StartFn = std::function<Result<StartedTake>(const ColorImage&, const DepthImage&,
                                                    std::uint64_t frame_index)>;
  TakeStart(StartFn start, std::string no_detector_note, int max_attempts = 3);
  TakeStart(const TakeStart&) = delete;
  TakeStart& operator=(const TakeStart&) = delete;
  ~TakeStart();  // waits for a start still running (it reads only this object's copies)

  // Starts an attempt on this frame unless one runs, the start is decided or no attempt is
  // left (a failed attempt is retried on a later frame, up to max_attempts).
  void offer(const RgbdFrame& frame);
  // True once decided: started, or every attempt failed. Never blocks.
  bool poll();
  // Blocks until decided (the stream ended first).
  void wait();

  const std::optional<StartedTake>& started() const { return started_; }
  const std::string& note() const { return note_; }  // why no face was found
  // The colour image of the frame the take started on (once started; moved out).
  ColorImage release_start_color() { return std::move(color_); }

 private:
  void take_result(Result<StartedTake> result);

  StartFn start_;
  std::string note_;
  int max_attempts_ = 3, attempts_ = 0;
  bool decided_ = false;
  std::optional<StartedTake> started_;
  ColorImage color_;  // the start thread's copies of its frame
  DepthImage depth_;
  std::uint64_t index_ = 0;
  std::future<Result<StartedTake>> running_;
};

}  // namespace fb
