#include "firmware/daemon/take_start.hpp"

#include <chrono>
#include <utility>

namespace fb {

TakeStart::TakeStart(StartFn start, std::string no_detector_note, int max_attempts)
    : start_(std::move(start)), max_attempts_(max_attempts) {
  if (!start_) {
    decided_ = true;
    note_ = std::move(no_detector_note);
  }
}

TakeStart::~TakeStart() {
  if (running_.valid()) running_.wait();
}

void TakeStart::offer(const RgbdFrame& frame) {
  if (decided_ || running_.valid() || attempts_ >= max_attempts_) return;
  ++attempts_;
  color_ = frame.color;
  depth_ = frame.depth_mm;
  index_ = frame.index;
  running_ = std::async(std::launch::async, [this] { return start_(color_, depth_, index_); });
}

void TakeStart::take_result(Result<StartedTake> result) {
  depth_ = DepthImage();  // the attempt is over: its copy goes (the daemon's memory is tight)
  if (result) {
    started_ = std::move(*result);
    decided_ = true;
    return;
  }
  note_ = result.error().message;
  if (attempts_ >= max_attempts_) decided_ = true;
}

bool TakeStart::poll() {
  if (!decided_ && running_.valid() &&
      running_.wait_for(std::chrono::seconds(0)) == std::future_status::ready)
    take_result(running_.get());
  return decided_;
}

void TakeStart::wait() {
  if (!decided_ && running_.valid()) take_result(running_.get());
  decided_ = true;  // no frame left to try again on
}

}  // namespace fb
