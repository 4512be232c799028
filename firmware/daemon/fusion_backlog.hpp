// Frames read from the camera but not yet fused: while dlib looks for the take's face, and
// while fusion catches up after that (its first frames are the slowest). The frame loop keeps
// reading at the sensor's rate and fuses from the front within a time budget, so fusion never
// makes the sensor overwrite a frame. Slots are reused; a full backlog turns frames away
// (counted) instead of growing.
#pragma once

#include <cstdint>
#include <vector>

#include "algo/core/frame.hpp"

namespace fb {

class FusionBacklog {
 public:
  explicit FusionBacklog(std::size_t capacity) : slots_(capacity) {}

  bool empty() const { return count_ == 0; }
  std::size_t size() const { return count_; }
  int turned_away() const { return turned_away_; }

  // Copies the frame's depth in; false (and counted) when full.
  bool push(const RgbdFrame& frame) {
    if (count_ == slots_.size()) {
      ++turned_away_;
      return false;
    }
    Slot& s = slots_[(head_ + count_) % slots_.size()];
    s.index = frame.index;
    s.depth_mm = frame.depth_mm;
    ++count_;
    return true;
  }
  std::uint64_t front_index() const { return slots_[head_].index; }
  const DepthImage& front_depth() const { return slots_[head_].depth_mm; }
  // Lets go of the frames up to and including `index` (fused elsewhere); returns how many
  // came before it (never fused).
  int drop_through(std::uint64_t index) {
    int before = 0;
    while (!empty() && front_index() <= index) {
      if (front_index() < index) ++before;
      pop();
    }
    return before;
  }
  // Gives the slots' memory back (once the take has caught up: it is not needed again).
  void release() {
    if (count_ == 0) slots_.assign(slots_.size(), Slot{});
  }
  void pop() {
    head_ = (head_ + 1) % slots_.size();
    --count_;
  }

 private:
  struct Slot {
    std::uint64_t index = 0;
    DepthImage depth_mm;
  };
  std::vector<Slot> slots_;
  std::size_t head_ = 0, count_ = 0;
  int turned_away_ = 0;
};

}  // namespace fb
