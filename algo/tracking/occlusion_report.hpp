// Occlusion as data (issue 35, item 4): how much of the face something in front of it (a hand)
// hides on a frame, measured by the tracker's occlusion mask, whether that counts as an
// occluded face, and the events a consumer (the `track` command, the device) reports. Pure.
#pragma once

namespace fb {

// The hidden share of the face: `hidden` samples under the occlusion mask of `hidden + visible`
// samples facing the camera inside the image. 0 when there is no sample.
float hidden_fraction(int hidden, int visible);

// The tracker's occlusion state across frames. A frame whose mask was made (the face was
// tracked, or lost only on this frame) measures; a frame that measures nothing (searching
// after a loss) holds the last state: a hand that hid the face enough to lose it is taken to
// hide it until the face is found again.
class OcclusionState {
 public:
  void measure(float fraction, float threshold) {
    fraction_ = fraction;
    occluded_ = fraction >= threshold;
  }
  void reset() { *this = OcclusionState(); }
  float fraction() const { return fraction_; }
  bool occluded() const { return occluded_; }

 private:
  float fraction_ = 0.0f;
  bool occluded_ = false;
};

// A take's occlusion as the consumer reports it: frames occluded, and the changes between
// occluded and clear (a message on each, not on every frame).
class OcclusionLog {
 public:
  enum class Change { kNone, kOccluded, kClear };
  Change add(bool occluded) {
    frames_ += occluded ? 1 : 0;
    const bool before = occluded_;
    occluded_ = occluded;
    if (occluded == before) return Change::kNone;
    return occluded ? Change::kOccluded : Change::kClear;
  }
  long long occluded_frames() const { return frames_; }
  bool occluded() const { return occluded_; }

 private:
  long long frames_ = 0;
  bool occluded_ = false;
};

}  // namespace fb
